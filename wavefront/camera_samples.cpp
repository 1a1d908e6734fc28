#include "wavefront/camera_samples.h"

#include <algorithm>

namespace theia {

CameraSampleOrder::CameraSampleOrder(uint64_t pixels, uint32_t sample_begin, uint32_t sample_end)
    : pixels_(pixels), sample_begin_(sample_begin), sample_count_(sample_end > sample_begin ? sample_end - sample_begin : 0) {
  size_ = pixels_ * sample_count_;
}

CameraSampleOrder::CameraSampleOrder(const SampleRanges& ranges) : ranges_(&ranges) {
  pixels_ = ranges.begin.size();
  size_ = ranges.total();
  // A counting sort by count, most first, stable.
  uint32_t most = 0;
  for (size_t p = 0; p < pixels_; ++p) most = std::max(most, ranges.count(p));
  std::vector<uint64_t> with(size_t(most) + 2, 0);  // with[c]: pixels with exactly c samples, then slots
  for (size_t p = 0; p < pixels_; ++p) ++with[ranges.count(p)];
  // Pixels with more than k samples: round k's size; round k starts after rounds 0..k-1.
  round_offset_.assign(size_t(most) + 1, 0);
  uint64_t more = pixels_ - with[0];
  for (uint32_t k = 0; k < most; ++k) {
    round_offset_[k + 1] = round_offset_[k] + more;
    more -= with[k + 1];
  }
  std::vector<uint64_t> next(size_t(most) + 2, 0);  // first place of the pixels with count c
  for (uint32_t c = most; c-- > 0;) next[c] = next[c + 1] + with[c + 1];
  order_.resize(pixels_);
  rank_.resize(pixels_);
  for (size_t p = 0; p < pixels_; ++p) {
    const uint64_t place = next[ranges.count(p)]++;
    order_[place] = uint32_t(p);
    rank_[p] = uint32_t(place);
  }
}

CameraSample CameraSampleOrder::at_ranges(uint64_t g) const {
  const uint32_t k = uint32_t(std::upper_bound(round_offset_.begin(), round_offset_.end(), g) - round_offset_.begin()) - 1;
  CameraSample s;
  s.pixel = order_[g - round_offset_[k]];
  s.sample = ranges_->begin[s.pixel] + k;
  s.alpha_only = s.sample >= ranges_->colour_end[s.pixel];
  return s;
}

uint32_t CameraSampleOrder::samples_in(uint32_t pixel, uint64_t done) const {
  if (!ranges_) {
    if (pixels_ == 0) return 0;
    const uint64_t got = done / pixels_ + (pixel < done % pixels_ ? 1 : 0);
    return uint32_t(std::min<uint64_t>(got, sample_count_));
  }
  // Rounds k < count with round_offset_[k] + rank_[pixel] < done.
  const uint32_t count = ranges_->count(pixel);
  if (done <= rank_[pixel]) return 0;
  const auto first = round_offset_.begin();
  return uint32_t(std::lower_bound(first, first + count, done - rank_[pixel]) - first);
}

}  // namespace theia
