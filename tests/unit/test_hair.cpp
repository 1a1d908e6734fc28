// pbrt-v4's HairBxDF (scene/hair.h): pbrt-v4's own hair tests (white furnace
// by uniform and by importance sampling, sampling weights, pdf/sampling
// consistency), theia's chi-square test of sample() against pdf(), and the
// "hair" material's parameters, precedence and shading frame.
#include "core/color.h"
#include "core/log.h"
#include "core/sampling.h"
#include "scene/accel.h"
#include "scene/bsdf.h"
#include "scene/parser.h"
#include "tests/unit/chi2.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <random>

using namespace theia;

namespace {

BxDF hair(float h, RGB sigma_a, float beta_m, float beta_n, float alpha = 2.0f) {
  return make_hair_bxdf(h, 1.55f, sigma_a, beta_m, beta_n, alpha);
}

float luminance_avg(RGB c) { return (c.x + c.y + c.z) / 3.0f; }

// Jittered-stratified directions over the sphere (n x n strata), so that the
// uniform estimates converge well past 2% on lobes as narrow as beta 0.1.
template <typename F>
void for_stratified_sphere(int n, std::mt19937& rng, F&& f) {
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) f(sample_uniform_sphere(vec2((i + U(rng)) / n, (j + U(rng)) / n)));
}

const float kBetas[] = {0.1f, 0.3f, 0.5f, 0.7f, 0.9f};

// Every (beta_m, beta_n) of the sweep, at a random offset h and direction wo.
template <typename F>
void for_beta_sweep(std::mt19937& rng, RGB sigma_a, F&& f) {
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  for (float bm : kBetas)
    for (float bn : kBetas) {
      BxDF b = hair(-1.0f + 2.0f * U(rng), sigma_a, bm, bn);
      vec3 wo = sample_uniform_sphere(vec2(U(rng), U(rng)));
      f(b, wo, bm, bn);
    }
}

}  // namespace

// With no absorption the fibre loses nothing: the integral of f |cos| over the
// sphere is 1 for every roughness, offset and direction (pbrt-v4's WhiteFurnace).
TEST(HairBxDF, WhiteFurnaceUniformSampling) {
  std::mt19937 rng(1);
  for_beta_sweep(rng, RGB(0.0f), [&](const BxDF& b, vec3 wo, float bm, float bn) {
    double sum = 0.0;
    const int n = 700;
    for_stratified_sphere(n, rng, [&](vec3 wi) { sum += luminance_avg(bxdf_f(b, wo, wi)) * std::abs(wi.z); });
    double avg = sum / (double(n) * n * uniform_sphere_pdf());
    EXPECT_NEAR(avg, 1.0, 0.02) << "beta_m " << bm << " beta_n " << bn;
  });
}

// The same integral estimated with the sampling routine.
TEST(HairBxDF, WhiteFurnaceImportanceSampling) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  for_beta_sweep(rng, RGB(0.0f), [&](const BxDF& b, vec3 wo, float bm, float bn) {
    double sum = 0.0;
    const int n = 100'000;
    for (int i = 0; i < n; ++i) {
      auto s = bxdf_sample(b, wo, U(rng), vec2(U(rng), U(rng)));
      if (s) sum += luminance_avg(s->f) * std::abs(s->wi.z) / s->pdf;
    }
    EXPECT_NEAR(sum / n, 1.0, 0.02) << "beta_m " << bm << " beta_n " << bn;
  });
}

// Sampling picks a lobe by A_p, so each sample's weight f |cos| / pdf lies
// between the smallest and largest A_p / P(p) of the lobes; without
// absorption that ratio is 1 for every lobe (pbrt-v4's SamplingWeights).
TEST(HairBxDF, SamplingWeightsWithinApBounds) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  for (RGB sigma_a : {RGB(0.0f), RGB(0.1f, 0.5f, 1.5f)})
    for (int k = 0; k < 200; ++k)
      for_beta_sweep(rng, sigma_a, [&](const BxDF& b, vec3 wo, float bm, float bn) {
        auto s = bxdf_sample(b, wo, U(rng), vec2(U(rng), U(rng)));
        if (!s) return;
        RGB w = s->f * std::abs(s->wi.z) / s->pdf;
        RGB ap[kHairPMax + 1];
        float ap_pdf[kHairPMax + 1];
        hair_ap(b.hair, wo, ap);
        hair_ap_pdf(b.hair, std::sqrt(std::max(0.0f, 1.0f - wo.x * wo.x)), ap_pdf);
        // f is linear in the A_p, so the bounds hold per band of the working
        // space too, with A_p taken there (no lossy round trip of f).
        for (int c = 0; c < 3; ++c) {
          float lo = 1e30f, hi = 0.0f;
          for (int p = 0; p <= kHairPMax; ++p) {
            if (!(ap_pdf[p] > 0.0f)) continue;
            float r = srgb_to_working(ap[p])[c] / ap_pdf[p];
            lo = std::min(lo, r), hi = std::max(hi, r);
          }
          EXPECT_GE(w[c], lo * 0.999f - 1e-6f) << bm << " " << bn << " band " << c;
          EXPECT_LE(w[c], hi * 1.001f + 1e-6f) << bm << " " << bn << " band " << c;
        }
      });
}

