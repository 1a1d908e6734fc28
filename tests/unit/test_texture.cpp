#include "core/color.h"
#include "scene/accel.h"
#include "scene/bsdf.h"
#include "scene/parser.h"
#include "scene/shapes.h"
#include "scene/texture.h"

#include "core/image.h"
#include "core/log.h"
#include "tests/test_util.h"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <unistd.h>

namespace theia {
namespace {

namespace fs = std::filesystem;

void expect_rgb_near(const RGB& a, const RGB& b, float tol, const std::string& what = "") {
  EXPECT_NEAR(a.x, b.x, tol) << what;
  EXPECT_NEAR(a.y, b.y, tol) << what;
  EXPECT_NEAR(a.z, b.z, tol) << what;
}

// A w x h RGB image whose texel (x, y) (row 0 at the top) is (x, y, 10 + x + w * y).
Image ramp_image(int w, int h) {
  return test::make_image(w, h, 3, [w](int x, int y) { return RGB(float(x), float(y), float(10 + x + w * y)); });
}
RGB ramp(int w, int x, int y) { return RGB(float(x), float(y), float(10 + x + w * y)); }

// Texture coordinates of the centre of texel (x, y).
vec2 centre(const Image& img, int x, int y) {
  return {(float(x) + 0.5f) / float(img.width), 1.0f - (float(y) + 0.5f) / float(img.height)};
}

TEST(TextureLookup, PixelCentresReturnThePixelAndHalfwayTheAverage) {
  Image img = ramp_image(4, 3);
  for (WrapMode wrap : {WrapMode::Repeat, WrapMode::Clamp, WrapMode::Black, WrapMode::OctahedralSphere})
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 4; ++x) expect_rgb_near(image_lookup_bilinear(img, centre(img, x, y), wrap), ramp(4, x, y), 1e-5f);

