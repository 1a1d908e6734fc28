// Guided phase-function sampling at a medium vertex (wavefront/guided_phase.h)
// with an analytic guide (a von Mises-Fisher lobe over a uniform floor, whose
// sampling and density are exact): one-sample MIS against its mixture
// density by chi-square, RIS's weighted histogram against the phase function
// cell by cell (RIS has no closed-form density, but phase / pdf per cell must
// integrate the phase function), over forward, isotropic and backward g.
#include "wavefront/guided_phase.h"

#include "core/hash.h"
#include "core/sampling.h"
#include "scene/microfacet.h"
#include "tests/unit/chi2.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>

using namespace theia;

namespace {

vec2 u2(uint64_t h) { return {to_unit_float(uint32_t(h)), to_unit_float(uint32_t(h >> 32))}; }

// floor x uniform + (1 - floor) x vMF(axis, kappa); one region.
class LobeGuide final : public DirectionalGuide {
 public:
  LobeGuide(const vec3& axis, float kappa, float floor)
      : frame_(Frame::from_z(glm::normalize(axis))), kappa_(kappa), floor_(floor) {}
  uint32_t region(const vec3&) const override { return 0; }
  GuideSample sample(uint32_t r, vec2 u) const override {
    vec3 w;
    if (u.x < floor_) {
      w = sample_uniform_sphere(vec2(std::min(u.x / floor_, kOneMinusEpsilon), u.y));
    } else {
      const float v = std::min((u.x - floor_) / (1.0f - floor_), kOneMinusEpsilon);
      // Inverse CDF of the vMF's cos theta, in the stable form.
      const float c = 1.0f + std::log(v + (1.0f - v) * std::exp(-2.0f * kappa_)) / kappa_;
      const float s = std::sqrt(std::max(0.0f, 1.0f - c * c)), phi = 2.0f * kPi * u.y;
      w = frame_.from_local(vec3(s * std::cos(phi), s * std::sin(phi), c));
    }
    return {w, pdf(r, w)};
  }
  float pdf(uint32_t, const vec3& w) const override {
    const double c = glm::dot(w, frame_.n);
    const double vmf = kappa_ / (2.0 * kPi * (1.0 - std::exp(-2.0 * kappa_))) * std::exp(kappa_ * (c - 1.0));
    return float(floor_ * kInv4Pi + (1.0 - floor_) * vmf);
  }
  float selection_probability(uint32_t) const override { return 0.5f; }
  float radiance_integral(uint32_t) const override { return 1.0f; }

 private:
  Frame frame_;
  float kappa_, floor_;
};

const vec3 kWo = glm::normalize(vec3(0.3f, -0.2f, 0.9f));
const float kGs[] = {-0.9f, 0.0f, 0.5f, 0.99f};
// Ahead of the path (the forward peak is at -wo), and off to the side.
const vec3 kAxes[] = {glm::normalize(vec3(-0.2f, 0.3f, -0.9f)), glm::normalize(vec3(1.0f, 0.2f, 0.1f))};

GuidedDraw draw(uint64_t i, uint64_t seed) {
  const uint64_t h = hash(i, seed);
  return {0.0f, u2(hash(h, 2)), u2(hash(h, 3)), to_unit_float(uint32_t(hash(h, 4)))};
}

}  // namespace

TEST(GuidedPhaseMIS, SamplesFollowTheMixtureDensity) {
  const float selection = 0.6f;
  const int n_tests = int(std::size(kGs) * std::size(kAxes));
  for (const vec3& axis : kAxes) {
    const LobeGuide guide(axis, 20.0f, 0.1f);
    for (float g : kGs) {
      uint64_t i = 0;
      auto sample = [&](vec2, float) -> std::optional<vec3> {
        auto s = sample_guided_phase_mis(kWo, g, guide, 0, selection, draw(i++, 23));
        if (!s) return std::nullopt;
        const float phase = henyey_greenstein(glm::dot(kWo, s->wi), g);
        const float expect = guided_mis_pdf(phase, guide.pdf(0, s->wi), selection);
        EXPECT_NEAR(s->pdf, expect, 1e-4f * expect);
        EXPECT_EQ(s->pdf, s->mis_pdf);
        EXPECT_NEAR(s->phase, phase, 1e-5f * phase);
        return s->wi;
      };
      auto pdf = [&](vec3 w) {
        return guided_mis_pdf(henyey_greenstein(glm::dot(kWo, w), g), guide.pdf(0, w), selection);
      };
      Chi2Result r = chi2_test_sphere(sample, pdf, 100'000, 16, 32, 0.01, n_tests, fmt::format("MIS g={}", g));
      EXPECT_TRUE(r.passed) << r.report;
    }
  }
}

TEST(GuidedPhaseRIS, WeightedHistogramIntegratesThePhaseFunction) {
  const int n_tests = int(std::size(kGs) * std::size(kAxes));
  for (const vec3& axis : kAxes) {
    const LobeGuide guide(axis, 20.0f, 0.1f);
    for (float g : kGs) {
      uint64_t i = 0, declined = 0;
      auto sample = [&](vec2, float) -> std::optional<WeightedDirection> {
        auto s = sample_guided_phase_ris(kWo, g, guide, 0, 0.5f, draw(i++, 17));
        if (!s) {
          ++declined;
          return std::nullopt;
        }
        // The correction a guided path's roulette applies: pdf / phase-sampling pdf.
        EXPECT_NEAR(s->roulette, double(s->pdf) / double(s->phase), 1e-6 * s->roulette);
        return WeightedDirection{s->wi, double(s->phase) / double(s->pdf)};
      };
      auto integrand = [&](vec3 w) { return double(henyey_greenstein(glm::dot(kWo, w), g)); };
      // The phase function's own lobe for the integral side (g = 0.99 is too narrow for uniform directions).
      DirectionLobe hg{[&](vec2 u, float) -> std::optional<vec3> {
                         float p = 0.0f;
                         return sample_henyey_greenstein(kWo, g, u, &p);
                       },
                       [&](vec3 w) { return double(henyey_greenstein(glm::dot(kWo, w), g)); }};
      WeightedChi2Settings st;
      st.n_samples = 60'000;
      st.n_evals = 60'000;
      st.n_tests = n_tests;
      st.uniform_share = 0.5;
      WeightedChi2Result r = chi2_test_sphere_weighted(fmt::format("RIS g={}", g), sample, integrand, {hg}, st);
      EXPECT_TRUE(r.passed) << r.report;
      EXPECT_EQ(declined, 0u) << "the phase function is positive everywhere: no candidate set is empty";
    }
  }
}
