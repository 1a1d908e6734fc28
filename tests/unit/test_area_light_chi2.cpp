// Chi-square tests of area-light sampling (sample_li) against its own pdf
// (area_light_pdf), for every way a shape is sampled: triangles chosen by
// area (unequal ones), triangles chosen by power (pbrt-v4's "power" per
// triangle; an emission image's luminance), the cone of a full sphere seen
// from outside, area sampling of a partial sphere, an annulus sector of
// a disk, and partial and elliptic cylinders.
//
// Directions are binned in the cone that bounds the light as seen from the
// reference point, so the test resolves the light itself rather than a few
// cells of the whole sphere: u = (1 - cos theta) / (1 - cos theta_max),
// v = phi / 2 pi, and the density there is the solid-angle pdf times
// 2 pi (1 - cos theta_max).  The pdf of a direction is found the way the
// engine finds it: trace the ray, and ask area_light_pdf about the hit.
#include "scene/accel.h"
#include "scene/lights.h"
#include "scene/parser.h"
#include "tests/test_util.h"
#include "tests/unit/chi2.h"

#include <gtest/gtest.h>

using namespace theia;

namespace {

constexpr double kSignificance = 0.01;

struct ConeChart {
  vec3 axis;
  Frame frame;
  float one_minus_cos_max;

