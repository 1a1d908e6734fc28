// Path-space regularisation (scene/bsdf.h bsdf_roughen, seeds/000 ch. 1
// section 7 eq. 25): the formula on worked numbers, which interfaces a BSDF
// roughens, chi-square of every roughened lobe's sampling against the pdf
// that NEE and MIS use, and a white furnace (roughening creates no energy).
#include "tests/unit/bxdf_test_util.h"
#include "tests/unit/chi2.h"

#include "scene/bsdf.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

using namespace theia;
using namespace theia::test;

namespace {

BSDF in_z_frame(const BxDF& b) { return bsdf_from(b, Frame::from_z(vec3(0, 0, 1)), vec3(0, 0, 1)); }
BSDF roughened(const BxDF& b, float gamma, float prev) {
  BSDF bsdf = in_z_frame(b);
  bsdf_roughen(bsdf, gamma, prev);
  return bsdf;
}

// Eq. 25 in float: 1 - (1 - alpha)(1 - gamma alpha') cancels, ~1e-8 off the exact value.
constexpr float kTol = 1e-6f;

}  // namespace

// alpha' = 1 - (1 - alpha) (1 - gamma alpha'_prev), worked by hand.
TEST(Roughening, Eq25OnWorkedNumbers) {
  EXPECT_NEAR(regularized_roughness(0.0f, 0.01f, 1.0f), 0.01f, kTol);    // a mirror after a diffuse bounce
  EXPECT_NEAR(regularized_roughness(0.2f, 0.01f, 1.0f), 0.208f, kTol);   // 1 - 0.8 * 0.99
  EXPECT_NEAR(regularized_roughness(0.3f, 0.5f, 0.4f), 0.44f, kTol);     // 1 - 0.7 * 0.8
  EXPECT_NEAR(regularized_roughness(0.0f, 1.0f, 0.25f), 0.25f, kTol);    // full strength passes alpha' on
  EXPECT_NEAR(regularized_roughness(0.3f, 0.0f, 1.0f), 0.3f, kTol);      // gamma 0: off
  EXPECT_NEAR(regularized_roughness(0.3f, 0.5f, 0.0f), 0.3f, kTol);      // after a delta lobe: nothing
  EXPECT_NEAR(regularized_roughness(1.0f, 0.5f, 1.0f), 1.0f, kTol);      // diffuse stays diffuse
  EXPECT_NEAR(regularized_roughness(1.7f, 0.5f, 1.0f), 1.7f, kTol);      // never smoother than the scene's
  // Never below alpha, never above 1 for alpha <= 1.
  for (float a : {0.0f, 0.05f, 0.5f, 0.99f})
    for (float g : {0.0f, 0.01f, 0.3f, 1.0f})
      for (float p : {0.0f, 0.2f, 1.0f}) {
        const float r = regularized_roughness(a, g, p);
        EXPECT_GE(r, a);
        EXPECT_LE(r, 1.0f);
      }
}

// The roughness a sampled direction hands on: its lobe's, 0 for a delta.
TEST(Roughening, SampledRoughnessIsTheSamplingLobes) {
  BSDFSample s;
  s.flags = kLobeReflection | kLobeSpecular;
  s.roughness = 0.7f;
  EXPECT_EQ(sampled_roughness(s), 0.0f);
  s.flags = kLobeReflection | kLobeGlossy;
  EXPECT_EQ(sampled_roughness(s), 0.7f);
  s.roughness = 1.4f;
  EXPECT_EQ(sampled_roughness(s), 1.0f);
  // A diffuse BSDF's sample hands on 1, a mirror's 0, a rough conductor's its alpha.
  const vec3 wo = dir_at(0.5f);
  auto d = bsdf_sample(in_z_frame(diffuse(RGB(0.5f))), wo, 0.3f, vec2(0.4f, 0.6f));
  ASSERT_TRUE(d);
  EXPECT_EQ(sampled_roughness(*d), 1.0f);
  auto m = bsdf_sample(in_z_frame(conductor(0.0f, 0.0f)), wo, 0.3f, vec2(0.4f, 0.6f));
  ASSERT_TRUE(m);
  EXPECT_EQ(sampled_roughness(*m), 0.0f);
  auto g = bsdf_sample(in_z_frame(conductor(0.3f, 0.3f)), wo, 0.3f, vec2(0.4f, 0.6f));
  ASSERT_TRUE(g);
  EXPECT_NEAR(sampled_roughness(*g), 0.3f, kTol);
  // The roughened BSDF's sample hands on the roughened alpha.
  auto r = bsdf_sample(roughened(conductor(0.0f, 0.0f), 0.1f, 1.0f), wo, 0.3f, vec2(0.4f, 0.6f));
  ASSERT_TRUE(r);
  EXPECT_NEAR(sampled_roughness(*r), 0.1f, kTol);
  // A guided direction hands on what a BSDF sample of it would (bsdf_event's
  // lobe, eq. 24): reflection and refraction of a roughened glass alike.
  const BSDF glass = roughened(dielectric(0.05f, 1.5f), 0.2f, 1.0f);
  int seen_transmission = 0;
  for (float uc = 0.05f; uc < 1.0f; uc += 0.1f) {
    auto s = bsdf_sample(glass, wo, uc, vec2(0.3f, 0.7f));
    ASSERT_TRUE(s);
    auto e = bsdf_event(glass, wo, s->wi);
    ASSERT_TRUE(e);
    EXPECT_EQ(sampled_roughness(*e), sampled_roughness(*s));
    EXPECT_EQ(e->flags, s->flags);
    seen_transmission += s->is_transmission();
  }
  EXPECT_GT(seen_transmission, 0);
}

