// Weighted chi-square tests of the layered BxDFs' sampling (coateddiffuse,
// coatedconductor: scene/layered.cpp) against their own evaluation, over a
// sweep of coat roughness, index, incident angle, medium and transport mode.
// The plain test (test_bsdf_chi2.cpp) needs the density of the samples, which
// a layered BxDF does not have: its sample's pdf is only proportional
// (pbrt-v4), and its f and pdf are random-walk estimates.  What both sides do
// give unbiasedly is the scattered energy per cell of directions: the
// sampler's weighted histogram of f |cos| / pdf, and the integral of f |cos|
// over the cell (tests/unit/chi2.h, chi2_test_sphere_weighted).
#include "tests/unit/bxdf_test_util.h"
#include "tests/unit/chi2.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

using namespace theia;
using namespace theia::test;

namespace {

constexpr double kSignificance = 0.01;
// 80k samples and 80k evaluations a case in 8 x 16 equal-solid-angle cells
// (64 over the lit hemisphere, ~1000 samples in a diffuse cell): the sweep of
// 46 cases takes ~7.5 s on one core, sampling and evaluation about equally.
// A tenth of the evaluations is uniform over the sphere, the rest follows the
// lobes below.
WeightedChi2Settings settings(int n_tests) {
  WeightedChi2Settings s;
  s.n_samples = 80'000;
  s.n_evals = 80'000;
  s.theta_res = 8;
  s.phi_res = 16;
  s.uniform_share = 0.1;
  s.significance = kSignificance;
  s.n_tests = n_tests;
  return s;
}

struct Case {
  std::string name;
  BxDF bxdf;
  vec3 wo;
  TransportMode mode = TransportMode::Radiance;
};

BxDF with_coat(BxDF b, float alpha, float eta) {
  coat_of(b) = DielectricBxDF{{alpha, alpha}, eta};
  return b;
}
BxDF coated_diffuse_case(float alpha, float eta) { return with_coat(coated_diffuse(alpha, RGB(0.8f, 0.5f, 0.2f)), alpha, eta); }
BxDF coated_conductor_case(float alpha, float eta, float base_alpha = 0.2f) {
  return coated_conductor(alpha, base_alpha, eta);
}
BxDF with_medium(BxDF b, float thickness, float albedo, float g) {
  LayerParams& layer = layer_of(b);
  layer.thickness = thickness;
  layer.albedo = RGB(albedo);
  layer.g = g;
  return b;
}

constexpr float kDeg = kPi / 180.0f;

std::vector<Case> sweep() {
  std::vector<Case> cases;
  const float angles[] = {5.0f * kDeg, 45.0f * kDeg, 85.0f * kDeg};
  for (float alpha : {0.0f, 0.05f, 0.3f, 0.8f})
    for (float theta : angles) {
      cases.push_back({fmt::format("coateddiffuse a={} eta=1.5 theta={:.0f}", alpha, theta / kDeg),
                       coated_diffuse_case(alpha, 1.5f), dir_at(theta)});
      cases.push_back({fmt::format("coatedconductor a={} eta=1.5 theta={:.0f}", alpha, theta / kDeg),
                       coated_conductor_case(alpha, 1.5f), dir_at(theta)});
    }
  for (float eta : {1.1f, 2.5f})
    for (float alpha : {0.0f, 0.05f, 0.3f}) {
      float theta = alpha == 0.05f ? angles[2] : angles[1];
      cases.push_back({fmt::format("coateddiffuse a={} eta={} theta={:.0f}", alpha, eta, theta / kDeg),
                       coated_diffuse_case(alpha, eta), dir_at(theta)});
      cases.push_back({fmt::format("coatedconductor a={} eta={} theta={:.0f}", alpha, eta, theta / kDeg),
                       coated_conductor_case(alpha, eta), dir_at(theta)});
    }
  // Scattering media: the walk's phase-function and NEE-through-the-coat branches.
  cases.push_back({"coateddiffuse a=0.3 medium albedo 0.8 g=0.5 thickness 0.1",
                   with_medium(coated_diffuse_case(0.3f, 1.5f), 0.1f, 0.8f, 0.5f), dir_at(angles[1])});
  cases.push_back({"coateddiffuse a=0 medium albedo 0.9 g=-0.3 thickness 1",
                   with_medium(coated_diffuse_case(0.0f, 1.5f), 1.0f, 0.9f, -0.3f), dir_at(angles[2])});
  cases.push_back({"coatedconductor a=0 smooth base, medium albedo 0.8 g=0.7 thickness 0.2",
                   with_medium(coated_conductor_case(0.0f, 1.5f, 0.0f), 0.2f, 0.8f, 0.7f), dir_at(angles[1])});
  cases.push_back({"coatedconductor a=0.3 base 0.5, medium albedo 0.5 g=0 thickness 0.05",
                   with_medium(coated_conductor_case(0.3f, 1.5f, 0.5f), 0.05f, 0.5f, 0.0f), dir_at(angles[0])});
  // A narrow base lobe under a rough coat.  (A smooth base under a rough coat
  // without a medium is left out: there pbrt-v4's f has only one strategy, the
  // walk from wo with NEE through the coat, whose estimate away from the
  // mirror direction is so heavy-tailed that a point's value still doubles
  // from 10^5 to 4 x 10^6 walks: unbiased, but no affordable integral of it
  // is close to its mean.)
  cases.push_back({"coatedconductor a=0.3 base 0.05", coated_conductor_case(0.3f, 1.5f, 0.05f), dir_at(angles[1])});
  // Importance transport differs wherever a refraction scales by 1 / eta^2.
  cases.push_back({"coateddiffuse a=0.3 eta=2.5 importance", coated_diffuse_case(0.3f, 2.5f), dir_at(angles[1]),
                   TransportMode::Importance});
  cases.push_back({"coateddiffuse a=0 eta=1.5 importance", coated_diffuse_case(0.0f, 1.5f), dir_at(angles[2]),
                   TransportMode::Importance});
  cases.push_back({"coatedconductor a=0.05 eta=1.5 importance", coated_conductor_case(0.05f, 1.5f),
                   dir_at(angles[2]), TransportMode::Importance});
  cases.push_back({"coateddiffuse a=0.3 medium importance",
                   with_medium(coated_diffuse_case(0.3f, 2.5f), 0.1f, 0.8f, 0.5f), dir_at(angles[1]),
                   TransportMode::Importance});
  // From below: both layered BxDFs are two-sided.
  cases.push_back({"coateddiffuse a=0.3 from below", coated_diffuse_case(0.3f, 1.5f), -dir_at(angles[1])});
  return cases;
}

// The integral side's densities: a cosine lobe over wo's hemisphere (both
// BxDFs are opaque), and microfacet reflection lobes around wo's mirror
// direction (a perfect mirror's visible-normal sampling, whose pdf is exact):
// the coat's width, half of it (the coat-base-coat path through a rough coat
// is narrower than the coat's reflection), and the conductor base's.
std::vector<DirectionLobe> lobes_for(const Case& c) {
  const float coat_alpha = coat_of(c.bxdf).distrib.alpha_x;
  std::vector<float> alphas = {coat_alpha, 0.5f * coat_alpha};
  if (c.bxdf.kind == BxDFKind::CoatedConductor) alphas.push_back(c.bxdf.coated_conductor.base.distrib.alpha_x);
  const float side = c.wo.z > 0.0f ? 1.0f : -1.0f;
  std::vector<DirectionLobe> lobes = {
      {[side](vec2 u, float) -> std::optional<vec3> { return sample_cosine_hemisphere(u) * side; },
       [side](vec3 v) { return v.z * side > 0.0f ? double(cosine_hemisphere_pdf(std::abs(v.z))) : 0.0; }}};
  for (float alpha : alphas) {
    BxDF mirror = perfect_mirror(alpha);
    if (mirror.conductor.distrib.effectively_smooth()) continue;
    vec3 wo = c.wo;
    lobes.push_back({[mirror, wo](vec2 u, float u1) -> std::optional<vec3> {
                       auto s = bxdf_sample(mirror, wo, u1, u);
                       if (!s) return std::nullopt;
                       return glm::normalize(s->wi);
                     },
                     [mirror, wo](vec3 v) { return double(bxdf_pdf(mirror, wo, v)); }});
  }
  return lobes;
}

double channel_mean(const RGB& c) { return (double(c[0]) + double(c[1]) + double(c[2])) / 3.0; }

// Specular samples (a smooth coat's reflection, all-specular walks) are
// deltas f leaves out (pbrt-v4's convention): they are declined here, and
// counted for the caller.
struct SpecularTally {
  long count = 0;
  double weight = 0.0;
};

// `distort` lets a test break the sampler on purpose.
WeightedChi2Result run(const Case& c, const WeightedChi2Settings& st, SpecularTally* specular = nullptr,
                       const std::function<void(WeightedDirection&)>& distort = {}) {
  auto sample = [&](vec2 u, float u1) -> std::optional<WeightedDirection> {
    auto s = bxdf_sample(c.bxdf, c.wo, u1, u, c.mode);
    if (!s) return std::nullopt;
    double w = channel_mean(s->f) * std::abs(s->wi.z) / double(s->pdf);
    if (s->is_specular()) {
      if (specular) {
        ++specular->count;
        specular->weight += w;
      }
      return std::nullopt;
    }
    WeightedDirection d{glm::normalize(s->wi), w};
    if (distort) distort(d);
    return d;
  };
  auto integrand = [&](vec3 wi) { return channel_mean(bxdf_f(c.bxdf, c.wo, wi, c.mode)) * std::abs(double(wi.z)); };
  return chi2_test_sphere_weighted(c.name, sample, integrand, lobes_for(c), st);
}

}  // namespace

