// `theia diff A.exr B.exr [--error-image OUT.png]`: compares a test image A
// with a reference B using core/metrics.h.
#pragma once

#include "core/math.h"

#include <string>

namespace theia {

// Prints relMSE, RMSE, MAPE, block relMSE (8x8) and the channel-mean
// deviation of `a` against the reference `b` to stdout, one "name value" per
// line, then the 8 worst 32x32 tiles by relMSE with their per-channel ratio of
// means ("tile x0 y0 x1 y1 relMSE rR rG rB"), so a mismatch points at a region.  If `error_image` is not empty, also writes a PNG of the per-pixel
// relative error |a - b| / (|b| + 1e-2) (mean over R, G, B) on a log10 scale
// through the inferno colour map, and prints the log10 range it spans.
// Returns 0; throws theia::Error on unreadable or mismatched images.
int run_diff(const std::string& a, const std::string& b, const std::string& error_image);

// Matplotlib's inferno colour map at t in [0, 1] (clamped), display-referred
// sRGB values in [0, 1].  Black = low error, yellow = high.
RGB inferno_colormap(float t);

}  // namespace theia
