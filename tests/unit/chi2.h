// Chi-square goodness-of-fit harness for sampling routines (after Mitsuba's
// chi2 tests): histogram N independent samples over a 2D domain, integrate
// the claimed pdf over each cell for the expected counts, pool cells expecting
// fewer than 5, and test at a significance level with Sidak correction for
// the number of tests in a sweep.  A routine passes only if its samples are
// distributed as its pdf says, so the pdf and the sampler are checked together.
#pragma once

#include "core/math.h"

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace theia {

struct Chi2Result {
  double statistic = 0.0;
  int dof = 0;
  double p_value = 0.0;
  bool passed = false;
  std::string report;  // summary; on failure also the observed and expected histograms
};

// Upper-tail probability of chi-square(dof) at `statistic`, and the per-test
// level that keeps the family-wise level at `significance` over `n_tests`
// tests (Sidak); shared by the plain and the weighted harness.
double chi2_p_value(double statistic, int dof);
double sidak_level(double significance, int n_tests);

// Observed against expected counts per cell (for a discrete distribution:
// its pmf times the number of samples): cells expecting fewer than 5 pooled,
// the statistic against chi-square, Sidak's level.  `failure` holds problems
// the caller found already (they fail the test).
Chi2Result chi2_counts(const std::vector<double>& observed, const std::vector<double>& expected, double significance,
                       int n_tests = 1, std::string failure = {});

// The generic test over [0, 1]^2.  `sample` maps uniform (u, u1) to a point in
// [0, 1]^2 or nullopt (the routine declined: the sample is dropped, and the
// pdf should integrate to less than 1 accordingly).  `pdf` is the density with
// respect to area in [0, 1]^2.  A point outside [0, 1]^2 or non-finite fails.
Chi2Result chi2_test(const std::string& name, const std::function<std::optional<vec2>(vec2 u, float u1)>& sample,
                     const std::function<double(vec2)>& pdf, int n_samples, int res_x, int res_y,
                     double significance, int n_tests = 1);

// Directions on the unit sphere, binned in (cos theta, phi) so that cells have
// equal solid angle; pdf is per unit solid angle.  A non-unit direction fails.
Chi2Result chi2_test_sphere(const std::function<std::optional<vec3>(vec2 u, float u1)>& sample,
                            const std::function<float(vec3)>& pdf, int n_samples, int theta_res, int phi_res,
                            double significance, int n_tests = 1, const std::string& name = "sphere");

// Points in the rectangle [lo, hi]; pdf is per unit area.
Chi2Result chi2_test_square(const std::function<std::optional<vec2>(vec2 u)>& sample,
                            const std::function<float(vec2)>& pdf, vec2 lo, vec2 hi, int n_samples, int res,
                            double significance, int n_tests = 1, const std::string& name = "square");

// The weighted variant, for samplers whose pdf is only proportional to their
// density or is itself a random estimate (pbrt-v4's layered BxDFs), so that
// expected counts cannot be formed.  `sample` returns a direction and its
// weight f |cos| / pdf; `integrand` is f |cos| at a direction (it may be a
// random but unbiased estimate).  In each equal-solid-angle (cos theta, phi)
// cell of the sphere, the sampler's weighted histogram
//   A_k = (1/N) sum_i w_i [wi_i in cell k]
// and the integral of the integrand over the cell
//   B_k = (1/M) sum_j [v_j in cell k] integrand(v_j) / q(v_j)
// estimate the same number when sampling agrees with evaluation.  The v_j are
// drawn independently of the sampler from a defensive mixture q: uniform over
// the sphere (`uniform_share`), the rest split evenly between `lobes`,
// densities whose exact pdf is known (a cosine hemisphere, a microfacet
// reflection lobe), which the caller supplies where the integrand has its
// mass or a peak too narrow for uniform directions to find
// (cell-by-cell stratified quadrature was tried: a few dozen evaluations a
// cell miss a roughness-0.05 lobe, and so does the variance estimated from
// them, which then passes sizeable errors).  Both variances come from the
// weights' per-cell second moments; cells holding fewer than 32 samples (of
// either kind) are pooled, and sum_k (A_k - B_k)^2 / (var A_k + var B_k) over
// the K cells left is tested against chi-square(K) (no constraint ties the A_k
// to the B_k, so no degree of freedom is lost); the totals sum_k A_k and
// sum_k B_k are compared too, and both tests count in the Sidak correction.
struct WeightedDirection {
  vec3 wi;
  double weight = 0.0;
};
struct DirectionLobe {
  // A direction (nullopt: declined) and the density of the directions it
  // returns, per unit solid angle (declines make it integrate to less than 1).
  std::function<std::optional<vec3>(vec2 u, float u1)> sample;
  std::function<double(vec3)> pdf;
};
struct WeightedChi2Settings {
  int n_samples = 100'000;  // N, from the sampler under test
  int n_evals = 100'000;    // M, of the integrand
  int theta_res = 8, phi_res = 16;
  double uniform_share = 0.5;  // of the integral side's mixture (all of it without lobes)
  double significance = 0.01;
  int n_tests = 1;
  uint64_t seed = 0;
};
struct WeightedChi2Result : Chi2Result {
  double sampled_total = 0.0, integrated_total = 0.0;  // sum_k A_k and sum_k B_k
  double sampled_sd = 0.0, integrated_sd = 0.0;        // their standard errors
  double total_p_value = 0.0;                           // of the totals' difference
};
WeightedChi2Result chi2_test_sphere_weighted(
    const std::string& name, const std::function<std::optional<WeightedDirection>(vec2 u, float u1)>& sample,
    const std::function<double(vec3)>& integrand, const std::vector<DirectionLobe>& lobes,
    const WeightedChi2Settings& settings);

}  // namespace theia
