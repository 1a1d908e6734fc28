// The stiff and extreme suite (issue 6; scenes/extreme/README.md).  Every case:
// no NaN/Inf in any output channel, the dropped-sample count in the log,
// bounded memory, and a closed form or a scaled twin to agree with.
#include "core/log.h"
#include "core/metrics.h"
#include "render_helpers.h"
#include "scene/camera.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <string>

using namespace theia;
using namespace theia::test;

namespace {

// A small pool and batches: the memory bound below is then a real bound.
RenderConfig extreme_config(int spp, int max_depth = -1) {
  RenderConfig c = quick_config(spp);
  c.max_depth = max_depth;
  c.max_paths = size_t(1) << 14;
  c.batch_size = size_t(1) << 12;
  return c;
}

void expect_sane(const RenderResult& r, bool expect_no_drops = true) {
  size_t bad = 0;
  for (float v : r.image.data) bad += std::isfinite(v) ? 0 : 1;
  EXPECT_EQ(bad, 0u) << "non-finite values in the output image";
  ASSERT_TRUE(r.log.contains("dropped_samples"));
  if (expect_no_drops) {
    EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
  }
  // Path pool (16k paths) + queued rays: far below this whatever the scene does.
  EXPECT_LT(r.log["memory"]["wavefront"].get<size_t>(), size_t(64) << 20);
  EXPECT_LT(r.log["memory"]["peak_rss"].get<size_t>(), size_t(2) << 30);
}

// A box with a sphere and an area light; `s` scales all of it (camera too),
// `L` is the light's radiance.  Area lights and diffuse surfaces: the image
// does not depend on s, and is linear in L.  `sphere` is the sphere's
// material (a mirror makes caustics on the floor, traced from the light).
std::string box_scene(double s, double L,
                      const std::string& sphere = R"(Material "diffuse" "rgb reflectance" [0.5 0.5 0.8])") {
  return fmt::format(R"(
    Film "rgb" "integer xresolution" [24] "integer yresolution" [24]
    LookAt 0 {1} {2}  0 {1} 0  0 1 0
    Camera "perspective" "float fov" [40]
    WorldBegin
    Scale {0} {0} {0}
    Material "diffuse" "rgb reflectance" [0.7 0.7 0.7]
    Shape "trianglemesh" "point3 P" [-1 0 -1  1 0 -1  1 0 1  -1 0 1   -1 2 -1  1 2 -1  1 2 1  -1 2 1]
      "integer indices" [0 1 2 0 2 3  4 6 5 4 7 6  3 2 6 3 6 7]
    Material "diffuse" "rgb reflectance" [0.7 0.2 0.2]
    Shape "trianglemesh" "point3 P" [-1 0 -1  -1 0 1  -1 2 1  -1 2 -1] "integer indices" [0 1 2 0 2 3]
    Material "diffuse" "rgb reflectance" [0.2 0.7 0.2]
    Shape "trianglemesh" "point3 P" [1 0 -1  1 0 1  1 2 1  1 2 -1] "integer indices" [0 2 1 0 3 2]
    AttributeBegin
      {4}
      Translate 0.3 0.35 0.2
      Shape "sphere" "float radius" [0.35]
    AttributeEnd
    AttributeBegin
      AreaLightSource "diffuse" "rgb L" [{3} {3} {3}] "bool twosided" true
      Shape "trianglemesh" "point3 P" [-0.3 1.98 -0.3  0.3 1.98 -0.3  0.3 1.98 0.3  -0.3 1.98 0.3]
        "integer indices" [0 1 2 0 2 3]
    AttributeEnd
  )",
                     s, 1.0 * s, -3.5 * s, L, sphere);
}

// A white furnace: a constant environment of radiance 1 around surfaces of
// albedo 1, so every pixel is 1 whatever the geometry.
std::string furnace(const std::string& body, int res = 24) {
  return fmt::format(R"(
    Film "rgb" "integer xresolution" [{}] "integer yresolution" [{}]
    LookAt 0 0.3 -4  0 0 0  0 1 0
    Camera "perspective" "float fov" [40]
    WorldBegin
    LightSource "infinite" "rgb L" [1 1 1]
    Material "diffuse" "rgb reflectance" [1 1 1]
    {}
  )",
                     res, res, body);
}

