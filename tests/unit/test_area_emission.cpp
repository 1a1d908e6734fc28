// Area-light emission with pbrt-v4's semantics: "power" on a mesh gives each
// triangle the power (radiance phi / (pi * sides * area_i)), "filename"
// images looked up at the surface's uv with v flipped and normalised by their
// mean luminance under "power", alpha-masked emission, light_power as the
// true total, and the parse errors for bad "filename" use.
#include "core/color.h"
#include "core/image.h"
#include "core/log.h"
#include "scene/accel.h"
#include "scene/lights.h"
#include "scene/parser.h"
#include "scene/texture.h"
#include "tests/test_util.h"

#include <fmt/format.h>
#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <random>

using namespace theia;

namespace {

// Triangles of areas 1 and 0.25 (z = 0, facing +z).
const char* kUnequalMesh = R"(Shape "trianglemesh" "point3 P" [0 0 0  2 0 0  2 1 0  2.5 0 0  3 0 0  3 1 0]
  "integer indices" [0 1 2 3 4 5])";
const float kAreas[2] = {1.0f, 0.25f};
// A point inside each triangle.
const vec2 kInside[2] = {vec2(1.6f, 0.3f), vec2(2.9f, 0.3f)};

struct Lit {
  Scene scene;
  std::unique_ptr<Accel> accel;
  std::unique_ptr<LightSet> lights;
  explicit Lit(Scene s) : scene(std::move(s)) {
    load_images(scene);
    accel = std::make_unique<Accel>(scene);
    lights = std::make_unique<LightSet>(scene, *accel);
  }
  // What a ray straight down onto (x, y, 0) finds: the emitter's radiance towards the ray's origin.
  RGB radiance_at(float x, float y) const {
    Ray r{vec3(x, y, 1.0f), 0.0f, vec3(0, 0, -1), kInfinity};
    Hit hit = accel->intersect1(r);
    EXPECT_TRUE(hit.hit()) << x << " " << y;
    if (!hit.hit()) return RGB(-1.0f);
    SurfaceInteraction si = compute_interaction(scene, *accel, r, hit);
    EXPECT_EQ(si.area_light, 0);
    return area_light_L(*lights, si.area_light, si, si.wo);
  }
};

// A w x h linear RGB EXR with texel(x, y), row 0 at the top.
std::string write_rgb_exr(const test::TempDir& dir, const std::string& name, int w, int h,
                          const std::function<RGB(int, int)>& texel) {
  ImageBuffer img(w, h, {"R", "G", "B"});
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) img.at(x, y, c) = texel(x, y)[c];
  std::string path = dir.file(name);
  write_exr(path, img);
  return path;
}

RGB four_colours(int x, int y) {
  static const RGB c[2][2] = {{RGB(1.0f, 0.1f, 0.1f), RGB(0.1f, 2.0f, 0.1f)},
                              {RGB(0.1f, 0.1f, 3.0f), RGB(0.5f, 0.5f, 0.5f)}};
  return c[y][x];
}

// A unit quad at z = 0 with uv = (x, y).
const char* kQuad = R"(Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 1 1 0 0 1 0] "point2 uv" [0 0 1 0 1 1 0 1]
  "integer indices" [0 1 2 0 2 3])";

// head + kQuad + tail.  Formatted rather than concatenated with std::string's
// operator+, on which GCC 12 with -march=native on AVX-512 machines raises a
// false -Warray-bounds (its bug 105329), an error under -Werror.
std::string quad_scene(std::string_view head, std::string_view tail = {}) {
  return fmt::format("{}{}{}", head, kQuad, tail);
}

}  // namespace

