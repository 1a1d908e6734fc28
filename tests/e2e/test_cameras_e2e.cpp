// End-to-end renders through the orthographic and spherical cameras, with
// the signed Mitchell and Lanczos filters, against closed forms: a diffuse
// plane under a distant light seen orthographically, and the inside of a
// uniformly emissive sphere seen by both spherical mappings.  Every pixel has
// the same analytic value, so whatever a filter weighs (negative lobes
// included) the resolved pixel must equal it: sum(w L) / sum(w) = L.
#include "render_helpers.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace theia;
using namespace theia::test;

namespace {

// Largest relative deviation of channel c from `expected` over the image.
float worst_deviation(const ImageBuffer& img, int c, float expected) {
  float worst = 0.0f;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      float v = pixel_channel(img, x, y, c);
      worst = std::isfinite(v) ? std::max(worst, std::abs(v - expected) / expected) : INFINITY;
    }
  return worst;
}

}  // namespace

std::string orthographic_plane(const std::string& filter) {
  return R"(
      Film "rgb" "integer xresolution" [24] "integer yresolution" [16]
      PixelFilter )" + filter + R"(
      LookAt 0 4 -4  0 0 0  0 1 0
      Camera "orthographic" "float screenwindow" [-3 3 -2 2]
      WorldBegin
      LightSource "distant" "rgb L" [3 2 1] "point3 from" [0.5 1 -0.25] "point3 to" [0 0 0]
      Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
      Shape "trianglemesh" "point3 P" [-20 0 -20  20 0 -20  20 0 20  -20 0 20]
        "integer indices" [0 1 2 0 2 3]
    )";
}

// An orthographic camera looking down at 45 degrees onto a diffuse plane lit
// by a distant light: L = rho / pi * E cos(theta) at every pixel.
TEST(CameraE2E, OrthographicDiffusePlaneUnderDistantLight) {
  for (const char* filter : {"\"mitchell\"", "\"sinc\"", "\"gaussian\""}) {
    Scene scene = load_test_scene(orthographic_plane(filter));
    ASSERT_EQ(scene.camera.kind, CameraKind::Orthographic);
    // 64 spp: no pixel's signed weights cancel (see below).
    RenderResult r = render_scene(scene, quick_config(64));
    const float cos_theta = 1.0f / glm::length(vec3(0.5f, 1.0f, -0.25f));
    for (int c = 0; c < 3; ++c) {
      const float expected = 0.5f / kPi * float(3 - c) * cos_theta;
      EXPECT_LT(worst_deviation(r.image, c, expected), 1e-3f) << filter << " channel " << c;
    }
    EXPECT_LT(worst_deviation(r.image, 3, 1.0f), 1e-4f) << filter << " alpha";
    EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
  }
  // At 4 spp some sinc pixels draw as many negative as positive weights
  // (+-integral(|table|) each, as pbrt-v4), which cancel exactly: such a
  // pixel is black with alpha 0, as pbrt-v4 leaves it; every other pixel is
  // the analytic value, and none is NaN or garbage.
  {
    Scene scene = load_test_scene(orthographic_plane("\"sinc\""));
    RenderResult r = render_scene(scene, quick_config(4));
    const float expected = 0.5f / kPi * 3.0f / glm::length(vec3(0.5f, 1.0f, -0.25f));
    int cancelled = 0;
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 24; ++x) {
        float v = pixel_channel(r.image, x, y, 0), a = pixel_channel(r.image, x, y, 3);
        if (v == 0.0f && a == 0.0f) {
          ++cancelled;
        } else {
          ASSERT_NEAR(v, expected, 1e-3f * expected) << x << " " << y;
        }
      }
    EXPECT_GT(cancelled, 0);  // the case is exercised
    EXPECT_LT(cancelled, 16 * 24 / 4);
  }
  // The rays are parallel: with every sample at its pixel centre (a tiny
  // box), the depth (channel 10) is the same along a row, 4 sqrt(2) at the
  // image centre, and 0.25 less per row down the image (camera -y by 0.25,
  // which is 0.25 along the view on this 45-degree plane); a perspective
  // camera's would vary along the rows too.
  Scene scene = load_test_scene(orthographic_plane("\"box\" \"float xradius\" 1e-4 \"float yradius\" 1e-4"));
  RenderResult r = render_scene(scene, quick_config(1));
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 24; ++x) {
      float want = 4.0f * std::sqrt(2.0f) - (float(y) + 0.5f - 8.0f) * 0.25f;
      ASSERT_NEAR(pixel_channel(r.image, x, y, 10), want, 1e-3f) << x << " " << y;
    }
}

// A spherical camera at the centre of a two-sided emissive sphere with a
// black surface sees L in every direction: every pixel of the equal-area and
// the equirectangular image, edges (where filter offsets leave the square
// and wrap) and poles included, is L.
TEST(CameraE2E, SphericalCameraInsideAnEmissiveSphereSeesTheConstant) {
  for (const char* mapping : {"equalarea", "equirectangular"})
    for (const char* filter : {"sinc", "mitchell"}) {
      Scene scene = load_test_scene(std::string(R"(
        Film "rgb" "integer xresolution" [32] "integer yresolution" [32]
        PixelFilter ")") + filter + R"("
        LookAt 0.3 -0.2 0.1  1 2 3  0 0 1
        Camera "spherical" "string mapping" ")" + mapping + R"("
        WorldBegin
        AttributeBegin
        AreaLightSource "diffuse" "rgb L" [0.3 0.5 0.7] "bool twosided" true
        Material "diffuse" "rgb reflectance" [0 0 0]
        Shape "sphere" "float radius" 2
        AttributeEnd
      )");
      ASSERT_EQ(scene.camera.kind, CameraKind::Spherical);
      // Enough samples that no pixel's signed weights cancel (it would be
      // black, as the orthographic test shows).
      RenderResult r = render_scene(scene, quick_config(64));
      for (int c = 0; c < 3; ++c)
        EXPECT_LT(worst_deviation(r.image, c, 0.3f + 0.2f * float(c)), 1e-4f)
            << mapping << " " << filter << " channel " << c;
      EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
    }
}
