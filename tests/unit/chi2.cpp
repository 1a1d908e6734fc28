#include "tests/unit/chi2.h"

#include "core/sampling.h"

#include <boost/math/special_functions/gamma.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <vector>

namespace theia {

namespace {

constexpr double kMinExpected = 5.0;

// Adaptive Simpson on [a, b] given f at a, midpoint, b.  The recursion always
// goes at least `min_depth` levels deep so that a narrow feature between the
// first few nodes is not missed; discontinuities are resolved by subdividing
// until the two halves agree with the whole.
template <typename F>
double simpson_rec(const F& f, double a, double b, double fa, double fm, double fb, double whole, double eps,
                   int depth, int min_depth) {
  double m = 0.5 * (a + b);
  double lm = 0.5 * (a + m), rm = 0.5 * (m + b);
  double flm = f(lm), frm = f(rm);
  double h = (b - a) / 12.0;
  double left = h * (fa + 4.0 * flm + fm), right = h * (fm + 4.0 * frm + fb);
  double delta = left + right - whole;
  if (depth <= 0 || (min_depth <= 0 && std::abs(delta) <= 15.0 * eps)) return left + right + delta / 15.0;
  return simpson_rec(f, a, m, fa, flm, fm, left, 0.5 * eps, depth - 1, min_depth - 1) +
         simpson_rec(f, m, b, fm, frm, fb, right, 0.5 * eps, depth - 1, min_depth - 1);
}

// Depth is capped at 10 (1024 intervals): a pdf that jumps along a curve
// through a cell (a microfacet BTDF's back-facing cut-off) otherwise drives
// both nested levels to the cap everywhere along it, ~10^8 evaluations a
// cell at depth 14, while 1024 intervals already resolve the jump far below
// the statistic's noise.
template <typename F>
double integrate_1d(const F& f, double a, double b, double eps) {
  double fa = f(a), fm = f(0.5 * (a + b)), fb = f(b);
  double whole = (b - a) / 6.0 * (fa + 4.0 * fm + fb);
  return simpson_rec(f, a, b, fa, fm, fb, whole, eps, 10, 3);
}

// Integral of pdf over one cell; the tolerance is relative to a coarse
// estimate so that both tiny and large cells get a few significant digits more
// than the chi-square statistic can resolve.
double integrate_cell(const std::function<double(vec2)>& pdf, double x0, double x1, double y0, double y1) {
  auto eval = [&](double x, double y) {
    double v = pdf(vec2(float(x), float(y)));
    return std::isfinite(v) ? v : 0.0;
  };
  double coarse = 0.0;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) coarse += eval(x0 + (i + 0.5) * (x1 - x0) / 4, y0 + (j + 0.5) * (y1 - y0) / 4);
  double area = (x1 - x0) * (y1 - y0);
  coarse *= area / 16.0;
  double eps = 1e-6 * std::max(std::abs(coarse), 1e-6 * area);
  double eps_inner = 0.5 * eps / (x1 - x0);
  auto inner = [&](double x) { return integrate_1d([&](double y) { return eval(x, y); }, y0, y1, eps_inner); };
  return integrate_1d(inner, x0, x1, eps);
}

std::string histogram_text(const std::vector<double>& h, int res_x, int res_y) {
  std::string s;
  for (int y = 0; y < res_y; ++y) {
    for (int x = 0; x < res_x; ++x) s += fmt::format("{:6.0f}", h[size_t(y) * size_t(res_x) + size_t(x)]);
    s += '\n';
  }
  return s;
}

// Cell coordinates ((cos theta + 1) / 2, phi / 2 pi) of a unit direction and
// back: d omega = d cos theta d phi = 4 pi dx dy, so equal cells have equal
// solid angle.
vec2 sphere_to_cell(const vec3& w) {
  float phi = std::atan2(w.y, w.x);
  if (phi < 0.0f) phi += 2.0f * kPi;
  return vec2(0.5f * (std::clamp(w.z, -1.0f, 1.0f) + 1.0f), std::min(phi * kInv2Pi, 1.0f));
}
vec3 cell_to_sphere(vec2 c) {
  float cos_theta = 2.0f * c.x - 1.0f, sin_theta = safe_sqrt(1.0f - cos_theta * cos_theta);
  float phi = 2.0f * kPi * c.y;
  return {sin_theta * std::cos(phi), sin_theta * std::sin(phi), cos_theta};
}

}  // namespace

