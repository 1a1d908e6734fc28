// Every warp and tabulated distribution in core/ against its own pdf, by
// chi-square; and the harness itself against a deliberately wrong pdf.
#include "core/distribution2d.h"
#include "core/equal_mass.h"
#include "core/log.h"
#include "core/sampling.h"
#include "tests/unit/chi2.h"

#include <gtest/gtest.h>

#include <bit>
#include <random>

using namespace theia;

namespace {

constexpr double kSignificance = 0.01;
constexpr int kSamples = 1'000'000;

std::vector<float> random_table(size_t n, uint64_t seed, float zero_fraction) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<float> t(n);
  for (float& v : t) v = u(rng) < zero_fraction ? 0.0f : 10.0f * u(rng) * u(rng);
  return t;
}

}  // namespace

TEST(Chi2Warps, CosineHemisphere) {
  auto r = chi2_test_sphere([](vec2 u, float) { return std::optional(sample_cosine_hemisphere(u)); },
                            [](vec3 w) { return cosine_hemisphere_pdf(w.z); }, kSamples, 32, 64, kSignificance, 1,
                            "cosine hemisphere");
  EXPECT_TRUE(r.passed) << r.report;
}

TEST(Chi2Warps, UniformSphereAndHemisphere) {
  auto sphere = chi2_test_sphere([](vec2 u, float) { return std::optional(sample_uniform_sphere(u)); },
                                 [](vec3) { return uniform_sphere_pdf(); }, kSamples, 32, 64, kSignificance, 2,
                                 "uniform sphere");
  EXPECT_TRUE(sphere.passed) << sphere.report;
  auto hemi = chi2_test_sphere([](vec2 u, float) { return std::optional(sample_uniform_hemisphere(u)); },
                               [](vec3 w) { return w.z >= 0.0f ? uniform_hemisphere_pdf() : 0.0f; }, kSamples, 32,
                               64, kSignificance, 2, "uniform hemisphere");
  EXPECT_TRUE(hemi.passed) << hemi.report;
}

TEST(Chi2Warps, UniformConeAtSeveralAngles) {
  const float angles[] = {-0.5f, 0.0f, 0.5f, 0.9f};
  for (float cos_max : angles) {
    auto r = chi2_test_sphere([&](vec2 u, float) { return std::optional(sample_uniform_cone(u, cos_max)); },
                              [&](vec3 w) { return w.z >= cos_max ? uniform_cone_pdf(cos_max) : 0.0f; }, kSamples,
                              32, 64, kSignificance, 5, "cone " + std::to_string(cos_max));
    EXPECT_TRUE(r.passed) << r.report;
  }
  // A narrow cone covers a fraction of one sphere cell, so bin it in its own
  // (cos theta, phi) rectangle, where the solid-angle pdf is also the area pdf.
  const float cos_max = 0.995f;
  auto narrow = chi2_test_square(
      [&](vec2 u) {
        vec3 w = sample_uniform_cone(u, cos_max);
        float phi = std::atan2(w.y, w.x);
        return std::optional(vec2(w.z, phi < 0.0f ? phi + 2.0f * kPi : phi));
      },
      [&](vec2) { return uniform_cone_pdf(cos_max); }, vec2(cos_max, 0.0f), vec2(1.0f, 2.0f * kPi), kSamples, 32,
      kSignificance, 5, "narrow cone");
  EXPECT_TRUE(narrow.passed) << narrow.report;
}

