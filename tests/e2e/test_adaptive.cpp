// Adaptive sampling, consistent alpha and holdout mattes (seeds/000 5.2.3).
#include "core/metrics.h"
#include "render_helpers.h"

#include <gtest/gtest.h>

using namespace theia;
using namespace theia::test;

namespace {

// Most of the frame sees a constant environment (converged after one
// iteration); a small sphere lit by a tiny bright light is hard.
const char* kUneven = R"(Film "rgb" "integer xresolution" [48] "integer yresolution" [32]
LookAt 0 0 -8  0 0 0  0 1 0
Camera "perspective" "float fov" [40]
WorldBegin
LightSource "infinite" "rgb L" [0.5 0.5 0.5]
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [200 200 200]
  Translate 1.2 1.0 -0.4
  Shape "sphere" "float radius" [0.05]
AttributeEnd
Material "diffuse" "rgb reflectance" [0.8 0.8 0.8]
Translate 1.5 0 0
Shape "sphere" "float radius" [0.9]
Shape "trianglemesh" "point3 P" [-0.5 -1 -1  0.8 -1 -1  0.8 1.5 -1  -0.5 1.5 -1] "integer indices" [0 1 2 0 2 3]
)";

// Two object sets: a wall filling the frame (A) and two spheres in front (B).
std::string two_sets(bool hold_a, bool hold_b) {
  auto h = [](bool on) { return std::string(on ? " \"bool holdout\" true" : ""); };
  return R"(Film "rgb" "integer xresolution" [40] "integer yresolution" [30]
PixelFilter "box"
LookAt 0 0 -5  0 0 0  0 1 0
Camera "perspective" "float fov" [40]
WorldBegin
LightSource "infinite" "rgb L" [1 1 1]
Material "diffuse" "rgb reflectance" [0.5 0.6 0.7]
Shape "trianglemesh" "point3 P" [-9 -9 3  9 -9 3  9 9 3  -9 9 3] "integer indices" [0 1 2 0 2 3])" +
         h(hold_a) + R"(
Shape "sphere" "float radius" [0.7])" + h(hold_b) + R"(
AttributeBegin
  Translate -0.9 0.5 -0.5
  Shape "sphere" "float radius" [0.3])" + h(hold_b) + R"(
AttributeEnd
)";
}

RenderConfig adaptive_config(int spp, bool adaptive) {
  RenderConfig c;
  c.spp = spp;
  c.adaptive.enabled = adaptive;
  c.iteration.first = 4;  // 4 8 16 32 ...: several iterations to adapt over
  c.iteration.repeat = 1;
  return c;
}

float alpha(const ImageBuffer& img, int x, int y) { return pixel_channel(img, x, y, img.channel_index("A")); }

}  // namespace

TEST(ConsistentAlpha, TwoHoldoutPassesSumToOneEverywhereEdgesIncluded) {
  Scene a = load_test_scene(two_sets(false, true));   // pass A: set B held out
  Scene b = load_test_scene(two_sets(true, false));   // pass B: set A held out
  ImageBuffer ia = render_scene(a, adaptive_config(64, true)).image;
  ImageBuffer ib = render_scene(b, adaptive_config(64, true)).image;
  int edges = 0;
  double worst = 0.0;
  for (int y = 0; y < ia.height; ++y)
    for (int x = 0; x < ia.width; ++x) {
      float aa = alpha(ia, x, y), ab = alpha(ib, x, y);
      if (aa > 0.02f && aa < 0.98f) ++edges;
      worst = std::max(worst, std::abs(double(aa) + double(ab) - 1.0));
      // A holdout contributes no colour: where pass B's alpha is 1, pass A is black.
      if (ab == 1.0f) {
        EXPECT_EQ(pixel_rgb(ia, x, y), RGB(0.0f)) << x << " " << y;
      }
    }
  EXPECT_GT(edges, 20) << "the test needs pixels on the silhouettes";
  // The same 64 camera rays per pixel in both passes: the sums are 1 up to
  // the rounding of the two divisions.
  EXPECT_LT(worst, 1e-6);
}

