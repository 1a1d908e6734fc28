#include "scheduler/adaptive.h"

#include "core/log.h"
#include "scheduler/combine.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace theia {

namespace {
// The film's sums carry float noise from the order of atomic adds (different
// in every run, and after a resume).  Rounding the error estimate to 8
// significant bits makes the plan, and so the image, the same run to run
// unless a value lies within that noise of a rounding boundary.  The blur
// and the shares below then add exactly (few-bit values in double).
double quantize(double v) {
  if (!(v > 0.0) || !std::isfinite(v)) return 0.0;
  int e;
  double m = std::frexp(v, &e);
  return std::ldexp(std::round(m * 256.0) / 256.0, e);
}
}  // namespace

AdaptiveSampler::AdaptiveSampler(int width, int height, std::vector<int> sizes, uint32_t alpha_spp)
    : width_(width), height_(height), sizes_(std::move(sizes)), alpha_spp_(alpha_spp),
      counts_(size_t(width) * size_t(height), 0) {
  std::vector<uint32_t> n(counts_.size(), sizes_.empty() ? 0u : uint32_t(sizes_[0]));
  set_ranges(n, sizes_.size() == 1);
}

void AdaptiveSampler::set_ranges(const std::vector<uint32_t>& n, bool last) {
  const size_t P = counts_.size();
  ranges_.begin = counts_;
  ranges_.colour_end.resize(P);
  ranges_.offset.assign(P + 1, 0);
  for (size_t p = 0; p < P; ++p) {
    uint32_t end = counts_[p] + n[p];
    ranges_.colour_end[p] = end;
    // Consistent alpha: the last iteration tops every pixel up to alpha_spp.
    uint32_t rays_end = last ? std::max(end, alpha_spp_) : end;
    ranges_.offset[p + 1] = ranges_.offset[p] + (rays_end - counts_[p]);
  }
}

void AdaptiveSampler::update(const Film& total, int index) {
  const size_t P = counts_.size();
  for (size_t p = 0; p < P; ++p) counts_[p] = ranges_.colour_end[p];
  const int next = index + 1;
  if (next >= int(sizes_.size())) return;

  // Per-sample relative standard deviation s_p, from the half buffers of
  // everything rendered so far: Var[mean] * n = per-sample variance.
  std::vector<float> var = half_buffer_variance(total);
  std::vector<double> s(P, 0.0);
  for (size_t p = 0; p < P; ++p) {
    if (var[p] < 0.0f || total.weight[p] <= 0.0f) continue;
    double w = total.weight[p];
    double lum = (double(total.r[p]) + total.g[p] + total.b[p]) / (3.0 * w);
    // The relMSE denominator (core/metrics.h): dark pixels matter less.
    s[p] = quantize(std::sqrt(double(var[p]) * counts_[p] / (lum * lum + 0.01)));
  }
  // A 3x3 box blur: one pair of halves gives a chi-square(1) estimate; pixels
  // whose halves agree by chance must not be starved.
  std::vector<double> blurred(P, 0.0);
  for (int y = 0; y < height_; ++y)
    for (int x = 0; x < width_; ++x) {
      double sum = 0.0;
      int n = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= width_ || yy >= height_) continue;
          sum += s[size_t(yy) * size_t(width_) + size_t(xx)];
          ++n;
        }
      blurred[size_t(y) * size_t(width_) + size_t(x)] = std::max(s[size_t(y) * size_t(width_) + size_t(x)], sum / n);
    }

  // Target totals proportional to s_p over the samples spent after this
  // iteration; the budget goes to each pixel's shortfall.
  const uint64_t budget = uint64_t(sizes_[size_t(next)]) * P;
  double s_sum = std::accumulate(blurred.begin(), blurred.end(), 0.0);
  double spent = std::accumulate(counts_.begin(), counts_.end(), 0.0) + double(budget);
  std::vector<double> want(P, 1.0);
  double want_sum = double(P);
  if (s_sum > 0.0) {
    want_sum = 0.0;
    for (size_t p = 0; p < P; ++p) {
      want[p] = std::max(0.0, spent * blurred[p] / s_sum - counts_[p]);
      want_sum += want[p];
    }
    if (want_sum <= 0.0) {
      std::fill(want.begin(), want.end(), 1.0);
      want_sum = double(P);
    }
  }
  // Integer counts: floors, then the remainder to the largest fractions
  // (ties to the lower pixel index), so the plan is deterministic.
  std::vector<uint32_t> n(P);
  std::vector<std::pair<double, uint32_t>> frac(P);
  uint64_t given = 0;
  for (size_t p = 0; p < P; ++p) {
    double x = double(budget) * want[p] / want_sum;
    n[p] = uint32_t(std::floor(x));
    given += n[p];
    frac[p] = {x - std::floor(x), uint32_t(p)};
  }
  std::sort(frac.begin(), frac.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  });
  for (size_t k = 0; given < budget && k < P; ++k, ++given) ++n[frac[k].second];
  set_ranges(n, next + 1 == int(sizes_.size()));
}

CheckpointParticipant AdaptiveSampler::participant() {
  CheckpointParticipant p;
  p.name = "adaptive_sampler";
  p.version = 1;
  p.save = [this] {
    ByteWriter w;
    w.put_vector(counts_);
    w.put_vector(ranges_.begin);
    w.put_vector(ranges_.colour_end);
    w.put_vector(ranges_.offset);
    return w.bytes;
  };
  p.load = [this](const CheckpointSection& s) {
    if (s.version != 1) throw_error("adaptive sampler section version {}, expected 1", s.version);
    ByteReader r(s.bytes, "adaptive sampler section");
    counts_ = r.get_vector<uint32_t>();
    ranges_.begin = r.get_vector<uint32_t>();
    ranges_.colour_end = r.get_vector<uint32_t>();
    ranges_.offset = r.get_vector<uint64_t>();
    const size_t P = size_t(width_) * size_t(height_);
    if (counts_.size() != P || ranges_.begin.size() != P || ranges_.colour_end.size() != P ||
        ranges_.offset.size() != P + 1)
      throw_error("adaptive sampler section: sizes do not match the image");
  };
  return p;
}

}  // namespace theia