TEST(Chi2LayeredBxDF, SamplingAgreesWithEvaluationAcrossRoughnessIorAngleAndMedium) {
  auto cases = sweep();
  EXPECT_GE(cases.size(), 40u);
  const WeightedChi2Settings st = settings(int(cases.size()));
  for (const Case& c : cases) {
    SpecularTally spec;
    auto r = run(c, st, &spec);
    EXPECT_TRUE(r.passed) << r.report;
    // The specular samples f leaves out: under a smooth coat over a base that
    // is not a mirror, only the coat's own reflection, each of weight 1 with
    // probability F (so a binomial count).
    const BxDF& b = c.bxdf;
    bool mirror_base = b.kind == BxDFKind::CoatedConductor && b.coated_conductor.base.distrib.effectively_smooth();
    if (coat_of(b).distrib.effectively_smooth() && !mirror_base) {
      double fresnel = fresnel_dielectric(std::abs(c.wo.z), coat_of(b).eta), n = st.n_samples;
      double z = (spec.weight / n - fresnel) / std::sqrt(fresnel * (1.0 - fresnel) / n);
      EXPECT_GE(chi2_p_value(z * z, 1), sidak_level(kSignificance, 2 * st.n_tests))
          << c.name << ": specular weight " << spec.weight / n << " (" << spec.count << " samples), Fresnel " << fresnel;
    } else if (!mirror_base) {
      EXPECT_EQ(spec.count, 0) << c.name;  // a rough coat: no path is all specular
    }
  }
}