std::string error_of(const std::string& text) {
  try {
    load_test_scene(text);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

// ---------------------------------------------------------------- scale

TEST(ExtremeScale, SameImageAtScale1eMinus4And1e5) {
  RenderResult base = render_scene(load_test_scene(box_scene(1.0, 4.0)), extreme_config(32, 5));
  expect_sane(base);
  for (double s : {1e-4, 1e5}) {
    RenderResult r = render_scene(load_test_scene(box_scene(s, 4.0)), extreme_config(32, 5));
    expect_sane(r);
    // Same random numbers, same paths up to rounding: the twin is the same image.
    EXPECT_LT(channel_mean_deviation(r.image, base.image), 0.01) << "scale " << s;
    EXPECT_LT(rel_mse(r.image, base.image), 1e-3) << "scale " << s;
  }
}

// The caustic pass at the same scales: a mirror sphere's caustic on the
// floor, traced from the light, gives the same image at 1e-4 and 1e5.
TEST(ExtremeScale, CausticsSameImageAtScale1eMinus4And1e5) {
  const std::string mirror = R"(Material "conductor" "float roughness" [0] "rgb eta" [0.2 0.9 1.1] "rgb k" [3.9 2.4 2.1])";
  RenderResult base = render_scene(load_test_scene(box_scene(1.0, 4.0, mirror)), extreme_config(32, 5));
  expect_sane(base);
  ASSERT_TRUE(base.log["caustics"]["traced"].get<bool>());
  EXPECT_GT(base.log["caustics"]["splats"].get<uint64_t>(), 100u);
  for (double s : {1e-4, 1e5}) {
    RenderResult r = render_scene(load_test_scene(box_scene(s, 4.0, mirror)), extreme_config(32, 5));
    expect_sane(r);
    EXPECT_EQ(r.log["caustics"]["dropped"].get<uint64_t>(), 0u) << "scale " << s;
    // Same random numbers, same light paths: (nearly) the same ones reach the camera.
    EXPECT_NEAR(double(r.log["caustics"]["splats"].get<uint64_t>()),
                double(base.log["caustics"]["splats"].get<uint64_t>()),
                0.02 * double(base.log["caustics"]["splats"].get<uint64_t>()))
        << "scale " << s;
    EXPECT_LT(channel_mean_deviation(r.image, base.image), 0.01) << "scale " << s;
    EXPECT_LT(rel_mse(r.image, base.image), 1e-3) << "scale " << s;
  }
}

// ---------------------------------------------------------------- radiance

TEST(ExtremeRadiance, ImageScalesExactlyWithRadiance1eMinus8And1e8) {
  RenderResult base = render_scene(load_test_scene(box_scene(1.0, 1.0)), extreme_config(16, 5));
  expect_sane(base);
  for (double L : {1e-8, 1e8}) {
    RenderResult r = render_scene(load_test_scene(box_scene(1.0, L)), extreme_config(16, 5));
    expect_sane(r);
    ImageBuffer scaled = r.image;
    const size_t nc = scaled.channels.size();
    for (size_t i = 0; i < scaled.pixel_count(); ++i)
      for (size_t c = 0; c < 3; ++c) scaled.data[i * nc + c] /= float(L);
    EXPECT_LT(max_relative_difference(scaled, base.image, 1e-6), 1e-4) << "L " << L;
  }
}

// A 1e-3-wide light of radiance 1e9 below a 10 x 10 one of radiance 1e-3,
// over a diffuse plane, direct light only: pixel = rho / pi * sum over the
// lights of the integral of L cos cos' / d^2 (quadrature in double).
TEST(ExtremeRadiance, TinyBrightLightBesideLargeDimOne) {
  const double rho = 0.8, Lt = 1e9, Ll = 1e-3, ht = 1.0, hl = 3.0, a = 0.5e-3, b = 5.0;
  Scene scene = load_test_scene(fmt::format(R"(
    Film "rgb" "integer xresolution" [32] "integer yresolution" [32]
    PixelFilter "box" "float xradius" [0.5] "float yradius" [0.5]
    LookAt 0 2 0  0 0 0  0 0 1
    Camera "perspective" "float fov" [60]
    WorldBegin
    Material "diffuse" "rgb reflectance" [{0} {0} {0}]
    Shape "trianglemesh" "point3 P" [-20 0 -20  20 0 -20  20 0 20  -20 0 20] "integer indices" [0 1 2 0 2 3]
    AttributeBegin
      AreaLightSource "diffuse" "rgb L" [{1} {1} {1}] "bool twosided" true
      Shape "trianglemesh" "point3 P" [-{3} {2} -{3}  {3} {2} -{3}  {3} {2} {3}  -{3} {2} {3}]
        "integer indices" [0 1 2 0 2 3]
    AttributeEnd
    AttributeBegin
      AreaLightSource "diffuse" "rgb L" [{4} {4} {4}] "bool twosided" true
      Shape "trianglemesh" "point3 P" [-{6} {5} -{6}  {6} {5} -{6}  {6} {5} {6}  -{6} {5} {6}]
        "integer indices" [0 1 2 0 2 3]
    AttributeEnd
  )",
                                            rho, Lt, ht, a, Ll, hl, b));
  RenderResult r = render_scene(scene, extreme_config(32, 1));
  // The camera sees the tiny light itself in a pixel near the centre: that
  // pixel is huge but must stay finite (expect_sane); compare the others.
  expect_sane(r);
  auto irradiance = [](dvec3 p, double L, double h, double half, int n) {
    double E = 0.0, cell = 2.0 * half / n;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        dvec3 q(-half + (i + 0.5) * cell, h, -half + (j + 0.5) * cell);
        dvec3 d = q - p;
        double d2 = glm::dot(d, d), c = d.y / std::sqrt(d2);
        E += L * c * c / d2 * cell * cell;
      }
    return E;
  };
  Camera cam = make_camera(scene.camera, scene.film);
  int checked = 0;
  double worst = 0.0;
  for (int y = 2; y < 32; y += 4)
    for (int x = 2; x < 32; x += 4) {
      if (std::abs(x - 16) < 4 && std::abs(y - 16) < 4) continue;
      auto ray = generate_camera_ray(cam, vec2(x + 0.5f, y + 0.5f), vec2(0.5f));
      dvec3 p = dvec3(ray.o) + double(-ray.o.y / ray.d.y) * dvec3(ray.d);
      double expected = rho / std::numbers::pi * (irradiance(p, Lt, ht, a, 1) + irradiance(p, Ll, hl, b, 200));
      double got = pixel_channel(r.image, x, y, 1);
      worst = std::max(worst, std::abs(got / expected - 1.0));
      ++checked;
    }
  EXPECT_GT(checked, 40);
  EXPECT_LT(worst, 0.05);
}