TEST(Chi2Warps, ConcentricDiskTriangleAndTent) {
  auto disk = chi2_test_square([](vec2 u) { return std::optional(sample_uniform_disk_concentric(u)); },
                               [](vec2 p) { return glm::dot(p, p) <= 1.0f ? kInvPi : 0.0f; }, vec2(-1.0f),
                               vec2(1.0f), kSamples, 40, kSignificance, 3, "concentric disk");
  EXPECT_TRUE(disk.passed) << disk.report;
  auto tri = chi2_test_square([](vec2 u) { return std::optional(sample_uniform_triangle(u)); },
                              [](vec2 b) { return b.x + b.y <= 1.0f ? 2.0f : 0.0f; }, vec2(0.0f), vec2(1.0f),
                              kSamples, 40, kSignificance, 3, "triangle barycentrics");
  EXPECT_TRUE(tri.passed) << tri.report;
  const float r = 1.5f;
  auto tent = chi2_test_square([&](vec2 u) { return std::optional(vec2(sample_tent(u.x, r), sample_tent(u.y, r))); },
                               [&](vec2 p) { return tent_pdf(p.x, r) * tent_pdf(p.y, r); }, vec2(-r), vec2(r),
                               kSamples, 40, kSignificance, 3, "tent");
  EXPECT_TRUE(tent.passed) << tent.report;
}

TEST(Chi2Distributions, Distribution1DWithRandomTables) {
  const size_t sizes[] = {1, 7, 64};
  for (size_t n : sizes) {
    std::vector<float> table = random_table(n, 100 + n, n > 1 ? 0.2f : 0.0f);
    Distribution1D d(table);
    auto pdf = [&](float x) {
      size_t i = std::min(size_t(x * float(n)), n - 1);
      return d.func[i] / d.integral;
    };
    // 1D: the second coordinate is an independent uniform, so the 2D pdf is the 1D one.
    auto r = chi2_test_square(
        [&](vec2 u) {
          float p = 0.0f;
          float x = d.sample_continuous(u.x, &p);
          // The pdf the routine reports is the pdf it samples with.
          if (std::abs(p - pdf(x)) > 1e-5f * pdf(x)) return std::optional<vec2>();
          return std::optional(vec2(x, u.y));
        },
        [&](vec2 p) { return pdf(p.x); }, vec2(0.0f), vec2(1.0f), kSamples, 50, kSignificance, 3,
        "Distribution1D n=" + std::to_string(n));
    EXPECT_TRUE(r.passed) << r.report;
  }
}

// EqualMass1D over [lo, hi]: its density is the one it reports (chi-square),
// every segment holds 1/n of the samples, and 1 / pdf is what sample() writes.
TEST(Chi2Distributions, EqualMass1DFromRandomTables) {
  const float lo = -1.5f, hi = 2.5f;
  for (size_t n : {size_t(7), size_t(64)}) {
    Distribution1D d(random_table(n, 300 + n, 0.2f));
    EqualMass1D e(d, 32, lo, hi, [&](float x) { return 1.0f + 0.5f * std::sin(3.0f * x); });
    ASSERT_EQ(e.size(), 32);
    EXPECT_EQ(e.bounds.front(), lo);
    EXPECT_EQ(e.bounds.back(), hi);
    auto r = chi2_test_square(
        [&](vec2 u) {
          float inv_pdf = 0.0f;
          float x = e.sample(u.x, &inv_pdf);
          if (std::abs(inv_pdf * e.pdf(x) - 1.0f) > 1e-5f) return std::optional<vec2>();
          return std::optional(vec2(x, u.y));
        },
        [&](vec2 p) { return e.pdf(p.x); }, vec2(lo, 0.0f), vec2(hi, 1.0f), kSamples, 50,
        kSignificance, 2, "EqualMass1D n=" + std::to_string(n));
    EXPECT_TRUE(r.passed) << r.report;
    // The segments are d's quantiles: each holds probability 1/32 under d.
    for (int k = 0; k <= 32; ++k) {
      float t = (e.bounds[size_t(k)] - lo) / (hi - lo);
      size_t i = std::min(size_t(t * float(n)), n - 1);
      float cdf = d.cdf[i] + (t * float(n) - float(i)) * (d.cdf[i + 1] - d.cdf[i]);
      EXPECT_NEAR(cdf, float(k) / 32.0f, 1e-5f) << "n=" << n << " k=" << k;
    }
    EXPECT_EQ(e.pdf(lo - 0.01f), 0.0f);
    EXPECT_EQ(e.pdf(hi + 0.01f), 0.0f);
  }
}

