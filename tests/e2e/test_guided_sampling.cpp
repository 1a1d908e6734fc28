// Guided directional sampling in the engine, with analytic guides (no
// learning): whatever the guide proposes, RIS and the one-sample mixture of
// guide and BSDF must leave the estimator unbiased, with NEE's MIS weights
// and the emission-hit weights taken against the mixture's pdf.
#include "render_helpers.h"
#include "core/directional_guide.h"
#include "wavefront/engine.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace theia;
using namespace theia::test;

namespace {

// A von Mises-Fisher lobe about `mean` (sharpness kappa), in region 0 for
// points with x above `valid_above_x` and nowhere else.
class VMFGuide final : public DirectionalGuide {
 public:
  VMFGuide(vec3 mean, float kappa, float fraction, float valid_above_x = -kInfinity)
      : mean_(glm::normalize(mean)), kappa_(kappa), fraction_(fraction), valid_above_x_(valid_above_x) {}
  uint32_t region(const vec3& p) const override { return p.x > valid_above_x_ ? 0u : kNoGuideRegion; }
  GuideSample sample(uint32_t, vec2 u) const override {
    float w = 1.0f + std::log(u.x + (1.0f - u.x) * std::exp(-2.0f * kappa_)) / kappa_;
    w = std::clamp(w, -1.0f, 1.0f);
    float s = std::sqrt(std::max(0.0f, 1.0f - w * w)), phi = 2.0f * kPi * u.y;
    Frame f = Frame::from_z(mean_);
    vec3 wi = glm::normalize(f.from_local(vec3(s * std::cos(phi), s * std::sin(phi), w)));
    return {wi, pdf(0, wi)};
  }
  float pdf(uint32_t, const vec3& wi) const override {
    return kappa_ / (2.0f * kPi * (1.0f - std::exp(-2.0f * kappa_))) *
           std::exp(kappa_ * (glm::dot(mean_, wi) - 1.0f));
  }
  float selection_probability(uint32_t) const override { return fraction_; }

 private:
  vec3 mean_;
  float kappa_, fraction_, valid_above_x_;
};

const GuideMixing kMixings[] = {GuideMixing::Resampled, GuideMixing::OneSampleMIS};
const char* mixing_name(GuideMixing m) { return m == GuideMixing::Resampled ? "RIS" : "MIS"; }

struct Rendered {
  ImageBuffer image;
  double path_length = 0.0;  // surface hits per path
};

Rendered render_with(const Scene& scene, const DirectionalGuide* guide, int spp, int max_depth = 50,
                     GuideMixing mixing = GuideMixing::Resampled) {
  RenderableScene rs(scene);
  EngineOptions opt;
  opt.max_depth = max_depth;
  opt.guiding.mixing = mixing;
  Film film(scene.film.width, scene.film.height);
  WavefrontEngine engine(rs, film, opt, EngineHooks{.guide = guide});
  engine.render(0, uint32_t(spp));
  const EngineStats& st = engine.stats();
  return {resolve_film(film), double(st.path_vertices) / double(std::max<uint64_t>(st.paths, 1))};
}

// Mean and standard error of the mean of one channel over a pixel block.
struct BlockStats {
  double mean = 0.0, stderr_mean = 0.0;
};
BlockStats block_stats(const ImageBuffer& img, int x0, int y0, int n, int c) {
  double s = 0.0, s2 = 0.0;
  for (int y = y0; y < y0 + n; ++y)
    for (int x = x0; x < x0 + n; ++x) {
      double v = pixel_channel(img, x, y, c);
      s += v;
      s2 += v * v;
    }
  double m = s / (n * n), var = std::max(0.0, s2 / (n * n) - m * m);
  return {m, std::sqrt(var / (n * n))};
}

}  // namespace

// A diffuse sphere of albedo 1 in a constant environment: every pixel on the
// sphere is exactly 1 in expectation.  Guided with a lobe that has nothing
// to do with the lighting, samples are no longer all 1, but their mean is.
TEST(GuidedSampling, WhiteFurnaceStaysOneUnderAnyGuide) {
  Scene scene = load_test_scene(furnace_sphere_scene(32, 18.0f, 1.0f));
  VMFGuide guide(vec3(0.3f, 1.0f, -0.2f), 20.0f, 0.7f);
  for (GuideMixing mixing : kMixings) {
  SCOPED_TRACE(mixing_name(mixing));
  ImageBuffer img = render_with(scene, &guide, 128, 50, mixing).image;
  double sum = 0.0;
  int covered = 0, off = 0;
  for (int y = 4; y < 28; ++y)
    for (int x = 4; x < 28; ++x) {
      if (pixel_channel(img, x, y, 3) < 1.0f) continue;
      float v = pixel_channel(img, x, y, 1);
      sum += v;
      ++covered;
      off += std::abs(v - 1.0f) > 0.25f;
    }
  ASSERT_GT(covered, 300);
  // Guided samples are not all 1, so noise is expected; its mean is 1.
  EXPECT_NEAR(sum / covered, 1.0, 0.01);
  EXPECT_LT(off, covered / 50);
  }
}