// ---------------------------------------------------------------- long paths

// scenes/extreme/closed-sphere.pbrt: L = Le / (1 - 0.999) = 1000 Le, paths of
// ~1000 bounces (max depth 10000).  Le is measured by the same scene at depth 0.
TEST(ExtremeLongPaths, ClosedSphereOfAlbedo0999MatchesClosedForm) {
  Scene scene = load_test_scene_file(std::string(THEIA_SCENES) + "/extreme/closed-sphere.pbrt");
  RenderResult emitted = render_scene(scene, extreme_config(1, 0));
  RenderResult r = render_scene(scene, extreme_config(32));
  expect_sane(r);
  EXPECT_EQ(r.log["options"]["max_depth"].get<int>(), 10000);
  RGB Le = image_mean(emitted.image), L = image_mean(r.image);
  for (int c = 0; c < 3; ++c) {
    EXPECT_GT(Le[c], 0.0f);
    EXPECT_NEAR(L[c] / Le[c], 1000.0, 50.0) << "channel " << c;
  }
  EXPECT_GT(r.log["paths"]["average_length"].get<double>(), 500.0);
}

// ---------------------------------------------------------------- geometry

TEST(ExtremeGeometry, GrazingZeroAreaAndCoincidentSurfacesInAWhiteFurnace) {
  Scene scene = load_test_scene(furnace(R"(
    # grazing: a large plane the camera looks along (camera at height 0.3, plane at 0.29)
    Shape "trianglemesh" "point3 P" [-50 0.29 -3  50 0.29 -3  50 0.29 100  -50 0.29 100]
      "integer indices" [0 1 2 0 2 3]
    # zero-area triangles: repeated vertices and collinear points beside a good one
    Shape "trianglemesh" "point3 P" [-1 -1 0  -0.5 -1 0  0 -1 0  -1 -0.5 0]
      "integer indices" [0 0 1  0 1 2  0 2 2  0 1 3]
    # coincident surfaces: the same quad twice, and a sphere inside a sphere of the same radius
    Shape "trianglemesh" "point3 P" [0.2 -1 0  1 -1 0  1 0 0  0.2 0 0] "integer indices" [0 1 2 0 2 3]
    Shape "trianglemesh" "point3 P" [0.2 -1 0  1 -1 0  1 0 0  0.2 0 0] "integer indices" [0 1 2 0 2 3]
    AttributeBegin
      Translate -0.6 -0.6 1
      Shape "sphere" "float radius" [0.3]
      Shape "sphere" "float radius" [0.3]
    AttributeEnd
  )"));
  RenderResult r = render_scene(scene, extreme_config(64, 100));
  expect_sane(r);
  RGB mean = image_mean(r.image);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], 1.0f, 0.01f) << "channel " << c;
  double worst = 0.0;
  for (int y = 0; y < r.image.height; ++y)
    for (int x = 0; x < r.image.width; ++x) worst = std::max(worst, double(std::abs(pixel_channel(r.image, x, y, 1) - 1.0f)));
  EXPECT_LT(worst, 0.1);
}

