// Participating media (scene/media.h, scene/medium_params.h): the
// Henyey-Greenstein phase function by chi-square, delta (spectral) and ratio
// tracking against closed-form slab transmittance and against a fine-stepped
// quadrature through a density grid, and the parser's media directives.
#include "core/color.h"
#include "scene/media.h"
#include "scene/microfacet.h"
#include "scene/parser.h"
#include "tests/unit/chi2.h"

#include <fmt/format.h>
#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <cmath>

using namespace theia;

namespace {

Medium homogeneous(RGB sigma_a, RGB sigma_s, float g = 0.0f) {
  Medium m;
  m.sigma_a = sigma_a;
  m.sigma_s = sigma_s;
  m.g = g;
  return m;
}

// A 4 x 4 x 4 grid of densities in [0, 2] over the box [-1, 1]^3 (with a
// non-identity transform: medium space is scaled by 2 and shifted).
Medium test_grid() {
  Medium m;
  m.kind = MediumKind::UniformGrid;
  m.sigma_a = RGB(0.4f, 0.8f, 1.2f);
  m.sigma_s = RGB(0.6f, 0.6f, 0.6f);
  m.nx = m.ny = m.nz = 4;
  for (int i = 0; i < 64; ++i) m.density.push_back(float((i * 37) % 11) / 5.0f);
  m.max_density = 2.0f;
  m.p0 = vec3(-1.0f);
  m.p1 = vec3(1.0f);
  m.render_from_medium = Transform(glm::translate(mat4(1.0f), vec3(0.5f, 0.0f, 0.0f)) * glm::scale(mat4(1.0f), vec3(2.0f)));
  build_majorant_grid(m);
  return m;
}

// exp(-integral of sigma_t) along the ray's [0, tmax], by the midpoint rule
// in medium space (distances as the medium measures them).
RGB quadrature_transmittance(const Medium& m, const Ray& ray, float tmax, int steps) {
  const MediumSegment seg = medium_segment(m, ray, 0.0f, tmax);
  if (seg.empty()) return RGB(1.0f);
  const double h = double(seg.s1 - seg.s0) / steps;
  double tau[3] = {0, 0, 0};
  for (int i = 0; i < steps; ++i) {
    const MediumProps mp = medium_props(m, seg.o + seg.d * float(seg.s0 + (i + 0.5) * h));
    for (int c = 0; c < 3; ++c) tau[c] += double(mp.sigma_a[c] + mp.sigma_s[c]) * h;
  }
  return RGB(float(std::exp(-tau[0])), float(std::exp(-tau[1])), float(std::exp(-tau[2])));
}

struct Estimate {
  double mean[3] = {0, 0, 0}, sd[3] = {0, 0, 0};  // sd of the mean
};
template <class F>
Estimate estimate(int n, F&& sample) {
  Estimate e;
  double sum[3] = {0, 0, 0}, sum2[3] = {0, 0, 0};
  for (int i = 0; i < n; ++i) {
    const RGB v = sample(uint64_t(i));
    for (int c = 0; c < 3; ++c) sum[c] += v[c], sum2[c] += double(v[c]) * v[c];
  }
  for (int c = 0; c < 3; ++c) {
    e.mean[c] = sum[c] / n;
    e.sd[c] = std::sqrt(std::max(0.0, sum2[c] / n - e.mean[c] * e.mean[c]) / n);
  }
  return e;
}

// Within 4.5 standard errors (plus a hair for a zero-variance estimate).
void expect_matches(const Estimate& e, const RGB& expected, const std::string& what) {
  for (int c = 0; c < 3; ++c)
    EXPECT_NEAR(e.mean[c], expected[c], 4.5 * e.sd[c] + 1e-6) << what << " channel " << c;
}

}  // namespace

