// Lights against their own pdfs and against closed forms: the sphere
// parameterisations of environment maps, environment-map sampling (both
// parameterisations, both distributions) by chi-square, importance sampling
// against uniform sampling, spot and distant lights, light power; and alpha
// cut-outs in the accel; goniometric and projection lights (intensity along
// known directions, their frustum and orientation, "power", bad input).
#include "checkpoint/fingerprint.h"
#include "core/color.h"
#include "core/image.h"
#include "core/log.h"
#include "core/sampling.h"
#include "scene/accel.h"
#include "scene/lights.h"
#include "scene/parser.h"
#include "scene/texture.h"
#include "tests/unit/chi2.h"

#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <vector>
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <random>

using namespace theia;

namespace {

constexpr double kSignificance = 0.01;

// A scene with one infinite light whose image is given in memory.
struct EnvScene {
  Scene scene;
  std::unique_ptr<Accel> accel;
  std::unique_ptr<LightSet> lights;

  EnvScene(int w, int h, const std::function<RGB(int, int)>& texel, const Transform& render_from_light = {}) {
    Image img = test::make_image(w, h, 3, texel);
    scene.images.push_back(std::move(img));
    Light l;
    l.kind = LightKind::Infinite;
    l.L = RGB(1.0f);
    l.image = 0;
    l.render_from_light = render_from_light;
    scene.lights.push_back(l);
    accel = std::make_unique<Accel>(scene);
    lights = std::make_unique<LightSet>(scene, *accel);
  }
};

// A bright "sun" on a dim, uneven sky.
RGB sun_texel(int x, int y, int w, int h) {
  float fx = (float(x) + 0.5f) / float(w), fy = (float(y) + 0.5f) / float(h);
  float sun = std::exp(-(sqr(fx - 0.4f) + sqr(fy - 0.35f)) / 0.002f);
  return RGB(0.05f + 0.1f * fx, 0.1f, 0.2f * fy) + 200.0f * sun * RGB(1.0f, 0.9f, 0.7f);
}

Transform some_rotation() {
  return Transform(glm::rotate(mat4(1.0f), 0.7f, glm::normalize(vec3(1.0f, 2.0f, 0.5f))));
}

}  // namespace

// ---------------------------------------------------------------- parameterisations

// The environment lookup's polynomial angle stays within its fit's error
// (4.1e-6 of pi / 2, times r <= 1, halved into the square) of the exact map,
// on the axes, the diagonals and the poles too.
TEST(EqualAreaMap, TheFastInverseIsWithinItsFitOfTheExactOne) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<vec3> dirs = {{1, 0, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}, glm::normalize(vec3(1, 1, 0)),
                            glm::normalize(vec3(-1, 1, -1)), glm::normalize(vec3(1, -1e-7f, 0.3f))};
  for (int k = 0; k < 20000; ++k) dirs.push_back(sample_uniform_sphere(vec2(u(rng), u(rng))));
  float worst = 0.0f;
  for (const vec3& w : dirs) {
    const vec2 d = glm::abs(equal_area_sphere_to_square_fast(w) - equal_area_sphere_to_square(w));
    worst = std::max({worst, d.x, d.y});
  }
  EXPECT_LE(worst, 2.5e-6f);
  EXPECT_GT(worst, 0.0f);  // a different function, not the exact one again
}

TEST(EqualAreaMap, IsABijectionBetweenSquareAndSphere) {
  for (int i = 0; i <= 64; ++i)
    for (int j = 0; j <= 64; ++j) {
      vec2 uv(float(i) / 64.0f, float(j) / 64.0f);
      vec3 w = equal_area_square_to_sphere(uv);
      ASSERT_NEAR(glm::length(w), 1.0f, 1e-5f);
      vec2 back = equal_area_sphere_to_square(w);
      vec3 w2 = equal_area_square_to_sphere(back);
      // The square's boundary is folded (its edges meet on the lower hemisphere),
      // so compare directions there; inside, the square point itself.
      if (i > 0 && i < 64 && j > 0 && j < 64) {
        EXPECT_NEAR(back.x, uv.x, 2e-5f) << i << " " << j;
        EXPECT_NEAR(back.y, uv.y, 2e-5f) << i << " " << j;
      }
      EXPECT_NEAR(glm::length(w2 - w), 0.0f, 5e-5f);
    }
  EXPECT_NEAR(equal_area_square_to_sphere(vec2(0.5f)).z, 1.0f, 1e-6f);
  EXPECT_NEAR(equal_area_square_to_sphere(vec2(0.0f)).z, -1.0f, 1e-6f);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int k = 0; k < 10000; ++k) {
    vec3 w = sample_uniform_sphere(vec2(u(rng), u(rng)));
    EXPECT_NEAR(glm::length(equal_area_square_to_sphere(equal_area_sphere_to_square(w)) - w), 0.0f, 5e-5f);
    EXPECT_NEAR(glm::length(equirect_to_sphere(sphere_to_equirect(w)) - w), 0.0f, 5e-5f);
  }
}

