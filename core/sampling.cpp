#include "core/sampling.h"

#include <algorithm>
#include <numeric>

namespace theia {

namespace {

// Largest i in [first, last] with !(u < cdf[i]), clamped to a valid cell:
// std::upper_bound's answer (NaN included) when it lies in that range.
// Without a branch on the comparison (a conditional move): u is random, and
// a branch on it was mispredicted every other step.
int upper_cell(const std::vector<float>& cdf, size_t first, size_t last, float u) {
  for (size_t len = last - first + 1; len > 1;) {
    const size_t half = len / 2;
    first = u < cdf[first + half] ? first : first + half;
    len -= half;
  }
  return std::min(int(first), int(cdf.size()) - 2);
}

std::vector<uint32_t> guide_table(const std::vector<float>& cdf, size_t n) {
  // Below 16 cells a plain binary search is as short as the guided one.
  const size_t m = n < 16 ? 0 : std::min(n, Distribution1D::kGuideBuckets);
  std::vector<uint32_t> guide(2 * m, 0);
  // A u that float rounding puts in slice k lies within a relative 2^-24 of
  // [k / m, (k + 1) / m): widening by 2^-20 each way keeps the cell inside.
  // Both ends grow with k, so one sweep over the cdf finds them all.
  size_t first = 0, last = 0;
  for (size_t k = 0; k < m; ++k) {
    const float lo = float(double(k) / double(m) * (1.0 - 0x1p-20));
    const float hi = float(double(k + 1) / double(m) * (1.0 + 0x1p-20));
    while (first < n && !(lo < cdf[first + 1])) ++first;
    while (last < n && !(hi < cdf[last + 1])) ++last;
    guide[2 * k] = uint32_t(std::min(first, n - 1));
    guide[2 * k + 1] = uint32_t(std::min(last, n - 1));
  }
  return guide;
}

}  // namespace

Distribution1D::Distribution1D(std::span<const float> f) : func(f.begin(), f.end()), cdf(f.size() + 1) {
  size_t n = func.size();
  for (float& v : func) v = std::isfinite(v) ? std::abs(v) : 0.0f;
  // Accumulate in double so that long tables keep their small cells.
  double sum = 0.0;
  cdf[0] = 0.0f;
  std::vector<double> acc(n + 1, 0.0);
  for (size_t i = 0; i < n; ++i) acc[i + 1] = acc[i] + func[i] / double(n);
  sum = acc[n];
  integral = float(sum);
  if (sum == 0.0) {
    for (size_t i = 1; i <= n; ++i) cdf[i] = float(double(i) / double(n));
  } else {
    for (size_t i = 1; i <= n; ++i) cdf[i] = float(acc[i] / sum);
  }
  if (n > 0) cdf[n] = 1.0f;
  guide = guide_table(cdf, n);
}



int Distribution1D::find_interval(float u) const {
  const size_t m = guide.size() / 2;
  if (m != 0 && u >= 0.0f && u < 1.0f) {
    const size_t k = std::min(size_t(u * float(m)), m - 1);
    return upper_cell(cdf, guide[2 * k], guide[2 * k + 1], u);
  }
  return upper_cell(cdf, 0, func.size(), u);
}

float Distribution1D::sample_continuous(float u, float* pdf, int* offset) const {
  int i = find_interval(u);
  if (offset) *offset = i;
  float du = u - cdf[i];
  float width = cdf[i + 1] - cdf[i];
  if (width > 0.0f) du /= width;
  if (pdf) *pdf = integral > 0.0f ? func[i] / integral : 1.0f;
  return std::min((float(i) + du) / float(size()), kOneMinusEpsilon);
}

int Distribution1D::sample_discrete(float u, float* pmf, float* u_remapped) const {
  int i = find_interval(u);
  float width = cdf[i + 1] - cdf[i];
  if (pmf) *pmf = width;
  if (u_remapped) *u_remapped = width > 0.0f ? std::min((u - cdf[i]) / width, kOneMinusEpsilon) : 0.0f;
  return i;
}

float Distribution1D::discrete_pmf(int i) const { return cdf[i + 1] - cdf[i]; }

}  // namespace theia