// Degenerate triangles in an emitting mesh carry no power: the light is the
// same as the good triangles alone (never sampled with an infinite pdf).
TEST(ExtremeGeometry, ZeroAreaTrianglesInALightChangeNothing) {
  auto scene = [](const char* indices) {
    return load_test_scene(fmt::format(R"(
      Film "rgb" "integer xresolution" [16] "integer yresolution" [16]
      LookAt 0 3 -3  0 0 0  0 1 0
      Camera "perspective" "float fov" [50]
      WorldBegin
      Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
      Shape "trianglemesh" "point3 P" [-5 0 -5  5 0 -5  5 0 5  -5 0 5] "integer indices" [0 1 2 0 2 3]
      AttributeBegin
        AreaLightSource "diffuse" "rgb L" [5 5 5] "bool twosided" true
        Shape "trianglemesh" "point3 P" [-0.5 2 -0.5  0.5 2 -0.5  0.5 2 0.5  -0.5 2 0.5  0 2 0]
          "integer indices" [{}]
      AttributeEnd
    )",
                                       indices));
  };
  RenderResult good = render_scene(scene("0 1 2 0 2 3"), extreme_config(32, 3));
  RenderResult degenerate = render_scene(scene("0 1 2 4 4 4 0 2 3 0 4 2 1 1 3"), extreme_config(32, 3));
  expect_sane(good);
  expect_sane(degenerate);
  // "0 4 2" is collinear (4 lies on the diagonal 0-2): zero area too.
  EXPECT_LT(channel_mean_deviation(degenerate.image, good.image), 0.02);
}

// ---------------------------------------------------------------- materials