// Binned in a frame around the forward direction -wo, on x = ((1 - cos) / 2)^(1/4)
// so that even g = 0.99's narrow peak spreads over many cells.
TEST(MediaPhase, HenyeyGreensteinChi2) {
  const vec3 wo = glm::normalize(vec3(0.3f, -0.2f, 0.9f));
  const Frame f = Frame::from_z(-wo);
  for (float g : {-0.9f, 0.0f, 0.5f, 0.99f}) {
    auto to_square = [&](const vec3& wi) {
      const vec3 l = f.to_local(wi);
      const float x = std::pow(std::max(0.0f, (1.0f - l.z) * 0.5f), 0.25f);
      float phi = std::atan2(l.y, l.x);
      if (phi < 0.0f) phi += 2.0f * kPi;
      return vec2(std::min(x, 1.0f), std::min(phi / (2.0f * kPi), 1.0f));
    };
    auto r = chi2_test(
        fmt::format("HG g={}", g),
        [&](vec2 u, float) -> std::optional<vec2> {
          float pdf = 0.0f;
          const vec3 wi = sample_henyey_greenstein(wo, g, u, &pdf);
          // The returned pdf is the density the phase function claims, up to
          // the float rounding of wi: HG's log-derivative in cos is
          // 3g / (1 + g^2 + 2g cos), 3e4 at g = 0.99's peak.
          const float c = glm::dot(wo, wi);
          const float sensitivity = 3.0f * std::abs(g) / (1.0f + g * g + 2.0f * g * c);
          if (std::abs(pdf - henyey_greenstein(c, g)) > (1e-4f + 1e-6f * sensitivity) * pdf) return vec2(-1.0f);
          return to_square(glm::normalize(wi));
        },
        [&](vec2 p) {
          const double x = p.x, c = 1.0 - 2.0 * x * x * x * x;  // cos from the forward direction
          // dw = 8 x^3 dx * 2 pi dy; cos(wo, wi) = -c.
          return double(henyey_greenstein(float(-c), g)) * 16.0 * kPi * x * x * x;
        },
        200'000, 32, 16, 0.01, 4);
    EXPECT_TRUE(r.passed) << r.report;
  }
}

TEST(MediaPhase, HenyeyGreensteinIntegratesToOne) {
  for (float g : {-0.9f, 0.0f, 0.5f, 0.99f}) {
    // Midpoint rule in cos theta (dense where g = 0.99 peaks).
    double sum = 0.0;
    const int n = 2'000'000;
    for (int i = 0; i < n; ++i) sum += henyey_greenstein(-1.0f + 2.0f * (float(i) + 0.5f) / n, g);
    EXPECT_NEAR(sum * 2.0 / n * 2.0 * kPi, 1.0, 2e-3) << "g " << g;
  }
}

// A purely absorbing chromatic slab: free flight passes with weight beta
// whose mean per channel is exp(-sigma_c L); ratio tracking's estimate too.
TEST(MediaTracking, HomogeneousSlabTransmittance) {
  const Medium m = homogeneous(RGB(0.5f, 1.0f, 2.0f), RGB(0.0f));
  const Ray ray{vec3(0.0f), 0.0f, vec3(2.0f, 0.0f, 0.0f), kInfinity};  // |d| = 2: L = 2 * tmax
  const float tmax = 0.75f;
  const RGB expected(std::exp(-0.5f * 1.5f), std::exp(-1.5f), std::exp(-3.0f));
  Estimate delta = estimate(200'000, [&](uint64_t i) {
    TrackingRng rng{i};
    FreeFlight ff = sample_free_flight(m, ray, tmax, RGB(1.0f), rng);
    return ff.event == MediumEvent::None ? ff.beta : RGB(0.0f);
  });
  expect_matches(delta, expected, "delta tracking");
  Estimate ratio = estimate(200'000, [&](uint64_t i) {
    TrackingRng rng{i + 7'000'000};
    return ratio_tracking(m, ray, tmax, rng);
  });
  expect_matches(ratio, expected, "ratio tracking");
}

// A chromatic scattering slab: the throughput-weighted probability of a
// first real scattering event is sigma_s / sigma_t (1 - exp(-sigma_t L)) per
// channel, and it happens at depth t with density sigma_s exp(-sigma_t t).
TEST(MediaTracking, ChromaticScatteringMatchesClosedForm) {
  const RGB sa(0.2f, 0.5f, 0.1f), ss(0.3f, 1.5f, 0.9f);
  const Medium m = homogeneous(sa, ss);
  const Ray ray{vec3(0.0f), 0.0f, vec3(0.0f, 0.0f, 1.0f), kInfinity};
  const float L = 1.5f, half = 0.6f;
  RGB all, first_part;
  for (int c = 0; c < 3; ++c) {
    const float st = sa[c] + ss[c];
    all[c] = ss[c] / st * (1.0f - std::exp(-st * L));
    first_part[c] = ss[c] / st * (1.0f - std::exp(-st * half));
  }
  Estimate scatter = estimate(300'000, [&](uint64_t i) {
    TrackingRng rng{i};
    FreeFlight ff = sample_free_flight(m, ray, L, RGB(1.0f), rng);
    return ff.event == MediumEvent::Scatter ? ff.beta : RGB(0.0f);
  });
  expect_matches(scatter, all, "scattering probability");
  Estimate early = estimate(300'000, [&](uint64_t i) {
    TrackingRng rng{i + 11'000'000};
    FreeFlight ff = sample_free_flight(m, ray, L, RGB(1.0f), rng);
    return ff.event == MediumEvent::Scatter && ff.t < half ? ff.beta : RGB(0.0f);
  });
  expect_matches(early, first_part, "scattering depth");
}

