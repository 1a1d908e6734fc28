#include "core/sampling.h"

#include <algorithm>
#include <numeric>

namespace theia {

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
}

static int find_interval(const std::vector<float>& cdf, float u) {
  // Largest i with cdf[i] <= u, clamped to a valid cell.
  auto it = std::upper_bound(cdf.begin(), cdf.end(), u);
  int i = int(it - cdf.begin()) - 1;
  return std::clamp(i, 0, int(cdf.size()) - 2);
}

float Distribution1D::sample_continuous(float u, float* pdf, int* offset) const {
  int i = find_interval(cdf, u);
  if (offset) *offset = i;
  float du = u - cdf[i];
  float width = cdf[i + 1] - cdf[i];
  if (width > 0.0f) du /= width;
  if (pdf) *pdf = integral > 0.0f ? func[i] / integral : 1.0f;
  return std::min((float(i) + du) / float(size()), kOneMinusEpsilon);
}

int Distribution1D::sample_discrete(float u, float* pmf, float* u_remapped) const {
  int i = find_interval(cdf, u);
  float width = cdf[i + 1] - cdf[i];
  if (pmf) *pmf = width;
  if (u_remapped) *u_remapped = width > 0.0f ? std::min((u - cdf[i]) / width, kOneMinusEpsilon) : 0.0f;
  return i;
}

float Distribution1D::discrete_pmf(int i) const { return cdf[i + 1] - cdf[i]; }

}  // namespace theia
