#include "core/log.h"
#include "core/sampler.h"
#include "core/color.h"
#include "scene/filter.h"
#include "wavefront/film.h"
#include "tests/unit/chi2.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <functional>
#include <numeric>
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

Filter mitchell(vec2 radius, float b = 1.0f / 3.0f, float c = 1.0f / 3.0f) {
  FilterParams p;
  p.kind = FilterKind::Mitchell;
  p.radius = radius;
  p.b = b, p.c = c;
  return make_filter(p);
}

Filter lanczos(vec2 radius, float tau = 3.0f) {
  FilterParams p;
  p.kind = FilterKind::Lanczos;
  p.radius = radius;
  p.tau = tau;
  return make_filter(p);
}

std::string name_of(const Filter& f) {
  const char* kinds[] = {"box", "triangle", "gaussian", "mitchell", "lanczos"};
  return std::string(kinds[int(f.kind)]) + " r=(" + std::to_string(f.radius.x) + ", " + std::to_string(f.radius.y) +
         ")";
}

// pbrt-v4's defaults, then Catmull-Rom (B = 0, C = 1/2: deeper negative lobes)
// and a short Lanczos window on unequal radii.
std::vector<Filter> signed_filters() {
  return {mitchell(vec2(2.0f)), mitchell(vec2(1.5f, 1.0f), 0.0f, 0.5f), lanczos(vec2(4.0f)),
          lanczos(vec2(2.0f, 1.5f), 2.0f)};
}

std::vector<Filter> test_filters() {
  std::vector<Filter> v = {filter_of(FilterKind::Box, vec2(0.5f)),       filter_of(FilterKind::Box, vec2(1.0f, 2.0f)),
                           filter_of(FilterKind::Triangle, vec2(2.0f)),  filter_of(FilterKind::Triangle, vec2(1.5f, 0.75f)),
                           filter_of(FilterKind::Gaussian, vec2(1.5f)),  filter_of(FilterKind::Gaussian, vec2(2.0f, 1.0f), 0.8f)};
  for (Filter& f : signed_filters()) v.push_back(std::move(f));
  return v;
}

