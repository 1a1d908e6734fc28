// Adaptive sampling with consistent alpha (seeds/000 section 5.2.3).
//
// The requested spp is a budget over the frame.  The first iteration samples
// every pixel alike; after each iteration the relative error of every pixel
// is estimated from the film's two half buffers (even and odd samples,
// blurred over 3x3 pixels: one pair of halves is a very noisy estimate) and
// the next iteration's budget goes to the pixels furthest below their share:
// minimising sum relMSE = sum s_p^2 / n_p under sum n_p = N gives
// n_p proportional to s_p, the per-sample relative standard deviation.
//
// Alpha is counted over samples 0 .. alpha_spp-1 of every pixel, the same in
// every render pass (EngineOptions::alpha_spp); pixels that end below
// alpha_spp get alpha-only rays for the missing samples in the last iteration.
#pragma once

#include "checkpoint/checkpoint.h"
#include "wavefront/engine.h"
#include "wavefront/film.h"

#include <vector>

namespace theia {

class AdaptiveSampler {
 public:
  // sizes: the schedule (mean spp per iteration); alpha_spp: samples alpha counts.
  AdaptiveSampler(int width, int height, std::vector<int> sizes, uint32_t alpha_spp);

  // The samples of iteration `index` (the first is uniform).
  const SampleRanges& ranges() const { return ranges_; }
  // After iteration `index` (its film folded into `total`): plan iteration index + 1.
  void update(const Film& total, int index);
  // Samples each pixel has had so far (colour), for tests and logs.
  const std::vector<uint32_t>& counts() const { return counts_; }

  CheckpointParticipant participant();

 private:
  void set_ranges(const std::vector<uint32_t>& n, bool last);
  int width_, height_;
  std::vector<int> sizes_;
  uint32_t alpha_spp_;
  std::vector<uint32_t> counts_;   // colour samples per pixel before the planned iteration
  SampleRanges ranges_;
};

}  // namespace theia
