// Error measures between a test image x and a reference r, used by tests,
// `theia diff` and the per-iteration log.  All are over every pixel and the
// R, G, B channels (by name, else the first three; see
// ImageBuffer::rgb_channel_indices), summed in double in a fixed order so the
// numbers are reproducible.  Mismatched sizes throw theia::Error.
#pragma once

#include "core/image.h"

#include <vector>

namespace theia {

// The offset keeps dark reference pixels from dominating (and 0/0).
inline constexpr double kRelErrorEpsilon = 1e-2;

// mean((x - r)^2 / (r^2 + 1e-2))
double rel_mse(const ImageBuffer& x, const ImageBuffer& r);
// sqrt(mean((x - r)^2))
double rmse(const ImageBuffer& x, const ImageBuffer& r);
// mean(|x - r| / (|r| + 1e-2))
double mape(const ImageBuffer& x, const ImageBuffer& r);
// relMSE of the images after averaging block x block pixel tiles (partial tiles
// at the right and bottom edges average the pixels they have): insensitive to
// zero-mean per-pixel noise, sensitive to bias and low-frequency error.
double block_rel_mse(const ImageBuffer& x, const ImageBuffer& r, int block = 8);
// mean(x) / mean(r) per compared channel (R, G, B): which way a global energy
// bias goes (a spectral renderer's image against an RGB one's, say). A channel
// whose reference mean is 0 has ratio 1 if x's mean is 0 too, else +-inf.
std::vector<double> channel_mean_ratios(const ImageBuffer& x, const ImageBuffer& r);
// max over R, G, B of |mean(x) / mean(r) - 1|: a global energy bias check.
double channel_mean_deviation(const ImageBuffer& x, const ImageBuffer& r);

struct ErrorMetrics {
  double rel_mse = 0, rmse = 0, mape = 0, block_rel_mse = 0, channel_mean_deviation = 0;
};
ErrorMetrics compute_error_metrics(const ImageBuffer& x, const ImageBuffer& r, int block = 8);

// Per-pixel relative error, mean over R, G, B of |x - r| / (|r| + 1e-2),
// row-major, one value per pixel (the quantity `theia diff` maps to colour).
std::vector<float> per_pixel_rel_error(const ImageBuffer& x, const ImageBuffer& r);

// One tile of the image and how far the test image is from the reference there.
struct TileError {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // pixel range [x0, x1) x [y0, y1)
  double rel_mse = 0;                   // relMSE over the tile's pixels
  double mean_ratio[3] = {1, 1, 1};     // per channel: mean(x) / mean(r) over the tile (bias shows here)
};
// The `count` tiles of tile x tile pixels with the largest relMSE, worst first
// (ties broken by position, so the report is deterministic).
std::vector<TileError> worst_tiles(const ImageBuffer& x, const ImageBuffer& r, int tile = 32, int count = 8);

}  // namespace theia
