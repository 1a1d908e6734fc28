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
  VMFGuide(vec3 mean, float kappa, float fraction, float valid_above_x = -kInfinity, float integral = 1.0f)
      : mean_(glm::normalize(mean)),
        kappa_(kappa),
        fraction_(fraction),
        valid_above_x_(valid_above_x),
        integral_(integral) {}
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
  float radiance_integral(uint32_t) const override { return integral_; }

 private:
  vec3 mean_;
  float kappa_, fraction_, valid_above_x_, integral_;
};

const GuideMixing kMixings[] = {GuideMixing::Resampled, GuideMixing::OneSampleMIS};
const char* mixing_name(GuideMixing m) { return m == GuideMixing::Resampled ? "RIS" : "MIS"; }

struct Rendered {
  ImageBuffer image;
  double path_length = 0.0;  // surface hits per path
};

Rendered render_with(const Scene& scene, const DirectionalGuide* guide, int spp, int max_depth = 50,
                     GuideMixing mixing = GuideMixing::Resampled, bool adjoint_roulette = false,
                     float roulette_floor = GuidedSampling{}.roulette_floor) {
  RenderableScene rs(scene);
  EngineOptions opt;
  opt.max_depth = max_depth;
  opt.guiding.mixing = mixing;
  opt.guiding.adjoint_roulette = adjoint_roulette;
  opt.guiding.roulette_floor = roulette_floor;
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

// Adjoint-driven roulette follows the field, not the throughput: where the
// field is one sharp lobe, continuations outside it are expected to bring
// little and mostly end (shorter paths than the throughput rule); where it
// is uniform, every continuation is expected to bring about what the pixel
// gets and survives (longer paths).  The Cornell block test checks the mean.
// A low floor (0.1), so that the field and not the floor decides.
TEST(GuidedSampling, AdjointRouletteSurvivalFollowsTheField) {
  Scene scene = load_test_scene_file(std::string(THEIA_SCENES) + "/cornell-box/scene.pbrt");
  scene.film.width = scene.film.height = 32;
  VMFGuide sharp(vec3(0.0f, 1.0f, 0.0f), 200.0f, 0.5f), flat(vec3(0.0f, 1.0f, 0.0f), 0.01f, 0.5f);
  auto length = [&](const VMFGuide& g, bool adjoint) {
    return render_with(scene, &g, 32, 16, GuideMixing::Resampled, adjoint, 0.1f).path_length;
  };
  const double sharp_plain = length(sharp, false), sharp_adjoint = length(sharp, true);
  const double flat_plain = length(flat, false), flat_adjoint = length(flat, true);
  std::printf("path length, throughput / adjoint roulette: sharp lobe %.3f / %.3f, uniform %.3f / %.3f\n",
              sharp_plain, sharp_adjoint, flat_plain, flat_adjoint);
  EXPECT_LT(sharp_adjoint, 0.9 * sharp_plain);
  EXPECT_GT(flat_adjoint, 1.1 * flat_plain);
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
    float radiance_integral(uint32_t) const override { return 1.0f; }

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
  struct Case {
    GuideMixing mixing;
    const VMFGuide* guide;
    bool adjoint_roulette;
  };
  std::vector<Case> cases;
  for (GuideMixing mixing : kMixings)
    for (const VMFGuide* g : {&up, &away, &half}) cases.push_back({mixing, g, false});
  // Adjoint-driven roulette with a field that is wrong about the light (the
  // lobe points away from it): only survival changes, never the mean.
  cases.push_back({GuideMixing::Resampled, &away, true});
  for (const Case& k : cases) {
    SCOPED_TRACE(std::string(mixing_name(k.mixing)) + (k.adjoint_roulette ? " adjoint roulette" : ""));
    ImageBuffer guided = render_with(scene, k.guide, spp, 8, k.mixing, k.adjoint_roulette).image;
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