// Through a density grid under a transform: both estimators against a
// 20000-step quadrature of the optical depth, for rays crossing, starting
// inside and stopping inside the box.
TEST(MediaTracking, GridTransmittanceMatchesQuadrature) {
  const Medium m = test_grid();
  const Ray rays[] = {
      {vec3(-3.0f, -1.1f, -0.7f), 0.0f, vec3(1.0f, 0.35f, 0.2f), kInfinity},
      {vec3(0.4f, 0.1f, 0.2f), 0.0f, vec3(-0.3f, 0.5f, -0.8f), kInfinity},
      {vec3(-2.5f, 0.3f, 0.3f), 0.0f, vec3(2.0f, 0.0f, 0.0f), 1.6f},
  };
  Medium global = m;  // one majorant for the whole grid: the same expectations
  global.majorants.clear();
  for (const Ray& ray : rays) {
    const RGB expected = quadrature_transmittance(m, ray, ray.tmax, 20000);
    Estimate coarse = estimate(100'000, [&](uint64_t i) {
      TrackingRng rng{i + 9'000'000};
      return ratio_tracking(global, ray, ray.tmax, rng);
    });
    expect_matches(coarse, expected, "ratio tracking under the global majorant");
    EXPECT_LT(expected.z, 0.9f) << "the ray should cross some density";
    Estimate delta = estimate(100'000, [&](uint64_t i) {
      TrackingRng rng{i};
      Medium absorbing = m;  // scattering counted as absorption: the pass-through weight is T
      absorbing.sigma_a += absorbing.sigma_s;
      absorbing.sigma_s = RGB(0.0f);
      FreeFlight ff = sample_free_flight(absorbing, ray, ray.tmax, RGB(1.0f), rng);
      return ff.event == MediumEvent::None ? ff.beta : RGB(0.0f);
    });
    expect_matches(delta, expected, "delta tracking through the grid");
    Estimate ratio = estimate(100'000, [&](uint64_t i) {
      TrackingRng rng{i + 5'000'000};
      return ratio_tracking(m, ray, ray.tmax, rng);
    });
    expect_matches(ratio, expected, "ratio tracking through the grid");
  }
}

// pbrt-v4's SampledGrid lookup: voxel centres hold their values, halfway
// between two centres is the mean, and density falls to 0 outside the grid.
TEST(MediaGrid, TrilinearBetweenVoxelCentres) {
  Medium m;
  m.kind = MediumKind::UniformGrid;
  m.nx = 2, m.ny = m.nz = 1;
  m.density = {1.0f, 3.0f};
  EXPECT_FLOAT_EQ(medium_density(m, vec3(0.25f, 0.5f, 0.5f)), 1.0f);
  EXPECT_FLOAT_EQ(medium_density(m, vec3(0.75f, 0.5f, 0.5f)), 3.0f);
  EXPECT_FLOAT_EQ(medium_density(m, vec3(0.5f, 0.5f, 0.5f)), 2.0f);
  EXPECT_FLOAT_EQ(medium_density(m, vec3(0.0f, 0.5f, 0.5f)), 0.5f);
  EXPECT_FLOAT_EQ(medium_density(m, vec3(2.0f, 0.5f, 0.5f)), 0.0f);
}

// A grid's emission follows pbrt-v4's one-voxel "Lescale" lookup: Le at the
// box's centre, Le / 2 at a face's centre, Le / 8 at a corner.
TEST(MediaGrid, EmissionScaleAsPbrtLookup) {
  Medium m;
  m.kind = MediumKind::UniformGrid;
  m.density = {1.0f};
  m.Le = RGB(2.0f);
  EXPECT_FLOAT_EQ(medium_props(m, vec3(0.5f)).Le.x, 2.0f);
  EXPECT_FLOAT_EQ(medium_props(m, vec3(0.0f, 0.5f, 0.5f)).Le.x, 1.0f);
  EXPECT_FLOAT_EQ(medium_props(m, vec3(1.0f)).Le.x, 0.25f);
}

