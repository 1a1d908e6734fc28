// Chi-square goodness-of-fit harness for sampling routines (after Mitsuba's
// chi2 tests): histogram N independent samples over a 2D domain, integrate
// the claimed pdf over each cell for the expected counts, pool cells expecting
// fewer than 5, and test at a significance level with Sidak correction for
// the number of tests in a sweep.  A routine passes only if its samples are
// distributed as its pdf says, so the pdf and the sampler are checked together.
#pragma once

#include "core/math.h"

#include <functional>
#include <optional>
#include <string>

namespace theia {

struct Chi2Result {
  double statistic = 0.0;
  int dof = 0;
  double p_value = 0.0;
  bool passed = false;
  std::string report;  // summary; on failure also the observed and expected histograms
};

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

}  // namespace theia
