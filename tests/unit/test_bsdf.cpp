// Statistical tests of the BxDFs (scene/bxdfs.h), as Mitsuba tests its BSDFs:
// white furnace, albedo against independent quadrature, reciprocity, pdf
// normalisation, and the layered BxDFs' sampling against their evaluation.
// The chi-square sweep is in test_bsdf_chi2.cpp.
#include "scene/bsdf.h"
#include "scene/bxdf_kinds.h"
#include "tests/unit/bxdf_test_util.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <bit>
#include <random>

using namespace theia;
using namespace theia::test;

namespace {

struct Case {
  std::string name;
  BxDF bxdf;
  float theta_o;
  bool below = false;  // wo in the lower hemisphere (inside a dielectric)
};

std::vector<Case> glossy_cases() {
  std::vector<Case> cases;
  const float thetas[] = {0.3f, 1.3f};
  for (float t : thetas) {
    for (float a : {0.032f, 0.3f, 1.0f})  // 0.032 = remapped roughness 1e-3
      cases.push_back({fmt::format("conductor a={} theta={}", a, t), conductor(a, a), t});
    cases.push_back({fmt::format("conductor aniso theta={}", t), conductor(0.08f, 0.5f), t});
    for (float a : {0.05f, 0.3f, 1.0f})
      // eta 1.0001 refracts into a near-delta lobe no histogram resolves; it is
      // covered by the furnace tests below.
      for (float eta : {1.05f, 1.5f, 4.0f})
        cases.push_back({fmt::format("dielectric a={} eta={} theta={}", a, eta, t), dielectric(a, eta), t});
    cases.push_back({fmt::format("dielectric inside a=0.3 theta={}", t), dielectric(0.3f, 1.5f), t, true});
    cases.push_back({fmt::format("diffuse theta={}", t), diffuse(RGB(0.7f)), t});
    cases.push_back({fmt::format("diffusetransmission theta={}", t), diffuse_transmission(RGB(0.2f), RGB(0.6f)), t});
  }
  return cases;
}

vec3 wo_of(const Case& c) {
  vec3 wo = dir_at(c.theta_o);
  return c.below ? -wo : wo;
}

// Integral over wi of g(wi) for a layered BxDF at wo, by defensive importance
// sampling that does not use the layered sampler (whose density is unknown):
// half the directions cosine-distributed, half from the coat's reflection
// lobe, weighted by the exact mixture density.  The coat lobe keeps a
// nearly-smooth coat's highlight from making the estimate hopelessly noisy.
template <typename G>
glm::dvec3 layered_integral(const BxDF& b, const vec3& wo, int n, const G& g) {
  BxDF coat = coat_of(b);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> u01(0.0f, 0.99999994f);
  glm::dvec3 sum(0.0);
  for (int i = 0; i < n; ++i) {
    vec3 wi;
    if (i % 2 == 0) {
      wi = sample_cosine_hemisphere(vec2((float(i / 2) + u01(rng)) / float(n / 2), u01(rng)));
    } else {
      auto s = bxdf_sample(coat, wo, u01(rng), vec2(u01(rng), u01(rng)), TransportMode::Radiance, kSampleReflection);
      if (!s) continue;
      wi = s->wi;
    }
    double m = 0.5 * cosine_hemisphere_pdf(wi.z) +
               0.5 * bxdf_pdf(coat, wo, wi, TransportMode::Radiance, kSampleReflection);
    if (m > 0.0) sum += g(wi) / m;
  }
  return sum / double(n);
}

// Albedo by defensive importance sampling (half uniform, half the BxDF's own
// samples, weighted by the mixture density): f |cos| / mixture stays bounded
// where pure uniform quadrature of a peaked lobe would be hopelessly noisy.
RGB albedo_by_mixture(const BxDF& b, const vec3& wo, int n, TransportMode mode) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<float> u01(0.0f, 0.99999994f);
  glm::dvec3 sum(0.0);
  for (int i = 0; i < n; ++i) {
    vec3 wi;
    if (i % 2 == 0) {
      wi = sample_uniform_sphere(vec2(u01(rng), u01(rng)));
    } else {
      auto s = bxdf_sample(b, wo, u01(rng), vec2(u01(rng), u01(rng)), mode);
      if (!s) continue;
      wi = s->wi;
    }
    double m = 0.5 * uniform_sphere_pdf() + 0.5 * bxdf_pdf(b, wo, wi, mode);
    sum += glm::dvec3(bxdf_f(b, wo, wi, mode) * std::abs(wi.z)) / m;
  }
  return RGB(sum / double(n));
}
}  // namespace

