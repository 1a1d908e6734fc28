#include "core/metrics.h"

#include "core/log.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace theia {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The three (or fewer) channels both images are compared on, checked to agree.
struct Channels {
  std::vector<int> x, r;
};

Channels matched_channels(const ImageBuffer& x, const ImageBuffer& r) {
  if (x.width != r.width || x.height != r.height)
    throw_error("image sizes differ: {}x{} vs reference {}x{}", x.width, x.height, r.width, r.height);
  if (x.data.size() != x.pixel_count() * x.channels.size() || r.data.size() != r.pixel_count() * r.channels.size())
    throw_error("image buffer size does not match its width, height and channels");
  Channels ch{x.rgb_channel_indices(), r.rgb_channel_indices()};
  if (ch.x.empty() || ch.x.size() != ch.r.size())
    throw_error("images have incompatible channels: {} vs reference {}", x.channels.size(), r.channels.size());
  return ch;
}

// Sum of f(x_value, r_value) over all pixels and compared channels, and the count.
template <typename F>
double mean_over(const ImageBuffer& x, const ImageBuffer& r, F f) {
  Channels ch = matched_channels(x, r);
  size_t nx = x.channels.size(), nr = r.channels.size(), n = x.pixel_count();
  double sum = 0.0;
  for (size_t i = 0; i < n; ++i)
    for (size_t c = 0; c < ch.x.size(); ++c)
      sum += f(double(x.data[i * nx + size_t(ch.x[c])]), double(r.data[i * nr + size_t(ch.r[c])]));
  return n == 0 ? 0.0 : sum / double(n * ch.x.size());
}

double rel_sq(double xv, double rv) { return (xv - rv) * (xv - rv) / (rv * rv + kRelErrorEpsilon); }

// Averages block x block tiles of the compared channels into a new buffer.
ImageBuffer block_average(const ImageBuffer& img, const std::vector<int>& ch, int block) {
  int bw = (img.width + block - 1) / block, bh = (img.height + block - 1) / block;
  std::vector<std::string> names;
  for (int c : ch) names.push_back(img.channels[size_t(c)]);
  ImageBuffer out(bw, bh, names);
  std::vector<double> acc(ch.size());
  for (int by = 0; by < bh; ++by)
    for (int bx = 0; bx < bw; ++bx) {
      std::fill(acc.begin(), acc.end(), 0.0);
      int x1 = std::min(img.width, (bx + 1) * block), y1 = std::min(img.height, (by + 1) * block);
      for (int y = by * block; y < y1; ++y)
        for (int x = bx * block; x < x1; ++x)
          for (size_t c = 0; c < ch.size(); ++c) acc[c] += img.at(x, y, ch[c]);
      double count = double(x1 - bx * block) * double(y1 - by * block);
      for (size_t c = 0; c < ch.size(); ++c) out.at(bx, by, int(c)) = float(acc[c] / count);
    }
  return out;
}

}  // namespace

double rel_mse(const ImageBuffer& x, const ImageBuffer& r) { return mean_over(x, r, rel_sq); }

double rmse(const ImageBuffer& x, const ImageBuffer& r) {
  return std::sqrt(mean_over(x, r, [](double xv, double rv) { return (xv - rv) * (xv - rv); }));
}

double mape(const ImageBuffer& x, const ImageBuffer& r) {
  return mean_over(x, r, [](double xv, double rv) { return std::abs(xv - rv) / (std::abs(rv) + kRelErrorEpsilon); });
}

double block_rel_mse(const ImageBuffer& x, const ImageBuffer& r, int block) {
  if (block < 1) throw_error("block size must be at least 1, got {}", block);
  Channels ch = matched_channels(x, r);
  return rel_mse(block_average(x, ch.x, block), block_average(r, ch.r, block));
}