// pdf() is a density over the sphere, and the sampled estimate of the
// absorbing fibre's albedo matches the uniform one (pbrt-v4's
// SamplingConsistency): sample() and pdf() describe the same distribution.
TEST(HairBxDF, PdfIntegratesToOneAndSamplingAgreesWithUniform) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  for (float bm : {0.2f, 0.5f, 0.9f})
    for (float bn : {0.2f, 0.5f, 0.9f}) {
      BxDF b = hair(-1.0f + 2.0f * U(rng), RGB(0.25f, 0.5f, 1.0f), bm, bn);
      vec3 wo = sample_uniform_sphere(vec2(U(rng), U(rng)));
      double pdf_sum = 0.0, uniform = 0.0, sampled = 0.0;
      const int n = 600;
      for_stratified_sphere(n, rng, [&](vec3 wi) {
        pdf_sum += bxdf_pdf(b, wo, wi);
        uniform += luminance_avg(bxdf_f(b, wo, wi)) * std::abs(wi.z);
      });
      pdf_sum /= double(n) * n * uniform_sphere_pdf();
      uniform /= double(n) * n * uniform_sphere_pdf();
      const int m = 200'000;
      for (int i = 0; i < m; ++i)
        if (auto s = bxdf_sample(b, wo, U(rng), vec2(U(rng), U(rng))))
          sampled += luminance_avg(s->f) * std::abs(s->wi.z) / s->pdf;
      sampled /= m;
      EXPECT_NEAR(pdf_sum, 1.0, 0.02) << bm << " " << bn;
      EXPECT_GT(uniform, 0.05) << bm << " " << bn;  // absorbing, but far from black
      EXPECT_LT(uniform, 0.95) << bm << " " << bn;
      EXPECT_NEAR(sampled / uniform, 1.0, 0.02) << bm << " " << bn << " uniform " << uniform;
    }
}

TEST(HairBxDF, SigmaAConversionsFollowPbrt) {
  RGB s = hair_sigma_a_from_concentration(1.3f, 0.0f);
  EXPECT_NEAR(s.x, 1.3f * 0.419f, 1e-6f);
  EXPECT_NEAR(s.z, 1.3f * 1.37f, 1e-6f);
  RGB c(0.2f, 0.5f, 0.8f);
  RGB back = hair_reflectance_from_sigma_a(hair_sigma_a_from_reflectance(c, 0.3f), 0.3f);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(back[i], c[i], 1e-4f);
  // Darker colours absorb more.
  RGB sa = hair_sigma_a_from_reflectance(c, 0.3f);
  EXPECT_GT(sa.x, sa.y);
  EXPECT_GT(sa.y, sa.z);
}

// sample() is distributed as pdf() says, over roughness, offset and angle.
TEST(Chi2Hair, SamplingMatchesPdf) {
  struct Case { float bm, bn, h, theta; };
  std::vector<Case> cases;
  for (float bm : {0.2f, 0.5f, 0.9f})
    for (float bn : {0.2f, 0.6f})
      for (float h : {-0.7f, 0.3f})
        for (float theta : {0.4f, 1.4f}) cases.push_back({bm, bn, h, theta});
  for (const Case& c : cases) {
    BxDF b = hair(c.h, RGB(0.3f, 0.6f, 1.2f), c.bm, c.bn);
    // wo tilted off the fibre (x) by theta, so sin(theta_o) = wo.x varies.
    vec3 wo = glm::normalize(vec3(std::cos(c.theta), 0.6f * std::sin(c.theta), 0.8f * std::sin(c.theta)));
    auto r = chi2_test_sphere(
        [&](vec2 u, float u1) -> std::optional<vec3> {
          auto s = bxdf_sample(b, wo, u1, u);
          if (!s) return std::nullopt;
          return glm::normalize(s->wi);
        },
        [&](vec3 wi) { return bxdf_pdf(b, wo, wi); }, 30'000, 16, 32, 0.01, int(cases.size()),
        fmt::format("hair beta_m={} beta_n={} h={} theta={}", c.bm, c.bn, c.h, c.theta));
    EXPECT_TRUE(r.passed) << r.report;
  }
}

