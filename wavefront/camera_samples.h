// Which (pixel, sample) the camera stage's g-th sample of an iteration is
// (pixel-sample order over the frame, or over the per-pixel ranges of
// adaptive sampling), and the samples' film draws.
#pragma once

#include "core/sampler.h"
#include "scene/filter.h"
#include "wavefront/engine.h"
#include "wavefront/sample_dims.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>

namespace theia {

struct PixelSample {
  uint32_t pixel = 0, sample = 0;
  bool alpha_only = false;  // past the pixel's colour samples: coverage only
};

// Camera samples g, g + 1, ... in turn: the first found by division (or by a
// search of the adaptive ranges), each next one by a step, which spares every
// camera sample a 64-bit division.  Stepping past the iteration's last sample
// is allowed (the walk stays in bounds); what it then holds is not a sample.
class CameraSampleWalk {
 public:
  CameraSampleWalk(uint64_t g, const SampleRanges* ranges, uint32_t sample_begin, uint32_t sample_count)
      : g_(g), ranges_(ranges), sample_begin_(sample_begin), sample_count_(sample_count) {
    if (ranges) {
      auto it = std::upper_bound(ranges->offset.begin(), ranges->offset.end(), g);
      s_.pixel = uint32_t(std::min<ptrdiff_t>(it - ranges->offset.begin(), ptrdiff_t(ranges->begin.size())) - 1);
      s_.sample = ranges->begin[s_.pixel] + uint32_t(g - ranges->offset[s_.pixel]);
      next_pixel_g_ = ranges->offset[s_.pixel + 1];
      s_.alpha_only = s_.sample >= ranges->colour_end[s_.pixel];
    } else {
      s_.pixel = uint32_t(g / sample_count);
      s_.sample = sample_begin + uint32_t(g % sample_count);
      next_pixel_g_ = (g / sample_count + 1) * sample_count;
    }
  }
  const PixelSample& operator*() const { return s_; }
  const PixelSample* operator->() const { return &s_; }

  void step() {
    if (++g_ < next_pixel_g_) {
      ++s_.sample;
      if (ranges_) s_.alpha_only = s_.sample >= ranges_->colour_end[s_.pixel];
      return;
    }
    if (!ranges_) {
      ++s_.pixel;
      s_.sample = sample_begin_;
      next_pixel_g_ += sample_count_;
      return;
    }
    // The next pixel with samples left (adaptive sampling gives some none).
    const uint32_t last = uint32_t(ranges_->begin.size()) - 1;
    while (s_.pixel < last && ranges_->offset[s_.pixel + 1] <= g_) ++s_.pixel;
    s_.sample = ranges_->begin[s_.pixel] + uint32_t(g_ - std::min(g_, ranges_->offset[s_.pixel]));
    next_pixel_g_ = ranges_->offset[s_.pixel + 1];
    s_.alpha_only = s_.sample >= ranges_->colour_end[s_.pixel];
  }

 private:
  PixelSample s_;
  uint64_t g_, next_pixel_g_ = 0;  // next_pixel_g_: the first g of the pixel after s_.pixel
  const SampleRanges* ranges_;
  uint32_t sample_begin_, sample_count_;
};

// Camera samples whose film offsets are drawn together (sample_filter's span form).
inline constexpr size_t kFilmBlock = 64;

// The film offsets and weights of a walk's camera samples, a block at a
// time: camera_filter_sample's, bit for bit.  A pixel's samples are
// consecutive, so its film pair is hashed once for them.
class CameraFilmDraws {
 public:
  CameraFilmDraws(const Filter& filter, uint32_t seed, uint32_t pixel)
      : filter_(filter), seed_(seed), pixel_(pixel), pair_(SamplerKey{seed, pixel, 0}, CameraDims::film) {}

  // The walk's next samples.size() (at most kFilmBlock) samples and their
  // film draws; the walk steps past them.
  void operator()(CameraSampleWalk& walk, std::span<PixelSample> samples, std::span<FilterSample> film) {
    std::array<vec2, kFilmBlock> u;
    for (size_t i = 0; i < samples.size(); ++i, walk.step()) {
      if (walk->pixel != pixel_)
        pixel_ = walk->pixel, pair_ = PairSampler(SamplerKey{seed_, pixel_, 0}, CameraDims::film);
      samples[i] = *walk;
      u[i] = pair_(walk->sample);
    }
    sample_filter(filter_, std::span<const vec2>(u.data(), samples.size()), film);
  }

 private:
  const Filter& filter_;
  uint32_t seed_, pixel_;
  PairSampler pair_;
};

}  // namespace theia
