#include "core/log.h"
#include "core/sampler.h"
#include "scene/filter.h"
#include "tests/unit/chi2.h"

#include <gtest/gtest.h>

#include <functional>
#include <string>

using namespace theia;

namespace {

Filter filter_of(FilterKind kind, vec2 radius, float sigma = 0.5f) {
  FilterParams p;
  p.kind = kind;
  p.radius = radius;
  p.sigma = sigma;
  return make_filter(p);
}

std::string name_of(const Filter& f) {
  const char* kinds[] = {"box", "triangle", "gaussian"};
  return std::string(kinds[int(f.kind)]) + " r=(" + std::to_string(f.radius.x) + ", " + std::to_string(f.radius.y) +
         ")";
}

std::vector<Filter> test_filters() {
  return {filter_of(FilterKind::Box, vec2(0.5f)),       filter_of(FilterKind::Box, vec2(1.0f, 2.0f)),
          filter_of(FilterKind::Triangle, vec2(2.0f)),  filter_of(FilterKind::Triangle, vec2(1.5f, 0.75f)),
          filter_of(FilterKind::Gaussian, vec2(1.5f)),  filter_of(FilterKind::Gaussian, vec2(2.0f, 1.0f), 0.8f)};
}

// Composite Simpson over [-r, r]^2 with the kinks of every filter (0 and the
// radius) on grid lines.
double integrate_over_filter(const Filter& f, const std::function<double(vec2)>& h, int n = 512) {
  vec2 r = f.radius;
  double hx = 2.0 * r.x / n, hy = 2.0 * r.y / n, sum = 0.0;
  auto w = [&](int i) { return (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0); };
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      vec2 p(float(-r.x + i * hx), float(-r.y + j * hy));
      sum += w(i) * w(j) * h(p);
    }
  return sum * hx * hy / 9.0;
}

}  // namespace

TEST(Filter, OffsetsStayWithinTheRadius) {
  for (const Filter& f : test_filters()) {
    EXPECT_EQ(filter_radius(f), f.radius);
    for (uint32_t i = 0; i < 20000; ++i) {
      FilterSample s = sample_filter(f, sample_2d({1, 0, i}, 0));
      ASSERT_LE(std::abs(s.p.x), f.radius.x) << name_of(f);
      ASSERT_LE(std::abs(s.p.y), f.radius.y) << name_of(f);
      ASSERT_TRUE(std::isfinite(s.weight) && s.weight > 0.0f) << name_of(f);
      if (f.kind != FilterKind::Gaussian) {
        ASSERT_EQ(s.weight, 1.0f);
      }
    }
    // Extreme u still lands inside.
    for (vec2 u : {vec2(0.0f), vec2(kOneMinusEpsilon), vec2(0.0f, kOneMinusEpsilon)}) {
      FilterSample s = sample_filter(f, u);
      EXPECT_LE(std::abs(s.p.x), f.radius.x);
      EXPECT_LE(std::abs(s.p.y), f.radius.y);
    }
  }
}

TEST(Filter, EvaluationAndIntegral) {
  Filter box = filter_of(FilterKind::Box, vec2(1.0f, 2.0f));
  EXPECT_EQ(filter_eval(box, vec2(0.9f, -1.9f)), 1.0f);
  EXPECT_EQ(filter_eval(box, vec2(1.1f, 0.0f)), 0.0f);
  Filter tri = filter_of(FilterKind::Triangle, vec2(2.0f, 1.0f));
  EXPECT_FLOAT_EQ(filter_eval(tri, vec2(0.0f)), 2.0f);
  EXPECT_FLOAT_EQ(filter_eval(tri, vec2(1.0f, 0.5f)), 0.5f);
  Filter g = filter_of(FilterKind::Gaussian, vec2(1.5f));
  EXPECT_NEAR(filter_eval(g, vec2(1.5f, 0.0f)), 0.0f, 1e-7f);  // falls to zero at the radius
  EXPECT_EQ(filter_eval(g, vec2(1.6f, 0.0f)), 0.0f);
  EXPECT_GT(filter_eval(g, vec2(0.0f)), filter_eval(g, vec2(0.3f, 0.0f)));
  // The closed-form integrals agree with quadrature.
  for (const Filter& f : test_filters()) {
    double q = integrate_over_filter(f, [&](vec2 p) { return filter_eval(f, p); });
    EXPECT_NEAR(filter_integral(f), q, 2e-4 * q) << name_of(f);
  }
}

