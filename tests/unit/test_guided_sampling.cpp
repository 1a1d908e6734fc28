// Guided directional sampling at one vertex (wavefront/guided_sampling.h),
// with a real learned guide (an SD-tree trained on an analytic field):
// RIS's weighted histogram against f |cos| cell by cell (RIS has no
// closed-form density, but f |cos| / pdf per cell must integrate f |cos|),
// one-sample MIS against its mixture density, and the below-surface loss
// that RIS removes.
#include "guiding/sd_tree.h"
#include "wavefront/guided_sampling.h"

#include "core/hash.h"
#include "core/sampling.h"
#include "tests/unit/bxdf_test_util.h"
#include "tests/unit/chi2.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

using namespace theia;
using namespace theia::test;

namespace {

vec2 u2(uint64_t h) { return {to_unit_float(uint32_t(h)), to_unit_float(uint32_t(h >> 32))}; }

const vec3 kAt(0.5f);

// A one-leaf SD-tree that learned a lobe about `axis` over a small constant.
SDTree learned_guide(const vec3& axis, float kappa) {
  SDTreeOptions o;
  o.spatial_threshold = 1e15;
  SDTree t(Bounds3(vec3(0.0f), vec3(1.0f)), o);
  const vec3 a = glm::normalize(axis);
  for (int it = 0; it < 3; ++it) {
    for (int i = 0; i < 40'000; ++i) {
      uint64_t key = hash(uint64_t(it), uint64_t(i), 5);
      vec3 w = sample_uniform_sphere(u2(key));
      float L = 0.05f + 20.0f * std::exp(kappa * (glm::dot(w, a) - 1.0f));
      t.add_sample(kAt, w, L, uniform_sphere_pdf(), key);
    }
    t.update();
  }
  return t;
}

struct Case {
  std::string name;
  BxDF bxdf;
};

// Rough lobes of every guidable kind: reflection only, and reflection plus
// transmission split by hemisphere.
std::vector<Case> bsdfs() {
  return {{"diffuse", diffuse(RGB(0.8f, 0.6f, 0.4f))},
          {"conductor a=0.3", conductor(0.3f, 0.3f)},
          {"dielectric a=0.4", dielectric(0.4f, 1.5f)}};
}

struct GuideCase {
  std::string name;
  vec3 axis;
};
// Above the surface off the mirror direction, and below it (for reflection,
// all its mass is where the BSDF does not scatter).
const GuideCase kGuides[] = {{"guide above", vec3(-0.5f, 0.2f, 0.8f)}, {"guide below", vec3(0.3f, 0.1f, -0.9f)}};

const vec3 kWo = glm::normalize(vec3(0.6f, 0.1f, 0.8f));
const Frame kFrame = Frame::from_z(vec3(0.0f, 0.0f, 1.0f));

GuidedDraw draw(uint64_t i, uint64_t seed) {
  uint64_t h = hash(i, seed);
  return {to_unit_float(uint32_t(hash(h, 1))), u2(hash(h, 2)), u2(hash(h, 3)), to_unit_float(uint32_t(hash(h, 4)))};
}

}  // namespace

TEST(GuidedSamplingRIS, WeightedHistogramIntegratesTheBSDF) {
  const std::vector<Case> cases = bsdfs();
  const int n_tests = int(cases.size() * std::size(kGuides));
  for (const GuideCase& gc : kGuides) {
    SDTree guide = learned_guide(gc.axis, 30.0f);
    const uint32_t region = guide.region(kAt);
    ASSERT_NE(region, kNoGuideRegion);
    for (const Case& c : cases) {
      const BSDF b = bsdf_from(c.bxdf, kFrame, kFrame.n);
      uint64_t i = 0;
      auto sample = [&](vec2, float) -> std::optional<WeightedDirection> {
        auto s = sample_guided_ris(b, kWo, kFrame.n, guide, region, 0.5f, draw(i++, 17));
        if (!s) return std::nullopt;
        return WeightedDirection{s->bs.wi, double(luminance(s->bs.f)) * std::abs(s->bs.wi.z) / double(s->bs.pdf)};
      };
      auto integrand = [&](vec3 w) { return double(luminance(bsdf_f(b, kWo, w))) * std::abs(w.z); };
      WeightedChi2Settings st;
      st.n_samples = 60'000;
      st.n_evals = 60'000;
      st.n_tests = n_tests;
      st.uniform_share = 1.0;
      WeightedChi2Result r = chi2_test_sphere_weighted(fmt::format("RIS {} {}", c.name, gc.name), sample, integrand, {}, st);
      EXPECT_TRUE(r.passed) << r.report;
    }
  }
}