  ConeChart(const vec3& p, const Bounds3& b) {
    vec3 c = 0.5f * (b.min + b.max);
    float r = 0.5f * glm::length(b.max - b.min), d = glm::length(c - p);
    axis = (c - p) / d;
    frame = Frame::from_z(axis);
    one_minus_cos_max = 1.0f - std::sqrt(std::max(0.0f, 1.0f - sqr(r / d)));
  }
  std::optional<vec2> to_uv(const vec3& w) const {
    vec3 l = frame.to_local(w);
    float u = (1.0f - l.z) / one_minus_cos_max;
    if (u > 1.0f) return std::nullopt;  // outside the bounding cone: the harness counts it as a failure
    float v = std::atan2(l.y, l.x) * kInv2Pi;
    if (v < 0.0f) v += 1.0f;
    return vec2(std::min(u, kOneMinusEpsilon), std::min(v, kOneMinusEpsilon));
  }
  vec3 to_direction(vec2 uv) const {
    float cos_theta = 1.0f - uv.x * one_minus_cos_max, sin_theta = safe_sqrt(1.0f - cos_theta * cos_theta);
    float phi = 2.0f * kPi * uv.y;
    return frame.from_local(vec3(sin_theta * std::cos(phi), sin_theta * std::sin(phi), cos_theta));
  }
  double jacobian() const { return 2.0 * M_PI * one_minus_cos_max; }
};

// all_hits: area sampling can pick any point of the surface along a direction
// (a partial sphere shows its inside through the cut), so the density of a
// direction sums the pdf of every hit; cone sampling of a full sphere picks
// the first hit only, and its pdf already is the density of the direction.
// `light`: the AreaLightSource's parameters; `image`: an emission image put
// in place of its "L".
void expect_light_sampling_matches_pdf(const std::string& name, const std::string& shape, vec3 p, int n_tests,
                                       bool all_hits = false,
                                       const std::string& light = "\"rgb L\" [1 1 1] \"bool twosided\" true",
                                       const Image* image = nullptr) {
  Scene scene = parse_scene_string("WorldBegin\nAreaLightSource \"diffuse\" " + light + "\n" + shape, name);
  ASSERT_EQ(scene.lights.size(), 1u);
  if (image) {
    scene.images.push_back(*image);
    scene.lights[0].image = int(scene.images.size()) - 1;
  }
  Accel accel(scene);
  LightSet lights(scene, accel);
  LightSampleContext ctx{p};
  ConeChart chart(p, accel.bounds());
  Chi2Result r = chi2_test(
      name,
      [&](vec2 u, float u1) -> std::optional<vec2> {
        auto ls = sample_li(lights, 0, ctx, u, u1);
        if (!ls) return std::nullopt;
        return chart.to_uv(ls->wi);
      },
      [&](vec2 uv) -> double {
        vec3 wi = chart.to_direction(uv);
        Ray ray{p, 0.0f, wi, kInfinity};
        double density = 0.0;
        for (int i = 0; i < 4; ++i) {
          Hit hit = accel.intersect1(ray);
          if (!hit.hit()) break;
          SurfaceInteraction si = compute_interaction(scene, accel, ray, hit);
          density += area_light_pdf(lights, 0, ctx, wi, si);
          if (!all_hits) break;
          ray = spawn_ray(si, wi);
        }
        return density * chart.jacobian();
      },
      100'000, 16, 16, kSignificance, n_tests);
  EXPECT_TRUE(r.passed) << r.report;
}

}  // namespace

TEST(Chi2AreaLight, SamplingMatchesPdfForEveryShapeKind) {
  const int n_tests = 4;
  // Two triangles of areas 1 and 0.25: chosen by area, then uniform on each.
  expect_light_sampling_matches_pdf(
      "triangles", "Shape \"trianglemesh\" \"point3 P\" [0 0 0  2 0 0  2 1 0  2.5 0 0  3 0 0  3 1 0] "
                   "\"integer indices\" [0 1 2 3 4 5]",
      vec3(1.2f, 0.6f, 1.5f), n_tests, /*all_hits=*/true);
  // The same with pbrt-v4's "power": each triangle emits it, so the small
  // one (four times the radiance) is chosen as often as the large one.
  expect_light_sampling_matches_pdf(
      "triangles by power", "Shape \"trianglemesh\" \"point3 P\" [0 0 0  2 0 0  2 1 0  2.5 0 0  3 0 0  3 1 0] "
                            "\"integer indices\" [0 1 2 3 4 5]",
      vec3(1.2f, 0.6f, 1.5f), n_tests, /*all_hits=*/true, "\"float power\" 3 \"bool twosided\" true");
  // Triangles chosen by their mean image luminance: a quad under an image
  // bright in one corner, of a mesh of eight unequal triangles.
  const Image corner = test::make_image(4, 4, 3, [](int x, int y) {
    return RGB(x == 3 && y == 0 ? 20.0f : 0.2f * float(x + y), 0.5f, 0.1f);
  });
  expect_light_sampling_matches_pdf(
      "triangles by image",
      "Shape \"trianglemesh\" \"point3 P\" [0 0 0  1 0 0  1 1 0  0 1 0  0.3 0.6 0  0.8 0.2 0] "
      "\"point2 uv\" [0 0  1 0  1 1  0 1  0.3 0.6  0.8 0.2] "
      "\"integer indices\" [0 1 5  1 2 5  2 4 5  2 3 4  3 0 4  0 5 4]",
      vec3(0.4f, 0.5f, 1.2f), n_tests, /*all_hits=*/true, "\"bool twosided\" true", &corner);
  // A full sphere from outside: uniform over its cone of directions.
  expect_light_sampling_matches_pdf("sphere cone", "Translate 0 0 -2\nShape \"sphere\" \"float radius\" 0.5",
                                    vec3(0.2f, -0.1f, 0.3f), n_tests);
  // A partial sphere: area sampling.
  expect_light_sampling_matches_pdf(
      "partial sphere", "Shape \"sphere\" \"float radius\" 0.6 \"float zmax\" 0.3 \"float phimax\" 270",
      vec3(0.4f, 0.3f, 2.5f), n_tests, /*all_hits=*/true);
  // An annulus sector of a disk, tilted.
  expect_light_sampling_matches_pdf(
      "disk sector", "Rotate 30 1 0 0\nShape \"disk\" \"float radius\" 1 \"float innerradius\" 0.3 \"float phimax\" 300",
      vec3(0.2f, 0.5f, 2.0f), n_tests, /*all_hits=*/true);
  // A partial cylinder, tilted: uniform by area; its inside shows through the cut.
  expect_light_sampling_matches_pdf(
      "cylinder", "Rotate 50 1 1 0\nShape \"cylinder\" \"float radius\" 0.7 \"float zmin\" -0.5 \"float zmax\" 0.8 "
                  "\"float phimax\" 260",
      vec3(0.3f, 0.4f, 2.5f), n_tests, /*all_hits=*/true);
  // A full elliptic cylinder: the density follows the non-uniform area scale.
  expect_light_sampling_matches_pdf(
      "elliptic cylinder", "Rotate 70 0 1 0\nScale 1.6 0.6 1\nShape \"cylinder\" \"float radius\" 0.7",
      vec3(0.2f, -0.3f, 3.0f), n_tests, /*all_hits=*/true);
}

// sample_le, the light paths' start: directions cosine-weighted on the
// emitting side (both sides of a two-sided quad, half each), points uniform
// by area on a sphere.  The first 2D sample drives what is being tested,
// the others are fixed-hash stand-ins.
TEST(Chi2LightEmission, DirectionsAndPointsMatchTheirPdfs) {
  const int n_tests = 3;
  auto lights_of = [](const std::string& text) {
    auto scene = std::make_unique<Scene>(parse_scene_string("WorldBegin\n" + text, "emission"));
    return scene;
  };
  for (bool two_sided : {false, true}) {
    auto scene = lights_of(std::string("AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"bool twosided\" ") +
                           (two_sided ? "true" : "false") +
                           "\nShape \"trianglemesh\" \"point3 P\" [0 0 0  1 0 0  1 1 0  0 1 0] "
                           "\"integer indices\" [0 1 2 0 2 3]");
    Accel accel(*scene);
    LightSet lights(*scene, accel);
    auto le0 = sample_le(lights, 0, vec2(0.3f), 0.5f, vec2(0.2f, 0.7f));
    ASSERT_TRUE(le0);
    const vec3 normal = le0->n;
    Chi2Result r = chi2_test_sphere(
        [&](vec2 u, float u1) -> std::optional<vec3> {
          auto le = sample_le(lights, 0, vec2(u1, 0.5f), 0.5f, u);
          if (!le) return std::nullopt;
          EXPECT_FLOAT_EQ(le->pdf_pos, 1.0f);  // a unit quad
          float c = glm::dot(le->w, normal);
          EXPECT_NEAR(le->pdf_dir, two_sided ? 0.5f * std::abs(c) * kInvPi : c * kInvPi, 1e-5f);
          return le->w;
        },
        [&](vec3 w) -> float {
          float c = glm::dot(w, normal);
          return two_sided ? 0.5f * std::abs(c) * kInvPi : std::max(c, 0.0f) * kInvPi;
        },
        100'000, 16, 32, kSignificance, n_tests, two_sided ? "two-sided quad" : "one-sided quad");
    EXPECT_TRUE(r.passed) << r.report;
  }
  // A sphere of radius 2 at (1, 2, 3): points uniform over its area.
  auto scene = lights_of("AreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\nTranslate 1 2 3\nShape \"sphere\" \"float radius\" 2");
  Accel accel(*scene);
  LightSet lights(*scene, accel);
  const vec3 centre(1, 2, 3);
  Chi2Result r = chi2_test_sphere(
      [&](vec2 u, float) -> std::optional<vec3> {
        auto le = sample_le(lights, 0, u, 0.5f, vec2(0.3f, 0.6f));
        if (!le) return std::nullopt;
        EXPECT_NEAR(le->pdf_pos, 1.0f / (16.0f * kPi), 1e-6f);
        EXPECT_GT(glm::dot(le->w, le->n), 0.0f);  // one-sided: leaves outwards
        return glm::normalize(le->p - centre);
      },
      [&](vec3) -> float { return kInv4Pi; }, 100'000, 16, 32, kSignificance, n_tests, "sphere points");
  EXPECT_TRUE(r.passed) << r.report;
}
