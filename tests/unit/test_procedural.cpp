// pbrt-v4's texture mappings, Perlin noise and procedural textures
// (scene/texture.h, scene/noise.h, scene/texture_params.h).
#include "core/color.h"
#include "core/log.h"
#include "scene/noise.h"
#include "scene/parser.h"
#include "scene/texture.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

namespace theia {
namespace {

Scene parse(const std::string& text) { return parse_scene_string("WorldBegin\n" + text, "test.pbrt", "."); }

const Texture& named(const Scene& s, const std::string& name) {
  for (const Texture& t : s.textures)
    if (t.name == name) return t;
  throw std::runtime_error("no texture " + name);
}
int index_of(const Scene& s, const std::string& name) { return int(&named(s, name) - s.textures.data()); }

std::string error_of(const std::string& text) {
  try {
    parse(text);
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

TextureEvalContext at_p(vec3 p, vec3 n = vec3(0.0f)) { return {vec2(0.0f), p, {}, n}; }

void expect_st(vec2 st, vec2 expected, const std::string& what) {
  EXPECT_NEAR(st.x, expected.x, 1e-5f) << what;
  EXPECT_NEAR(st.y, expected.y, 1e-5f) << what;
}

// ---------------------------------------------------------------- mappings

TEST(TextureMapping, SphericalCylindricalAndPlanarMapKnownPoints) {
  Texture t;
  t.mapping_kind = TextureMappingKind::Spherical;
  // s = theta / pi from +z, t = phi / 2 pi from +x towards +y.
  expect_st(map_texture_2d(t, at_p({1, 0, 0})).st, {0.5f, 0.0f}, "equator, phi = 0");
  expect_st(map_texture_2d(t, at_p({0, 3, 0})).st, {0.5f, 0.25f}, "equator, phi = pi/2 (any radius)");
  expect_st(map_texture_2d(t, at_p({0, -1, 0})).st, {0.5f, 0.75f}, "equator, phi = 3 pi/2");
  expect_st(map_texture_2d(t, at_p({0, 0, 2})).st, {0.0f, 0.0f}, "north pole");
  expect_st(map_texture_2d(t, at_p({1, 0, -1})).st, {0.75f, 0.0f}, "45 degrees below the equator");
  vec2 centre = map_texture_2d(t, at_p({0, 0, 0})).st;
  EXPECT_TRUE(std::isfinite(centre.x) && std::isfinite(centre.y)) << "the centre has no direction";

  t.mapping_kind = TextureMappingKind::Cylindrical;
  // s = (pi + phi) / 2 pi, t = z.
  expect_st(map_texture_2d(t, at_p({1, 0, 0.3f})).st, {0.5f, 0.3f}, "cylinder, phi = 0");
  expect_st(map_texture_2d(t, at_p({0, 2, -1})).st, {0.75f, -1.0f}, "cylinder, phi = pi/2");
  expect_st(map_texture_2d(t, at_p({0, -1, 4})).st, {0.25f, 4.0f}, "cylinder, phi = -pi/2");

  t.mapping_kind = TextureMappingKind::Planar;
  t.planar_s = {1, 1, 0};
  t.planar_t = {0, 0, 2};
  t.mapping.du = 0.5f;
  t.mapping.dv = -1.0f;
  // s = udelta + p . v1, t = vdelta + p . v2.
  expect_st(map_texture_2d(t, at_p({1, 2, 3})).st, {3.5f, 5.0f}, "planar");
  t.mapping.su = 7.0f;  // uscale is the uv mapping's only
  expect_st(map_texture_2d(t, at_p({1, 2, 3})).st, {3.5f, 5.0f}, "planar ignores uscale");
  // Only uv has a footprint (theia has no dp/dx).
  TextureEvalContext ctx = at_p({1, 2, 3});
  ctx.fp = {0.1f, 0.2f, 0.3f, 0.4f};
  EXPECT_EQ(map_texture_2d(t, ctx).dst0, vec2(0.0f));
  t.mapping_kind = TextureMappingKind::UV;
  t.mapping = {2.0f, 3.0f, 0.5f, 0.25f};
  ctx.uv = {0.25f, 0.5f};
  TexCoord2D uv = map_texture_2d(t, ctx);
  expect_st(uv.st, {1.0f, 1.75f}, "uv");
  expect_st(uv.dst0, {0.2f, 0.9f}, "uv d/dx");
  expect_st(uv.dst1, {0.4f, 1.2f}, "uv d/dy");
}

TEST(TextureMapping, TheTexturesCTMIsItsObjectSpace) {
  // p_render = T(0, 0, 5) S(2) p_texture: render (2, 0, 5) is texture (1, 0, 0).
  Scene s = parse(R"(AttributeBegin
Translate 0 0 5
Scale 2 2 2
Texture "sph" "float" "bilerp" "string mapping" "spherical"
Texture "cyl" "float" "bilerp" "string mapping" "cylindrical"
Texture "pl" "float" "bilerp" "string mapping" "planar" "vector3 v1" [0 1 0] "vector3 v2" [0 0 1] "float udelta" 1 "float vdelta" 2
Texture "uv" "float" "bilerp" "float uscale" 2
AttributeEnd
Rotate 90 0 0 1
Texture "rot" "float" "bilerp" "string mapping" "spherical")");
  expect_st(map_texture_2d(named(s, "sph"), at_p({2, 0, 5})).st, {0.5f, 0.0f}, "spherical through the CTM");
  expect_st(map_texture_2d(named(s, "sph"), at_p({0, 0, 7})).st, {0.0f, 0.0f}, "pole through the CTM");
  expect_st(map_texture_2d(named(s, "cyl"), at_p({0, 2, 6})).st, {0.75f, 0.5f}, "cylindrical through the CTM");
  // Texture space (1, 3, -1): s = 1 + 3, t = 2 - 1.
  expect_st(map_texture_2d(named(s, "pl"), at_p({2, 6, 3})).st, {4.0f, 1.0f}, "planar through the CTM");
  // uv ignores the CTM.
  TextureEvalContext ctx = at_p({9, 9, 9});
  ctx.uv = {0.25f, 0.5f};
  expect_st(map_texture_2d(named(s, "uv"), ctx).st, {0.5f, 0.5f}, "uv");
  // Rotated 90 degrees about z: render (-1, 1, 0) is texture (1, 1, 0), phi = pi/4
  // (off the seam at phi = 0, where rounding may give t = 1 for 0).
  expect_st(map_texture_2d(named(s, "rot"), at_p({-1, 1, 0})).st, {0.5f, 0.125f}, "rotation");
}

// ---------------------------------------------------------------- noise

TEST(TextureNoise, ZeroAtTheLatticeAndHandComputedValues) {
  for (int x = -3; x <= 3; ++x)
    for (int y = -3; y <= 3; ++y)
      for (int z : {-300, -1, 0, 2, 255, 256, 100000}) EXPECT_EQ(perlin_noise(float(x), float(y), float(z)), 0.0f);
  // At a cell centre every fade weight is 1/2: the mean of the 8 corner
  // gradients dotted with (+-1/2, +-1/2, +-1/2).  Hash h = perm[perm[perm[x] + y] + z] & 15
  // from Perlin's table, e.g. corner (0,0,0): perm[0] = 151, perm[151] = 17,
  // perm[17] = 36, h = 4: u = dx, v = dz, -v: 1/2 + 1/2 = 1.  The eight corners
  // (000, 100, 010, 110, 001, 101, 011, 111) have h = 4, 6, 12, 0, 7, 4, 14, 3 and
  // give 1, -1, 0, -1, 0, -1, 0, 1: noise = -1/8.
  EXPECT_FLOAT_EQ(perlin_noise(0.5f, 0.5f, 0.5f), -0.125f);
  EXPECT_FLOAT_EQ(perlin_noise(0.5f), -0.125f);  // y, z default to 1/2
  // From an independent transcription of pbrt-v4's Noise (double precision).
  EXPECT_NEAR(perlin_noise(10.5f, 0.5f, 0.5f), -0.25f, 1e-6f);
  EXPECT_NEAR(perlin_noise(1.25f, 2.5f, 0.75f), 0.47278166f, 1e-5f);
  EXPECT_NEAR(perlin_noise(-3.3f, 0.1f, 7.9f), 0.43800442f, 1e-5f);
  // Deterministic, and periodic in 256 as the table is.
  EXPECT_EQ(perlin_noise(-3.3f, 0.1f, 7.9f), perlin_noise(-3.3f, 0.1f, 7.9f));
  EXPECT_NEAR(perlin_noise(0.25f, 0.75f, 0.5f), perlin_noise(256.25f, 0.75f, 0.5f), 1e-5f);
}

TEST(TextureNoise, BoundedContinuousAndFiniteEverywhere) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-100.0f, 100.0f);
  float max_abs = 0.0f;
  for (int i = 0; i < 200000; ++i) max_abs = std::max(max_abs, std::abs(perlin_noise(u(rng), u(rng), u(rng))));
  // Improved Perlin noise stays in about [-1, 1] (measured: 0.995 in 2e5
  // points); the sweep must also come near it, or the gradients are wrong.
  EXPECT_LE(max_abs, 1.05f);
  EXPECT_GE(max_abs, 0.8f);
  // Continuous across cell faces (where the lattice hash changes) and inside
  // cells: the gradient is at most a few units, so a 1e-3 step moves < 1e-2.
  for (int i = 0; i < 2000; ++i) {
    vec3 p(std::round(u(rng)), u(rng), u(rng));  // on an x face
    for (int axis = 0; axis < 3; ++axis) {
      vec3 e(0.0f);
      e[axis] = 1e-3f;
      EXPECT_LT(std::abs(perlin_noise(p + e) - perlin_noise(p - e)), 1e-2f) << p.x << " " << p.y << " " << p.z;
    }
  }
  for (float big : {1e7f, -3e9f, 1e30f, kInfinity, std::nanf("")})
    EXPECT_TRUE(std::isfinite(perlin_noise(big, 0.3f, big))) << big;
}

TEST(TextureNoise, OctaveCountsFollowTheFootprint) {
  vec3 zero(0.0f);
  EXPECT_EQ(noise_octaves(zero, zero, 8), 8.0f);  // no footprint: every octave
  // n = -1 - log2(max |dp|^2) / 2: |dp| = 2^-5 keeps 4 octaves.
  EXPECT_FLOAT_EQ(noise_octaves(vec3(0.03125f, 0, 0), zero, 8), 4.0f);
  EXPECT_FLOAT_EQ(noise_octaves(vec3(0.001f, 0, 0), vec3(0, 0.03125f, 0), 8), 4.0f);  // the larger one counts
  EXPECT_FLOAT_EQ(noise_octaves(vec3(0, std::exp2(-4.5f), 0), zero, 8), 3.5f);
  EXPECT_EQ(noise_octaves(vec3(1, 0, 0), zero, 8), 0.0f);          // -1, clamped
  EXPECT_EQ(noise_octaves(vec3(1e-9f, 0, 0), zero, 8), 8.0f);      // 28.9, clamped
  EXPECT_EQ(noise_octaves(vec3(kInfinity, 0, 0), zero, 8), 0.0f);

  // FBm with 3 whole octaves (the fraction 0 fades the fourth out entirely) and
  // with 3.5 (smoothstep(0.5; 0.3, 0.7) = 1/2 of the fourth).
  vec3 p(0.3f, 0.7f, 1.1f);
  const float omega = 0.6f;
  auto octave = [&](int i) { return std::pow(omega, float(i)) * perlin_noise(std::pow(1.99f, float(i)) * p); };
  vec3 fp3(0.0625f, 0, 0), fp35(std::exp2(-4.5f), 0, 0);
  float sum3 = octave(0) + octave(1) + octave(2);
  EXPECT_NEAR(fbm(p, fp3, zero, omega, 8), sum3, 1e-5f);
  EXPECT_NEAR(fbm(p, fp35, zero, omega, 8), sum3 + 0.5f * octave(3), 1e-5f);
  float all = 0.0f;
  for (int i = 0; i < 8; ++i) all += octave(i);
  EXPECT_NEAR(fbm(p, zero, zero, omega, 8), all, 1e-5f);
  EXPECT_NEAR(fbm(p, zero, zero, 0.5f, 8), -0.36001112f, 1e-5f);  // the independent transcription

  // Turbulence: |noise| for the kept octaves; the dropped ones (3..7) add
  // their mean 0.2 omega^i, and the faded-out fourth its 0.2 at the same weight.
  float abs3 = 0.0f, dropped = 0.0f;
  for (int i = 0; i < 3; ++i) abs3 += std::abs(octave(i));
  for (int i = 3; i < 8; ++i) dropped += 0.2f * std::pow(omega, float(i));
  EXPECT_NEAR(turbulence(p, fp3, zero, omega, 8), abs3 + 0.2f * std::pow(omega, 3.0f) + dropped, 1e-5f);
  float abs8 = 0.0f;
  for (int i = 0; i < 8; ++i) abs8 += std::abs(octave(i));
  EXPECT_NEAR(turbulence(p, zero, zero, omega, 8), abs8 + 0.2f * std::pow(omega, 8.0f), 1e-5f);
}

// ---------------------------------------------------------------- textures

TEST(TextureProcedural, BilerpCornersAndCentre) {
  Scene s = parse(R"(Texture "f" "float" "bilerp" "float v00" 1 "float v01" 2 "float v10" 3 "float v11" 5
Texture "c" "spectrum" "bilerp" "rgb v00" [1 0 0] "rgb v01" [0 1 0] "rgb v10" [0 0 1] "rgb v11" [1 1 1]
Texture "d" "float" "bilerp")");
  int f = index_of(s, "f"), c = index_of(s, "c"), d = index_of(s, "d");
  auto uv = [](float u, float v) { return TextureEvalContext{{u, v}, vec3(0.0f)}; };
  EXPECT_FLOAT_EQ(eval_float_texture(s, f, uv(0, 0)), 1.0f);
  EXPECT_FLOAT_EQ(eval_float_texture(s, f, uv(0, 1)), 2.0f);
  EXPECT_FLOAT_EQ(eval_float_texture(s, f, uv(1, 0)), 3.0f);
  EXPECT_FLOAT_EQ(eval_float_texture(s, f, uv(1, 1)), 5.0f);
  EXPECT_FLOAT_EQ(eval_float_texture(s, f, uv(0.5f, 0.5f)), 2.75f);
  EXPECT_FLOAT_EQ(eval_float_texture(s, f, uv(0.25f, 0)), 1.5f);
  auto near = [](RGB a, RGB b) { return glm::all(glm::lessThan(glm::abs(a - b), RGB(1e-5f))); };
  EXPECT_TRUE(near(eval_texture(s, c, uv(0, 0)), srgb_to_working(RGB(1, 0, 0))));
  EXPECT_TRUE(near(eval_texture(s, c, uv(0, 1)), srgb_to_working(RGB(0, 1, 0))));
  EXPECT_TRUE(near(eval_texture(s, c, uv(1, 0)), srgb_to_working(RGB(0, 0, 1))));
  EXPECT_TRUE(near(eval_texture(s, c, uv(1, 1)), RGB(1.0f)));
  // pbrt-v4's defaults: v00 = v10 = 0, v01 = v11 = 1, so the value is t.
  EXPECT_FLOAT_EQ(eval_float_texture(s, d, uv(0.3f, 0.7f)), 0.7f);
}

TEST(TextureProcedural, Checkerboard3DParityAndFiltered2DEdges) {
  Scene s = parse(R"(Scale 0.5 0.5 0.5
Texture "c3" "float" "checkerboard" "integer dimension" 3 "float tex1" 0.25 "float tex2" 0.75
Texture "c2" "float" "checkerboard" "float tex1" 0.25 "float tex2" 0.75)");
  int c3 = index_of(s, "c3"), c2 = index_of(s, "c2");
  // Texture space is twice render space: cells of side 1/2 in render space.
  auto check3 = [&](vec3 texture_p) { return eval_float_texture(s, c3, at_p(0.5f * texture_p)); };
  EXPECT_EQ(check3({0.5f, 0.5f, 0.5f}), 0.25f);   // 0 + 0 + 0: even
  EXPECT_EQ(check3({1.5f, 0.5f, 0.5f}), 0.75f);   // odd
  EXPECT_EQ(check3({1.5f, 1.5f, 0.5f}), 0.25f);   // even
  EXPECT_EQ(check3({1.5f, 1.5f, 2.5f}), 0.25f);   // 1 + 1 + 2: even
  EXPECT_EQ(check3({-0.5f, 0.5f, 0.5f}), 0.75f);  // -1: odd
  EXPECT_EQ(check3({-0.5f, -0.5f, -0.5f}), 0.75f);
  EXPECT_EQ(check3({7.5f, 4.5f, 0.5f}), 0.75f);

  // 2D with a footprint: pbrt-v4's triangle-filtered checks.  Inside a cell
  // wider than the filter nothing changes; straddling an edge symmetrically
  // gives the average; a huge footprint averages everything to 1/2.
  auto check2 = [&](vec2 uv, float d) { return eval_float_texture(s, c2, {uv, vec3(0.0f), {d, 0.0f, 0.0f, d}}); };
  EXPECT_EQ(check2({0.5f, 0.5f}, 0.0f), 0.25f);
  EXPECT_EQ(check2({0.5f, 0.5f}, 0.2f), 0.25f);   // filter half-width 0.3 stays inside
  EXPECT_EQ(check2({1.5f, 0.5f}, 0.2f), 0.75f);
  EXPECT_NEAR(check2({1.0f, 0.5f}, 0.2f), 0.5f, 1e-6f);
  // At 0.9 the triangle of half-width r = 0.3 puts m = (r - 0.1)^2 / (2 r^2)
  // of its weight past the edge at 1: weight of tex2 = m.
  const float m = 0.2f * 0.2f / (2.0f * 0.3f * 0.3f);
  EXPECT_NEAR(check2({0.9f, 0.5f}, 0.2f), 0.25f + 0.5f * m, 1e-5f);
  EXPECT_NEAR(check2({0.3f, 0.4f}, 100.0f), 0.5f, 1e-3f);
  // Between the extremes it moves monotonically across an edge.
  float prev = 0.0f;
  for (float x = 0.6f; x <= 1.4f; x += 0.05f) {
    float v = check2({x, 0.5f}, 0.2f);
    EXPECT_GE(v, prev - 1e-6f) << x;
    prev = v;
  }
}

TEST(TextureProcedural, DotsInsideAndOutside) {
  // A dot of radius 0.35 sits within 0.15 (max shift) of a cell's centre,
  // so a cell with a dot has its centre inside and its corners outside, and
  // about half the cells have one.
  int dots = 0, cells = 0;
  for (int i = -20; i < 20; ++i)
    for (int j = -20; j < 20; ++j) {
      const vec2 c{float(i), float(j)};
      ++cells;
      bool has_dot = perlin_noise(c.x + 0.5f, c.y + 0.5f) > 0.0f;
      dots += has_dot;
      EXPECT_EQ(inside_polka_dot(c), has_dot) << i << " " << j;
      for (vec2 corner : {vec2(0.49f, 0.49f), vec2(-0.49f, 0.49f), vec2(0.49f, -0.49f), vec2(-0.49f, -0.49f)})
        EXPECT_FALSE(inside_polka_dot(c + corner)) << i << " " << j;
      if (!has_dot) {
        for (float dx = -0.4f; dx <= 0.4f; dx += 0.1f) EXPECT_FALSE(inside_polka_dot(c + vec2(dx, -dx)));
      }
    }
  EXPECT_GT(dots, cells / 4);
  EXPECT_LT(dots, 3 * cells / 4);

  // Cell (0, 1) has a dot (noise(0.5, 1.5, 0.5) = 1/4), cell (0, 0) has none
  // (noise(0.5, 0.5, 0.5) = -1/8).
  ASSERT_GT(perlin_noise(0.5f, 1.5f), 0.0f);
  Scene s = parse(R"(Texture "d" "float" "dots" "float inside" 0.9 "float outside" 0.2 "float uscale" 2)");
  int d = index_of(s, "d");
  auto eval_uv = [&](float u, float v) { return eval_float_texture(s, d, {{u, v}, vec3(0.0f)}); };
  // As pbrt-v4 renders it (its DotsTexture::Create swaps the two): "outside"
  // in the dots, "inside" around them.
  EXPECT_EQ(eval_uv(0.0f, 1.0f), 0.2f);     // st (0, 1): the dot's cell centre
  EXPECT_EQ(eval_uv(0.0f, 0.0f), 0.9f);     // st (0, 0): no dot
  EXPECT_EQ(eval_uv(0.245f, 1.49f), 0.9f);  // st (0.49, 1.49): the dotted cell's corner
}

TEST(TextureProcedural, NoiseTexturesAreFiniteAndBoundedOverASweep) {
  Scene s = parse(R"(Scale 0.3 0.3 0.3
Texture "fbm" "float" "fbm" "integer octaves" 6 "float roughness" 0.7
Texture "wr" "float" "wrinkled"
Texture "wi" "float" "windy"
Texture "ma" "spectrum" "marble" "float scale" 2 "float variation" 0.5)");
  int fb = index_of(s, "fbm"), wr = index_of(s, "wr"), wi = index_of(s, "wi"), ma = index_of(s, "ma");
  // |noise| < 1.05 (TextureNoise.BoundedContinuousAndFiniteEverywhere), so
  // |fbm| < 1.05 sum omega^i; turbulence adds 0.2 omega^8 at most;
  // windy is |fbm(3 octaves)| * fbm(6 octaves), each with omega = 1/2.
  auto geometric = [](float omega, int n) { return (1.0f - std::pow(omega, float(n))) / (1.0f - omega); };
  const float b = 1.05f;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-50.0f, 50.0f);
  float fbm_min = 0, fbm_max = 0, wr_min = 10, wr_max = 0;
  for (int i = 0; i < 20000; ++i) {
    vec3 p(u(rng), u(rng), u(rng));
    if (i % 1000 == 0) p *= 1e6f;  // far away too
    float f = eval_float_texture(s, fb, at_p(p)), w = eval_float_texture(s, wr, at_p(p));
    float wind = eval_float_texture(s, wi, at_p(p));
    RGB m = working_to_srgb(eval_texture(s, ma, at_p(p)));
    ASSERT_TRUE(std::isfinite(f) && std::isfinite(w) && std::isfinite(wind));
    ASSERT_TRUE(std::isfinite(m.x + m.y + m.z));
    EXPECT_LE(std::abs(f), b * geometric(0.7f, 6));
    EXPECT_GE(w, 0.0f);
    EXPECT_LE(w, b * geometric(0.5f, 8) + 0.2f * std::pow(0.5f, 8.0f));
    EXPECT_LE(std::abs(wind), b * geometric(0.5f, 3) * b * geometric(0.5f, 6));
    // The marble spline's control points are between 0.2 and 0.6 (sRGB), times 1.5.
    for (int c = 0; c < 3; ++c) {
      EXPECT_GE(m[c], 0.3f - 1e-4f);
      EXPECT_LE(m[c], 0.9f + 1e-4f);
    }
    fbm_min = std::min(fbm_min, f);
    fbm_max = std::max(fbm_max, f);
    wr_min = std::min(wr_min, w);
    wr_max = std::max(wr_max, w);
  }
  // Not degenerate: they vary.
  EXPECT_LT(fbm_min, -0.3f);
  EXPECT_GT(fbm_max, 0.3f);
  EXPECT_GT(wr_max - wr_min, 0.3f);
  // The texture's CTM: fbm at render p is FBm at texture p = p / 0.3.
  vec3 p(0.4f, -1.2f, 2.0f);
  EXPECT_NEAR(eval_float_texture(s, fb, at_p(p)), fbm(p / 0.3f, vec3(0.0f), vec3(0.0f), 0.7f, 6), 1e-5f);
}

TEST(TextureProcedural, DirectionMixWeightsByTheNormal) {
  // dir (0, 1, 0) rotated 90 degrees about x: render +z.
  Scene s = parse(R"(Rotate 90 1 0 0
Texture "dm" "float" "directionmix" "float tex1" 0.8 "float tex2" 0.2 "vector3 dir" [0 1 0]
Texture "dflt" "float" "directionmix")");
  const Texture& t = named(s, "dm");
  EXPECT_NEAR(t.dir.z, 1.0f, 1e-6f);
  int dm = index_of(s, "dm"), dflt = index_of(s, "dflt");
  EXPECT_NEAR(eval_float_texture(s, dm, at_p(vec3(0.0f), {0, 0, 1})), 0.8f, 1e-6f);   // along dir: tex1
  EXPECT_NEAR(eval_float_texture(s, dm, at_p(vec3(0.0f), {0, 0, -1})), 0.8f, 1e-6f);  // either side
  EXPECT_NEAR(eval_float_texture(s, dm, at_p(vec3(0.0f), {1, 0, 0})), 0.2f, 1e-6f);   // perpendicular: tex2
  // |cos 60 degrees| = 1/2: halfway.
  vec3 n60(std::sin(kPi / 3), 0.0f, std::cos(kPi / 3));
  EXPECT_NEAR(eval_float_texture(s, dm, at_p(vec3(0.0f), n60)), 0.5f, 1e-6f);
  // Defaults tex1 = 0, tex2 = 1, dir = +y (turned to +z by the same CTM).
  vec3 ny = glm::normalize(vec3(0, 1, 1));
  EXPECT_NEAR(eval_float_texture(s, dflt, at_p(vec3(0.0f), ny)), 1.0f - std::sqrt(0.5f), 1e-5f);
}

// ---------------------------------------------------------------- parsing

TEST(TextureParams, EveryClassParsesWithoutWarnings) {
  int before = warning_count();
  Scene s = parse(R"(Texture "a" "float" "fbm" "integer octaves" 4 "float roughness" 0.4
Texture "b" "float" "wrinkled" "integer octaves" 3
Texture "c" "float" "windy"
Texture "d" "spectrum" "marble" "integer octaves" 5 "float roughness" 0.6 "float scale" 3 "float variation" 0.1
Texture "e" "spectrum" "dots" "rgb inside" [1 0 0] "rgb outside" [0 0 1] "string mapping" "cylindrical"
Texture "f" "spectrum" "checkerboard" "integer dimension" 3 "texture tex1" "d"
Texture "g" "float" "bilerp" "string mapping" "planar" "vector3 v1" [0 0 1] "float udelta" 3
Texture "h" "spectrum" "directionmix" "texture tex1" "e" "texture tex2" "f" "vector3 dir" [1 0 0]
Texture "k" "float" "scale" "texture tex" "a" "float scale" 2)");
  EXPECT_EQ(warning_count() - before, 0);
  EXPECT_EQ(named(s, "a").kind, TextureKind::FBm);
  EXPECT_EQ(named(s, "a").octaves, 4);
  EXPECT_FLOAT_EQ(named(s, "a").roughness, 0.4f);
  EXPECT_EQ(named(s, "a").mapping_kind, TextureMappingKind::Point3D);
  EXPECT_EQ(named(s, "b").kind, TextureKind::Wrinkled);
  EXPECT_FLOAT_EQ(named(s, "b").roughness, 0.5f);
  EXPECT_EQ(named(s, "c").kind, TextureKind::Windy);
  const Texture& d = named(s, "d");
  EXPECT_EQ(d.kind, TextureKind::Marble);
  EXPECT_EQ(d.octaves, 5);
  EXPECT_FLOAT_EQ(d.marble_scale, 3.0f);
  EXPECT_FLOAT_EQ(d.variation, 0.1f);
  EXPECT_EQ(named(s, "e").kind, TextureKind::Dots);
  EXPECT_EQ(named(s, "e").mapping_kind, TextureMappingKind::Cylindrical);
  EXPECT_EQ(named(s, "f").mapping_kind, TextureMappingKind::Point3D);
  EXPECT_EQ(named(s, "f").tex1, index_of(s, "d"));
  EXPECT_EQ(named(s, "g").planar_s, vec3(0, 0, 1));
  EXPECT_EQ(named(s, "g").planar_t, vec3(0, 1, 0));
  EXPECT_FLOAT_EQ(named(s, "g").mapping.du, 3.0f);
  EXPECT_EQ(named(s, "h").dir, vec3(1, 0, 0));

  // Parameters a class or mapping does not read are reported, as pbrt-v4 does.
  before = warning_count();
  parse(R"(Texture "s" "float" "bilerp" "string mapping" "spherical" "float uscale" 2
Texture "m" "float" "mix" "string mapping" "uv")");
  EXPECT_EQ(warning_count() - before, 2);
  // ptex keeps its warning and a constant 0.5.
  before = warning_count();
  Scene p = parse(R"(Texture "p" "float" "ptex" "string filename" "x.ptx")");
  EXPECT_EQ(warning_count() - before, 1);
  EXPECT_EQ(named(p, "p").value, RGB(0.5f));
}

TEST(TextureParams, BadInputIsAnErrorWithItsLocation) {
  auto expect_error = [](const std::string& text, const std::string& what) {
    std::string e = error_of(text);
    EXPECT_NE(e.find("test.pbrt:2:1"), std::string::npos) << e;
    EXPECT_NE(e.find("expected"), std::string::npos) << e;
    EXPECT_NE(e.find(what), std::string::npos) << e;
  };
  expect_error(R"(Texture "f" "spectrum" "fbm")", "\"fbm\"");
  expect_error(R"(Texture "f" "spectrum" "windy")", "\"windy\"");
  expect_error(R"(Texture "m" "float" "marble")", "\"marble\"");
  expect_error(R"(Texture "c" "float" "checkerboard" "integer dimension" 4)", "dimension 4");
  expect_error(R"(Texture "c" "float" "checkerboard" "string mapping" "cubic")", "\"cubic\"");
  expect_error(R"(Texture "w" "float" "wrinkled" "integer octaves" -1)", "octaves -1");
  expect_error(R"(Texture "w" "float" "fbm" "integer octaves" 1000000)", "octaves 1000000");
  expect_error(R"(Texture "d" "float" "directionmix" "vector3 dir" [0 0 0])", "dir");
}

}  // namespace
}  // namespace theia