// Roughness 1e-4 and 1, IOR 1.0001 and 4, in a white furnace: no material may
// create energy (every pixel <= 1) or a non-finite sample.  Until the real
// BSDFs land these parse as grey diffuse; the assertions hold for both.
TEST(ExtremeMaterials, StiffRoughnessAndIorStayFiniteAndConserveEnergy) {
  const char* materials[] = {
      R"(Material "conductor" "float roughness" [0.0001] "spectrum eta" "metal-Ag-eta" "spectrum k" "metal-Ag-k")",
      R"(Material "conductor" "float roughness" [1] "spectrum eta" "metal-Ag-eta" "spectrum k" "metal-Ag-k")",
      R"(Material "dielectric" "float eta" [1.0001] "float roughness" [0])",
      R"(Material "dielectric" "float eta" [4] "float roughness" [0])",
      R"(Material "dielectric" "float eta" [4] "float roughness" [0.0001])",
      R"(Material "dielectric" "float eta" [1.0001] "float roughness" [1])",
      R"(Material "coateddiffuse" "float roughness" [0.0001] "rgb reflectance" [1 1 1])",
  };
  for (const char* m : materials) {
    SCOPED_TRACE(m);
    Scene scene = load_test_scene(furnace(std::string(m) + "\nShape \"sphere\" \"float radius\" [1]", 16));
    RenderResult r = render_scene(scene, extreme_config(64, 50));
    expect_sane(r);
    RGB mean = image_mean(r.image);
    for (int c = 0; c < 3; ++c) EXPECT_LE(mean[c], 1.01f) << "channel " << c;
    // Colour only: the normal AOV is signed.
    float lowest = 0.0f;
    for (size_t i = 0; i < r.image.pixel_count(); ++i)
      for (size_t c = 0; c < 3; ++c) lowest = std::min(lowest, r.image.data[i * r.image.channels.size() + c]);
    EXPECT_GE(lowest, 0.0f);
  }
}

// ---------------------------------------------------------------- bad input

TEST(ExtremeInput, NanInAParameterFileIsAnErrorWithFileAndLine) {
  try {
    load_test_scene_file(std::string(THEIA_SCENES) + "/extreme/nan-reflectance.pbrt");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    std::string msg = e.what();
    EXPECT_NE(msg.find("nan-reflectance.pbrt:9"), std::string::npos) << msg;
    EXPECT_NE(msg.find("finite"), std::string::npos) << msg;
  }
}

TEST(ExtremeInput, InfOverflowAndNegativeParametersAreErrorsWithLine) {
  const std::string head = "Film \"rgb\"\nCamera \"perspective\"\nWorldBegin\n";
  struct Case {
    std::string line, expect;
  } cases[] = {
      {"Shape \"sphere\" \"float radius\" [inf]", "finite"},
      {"Shape \"sphere\" \"float radius\" [-inf]", "finite"},
      {"Shape \"sphere\" \"float radius\" [1e39]", "finite"},
      {"Material \"diffuse\" \"rgb reflectance\" [0.5 -0.1 0.5]", "negative"},
      {"LightSource \"infinite\" \"rgb L\" [-1 1 1]", "negative"},
      {"LightSource \"infinite\" \"spectrum L\" [400 1 500 -2 600 1]", "negative"},
  };
  for (const Case& c : cases) {
    std::string msg = error_of(head + c.line + "\n");
    EXPECT_NE(msg.find("<test>:4"), std::string::npos) << c.line << ": " << msg;
    EXPECT_NE(msg.find(c.expect), std::string::npos) << c.line << ": " << msg;
  }
}

// NaN and Inf texels: clamped to 0 with one warning (a documented clamp,
// scene/README.md); a negative one stays (linear float data); the render stays finite.
TEST(ExtremeInput, NonFiniteTexelsAreClampedWithAWarning) {
  TempDir tmp("theia_extreme_texels");
  ImageBuffer tex;
  tex.width = 4;
  tex.height = 4;
  tex.channels = {"R", "G", "B"};
  tex.data.assign(4 * 4 * 3, 0.5f);
  tex.data[0] = std::numeric_limits<float>::quiet_NaN();
  tex.data[7] = std::numeric_limits<float>::infinity();
  tex.data[20] = -3.0f;
  write_exr(tmp.file("bad.exr"), tex);
  const int warnings_before = warning_count();
  Scene scene = load_test_scene(furnace(fmt::format(R"(
    Texture "bad" "spectrum" "imagemap" "string filename" "{}"
    Material "diffuse" "texture reflectance" "bad"
    Shape "sphere" "float radius" [1]
    LightSource "infinite" "rgb L" [1 1 1]
  )",
                                                    tmp.file("bad.exr")),
                                        16));
  EXPECT_EQ(warning_count(), warnings_before + 1);  // one warning for the image (2 non-finite texels)
  RenderResult r = render_scene(scene, extreme_config(16, 10));
  expect_sane(r);
}