TEST(EqualAreaMap, PreservesArea) {
  // |dw/du x dw/dv| = 4 pi everywhere (away from the folds, by central differences).
  const float h = 1e-3f;
  double worst = 0.0;
  for (int i = 1; i < 40; ++i)
    for (int j = 1; j < 40; ++j) {
      vec2 uv(float(i) / 40.0f + 0.0123f, float(j) / 40.0f + 0.0071f);
      if (std::abs(std::abs(2 * uv.x - 1) + std::abs(2 * uv.y - 1) - 1) < 0.01f) continue;  // the diamond's edge
      if (std::abs(uv.x - 0.5f) < 0.01f || std::abs(uv.y - 0.5f) < 0.01f) continue;         // the axes
      dvec3 du = dvec3(equal_area_square_to_sphere(uv + vec2(h, 0)) - equal_area_square_to_sphere(uv - vec2(h, 0))) /
                 double(2 * h);
      dvec3 dv = dvec3(equal_area_square_to_sphere(uv + vec2(0, h)) - equal_area_square_to_sphere(uv - vec2(0, h))) /
                 double(2 * h);
      double jac = glm::length(glm::cross(du, dv));
      worst = std::max(worst, std::abs(jac / (4.0 * M_PI) - 1.0));
    }
  EXPECT_LT(worst, 0.01);
}

// ---------------------------------------------------------------- environment sampling

