#include "app/diff.h"

#include "core/image.h"
#include "core/log.h"
#include "core/metrics.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <utility>

namespace theia {

RGB inferno_colormap(float t) {
  // Degree-6 minimax polynomial fit of matplotlib's inferno table
  // (Matt Zucconi, CC0): no table, within about 0.015 of matplotlib's values.
  t = std::clamp(std::isnan(t) ? 0.0f : t, 0.0f, 1.0f);
  const RGB c0(0.0002189403691192265f, 0.001651004631001012f, -0.01948089843709184f);
  const RGB c1(0.1065134194856116f, 0.5639564367884091f, 3.932712388889277f);
  const RGB c2(11.60249308247187f, -3.972853965665698f, -15.9423941062914f);
  const RGB c3(-41.70399613139459f, 17.43639888205313f, 44.35414519872813f);
  const RGB c4(77.162935699427f, -33.40235894210092f, -81.80730925738993f);
  const RGB c5(-71.31942824499214f, 32.62606426397723f, 73.20951985803202f);
  const RGB c6(25.13112622477341f, -12.24266895238567f, -23.07032500287172f);
  RGB c = c0 + t * (c1 + t * (c2 + t * (c3 + t * (c4 + t * (c5 + t * c6)))));
  return glm::clamp(c, RGB(0.0f), RGB(1.0f));
}

namespace {

// Writes the false-colour error image; returns the log10 range it maps.
std::pair<double, double> write_error_image(const std::string& path, const ImageBuffer& x, const ImageBuffer& r) {
  std::vector<float> err = per_pixel_rel_error(x, r);
  double emin = std::numeric_limits<double>::infinity(), emax = 0.0;
  for (float e : err)
    if (std::isfinite(e) && e > 0.0f) {
      emin = std::min(emin, double(e));
      emax = std::max(emax, double(e));
    }
  // Four decades below the worst pixel are enough to see structure; anything
  // smaller is as good as exact at preview precision.
  double hi = emax > 0.0 ? std::log10(emax) : 0.0;
  double lo = emax > 0.0 ? std::max(std::log10(emin), hi - 4.0) : 0.0;
  ImageBuffer out(x.width, x.height, {"R", "G", "B"});
  for (size_t i = 0; i < err.size(); ++i) {
    float e = err[i];
    RGB c;
    if (!std::isfinite(e))
      c = RGB(0.0f, 1.0f, 1.0f);  // cyan, outside the map: NaN or infinite samples
    else if (e <= 0.0f || hi <= lo)
      c = inferno_colormap(e > 0.0f ? 1.0f : 0.0f);
    else
      c = inferno_colormap(float((std::log10(double(e)) - lo) / (hi - lo)));
    // The map is display-referred; undo the encoding write_png_srgb applies.
    for (int k = 0; k < 3; ++k) out.data[3 * i + size_t(k)] = srgb_to_linear(c[k]);
  }
  write_png_srgb(path, out, 0, 1, 2);
  return {lo, hi};
}

}  // namespace

constexpr int kDiffTile = 32, kDiffTileCount = 8;

int run_diff(const std::string& a, const std::string& b, const std::string& error_image) {
  ImageBuffer x = read_image_file(a);
  ImageBuffer r = read_image_file(b);
  if (x.width != r.width || x.height != r.height)
    throw_error("{}: size {}x{} differs from {} ({}x{})", a, x.width, x.height, b, r.width, r.height);
  ErrorMetrics m = compute_error_metrics(x, r);
  fmt::print("relMSE {:.9g}\n", m.rel_mse);
  fmt::print("RMSE {:.9g}\n", m.rmse);
  fmt::print("MAPE {:.9g}\n", m.mape);
  fmt::print("block_relMSE {:.9g}\n", m.block_rel_mse);
  fmt::print("channel_mean_deviation {:.9g}\n", m.channel_mean_deviation);
  // Signed, per channel: a deviation alone cannot say which image is brighter.
  fmt::print("channel_mean_ratio");
  for (double ratio : channel_mean_ratios(x, r)) fmt::print(" {:.9g}", ratio);
  fmt::print("\n");
  // Where the error lives: a biased material shows as a tile whose mean ratio is off 1.
  fmt::print("worst {}x{} tiles (x0 y0 x1 y1 relMSE mean_ratio_R mean_ratio_G mean_ratio_B):\n", kDiffTile, kDiffTile);
  for (const TileError& t : worst_tiles(x, r, kDiffTile, kDiffTileCount))
    fmt::print("tile {} {} {} {} {:.6g} {:.4f} {:.4f} {:.4f}\n", t.x0, t.y0, t.x1, t.y1, t.rel_mse, t.mean_ratio[0],
               t.mean_ratio[1], t.mean_ratio[2]);
  if (!error_image.empty()) {
    auto [lo, hi] = write_error_image(error_image, x, r);
    fmt::print("error_image {} log10_rel_error_range {:.3f} {:.3f}\n", error_image, lo, hi);
  }
  std::fflush(stdout);
  return 0;
}

}  // namespace theia
