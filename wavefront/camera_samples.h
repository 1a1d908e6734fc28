// The numbering of an iteration's camera samples: one function for all who
// count them (the camera stage, the caustic pass, the scheduler's spp range,
// an iteration resumed or stopped part-way).
//
// Sample-major: every pixel's first sample of the iteration, then every
// pixel's second, and so on.  The first g samples give each pixel g / P of
// them or one more, so a render its time limit stops inside an iteration is
// evenly sampled: in pixel-major order the first rows had the whole
// iteration and the last none of it, a band of noise and 1.16x the relMSE of
// an even image of as many samples.  Consecutive camera rays are
// neighbouring pixels, as coherent as before.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace theia {

// Per-pixel samples of one iteration (adaptive sampling).  Pixel p renders
// samples [begin[p], begin[p] + offset[p+1] - offset[p]); those at or past
// colour_end[p] are alpha-only rays: they measure coverage and nothing else.
struct SampleRanges {
  std::vector<uint32_t> begin;
  std::vector<uint32_t> colour_end;
  std::vector<uint64_t> offset;  // pixel_count + 1 prefix sums of the per-pixel counts
  uint64_t total() const { return offset.empty() ? 0 : offset.back(); }
  uint32_t count(size_t pixel) const { return uint32_t(offset[pixel + 1] - offset[pixel]); }
};

struct CameraSample {
  uint32_t pixel = 0, sample = 0;
  bool alpha_only = false;  // past the pixel's colour samples: coverage only
};

// With per-pixel ranges, round k holds the pixels that have more than k
// samples, ordered by count (most first; pixel order among equals), so each
// round is a prefix of one order and a pixel has the same place in every
// round it is in.
class CameraSampleOrder {
 public:
  CameraSampleOrder() = default;
  // Samples [sample_begin, sample_end) of every one of `pixels` pixels.
  CameraSampleOrder(uint64_t pixels, uint32_t sample_begin, uint32_t sample_end);
  // Adaptive sampling's ranges; `ranges` must outlive the order.
  explicit CameraSampleOrder(const SampleRanges& ranges);

  uint64_t size() const { return size_; }
  // Camera sample g, g < size().
  CameraSample at(uint64_t g) const {
    if (!ranges_) return {uint32_t(g % pixels_), sample_begin_ + uint32_t(g / pixels_), false};
    return at_ranges(g);
  }
  // How many of `pixel`'s samples are among the first `done`.
  uint32_t samples_in(uint32_t pixel, uint64_t done) const;

 private:
  CameraSample at_ranges(uint64_t g) const;

  uint64_t pixels_ = 0, size_ = 0;
  uint32_t sample_begin_ = 0, sample_count_ = 0;
  const SampleRanges* ranges_ = nullptr;
  std::vector<uint32_t> order_;         // pixels, most samples first
  std::vector<uint32_t> rank_;          // pixel -> its place in order_
  std::vector<uint64_t> round_offset_;  // first g of round k; one past the last round at the end
};

}  // namespace theia