// pbrt-v4 makes one light per triangle, each emitting the whole power: the
// radiance of triangle i is scale * phi / (pi * sides * A_i), with no warning.
TEST(ParserAreaLight, PowerOnUnequalMeshGivesEachTriangleThePower) {
  for (bool two_sided : {false, true}) {
    int before = warning_count();
    Scene s = parse_scene_string(std::string("WorldBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"float power\" 10 "
                                             "\"float scale\" 2 \"bool twosided\" ") +
                                     (two_sided ? "true\n" : "false\n") + kUnequalMesh,
                                 "t.pbrt");
    EXPECT_EQ(warning_count(), before);
    ASSERT_EQ(s.lights.size(), 1u);
    const Light& l = s.lights[0];
    ASSERT_EQ(l.triangle_scale.size(), 2u);
    const float sides = two_sided ? 2.0f : 1.0f;
    Lit lit(std::move(s));
    for (int i = 0; i < 2; ++i) {
      float want = 2.0f * 10.0f / (kPi * sides * kAreas[i]);
      RGB L = lit.radiance_at(kInside[i].x, kInside[i].y);
      EXPECT_NEAR(luminance(L) / want, 1.0f, 1e-5f) << "triangle " << i;
      EXPECT_NEAR(L.x / L.y, 1.0f, 1e-5f);  // grey stays grey
    }
    // Every triangle emits scale * phi: the power light sampler sees the total.
    EXPECT_NEAR(light_power(*lit.lights, 0) / (2.0f * 2.0f * 10.0f), 1.0f, 1e-5f);
    // And light sampling chooses the triangles by power: half each, not 4 : 1 by area.
    int first = 0;
    const int n = 1000;
    for (int i = 0; i < n; ++i) {
      auto ls = sample_li(*lit.lights, 0, LightSampleContext{vec3(1.5f, 0.5f, 2.0f)}, vec2(0.5f, 0.3f),
                          (float(i) + 0.5f) / float(n));
      ASSERT_TRUE(ls);
      first += ls->p_light.x < 2.25f;
    }
    EXPECT_NEAR(first, n / 2, 2);
  }
}

// pbrt-v4 makes one light per bilinear patch: both triangles of a patch share
// its radiance phi / (pi * A_patch), and each patch (not each triangle) emits phi.
TEST(ParserAreaLight, PowerOnABilinearMeshIsPerPatch) {
  // Patch 0: [0,2] x [0,1] (area 2); patch 1: [3,3.5] x [0,0.5] (area 0.25).
  Scene s = parse_scene_string(R"(WorldBegin
    AreaLightSource "diffuse" "float power" 10
    Shape "bilinearmesh" "point3 P" [0 0 0  2 0 0  0 1 0  2 1 0  3 0 0  3.5 0 0  3 0.5 0  3.5 0.5 0]
      "integer indices" [0 1 2 3 4 5 6 7])",
                               "t.pbrt");
  ASSERT_EQ(s.lights.size(), 1u);
  ASSERT_EQ(s.lights[0].triangle_scale.size(), 4u);
  Lit lit(std::move(s));
  const vec2 inside[2][2] = {{vec2(1.5f, 0.2f), vec2(0.5f, 0.8f)}, {vec2(3.4f, 0.1f), vec2(3.1f, 0.4f)}};
  const float area[2] = {2.0f, 0.25f};
  for (int k = 0; k < 2; ++k)
    for (const vec2& p : inside[k])
      EXPECT_NEAR(luminance(lit.radiance_at(p.x, p.y)) / (10.0f / (kPi * area[k])), 1.0f, 1e-5f)
          << "patch " << k << " at " << p.x << " " << p.y;
  EXPECT_NEAR(light_power(*lit.lights, 0) / (2.0f * 10.0f), 1.0f, 1e-5f);
}

TEST(ParserAreaLight, PowerOnEqualTrianglesKeepsOneRadiance) {
  Scene s = parse_scene_string(quad_scene("WorldBegin\nAreaLightSource \"diffuse\" \"float power\" 6\n"), "t.pbrt");
  ASSERT_EQ(s.lights.size(), 1u);
  EXPECT_TRUE(s.lights[0].triangle_scale.empty());
  EXPECT_NEAR(luminance(s.lights[0].L), 6.0f / (kPi * 0.5f), 1e-4f);
}

