// End-to-end renders of shapes: pbrt-v4's cylinder against a closed form (a
// diffuse plane under a cylinder area light given by "power": pbrt-v4's
// object-space area, one-sided outward emission, area sampling and MIS
// together), and curves in a white furnace.
#include "core/log.h"
#include "render_helpers.h"
#include "scene/camera.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

using namespace theia;
using namespace theia::test;

// A horizontal cylinder (axis along x, radius 0.25, length 2, centre height
// 1.2) of power 10 above a diffuse plane, seen from a camera between the two
// looking down.  Its radiance is phi / (pi * 2 pi r * 2), and the plane's
// L = rho / pi * integral of L cos cos / d^2 over the cylinder's side that
// faces the point (the other side faces away; the open ends emit nothing).
TEST(CylinderLight, DiffusePlaneMatchesTheIrradianceIntegral) {
  const float rho = 0.5f, phi = 10.0f, radius = 0.25f, height = 1.2f;
  Scene scene = load_test_scene(R"(
    Film "rgb" "integer xresolution" [24] "integer yresolution" [24]
    PixelFilter "box" "float xradius" [0.5] "float yradius" [0.5]
    LookAt 0 0.8 0  0 0 0  0 0 1
    Camera "perspective" "float fov" [90]
    WorldBegin
    AttributeBegin
    Material "diffuse" "rgb reflectance" [0 0 0]
    AreaLightSource "diffuse" "float power" 10
    Translate 0 1.2 0
    Rotate 90 0 1 0
    Shape "cylinder" "float radius" 0.25 "float zmin" -1 "float zmax" 1
    AttributeEnd
    Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
    Shape "trianglemesh" "point3 P" [-10 0 -10  10 0 -10  10 0 10  -10 0 10]
      "integer indices" [0 1 2 0 2 3]
  )");
  const double L = phi / (kPi * 2.0 * kPi * radius * 2.0);
  auto predicted = [&](const vec3& p) {
    // Rotate 90 about y takes object (x, y, z) to (z, y, -x).
    const int n_phi = 256, n_z = 64;
    double e = 0.0;
    for (int i = 0; i < n_phi; ++i) {
      double a = 2.0 * M_PI * (i + 0.5) / n_phi;
      glm::dvec3 n(0.0, std::sin(a), -std::cos(a));
      for (int j = 0; j < n_z; ++j) {
        double z = -1.0 + 2.0 * (j + 0.5) / n_z;
        glm::dvec3 q(z, height + radius * std::sin(a), -radius * std::cos(a));
        glm::dvec3 d = glm::dvec3(p) - q;
        double d2 = glm::dot(d, d);
        double cos_l = glm::dot(n, d) / std::sqrt(d2), cos_p = -d.y / std::sqrt(d2);
        if (cos_l > 0.0 && cos_p > 0.0) e += cos_l * cos_p / d2;
      }
    }
    return rho / kPi * L * e * (2.0 * M_PI * radius / n_phi) * (2.0 / n_z);
  };
  RenderResult r = render_scene(scene, quick_config(256));
  Camera cam = make_camera(scene.camera, scene.film);
  // Under the cylinder (|z| small) and to either side of it; one pixel is
  // noisy to a few percent at 256 spp, a sum over ~190 to well under 1%.
  expect_region_sums_match(
      r.image, cam, 3, [](vec3 p) { return std::abs(p.z) < 0.25f ? 0 : p.z > 0.0f ? 1 : 2; }, predicted, 0.01,
      {"under", "+z side", "-z side"});
  EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
}

