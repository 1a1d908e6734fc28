// End-to-end renders of the "hair" material (pbrt-v4's HairMaterial) on a
// clump of round ("cylinder") curves in a white constant environment: the
// BxDF's unit tests (tests/unit/test_hair.cpp) cannot see how the material
// reaches it at render time (the offset h across the fibre, the frame, the
// absorption), a render can.
#include "tests/e2e/render_helpers.h"

#include <fmt/format.h>

using namespace theia;
using namespace theia::test;

namespace {

// `n` gently bent vertical hairs (one cubic Bezier each) with roots spread
// over a square of side 1 around the origin, in front of a camera on -z:
// about n * width layers deep: 250 hairs of width 0.04 cover most of the
// image, and few paths are still inside after 100 bounces (a diffuse white
// tuft twice as dense lost 1.5% to maxdepth).
std::string hair_tuft(int n, float width) {
  std::string s;
  uint64_t state = 0x9e3779b97f4a7c15ull;
  auto rnd = [&] {  // splitmix-style LCG, deterministic across platforms
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return float(state >> 40) / float(1ull << 24);
  };
  for (int i = 0; i < n; ++i) {
    float x = rnd() - 0.5f, z = rnd() - 0.5f, bend = 0.3f * (rnd() - 0.5f), lean = 0.3f * (rnd() - 0.5f);
    s += fmt::format(
        R"(Shape "curve" "string type" "cylinder" "float width" [{}] "point3 P" [{} -0.9 {}  {} -0.3 {}  {} 0.3 {}  {} 0.9 {}]
)",
        width, x, z, x + bend, z + lean, x - bend, z + lean, x + lean, z - bend);
  }
  return s;
}

struct CoveredMean {
  RGB mean{0.0f};   // over the fully covered pixels
  double sigma = 0;  // spread of a pixel's green value about that mean
  int pixels = 0;
};

// A white furnace (constant environment of radiance 1) around the tuft,
// 32 x 32, maxdepth 100, 64 spp, with the given material line.
CoveredMean render_tuft(const std::string& material) {
  Scene scene = load_test_scene(R"(
    Film "rgb" "integer xresolution" [32] "integer yresolution" [32]
    Sampler "zsobol" "integer pixelsamples" [64]
    Integrator "volpath" "integer maxdepth" [100]
    LookAt 0 0 -3  0 0 0  0 1 0
    Camera "perspective" "float fov" [30]
    WorldBegin
    LightSource "infinite" "rgb L" [1 1 1]
    )" + material + "\n" + hair_tuft(250, 0.04f));
  RenderResult r = render_scene(scene, quick_config(64));
  EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u) << material;
  CoveredMean c;
  glm::dvec3 sum(0.0);
  double sum2 = 0.0;
  for (int y = 0; y < r.image.height; ++y)
    for (int x = 0; x < r.image.width; ++x) {
      RGB v = pixel_rgb(r.image, x, y);
      for (int k = 0; k < 3; ++k) EXPECT_TRUE(std::isfinite(v[k])) << material;
      // Partly the environment.  Not `< 1`: the film's weighted sum of alphas
      // of 1 rounds to either side of 1 with the threads' summation order.
      if (pixel_channel(r.image, x, y, 3) < 0.999f) continue;
      sum += glm::dvec3(v);
      sum2 += double(v.y) * double(v.y);
      ++c.pixels;
    }
  if (c.pixels == 0) return c;
  c.mean = RGB(sum / double(c.pixels));
  c.sigma = std::sqrt(std::max(sum2 / c.pixels - double(c.mean.y) * double(c.mean.y), 0.0));
  fmt::print("{}: {} covered pixels, mean ({:.4f} {:.4f} {:.4f}), pixel sigma {:.4f}\n", material, c.pixels,
             c.mean.x, c.mean.y, c.mean.z, c.sigma);
  return c;
}

}  // namespace

// Without absorption the hair loses nothing (its BxDF integrates to 1), so in
// a white furnace every covered pixel's expectation is 1, less what paths
// still inside the tuft after 100 bounces take away.  The same tuft of
// diffuse white hairs is the control: it tests the scene, not the hair.
TEST(HairFurnace, LosslessHairRendersTheEnvironmentRadiance) {
  for (const char* material : {R"(Material "diffuse" "rgb reflectance" [1 1 1])",
                               R"(Material "hair" "rgb sigma_a" [0 0 0])"}) {
    CoveredMean c = render_tuft(material);
    ASSERT_GT(c.pixels, 100) << material << ": the tuft must cover a good part of the image";
    // The mean of independent pixels within 5 standard errors of 1.
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(c.mean[k], 1.0, 5.0 * c.sigma / std::sqrt(c.pixels)) << material;
  }
}

// Absorbing hair must be darker than the environment: eumelanin 8 (nearly
// black hair, sigma_a = 8 * (0.419, 0.697, 1.37)) and sigma_a 5 keep little
// more than the surface reflection.  Hair that renders ~1 here has lost its
// absorption between the material and the BxDF (at h = +-1 the fibre's
// Fresnel reflectance is 1 and no light enters it).
TEST(HairFurnace, AbsorbingHairIsDarkerThanTheEnvironment) {
  for (const char* material : {R"(Material "hair" "float eumelanin" 8)", R"(Material "hair" "rgb sigma_a" [5 5 5])"}) {
    CoveredMean c = render_tuft(material);
    ASSERT_GT(c.pixels, 100) << material;
    for (int k = 0; k < 3; ++k) {
      EXPECT_LT(c.mean[k], 0.9f) << material;
      EXPECT_GT(c.mean[k], 0.0f) << material << ": the surface reflection still shows";
    }
  }
}

// Hair given by a colour (pbrt-v4's SigmaAFromReflectance): the absorption is
// chosen so that multiply scattered light takes that colour, so the tuft
// keeps the colour's order of channels and is darker than white.
TEST(HairFurnace, ReflectanceColourReachesTheRender) {
  CoveredMean c = render_tuft(R"(Material "hair" "rgb reflectance" [0.8 0.45 0.15])");
  ASSERT_GT(c.pixels, 100);
  EXPECT_GT(c.mean.x, c.mean.y + 0.05f);
  EXPECT_GT(c.mean.y, c.mean.z + 0.05f);
  EXPECT_LT(c.mean.x, 0.95f);
}