TEST(Chi2EnvironmentMap, SamplingMatchesPdfForBothMapsAndDistributions) {
  const int n_tests = 4;
  for (bool equal_area : {true, false}) {
    // Small maps: the harness integrates the pdf adaptively over each cell, and
    // every texel edge inside a cell costs subdivisions.
    int w = equal_area ? 8 : 16, h = 8;
    EnvScene env(w, h, [&](int x, int y) { return sun_texel(x, y, w, h) * (x % 7 == 3 ? 0.0f : 1.0f); },
                 some_rotation());
    ASSERT_EQ(env.lights->environments[0].equal_area, equal_area);
    for (bool compensated : {true, false}) {
      LightSampleContext ctx{vec3(0.3f, 0.2f, 0.1f)};
      // The sample's radiance and pdf agree with what escaped rays see (but
      // for samples within rounding of a texel edge, which may land in the
      // neighbour when mapped back).
      int samples = 0, disagree = 0;
      // Binned in the map's own (u, v), so cell edges fall on texel edges and
      // the harness integrates the pdf cheaply; the density there is the
      // solid-angle pdf times the parameterisation's Jacobian.
      const EnvironmentMap& em = env.lights->environments[0];
      const Transform& xf = env.scene.lights[0].render_from_light;
      auto r = chi2_test(
          fmt::format("{} {}", equal_area ? "equal-area" : "lat-long", compensated ? "compensated" : "full"),
          [&](vec2 u, float) -> std::optional<vec2> {
            auto ls = sample_li(*env.lights, 0, ctx, u, 0.5f, compensated);
            if (!ls) return std::nullopt;
            ++samples;
            if (ls->L != infinite_light_Le(*env.lights, 0, ls->wi) ||
                std::abs(ls->pdf / infinite_light_pdf(*env.lights, 0, ls->wi, compensated) - 1.0f) > 2e-3f)
              ++disagree;
            return environment_uv(em, glm::normalize(mat3(xf.m_inv) * ls->wi));
          },
          [&](vec2 uv) {
            // The density is constant over each texel: evaluate it at the
            // texel's centre, away from the rounding of its edges.
            ivec2 res(em.image->width, em.image->height);
            uv = (glm::floor(uv * vec2(res)) + 0.5f) / vec2(res);
            vec3 wi = xf.vector(environment_direction(em, uv));
            double jacobian = equal_area ? 4.0 * M_PI : 2.0 * M_PI * M_PI * std::sin(M_PI * uv.y);
            return double(infinite_light_pdf(*env.lights, 0, wi, compensated)) * jacobian;
          },
          200'000, 16, 16, kSignificance, n_tests);
      EXPECT_TRUE(r.passed) << r.report;
      EXPECT_LT(disagree, samples / 1000) << disagree << " of " << samples;
    }
  }
}

TEST(EnvironmentMap, ImportanceSamplingBeatsUniformOnASun) {
  const int w = 64, h = 64;
  EnvScene env(w, h, [&](int x, int y) { return sun_texel(x, y, w, h); });
  // Irradiance at an upward-facing point: exact by quadrature over the
  // equal-area square (each point stands for equal solid angle).
  const int q = 512;
  double exact = 0.0;
  for (int i = 0; i < q; ++i)
    for (int j = 0; j < q; ++j) {
      vec3 wi = equal_area_square_to_sphere(vec2((float(i) + 0.5f) / q, (float(j) + 0.5f) / q));
      if (wi.z > 0.0f) exact += luminance(infinite_light_Le(*env.lights, 0, wi)) * wi.z;
    }
  exact *= 4.0 * M_PI / (double(q) * q);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const int n = 64, trials = 400;
  double se_is = 0.0, se_uniform = 0.0;
  LightSampleContext ctx{vec3(0.0f), vec3(0.0f), vec3(0, 0, 1), vec3(0, 0, 1)};
  for (int t = 0; t < trials; ++t) {
    double e_is = 0.0, e_u = 0.0;
    for (int k = 0; k < n; ++k) {
      vec2 r(u(rng), u(rng));
      if (auto ls = sample_li(*env.lights, 0, ctx, r, 0.5f, false); ls && ls->wi.z > 0.0f)
        e_is += luminance(ls->L) * ls->wi.z / ls->pdf;
      vec3 wi = sample_uniform_sphere(r);
      if (wi.z > 0.0f) e_u += luminance(infinite_light_Le(*env.lights, 0, wi)) * wi.z / uniform_sphere_pdf();
    }
    se_is += sqr(e_is / n - exact);
    se_uniform += sqr(e_u / n - exact);
  }
  double rmse_is = std::sqrt(se_is / trials) / exact, rmse_u = std::sqrt(se_uniform / trials) / exact;
  EXPECT_LT(rmse_is, 0.05);
  EXPECT_LT(rmse_is * 5.0, rmse_u) << "importance " << rmse_is << " uniform " << rmse_u;
}

TEST(EnvironmentMap, OrientationFollowsTheTransformAndConstantMapsSampleUniformly) {
  // A map that is bright only at the light-space +z pole, rotated so +z points along render-space +x.
  const int w = 16;
  EnvScene env(w, w, [&](int x, int y) { return (x == w / 2 || x == w / 2 - 1) && (y == w / 2 || y == w / 2 - 1)
                                                    ? RGB(5.0f) : RGB(0.0f); },
               Transform(glm::rotate(mat4(1.0f), kPi / 2.0f, vec3(0, 1, 0))));
  EXPECT_EQ(infinite_light_Le(*env.lights, 0, vec3(1, 0, 0)), RGB(5.0f));
  EXPECT_EQ(infinite_light_Le(*env.lights, 0, vec3(0, 0, 1)), RGB(0.0f));
  EnvScene flat(8, 8, [](int, int) { return RGB(2.0f); });
  for (vec3 wi : {vec3(0, 0, 1), vec3(0.6f, 0.0f, -0.8f)}) {
    EXPECT_NEAR(infinite_light_pdf(*flat.lights, 0, wi, true), kInv4Pi, 1e-6f);
    EXPECT_NEAR(infinite_light_pdf(*flat.lights, 0, wi, false), kInv4Pi, 1e-6f);
  }
}

TEST(EnvironmentMap, IlluminanceAndPowerFollowPbrtV4) {
  // A constant map of 1 has pbrt-v4 "illuminance" pi / 2 (its definition: half the true upper-hemisphere value).
  for (int w : {32, 64}) {
    Scene s = parse_scene_string("WorldBegin\nShape \"sphere\" \"float radius\" 2", "t.pbrt");
    Image img;
    img.width = w;
    img.height = 32;
    img.channels = 3;
    img.pixels.assign(size_t(w) * 32 * 3, 1.0f);
    s.images.push_back(img);
    Light l;
    l.kind = LightKind::Infinite;
    l.L = RGB(3.0f);
    l.image = 0;
    l.illuminance = 10.0f;
    s.lights.push_back(l);
    Accel accel(s);
    LightSet lights(s, accel);
    EXPECT_NEAR(lights.environments[0].scale.x / (3.0f * 10.0f / (kPi / 2.0f)), 1.0f, 0.01f) << w;  // scale *= E / k_e
    // Power: pi R^2 times the integral of radiance over the sphere.
    EXPECT_NEAR(light_power(lights, 0) / (kPi * sqr(lights.scene_radius) * 4.0f * kPi * lights.environments[0].scale.x),
                1.0f, 0.01f);
  }
}

// ---------------------------------------------------------------- spot and distant

TEST(SpotLight, IntensityFallsOffBetweenTheConesAndPowerMatches) {
  Scene s = parse_scene_string(R"(WorldBegin
LightSource "spot" "rgb I" [4 4 4] "point3 from" [0 0 2] "point3 to" [0 0 0] "float coneangle" 30 "float conedeltaangle" 10
Shape "sphere" "float radius" 0.1)", "t.pbrt");
  Accel accel(s);
  LightSet lights(s, accel);
  auto li_at = [&](float angle_deg) {
    float r = 2.0f * std::tan(radians(angle_deg));
    auto ls = sample_li(lights, 0, LightSampleContext{vec3(r, 0, 0)}, vec2(0.5f), 0.5f);
    return ls ? ls->L.x * (4.0f + r * r) : 0.0f;  // intensity towards the point
  };
  EXPECT_NEAR(li_at(0.0f), 4.0f, 1e-5f);
  EXPECT_NEAR(li_at(19.0f), 4.0f, 1e-4f);
  EXPECT_NEAR(li_at(25.0f), 4.0f * 0.5f, 0.3f);  // mid-way through the smoothstep (in cosine)
  EXPECT_EQ(li_at(31.0f), 0.0f);
  float cs = std::cos(radians(20.0f)), ce = std::cos(radians(30.0f));
  // Power = integral of I over the sphere, by midpoint quadrature in cos(theta).
  double phi = 0.0;
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    float c = -1.0f + 2.0f * (float(i) + 0.5f) / float(n);
    float t = std::clamp((c - ce) / (cs - ce), 0.0f, 1.0f);
    phi += 4.0 * t * t * (3 - 2 * t) * 2.0 * M_PI * (2.0 / n);
  }
  EXPECT_NEAR(light_power(lights, 0) / float(phi), 1.0f, 1e-3f);
}