namespace {

// A clump of `n` hairs rising from the unit disk around the origin: degree 3
// b-splines of 6 control points (3 segments each), tapering from width0 to
// width1, deterministic positions.
std::string hair_clump(int n, const std::string& type, float width0, float width1) {
  std::string s;
  uint32_t state = 12345u;
  auto next = [&] {
    state = state * 1664525u + 1013904223u;
    return float(state >> 8) / float(1u << 24);
  };
  for (int i = 0; i < n; ++i) {
    float a = 6.2831853f * next(), r = 0.6f * std::sqrt(next());
    float x = r * std::cos(a), z = r * std::sin(a);
    std::string p;
    for (int k = 0; k < 6; ++k) {
      float h = -0.8f + 0.32f * float(k);
      p += fmt::format("{} {} {}  ", x + 0.15f * (next() - 0.5f), h, z + 0.15f * (next() - 0.5f));
    }
    s += fmt::format(R"(Shape "curve" "string basis" "bspline" "string type" "{}" "float width0" [{}] "float width1" [{}] "point3 P" [{}]
)",
                     type, width0, width1, p);
    // Ribbons twist along the hair but keep facing the camera (on -z) enough to be seen.
    if (type == "ribbon")
      s.insert(s.size() - 1, fmt::format(R"( "normal N" [{} 0 -1  0 {} -1  {} 0 -1  0 0 -1])", z, x, -z));
  }
  return s;
}

}  // namespace

// A white furnace around curves: albedo-1 diffuse hairs of every type in a
// constant environment of radiance 1.  Every path ends in the environment with
// expected throughput 1, so every pixel's expectation is 1 whatever the
// geometry; what a pixel shows beyond that is the estimator's noise (light
// sampling vs BSDF sampling under MIS, Russian roulette), which shrinks as
// 1/sqrt(spp).  A ray that leaks into or gets stuck on the thin geometry is a
// bias instead: it moves the mean and does not shrink with spp.  Measured
// (this clump, 300 hairs): rms |L - 1| over the image 0.022 / 0.010 / 0.005 at
// 32 / 128 / 512 spp, worst pixel 0.19 / 0.055 / 0.031 (flat): noise.
TEST(CurveFurnace, AlbedoOneHairsRenderTheEnvironmentRadiance) {
  for (std::string type : {"flat", "cylinder", "ribbon"}) {
    Scene scene = load_test_scene(R"(
      Film "rgb" "integer xresolution" [32] "integer yresolution" [32]
      Sampler "zsobol" "integer pixelsamples" [32]
      Integrator "volpath" "integer maxdepth" [200]
      LookAt 0 0 -3  0 0 0  0 1 0
      Camera "perspective" "float fov" [45]
      WorldBegin
      LightSource "infinite" "rgb L" [1 1 1]
      Material "diffuse" "rgb reflectance" [1 1 1]
    )" + hair_clump(400, type, 0.03f, 0.005f));
    // Per render: coverage, image mean, rms of L - 1 over the covered pixels
    // (the pixel noise sigma: the expectation is 1), worst |L - 1|.
    struct Stats {
      double coverage = 0, covered = 0, rms = 0, worst = 0;  // mean alpha; pixels with alpha > 0
      RGB mean;
    };
    auto render = [&](int spp) {
      RenderResult r = render_scene(scene, quick_config(spp));
      EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u) << type;
      Stats st;
      st.mean = image_mean(r.image);
      double sum2 = 0.0;
      for (int y = 0; y < r.image.height; ++y)
        for (int x = 0; x < r.image.width; ++x) {
          st.coverage += pixel_channel(r.image, x, y, 3);
          st.covered += pixel_channel(r.image, x, y, 3) > 0.0f;
          for (int c = 0; c < 3; ++c) {
            float v = pixel_channel(r.image, x, y, c);
            EXPECT_TRUE(std::isfinite(v)) << type;
            sum2 += (double(v) - 1.0) * (double(v) - 1.0);
            st.worst = std::max(st.worst, std::abs(double(v) - 1.0));
          }
        }
      st.rms = std::sqrt(sum2 / (3.0 * std::max(st.covered, 1.0)));
      st.coverage /= double(r.image.width * r.image.height);
      return st;
    };
    Stats lo = render(32), hi = render(128);
    fmt::print("{}: coverage {:.3f}; 32 spp: mean {:.5f}, sigma {:.4f}, worst {:.4f}; 128 spp: mean {:.5f}, sigma "
               "{:.4f}, worst {:.4f}\n",
               type, hi.coverage, lo.mean.x, lo.rms, lo.worst, hi.mean.x, hi.rms, hi.worst);
    EXPECT_GT(hi.coverage, 0.2) << type << ": the hairs must cover a good part of the image";
    // Noise, not a leak: 4x the samples halve the pixel deviations (0.5; a
    // bias would keep the ratio near 1).
    EXPECT_LT(hi.rms / lo.rms, 0.65) << type;
    // The image mean is 1 within 5 standard errors (pixels are independent).
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(hi.mean[c], 1.0, 5.0 * hi.rms * std::sqrt(hi.covered) / 1024.0) << type;
    // And no pixel is an outlier of that noise.
    EXPECT_LT(hi.worst, 6.0 * hi.rms) << type;
  }
}