// The Trowbridge-Reitz D is normalised: integral of D(wm) cos(theta_m) = 1,
// and the visible-normal density integrates to 1 for any direction.
TEST(Microfacet, TrowbridgeReitzIsNormalised) {
  for (auto [ax, ay] : {std::pair{0.1f, 0.1f}, {0.5f, 0.5f}, {1.0f, 1.0f}, {0.1f, 0.6f}}) {
    TrowbridgeReitz d{ax, ay};
    const int n = 400'000;
    double projected = 0.0, visible = 0.0;
    vec3 w = dir_at(1.0f);
    for (int i = 0; i < n; ++i) {
      vec2 u((float(i % 1000) + 0.5f) / 1000.0f, (float(i / 1000) + 0.5f) / float(n / 1000));
      vec3 wm = sample_uniform_hemisphere(u);
      projected += d.D(wm) * wm.z / uniform_hemisphere_pdf();
      if (glm::dot(w, wm) > 0.0f) visible += d.D(w, wm) / uniform_hemisphere_pdf();  // front-facing only
    }
    EXPECT_NEAR(projected / n, 1.0, 0.02) << ax << " " << ay;
    EXPECT_NEAR(visible / n, 1.0, 0.02) << ax << " " << ay;
  }
}

// Integral of a pdf by defensive importance sampling: half the directions
// uniform on the sphere, half from the BxDF itself, weighted by the mixture
// density.  Bounded weights (pdf / mixture <= 2) even for peaked lobes.
double pdf_integral(const BxDF& b, const vec3& wo, int n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u01(0.0f, 0.99999994f);
  double sum = 0.0;
  for (int i = 0; i < n; ++i) {
    vec3 wi;
    if (i % 2 == 0) {
      wi = sample_uniform_sphere(vec2(u01(rng), u01(rng)));
    } else {
      auto s = bxdf_sample(b, wo, u01(rng), vec2(u01(rng), u01(rng)));
      if (!s) continue;
      wi = s->wi;
    }
    double p = bxdf_pdf(b, wo, wi);
    sum += p / (0.5 * uniform_sphere_pdf() + 0.5 * p);
  }
  return sum / n;
}