TEST(ParserAreaLight, FilenameErrorsNameFileAndLine) {
  auto error_of = [](const std::string& text, const std::string& base_dir) {
    try {
      parse_scene_string(text, "test.pbrt", base_dir);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  test::TempDir dir;
  std::string img = write_rgb_exr(dir, "e.exr", 2, 2, four_colours);
  std::string both = error_of("WorldBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"string filename\" \"e.exr\"\n",
                              dir.path.string());
  EXPECT_NE(both.find("test.pbrt:2:1: error:"), std::string::npos) << both;
  EXPECT_NE(both.find("expected one of them"), std::string::npos) << both;
  std::string missing =
      error_of("WorldBegin\nAreaLightSource \"diffuse\" \"string filename\" \"nope.exr\"\n", dir.path.string());
  EXPECT_NE(missing.find("test.pbrt:2:"), std::string::npos) << missing;
  EXPECT_NE(missing.find("not found, expected an existing file"), std::string::npos) << missing;
  EXPECT_EQ(error_of("WorldBegin\nAreaLightSource \"diffuse\" \"string filename\" \"e.exr\"\n", dir.path.string()),
            "no error");
}

// The image's texel at the surface's uv, v flipped (uv (0, 1) is the image's
// top-left), times "scale": at texel centres the bilinear lookup is the texel.
TEST(AreaEmission, ImageIsLookedUpAtTheHitsUvWithVFlipped) {
  test::TempDir dir;
  write_rgb_exr(dir, "e.exr", 2, 2, four_colours);
  Lit lit(parse_scene_string(quad_scene("WorldBegin\nAreaLightSource \"diffuse\" \"string filename\" \"e.exr\" "
                                         "\"float scale\" 3\n"),
                             dir.file("t.pbrt"), dir.path.string()));
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 2; ++x) {
      // Texel (x, y) has its centre at u = (x + 0.5) / 2, v = 1 - (y + 0.5) / 2.
      RGB L = lit.radiance_at((float(x) + 0.5f) / 2.0f, 1.0f - (float(y) + 0.5f) / 2.0f);
      RGB want = 3.0f * srgb_to_working(four_colours(x, y));
      EXPECT_NEAR(glm::length(L - want), 0.0f, 1e-4f * glm::length(want)) << x << " " << y;
    }
  // Light sampling returns the same radiance as the ray finds at the sampled point.
  LightSampleContext ctx{vec3(0.5f, 0.5f, 2.0f)};
  int n = 0;
  for (int i = 0; i < 64; ++i) {
    auto ls = sample_li(*lit.lights, 0, ctx, vec2((float(i % 8) + 0.5f) / 8.0f, (float(i / 8) + 0.5f) / 8.0f),
                        (float(i) + 0.5f) / 64.0f);
    ASSERT_TRUE(ls);
    RGB at_hit = lit.radiance_at(ls->p_light.x, ls->p_light.y);
    EXPECT_NEAR(glm::length(ls->L - at_hit), 0.0f, 1e-3f * glm::length(at_hit));
    ++n;
  }
  EXPECT_EQ(n, 64);
}

// With "power", pbrt-v4 divides by k_e, the image's mean luminance over its
// pixels, so that a uniform image emits exactly the power; light_power is the
// emission integrated over the surface (here by brute force).
TEST(AreaEmission, ImagePowerNormalisesByMeanLuminanceAndLightPowerIsTheIntegral) {
  test::TempDir dir;
  write_rgb_exr(dir, "e.exr", 2, 2, four_colours);
  const float phi = 5.0f;
  Lit lit(parse_scene_string(quad_scene("WorldBegin\nAreaLightSource \"diffuse\" \"string filename\" \"e.exr\" "
                                         "\"float power\" 5\n"),
                             dir.file("t.pbrt"), dir.path.string()));
  double k_e = 0.0;
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 2; ++x) k_e += luminance(srgb_to_working(four_colours(x, y))) / 4.0;
  // Each triangle (area 1/2) is a light of power phi: radiance phi / (pi A k_e) * texel.
  RGB L = lit.radiance_at(0.75f, 0.25f);  // texel (1, 1)
  RGB want = srgb_to_working(four_colours(1, 1)) * float(phi / (kPi * 0.5 * k_e));
  EXPECT_NEAR(glm::length(L - want), 0.0f, 1e-4f * glm::length(want));
  // Power: pi * integral of luminance over the quad, by a fine midpoint rule.
  const int n = 512;
  double integral = 0.0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      float x = (float(i) + 0.5f) / float(n), y = (float(j) + 0.5f) / float(n);
      integral += luminance(lit.radiance_at(x, y)) / double(n * n);
    }
  EXPECT_NEAR(light_power(*lit.lights, 0) / (kPi * integral), 1.0, 1e-3);
  // And that is 2 phi up to how far the triangles' means differ from the pixels' mean.
  EXPECT_NEAR(light_power(*lit.lights, 0) / (2.0f * phi), 1.0f, 0.05f);
}