// Every microfacet and delta interface is roughened, each axis on its own;
// a delta lobe becomes a glossy one; diffuse, thin dielectric and hair stay.
TEST(Roughening, RoughensEveryInterfaceAndRefreshesTheLobes) {
  BSDF glass = roughened(dielectric(0.0f, 1.5f), 0.01f, 1.0f);
  EXPECT_NEAR(glass.bxdf.dielectric.distrib.alpha_x, 0.01f, kTol);
  EXPECT_NEAR(glass.bxdf.dielectric.distrib.alpha_y, 0.01f, kTol);
  ASSERT_EQ(glass.lobe_count, 2);
  for (int i = 0; i < 2; ++i) {
    EXPECT_TRUE(glass.lobes[i].flags & kLobeGlossy) << i;
    EXPECT_FALSE(glass.lobes[i].flags & kLobeSpecular) << i;
    EXPECT_NEAR(glass.lobes[i].roughness, 0.01f, kTol) << i;
  }
  EXPECT_FALSE(bsdf_is_specular(glass));  // NEE now runs at the glass

  BSDF aniso = roughened(conductor(0.1f, 0.5f), 0.5f, 0.4f);
  EXPECT_NEAR(aniso.bxdf.conductor.distrib.alpha_x, 1.0f - 0.9f * 0.8f, kTol);
  EXPECT_NEAR(aniso.bxdf.conductor.distrib.alpha_y, 1.0f - 0.5f * 0.8f, kTol);
  EXPECT_NEAR(aniso.lobes[0].roughness, 0.6f, kTol);

  BSDF cc = roughened(coated_conductor(0.0f, 0.2f), 0.1f, 1.0f);
  EXPECT_NEAR(cc.bxdf.coated_conductor.top.distrib.alpha_x, 0.1f, kTol);
  EXPECT_NEAR(cc.bxdf.coated_conductor.base.distrib.alpha_x, 1.0f - 0.8f * 0.9f, kTol);
  BSDF cd = roughened(coated_diffuse(0.0f, RGB(0.5f)), 0.1f, 1.0f);
  EXPECT_NEAR(cd.bxdf.coated_diffuse.top.distrib.alpha_x, 0.1f, kTol);
  EXPECT_FALSE(bxdf_flags(cd.bxdf) & kBxDFSpecular);

  // A weak roughening that stays under the smooth threshold keeps a delta lobe (and its sampling).
  BSDF still = roughened(conductor(0.0f, 0.0f), 1e-4f, 1.0f);
  EXPECT_TRUE(still.lobes[0].flags & kLobeSpecular);
  EXPECT_TRUE(bsdf_is_specular(still));

  BSDF thin = roughened(ThinDielectricBxDF{1.5f}, 0.5f, 1.0f);
  EXPECT_TRUE(bsdf_is_specular(thin));
  BSDF d = roughened(diffuse(RGB(0.5f)), 0.5f, 1.0f);
  EXPECT_EQ(d.lobes[0].roughness, 1.0f);
  EXPECT_TRUE(d.lobes[0].flags & kLobeDiffuse);
}

