// The numbering of an iteration's camera samples: every (pixel, sample) once,
// and a prefix of it samples the pixels evenly (a time limit's cut).
#include "wavefront/camera_samples.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>
#include <utility>

using namespace theia;

namespace {

// Checks `order` against brute force: each (pixel, sample) of the ranges
// once, and samples_in(p, done) equal to the count of p among at(0..done-1)
// for every done.  Returns the largest spread over all prefixes: how many
// more samples any pixel has than the poorest pixel that has more to come.
uint32_t check_order(const CameraSampleOrder& order, size_t pixels, const std::vector<uint32_t>& begin,
                     const std::vector<uint32_t>& count, const std::vector<uint32_t>& colour_end) {
  std::set<std::pair<uint32_t, uint32_t>> seen;
  std::vector<uint32_t> got(pixels, 0);
  uint32_t spread = 0;
  for (uint64_t g = 0; g <= order.size(); ++g) {
    for (uint32_t p = 0; p < pixels; ++p) EXPECT_EQ(order.samples_in(p, g), got[p]) << "pixel " << p << " done " << g;
    uint32_t lo = UINT32_MAX;  // fewest samples among the pixels that have more to come
    for (uint32_t p = 0; p < pixels; ++p)
      if (got[p] < count[p]) lo = std::min(lo, got[p]);
    for (uint32_t p = 0; p < pixels; ++p)
      if (lo != UINT32_MAX && got[p] > lo) spread = std::max(spread, got[p] - lo);
    if (g == order.size()) break;
    const CameraSample s = order.at(g);
    EXPECT_LT(s.pixel, pixels);
    EXPECT_EQ(s.sample, begin[s.pixel] + got[s.pixel]) << "a pixel's samples come in order";
    EXPECT_EQ(s.alpha_only, s.sample >= colour_end[s.pixel]);
    EXPECT_TRUE(seen.insert({s.pixel, s.sample}).second) << "sample " << g << " twice";
    ++got[s.pixel];
  }
  for (size_t p = 0; p < pixels; ++p) EXPECT_EQ(got[p], count[p]) << "pixel " << p;
  return spread;
}

}  // namespace

TEST(CameraSampleOrder, UniformIsSampleMajorAndEveryPrefixIsEven) {
  const size_t pixels = 7;
  const CameraSampleOrder order(pixels, 8, 13);
  ASSERT_EQ(order.size(), 35u);
  EXPECT_EQ(order.at(0).pixel, 0u);
  EXPECT_EQ(order.at(1).pixel, 1u) << "neighbouring pixels next to each other";
  EXPECT_EQ(order.at(7).sample, 9u);
  const std::vector<uint32_t> begin(pixels, 8), count(pixels, 5), end(pixels, 13);
  EXPECT_EQ(check_order(order, pixels, begin, count, end), 1u) << "a cut leaves n or n + 1 samples in each pixel";
}

// Adaptive sampling's ranges: a pixel's count from 0 to 9, some with
// alpha-only samples at the end.  Every prefix leaves each pixel that still
// has samples to come within one of the others.
TEST(CameraSampleOrder, PerPixelRangesAreSampleMajorToo) {
  std::mt19937 rng(5);
  const size_t pixels = 40;
  SampleRanges r;
  std::vector<uint32_t> count(pixels);
  r.offset.assign(pixels + 1, 0);
  for (size_t p = 0; p < pixels; ++p) {
    count[p] = uint32_t(rng() % 10);
    r.begin.push_back(uint32_t(rng() % 5));
    r.colour_end.push_back(r.begin[p] + count[p] - std::min<uint32_t>(count[p], uint32_t(rng() % 3)));
    r.offset[p + 1] = r.offset[p] + count[p];
  }
  const CameraSampleOrder order(r);
  ASSERT_EQ(order.size(), r.total());
  EXPECT_EQ(check_order(order, pixels, r.begin, count, r.colour_end), 1u);
}

TEST(CameraSampleOrder, EmptyRangesAndNoPixels) {
  SampleRanges r;
  r.offset.assign(4, 0);
  r.begin.assign(3, 2);
  r.colour_end.assign(3, 2);
  const CameraSampleOrder order(r);
  EXPECT_EQ(order.size(), 0u);
  EXPECT_EQ(order.samples_in(1, 0), 0u);
  const CameraSampleOrder none(0, 0, 4);
  EXPECT_EQ(none.size(), 0u);
  EXPECT_EQ(none.samples_in(0, 0), 0u);
}