TEST(Filter, WeightedSamplesEstimateTheFilteredIntegral) {
  // E[weight * h(p)] must equal the integral of f * h, up to the constant
  // pbrt-v4 leaves out (the film divides by the sum of weights): box and
  // triangle weigh every sample 1, i.e. they estimate the integral of
  // f * h / integral(f); the Gaussian's weights are f / pdf.
  const std::function<double(vec2)> tests[] = {
      [](vec2) { return 1.0; },
      [](vec2 p) { return double(p.x * p.x); },
      [](vec2 p) { return std::exp(double(p.x) - 0.5 * p.y); },
      [](vec2 p) { return std::cos(2.0 * p.x) * p.y + 0.3 * p.y * p.y * p.x; },
  };
  // Randomised QMC: independent scrambles (pixels) of a 2^13-point net give
  // independent unbiased estimates, whose spread bounds the error honestly.
  const int replicates = 32, n = 1 << 13;
  for (const Filter& f : test_filters()) {
    double scale = f.kind == FilterKind::Gaussian ? 1.0 : 1.0 / double(filter_integral(f));
    for (size_t k = 0; k < std::size(tests); ++k) {
      const auto& h = tests[k];
      double truth = scale * integrate_over_filter(f, [&](vec2 p) { return filter_eval(f, p) * h(p); });
      double sum = 0.0, sum_sq = 0.0;
      for (uint32_t rep = 0; rep < replicates; ++rep) {
        double est = 0.0;
        for (uint32_t i = 0; i < n; ++i) {
          FilterSample s = sample_filter(f, sample_2d({77, rep, i}, 0));
          est += s.weight * h(s.p);
        }
        est /= n;
        sum += est;
        sum_sq += est * est;
      }
      double mean = sum / replicates;
      double stderr_ = std::sqrt(std::max(0.0, sum_sq / replicates - mean * mean) / (replicates - 1));
      // 5 standard errors, and a floor for float rounding of p and the weight.
      EXPECT_NEAR(mean, truth, 5.0 * stderr_ + 1e-5 * std::abs(truth) + 1e-7)
          << name_of(f) << ", test function " << k;
    }
  }
}

TEST(Filter, SamplingMatchesItsPdf) {
  auto filters = test_filters();
  for (const Filter& f : filters) {
    auto r = chi2_test_square([&](vec2 u) { return std::optional(sample_filter(f, u).p); },
                              [&](vec2 p) { return filter_pdf(f, p); }, -f.radius, f.radius, 500'000, 32, 0.01,
                              int(filters.size()), name_of(f));
    EXPECT_TRUE(r.passed) << r.report;
  }
}

TEST(Filter, GaussianWeightIsFOverPdf) {
  Filter f = filter_of(FilterKind::Gaussian, vec2(1.5f));
  for (uint32_t i = 0; i < 1000; ++i) {
    FilterSample s = sample_filter(f, sample_2d({3, 1, i}, 0));
    EXPECT_NEAR(s.weight, filter_eval(f, s.p) / filter_pdf(f, s.p), 1e-4f * s.weight);
  }
}

TEST(Filter, RejectsBadParameters) {
  EXPECT_THROW(filter_of(FilterKind::Box, vec2(0.0f, 1.0f)), Error);
  EXPECT_THROW(filter_of(FilterKind::Triangle, vec2(1.0f, -1.0f)), Error);
  EXPECT_THROW(filter_of(FilterKind::Gaussian, vec2(1.0f), 0.0f), Error);
  EXPECT_THROW(filter_of(FilterKind::Gaussian, vec2(kInfinity), 0.5f), Error);
}