// pbrt-v4's AlphaMasked: light samples on points where alpha is 0 carry no
// emission; where alpha is 1 they do.  A constant alpha of 0 is pbrt-v4's
// invisible area light: never hit, fully emissive, sampled without MIS.
TEST(AreaEmission, AlphaMasksSampledEmission) {
  Lit lit(parse_scene_string(quad_scene(R"(WorldBegin
Texture "a" "float" "checkerboard" "float uscale" 2 "float vscale" 2 "float tex1" 1 "float tex2" 0
AreaLightSource "diffuse" "rgb L" [1 1 1]
)",
                                        " \"texture alpha\" \"a\""),
                             "t.pbrt"));
  LightSampleContext ctx{vec3(0.5f, 0.5f, 2.0f)};
  int emitting = 0;
  const int n = 1024;
  for (int i = 0; i < n; ++i) {
    vec2 u((float(i % 32) + 0.5f) / 32.0f, (float(i / 32) + 0.5f) / 32.0f);
    auto ls = sample_li(*lit.lights, 0, ctx, u, float(i % 7) / 7.0f);
    if (!ls) continue;
    ++emitting;
    // The checkerboard's tex1 (alpha 1) squares: floor(2u) + floor(2v) even.
    vec2 uv(ls->p_light.x, ls->p_light.y);
    EXPECT_EQ((int(std::floor(2.0f * uv.x)) + int(std::floor(2.0f * uv.y))) % 2, 0) << uv.x << " " << uv.y;
    EXPECT_FALSE(ls->is_delta);
  }
  EXPECT_NEAR(double(emitting) / n, 0.5, 0.05);

  Lit invisible(parse_scene_string(quad_scene("WorldBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n",
                                              " \"float alpha\" 0"),
                                   "t.pbrt"));
  Ray down{vec3(0.5f, 0.5f, 1.0f), 0.0f, vec3(0, 0, -1), kInfinity};
  EXPECT_FALSE(invisible.accel->intersect1(down).hit());
  auto ls = sample_li(*invisible.lights, 0, ctx, vec2(0.3f, 0.6f), 0.2f);
  ASSERT_TRUE(ls);
  EXPECT_TRUE(ls->is_delta);
  EXPECT_NEAR(luminance(ls->L), 1.0f, 1e-5f);
}

// The same on a disk: the mask is looked up at pbrt-v4's disk (u, v) =
// (phi / phimax, (rmax - r) / (rmax - rmin)), so sampled emission follows
// the checkerboard in those coordinates.
TEST(AreaEmission, AlphaMasksSampledEmissionOnADisk) {
  Lit lit(parse_scene_string(R"(WorldBegin
Texture "a" "float" "checkerboard" "float uscale" 2 "float vscale" 2 "float tex1" 1 "float tex2" 0
AreaLightSource "diffuse" "rgb L" [1 1 1]
Shape "disk" "float radius" 1 "texture alpha" "a")",
                             "t.pbrt"));
  LightSampleContext ctx{vec3(0.0f, 0.0f, 2.0f)};
  int emitting = 0, masked = 0;
  const int n = 1024;
  for (int i = 0; i < n; ++i) {
    vec2 u((float(i % 32) + 0.5f) / 32.0f, (float(i / 32) + 0.5f) / 32.0f);
    auto ls = sample_li(*lit.lights, 0, ctx, u, 0.5f);
    if (!ls) {
      ++masked;
      continue;
    }
    ++emitting;
    float phi = std::atan2(ls->p_light.y, ls->p_light.x);
    if (phi < 0.0f) phi += 2.0f * kPi;
    vec2 uv(phi / (2.0f * kPi), 1.0f - glm::length(vec2(ls->p_light)));
    EXPECT_EQ((int(std::floor(2.0f * uv.x)) + int(std::floor(2.0f * uv.y))) % 2, 0) << uv.x << " " << uv.y;
  }
  // By area: alpha is 1 on half of the outer ring (r > 1/2, 3/8 of the disk)
  // and the other half of the inner disk (1/8).
  EXPECT_NEAR(double(emitting) / n, 0.5, 0.05);
  EXPECT_GT(masked, 0);
}