// Zero density everywhere: nothing happens and nothing is divided by zero.
TEST(MediaTracking, ZeroDensityPassesUntouched) {
  Medium m = homogeneous(RGB(0.0f), RGB(0.0f));
  const Ray ray{vec3(0.0f), 0.0f, vec3(1.0f, 0.0f, 0.0f), kInfinity};
  TrackingRng rng{1};
  FreeFlight ff = sample_free_flight(m, ray, kInfinity, RGB(0.5f), rng);
  EXPECT_EQ(ff.event, MediumEvent::None);
  EXPECT_EQ(ff.beta, RGB(0.5f));
  EXPECT_EQ(ratio_tracking(m, ray, kInfinity, rng), RGB(1.0f));
}

// ---------------------------------------------------------------- parser

TEST(ParserMedia, HomogeneousGridInterfaceAndCameraMedium) {
  Scene s = parse_scene_string(R"(
    MakeNamedMedium "fog" "string type" "homogeneous" "rgb sigma_a" [0.1 0.2 0.3] "rgb sigma_s" [1 1 1]
      "float scale" 2 "float g" 0.3
    MediumInterface "" "fog"
    Camera "perspective"
    WorldBegin
    AttributeBegin
      Translate 1 0 0
      MakeNamedMedium "smoke" "string type" "uniformgrid" "integer nx" 2 "integer ny" 1 "integer nz" 1
        "float density" [0.5 4] "point3 p0" [-1 -1 -1] "point3 p1" [1 1 1]
      MediumInterface "smoke" ""
      Material "interface"
      Shape "sphere"
    AttributeEnd
    Shape "sphere"
  )", "<test>", ".");
  ASSERT_EQ(s.media.size(), 2u);
  EXPECT_EQ(s.camera_medium, 0);
  // Colours in the working space, "scale" applied.
  const RGB expected_sa = srgb_to_working(RGB(0.2f, 0.4f, 0.6f));
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(s.media[0].sigma_a[c], expected_sa[c], 1e-5f);
  EXPECT_EQ(s.media[0].sigma_s, RGB(2.0f));
  EXPECT_FLOAT_EQ(s.media[0].g, 0.3f);
  EXPECT_EQ(s.media[1].kind, MediumKind::UniformGrid);
  EXPECT_FLOAT_EQ(s.media[1].max_density, 4.0f);
  EXPECT_EQ(s.media[1].render_from_medium.point(vec3(0.0f)), vec3(1.0f, 0.0f, 0.0f));
  ASSERT_EQ(s.shapes.size(), 2u);
  EXPECT_EQ(s.shapes[0].medium_inside, 1);
  EXPECT_EQ(s.shapes[0].medium_outside, -1);
  // AttributeEnd restores the interface current before it: "" inside, "fog" outside.
  EXPECT_EQ(s.shapes[1].medium_inside, -1);
  EXPECT_EQ(s.shapes[1].medium_outside, 0);
  EXPECT_TRUE(s.has_media());
}