  // t = 1 is the top row: the flip pbrt-v4 applies to image textures.
  expect_rgb_near(image_lookup_bilinear(img, {0.125f, 5.0f / 6.0f}, WrapMode::Clamp), ramp(4, 0, 0), 1e-5f);
  // Halfway between horizontal neighbours, and at the corner of four texels.
  vec2 mid = 0.5f * (centre(img, 1, 1) + centre(img, 2, 1));
  expect_rgb_near(image_lookup_bilinear(img, mid, WrapMode::Repeat), 0.5f * (ramp(4, 1, 1) + ramp(4, 2, 1)), 1e-5f);
  vec2 corner = 0.5f * (centre(img, 1, 0) + centre(img, 2, 1));
  RGB avg4 = 0.25f * (ramp(4, 1, 0) + ramp(4, 2, 0) + ramp(4, 1, 1) + ramp(4, 2, 1));
  expect_rgb_near(image_lookup_bilinear(img, corner, WrapMode::Repeat), avg4, 1e-5f);
  // A quarter of the way gives 3:1 weights.
  vec2 quarter = 0.75f * centre(img, 0, 2) + 0.25f * centre(img, 1, 2);
  expect_rgb_near(image_lookup_bilinear(img, quarter, WrapMode::Clamp), 0.75f * ramp(4, 0, 2) + 0.25f * ramp(4, 1, 2),
                  1e-5f);
  // Raster-space lookup has no flip.
  expect_rgb_near(image_bilerp(img, {0.125f, 1.0f / 6.0f}, WrapMode::Clamp), ramp(4, 0, 0), 1e-5f);
}

TEST(TextureLookup, WrapModesAtAndBeyondTheBorders) {
  const int w = 4, h = 3;
  Image img = ramp_image(w, h);
  // Texels just outside each edge.
  EXPECT_EQ(image_texel(img, {-1, 1}, WrapMode::Repeat), ramp(w, 3, 1));
  EXPECT_EQ(image_texel(img, {4, 2}, WrapMode::Repeat), ramp(w, 0, 2));
  EXPECT_EQ(image_texel(img, {-5, -4}, WrapMode::Repeat), ramp(w, 3, 2));
  EXPECT_EQ(image_texel(img, {9, 7}, WrapMode::Repeat), ramp(w, 1, 1));
  EXPECT_EQ(image_texel(img, {-1, 1}, WrapMode::Clamp), ramp(w, 0, 1));
  EXPECT_EQ(image_texel(img, {7, -3}, WrapMode::Clamp), ramp(w, 3, 0));
  EXPECT_EQ(image_texel(img, {-1, 1}, WrapMode::Black), RGB(0.0f));
  EXPECT_EQ(image_texel(img, {1, 3}, WrapMode::Black), RGB(0.0f));
  EXPECT_EQ(image_texel(img, {3, 2}, WrapMode::Black), ramp(w, 3, 2));
  // Octahedral: crossing u = 0 or 1 mirrors v about 0.5, crossing v = 0 or 1 mirrors u.
  EXPECT_EQ(image_texel(img, {-1, 0}, WrapMode::OctahedralSphere), ramp(w, 1, 2));
  EXPECT_EQ(image_texel(img, {4, 0}, WrapMode::OctahedralSphere), ramp(w, 3, 2));
  EXPECT_EQ(image_texel(img, {1, -1}, WrapMode::OctahedralSphere), ramp(w, 2, 1));
  EXPECT_EQ(image_texel(img, {0, 3}, WrapMode::OctahedralSphere), ramp(w, 3, 2));
  EXPECT_EQ(image_texel(img, {-1, -1}, WrapMode::OctahedralSphere), ramp(w, 2, 2));

  // Bilinear at the left edge, on the middle row: half the edge texel, half the wrapped one.
  vec2 edge{0.0f, centre(img, 0, 1).y};
  expect_rgb_near(image_lookup_bilinear(img, edge, WrapMode::Repeat), 0.5f * (ramp(w, 3, 1) + ramp(w, 0, 1)), 1e-5f);
  expect_rgb_near(image_lookup_bilinear(img, edge, WrapMode::Clamp), ramp(w, 0, 1), 1e-5f);
  expect_rgb_near(image_lookup_bilinear(img, edge, WrapMode::Black), 0.5f * ramp(w, 0, 1), 1e-5f);
  expect_rgb_near(image_lookup_bilinear(img, edge, WrapMode::OctahedralSphere),
                  0.5f * (ramp(w, 1, 1) + ramp(w, 0, 1)), 1e-5f);

  // Well beyond the image.
  vec2 far = centre(img, 1, 2) + vec2(3.0f, -2.0f);
  expect_rgb_near(image_lookup_bilinear(img, far, WrapMode::Repeat), ramp(w, 1, 2), 1e-4f);
  expect_rgb_near(image_lookup_bilinear(img, vec2(5.0f, -7.0f), WrapMode::Clamp), ramp(w, 3, 2), 1e-5f);
  expect_rgb_near(image_lookup_bilinear(img, vec2(5.0f, -7.0f), WrapMode::Black), RGB(0.0f), 0.0f);
  // NaN coordinates stay defined (no crash) and finite.
  EXPECT_TRUE(is_finite(image_lookup_bilinear(img, vec2(std::nanf(""), 0.5f), WrapMode::Repeat)));
}

TEST(TextureLookup, GreyImagesAreGreyAndEmptyImagesBlack) {
  Image grey;
  grey.width = 2;
  grey.height = 1;
  grey.channels = 1;
  grey.pixels = {0.25f, 0.75f};
  expect_rgb_near(image_lookup_bilinear(grey, {0.25f, 0.5f}, WrapMode::Clamp), RGB(0.25f), 1e-6f);
  expect_rgb_near(image_lookup_bilinear(grey, {0.5f, 0.5f}, WrapMode::Clamp), RGB(0.5f), 1e-6f);
  EXPECT_EQ(image_lookup_bilinear(Image{}, {0.5f, 0.5f}, WrapMode::Repeat), RGB(0.0f));
}

// ---------------------------------------------------------------- evaluation

int add(Scene& s, Texture t) {
  s.textures.push_back(t);
  return int(s.textures.size()) - 1;
}
int constant(Scene& s, RGB v, bool is_float = false) {
  Texture t;
  t.kind = TextureKind::Constant;
  t.value = v;
  t.is_float = is_float;
  return add(s, t);
}

TEST(TextureEval, CheckerboardPicksByParityOfFlooredST) {
  Scene s;
  int a = constant(s, RGB(0.1f, 0.2f, 0.3f)), b = constant(s, RGB(0.7f, 0.8f, 0.9f));
  Texture c;
  c.kind = TextureKind::Checkerboard;
  c.mapping = {2.0f, 2.0f, 0.0f, 0.0f};
  c.tex1 = a;
  c.tex2 = b;
  int cb = add(s, c);
  auto at = [&](float u, float v) { return eval_texture(s, cb, {{u, v}, vec3(0.0f)}); };
  EXPECT_EQ(at(0.1f, 0.1f), s.textures[size_t(a)].value);   // (0, 0): even
  EXPECT_EQ(at(0.6f, 0.1f), s.textures[size_t(b)].value);   // (1, 0): odd
  EXPECT_EQ(at(0.6f, 0.6f), s.textures[size_t(a)].value);   // (1, 1): even
  EXPECT_EQ(at(0.1f, 0.6f), s.textures[size_t(b)].value);   // (0, 1): odd
  EXPECT_EQ(at(-0.1f, 0.1f), s.textures[size_t(b)].value);  // (-1, 0): odd
  EXPECT_EQ(at(-0.1f, -0.1f), s.textures[size_t(a)].value); // (-1, -1): even
  // Offsets shift the pattern.
  s.textures[size_t(cb)].mapping.du = 1.0f;
  EXPECT_EQ(at(0.1f, 0.1f), s.textures[size_t(b)].value);
  // Missing children take pbrt-v4's defaults (tex1 = 1, tex2 = 0).
  s.textures[size_t(cb)].tex1 = -1;
  s.textures[size_t(cb)].tex2 = -1;
  EXPECT_EQ(at(0.1f, 0.1f), RGB(0.0f));
  EXPECT_EQ(at(0.6f, 0.1f), RGB(1.0f));
}

TEST(TextureEval, ScaleAndMix) {
  Scene s;
  int colour = constant(s, RGB(0.2f, 0.4f, 0.8f));
  int other = constant(s, RGB(1.0f, 0.0f, 0.5f));
  int half = constant(s, RGB(0.5f, 9.0f, 9.0f), true);  // float: only .x counts
  int quarter = constant(s, RGB(0.25f), true);
  int zero = constant(s, RGB(0.0f), true);

  Texture sc;
  sc.kind = TextureKind::Scale;
  sc.tex1 = colour;
  sc.tex2 = half;
  int scaled = add(s, sc);
  expect_rgb_near(eval_texture(s, scaled, {}), RGB(0.1f, 0.2f, 0.4f), 1e-7f);
  EXPECT_FLOAT_EQ(eval_float_texture(s, scaled, {}), 0.1f);
  s.textures[size_t(scaled)].tex2 = zero;
  EXPECT_EQ(eval_texture(s, scaled, {}), RGB(0.0f));

  Texture mx;
  mx.kind = TextureKind::Mix;
  mx.tex1 = colour;
  mx.tex2 = other;
  mx.amount = quarter;
  int mixed = add(s, mx);
  expect_rgb_near(eval_texture(s, mixed, {}), 0.75f * RGB(0.2f, 0.4f, 0.8f) + 0.25f * RGB(1.0f, 0.0f, 0.5f), 1e-6f);
  s.textures[size_t(mixed)].amount = -1;  // pbrt-v4 default amount 0.5
  expect_rgb_near(eval_texture(s, mixed, {}), RGB(0.6f, 0.2f, 0.65f), 1e-6f);

  // Float textures compose: mix(0.25, 0.5 * 0.25, amount 0.25).
  Texture fs;
  fs.kind = TextureKind::Scale;
  fs.is_float = true;
  fs.tex1 = half;
  fs.tex2 = quarter;
  int fscaled = add(s, fs);
  Texture fm;
  fm.kind = TextureKind::Mix;
  fm.is_float = true;
  fm.tex1 = quarter;
  fm.tex2 = fscaled;
  fm.amount = quarter;
  int fmixed = add(s, fm);
  EXPECT_FLOAT_EQ(eval_float_texture(s, fmixed, {}), 0.75f * 0.25f + 0.25f * 0.125f);
}

TEST(TextureEval, ImageMapFlipsTAppliesScaleThenInvert) {
  Scene s;
  Image img;
  img.width = 2;
  img.height = 2;
  img.channels = 3;
  // top-left, top-right, bottom-left, bottom-right
  img.pixels = {0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f, 0.25f, 0.5f, 0.75f, 0.7f, 0.8f, 0.9f};
  s.images.push_back(img);
  Texture t;
  t.kind = TextureKind::ImageMap;
  t.image = 0;
  t.wrap = WrapMode::Clamp;
  int tex = add(s, t);
  // uv (0.25, 0.75) is the top-left texel's centre; (0.25, 0.25) the bottom-left's.
  expect_rgb_near(eval_texture(s, tex, {{0.25f, 0.75f}, vec3(0.0f)}), RGB(0.1f, 0.2f, 0.3f), 1e-6f);
  expect_rgb_near(eval_texture(s, tex, {{0.25f, 0.25f}, vec3(0.0f)}), RGB(0.25f, 0.5f, 0.75f), 1e-6f);
  // The uv mapping: st = (su * u + du, sv * v + dv).
  s.textures[size_t(tex)].mapping = {0.5f, 0.5f, 0.5f, 0.0f};
  expect_rgb_near(eval_texture(s, tex, {{0.5f, 0.5f}, vec3(0.0f)}), RGB(0.7f, 0.8f, 0.9f), 1e-6f);
  s.textures[size_t(tex)].mapping = {};

  s.textures[size_t(tex)].scale = 2.0f;
  vec2 bl{0.25f, 0.25f};
  expect_rgb_near(eval_texture(s, tex, {bl, vec3(0.0f)}), RGB(0.5f, 1.0f, 1.5f), 1e-6f);
  s.textures[size_t(tex)].invert = true;
  // 1 - scale * lookup, clamped at zero: (0.5, 0, -0.5) -> (0.5, 0, 0).
  expect_rgb_near(eval_texture(s, tex, {bl, vec3(0.0f)}), RGB(0.5f, 0.0f, 0.0f), 1e-6f);
  // Float imagemap: first channel.
  s.textures[size_t(tex)].is_float = true;
  EXPECT_NEAR(eval_float_texture(s, tex, {bl, vec3(0.0f)}), 0.5f, 1e-6f);
  s.textures[size_t(tex)].scale = 8.0f;
  EXPECT_EQ(eval_float_texture(s, tex, {bl, vec3(0.0f)}), 0.0f);  // 1 - 2, clamped
  s.textures[size_t(tex)].invert = false;
  EXPECT_NEAR(eval_float_texture(s, tex, {bl, vec3(0.0f)}), 2.0f, 1e-6f);
}

// ---------------------------------------------------------------- bump mapping

// A flat diffuse surface at the origin, uv = (x, y), bump mapped by `height`
// (a float texture index in s).
struct BumpPlane {
  Scene scene;
  SurfaceInteraction si;
  explicit BumpPlane(Scene s, int height, vec2 uv) : scene(std::move(s)) {
    Material m;
    m.kind = MaterialKind::Diffuse;
    m.displacement = height;
    scene.materials.push_back(m);
    si.p = vec3(uv, 0.0f);
    si.ng = si.ns = vec3(0, 0, 1);
    si.dpdu = vec3(1, 0, 0);
    si.dpdv = vec3(0, 1, 0);
    si.uv = uv;
    si.wo = vec3(0, 0, 1);
    si.material = 0;
  }
  vec3 normal(const UVFootprint& fp) const { return make_bsdf(scene, si, fp).shading.n; }
};

// With dpdu = x, dpdv = y and n = z, bumps of slope (hu, hv) tilt the normal
// to normalize(-hu, -hv, 1).
vec3 bumped(float hu, float hv) { return glm::normalize(vec3(-hu, -hv, 1.0f)); }

TEST(TextureBumpMap, LinearRampTiltsTheNormalByItsSlopeWithAnyOffset) {
  // Height 1/64 per texel along x and 2/64 per texel up the image: slopes 1
  // and 2 in (u, v).  Bilinear lookups of it are exactly linear between the
  // outermost texel centres, so every finite difference there is the slope.
  Scene s;
  s.images.push_back(test::make_image(64, 64, 1, [](int x, int y) { return RGB((float(x) + 2.0f * float(63 - y)) / 64.0f); }));
  Texture t;
  t.kind = TextureKind::ImageMap;
  t.is_float = true;
  t.image = 0;
  t.wrap = WrapMode::Clamp;
  int height = add(s, t);
  BumpPlane plane(s, height, {0.3f, 0.4f});
  const vec3 expected = bumped(1.0f, 2.0f);
  for (UVFootprint fp : {UVFootprint{}, UVFootprint{0.02f, 0.01f, 0.005f, 0.03f}, UVFootprint{-0.1f, 0.0f, 0.0f, -0.2f}}) {
    vec3 n = plane.normal(fp);
    EXPECT_NEAR(n.x, expected.x, 2e-4f) << fp.dudx;
    EXPECT_NEAR(n.y, expected.y, 2e-4f) << fp.dudx;
    EXPECT_NEAR(n.z, expected.z, 2e-4f) << fp.dudx;
  }
}

TEST(TextureBumpMap, OffsetIsHalfTheFootprintOrTheFixedFallback) {
  // A unit step (checkerboard: 1 below u = 1, 0 above) seen from just left of
  // it: the finite difference is -1 / offset when the offset reaches past the
  // step and 0 when it does not, which reveals the offset.  The 3D checkerboard
  // (p = (u, v, 0) here) keeps the step sharp whatever the footprint; the 2D one
  // would filter it over the footprint, as pbrt-v4 does.
  Scene s;
  Texture c;
  c.kind = TextureKind::Checkerboard;
  c.mapping_kind = TextureMappingKind::Point3D;
  c.is_float = true;
  int step = add(s, c);
  auto expect_normal = [](vec3 n, vec3 e, const char* what) {
    EXPECT_NEAR(n.x, e.x, 1e-4f) << what;
    EXPECT_NEAR(n.y, e.y, 1e-4f) << what;
    EXPECT_NEAR(n.z, e.z, 1e-4f) << what;
  };
  // du = (|dudx| + |dudy|) / 2 = 0.15 reaches the step from u = 0.9; 0.0005 does not.
  BumpPlane far(s, step, {0.9f, 0.5f});
  expect_normal(far.normal({0.2f, -0.1f, 0.0f, 0.0f}), bumped(-1.0f / 0.15f, 0.0f), "du from the footprint");
  expect_normal(far.normal({}), vec3(0, 0, 1), "no footprint: 0.0005 stays short of the step");
  // From u = 0.9997 both reach it: the fallback 0.0005 gives the steep slope.
  BumpPlane near(s, step, {0.9997f, 0.5f});
  vec3 fallback = near.normal({});
  expect_normal(fallback, bumped(-1.0f / 0.0005f, 0.0f), "zero footprint falls back to 0.0005");
  expect_normal(near.normal({0.2f, -0.1f, 0.0f, 0.0f}), bumped(-1.0f / 0.15f, 0.0f), "footprint");
  // A footprint along v only leaves du at the fallback.
  expect_normal(near.normal({0.0f, 0.0f, 0.01f, 0.0f}), fallback, "v footprint, u fallback");
  // And dv likewise, from the v derivatives' magnitudes: 0.2 reaches v = 1 from 0.9.
  BumpPlane below(s, step, {0.5f, 0.9f});
  expect_normal(below.normal({0.0f, 0.0f, -0.1f, 0.3f}), bumped(0.0f, -1.0f / 0.2f), "dv from the footprint");
  expect_normal(below.normal({}), vec3(0, 0, 1), "dv fallback stays short");
}

// The bump-mapped normal of a curved surface is the normal of the displaced
// surface P = p + d n, whose partials carry d dn/du: against P written out in
// the test for a sphere of radius R (uniform scale s of a unit sphere, and its
// centre moved), with d linear in (u, v) so the bump's finite differences are
// exact.  Without the d dn/du term the tilt is (R + d) / R too large (up to 2x
// here); with pbrt-v4's dn/du under a scale (carried as a normal, 1/s too
// short) it is off by the scale.
TEST(TextureBumpMap, CurvedSurfaceTiltsLikeTheDisplacedSurface) {
  for (float scale : {1.0f, 2.0f}) {
    const vec3 centre(0.5f, -1.0f, 0.25f);
    Scene s = parse_scene_string(
        fmt::format("WorldBegin\nTexture \"d\" \"float\" \"bilerp\" \"float v00\" 0.3 \"float v10\" 2.3 "
                    "\"float v01\" 0.5 \"float v11\" 2.5\nMaterial \"diffuse\" \"texture displacement\" \"d\"\n"
                    "Translate {} {} {}\nScale {} {} {}\nShape \"sphere\"\n",
                    centre.x, centre.y, centre.z, scale, scale, scale),
        "bump.pbrt", ".");
    Accel accel(s);
    const double R = scale;
    auto d_at = [](double u, double v) { return 0.3 + 2.0 * u + 0.2 * v; };
    // pbrt-v4's full sphere: phi = 2 pi u, theta = pi (1 - v), p - centre = (R + d) * unit direction.
    auto displaced = [&](double u, double v) {
      double phi = 2.0 * kPi * u, theta = kPi * (1.0 - v);
      glm::dvec3 dir(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
      return (R + d_at(u, v)) * dir;
    };
    int checked = 0;
    for (vec3 dir : {vec3(1, 0.2f, 0.3f), vec3(-0.4f, 1, -0.5f), vec3(0.3f, -0.8f, 0.6f), vec3(-1, -0.3f, -0.2f)}) {
      dir = glm::normalize(dir);
      Ray ray{centre + 5.0f * dir, 0.0f, -dir, kInfinity};
      Hit hit = accel.intersect1(ray);
      ASSERT_TRUE(hit.hit());
      SurfaceInteraction si = compute_interaction(s, accel, ray, hit);
      vec3 n = make_bsdf(s, si, UVFootprint{}).shading.n;
      const double h = 1e-5, u = si.uv.x, v = si.uv.y;
      glm::dvec3 Pu = (displaced(u + h, v) - displaced(u - h, v)) / (2 * h);
      glm::dvec3 Pv = (displaced(u, v + h) - displaced(u, v - h)) / (2 * h);
      glm::dvec3 truth = glm::normalize(glm::cross(Pu, Pv));
      if (glm::dot(truth, glm::dvec3(si.ng)) < 0) truth = -truth;
      glm::dvec3 plain(si.ns);
      EXPECT_GT(glm::length(truth - plain), 0.05) << "the bumps must tilt the normal visibly";
      EXPECT_NEAR(n.x, truth.x, 2e-4) << "scale " << scale << " uv " << u << " " << v;
      EXPECT_NEAR(n.y, truth.y, 2e-4) << "scale " << scale << " uv " << u << " " << v;
      EXPECT_NEAR(n.z, truth.z, 2e-4) << "scale " << scale << " uv " << u << " " << v;
      ++checked;
    }
    EXPECT_EQ(checked, 4);
  }
}

// ---------------------------------------------------------------- loading

class TextureFiles : public theia::test::TempDirTest {
 protected:
  void write(const std::string& path, int w, int h, int nc, OIIO::TypeDesc type, const void* px) {
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out) << OIIO::geterror();
    OIIO::ImageSpec spec(w, h, nc, type);
    spec.attribute("oiio:UnassociatedAlpha", 1);  // the values are the file's values
    ASSERT_TRUE(out->open(path, spec)) << out->geterror();
    ASSERT_TRUE(out->write_image(type, px)) << out->geterror();
    ASSERT_TRUE(out->close());
  }
};

TEST_F(TextureFiles, EightBitImagesAreDecodedByTheirEncoding) {
  const std::vector<uint8_t> rgba = {0, 128, 255, 128, 64, 32, 16, 255};
  write(file("a.png"), 2, 1, 4, OIIO::TypeDesc::UINT8, rgba.data());
  const std::vector<uint8_t> grey = {51, 204};
  write(file("g.png"), 2, 1, 1, OIIO::TypeDesc::UINT8, grey.data());

  Scene s;
  for (const char* enc : {"", "sRGB", "linear", "gamma 2.2"}) {
    Image img;
    img.filename = file("a.png");
    img.encoding = enc;
    s.images.push_back(img);
  }
  Image g;
  g.filename = file("g.png");
  s.images.push_back(g);
  load_images(s);

  for (int i = 0; i < 4; ++i) {
    const Image& img = s.images[size_t(i)];
    ASSERT_EQ(img.width, 2);
    ASSERT_EQ(img.height, 1);
    ASSERT_EQ(img.channels, 4);
    ASSERT_EQ(img.pixels.size(), 8u);
    for (size_t k = 0; k < 8; ++k) {
      float code = float(rgba[k]) / 255.0f;
      float expected = code;
      if (k % 4 != 3) {  // alpha is never decoded
        if (i <= 1) expected = srgb8_to_linear(rgba[k]);
        if (i == 3) expected = std::pow(code, 2.2f);
      }
      EXPECT_NEAR(img.pixels[k], expected, 1e-6f) << "encoding '" << img.encoding << "' value " << k;
    }
  }
  EXPECT_NEAR(s.images[0].pixels[1], 0.2158605f, 1e-6f);  // sRGB 128
  const Image& gi = s.images[4];
  ASSERT_EQ(gi.channels, 1);
  expect_rgb_near(image_lookup_bilinear(gi, {0.75f, 0.5f}, WrapMode::Clamp), RGB(srgb8_to_linear(204)), 1e-6f);
}

TEST_F(TextureFiles, FloatImagesStayLinearAndRelativePathsResolveBesideTheScene) {
  fs::create_directories(dir / "tex");
  const std::vector<float> px = {0.5f, 2.0f, -0.25f, 0.125f, 0.0f, 8.0f};
  write(file("tex/e.exr"), 1, 2, 3, OIIO::TypeDesc::FLOAT, px.data());
  {
    // OpenImageIO 2.4 cannot write PFM: bottom row first, little-endian.
    std::ofstream f(file("tex/p.pfm"), std::ios::binary);
    f << "PF\n1 2\n-1.0\n";
    f.write(reinterpret_cast<const char*>(&px[3]), 3 * sizeof(float));
    f.write(reinterpret_cast<const char*>(&px[0]), 3 * sizeof(float));
  }
  Scene s;
  s.path = file("scene.pbrt");
  Image e;
  e.filename = "tex/e.exr";
  e.encoding = "sRGB";  // ignored for float pixels, as in pbrt-v4
  s.images.push_back(e);
  Image p;
  p.filename = "tex/p.pfm";
  s.images.push_back(p);
  Image colour = p;
  colour.is_color = true;
  s.images.push_back(colour);
  load_images(s);
  EXPECT_EQ(s.images[0].pixels, px);
  EXPECT_EQ(s.images[1].pixels, px);
  EXPECT_EQ(s.images[0].channels, 3);
  // A colour image joins the working colour space at load; data images stay as stored.
  for (int i = 0; i < 2; ++i) {
    RGB want = srgb_to_working(RGB(px[3 * i], px[3 * i + 1], px[3 * i + 2]));
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(s.images[2].pixels[size_t(3 * i + c)], want[c], 1e-6f);
  }
}

TEST_F(TextureFiles, ManyImagesLoadInParallelAndErrorsNameTheFile) {
  Scene s;
  for (int i = 0; i < 12; ++i) {
    std::vector<float> px(4 * 3, float(i));
    std::string path = file(fmt::format("img{}.exr", i));
    write(path, 2, 2, 3, OIIO::TypeDesc::FLOAT, px.data());
    Image img;
    img.filename = path;
    s.images.push_back(img);
  }
  load_images(s);
  for (int i = 0; i < 12; ++i) EXPECT_EQ(s.images[size_t(i)].pixels, std::vector<float>(12, float(i)));

  Scene bad;
  Image missing;
  missing.filename = file("missing.png");
  bad.images.push_back(missing);
  try {
    load_images(bad);
    FAIL() << "expected theia::Error";
  } catch (const Error& err) {
    EXPECT_NE(std::string(err.what()).find("missing.png"), std::string::npos) << err.what();
  }

  // In-memory images are left alone; an image with neither file nor pixels is an error.
  Scene mem;
  Image procedural;
  procedural.width = procedural.height = procedural.channels = 1;
  procedural.pixels = {0.5f};
  mem.images.push_back(procedural);
  load_images(mem);
  EXPECT_EQ(mem.images[0].pixels, std::vector<float>{0.5f});
  mem.images.push_back(Image{});
  try {
    load_images(mem);
    FAIL() << "expected theia::Error";
  } catch (const Error& err) {
    EXPECT_EQ(std::string(err.what()).rfind("image #1:", 0), 0u) << err.what();
  }

  Scene enc;
  Image img = s.images[0];
  img.pixels.clear();
  img.encoding = "gamma";
  enc.images.push_back(img);
  try {
    load_images(enc);
    FAIL() << "expected theia::Error";
  } catch (const Error& err) {
    EXPECT_NE(std::string(err.what()).find("img0.exr"), std::string::npos) << err.what();
    EXPECT_NE(std::string(err.what()).find("gamma"), std::string::npos) << err.what();
  }
}

// The engine computes a footprint only at hits on materials that read one:
// a filtered texture anywhere beneath them (through texture and material
// nesting) or a bump map.  Elsewhere any footprint gives the same BSDF.
TEST(TextureFootprint, MaterialsReadItOnlyThroughFilteredTexturesOrBumps) {
  Scene scene = parse_scene_string(R"(WorldBegin
Texture "checks" "spectrum" "checkerboard" "rgb tex1" [0 0 0] "rgb tex2" [1 1 1]
Texture "checks3d" "spectrum" "checkerboard" "integer dimension" [3]
Texture "scaled" "spectrum" "scale" "texture tex" "checks"
Texture "amount" "float" "checkerboard"
MakeNamedMaterial "plain" "string type" "diffuse" "rgb reflectance" [0.5 0.5 0.5]
MakeNamedMaterial "checked" "string type" "diffuse" "texture reflectance" "checks"
MakeNamedMaterial "checked3d" "string type" "diffuse" "texture reflectance" "checks3d"
MakeNamedMaterial "scaled" "string type" "coateddiffuse" "texture reflectance" "scaled"
MakeNamedMaterial "bumpy" "string type" "diffuse" "float displacement" [0.1]
MakeNamedMaterial "mix-plain" "string type" "mix" "string materials" ["plain" "checked3d"] "float amount" [0.3]
MakeNamedMaterial "mix-checked" "string type" "mix" "string materials" ["plain" "checked"]
MakeNamedMaterial "mix-amount" "string type" "mix" "string materials" ["plain" "plain"] "texture amount" "amount"
)");
  auto reads = [&](const std::string& name) {
    for (size_t i = 0; i < scene.materials.size(); ++i)
      if (scene.materials[i].name == name) return material_reads_footprint(scene, int(i));
    ADD_FAILURE() << "no material " << name;
    return false;
  };
  EXPECT_FALSE(material_reads_footprint(scene, -1));
  EXPECT_FALSE(reads("plain"));
  EXPECT_TRUE(reads("checked"));
  EXPECT_FALSE(reads("checked3d"));
  EXPECT_TRUE(reads("scaled"));
  EXPECT_TRUE(reads("bumpy"));
  EXPECT_FALSE(reads("mix-plain"));
  EXPECT_TRUE(reads("mix-checked"));
  EXPECT_TRUE(reads("mix-amount"));
}

}  // namespace
}  // namespace theia