// pdf integrates to the share of samples that are not declined.
TEST(BxDFPdf, IntegratesToTheAcceptedShare) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<float> u01(0.0f, 0.99999994f);
  for (const Case& c : glossy_cases()) {
    vec3 wo = wo_of(c);
    const int n = 20'000;
    int accepted = 0;
    for (int i = 0; i < n; ++i) accepted += bxdf_sample(c.bxdf, wo, u01(rng), vec2(u01(rng), u01(rng))).has_value();
    EXPECT_NEAR(pdf_integral(c.bxdf, wo, 40'000, 11), double(accepted) / n, 0.02) << c.name;
  }
}

// f |cos| / pdf averaged over the BxDF's own samples equals the albedo
// integrated without them, and no BxDF creates energy.
TEST(BxDFFurnace, AlbedoAtMostOneAndSamplingAgreesWithQuadrature) {
  for (const Case& c : glossy_cases()) {
    vec3 wo = wo_of(c);
    for (TransportMode mode : {TransportMode::Importance, TransportMode::Radiance}) {
      Estimate e = albedo_by_sampling(c.bxdf, wo, 20'000, mode);
      RGB q = albedo_by_mixture(c.bxdf, wo, 40'000, mode);
      for (int ch = 0; ch < 3; ++ch) {
        // The quadrature is itself noisy for peaked lobes: 3% relative slack.
        EXPECT_NEAR(e.mean[ch], q[ch], 5.0f * e.stderr_max + 0.03f * q[ch] + 1e-3f) << c.name << " ch " << ch;
        if (mode == TransportMode::Importance) {
          EXPECT_LE(e.mean[ch], 1.0f + 5.0f * e.stderr_max) << c.name;
        }
      }
    }
  }
}

// Lossless models conserve energy exactly (Importance mode: no 1/eta^2).
TEST(BxDFFurnace, SmoothDielectricThinDielectricAndMirrorAreLossless) {
  std::vector<std::pair<std::string, BxDF>> cases;
  for (float eta : {1.0001f, 1.33f, 1.5f, 4.0f}) {
    cases.push_back({fmt::format("smooth dielectric {}", eta), dielectric(0.0f, eta)});
    cases.push_back({fmt::format("thin dielectric {}", eta), ThinDielectricBxDF{eta}});
  }
  cases.push_back({"mirror", conductor(0.0f, 0.0f, RGB(1.0f), RGB(1e4f))});
  for (auto& [name, b] : cases)
    for (float theta : {0.0f, 0.5f, 1.0f, 1.4f, 1.55f})
      for (bool below : {false, true}) {
        vec3 wo = below ? -dir_at(theta) : dir_at(theta);
        Estimate e = albedo_by_sampling(b, wo, 2'000, TransportMode::Importance);
        for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(e.mean[ch], 1.0f, 2e-3f) << name << " theta " << theta;
        // Specular: nothing for f and pdf to evaluate.
        EXPECT_EQ(bxdf_pdf(b, wo, vec3(-wo.x, -wo.y, wo.z)), 0.0f);
        EXPECT_TRUE(is_black(bxdf_f(b, wo, vec3(-wo.x, -wo.y, wo.z))));
      }
  // In radiance mode refraction scales by 1/eta^2 (pbrt-v4), and the sample reports eta.
  BxDF d = dielectric(0.0f, 1.5f);
  for (float uc = 0.0f; uc < 1.0f; uc += 0.01f) {
    auto s = bxdf_sample(d, dir_at(0.3f), uc, vec2(0.5f));
    ASSERT_TRUE(s);
    if (s->is_transmission()) {
      EXPECT_FLOAT_EQ(s->eta, 1.5f);
      auto si = bxdf_sample(d, dir_at(0.3f), uc, vec2(0.5f), TransportMode::Importance);
      EXPECT_NEAR(s->f.x * 1.5f * 1.5f, si->f.x, 1e-5f);
      EXPECT_NEAR(s->wi.z, -std::sqrt(1.0f - sqr(std::sin(0.3f) / 1.5f)), 1e-5f);  // Snell
    } else {
      EXPECT_FLOAT_EQ(s->wi.z, dir_at(0.3f).z);
    }
  }
}

// Rough mirrors lose the energy that single scattering misses (Kulla & Conty
// 2017 tabulate it against r = sqrt(alpha): alpha 0.3 keeps ~0.85, alpha 1
// keeps ~0.3 at normal incidence).  The sampled albedo must match the
// independent quadrature within noise, and the quadrature itself is checked
// against two closed forms: alpha -> 0 keeps everything, and at alpha = 1,
// normal incidence, D = 1/pi and E = integral over theta_m < 45 degrees.
TEST(BxDFFurnace, RoughMirrorAlbedoMatchesIndependentQuadrature) {
  // Closed form at alpha 1, wo = z: theta_i = 2 theta_m, Lambda(wi) = (1/cos theta_i - 1)/2.
  double closed = 0.0;
  const int m = 200'000;
  for (int i = 0; i < m; ++i) {
    double tm = (i + 0.5) / m * (kPi / 4.0), ti = 2.0 * tm;
    closed += 2.0 * std::cos(tm) * std::sin(tm) / (1.0 + (1.0 / std::cos(ti) - 1.0) / 2.0) * (kPi / 4.0) / m;
  }
  EXPECT_NEAR(ggx_albedo_quadrature(1.0, 0.0, 400), closed, 1e-4);
  EXPECT_NEAR(ggx_albedo_quadrature(1e-3, 0.5, 400), 1.0, 1e-3);
  for (float a : {0.05f, 0.3f, 1.0f})
    for (float theta : {0.0f, 0.3f, 0.8f, 1.3f, 1.4f}) {
      double q = ggx_albedo_quadrature(a, theta, 400);
      // The wo of the sampled estimate lies in the x-z plane like the quadrature's.
      Estimate e = albedo_by_sampling(perfect_mirror(a), dir_at(theta, 0.0f), 20'000, TransportMode::Radiance);
      // 1e-3 covers the quadrature's own error at 400^2 nodes (1e-3 at alpha 0.05, grazing).
      EXPECT_NEAR(e.mean.x, q, 4.0f * e.stderr_max + 1e-3f) << "alpha " << a << " theta " << theta;
      EXPECT_LE(q, 1.0) << "alpha " << a << " theta " << theta;
    }
}

TEST(BxDFReciprocity, ReflectionIsSymmetricAndRefractionScalesByEtaSquared) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  std::vector<BxDF> reflective = {conductor(0.3f, 0.3f), conductor(0.1f, 0.6f), dielectric(0.4f, 1.5f)};
  reflective.push_back(diffuse(RGB(0.5f)));
  int checked = 0;
  for (const BxDF& b : reflective)
    for (int i = 0; i < 2000; ++i) {
      vec3 wo = sample_uniform_hemisphere(vec2(u01(rng), u01(rng)));
      vec3 wi = sample_uniform_hemisphere(vec2(u01(rng), u01(rng)));
      RGB a = bxdf_f(b, wo, wi), c = bxdf_f(b, wi, wo);
      for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(a[ch], c[ch], 1e-4f * std::max(1.0f, a[ch]));
      ++checked;
    }
  // Radiance-mode BTDF: f(wi -> wo) = eta^2 f(wo -> wi) for wo outside, wi inside.
  BxDF g = dielectric(0.4f, 1.5f);
  for (int i = 0; i < 2000; ++i) {
    vec3 wo = sample_uniform_hemisphere(vec2(u01(rng), u01(rng)));
    vec3 wi = -sample_uniform_hemisphere(vec2(u01(rng), u01(rng)));
    float a = bxdf_f(g, wo, wi).x, c = bxdf_f(g, wi, wo).x;
    EXPECT_NEAR(c, 1.5f * 1.5f * a, 1e-4f * std::max(1.0f, c));
    ++checked;
  }
  EXPECT_EQ(checked, 10000);
}

// The layered BxDFs are stochastic: their sampled pdf is only proportional
// to the density (as in pbrt-v4), so the chi-square test does not apply.
// Instead: the albedo from their sampling weights agrees with the albedo
// integrated from their f (this caught MIS weights in f's random walk that did
// not sum to one), energy is bounded, and the pdf is positive wherever f is and roughly normalised.
// The layered walk's shortcut: a dielectric's one-half sample with its weight
// alone must be bxdf_sample's sample (same direction, same refusals) with its
// f |cos| / pdf, for every roughness (smooth included), index, side and mode.
TEST(DielectricHalfSample, IsTheFullSampleWithItsWeight) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<float> u01(0.0f, 0.99999994f);
  int compared = 0, refused = 0;
  for (float alpha : {0.0f, 0.001f, 0.05f, 0.3f, 1.0f})
    for (float eta : {1.0f, 1.05f, 1.5f, 4.0f})
      for (uint8_t half : {uint8_t(kSampleReflection), uint8_t(kSampleTransmission)})
        for (TransportMode mode : {TransportMode::Radiance, TransportMode::Importance})
          for (int k = 0; k < 400; ++k) {
            const DielectricBxDF b{{alpha, alpha}, eta};
            const float cos_o = 2.0f * u01(rng) - 1.0f, phi = 6.2831853f * u01(rng);
            const float sin_o = std::sqrt(std::max(0.0f, 1.0f - cos_o * cos_o));
            const vec3 wo(sin_o * std::cos(phi), sin_o * std::sin(phi), cos_o);
            const vec2 u(u01(rng), u01(rng));
            const auto full = bxdf_sample(b, wo, 0.5f, u, mode, half);
            const auto one = bxdf_kinds::sample_one_half(b, wo, u, mode, half);
            ASSERT_EQ(bool(full), bool(one)) << "alpha " << alpha << " eta " << eta << " wo.z " << wo.z;
            if (!full) {
              ++refused;
              continue;
            }
            EXPECT_EQ(full->wi, one->wi);
            const RGB w = full->f * std::abs(full->wi.z) / full->pdf;
            for (int c = 0; c < 3; ++c) EXPECT_NEAR(one->weight[c], w[c], 2e-5f * std::max(1.0f, w[c]));
            ++compared;
          }
  EXPECT_GT(compared, 10000);
  EXPECT_GT(refused, 100);  // total internal reflection, eta 1 reflections: the refusals were exercised
}

TEST(LayeredBxDF, SamplingWeightsAgreeWithEvaluationAndConserveEnergy) {
  struct L {
    std::string name;
    BxDF b;
  };
  std::vector<L> cases = {
      {"coated white smooth", coated_diffuse(0.0f, RGB(1.0f))},
      {"coated white rough", coated_diffuse(0.3f, RGB(1.0f))},
      {"coated grey medium", coated_diffuse(0.1f, RGB(0.5f), RGB(0.8f))},
      {"coated grey rough medium", coated_diffuse(0.5f, RGB(0.5f), RGB(0.8f))},
      {"coated conductor", coated_conductor(0.05f, 0.2f)},
      {"coated conductor rough", coated_conductor(0.3f, 0.3f)},
      {"coated conductor smooth", coated_conductor(0.0f, 0.0f)},
  };
  for (const L& c : cases)
    for (float theta : {0.2f, 0.9f, 1.3f}) {
      vec3 wo = dir_at(theta);
      Estimate e = albedo_by_sampling(c.b, wo, 10'000, TransportMode::Radiance);
      for (int ch = 0; ch < 3; ++ch) EXPECT_LE(e.mean[ch], 1.0f + 5.0f * e.stderr_max) << c.name;
      // Where the coat is smooth, f holds only the walk's non-specular part.
      if (coat_of(c.b).distrib.effectively_smooth()) continue;
      glm::dvec3 q = layered_integral(c.b, wo, 20'000, [&](vec3 wi) {
        return glm::dvec3(bxdf_f(c.b, wo, wi, TransportMode::Radiance)) * double(std::abs(wi.z));
      });
      // 0.015: the quadrature's own noise (f is itself a one-walk estimate).
      for (int ch = 0; ch < 3; ++ch)
        EXPECT_NEAR(e.mean[ch], q[ch], 5.0f * e.stderr_max + 0.015f) << c.name << " theta " << theta << " ch " << ch;
      double pdf_total = layered_integral(c.b, wo, 4'000, [&](vec3 wi) {
                           return glm::dvec3(bxdf_pdf(c.b, wo, wi));
                         }).x;
      // A heuristic density (scene/layered.cpp): 0.94-1.87 over these cases;
      // pbrt-v4's unweighted sum gave 1.8-2.8.
      EXPECT_GT(pdf_total, 0.8) << c.name << " theta " << theta;
      EXPECT_LT(pdf_total, 2.0) << c.name << " theta " << theta;
    }
  // pdf: positive over f's hemisphere (MIS needs it), zero across it.
  BxDF b = coated_diffuse(0.3f, RGB(0.6f));
  for (float t : {0.0f, 0.7f, 1.5f}) EXPECT_GT(bxdf_pdf(b, dir_at(0.4f), dir_at(t, 2.0f)), 0.0f);
  EXPECT_EQ(bxdf_pdf(b, dir_at(0.4f), -dir_at(0.7f, 2.0f)), 0.0f);
  // Deterministic: the same arguments give the same value.
  EXPECT_EQ(bxdf_f(b, dir_at(0.4f), dir_at(0.7f, 2.0f)), bxdf_f(b, dir_at(0.4f), dir_at(0.7f, 2.0f)));
  EXPECT_TRUE(is_black(bxdf_f(b, dir_at(0.4f), -dir_at(0.7f, 2.0f))));  // opaque base
}

// A deferred layered pdf (scene/bsdf.h DeferredPdf) keeps only the coat, the
// base and the walk count: bit for bit bsdf_pdf of the whole BxDF, whatever
// its layer's other parameters (thickness, albedo, g, depth), both modes.
TEST(LayeredBxDF, DeferredPdfIsTheWholeBxDFsPdfBitForBit) {
  std::vector<BxDF> cases = {coated_diffuse(0.001f, RGB(0.2f, 0.05f, 0.0f)), coated_diffuse(0.3f, RGB(0.5f), RGB(0.8f)),
                             coated_conductor(0.05f, 0.2f), coated_conductor(0.0f, 0.3f, 1.3f)};
  layer_of(cases[1]) = LayerParams{0.3f, 0.6f, RGB(0.9f, 0.5f, 0.2f), 7, 3};
  layer_of(cases[2]) = LayerParams{0.05f, -0.4f, RGB(0.4f), 4, 2};
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  int nonzero = 0;
  for (const BxDF& b : cases)
    for (int i = 0; i < 200; ++i) {
      const vec3 wo = sample_uniform_sphere(vec2(u01(rng), u01(rng)));
      const vec3 wi = sample_uniform_sphere(vec2(u01(rng), u01(rng)));
      for (TransportMode mode : {TransportMode::Radiance, TransportMode::Importance}) {
        const float whole = bxdf_pdf(b, wo, wi, mode);
        ASSERT_EQ(std::bit_cast<uint32_t>(deferred_pdf(DeferredPdf(b, wo, wi, mode))), std::bit_cast<uint32_t>(whole));
        nonzero += whole > 0.0f;
      }
    }
  EXPECT_GT(nonzero, 600);
}

// A diffuse sample given its cosine-weighted direction made ahead (the
// wavefront's draw) is the sample that makes it, bit for bit, from either
// side of the surface; other kinds ignore the direction.
TEST(BxDFSample, DiffuseFromADirectionMadeAheadIsTheSame) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  const BxDF diffuse = DiffuseBxDF{RGB(0.7f, 0.5f, 0.3f)};
  const BxDF conductor = ConductorBxDF{};
  for (int i = 0; i < 2000; ++i) {
    const vec2 u(u01(rng), u01(rng));
    const vec3 wo = glm::normalize(vec3(u01(rng) - 0.5f, u01(rng) - 0.5f, (i % 2 ? 1.0f : -1.0f) * (0.05f + u01(rng))));
    const vec3 ahead = sample_cosine_hemisphere(u);
    for (const BxDF* b : {&diffuse, &conductor}) {
      const auto made = bxdf_sample(*b, wo, 0.5f, u);
      const auto given = bxdf_sample(*b, wo, 0.5f, u, TransportMode::Radiance, kSampleAll, &ahead);
      ASSERT_EQ(made.has_value(), given.has_value());
      if (!made) continue;
      for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(std::bit_cast<uint32_t>(made->wi[c]), std::bit_cast<uint32_t>(given->wi[c]));
        EXPECT_EQ(std::bit_cast<uint32_t>(made->f[c]), std::bit_cast<uint32_t>(given->f[c]));
      }
      EXPECT_EQ(std::bit_cast<uint32_t>(made->pdf), std::bit_cast<uint32_t>(given->pdf));
    }
  }
}