// The centre of the table cell holding offset p (32 cells per unit radius).
vec2 cell_centre(const Filter& f, vec2 p) {
  vec2 n = vec2(f.table_size);
  vec2 cell = glm::min(glm::floor((p / f.radius + 1.0f) * 0.5f * n), n - 1.0f);
  return ((cell + 0.5f) / n * 2.0f - 1.0f) * f.radius;
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
    int negative = 0;
    for (uint32_t i = 0; i < 20000; ++i) {
      FilterSample s = sample_filter(f, sample_2d({1, 0, i}, 0));
      ASSERT_LE(std::abs(s.p.x), f.radius.x) << name_of(f);
      ASSERT_LE(std::abs(s.p.y), f.radius.y) << name_of(f);
      ASSERT_TRUE(std::isfinite(s.weight)) << name_of(f);
      if (!filter_is_tabulated(f)) {
        ASSERT_EQ(s.weight, 1.0f);
      } else {
        // The weight carries f's sign (Mitchell, Lanczos: at the table
        // cell's centre, as pbrt-v4): negative lobes count negatively.
        float fp = filter_eval(f, f.kind == FilterKind::Gaussian ? s.p : cell_centre(f, s.p));
        ASSERT_TRUE(fp > 0.0f ? s.weight > 0.0f : fp < 0.0f ? s.weight < 0.0f : s.weight == 0.0f)
            << name_of(f) << " f = " << fp << " weight = " << s.weight;
      }
      negative += s.weight < 0.0f;
    }
    // The signed filters reach their negative lobes (about 1 sample in 10 or more).
    if (f.kind == FilterKind::Mitchell || f.kind == FilterKind::Lanczos) {
      EXPECT_GT(negative, 1000) << name_of(f);
    } else {
      EXPECT_EQ(negative, 0) << name_of(f);
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
  // pbrt-v4's Mitchell1D at 0 is (6 - 2B) / 6 and dips below zero in its outer
  // half; the windowed sinc is 1 at 0, 0 at the integers, sinc(x) sinc(x / tau) between.
  Filter m = mitchell(vec2(2.0f));
  EXPECT_FLOAT_EQ(filter_eval(m, vec2(0.0f)), sqr(8.0f / 9.0f));
  EXPECT_LT(filter_eval(m, vec2(1.5f, 0.0f)), 0.0f);
  EXPECT_EQ(filter_eval(m, vec2(2.01f, 0.0f)), 0.0f);
  Filter cr = mitchell(vec2(4.0f), 0.0f, 0.5f);  // Catmull-Rom interpolates: 1 at 0, 0 at +-1 (radius / 2)
  EXPECT_FLOAT_EQ(filter_eval(cr, vec2(0.0f)), 1.0f);
  EXPECT_NEAR(filter_eval(cr, vec2(2.0f, 0.0f)), 0.0f, 1e-6f);
  Filter l = lanczos(vec2(4.0f));
  EXPECT_FLOAT_EQ(filter_eval(l, vec2(0.0f)), 1.0f);
  EXPECT_NEAR(filter_eval(l, vec2(1.0f, 0.0f)), 0.0f, 1e-6f);
  double x = 0.5, tau = 3.0;
  double expect = std::sin(kPi * x) / (kPi * x) * std::sin(kPi * x / tau) / (kPi * x / tau);
  EXPECT_NEAR(filter_eval(l, vec2(0.5f, 0.0f)), expect, 1e-6);
  EXPECT_LT(filter_eval(l, vec2(1.5f, 0.0f)), 0.0f);
  EXPECT_EQ(filter_eval(l, vec2(0.0f, 4.01f)), 0.0f);
  // Mitchell integrates to radius.x * radius.y / 4 for any B and C.
  EXPECT_FLOAT_EQ(filter_integral(mitchell(vec2(1.5f, 1.0f), 0.0f, 0.5f)), 1.5f / 4.0f);
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
  // f * h / integral(f); the tabulated filters' weights are f / pdf, negative
  // in Mitchell's and Lanczos' negative lobes (pbrt-v4's cell-centre f for
  // those two: the table's midpoint bias, ~1e-3 here, stays within the bound).
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
    double scale = filter_is_tabulated(f) ? 1.0 : 1.0 / double(filter_integral(f));
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

// The camera stage draws its film offsets a block at a time, and the caustic
// pass re-draws one sample's weight alone: the two must agree bit for bit.
// The inputs cover every Gaussian segment's ends and interior, 0, the top of
// [0, 1), and blocks of every length around the vector width.
TEST(Filter, ABlockOfSamplesIsEachSampleBitForBit) {
  std::vector<vec2> u;
  for (int k = 0; k <= kGaussianSegments; ++k)
    for (float d : {-1e-6f, 0.0f, 1e-6f, 0.5f / float(kGaussianSegments)})
      u.push_back(vec2(std::clamp(float(k) / float(kGaussianSegments) + d, 0.0f, kOneMinusEpsilon),
                       std::clamp(1.0f - float(k) / float(kGaussianSegments) - d, 0.0f, kOneMinusEpsilon)));
  for (uint32_t i = 0; i < 200000; ++i) u.push_back(sample_2d({5, i / 64, i % 64}, 0));
  const Filter filters[] = {filter_of(FilterKind::Gaussian, vec2(1.5f)),
                            filter_of(FilterKind::Gaussian, vec2(0.5f, 3.0f), 0.8f),
                            filter_of(FilterKind::Gaussian, vec2(2.0f), 4.0f),
                            filter_of(FilterKind::Box, vec2(0.5f)),
                            mitchell(vec2(2.0f)),
                            lanczos(vec2(3.0f))};
  for (const Filter& f : filters) {
    std::vector<FilterSample> block(u.size());
    for (size_t first = 0, len = 1; first < u.size(); first += len, len = len % 67 + 1)
      sample_filter(f, std::span<const vec2>(u).subspan(first, std::min(len, u.size() - first)),
                    std::span<FilterSample>(block).subspan(first, std::min(len, u.size() - first)));
    size_t differ = 0;
    for (size_t i = 0; i < u.size(); ++i) {
      const FilterSample one = sample_filter(f, u[i]);
      differ += std::memcmp(&one.p, &block[i].p, sizeof one.p) != 0 ||
                std::memcmp(&one.weight, &block[i].weight, sizeof one.weight) != 0;
    }
    EXPECT_EQ(differ, 0u) << "filter kind " << int(f.kind) << ", " << u.size() << " samples";
  }
}

// Mitchell and Lanczos weigh as pbrt-v4: the cell's tabulated f over the pdf,
// +-integral(|table|) everywhere, so weights that cancel sum to exactly 0.
TEST(Filter, SignedFilterWeightsArePlusMinusTheTableIntegral) {
  for (const Filter& f : signed_filters()) {
    const float c = f.distribution.integral() * 4.0f * f.radius.x * f.radius.y;
    float positive = 0.0f, negative = 0.0f;
    for (uint32_t i = 0; i < 1000; ++i) {
      FilterSample s = sample_filter(f, sample_2d({3, 1, i}, 0));
      EXPECT_NEAR(std::abs(s.weight), c, 1e-4f * c) << name_of(f);
      EXPECT_NEAR(s.weight, filter_eval(f, cell_centre(f, s.p)) / filter_pdf(f, s.p), 1e-4f * c) << name_of(f);
      (s.weight > 0.0f ? positive : negative) = s.weight;
    }
    ASSERT_TRUE(positive > 0.0f && negative < 0.0f) << name_of(f);
    EXPECT_EQ(positive + negative, 0.0f) << name_of(f);
  }
}

// pbrt-v4's FilterSampler draws from |f|: against |f| / integral(|f|) itself
// rather than the table's pdf, the sampling of the signed filters (and the
// Gaussian) passes chi-square too, so the table follows the filter.  Each
// histogram bin is a union of whole table cells (32 per unit radius), where
// the table's cell-centre values integrate |f| to second order; a bin that
// cut cells would see the table's first-order steps (its L1 distance from
// |f| / integral(|f|) is a few percent), which 500k samples resolve.
TEST(Filter, TabulatedSamplingFollowsAbsF) {
  std::vector<Filter> filters = signed_filters();
  filters.push_back(filter_of(FilterKind::Gaussian, vec2(2.0f, 1.0f), 0.8f));
  for (const Filter& f : filters) {
    int res = std::gcd(int(32.0f * f.radius.x), int(32.0f * f.radius.y));
    while (res > 32 && res % 2 == 0) res /= 2;
    double abs_integral = integrate_over_filter(f, [&](vec2 p) { return std::abs(double(filter_eval(f, p))); }, 2048);
    auto r = chi2_test_square([&](vec2 u) { return std::optional(sample_filter(f, u).p); },
                              [&](vec2 p) { return float(std::abs(filter_eval(f, p)) / abs_integral); }, -f.radius,
                              f.radius, 500'000, res, 0.01, int(filters.size()), name_of(f) + " vs |f|");
    EXPECT_TRUE(r.passed) << r.report;
  }
}

TEST(Filter, RejectsBadParameters) {
  EXPECT_THROW(filter_of(FilterKind::Box, vec2(0.0f, 1.0f)), Error);
  EXPECT_THROW(filter_of(FilterKind::Triangle, vec2(1.0f, -1.0f)), Error);
  EXPECT_THROW(filter_of(FilterKind::Gaussian, vec2(1.0f), 0.0f), Error);
  EXPECT_THROW(filter_of(FilterKind::Gaussian, vec2(kInfinity), 0.5f), Error);
  EXPECT_THROW(lanczos(vec2(4.0f), 0.0f), Error);
  EXPECT_THROW(mitchell(vec2(2.0f), kInfinity), Error);
  EXPECT_THROW(mitchell(vec2(-2.0f)), Error);
}

// Negative weights reach the film unclamped, as pbrt-v4's RGBFilm adds
// weight * L and weight: a pixel is sum(w L) / sum(w) with signed terms.  A
// pixel whose weights cancel exactly stays 0, as in pbrt-v4 (no NaN), and so
// does one whose quotient overflows.
TEST(Filter, FilmSumsSignedWeightsAndLeavesCancelledPixelsBlack) {
  Film film(3, 1);
  auto add = [&](uint32_t pixel, uint32_t sample, float w, RGB L) {
    film.add_weight(pixel, sample, w);
    film.add_alpha_weight(pixel, w);
    film.splat(pixel, sample, w * L, kEventEmission);
    film.splat_first_hit(pixel, w, true, RGB(0.5f), vec3(0, 0, 1), 2.0f);
  };
  add(0, 0, 2.0f, RGB(1.0f, 2.0f, 3.0f));
  add(0, 1, -0.5f, RGB(4.0f));
  add(1, 0, 1.5f, RGB(1.0f));
  add(1, 1, -1.5f, RGB(3.0f));
  film.add_weight(2, 0, 1e-39f);  // denormal: 1 / it overflows
  film.splat(2, 0, RGB(1.0f), kEventEmission);
  ImageBuffer img = resolve_film(film);
  const size_t nc = img.channels.size();
  RGB want = working_to_srgb((2.0f * RGB(1.0f, 2.0f, 3.0f) - 0.5f * RGB(4.0f)) / 1.5f);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(img.data[size_t(c)], want[c], 1e-5f);
  EXPECT_LT(img.data[0], 1.0f / 1.5f);  // the negative sample pulled it down: nothing clamped it at zero
  EXPECT_FLOAT_EQ(img.data[3], 1.0f);   // alpha: sum of hit weights over the alpha weights
  EXPECT_FLOAT_EQ(img.data[10], 2.0f);  // depth, averaged over the signed hit weights
  for (size_t pixel : {size_t(1), size_t(2)})
    for (size_t c = 0; c < nc; ++c) {
      float v = img.data[pixel * nc + c];
      EXPECT_TRUE(std::isfinite(v)) << pixel << " " << img.channels[c];
      EXPECT_EQ(v, 0.0f) << pixel << " " << img.channels[c];
    }
}

// The Gaussian samples each axis from the equal-probability segments of its
// factor, linear within each: its density is its own (SamplingMatchesItsPdf)
// and close to f but not f: in the outermost segment, wide because the tail
// holds little mass, the line to f(radius) = 0 lies above the convex tail
// (about 2x f in the last 1/40 of pbrt-v4's default radius; chi-square
// against f at 1M samples sees it).  The weights f / pdf are exact, so what
// the approximation can cost is variance: their mean is the integral and
// their second moment within 1% of its square (1 for sampling exactly by f),
// for pbrt-v4's default filter and a wide, unequal one.
TEST(Filter, GaussianWeightsStayNearTheirMean) {
  const Filter filters[] = {filter_of(FilterKind::Gaussian, vec2(1.5f)),
                            filter_of(FilterKind::Gaussian, vec2(3.0f, 1.0f), 1.2f)};
  for (const Filter& f : filters) {
    double sum = 0.0, sum_sq = 0.0;
    const uint32_t n = 1 << 16;
    for (uint32_t i = 0; i < n; ++i) {
      const float w = sample_filter(f, sample_2d({5, 2, i}, 0)).weight;
      sum += w, sum_sq += double(w) * w;
    }
    EXPECT_NEAR(sum / n, filter_integral(f), 1e-3 * filter_integral(f)) << name_of(f);
    EXPECT_LT(sum_sq / n / sqr(sum / n), 1.01) << name_of(f);
  }
}
