// Folding per-iteration images into the result.
//
// Equal weighting (the default) sums every iteration's film: each sample
// counts the same, so a guided render is never noisier than an unguided one at
// equal spp (seeds/000 section 6).  Inverse-variance weighting (seeds/001
// section 10.3) combines only the last four iterations' images, each weighted
// by the inverse of its mean pixel variance over the image (a whole-image
// weight: per-pixel weights would correlate with the pixel values and bias
// them), for path guiding, whose later iterations are better.
#pragma once

#include "core/image.h"
#include "wavefront/film.h"

#include <deque>
#include <string>
#include <vector>

namespace theia {

enum class Combination { Equal, InverseVariance };
Combination parse_combination(const std::string& name);  // "equal" | "inverse-variance"
const char* combination_name(Combination c);

inline constexpr size_t kInverseVarianceWindow = 4;

// One iteration's colour, kept for inverse-variance weighting.
struct IterationImage {
  std::vector<float> rgb;   // resolved R G B per pixel (linear sRGB, as the output), interleaved
  double mean_variance = 0; // mean over pixels and channels of the variance of the pixel estimate; < 0: unknown
};

// Variance of each pixel's iteration estimate from its two half buffers
// (even and odd samples): ((even - odd) / 2)^2 averaged over R, G, B.  Pixels
// with no sample in one half get -1 (unknown).
std::vector<float> half_buffer_variance(const Film& film);

struct ImageAccumulator {
  Film total;                             // every finished iteration summed
  std::deque<IterationImage> recent;      // the last kInverseVarianceWindow iterations

  ImageAccumulator(int width, int height) : total(width, height) {}
  void fold(const Film& iteration);
  // R G B A albedo.* N.* depth.Z, as resolve_film.
  ImageBuffer resolve(Combination c) const;
};

}  // namespace theia