double chi2_p_value(double statistic, int dof) {
  return (dof >= 1 && std::isfinite(statistic)) ? boost::math::gamma_q(0.5 * dof, 0.5 * statistic) : 0.0;
}

double sidak_level(double significance, int n_tests) {
  return 1.0 - std::pow(1.0 - significance, 1.0 / double(std::max(n_tests, 1)));
}

Chi2Result chi2_counts(const std::vector<double>& observed, const std::vector<double>& expected, double significance,
                       int n_tests, std::string failure) {
  // Pool the cells that expect few samples (the chi-square approximation needs
  // about 5 per cell), smallest first, as Mitsuba does.
  const size_t n_cells = observed.size();
  std::vector<size_t> order(n_cells);
  std::iota(order.begin(), order.end(), size_t(0));
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return expected[a] < expected[b]; });
  double pooled_obs = 0.0, pooled_exp = 0.0, stat = 0.0;
  int pooled_cells = 0, dof = 0, zero_expected_hits = 0;
  for (size_t i : order) {
    if (expected[i] == 0.0 && observed[i] > 0.0) ++zero_expected_hits;
    if (expected[i] < kMinExpected || (pooled_cells > 0 && pooled_exp < kMinExpected)) {
      pooled_obs += observed[i];
      pooled_exp += expected[i];
      ++pooled_cells;
    } else {
      stat += (observed[i] - expected[i]) * (observed[i] - expected[i]) / expected[i];
      ++dof;
    }
  }
  if (pooled_exp > 0.0) {
    stat += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
    ++dof;
  } else if (pooled_obs > 0.0) {
    stat = kInfinity;
  }
  dof -= 1;
  if (zero_expected_hits > 0)
    failure += fmt::format("{} cells received samples where the pdf integrates to zero\n", zero_expected_hits);
  if (dof < 1) failure += "fewer than 2 cells after pooling: the test says nothing\n";

  Chi2Result r;
  r.statistic = stat;
  r.dof = dof;
  r.p_value = chi2_p_value(stat, dof);
  double alpha = sidak_level(significance, n_tests);
  r.passed = failure.empty() && r.p_value >= alpha;
  r.report = fmt::format("statistic {:.2f}, dof {}, p-value {:.4g}, threshold {:.4g} ({} pooled cells): {}\n", stat,
                         dof, r.p_value, alpha, pooled_cells, r.passed ? "passed" : "FAILED");
  if (!r.passed) r.report += failure;
  return r;
}

Chi2Result chi2_test(const std::string& name, const std::function<std::optional<vec2>(vec2 u, float u1)>& sample,
                     const std::function<double(vec2)>& pdf, int n_samples, int res_x, int res_y,
                     double significance, int n_tests) {
  Chi2Result r;
  size_t n_cells = size_t(res_x) * size_t(res_y);
  std::vector<double> observed(n_cells, 0.0), expected(n_cells, 0.0);

  // Independent samples: the statistic assumes a multinomial, which stratified
  // (low-discrepancy) samples are not.
  std::mt19937_64 rng(0x7e57c412u + uint64_t(n_samples));
  auto uniform = [&] { return float(rng() >> 40) * 0x1p-24f; };
  int declined = 0, bad = 0;
  std::string first_bad;
  for (int i = 0; i < n_samples; ++i) {
    vec2 u(uniform(), uniform());
    float u1 = uniform();
    std::optional<vec2> p = sample(u, u1);
    if (!p) {
      ++declined;
      continue;
    }
    if (!(std::isfinite(p->x) && std::isfinite(p->y) && p->x >= 0.0f && p->x <= 1.0f && p->y >= 0.0f &&
          p->y <= 1.0f)) {
      if (bad++ == 0) first_bad = fmt::format("u = ({}, {}), u1 = {} gave ({}, {})", u.x, u.y, u1, p->x, p->y);
      continue;
    }
    int cx = std::min(int(p->x * float(res_x)), res_x - 1), cy = std::min(int(p->y * float(res_y)), res_y - 1);
    observed[size_t(cy) * size_t(res_x) + size_t(cx)] += 1.0;
  }

  double pdf_integral = 0.0;
  for (int y = 0; y < res_y; ++y)
    for (int x = 0; x < res_x; ++x) {
      double v = integrate_cell(pdf, double(x) / res_x, double(x + 1) / res_x, double(y) / res_y,
                                double(y + 1) / res_y);
      pdf_integral += v;
      expected[size_t(y) * size_t(res_x) + size_t(x)] = v * n_samples;
    }

  r.report = fmt::format("chi2 test '{}': {} samples ({} declined), {}x{} cells, pdf integrates to {:.6f}\n", name,
                         n_samples, declined, res_x, res_y, pdf_integral);
  std::string failure;
  if (bad > 0) failure += fmt::format("{} samples outside the domain or not finite, first: {}\n", bad, first_bad);

  const Chi2Result counted = chi2_counts(observed, expected, significance, n_tests, failure);
  r.statistic = counted.statistic;
  r.dof = counted.dof;
  r.p_value = counted.p_value;
  r.passed = counted.passed;
  r.report += counted.report;
  if (!r.passed) {
    // The worst cells first, then the full histograms (x across, y down).
    std::vector<size_t> worst(n_cells);
    std::iota(worst.begin(), worst.end(), size_t(0));
    auto residual = [&](size_t i) {
      return (observed[i] - expected[i]) * (observed[i] - expected[i]) / std::max(expected[i], 1.0);
    };
    std::sort(worst.begin(), worst.end(), [&](size_t a, size_t b) { return residual(a) > residual(b); });
    r.report += "largest deviations (cell x, y: observed / expected):\n";
    for (size_t k = 0; k < std::min<size_t>(8, n_cells); ++k) {
      size_t i = worst[k];
      r.report += fmt::format("  {}, {}: {} / {:.1f}\n", i % size_t(res_x), i / size_t(res_x), observed[i],
                              expected[i]);
    }
    r.report += "observed:\n" + histogram_text(observed, res_x, res_y);
    r.report += "expected:\n" + histogram_text(expected, res_x, res_y);
  }
  return r;
}