TEST(ParserMedia, BadMediaAreErrorsWithLocation) {
  auto error_of = [](const std::string& text) {
    try {
      parse_scene_string(text, "m.pbrt", ".");
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error_of("WorldBegin\nMediumInterface \"nope\"\n").find("m.pbrt:2:"), std::string::npos);
  EXPECT_NE(error_of("WorldBegin\nMakeNamedMedium \"a\" \"string type\" \"nanovdb\"\n").find("nanovdb medium \"a\" without \"string filename\""),
            std::string::npos);
  EXPECT_NE(error_of("WorldBegin\nMakeNamedMedium \"a\" \"string type\" \"fog\"\n").find("m.pbrt:2:"), std::string::npos);
  EXPECT_NE(error_of("WorldBegin\nMakeNamedMedium \"a\" \"string type\" \"uniformgrid\" \"integer nx\" 2 "
                     "\"float density\" [1]\n")
                .find("expected nx*ny*nz = 2"),
            std::string::npos);
  EXPECT_NE(error_of("WorldBegin\nMakeNamedMedium \"a\" \"string type\" \"uniformgrid\" \"float density\" [-1]\n")
                .find("expected >= 0"),
            std::string::npos);
  EXPECT_NE(error_of("WorldBegin\nMakeNamedMedium \"a\" \"string type\" \"homogeneous\" \"float g\" 1\n")
                .find("expected -1 < g < 1"),
            std::string::npos);
  EXPECT_NE(error_of("WorldBegin\nMakeNamedMedium \"a\" \"string type\" \"homogeneous\"\n"
                     "MakeNamedMedium \"a\" \"string type\" \"homogeneous\"\n")
                .find("defined twice"),
            std::string::npos);
}

// Every cell of the majorant grid bounds the density anywhere inside it.
TEST(MediaGrid, MajorantGridBoundsTheDensity) {
  Medium m = test_grid();
  // res^3 cells (media.h: fewer than kMajorantGridRes per axis for a small grid).
  const int res = int(std::lround(std::cbrt(double(m.majorants.size()))));
  ASSERT_EQ(size_t(res) * size_t(res) * size_t(res), m.majorants.size());
  uint64_t k = 0;
  for (int i = 0; i < 200'000; ++i) {
    vec3 u;
    for (int a = 0; a < 3; ++a) u[a] = to_unit_float(uint32_t(hash(k++)));
    const vec3 p = m.p0 + (m.p1 - m.p0) * u;
    const vec3 c = glm::min((p - m.p0) / (m.p1 - m.p0) * float(res), vec3(float(res) - 0.5f));
    const size_t cell = (size_t(c.z) * size_t(res) + size_t(c.y)) * size_t(res) + size_t(c.x);
    ASSERT_LE(medium_density(m, p), m.majorants[cell] + 1e-6f) << p.x << " " << p.y << " " << p.z;
  }
}

// The other heterogeneous types through their majorant grids: a chromatic
// rgbgrid and pbrt-v4's cloud, delta and ratio tracking against the quadrature.
TEST(MediaTracking, RGBGridAndCloudTransmittanceMatchQuadrature) {
  Medium rgb;
  rgb.kind = MediumKind::RGBGrid;
  rgb.nx = rgb.ny = rgb.nz = 4;
  for (int i = 0; i < 64; ++i) {
    rgb.sigma_a_grid.push_back(RGB(float((i * 37) % 11), float((i * 13) % 7), float((i * 5) % 3)) / 5.0f);
    rgb.sigma_s_grid.push_back(RGB(float((i * 7) % 5)) / 5.0f);
  }
  rgb.sigma_a = rgb.sigma_s = RGB(1.5f);  // "scale"
  rgb.p0 = vec3(-1.0f);
  rgb.p1 = vec3(1.0f);
  rgb.render_from_medium = Transform(glm::translate(mat4(1.0f), vec3(0.5f, 0.0f, 0.0f)) * glm::scale(mat4(1.0f), vec3(2.0f)));
  build_majorant_grid(rgb);
  Medium cloud;
  cloud.kind = MediumKind::Cloud;
  cloud.sigma_a = RGB(0.5f, 1.0f, 1.5f);
  cloud.sigma_s = RGB(1.0f);
  cloud.p0 = vec3(-1.0f);
  cloud.render_from_medium = rgb.render_from_medium;
  build_majorant_grid(cloud);
  const Ray rays[] = {
      {vec3(-3.0f, -1.1f, -0.7f), 0.0f, vec3(1.0f, 0.35f, 0.2f), kInfinity},
      {vec3(0.4f, 0.1f, 0.2f), 0.0f, vec3(-0.3f, 0.5f, -0.8f), kInfinity},
  };
  for (const Medium* m : {&rgb, &cloud}) {
    Medium absorbing = *m;  // scattering counted as absorption: the pass-through weight is T
    if (m->kind == MediumKind::RGBGrid) {
      for (size_t i = 0; i < 64; ++i) absorbing.sigma_a_grid[i] += absorbing.sigma_s_grid[i];
      absorbing.sigma_s_grid.assign(64, RGB(0.0f));
    } else {
      absorbing.sigma_a += absorbing.sigma_s;
      absorbing.sigma_s = RGB(0.0f);
    }
    build_majorant_grid(absorbing);
    for (const Ray& ray : rays) {
      const RGB expected = quadrature_transmittance(*m, ray, ray.tmax, 20000);
      EXPECT_LT(expected.x, 0.9f) << "the ray should cross some density";
      Estimate delta = estimate(40'000, [&](uint64_t i) {
        TrackingRng rng{i};
        FreeFlight ff = sample_free_flight(absorbing, ray, ray.tmax, RGB(1.0f), rng);
        return ff.event == MediumEvent::None ? ff.beta : RGB(0.0f);
      });
      expect_matches(delta, expected, "delta tracking");
      Estimate ratio = estimate(40'000, [&](uint64_t i) {
        TrackingRng rng{i + 5'000'000};
        return ratio_tracking(*m, ray, ray.tmax, rng);
      });
      expect_matches(ratio, expected, "ratio tracking");
    }
  }
}