// Not run by default (~80 s): the sweep under 8 other seeds, to check after
// retuning that the statistic follows its null distribution (the variances
// are estimated, the weights skewed) and the sweep does not fail by chance.
// Measured with the settings above: 736 p-values (both tests, 46 cases),
// 90 below 0.1 (73.6 expected), 10 below 0.01 (7.4), none below 0.001.
TEST(Chi2LayeredBxDF, DISABLED_NullCalibration) {
  auto cases = sweep();
  std::vector<double> ps;
  for (uint64_t seed = 1; seed <= 8; ++seed)
    for (const Case& c : cases) {
      auto st = settings(int(cases.size()));
      st.seed = seed;
      auto r = run(c, st);
      ps.push_back(r.p_value);
      ps.push_back(r.total_p_value);
      if (std::min(r.p_value, r.total_p_value) < 0.001) std::printf("seed %d: %s", int(seed), r.report.c_str());
    }
  auto below = [&](double t) { return double(std::count_if(ps.begin(), ps.end(), [&](double p) { return p < t; })); };
  for (double t : {0.1, 0.01, 0.001})
    std::printf("p < %g: %.0f of %zu (expected %.1f)\n", t, below(t), ps.size(), t * double(ps.size()));
  EXPECT_LE(below(0.01), 2.0 * 0.01 * double(ps.size()));
  EXPECT_EQ(below(sidak_level(kSignificance, 2 * int(cases.size()))), 0.0);
}

// The sweep's settings can fail: with the same sample counts, grid and Sidak
// correction, a sampler whose weights are 5% high (all of them: an overall
// energy error), 10% high over half the hemisphere (wi.y > 0), or whose
// directions lean ~1.5 degrees towards the normal is rejected, on a rough and
// a narrow coat and on a smooth coat at grazing incidence (largest p-values
// 3e-10, 8e-7 and 4e-15 against the sweep's threshold of 1.1e-4).  5% over
// half the hemisphere is beyond these settings: rejected on the first case
// only (p 3e-5; 0.06 and 0.005 on the others).
TEST(Chi2LayeredBxDF, SweepSettingsRejectASlightlyWrongSampler) {
  const int n_tests = int(sweep().size());
  const Case cases[] = {{"coateddiffuse a=0.3", coated_diffuse_case(0.3f, 1.5f), dir_at(45.0f * kDeg)},
                        {"coatedconductor a=0.05", coated_conductor_case(0.05f, 1.5f), dir_at(45.0f * kDeg)},
                        {"coateddiffuse a=0 grazing", coated_diffuse_case(0.0f, 1.5f), dir_at(85.0f * kDeg)}};
  for (const Case& c : cases) {
    auto energy = run(c, settings(n_tests), nullptr, [](WeightedDirection& d) { d.weight *= 1.05; });
    EXPECT_FALSE(energy.passed) << "weights x 1.05: " << energy.report;
    auto half = run(c, settings(n_tests), nullptr, [](WeightedDirection& d) {
      if (d.wi.y > 0.0f) d.weight *= 1.1;
    });
    EXPECT_FALSE(half.passed) << "weights x 1.1 where wi.y > 0: " << half.report;
    auto tilted = run(c, settings(n_tests), nullptr, [](WeightedDirection& d) {
      d.wi = glm::normalize(d.wi + vec3(0.0f, 0.0f, 0.03f * (d.wi.z > 0.0f ? 1.0f : -1.0f)));
    });
    EXPECT_FALSE(tilted.passed) << "directions tilted: " << tilted.report;
  }
}