Chi2Result chi2_test_sphere(const std::function<std::optional<vec3>(vec2 u, float u1)>& sample,
                            const std::function<float(vec3)>& pdf, int n_samples, int theta_res, int phi_res,
                            double significance, int n_tests, const std::string& name) {
  // The density over the cells is 4 pi pdf (sphere_to_cell).
  auto to_cell = [&](vec2 u, float u1) -> std::optional<vec2> {
    std::optional<vec3> w = sample(u, u1);
    if (!w) return std::nullopt;
    float len = glm::length(*w);
    if (!(std::abs(len - 1.0f) <= 1e-3f)) return vec2(kInfinity);
    return sphere_to_cell(*w);
  };
  auto cell_pdf = [&](vec2 c) { return 4.0 * double(kPi) * double(pdf(cell_to_sphere(c))); };
  return chi2_test(name, to_cell, cell_pdf, n_samples, theta_res, phi_res, significance, n_tests);
}

Chi2Result chi2_test_square(const std::function<std::optional<vec2>(vec2 u)>& sample,
                            const std::function<float(vec2)>& pdf, vec2 lo, vec2 hi, int n_samples, int res,
                            double significance, int n_tests, const std::string& name) {
  vec2 extent = hi - lo;
  auto to_cell = [&](vec2 u, float) -> std::optional<vec2> {
    std::optional<vec2> p = sample(u);
    if (!p) return std::nullopt;
    return (*p - lo) / extent;
  };
  auto cell_pdf = [&](vec2 c) { return double(pdf(lo + c * extent)) * double(extent.x) * double(extent.y); };
  return chi2_test(name, to_cell, cell_pdf, n_samples, res, res, significance, n_tests);
}

namespace {

// One side of the weighted test: per-cell sums of weights and squared weights
// over n independent draws.
struct WeightedHistogram {
  std::vector<double> sum, sum2;
  std::vector<int> count;
  int bad = 0;
  std::string first_bad;
  explicit WeightedHistogram(size_t n_cells) : sum(n_cells, 0.0), sum2(n_cells, 0.0), count(n_cells, 0) {}
  void add(size_t k, double w) {
    sum[k] += w;
    sum2[k] += w * w;
    ++count[k];
  }
};

// The variance of (1/n) sum_i w_i [x_i in the cell] from its sums.
double histogram_variance(double sum, double sum2, double n) {
  return std::max(sum2 / (n * n) - sqr(sum / n) / n, 0.0);
}

}  // namespace