// Each roughened single-layer lobe samples what bsdf_pdf (the density NEE's
// MIS weight takes) says, checked by chi-square as tests/unit/test_bsdf_chi2.cpp
// checks the scene's own lobes.  Roughened layered coats are the layered
// BxDFs of another alpha, which tests/unit/test_layered_chi2.cpp sweeps.
TEST(Roughening, RoughenedLobesSampleTheirPdf) {
  struct Case {
    std::string name;
    BxDF bxdf;
    float gamma, prev;
    vec3 wo;
  };
  const std::vector<Case> cases = {
      {"mirror after diffuse, gamma 0.05", conductor(0.0f, 0.0f), 0.05f, 1.0f, dir_at(0.4f)},
      {"mirror after glossy 0.5, gamma 0.3", conductor(0.0f, 0.0f), 0.3f, 0.5f, dir_at(1.2f)},
      {"anisotropic conductor 0.05 x 0.3, gamma 0.2", conductor(0.05f, 0.3f), 0.2f, 1.0f, dir_at(0.9f, 1.0f)},
      {"smooth glass after diffuse, gamma 0.1", dielectric(0.0f, 1.5f), 0.1f, 1.0f, dir_at(0.6f)},
      {"smooth glass from inside, gamma 0.2", dielectric(0.0f, 1.5f), 0.2f, 1.0f, -dir_at(0.5f)},
      {"rough glass 0.2 after diffuse, gamma 0.1", dielectric(0.2f, 1.33f), 0.1f, 1.0f, dir_at(1.1f)},
  };
  for (const Case& c : cases) {
    const BSDF b = roughened(c.bxdf, c.gamma, c.prev);
    ASSERT_FALSE(bsdf_is_specular(b)) << c.name;
    auto r = chi2_test_sphere(
        [&](vec2 u, float u1) -> std::optional<vec3> {
          auto s = bsdf_sample(b, c.wo, u1, u);
          if (!s) return std::nullopt;
          EXPECT_NEAR(s->pdf, bsdf_pdf(b, c.wo, s->wi), 1e-3f * s->pdf) << c.name;
          return glm::normalize(s->wi);
        },
        [&](vec3 wi) { return bsdf_pdf(b, c.wo, wi); }, 30'000, 16, 32, 0.01, int(cases.size()), c.name);
    EXPECT_TRUE(r.passed) << r.report;
  }
  // The same test rejects the scene's own pdf for the roughened lobe (what
  // NEE's MIS would use if it saw the BSDF unroughened).
  const BxDF glass = dielectric(0.2f, 1.33f);
  const BSDF b = roughened(glass, 0.1f, 1.0f), plain = in_z_frame(glass);
  const vec3 wo = dir_at(1.1f);
  auto wrong = chi2_test_sphere(
      [&](vec2 u, float u1) -> std::optional<vec3> {
        auto s = bsdf_sample(b, wo, u1, u);
        if (!s) return std::nullopt;
        return glm::normalize(s->wi);
      },
      [&](vec3 wi) { return bsdf_pdf(plain, wo, wi); }, 30'000, 16, 32, 0.01, int(cases.size()), "unroughened pdf");
  EXPECT_FALSE(wrong.passed) << wrong.report;
}

// Roughening creates no energy: lossless interfaces (a perfect mirror, a
// smooth glass) roughened keep their albedo at most 1 (single-scattering
// microfacets lose a little), and the layered kinds stay below 1.  In
// Importance mode, as tests/unit/test_bsdf.cpp's furnace: radiance refracted
// out of glass is scaled by eta^2 and is no albedo.
TEST(Roughening, WhiteFurnaceAlbedoAtMostOne) {
  struct Case {
    std::string name;
    BxDF bxdf;
    bool lossless;  // albedo 1 before roughening
    float side = 1.0f;
  };
  const std::vector<Case> cases = {
      {"perfect mirror", perfect_mirror(0.0f), true},
      {"smooth glass", dielectric(0.0f, 1.5f), true},
      {"smooth glass from inside", dielectric(0.0f, 1.5f), true, -1.0f},
      {"rough glass 0.3", dielectric(0.3f, 1.5f), false},
      {"coated diffuse, white base", coated_diffuse(0.0f, RGB(1.0f)), false},
      {"coated conductor", coated_conductor(0.0f, 0.1f), false},
  };
  for (const Case& c : cases)
    for (float gamma : {0.01f, 0.2f, 1.0f})
      for (float theta : {0.3f, 1.2f}) {
        const vec3 wo = c.side * dir_at(theta);
        const BSDF b = roughened(c.bxdf, gamma, 1.0f);
        const Estimate e = albedo_by_sampling(b.bxdf, wo, 40'000, TransportMode::Importance);
        const std::string what = fmt::format("{} gamma={} theta={}", c.name, gamma, theta);
        for (int ch = 0; ch < 3; ++ch) {
          EXPECT_LE(e.mean[ch], 1.0f + 4.0f * e.stderr_max + 1e-4f) << what;
          // A slight roughening of a lossless interface loses almost nothing.
          if (c.lossless && gamma == 0.01f) {
            EXPECT_GT(e.mean[ch], 0.97f) << what;
          }
        }
      }
}