TEST(DistantLight, ArrivesFromItsDirectionEverywhere) {
  Scene s = parse_scene_string(R"(WorldBegin
LightSource "distant" "rgb L" [2 2 2] "point3 from" [0 0 1] "point3 to" [1 0 0]
Shape "sphere" "float radius" 3)", "t.pbrt");
  Accel accel(s);
  LightSet lights(s, accel);
  vec3 expected = glm::normalize(vec3(-1, 0, 1));
  for (vec3 p : {vec3(0.0f), vec3(2, -1, 0.5f)}) {
    auto ls = sample_li(lights, 0, LightSampleContext{p}, vec2(0.3f), 0.1f);
    ASSERT_TRUE(ls);
    EXPECT_TRUE(ls->is_delta);
    EXPECT_NEAR(glm::length(ls->wi - expected), 0.0f, 1e-6f);
    EXPECT_NEAR(glm::length(ls->L - RGB(2.0f)), 0.0f, 1e-5f);  // grey survives the working space
    EXPECT_GT(glm::length(ls->p_light - p), 2.0f * lights.scene_radius);  // outside the scene
  }
  EXPECT_TRUE(lights.infinite_lights.empty());  // escaped rays never see a delta light
  EXPECT_NEAR(light_power(lights, 0), kPi * sqr(lights.scene_radius) * 2.0f, 1e-3f);
}

// ---------------------------------------------------------------- alpha cut-outs

TEST(AlphaCutout, CheckerboardAlphaIsInvisibleWhereZeroForCameraAndShadowRays) {
  Scene s = parse_scene_string(R"(WorldBegin
Texture "a" "float" "checkerboard" "float uscale" 4 "float vscale" 4 "float tex1" 1 "float tex2" 0
Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 1 1 0 0 1 0] "point2 uv" [0 0 1 0 1 1 0 1]
  "integer indices" [0 1 2 0 2 3] "texture alpha" "a"
)", "t.pbrt");
  load_images(s);
  ASSERT_GE(s.shapes[0].alpha, 0);
  Accel accel(s);
  int opaque = 0, clear = 0;
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 8; ++j) {
      vec2 p((float(i) + 0.5f) / 8.0f, (float(j) + 0.5f) / 8.0f);
      bool solid = (int(std::floor(4 * p.x)) + int(std::floor(4 * p.y))) % 2 == 0;
      Ray r{vec3(p, 1.0f), 0.0f, vec3(0, 0, -1), kInfinity};
      EXPECT_EQ(accel.intersect1(r).hit(), solid) << i << " " << j;
      EXPECT_EQ(accel.occluded1(r), solid) << i << " " << j;
      (solid ? opaque : clear)++;
    }
  EXPECT_EQ(opaque, 32);
  EXPECT_EQ(clear, 32);
}

TEST(AlphaCutout, FractionalAlphaKeepsThatFractionOfHitsDeterministically) {
  Scene s = parse_scene_string(R"(WorldBegin
Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 1 1 0 0 1 0] "integer indices" [0 1 2 0 2 3] "float alpha" 0.25
)", "t.pbrt");
  Accel accel(s);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  int hits = 0;
  const int n = 20000;
  for (int k = 0; k < n; ++k) {
    Ray r{vec3(u(rng), u(rng), 1.0f), 0.0f, vec3(0, 0, -1), kInfinity};
    bool h = accel.intersect1(r).hit();
    EXPECT_EQ(accel.intersect1(r).hit(), h);  // a pure function of the ray
    EXPECT_EQ(accel.occluded1(r), h);
    hits += h;
  }
  EXPECT_NEAR(double(hits) / n, 0.25, 0.015);
}

// ---------------------------------------------------------------- texture filter