// light_faces_away, the shortcut next-event estimation takes before drawing a
// point on a light, against sample_li itself: wherever it calls a point
// behind a light, no sample from there reaches it, and on the one-sided
// planar lights it does call the points clearly behind them.  Light 0 is a
// tilted quad, 1 the same reversed, 2 two-sided, 3 a quad folded along its
// diagonal, 4 a planar quad whose vertex normals point against its winding
// (so it emits the other way).
TEST(AreaEmission, LightFacesAwayOnlyWhereEverySampleIsRefused) {
  Lit lit(parse_scene_string(R"(WorldBegin
AttributeBegin
  Translate 0 1 0
  Rotate 30 1 0.5 0
  AreaLightSource "diffuse" "rgb L" [1 1 1]
  Shape "trianglemesh" "point3 P" [-1 0 -1  1 0 -1  1 0 1  -1 0 1] "integer indices" [0 1 2 0 2 3]
AttributeEnd
AttributeBegin
  Translate 0 1 0
  Rotate 30 1 0.5 0
  ReverseOrientation
  AreaLightSource "diffuse" "rgb L" [1 1 1]
  Shape "trianglemesh" "point3 P" [-1 0 -1  1 0 -1  1 0 1  -1 0 1] "integer indices" [0 1 2 0 2 3]
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [1 1 1] "bool twosided" true
  Shape "trianglemesh" "point3 P" [-1 0 -1  1 0 -1  1 0 1  -1 0 1] "integer indices" [0 1 2 0 2 3]
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [1 1 1]
  Shape "trianglemesh" "point3 P" [-1 0 -1  1 0 -1  1 0.5 1  -1 0 1] "integer indices" [0 1 2 0 2 3]
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [1 1 1]
  Shape "trianglemesh" "point3 P" [-1 0 -1  1 0 -1  1 0 1  -1 0 1] "integer indices" [0 1 2 0 2 3]
      "normal N" [0 1 0  0 1 0  0 1 0  0 1 0]
AttributeEnd
)",
                             "t.pbrt"));
  ASSERT_EQ(lit.scene.lights.size(), 5u);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> box(-3.0f, 3.0f), unit(0.0f, 1.0f);
  int away[5] = {}, behind_0[2][2] = {};  // behind_0[side of the plane][light 0 behind]
  for (int k = 0; k < 4000; ++k) {
    const vec3 p(box(rng), box(rng), box(rng));
    for (int light = 0; light < 5; ++light) {
      if (!light_faces_away(*lit.lights, light, p)) continue;
      ++away[light];
      for (int i = 0; i < 64; ++i)
        EXPECT_FALSE(sample_li(*lit.lights, light, LightSampleContext{p}, vec2(unit(rng), unit(rng)), unit(rng)))
            << "light " << light << " at " << p.x << " " << p.y << " " << p.z;
    }
    // Lights 0 and 1 share one plane (from the parser's transform) and emit
    // to opposite sides: off the plane, exactly one of them is behind p.
    const mat4 m = glm::rotate(glm::translate(mat4(1.0f), vec3(0, 1, 0)), glm::radians(30.0f), vec3(1, 0.5f, 0));
    const vec3 normal = glm::normalize(vec3(m * vec4(0, 1, 0, 0)));
    const float height = glm::dot(normal, p - vec3(0, 1, 0));
    if (std::abs(height) > 0.01f) {
      const bool a0 = light_faces_away(*lit.lights, 0, p), a1 = light_faces_away(*lit.lights, 1, p);
      EXPECT_NE(a0, a1) << "height " << height;
      ++behind_0[height > 0.0f ? 1 : 0][a0 ? 1 : 0];
    }
  }
  // Light 0 is behind every point on one side of the plane and none on the other.
  EXPECT_TRUE((behind_0[0][1] == 0 && behind_0[1][0] == 0) || (behind_0[0][0] == 0 && behind_0[1][1] == 0));
  EXPECT_GT(away[0], 1000);
  EXPECT_GT(away[1], 1000);
  EXPECT_EQ(away[2], 0);  // two-sided
  EXPECT_EQ(away[3], 0);  // not planar
  EXPECT_EQ(away[4], 0);  // its normals decide its side: not taken as planar
}
