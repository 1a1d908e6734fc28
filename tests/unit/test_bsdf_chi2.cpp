// Chi-square tests of every single-layer BxDF's sampling against its own pdf
// over a sweep of roughness, index and incident angle (tests/unit/chi2.h),
// with Sidak correction over the sweep; and proof that the sweep's sample
// counts and resolution reject a slightly wrong pdf.
#include "tests/unit/bxdf_test_util.h"
#include "tests/unit/chi2.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

using namespace theia;
using namespace theia::test;

namespace {

constexpr double kSignificance = 0.01;
// 30k samples in 16 x 32 equal-area cells: ~60 per cell on a diffuse lobe,
// and the whole sweep stays under a few seconds (the adaptive integration of
// the pdf over cells holding a narrow lobe is what costs).
constexpr int kSamples = 30'000;
constexpr int kThetaRes = 16, kPhiRes = 32;

struct Case {
  std::string name;
  BxDF bxdf;
  vec3 wo;
};

std::vector<Case> sweep() {
  std::vector<Case> cases;
  for (float theta : {0.3f, 1.3f}) {
    // 0.032 = pbrt-v4's remapped roughness 1e-3, just above the smooth cut-off.
    for (float a : {0.032f, 0.1f, 0.5f, 1.0f})
      cases.push_back({fmt::format("conductor a={} theta={}", a, theta), conductor(a, a), dir_at(theta)});
    for (float a : {0.1f, 0.5f, 1.0f})
      for (float eta : {1.5f, 4.0f})
        cases.push_back({fmt::format("dielectric a={} eta={} theta={}", a, eta, theta), dielectric(a, eta),
                         dir_at(theta)});
  }
  cases.push_back({"conductor anisotropic 0.08 x 0.5", conductor(0.08f, 0.5f), dir_at(0.9f, 1.0f)});
  cases.push_back({"dielectric a=0.032 eta=1.5", dielectric(0.032f, 1.5f), dir_at(0.6f)});
  cases.push_back({"dielectric a=0.5 eta=1.05", dielectric(0.5f, 1.05f), dir_at(0.6f)});
  cases.push_back({"dielectric from inside a=0.3 eta=1.5", dielectric(0.3f, 1.5f), -dir_at(0.9f)});
  cases.push_back({"diffuse", diffuse(RGB(0.7f)), dir_at(0.9f)});
  cases.push_back({"diffuse transmission", diffuse_transmission(RGB(0.2f), RGB(0.6f)), dir_at(0.9f)});
  return cases;
}

Chi2Result run(const BxDF& b, const vec3& wo, const std::function<float(vec3)>& pdf, int n_tests,
               const std::string& name) {
  return chi2_test_sphere(
      [&](vec2 u, float u1) -> std::optional<vec3> {
        auto s = bxdf_sample(b, wo, u1, u);
        if (!s) return std::nullopt;
        return glm::normalize(s->wi);
      },
      pdf, kSamples, kThetaRes, kPhiRes, kSignificance, n_tests, name);
}

}  // namespace

TEST(BxDFChi2, SamplingMatchesPdfAcrossRoughnessIorAndAngle) {
  auto cases = sweep();
  EXPECT_GE(cases.size(), 24u);
  for (const Case& c : cases) {
    auto r = run(c.bxdf, c.wo, [&](vec3 wi) { return bxdf_pdf(c.bxdf, c.wo, wi); }, int(cases.size()), c.name);
    EXPECT_TRUE(r.passed) << r.report;
  }
}

// The sweep's settings can fail: a pdf 10% too rough, or one that forgets the
// Fresnel split between reflection and refraction, is rejected.
TEST(BxDFChi2, SweepSettingsRejectASlightlyWrongPdf) {
  const int n_tests = int(sweep().size());
  BxDF b = conductor(0.3f, 0.3f), wrong = conductor(0.33f, 0.33f);
  vec3 wo = dir_at(0.6f);
  auto r = run(b, wo, [&](vec3 wi) { return bxdf_pdf(wrong, wo, wi); }, n_tests, "conductor, pdf of a=0.33");
  EXPECT_FALSE(r.passed) << r.report;
  BxDF d = dielectric(0.3f, 1.5f);
  auto unsplit = run(
      d, wo,
      [&](vec3 wi) {
        float refl = bxdf_pdf(d, wo, wi, TransportMode::Radiance, kSampleReflection);
        float trans = bxdf_pdf(d, wo, wi, TransportMode::Radiance, kSampleTransmission);
        return 0.5f * (refl + trans);  // each normalised alone, mixed 50/50 instead of by Fresnel
      },
      n_tests, "dielectric, 50/50 split");
  EXPECT_FALSE(unsplit.passed) << unsplit.report;
}

TEST(BxDFChi2, HenyeyGreensteinPhaseFunction) {
  for (float g : {-0.7f, 0.0f, 0.3f, 0.9f}) {
    vec3 wo = glm::normalize(vec3(0.3f, -0.2f, 0.9f));
    auto r = chi2_test_sphere(
        [&](vec2 u, float) -> std::optional<vec3> {
          float pdf;
          return glm::normalize(sample_henyey_greenstein(wo, g, u, &pdf));
        },
        [&](vec3 wi) { return henyey_greenstein(glm::dot(wo, wi), g); }, kSamples, kThetaRes, kPhiRes,
        kSignificance, 4, fmt::format("HG g={}", g));
    EXPECT_TRUE(r.passed) << r.report;
  }
}