TEST(TextureFilter, PointPicksTheNearestTexel) {
  Image img;
  img.width = 2;
  img.height = 2;
  img.channels = 1;
  img.pixels = {1.0f, 2.0f, 3.0f, 4.0f};  // top row 1 2, bottom row 3 4
  EXPECT_EQ(image_lookup_nearest(img, vec2(0.1f, 0.9f), WrapMode::Repeat), RGB(1.0f));
  EXPECT_EQ(image_lookup_nearest(img, vec2(0.74f, 0.9f), WrapMode::Repeat), RGB(2.0f));
  EXPECT_EQ(image_lookup_nearest(img, vec2(0.26f, 0.1f), WrapMode::Repeat), RGB(3.0f));
  EXPECT_EQ(image_lookup_nearest(img, vec2(0.9f, 0.4f), WrapMode::Repeat), RGB(4.0f));
  EXPECT_EQ(image_lookup_nearest(img, vec2(1.1f, 0.9f), WrapMode::Repeat), RGB(1.0f));
  Scene s = parse_scene_string(R"(WorldBegin
Texture "p" "float" "imagemap" "string filename" "cornell-box.exr" "string filter" "point"
Texture "t" "float" "imagemap" "string filename" "cornell-box.exr" "string filter" "trilinear"
)", "t.pbrt", THEIA_TEST_DATA);
  EXPECT_EQ(s.textures[0].filter, TextureFilter::Point);
  EXPECT_EQ(s.textures[1].filter, TextureFilter::Trilinear);
  EXPECT_EQ(s.textures[1].max_anisotropy, 8.0f);  // pbrt-v4's default
  int before = warning_count();
  Scene e = parse_scene_string("WorldBegin\nTexture \"e\" \"float\" \"imagemap\" \"string filename\" "
                               "\"cornell-box.exr\" \"string filter\" \"ewa\" \"float maxanisotropy\" 16",
                               "t.pbrt", THEIA_TEST_DATA);
  EXPECT_EQ(e.textures[0].filter, TextureFilter::EWA);
  EXPECT_EQ(e.textures[0].max_anisotropy, 16.0f);
  EXPECT_EQ(warning_count() - before, 0);
  try {
    parse_scene_string("WorldBegin\nTexture \"e\" \"float\" \"imagemap\" \"string filename\" "
                       "\"cornell-box.exr\" \"string filter\" \"ewa\" \"float maxanisotropy\" 0", "t.pbrt", THEIA_TEST_DATA);
    ADD_FAILURE() << "maxanisotropy 0 accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("t.pbrt:2:1: error: maxanisotropy 0, expected a positive ratio"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(parse_scene_string("WorldBegin\nTexture \"b\" \"float\" \"imagemap\" \"string filename\" "
                                  "\"cornell-box.exr\" \"string filter\" \"cubic\"", "t.pbrt", THEIA_TEST_DATA),
               Error);
}

// ---------------------------------------------------------------- goniometric and projection

namespace {

// A scene whose lights are declared by `world` (after WorldBegin, from line
// 2 of t.pbrt), which may name "light.exr": a w x h RGB image of texel(x, y),
// row 0 at the top.
struct ImageLightScene {
  test::TempDir tmp;
  Scene scene;
  std::unique_ptr<Accel> accel;
  std::unique_ptr<LightSet> lights;

  ImageLightScene(const std::string& world, int w, int h, const std::function<RGB(int, int)>& texel) {
    ImageBuffer img(w, h, {"R", "G", "B"});
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) img.at(x, y, c) = texel(x, y)[c];
    write_exr(tmp.file("light.exr"), img);
    scene = parse_scene_string("WorldBegin\n" + world + "\n", tmp.file("t.pbrt"), tmp.path.string());
    load_images(scene);
    accel = std::make_unique<Accel>(scene);
    lights = std::make_unique<LightSet>(scene, *accel);
  }
  RGB I(const vec3& w, int light = 0) const { return light_intensity(*lights, light, glm::normalize(w)); }
};

RGB distinct_texel(int x, int y) { return RGB(1.0f + float(x), 0.5f + float(y), 0.25f * float((x * y) % 3)); }
float mean_of(RGB c) { return (c.x + c.y + c.z) / 3.0f; }

