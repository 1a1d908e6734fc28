// The grid media render what a homogeneous medium renders when their voxels
// are constant: uniformgrid and rgbgrid (through their majorant grids) against
// "homogeneous" in the same scene, compared at the noise level of two
// homogeneous renders with different seeds.
#include "core/metrics.h"
#include "render_helpers.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

using namespace theia;
using namespace theia::test;

namespace {

// An interface sphere of radius 1 holding `medium` (named "m") in a white
// environment: mostly absorbing, so the image follows the optical depth
// (a density 10% low moves the image mean 2.6%, 10 standard errors).
std::string sphere_scene(const std::string& medium) {
  return "Film \"rgb\" \"integer xresolution\" [20] \"integer yresolution\" [20]\n"
         "Integrator \"volpath\" \"integer maxdepth\" [100]\n"
         "LookAt 0 0 -4  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [35]\nWorldBegin\n"
         "LightSource \"infinite\" \"rgb L\" [1 1 1]\n"
         "MakeNamedMedium \"m\" " + medium + "\nMediumInterface \"m\" \"\"\nMaterial \"interface\"\n"
         "Shape \"sphere\" \"float radius\" [1]\n";
}

// 3^3 voxels over [-1.5, 1.5]^3: every point of the sphere lies between voxel
// centres, where the trilinear lookup of constant voxels is exactly the constant.
std::string repeat(const std::string& v, int n) {
  std::string s;
  for (int i = 0; i < n; ++i) s += v + " ";
  return s;
}
const std::string kBox = "\"integer nx\" 3 \"integer ny\" 3 \"integer nz\" 3 \"point3 p0\" [-1.5 -1.5 -1.5] \"point3 p1\" [1.5 1.5 1.5] ";

ImageBuffer render(const std::string& medium, uint32_t seed) {
  RenderConfig c = quick_config(128);
  c.seed = seed;
  RenderResult r = render_scene(load_test_scene(sphere_scene(medium)), c);
  EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u) << medium;
  return r.image;
}

// Two renders of one scene with different seeds: the standard error of the
// difference of their image means, per channel, from the pixels' differences.
RGB mean_difference_sd(const ImageBuffer& a, const ImageBuffer& b) {
  RGB sd(0.0f);
  const double n = double(a.width) * a.height;
  for (int c = 0; c < 3; ++c) {
    double sum = 0.0, sum2 = 0.0;
    for (int y = 0; y < a.height; ++y)
      for (int x = 0; x < a.width; ++x) {
        const double d = double(pixel_channel(a, x, y, c)) - double(pixel_channel(b, x, y, c));
        sum += d, sum2 += d * d;
      }
    sd[c] = float(std::sqrt(std::max(0.0, sum2 / n - (sum / n) * (sum / n)) / n));
  }
  return sd;
}

// `medium` rendered with seed 1 against the homogeneous `reference` (seed 0):
// relMSE at most 1.5x the noise's, and image means within 4 standard errors.
void expect_renders_like(const std::string& medium, const ImageBuffer& reference, const ImageBuffer& other_seed) {
  const double noise = rel_mse(other_seed, reference);
  const RGB sd = mean_difference_sd(other_seed, reference);
  const ImageBuffer image = render(medium, 1);
  const double err = rel_mse(image, reference);
  EXPECT_LT(err, 1.5 * noise) << medium << ": relMSE " << err << " against the noise's " << noise;
  const RGB a = image_mean(image), b = image_mean(reference);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 4.0f * sd[c]) << medium << ", channel " << c;
}

}  // namespace

TEST(MediaGridsE2E, ConstantGridsRenderLikeHomogeneous) {
  const std::string coefficients = "\"rgb sigma_a\" [0.5 0.7 0.9] \"rgb sigma_s\" [0.3 0.3 0.3] \"float g\" 0.4";
  const ImageBuffer reference = render("\"string type\" \"homogeneous\" " + coefficients, 0);
  const ImageBuffer other_seed = render("\"string type\" \"homogeneous\" " + coefficients, 1);
  // The medium shows: it absorbs.
  EXPECT_LT(image_mean(reference).x, 0.9f);
  const std::string grids[] = {
      "\"string type\" \"uniformgrid\" " + kBox + "\"float density\" [" + repeat("1", 27) + "] " + coefficients,
      "\"string type\" \"uniformgrid\" " + kBox + "\"float density\" [" + repeat("4", 27) + "] \"float scale\" 0.25 " +
          coefficients,
      "\"string type\" \"rgbgrid\" " + kBox + "\"rgb sigma_a\" [" + repeat("0.5 0.7 0.9", 27) + "] \"rgb sigma_s\" [" +
          repeat("0.3 0.3 0.3", 27) + "] \"float g\" 0.4",
  };
  for (const std::string& g : grids) expect_renders_like(g, reference, other_seed);
}

// Emission: an rgbgrid's constant Le grid (times Lescale) glows as a
// homogeneous medium's Le does.
TEST(MediaGridsE2E, ConstantEmissiveRGBGridRendersLikeHomogeneous) {
  const std::string coefficients = "\"rgb sigma_a\" [0.5 0.5 0.5] \"rgb sigma_s\" [0.5 0.5 0.5]";
  const ImageBuffer reference = render("\"string type\" \"homogeneous\" \"rgb Le\" [0.5 0.25 1] " + coefficients, 0);
  const ImageBuffer other_seed = render("\"string type\" \"homogeneous\" \"rgb Le\" [0.5 0.25 1] " + coefficients, 1);
  EXPECT_GT(image_mean(reference).z, image_mean(reference).x + 0.01f) << "the medium should glow blue";
  expect_renders_like("\"string type\" \"rgbgrid\" " + kBox + "\"rgb sigma_a\" [" + repeat("0.5 0.5 0.5", 27) +
                          "] \"rgb sigma_s\" [" + repeat("0.5 0.5 0.5", 27) + "] \"rgb Le\" [" + repeat("0.25 0.125 0.5", 27) +
                          "] \"float Lescale\" 2",
                      reference, other_seed);
}