// A guide whose every direction lies below the Cornell box's floor, active
// only on the floor: RIS never picks such a direction (its target is zero
// there), so paths are as long as unguided ones; one-sample MIS loses its
// guided draws there (the reason RIS is the default).
TEST(GuidedSampling, GuideBelowTheSurfaceEndsNoPathUnderRIS) {
  Scene scene = load_test_scene_file(std::string(THEIA_SCENES) + "/cornell-box/scene.pbrt");
  scene.film.width = scene.film.height = 32;
  class IntoTheFloor final : public DirectionalGuide {
   public:
    uint32_t region(const vec3& p) const override { return p.y < 1e-3f ? 0u : kNoGuideRegion; }
    GuideSample sample(uint32_t, vec2 u) const override { return lobe_.sample(0, u); }
    float pdf(uint32_t, const vec3& wi) const override { return lobe_.pdf(0, wi); }
    float selection_probability(uint32_t) const override { return 0.5f; }

   private:
    VMFGuide lobe_{vec3(0.0f, -1.0f, 0.0f), 200.0f, 0.5f};
  } down;
  const double plain = render_with(scene, nullptr, 64, 8).path_length;
  const double ris = render_with(scene, &down, 64, 8, GuideMixing::Resampled).path_length;
  const double mis = render_with(scene, &down, 64, 8, GuideMixing::OneSampleMIS).path_length;
  std::printf("path length: unguided %.4f, RIS %.4f, MIS %.4f\n", plain, ris, mis);
  EXPECT_NEAR(ris / plain, 1.0, 0.01);
  EXPECT_LT(mis / plain, 0.97);
}

// The Cornell box: guided renders (a lobe towards the light, one away from
// it, one that guides only half the box) agree with the unguided render
// block by block within their noise.  Getting the mixture pdf wrong in NEE's
// MIS weight or in the emission-hit weight shifts every block.
TEST(GuidedSampling, CornellBoxAgreesWithUnguidedBlockByBlock) {
  Scene scene = load_test_scene_file(std::string(THEIA_SCENES) + "/cornell-box/scene.pbrt");
  scene.film.width = scene.film.height = 48;
  const int spp = 256;
  ImageBuffer plain = render_with(scene, nullptr, spp, 8).image;
  VMFGuide up(vec3(0.0f, 1.0f, 0.0f), 8.0f, 0.5f), away(vec3(0.2f, -1.0f, 0.4f), 30.0f, 0.5f),
      half(vec3(-1.0f, 0.3f, 0.0f), 4.0f, 0.9f, 0.0f);
  for (GuideMixing mixing : kMixings)
  for (const VMFGuide* g : {&up, &away, &half}) {
    SCOPED_TRACE(mixing_name(mixing));
    ImageBuffer guided = render_with(scene, g, spp, 8, mixing).image;
    int worse = 0, blocks = 0;
    double chi2 = 0.0;
    for (int by = 0; by < 48; by += 8)
      for (int bx = 0; bx < 48; bx += 8)
        for (int c = 0; c < 3; ++c) {
          BlockStats a = block_stats(plain, bx, by, 8, c), b = block_stats(guided, bx, by, 8, c);
          // The block means of two independent renders differ by noise whose
          // variance is the sum of theirs (pixel spread / 64 per block).
          double sigma = std::sqrt(sqr(a.stderr_mean) + sqr(b.stderr_mean)) + 1e-4 * a.mean;
          double z = (b.mean - a.mean) / sigma;
          chi2 += z * z;
          worse += std::abs(z) > 4.0;
          ++blocks;
        }
    // The pixel spread over a block includes the image's own structure, so
    // these sigmas overestimate the noise: a biased estimator still shows as
    // a shifted mean over all blocks.
    EXPECT_EQ(worse, 0);
    EXPECT_LT(chi2 / blocks, 2.0);
    RGB mp = image_mean(plain), mg = image_mean(guided);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(mg[c] / mp[c], 1.0, 0.01) << "channel " << c;
  }
}