// The error message of building the scene (and its LightSet), or "" if it builds.
std::string image_light_error(const std::string& world, int w, int h) {
  try {
    ImageLightScene s(world, w, h, [](int, int) { return RGB(1.0f); });
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

// Axes by hand: with no transform, pbrt-v4's y/z swap puts the map's pole
// (the square's centre) at +y; +x is the right edge's middle, +z the bottom
// edge's, -x the left edge's, -z the top edge's.  The map is one channel, the
// mean of the file's R, G, B as stored (not converted to the working space).
TEST(GoniometricLight, AxesHitTheirTexels) {
  ImageLightScene s(R"(LightSource "goniometric" "rgb I" [2 2 2] "string filename" "light.exr")", 9, 9,
                    distinct_texel);
  const std::pair<vec3, ivec2> axes[] = {{vec3(0, 1, 0), {4, 4}}, {vec3(1, 0, 0), {8, 4}}, {vec3(0, 0, 1), {4, 8}},
                                         {vec3(-1, 0, 0), {0, 4}}, {vec3(0, 0, -1), {4, 0}}};
  for (const auto& [w, t] : axes) {
    float want = 2.0f * mean_of(distinct_texel(t.x, t.y));
    EXPECT_NEAR(glm::length(s.I(w) - RGB(want)), 0.0f, 1e-5f * want) << t.x << " " << t.y;
  }
  // Off the poles' ambiguity: a direction a little below the equator on +x is still column 8.
  EXPECT_NEAR(s.I(vec3(1, -0.05f, 0)).x / (2.0f * mean_of(distinct_texel(8, 4))), 1.0f, 1e-5f);
}

// Every texel centre, through the equal-area map to a direction and the
// light's transform (a rotation and pbrt-v4's swap) to render space, comes
// back as that texel; and random render-space directions see the texel at
// their equal-area position.
TEST(GoniometricLight, IntensityIsTheTexelAtItsEqualAreaPositionBothWays) {
  ImageLightScene s(R"(Translate 1 2 3
Rotate 40 1 1 0
LightSource "goniometric" "rgb I" [2 2 2] "float scale" 1.5 "string filename" "light.exr")",
                    8, 8, distinct_texel);
  const Light& l = s.scene.lights[0];
  EXPECT_EQ(l.kind, LightKind::Goniometric);
  EXPECT_NEAR(glm::length(l.position - vec3(1, 2, 3)), 0.0f, 1e-6f);
  mat3 rot = mat3(glm::rotate(mat4(1.0f), radians(40.0f), glm::normalize(vec3(1, 1, 0))));
  auto render_from_map = [&](vec3 d) { return rot * vec3(d.x, d.z, d.y); };
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) {
      vec3 w = render_from_map(equal_area_square_to_sphere(vec2((float(x) + 0.5f) / 8.0f, (float(y) + 0.5f) / 8.0f)));
      EXPECT_NEAR(s.I(w).y / (3.0f * mean_of(distinct_texel(x, y))), 1.0f, 1e-5f) << x << " " << y;
    }
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int k = 0; k < 200; ++k) {
    vec3 w = sample_uniform_sphere(vec2(u(rng), u(rng)));
    vec3 m = glm::transpose(rot) * w;
    vec2 uv = equal_area_sphere_to_square(vec3(m.x, m.z, m.y));
    int x = std::min(int(uv.x * 8.0f), 7), y = std::min(int(uv.y * 8.0f), 7);
    EXPECT_NEAR(s.I(w).y / (3.0f * mean_of(distinct_texel(x, y))), 1.0f, 1e-5f) << k;
  }
}

// A constant white image: the same light samples and power as a point light of the same I.
TEST(GoniometricLight, ConstantWhiteImageIsAPointLight) {
  ImageLightScene s(R"(AttributeBegin
Translate 0.5 2 0.25
Rotate 70 0 0 1
LightSource "goniometric" "rgb I" [3 2 1] "string filename" "light.exr"
AttributeEnd
LightSource "point" "rgb I" [3 2 1] "point3 from" [0.5 2 0.25])",
                    4, 4, [](int, int) { return RGB(1.0f); });
  for (vec3 p : {vec3(0.0f), vec3(3, -1, 2), vec3(0.5f, 5, 0.25f), vec3(-2, 2, 0)}) {
    auto g = sample_li(*s.lights, 0, LightSampleContext{p}, vec2(0.3f), 0.7f);
    auto pt = sample_li(*s.lights, 1, LightSampleContext{p}, vec2(0.3f), 0.7f);
    ASSERT_TRUE(g && pt);
    EXPECT_NEAR(glm::length(g->L - pt->L), 0.0f, 1e-6f * glm::length(pt->L));
    EXPECT_NEAR(glm::length(g->wi - pt->wi), 0.0f, 1e-6f);
    EXPECT_NEAR(glm::length(g->p_light - pt->p_light), 0.0f, 1e-6f);
    EXPECT_TRUE(g->is_delta);
    EXPECT_FALSE(g->is_infinite);
    EXPECT_EQ(g->pdf, 1.0f);
  }
  EXPECT_NEAR(light_power(*s.lights, 0) / light_power(*s.lights, 1), 1.0f, 1e-5f);
}