// sealed_media: a medium inside a closed, opaque sphere with every light
// outside is sealed (NEE from it is skipped); anything that could let a
// shadow ray out, or a light in, unseals it.
TEST(MediaSealed, ClosedSphereWithLightsOutsideOnly) {
  auto sealed = [](const std::string& sphere, const std::string& light = "LightSource \"point\" \"point3 from\" [0 5 0]",
                   const std::string& camera_medium = "") {
    const std::string text = fmt::format(R"(
      MakeNamedMedium "milk" "string type" "homogeneous" "rgb sigma_a" [0.2 0.2 0.2] "rgb sigma_s" [20 20 20]
      {}
      Camera "perspective"
      WorldBegin
      LightSource "infinite" "rgb L" [0.1 0.1 0.1]
      {}
      AttributeBegin
        Material "diffuse"
        AreaLightSource "diffuse" "rgb L" [1 1 1]
        Shape "trianglemesh" "integer indices" [0 1 2] "point3 P" [-1 3 -1 1 3 -1 0 3 1]
      AttributeEnd
      AttributeBegin
        Translate 0 0.5 0
        {}
      AttributeEnd
    )", camera_medium, light, sphere);
    Scene s = parse_scene_string(text, "<test>", ".");
    return sealed_media(s).at(0) != 0;
  };
  const std::string glass = R"(MediumInterface "milk" "" Material "dielectric" "float eta" 1.33 )";
  EXPECT_TRUE(sealed(glass + R"(Shape "sphere" "float radius" 0.5)"));
  EXPECT_TRUE(sealed(R"(MediumInterface "milk" "" Material "diffuse" Shape "sphere" "float radius" 0.5)"));
  // Scaled unevenly, the sphere is an ellipsoid: the light at (0, 5, 0) stays outside.
  EXPECT_TRUE(sealed(glass + R"(Scale 1 4 1 Shape "sphere" "float radius" 0.5)"));
  // A light inside (the point light at the sphere's centre; the sphere grown around the area light).
  EXPECT_FALSE(sealed(glass + R"(Shape "sphere" "float radius" 0.5)",
                      R"(LightSource "point" "point3 from" [0 0.5 0])"));
  EXPECT_FALSE(sealed(glass + R"(Shape "sphere" "float radius" 4)"));
  EXPECT_FALSE(sealed(glass + R"(Scale 1 12 1 Shape "sphere" "float radius" 0.5)"));
  // Open spheres, an inward normal, a surface that lets shadow rays through, a cut-out, an emitter.
  EXPECT_FALSE(sealed(glass + R"(Shape "sphere" "float radius" 0.5 "float zmax" 0.3)"));
  EXPECT_FALSE(sealed(glass + R"(Shape "sphere" "float radius" 0.5 "float phimax" 300)"));
  EXPECT_FALSE(sealed(glass + R"(ReverseOrientation Shape "sphere" "float radius" 0.5)"));
  EXPECT_FALSE(sealed(R"(MediumInterface "milk" "" Material "interface" Shape "sphere" "float radius" 0.5)"));
  EXPECT_FALSE(sealed(glass + R"(Shape "sphere" "float radius" 0.5 "float alpha" 0.5)"));
  EXPECT_FALSE(sealed(glass + R"(AreaLightSource "diffuse" "rgb L" [1 1 1] Shape "sphere" "float radius" 0.5)"));
  // The medium outside the sphere, a mesh boundary, the camera in the medium.
  EXPECT_FALSE(sealed(R"(MediumInterface "" "milk" Material "dielectric" Shape "sphere" "float radius" 0.5)"));
  EXPECT_FALSE(sealed(glass + R"(Shape "trianglemesh" "integer indices" [0 1 2] "point3 P" [0 0 0 1 0 0 0 1 0])"));
  EXPECT_FALSE(sealed(glass + R"(Shape "sphere" "float radius" 0.5)", "", R"(MediumInterface "" "milk")"));
}