TEST(GuidedSamplingMIS, SamplesFollowTheMixtureDensity) {
  const std::vector<Case> cases = bsdfs();
  const float selection = 0.6f;
  for (const GuideCase& gc : kGuides) {
    SDTree guide = learned_guide(gc.axis, 30.0f);
    const uint32_t region = guide.region(kAt);
    for (const Case& c : cases) {
      const BSDF b = bsdf_from(c.bxdf, kFrame, kFrame.n);
      uint64_t i = 0;
      auto sample = [&](vec2, float) -> std::optional<vec3> {
        auto s = sample_guided_mis(b, kWo, guide, region, selection, draw(i++, 23));
        if (!s) return std::nullopt;
        // The reported pdf is the mixture's at the direction.
        const float expect = guided_mis_pdf(bsdf_pdf(b, kWo, s->bs.wi), guide.pdf(region, s->bs.wi), selection);
        EXPECT_NEAR(s->bs.pdf, expect, 1e-4f * expect);
        return s->bs.wi;
      };
      // Guide directions where the BSDF is zero are declined: no density there.
      auto pdf = [&](vec3 w) {
        if (is_black(bsdf_f(b, kWo, w))) return 0.0f;
        return guided_mis_pdf(bsdf_pdf(b, kWo, w), guide.pdf(region, w), selection);
      };
      Chi2Result r = chi2_test_sphere(sample, pdf, 100'000, 16, 32, 0.01, int(cases.size() * std::size(kGuides)),
                                      fmt::format("MIS {} {}", c.name, gc.name));
      EXPECT_TRUE(r.passed) << r.report;
    }
  }
}

// The loss one-sample MIS suffers where the guide points below the surface,
// and RIS does not: every RIS draw at a diffuse surface continues the path.
TEST(GuidedSamplingRIS, GuideBelowTheSurfaceEndsNoPath) {
  SDTree guide = learned_guide(vec3(0.3f, 0.1f, -0.9f), 30.0f);
  const uint32_t region = guide.region(kAt);
  const BSDF b = bsdf_from(diffuse(RGB(0.8f)), kFrame, kFrame.n);
  int ris_lost = 0, mis_lost = 0;
  const int n = 20'000;
  for (int i = 0; i < n; ++i) {
    GuidedDraw u = draw(uint64_t(i), 31);
    auto r = sample_guided_ris(b, kWo, kFrame.n, guide, region, 0.5f, u);
    ris_lost += !r || !(r->bs.pdf > 0.0f) || r->bs.wi.z <= 0.0f;
    mis_lost += !sample_guided_mis(b, kWo, guide, region, 0.5f, u);
  }
  std::printf("paths ended by a guide below the surface: RIS %d, MIS %d of %d\n", ris_lost, mis_lost, n);
  EXPECT_EQ(ris_lost, 0);
  EXPECT_GT(mis_lost, n / 3);  // the guide's share (0.5) times its mass below (most of it)
}

// The RIS pdf and the roulette correction are consistent: pdf / BSDF pdf.
TEST(GuidedSamplingRIS, RouletteCorrectionIsPdfOverBSDFPdf) {
  SDTree guide = learned_guide(vec3(-0.5f, 0.2f, 0.8f), 30.0f);
  const uint32_t region = guide.region(kAt);
  const BSDF b = bsdf_from(conductor(0.3f, 0.3f), kFrame, kFrame.n);
  for (int i = 0; i < 2000; ++i) {
    auto r = sample_guided_ris(b, kWo, kFrame.n, guide, region, 0.5f, draw(uint64_t(i), 41));
    if (!r) continue;
    const double p = bsdf_pdf(b, kWo, r->bs.wi);
    ASSERT_NEAR(r->roulette, double(r->bs.pdf) / p, 1e-3 * r->roulette);
    ASSERT_NEAR(r->mis_pdf, 0.5 * (p + guide.pdf(region, r->bs.wi)), 1e-3 * r->mis_pdf);
  }
}