// "power" phi: light_power is phi, and so is the intensity integrated over the
// sphere (an equal-area grid 4x finer than the map: exact for nearest texels).
// "scale" still multiplies, as in pbrt-v4.
TEST(GoniometricLight, PowerIsTheIntegralOfIntensity) {
  for (float scale : {1.0f, 2.0f}) {
    ImageLightScene s(R"(Rotate 25 0 1 1
LightSource "goniometric" "float power" 50 "string filename" "light.exr" "float scale" )" +
                          std::to_string(scale),
                      8, 8, distinct_texel);
    EXPECT_NEAR(light_power(*s.lights, 0), 50.0f * scale, 1e-4f * 50.0f * scale);
    double sum = 0.0;
    const int n = 32;
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        vec3 d = equal_area_square_to_sphere(vec2((float(x) + 0.5f) / n, (float(y) + 0.5f) / n));
        sum += double(luminance(light_intensity(*s.lights, 0, s.scene.lights[0].render_from_light.vector(d))));
      }
    EXPECT_NEAR(sum * 4.0 * kPi / (n * n), 50.0 * scale, 1e-4 * 50.0 * scale);
  }
}

// A 5 x 3 image (wide: fov spans its height) with no transform: the frustum
// looks down +z, +y is the image's top and +x its right.
TEST(ProjectionLight, FrustumCentreCornersAndOutside) {
  ImageLightScene s(R"(LightSource "projection" "float fov" 60 "float scale" 2 "string filename" "light.exr")", 5, 3,
                    distinct_texel);
  EXPECT_EQ(s.scene.lights[0].kind, LightKind::Projection);
  auto texel = [](int x, int y) { return 2.0f * srgb_to_working(distinct_texel(x, y)); };  // a colour image
  auto expect_rgb = [](RGB got, RGB want, const char* what) {
    EXPECT_NEAR(glm::length(got - want), 0.0f, 1e-5f * glm::length(want)) << what;
  };
  const float t = std::tan(radians(30.0f)), sx = 5.0f / 3.0f;
  expect_rgb(s.I(vec3(0, 0, 1)), texel(2, 1), "centre");
  expect_rgb(s.I(vec3(0.99f * sx * t, 0.99f * t, 1)), texel(4, 0), "top right");
  expect_rgb(s.I(vec3(-0.99f * sx * t, 0.99f * t, 1)), texel(0, 0), "top left");
  expect_rgb(s.I(vec3(0.99f * sx * t, -0.99f * t, 1)), texel(4, 2), "bottom right");
  expect_rgb(s.I(vec3(-0.99f * sx * t, -0.99f * t, 1)), texel(0, 2), "bottom left");
  for (vec3 w : {vec3(1.01f * sx * t, 0, 1), vec3(0, 1.01f * t, 1), vec3(0, -1.01f * t, 1), vec3(0, 0, -1),
                 vec3(1, 0, 0), vec3(0.1f, 0.1f, -1)})
    EXPECT_EQ(s.I(w), RGB(0.0f)) << w.x << " " << w.y << " " << w.z;
  // A tall image: fov spans the width.
  ImageLightScene tall(R"(LightSource "projection" "float fov" 60 "string filename" "light.exr")", 3, 5,
                       distinct_texel);
  EXPECT_EQ(tall.I(vec3(1.01f * t, 0, 1)), RGB(0.0f));
  EXPECT_NE(tall.I(vec3(0.99f * t, 0, 1)), RGB(0.0f));
  EXPECT_NEAR(glm::length(tall.I(vec3(0, 0.99f * sx * t, 1)) - srgb_to_working(distinct_texel(1, 0))), 0.0f, 1e-5f);
}

// Placed by the CTM: pointing down from (0, 2, 0), the CTM's +y (the image's
// top) along render +z.  Light samples are delta samples from the light's
// position with L = I / d^2.
TEST(ProjectionLight, SamplesFollowTheTransform) {
  ImageLightScene s(R"(Translate 0 2 0
Rotate 90 1 0 0
LightSource "projection" "float fov" 90 "string filename" "light.exr")",
                    2, 2, distinct_texel);
  const std::pair<vec3, ivec2> points[] = {
      {vec3(0.5f, 0, 0.5f), {1, 0}}, {vec3(-0.5f, 0, 0.5f), {0, 0}}, {vec3(0.5f, 0, -0.5f), {1, 1}},
      {vec3(-0.5f, 0, -0.5f), {0, 1}}};
  for (const auto& [p, t] : points) {
    auto ls = sample_li(*s.lights, 0, LightSampleContext{p}, vec2(0.5f), 0.5f);
    ASSERT_TRUE(ls);
    EXPECT_TRUE(ls->is_delta);
    EXPECT_EQ(ls->pdf, 1.0f);
    EXPECT_NEAR(glm::length(ls->p_light - vec3(0, 2, 0)), 0.0f, 1e-6f);
    float d2 = glm::dot(vec3(0, 2, 0) - p, vec3(0, 2, 0) - p);
    RGB want = srgb_to_working(distinct_texel(t.x, t.y)) / d2;
    EXPECT_NEAR(glm::length(ls->L - want), 0.0f, 1e-5f * glm::length(want)) << p.x << " " << p.z;
  }
  EXPECT_FALSE(sample_li(*s.lights, 0, LightSampleContext{vec3(3, 0, 0)}, vec2(0.5f), 0.5f));  // outside
  EXPECT_FALSE(sample_li(*s.lights, 0, LightSampleContext{vec3(0, 3, 0)}, vec2(0.5f), 0.5f));  // behind
}