TEST(ConsistentAlpha, AlphaDoesNotDependOnHowAdaptiveSamplingSpentColourSamples) {
  // Colour changes (adaptive sampling moved samples around), alpha does not:
  // it counts samples 0..spp-1 of every pixel, like a uniform render.
  Scene a = load_test_scene(two_sets(false, true));
  ImageBuffer adaptive = render_scene(a, adaptive_config(64, true)).image;
  ImageBuffer uniform = render_scene(a, adaptive_config(64, false)).image;
  EXPECT_GT(max_relative_difference(adaptive, uniform), 1e-3);
  for (int y = 0; y < a.film.height; ++y)
    for (int x = 0; x < a.film.width; ++x) {
      EXPECT_EQ(alpha(adaptive, x, y), alpha(uniform, x, y)) << x << " " << y;
    }
}

TEST(AdaptiveSampling, LowersEqualTimeErrorOnUnevenDifficulty) {
  Scene s = load_test_scene(kUneven);
  // The reference is adaptive too: at 1024 spp its error is ~1/16 of the
  // 64-spp adaptive render's, where a uniform one would be ~ as noisy.
  RenderConfig ref_config = adaptive_config(1024, true);
  ImageBuffer ref = render_scene(s, ref_config).image;
  RenderResult uniform = render_scene(s, adaptive_config(64, false));
  RenderResult adaptive = render_scene(s, adaptive_config(64, true));
  double e_uniform = rel_mse(uniform.image, ref), e_adaptive = rel_mse(adaptive.image, ref);
  double t_uniform = uniform.log["time"]["render"].get<double>(), t_adaptive = adaptive.log["time"]["render"].get<double>();
  // Equal spp: much lower error.  Equal time: error x time (inverse efficiency) lower too.
  EXPECT_LT(e_adaptive, 0.3 * e_uniform) << e_adaptive << " vs " << e_uniform;
  EXPECT_LT(e_adaptive * t_adaptive, 0.5 * e_uniform * t_uniform)
      << "relMSE x seconds: adaptive " << e_adaptive << " x " << t_adaptive << ", uniform " << e_uniform << " x "
      << t_uniform;
}

TEST(AdaptiveSampling, AlphaOnlyRaysKeepMemoryBounded) {
  // Guiding schedule: the last iteration is small, and the pixels that
  // converged early need many alpha-only rays in it (the paper's case).
  Scene s = load_test_scene(kUneven);
  RenderConfig c;
  c.spp = 64;
  c.schedule = "guiding";
  c.max_paths = 4096;
  RenderResult uniform = render_scene(s, c);
  c.adaptive.enabled = true;
  RenderResult adaptive = render_scene(s, c);
  const uint64_t pixels = 48 * 32, colour = 64 * pixels;
  uint64_t alpha_only = adaptive.log["rays"]["camera"].get<uint64_t>() - colour;
  uint64_t last_iteration = uint64_t(adaptive.log["scheduler"]["schedule"].back().get<int>()) * pixels;
  EXPECT_GT(alpha_only, 2 * last_iteration) << "alpha-only rays should outnumber the last iteration's";
  EXPECT_LE(adaptive.log["paths"]["peak_live"].get<size_t>(), 4096u);
  EXPECT_LE(adaptive.log["memory"]["peak_queued_rays"].get<size_t>(), 4096u);
  size_t m_uniform = uniform.log["memory"]["wavefront"].get<size_t>();
  size_t m_adaptive = adaptive.log["memory"]["wavefront"].get<size_t>();
  EXPECT_LT(m_adaptive, 4 * m_uniform) << m_adaptive << " vs " << m_uniform;
  RecordProperty("wavefront_bytes_uniform", std::to_string(m_uniform));
  RecordProperty("wavefront_bytes_adaptive", std::to_string(m_adaptive));
}