// A hair-like clump (b-spline round hairs, tapered, under a transform and
// instanced) loads without a single warning and renders something finite.
TEST(CurveScene, HairClumpLoadsWithoutWarningsAndRenders) {
  int before = warning_count();
  Scene scene = load_test_scene(R"(
    Film "rgb" "integer xresolution" [24] "integer yresolution" [24]
    Sampler "zsobol" "integer pixelsamples" [8]
    LookAt 0 0.5 -3  0 0 0  0 1 0
    Camera "perspective" "float fov" [50]
    WorldBegin
    LightSource "distant" "point3 from" [1 2 -1] "point3 to" [0 0 0] "rgb L" [3 3 3]
    Material "coateddiffuse" "rgb reflectance" [0.4 0.25 0.1]
    ObjectBegin "tuft"
    )" + hair_clump(60, "cylinder", 0.02f, 0.002f) + R"(
    ObjectEnd
    AttributeBegin Translate -0.5 0 0 ObjectInstance "tuft" AttributeEnd
    AttributeBegin Translate 0.5 0 0 Rotate 30 0 1 0 Scale 0.8 0.8 0.8 ObjectInstance "tuft" AttributeEnd
  )");
  EXPECT_EQ(warning_count(), before);
  EXPECT_EQ(scene.curves.size(), 60u);
  RenderResult r = render_scene(scene, quick_config(8));
  EXPECT_EQ(warning_count(), before);
  double lit = 0.0;
  for (int y = 0; y < r.image.height; ++y)
    for (int x = 0; x < r.image.width; ++x) {
      for (int c = 0; c < 3; ++c) ASSERT_TRUE(std::isfinite(pixel_channel(r.image, x, y, c)));
      lit += pixel_channel(r.image, x, y, 0);
    }
  EXPECT_GT(lit, 0.0);
}

// One straight flat (ray-facing) hair under a distant light, seen face-on:
// its normal faces the camera, so every fully covered pixel is
// rho / pi * E * cos, and nothing about the ribbon shadows itself.
TEST(CurveScene, FlatHairUnderADistantLightMatchesTheAnalyticRadiance) {
  Scene scene = load_test_scene(R"(
    Film "rgb" "integer xresolution" [32] "integer yresolution" [16]
    PixelFilter "box" "float xradius" [0.5] "float yradius" [0.5]
    LookAt 0 0 -3  0 0 0  0 1 0
    Camera "perspective" "float fov" [10]
    WorldBegin
    LightSource "distant" "point3 from" [0 1 -1] "point3 to" [0 0 0] "rgb L" [3 3 3]
    Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
    Shape "curve" "string type" "flat" "point3 P" [-2 0 0  -0.7 0 0  0.7 0 0  2 0 0] "float width" [0.2]
  )");
  RenderResult r = render_scene(scene, quick_config(16));
  // The ribbon faces the camera (normal -z); the light arrives from (0, 1, -1).
  const double want = 0.5 / kPi * 3.0 * std::sqrt(0.5);
  int checked = 0;
  for (int y = 7; y <= 8; ++y)  // the rows the 0.2-wide ribbon covers entirely (about 6 pixels tall)
    for (int x = 0; x < 32; ++x) {
      EXPECT_NEAR(pixel_channel(r.image, x, y, 1) / want, 1.0, 0.02) << x << " " << y;
      ++checked;
    }
  EXPECT_EQ(checked, 64);
  EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
}