// "power" phi gives light_power phi; the intensity integrated over the
// frustum (a fine grid on the screen, d omega = tan^2 cos^3 dA) agrees to
// pbrt-v4's midpoint rule over the 32 x 16 texels.
TEST(ProjectionLight, PowerIsTheIntegralOfIntensity) {
  ImageLightScene s(R"(Rotate 30 1 0 0
LightSource "projection" "float fov" 50 "float power" 20 "string filename" "light.exr")",
                    32, 16, [](int x, int y) { return RGB(0.2f + 0.02f * float(x), 0.5f, 0.1f + 0.05f * float(y)); });
  EXPECT_NEAR(light_power(*s.lights, 0), 20.0f, 20.0f * 1e-5f);
  const Transform& m = s.scene.lights[0].render_from_light;
  const float t = std::tan(radians(25.0f));
  const int nx = 1024, ny = 512;
  double sum = 0.0;
  for (int y = 0; y < ny; ++y)
    for (int x = 0; x < nx; ++x) {
      vec2 ps((2.0f * (float(x) + 0.5f) / nx - 1.0f) * 2.0f, 2.0f * (float(y) + 0.5f) / ny - 1.0f);
      vec3 w = glm::normalize(vec3(ps * t, 1.0f));
      sum += double(luminance(light_intensity(*s.lights, 0, glm::normalize(m.vector(w))))) * std::pow(double(w.z), 3.0);
    }
  double phi = sum * double(t * t) * (4.0 * 2.0) / (nx * ny);
  EXPECT_NEAR(phi / 20.0, 1.0, 1e-3);
}

TEST(PointImageLights, BadInputIsAnErrorWithItsLocation) {
  auto expect_error = [](const std::string& world, int w, int h, const std::string& what) {
    std::string e = image_light_error(world, w, h);
    EXPECT_NE(e.find("t.pbrt:2:1: error: "), std::string::npos) << e;
    EXPECT_NE(e.find(what), std::string::npos) << e;
  };
  expect_error(R"(LightSource "goniometric" "string filename" "light.exr")", 8, 4, "is 8x4, expected a square");
  expect_error(R"(LightSource "goniometric" "rgb I" [1 1 1])", 4, 4,
               "goniometric light without \"string filename\", expected an image");
  expect_error(R"(LightSource "projection" "float fov" 30)", 4, 4,
               "projection light without \"string filename\", expected an image");
  expect_error(R"(LightSource "projection" "string filename" "light.exr" "float fov" 180)", 4, 4,
               "projection \"fov\" 180, expected (0, 180) degrees");
  expect_error(R"(LightSource "projection" "string filename" "light.exr" "float fov" 0)", 4, 4, "expected (0, 180)");
  // The missing file is reported at the parameter.
  std::string e = image_light_error(R"(LightSource "goniometric" "string filename" "nope.exr")", 4, 4);
  EXPECT_NE(e.find("t.pbrt:2:27: error: image \""), std::string::npos) << e;
  EXPECT_NE(e.find("nope.exr\" not found, expected an existing file"), std::string::npos) << e;
  // "power" cannot normalise a black image.
  try {
    ImageLightScene s(R"(LightSource "projection" "float power" 3 "string filename" "light.exr")", 2, 2,
                      [](int, int) { return RGB(0.0f); });
    ADD_FAILURE() << "black image with power accepted";
  } catch (const Error& err) {
    EXPECT_NE(std::string(err.what()).find("t.pbrt:2:1: error: \"power\" given for a light whose image"),
              std::string::npos)
        << err.what();
  }
  EXPECT_EQ(image_light_error(R"(LightSource "projection" "string filename" "light.exr")", 4, 2), "");
}

TEST(PointImageLights, FingerprintSeesTheirParameters) {
  test::TempDir tmp;
  write_exr(tmp.file("light.exr"), ImageBuffer(2, 2, {"R", "G", "B"}, 1.0f));
  auto fp = [&](const std::string& light) {
    return scene_fingerprint(parse_scene_string("WorldBegin\n" + light, tmp.file("t.pbrt"), tmp.path.string()));
  };
  const std::string proj = R"(LightSource "projection" "string filename" "light.exr" "float fov" )";
  EXPECT_EQ(fp(proj + "40"), fp(proj + "40"));
  EXPECT_NE(fp(proj + "40"), fp(proj + "41"));
  EXPECT_NE(fp(proj + "40 \"float power\" 3"), fp(proj + "40"));
  const std::string gonio = R"(LightSource "goniometric" "string filename" "light.exr")";
  EXPECT_NE(fp(gonio), fp("Rotate 10 0 0 1\n" + gonio));
  EXPECT_NE(fp(gonio), fp(proj + "90"));
}