std::vector<double> channel_mean_ratios(const ImageBuffer& x, const ImageBuffer& r) {
  Channels ch = matched_channels(x, r);
  std::vector<double> ratio(ch.x.size());
  for (size_t c = 0; c < ratio.size(); ++c) {
    double sx = 0.0, sr = 0.0;
    for (int y = 0; y < x.height; ++y)
      for (int px = 0; px < x.width; ++px) {
        sx += x.at(px, y, ch.x[c]);
        sr += r.at(px, y, ch.r[c]);
      }
    // Means share the pixel count, so their ratio is the ratio of sums.
    if (sr != 0.0)
      ratio[c] = sx / sr;
    else if (sx == 0.0)
      ratio[c] = 1.0;
    else  // NaN stays NaN: it must not pass for a finite bias
      ratio[c] = std::isnan(sx) ? sx : std::copysign(std::numeric_limits<double>::infinity(), sx);
  }
  return ratio;
}

double channel_mean_deviation(const ImageBuffer& x, const ImageBuffer& r) {
  double worst = 0.0;
  for (double ratio : channel_mean_ratios(x, r)) {
    double dev = std::abs(ratio - 1.0);
    // NaN must not hide behind max().
    if (std::isnan(dev)) return dev;
    worst = std::max(worst, dev);
  }
  return worst;
}

ErrorMetrics compute_error_metrics(const ImageBuffer& x, const ImageBuffer& r, int block) {
  return {rel_mse(x, r), rmse(x, r), mape(x, r), block_rel_mse(x, r, block), channel_mean_deviation(x, r)};
}

std::vector<float> per_pixel_rel_error(const ImageBuffer& x, const ImageBuffer& r) {
  Channels ch = matched_channels(x, r);
  size_t nx = x.channels.size(), nr = r.channels.size(), n = x.pixel_count();
  std::vector<float> err(n);
  for (size_t i = 0; i < n; ++i) {
    double sum = 0.0;
    for (size_t c = 0; c < ch.x.size(); ++c) {
      double xv = x.data[i * nx + size_t(ch.x[c])], rv = r.data[i * nr + size_t(ch.r[c])];
      sum += std::abs(xv - rv) / (std::abs(rv) + kRelErrorEpsilon);
    }
    err[i] = float(sum / double(ch.x.size()));
  }
  return err;
}

std::vector<TileError> worst_tiles(const ImageBuffer& x, const ImageBuffer& r, int tile, int count) {
  if (tile < 1) throw_error("tile size must be at least 1, got {}", tile);
  Channels ch = matched_channels(x, r);
  std::vector<TileError> tiles;
  for (int y0 = 0; y0 < x.height; y0 += tile)
    for (int x0 = 0; x0 < x.width; x0 += tile) {
      TileError t{x0, y0, std::min(x.width, x0 + tile), std::min(x.height, y0 + tile)};
      double sq = 0.0, sx[3] = {0, 0, 0}, sr[3] = {0, 0, 0};
      for (int y = t.y0; y < t.y1; ++y)
        for (int px = t.x0; px < t.x1; ++px)
          for (size_t c = 0; c < ch.x.size(); ++c) {
            double xv = x.at(px, y, ch.x[c]), rv = r.at(px, y, ch.r[c]);
            sq += rel_sq(xv, rv);
            sx[c] += xv;
            sr[c] += rv;
          }
      double n = double(t.x1 - t.x0) * double(t.y1 - t.y0) * double(ch.x.size());
      t.rel_mse = sq / n;
      for (size_t c = 0; c < ch.x.size(); ++c) t.mean_ratio[c] = sr[c] != 0.0 ? sx[c] / sr[c] : (sx[c] == 0.0 ? 1.0 : kInf);
      tiles.push_back(t);
    }
  std::stable_sort(tiles.begin(), tiles.end(), [](const TileError& a, const TileError& b) { return a.rel_mse > b.rel_mse; });
  if (count >= 0 && tiles.size() > size_t(count)) tiles.resize(size_t(count));
  return tiles;
}

}  // namespace theia