// The harness at this resolution rejects a pdf off by a few percent of its mass:
// hair sampled at beta_n 0.6 against the pdf of beta_n 0.5.
TEST(Chi2Hair, RejectsASlightlyWrongPdf) {
  BxDF b = hair(0.3f, RGB(0.3f), 0.4f, 0.6f), wrong = hair(0.3f, RGB(0.3f), 0.4f, 0.5f);
  vec3 wo = glm::normalize(vec3(0.5f, 0.5f, 0.7f));
  auto r = chi2_test_sphere(
      [&](vec2 u, float u1) -> std::optional<vec3> {
        auto s = bxdf_sample(b, wo, u1, u);
        if (!s) return std::nullopt;
        return glm::normalize(s->wi);
      },
      [&](vec3 wi) { return bxdf_pdf(wrong, wo, wi); }, 30'000, 16, 32, 0.01, 1, "wrong hair pdf");
  EXPECT_FALSE(r.passed) << r.report;
}

namespace {
Scene parse_hair(const std::string& params) {
  return parse_scene_string(fmt::format(R"(WorldBegin
MakeNamedMaterial "m" "string type" "hair" {}
NamedMaterial "m"
Shape "sphere"
)", params), "test.pbrt");
}
int warnings_of(const std::string& params) {
  int before = warning_count();
  parse_hair(params);
  return warning_count() - before;
}
const Material& hair_material(const Scene& s) {
  for (const Material& m : s.materials)
    if (m.kind == MaterialKind::Hair) return m;
  throw std::runtime_error("no hair material");
}
}  // namespace

TEST(HairMaterial, ParametersAndPrecedence) {
  // Nothing given: eumelanin 1.3, no warning (the material used to be substituted with one).
  EXPECT_EQ(warnings_of(""), 0);
  {
    Scene s = parse_hair("");
    const Material& m = hair_material(s);
    EXPECT_EQ(m.sigma_a, -1);
    EXPECT_EQ(m.reflectance, -1);
    ASSERT_GE(m.eumelanin, 0);
    EXPECT_FLOAT_EQ(s.textures[size_t(m.eumelanin)].value.x, 1.3f);
    EXPECT_FLOAT_EQ(m.eta, 1.55f);
    EXPECT_FLOAT_EQ(s.textures[size_t(m.beta_m)].value.x, 0.3f);
    EXPECT_FLOAT_EQ(s.textures[size_t(m.beta_n)].value.x, 0.3f);
    EXPECT_FLOAT_EQ(s.textures[size_t(m.hair_alpha)].value.x, 2.0f);
  }
  // Only pheomelanin: eumelanin 0 (pbrt-v4 defaults eumelanin only when no form is given).
  {
    Scene s = parse_hair(R"("float pheomelanin" 0.8 "float eta" 1.4 "float beta_m" 0.2 "float beta_n" 0.6 "float alpha" 3)");
    const Material& m = hair_material(s);
    EXPECT_FLOAT_EQ(s.textures[size_t(m.eumelanin)].value.x, 0.0f);
    EXPECT_FLOAT_EQ(s.textures[size_t(m.pheomelanin)].value.x, 0.8f);
    EXPECT_FLOAT_EQ(m.eta, 1.4f);
    EXPECT_FLOAT_EQ(s.textures[size_t(m.beta_m)].value.x, 0.2f);
    EXPECT_FLOAT_EQ(s.textures[size_t(m.beta_n)].value.x, 0.6f);
    EXPECT_FLOAT_EQ(s.textures[size_t(m.hair_alpha)].value.x, 3.0f);
  }
  // sigma_a wins and stays in the bands the scene gives (not converted to the working space).
  {
    Scene s = parse_hair(R"("rgb sigma_a" [0.2 0.4 0.9])");
    const Material& m = hair_material(s);
    ASSERT_GE(m.sigma_a, 0);
    vec3 v = s.textures[size_t(m.sigma_a)].value;
    EXPECT_NEAR(v.x, 0.2f, 1e-6f);
    EXPECT_NEAR(v.y, 0.4f, 1e-6f);
    EXPECT_NEAR(v.z, 0.9f, 1e-6f);
    EXPECT_EQ(m.eumelanin, -1);
  }
  EXPECT_EQ(warnings_of(R"("rgb sigma_a" [0.2 0.4 0.9])"), 0);
  EXPECT_EQ(warnings_of(R"("rgb reflectance" [0.3 0.2 0.1])"), 0);
  // Lower-precedence forms alongside a higher one are ignored with one warning each, as pbrt-v4 does.
  EXPECT_EQ(warnings_of(R"("rgb sigma_a" [1 1 1] "rgb reflectance" [0.3 0.2 0.1] "float eumelanin" 2)"), 2);
  {
    Scene s = parse_hair(R"("rgb reflectance" [0.3 0.2 0.1] "float eumelanin" 2)");
    const Material& m = hair_material(s);
    EXPECT_GE(m.reflectance, 0);
    EXPECT_EQ(m.eumelanin, -1);
  }
}

// make_bsdf: h = -1 + 2 v, the frame's x along dpdu even when the shading
// normal leans along the fibre, and sigma_a from the material.
TEST(HairMaterial, BsdfFrameAndOffset) {
  Scene s = parse_hair(R"("rgb sigma_a" [0.2 0.4 0.9])");
  SurfaceInteraction si;
  si.material = int(&hair_material(s) - s.materials.data());
  si.uv = vec2(0.3f, 0.8f);
  si.dpdu = vec3(0.0f, 2.0f, 0.0f);
  si.dpdv = vec3(0.1f, 0.0f, 0.0f);
  si.ng = glm::normalize(vec3(0.0f, 0.3f, 1.0f));  // not perpendicular to dpdu
  si.ns = si.ng;
  BSDF b = make_bsdf(s, si);
  ASSERT_EQ(b.bxdf.kind, BxDFKind::Hair);
  EXPECT_NEAR(b.bxdf.hair.h, 0.6f, 1e-6f);
  EXPECT_NEAR(b.shading.s.y, 1.0f, 1e-6f);
  EXPECT_NEAR(glm::dot(b.shading.n, b.shading.s), 0.0f, 1e-6f);
  EXPECT_NEAR(glm::dot(b.shading.n, si.ng), std::sqrt(1.0f - sqr(si.ng.y)), 1e-5f);
  EXPECT_NEAR(b.bxdf.hair.sigma_a.z, 0.9f, 1e-6f);
  EXPECT_EQ(b.lobe_count, 1);
  EXPECT_EQ(b.lobes[0].flags, kLobeReflection | kLobeTransmission | kLobeGlossy);
  EXPECT_FLOAT_EQ(b.lobes[0].roughness, 0.3f);
  // A direction along the fibre has sin(theta) = 1 in the BxDF's frame.
  EXPECT_NEAR(b.shading.to_local(vec3(0, 1, 0)).x, 1.0f, 1e-6f);
}

namespace {
// A straight hair along x from (0, 0, 0) to (1, 0, 0), width 0.2, of the
// given curve type; ribbons face +z.  Variants: 1 runs it backwards, 2 under
// ReverseOrientation, 3 mirrored in z (Scale 1 1 -1, baked), 4 an instance
// mirrored in z.  None moves the fibre.
Scene straight_hair(const std::string& type, const std::string& material, int variant = 0) {
  std::string p = variant == 1 ? "1 0 0  0.666667 0 0  0.333333 0 0  0 0 0" : "0 0 0  0.333333 0 0  0.666667 0 0  1 0 0";
  std::string n = type == "ribbon" ? R"("normal N" [0 0 1  0 0 1])" : "";
  std::string shape = fmt::format(R"(Shape "curve" "string type" "{}" "float width" [0.2] "point3 P" [{}] {})", type, p, n);
  if (variant == 2) shape = "ReverseOrientation " + shape;
  if (variant == 3) shape = "Scale 1 1 -1 " + shape;
  if (variant == 4) shape = "ObjectBegin \"h\" " + shape + " ObjectEnd Scale 1 1 -1 ObjectInstance \"h\"";
  return parse_scene_string(fmt::format("WorldBegin\nMaterial \"hair\" {}\n{}\n", material, shape), "test.pbrt");
}

BSDF hair_bsdf_at(const Scene& s, const Accel& a, const Ray& ray) {
  Hit hit = a.intersect1(ray);
  EXPECT_TRUE(hit.hit());
  if (!hit.hit()) return {};
  return make_bsdf(s, compute_interaction(s, a, ray, hit));
}
}  // namespace

// The offset h that reaches the BxDF on each curve type is the ray's distance
// from the fibre's axis over the radius, signed along y = z x x of a frame
// whose z faces the ray, whichever way the curve runs, from either side,
// with the normal reversed and under mirrors.
// (On round curves Embree's v is 0: reading h = -1 + 2v there made every hit
// grazing, Fresnel 1, and absorbing hair lossless.)
TEST(HairMaterial, OffsetAcrossTheFibreOnEveryCurveType) {
  const float r = 0.1f;
  for (std::string type : {"cylinder", "flat", "ribbon"})
    for (int variant = 0; variant < 5; ++variant)
      for (float side : {1.0f, -1.0f})
        for (float tilt : {0.0f, 0.4f})
          for (float y0 : {-0.085f, -0.04f, 0.0f, 0.03f, 0.075f}) {
            Scene s = straight_hair(type, R"("rgb sigma_a" [1 1 1])", variant);
            Accel a(s);
            vec3 d = glm::normalize(vec3(tilt, 0.0f, -side));
            vec3 o = vec3(0.5f, y0, 0.0f) - 5.0f * d;
            BSDF b = hair_bsdf_at(s, a, Ray{o, 0.0f, d, kInfinity});
            ASSERT_EQ(b.bxdf.kind, BxDFKind::Hair) << type;
            vec3 x = b.shading.s, wo = -d;
            EXPECT_NEAR(std::abs(x.x), 1.0f, 1e-4f) << type;
            vec3 wo_perp = glm::normalize(wo - glm::dot(wo, x) * x);
            float want = glm::dot(o - vec3(0.5f, 0.0f, 0.0f), glm::normalize(glm::cross(wo_perp, x))) / r;
            // Tubes: Embree's hit point is within ~2% of the radius; flat: its chord.
            EXPECT_NEAR(b.bxdf.hair.h, want, 0.03f)
                << type << " variant " << variant << " side " << side << " tilt " << tilt << " y0 " << y0;
          }
}

// The whole chain, from the hit to the BxDF's azimuths: on a tube with only
// the R lobe left (opaque, smooth, untilted scales), f peaks at the mirror
// image of wo in the tube's true normal, not at the mirror image about the
// normal on the other side of the axis (what a flipped h would give).
TEST(HairMaterial, SurfaceReflectionLeavesAtTheMirrorDirection) {
  Scene s = straight_hair("cylinder", R"("rgb sigma_a" [50 50 50] "float beta_m" 0.1 "float beta_n" 0.1 "float alpha" 0)");
  Accel a(s);
  for (float y0 : {-0.07f, -0.04f, 0.03f, 0.06f}) {
    vec3 o(0.5f, y0, 5.0f), d(0.0f, 0.0f, -1.0f);
    BSDF b = hair_bsdf_at(s, a, Ray{o, 0.0f, d, kInfinity});
    ASSERT_EQ(b.bxdf.kind, BxDFKind::Hair);
    // The true normal where the ray meets the tube of radius 0.1 and the normal mirrored across the axis.
    vec3 n(0.0f, y0 / 0.1f, std::sqrt(1.0f - sqr(y0 / 0.1f))), n_flip(0.0f, -n.y, n.z);
    vec3 wo = -d;
    vec3 mirror = 2.0f * glm::dot(wo, n) * n - wo, wrong = 2.0f * glm::dot(wo, n_flip) * n_flip - wo;
    float f_mirror = luminance_avg(bsdf_f(b, wo, mirror)), f_wrong = luminance_avg(bsdf_f(b, wo, wrong));
    EXPECT_GT(f_mirror, 10.0f * f_wrong) << "y0 " << y0 << ": h " << b.bxdf.hair.h;
  }
}

// Guiding shares sampling by hemisphere (bsdf_event's lobe_of), which the
// fibre's lobes do not follow.
TEST(HairMaterial, IsNotGuidable) {
  Scene s = straight_hair("cylinder", R"("rgb sigma_a" [1 1 1] "float beta_m" 0.9)");
  Accel a(s);
  BSDF b = hair_bsdf_at(s, a, Ray{vec3(0.5f, 0.02f, 5.0f), 0.0f, vec3(0, 0, -1), kInfinity});
  ASSERT_EQ(b.bxdf.kind, BxDFKind::Hair);
  EXPECT_FALSE(bsdf_is_guidable(b, 0.0f));
}