TEST(Chi2Distributions, Distribution2DWithRandomTables) {
  const ivec2 sizes[] = {{1, 1}, {5, 3}, {16, 9}};
  for (ivec2 n : sizes) {
    std::vector<float> table = random_table(size_t(n.x * n.y), 7 + size_t(n.x), n.x > 1 ? 0.25f : 0.0f);
    Distribution2D d(table, n.x, n.y);
    auto r = chi2_test_square(
        [&](vec2 u) {
          float p = 0.0f;
          vec2 x = d.sample_continuous(u, &p);
          if (std::abs(p - d.pdf(x)) > 1e-5f * d.pdf(x)) return std::optional<vec2>();
          return std::optional(x);
        },
        [&](vec2 p) { return d.pdf(p); }, vec2(0.0f), vec2(1.0f), kSamples, 40, kSignificance, 3,
        "Distribution2D " + std::to_string(n.x) + "x" + std::to_string(n.y));
    EXPECT_TRUE(r.passed) << r.report;
  }
}

TEST(Distribution2D, MatchesItsTableAndHandlesZeros) {
  // A row and a column of zeros are never sampled; an all-zero table is uniform.
  std::vector<float> t = {1, 0, 3,  //
                          0, 0, 0,  //
                          2, 0, 4};
  Distribution2D d(t, 3, 3);
  EXPECT_FLOAT_EQ(d.integral(), 10.0f / 9.0f);
  EXPECT_FLOAT_EQ(d.pdf(vec2(0.9f, 0.9f)), 4.0f / d.integral());
  EXPECT_EQ(d.pdf(vec2(0.5f, 0.1f)), 0.0f);
  std::mt19937 rng(3);
  for (int i = 0; i < 10000; ++i) {
    vec2 u(std::generate_canonical<float, 24>(rng), std::generate_canonical<float, 24>(rng));
    ivec2 cell;
    float pdf;
    vec2 p = d.sample_continuous(glm::min(u, vec2(kOneMinusEpsilon)), &pdf, &cell);
    ASSERT_NE(cell.x, 1);
    ASSERT_NE(cell.y, 1);
    ASSERT_GT(pdf, 0.0f);
    ASSERT_TRUE(p.x >= 0.0f && p.x < 1.0f && p.y >= 0.0f && p.y < 1.0f);
  }
  std::vector<float> zeros(6, 0.0f);
  Distribution2D z(zeros, 2, 3);
  float pdf = 0.0f;
  vec2 p = z.sample_continuous(vec2(0.3f, 0.7f), &pdf);
  EXPECT_FLOAT_EQ(pdf, 1.0f);
  EXPECT_FLOAT_EQ(z.pdf(p), 1.0f);
  EXPECT_NEAR(p.x, 0.3f, 1e-6f);
  EXPECT_NEAR(p.y, 0.7f, 1e-6f);
  EXPECT_THROW(Distribution2D(zeros, 4, 4), Error);
}

TEST(Chi2Harness, RejectsAWrongPdf) {
  // Without this, a passing chi-square test proves nothing.
  auto gross = chi2_test_sphere([](vec2 u, float) { return std::optional(sample_cosine_hemisphere(u)); },
                                [](vec3 w) { return w.z >= 0.0f ? uniform_hemisphere_pdf() : 0.0f; }, kSamples,
                                32, 64, kSignificance, 1, "cosine samples, uniform pdf");
  EXPECT_FALSE(gross.passed);
  EXPECT_LT(gross.p_value, 1e-10);
  EXPECT_NE(gross.report.find("observed:"), std::string::npos) << "a failure prints the histograms";
  // A 5% tilt of the density is caught as well.
  auto subtle = chi2_test_sphere([](vec2 u, float) { return std::optional(sample_uniform_hemisphere(u)); },
                                 [](vec3 w) { return w.z >= 0.0f ? (1.0f + 0.1f * w.z) / (2.1f * kPi) : 0.0f; },
                                 kSamples, 32, 64, kSignificance, 1, "uniform samples, tilted pdf");
  EXPECT_FALSE(subtle.passed);
  // Samples where the pdf is zero fail outright.
  auto outside = chi2_test_square([](vec2 u) { return std::optional(u); },
                                  [](vec2 p) { return p.x < 0.5f ? 2.0f : 0.0f; }, vec2(0.0f), vec2(1.0f), 10000,
                                  8, kSignificance, 1, "support too small");
  EXPECT_FALSE(outside.passed);
  // Declined samples must be accounted for by the pdf.
  auto declined = chi2_test_square(
      [](vec2 u) { return u.x < 0.1f ? std::optional<vec2>() : std::optional(u); }, [](vec2) { return 1.0f; },
      vec2(0.0f), vec2(1.0f), kSamples, 16, kSignificance, 1, "declines 10%");
  EXPECT_FALSE(declined.passed);
}