WeightedChi2Result chi2_test_sphere_weighted(
    const std::string& name, const std::function<std::optional<WeightedDirection>(vec2 u, float u1)>& sample,
    const std::function<double(vec3)>& integrand, const std::vector<DirectionLobe>& lobes,
    const WeightedChi2Settings& st) {
  // A cell's weighted sum is close to normal only with a few dozen draws in it.
  constexpr int kMinCount = 32;
  WeightedChi2Result r;
  const size_t n_cells = size_t(st.theta_res) * size_t(st.phi_res);
  const double n_a = double(st.n_samples), n_b = double(st.n_evals);
  std::mt19937_64 rng(0x3e16c7edu ^ st.seed);
  auto uniform = [&] { return float(rng() >> 40) * 0x1p-24f; };
  auto cell_of = [&](const vec3& w) {
    vec2 c = sphere_to_cell(w);
    int cx = std::min(int(c.x * float(st.theta_res)), st.theta_res - 1);
    int cy = std::min(int(c.y * float(st.phi_res)), st.phi_res - 1);
    return size_t(cy) * size_t(st.theta_res) + size_t(cx);
  };
  auto unit = [](const vec3& w) { return std::abs(glm::length(w) - 1.0f) <= 1e-3f; };

  WeightedHistogram a(n_cells), b(n_cells);
  int declined = 0;
  for (int i = 0; i < st.n_samples; ++i) {
    vec2 u(uniform(), uniform());
    float u1 = uniform();
    std::optional<WeightedDirection> s = sample(u, u1);
    if (!s) {
      ++declined;
      continue;
    }
    if (!unit(s->wi) || !std::isfinite(s->weight) || s->weight < 0.0) {
      if (a.bad++ == 0)
        a.first_bad = fmt::format("u = ({}, {}), u1 = {} gave ({}, {}, {}) weight {}", u.x, u.y, u1, s->wi.x,
                                  s->wi.y, s->wi.z, s->weight);
      continue;
    }
    a.add(cell_of(s->wi), s->weight);
  }

  // The mixture density at v, for the integral side's weights.
  const double uniform_share = lobes.empty() ? 1.0 : std::clamp(st.uniform_share, 0.0, 1.0);
  const double lobe_share = lobes.empty() ? 0.0 : (1.0 - uniform_share) / double(lobes.size());
  auto mixture_pdf = [&](const vec3& v) {
    double q = uniform_share * double(kInv4Pi);
    for (const DirectionLobe& l : lobes) q += lobe_share * l.pdf(v);
    return q;
  };
  for (int j = 0; j < st.n_evals; ++j) {
    double pick = double(uniform());
    vec2 u(uniform(), uniform());
    float u1 = uniform();
    std::optional<vec3> v;
    if (pick < uniform_share)
      v = sample_uniform_sphere(u);
    else
      v = lobes[std::min(size_t((pick - uniform_share) / lobe_share), lobes.size() - 1)].sample(u, u1);
    if (!v) continue;
    double g = unit(*v) ? integrand(*v) : std::numeric_limits<double>::quiet_NaN();
    double q = unit(*v) ? mixture_pdf(*v) : 0.0;
    if (!std::isfinite(g) || g < 0.0 || !(q > 0.0)) {
      if (b.bad++ == 0) b.first_bad = fmt::format("({}, {}, {}): integrand {}, mixture pdf {}", v->x, v->y, v->z, g, q);
      continue;
    }
    b.add(cell_of(*v), g / q);
  }

  // Pool the cells with few draws on either side, fewest first; the pooled
  // cell's variances are recomputed from its pooled sums (its indicator is the union's).
  std::vector<size_t> order(n_cells);
  std::iota(order.begin(), order.end(), size_t(0));
  auto fewest = [&](size_t k) { return std::min(a.count[k], b.count[k]); };
  std::sort(order.begin(), order.end(), [&](size_t x, size_t y) { return fewest(x) < fewest(y); });
  struct Term {
    double a = 0.0, b = 0.0, var = 0.0;
    int count_a = 0, count_b = 0;
    size_t cell = 0;  // n_cells for the pooled cell
  };
  std::vector<Term> terms;
  double pooled[4] = {0.0, 0.0, 0.0, 0.0};  // sums and squared sums of both sides
  Term pool{0.0, 0.0, 0.0, 0, 0, n_cells};
  int pooled_cells = 0;
  for (size_t k : order) {
    r.sampled_total += a.sum[k] / n_a;
    r.integrated_total += b.sum[k] / n_b;
    if (fewest(k) < kMinCount || (pooled_cells > 0 && std::min(pool.count_a, pool.count_b) < kMinCount)) {
      pooled[0] += a.sum[k];
      pooled[1] += a.sum2[k];
      pooled[2] += b.sum[k];
      pooled[3] += b.sum2[k];
      pool.count_a += a.count[k];
      pool.count_b += b.count[k];
      ++pooled_cells;
    } else {
      terms.push_back({a.sum[k] / n_a, b.sum[k] / n_b,
                       histogram_variance(a.sum[k], a.sum2[k], n_a) + histogram_variance(b.sum[k], b.sum2[k], n_b),
                       a.count[k], b.count[k], k});
    }
  }
  auto total = [](const std::vector<double>& v) { return std::accumulate(v.begin(), v.end(), 0.0); };
  r.sampled_sd = std::sqrt(histogram_variance(total(a.sum), total(a.sum2), n_a));
  r.integrated_sd = std::sqrt(histogram_variance(total(b.sum), total(b.sum2), n_b));
  if (pooled_cells > 0) {
    pool.a = pooled[0] / n_a;
    pool.b = pooled[2] / n_b;
    pool.var = histogram_variance(pooled[0], pooled[1], n_a) + histogram_variance(pooled[2], pooled[3], n_b);
    terms.push_back(pool);
  }
  double stat = 0.0;
  int dof = 0;
  for (const Term& t : terms) {
    if (t.var > 0.0) {
      stat += sqr(t.a - t.b) / t.var;
      ++dof;
    } else if (t.a != t.b) {
      stat = kInfinity;  // mass where the other side has exactly none
    }
  }

  r.report = fmt::format(
      "weighted chi2 test '{}': {} samples ({} declined), {} evaluations, {}x{} cells; "
      "sampled total {:.5f} +- {:.5f}, integrated total {:.5f} +- {:.5f}\n",
      name, st.n_samples, declined, st.n_evals, st.theta_res, st.phi_res, r.sampled_total, r.sampled_sd,
      r.integrated_total, r.integrated_sd);
  std::string failure;
  if (a.bad > 0) failure += fmt::format("{} samples not unit or with a bad weight, first: {}\n", a.bad, a.first_bad);
  if (b.bad > 0) failure += fmt::format("{} bad evaluations, first: {}\n", b.bad, b.first_bad);
  if (dof < 1) failure += "no cell with a variance: the test says nothing\n";
  r.statistic = stat;
  r.dof = dof;
  r.p_value = chi2_p_value(stat, dof);
  // The totals as a second test: one degree of freedom, so an error spread
  // thinly over all cells (an overall energy error) stands out more there.
  double total_var = sqr(r.sampled_sd) + sqr(r.integrated_sd);
  r.total_p_value = total_var > 0.0 ? chi2_p_value(sqr(r.sampled_total - r.integrated_total) / total_var, 1)
                                    : (r.sampled_total == r.integrated_total ? 1.0 : 0.0);
  double alpha = sidak_level(st.significance, 2 * st.n_tests);
  r.passed = failure.empty() && r.p_value >= alpha && r.total_p_value >= alpha;
  r.report += fmt::format(
      "statistic {:.2f}, dof {}, p-value {:.4g}; totals' p-value {:.4g}; threshold {:.4g} ({} pooled cells): {}\n",
      stat, dof, r.p_value, r.total_p_value, alpha, pooled_cells, r.passed ? "passed" : "FAILED");
  if (!r.passed) {
    r.report += failure;
    auto residual = [](const Term& t) { return sqr(t.a - t.b) / std::max(t.var, 1e-300); };
    std::sort(terms.begin(), terms.end(), [&](const Term& x, const Term& y) { return residual(x) > residual(y); });
    r.report += "largest deviations (cell cos-theta, phi index: sampled / integrated +- sd, draws on each side):\n";
    for (size_t i = 0; i < std::min<size_t>(8, terms.size()); ++i) {
      const Term& t = terms[i];
      std::string cell = t.cell == n_cells ? std::string("pooled")
                                           : fmt::format("{}, {}", t.cell % size_t(st.theta_res),
                                                         t.cell / size_t(st.theta_res));
      r.report += fmt::format("  {}: {:.5g} / {:.5g} +- {:.2g}, {} / {}\n", cell, t.a, t.b, std::sqrt(t.var),
                              t.count_a, t.count_b);
    }
  }
  return r;
}

}  // namespace theia
