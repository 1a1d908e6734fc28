// A tabulated 1D distribution sampled in constant time (the Gaussian pixel
// filter's, scene/filter.h).
#pragma once

#include "core/sampling.h"

#include <algorithm>
#include <span>
#include <vector>

namespace theia {

// The sample of EqualMass1D below, over its n segments' bounds and values.
// Both cases are computed and one is chosen, with no branch: so written, a
// loop of calls vectorizes, and the values are the same as with branches.
inline float equal_mass_sample(const float* bounds, const float* value, int n, float u, float& inv_pdf) {
  const float t = u * float(n);
  const int k = std::min(int(t), n - 1);
  const float a = bounds[size_t(k)], b = bounds[size_t(k) + 1];
  const float fa = value[size_t(k)], fb = value[size_t(k) + 1];
  const float v = std::min(t - float(k), kOneMinusEpsilon);
  // A segment where the function is 0 at both ends: uniform.
  const bool flat = !(fa + fb > 0.0f);
  // Otherwise the inverse of the linear density's cdf, in the form that stays finite as fa -> 0.
  const float s =
      v > 0.0f ? std::min(v * (fa + fb) / (fa + std::sqrt(fa * fa + v * (fb * fb - fa * fa))), 1.0f) : 0.0f;
  const float density = fa + s * (fb - fa);
  const float linear_inv_pdf = density > 0.0f ? float(n) * (b - a) * 0.5f * (fa + fb) / density : 0.0f;
  inv_pdf = flat ? float(n) * (b - a) : linear_inv_pdf;
  return flat ? std::min(a + v * (b - a), b) : std::min(a + s * (b - a), b);
}

// n segments of probability 1/n each (the quantiles of a tabulated
// distribution), and within each a density linear between the function's
// values at the segment's ends: a sample is one lerp and one square root,
// with no search.  The density is exact (a weight f / pdf taken with it is
// exact for any f), and it follows f closely, the tails included, where f
// falls linearly to 0 (a density flat within each segment put up to 7 times
// too many samples in the last 1/40 of the Gaussian filter's radius).
struct EqualMass1D {
  std::vector<float> bounds;  // n + 1, non-decreasing: the segments' ends
  std::vector<float> value;   // n + 1, >= 0: the function at the bounds

  EqualMass1D() = default;
  // The quantiles k / n of d, mapped from [0, 1) onto [lo, hi]; f gives the values.
  template <typename F>
  EqualMass1D(const Distribution1D& d, int n, float lo, float hi, F&& f);

  int size() const { return int(bounds.size()) - 1; }
  // Returns x in [bounds[0], bounds[n]]; writes 1 / pdf(x) (0 where the density is 0).
  float sample(float u, float* inv_pdf) const {
    return equal_mass_sample(bounds.data(), value.data(), size(), u, *inv_pdf);
  }
  // x[i] = sample(u[i], &inv_pdf[i]) for every i, bit for bit, several
  // lanes at a time: the loop over the inline sample vectorizes.
  void sample(std::span<const float> u, std::span<float> x, std::span<float> inv_pdf) const {
    const float* __restrict b = bounds.data();
    const float* __restrict f = value.data();
    const int n = size();
    for (size_t i = 0; i < u.size(); ++i) x[i] = equal_mass_sample(b, f, n, u[i], inv_pdf[i]);
  }
  // Density of sample() at x; 0 outside [bounds[0], bounds[n]].
  float pdf(float x) const;
};

template <typename F>
EqualMass1D::EqualMass1D(const Distribution1D& d, int n, float lo, float hi, F&& f)
    : bounds(size_t(n) + 1), value(size_t(n) + 1) {
  bounds[0] = lo;
  for (int k = 1; k < n; ++k) {
    float p = 0.0f;
    bounds[size_t(k)] = std::max(bounds[size_t(k) - 1], lo + (hi - lo) * d.sample_continuous(float(k) / float(n), &p));
  }
  bounds[size_t(n)] = hi;
  for (size_t k = 0; k <= size_t(n); ++k) value[k] = std::max(0.0f, f(bounds[k]));
}

inline float EqualMass1D::pdf(float x) const {
  const int n = size();
  if (n <= 0 || !(x >= bounds.front() && x <= bounds.back())) return 0.0f;
  const int k = std::clamp(int(std::upper_bound(bounds.begin(), bounds.end(), x) - bounds.begin()) - 1, 0, n - 1);
  const float a = bounds[size_t(k)], w = bounds[size_t(k) + 1] - a;
  if (!(w > 0.0f)) return 0.0f;
  const float fa = value[size_t(k)], fb = value[size_t(k) + 1];
  if (!(fa + fb > 0.0f)) return 1.0f / (float(n) * w);
  const float s = std::clamp((x - a) / w, 0.0f, 1.0f);
  return (fa + s * (fb - fa)) / (float(n) * w * 0.5f * (fa + fb));
}

}  // namespace theia