TEST(PowerHeuristic, WeightsOfTwoStrategiesSumToOne) {
  std::mt19937_64 rng(11);
  // Pdfs from 1e-30 to 1e30: squares of either end overflow or underflow a float.
  std::uniform_real_distribution<float> log_pdf(-30.0f, 30.0f);
  std::uniform_int_distribution<int> count(1, 8);
  for (int i = 0; i < 100000; ++i) {
    float nf = float(count(rng)), ng = float(count(rng));
    float f = std::pow(10.0f, log_pdf(rng)), g = std::pow(10.0f, log_pdf(rng));
    float wf = power_heuristic(nf, f, ng, g), wg = power_heuristic(ng, g, nf, f);
    ASSERT_GE(wf, 0.0f);
    ASSERT_GE(wg, 0.0f);
    ASSERT_NEAR(wf + wg, 1.0f, 1e-5f) << nf << " " << f << " " << ng << " " << g;
  }
  // One strategy that cannot produce the sample leaves all weight to the other.
  EXPECT_EQ(power_heuristic(1, 0.5f, 1, 0.0f), 1.0f);
  EXPECT_EQ(power_heuristic(1, 0.0f, 1, 0.5f), 0.0f);
  EXPECT_EQ(power_heuristic(1, kInfinity, 1, 0.5f), 1.0f);
  EXPECT_EQ(power_heuristic(1, 0.5f, 1, kInfinity), 0.0f);
  EXPECT_FLOAT_EQ(power_heuristic(1, 1e-25f, 1, 1e-25f), 0.5f);
  EXPECT_FLOAT_EQ(power_heuristic(1, 3e20f, 1, 1e20f), 0.9f);
  EXPECT_FLOAT_EQ(power_heuristic(2, 0.5f, 1, 3.0f), 0.1f);
}

// The span form the wavefront draws a chunk of hits' diffuse directions
// with is the one-sample warp bit for bit, at every chunk length (the
// vector loop's body and its scalar tail alike), the disk's centre and the
// square's edges included.
TEST(CosineHemisphere, SpanFormIsTheWarpBitForBit) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  std::vector<vec4> u;
  for (float e : {0.0f, 0.5f, kOneMinusEpsilon, 0.25f, 1e-30f})
    for (float f : {0.0f, 0.5f, kOneMinusEpsilon, 0.75f}) u.push_back(vec4(e, f, 0.0f, 0.0f));
  while (u.size() < 4099) u.push_back(vec4(u01(rng), u01(rng), u01(rng), u01(rng)));
  for (size_t n : {size_t(1), size_t(7), size_t(16), size_t(17), u.size()}) {
    std::vector<vec3> out(n);
    sample_cosine_hemisphere(std::span<const vec4>(u).first(n), out);
    for (size_t i = 0; i < n; ++i) {
      const vec3 w = sample_cosine_hemisphere(vec2(u[i]));
      for (int c = 0; c < 3; ++c)
        ASSERT_EQ(std::bit_cast<uint32_t>(out[i][c]), std::bit_cast<uint32_t>(w[c])) << "n " << n << " i " << i << " c " << c;
    }
  }
}
