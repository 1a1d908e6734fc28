// Iteration schedules, checkpoint skipping, the between-iteration task order
// and the combination of per-iteration images.
#include "core/color.h"
#include "core/log.h"
#include "scheduler/combine.h"
#include "scheduler/schedule.h"

#include <gtest/gtest.h>

using namespace theia;

TEST(Schedule, RegularDoublesToTheMaximumAndHitsTheTotal) {
  EXPECT_EQ(make_schedule(regular_schedule(), 1024), (std::vector<int>{16, 16, 32, 64, 128, 256, 256, 256}));
  // The last iteration is shortened so the total is exact.
  EXPECT_EQ(make_schedule(regular_schedule(), 100), (std::vector<int>{16, 16, 32, 36}));
  EXPECT_EQ(make_schedule(regular_schedule(), 5), (std::vector<int>{5}));
}

TEST(Schedule, GuidingRepeatsTheSmallFirstSizeThenGrowsToASmallerMaximum) {
  std::vector<int> sizes = make_schedule(guiding_schedule(), 128);
  EXPECT_EQ(sizes, (std::vector<int>{1, 1, 1, 1, 1, 1, 1, 1, 2, 4, 8, 16, 16, 16, 16, 16, 16, 10}));
  EXPECT_EQ(cumulative_spp(sizes),
            (std::vector<int>{1, 2, 3, 4, 5, 6, 7, 8, 10, 14, 22, 38, 54, 70, 86, 102, 118, 128}));
}

TEST(Schedule, FullyConfigurable) {
  ScheduleOptions o{3, 2, 1.5, 10};
  // 3 3 then x1.5: 4.5 -> 4, 6.75 -> 6, 10 (capped) ...
  EXPECT_EQ(make_schedule(o, 40), (std::vector<int>{3, 3, 4, 6, 10, 10, 4}));
  EXPECT_EQ(make_schedule({4, 1, 1.0, 4}, 10), (std::vector<int>{4, 4, 2}));
}

TEST(Schedule, ImpossibleOptionsAreRefused) {
  EXPECT_THROW(make_schedule({0, 1, 2.0, 16}, 16), Error);
  EXPECT_THROW(make_schedule({4, 1, 0.5, 16}, 16), Error);
  EXPECT_THROW(make_schedule({32, 1, 2.0, 16}, 16), Error);
  EXPECT_THROW(make_schedule({4, 0, 2.0, 16}, 16), Error);
  EXPECT_THROW(make_schedule(regular_schedule(), 0), Error);
}

TEST(CheckpointSkipping, ThePapersExampleComesOutExactly) {
  std::vector<int> cumulative{1, 2, 3, 4, 5, 6, 7, 8, 10, 14, 22, 38, 54, 70, 86, 102, 118, 128};
  std::vector<bool> write = checkpoint_iterations(cumulative, 4);
  std::vector<int> written;
  for (size_t i = 0; i < write.size(); ++i)
    if (write[i]) written.push_back(cumulative[i]);
  EXPECT_EQ(written, (std::vector<int>{4, 8, 14, 22, 54, 128}));
}

TEST(CheckpointSkipping, RegularScheduleAndEveryIteration) {
  std::vector<int> cumulative = cumulative_spp(make_schedule(regular_schedule(), 128));  // 16 32 64 128
  std::vector<bool> write = checkpoint_iterations(cumulative, 4);
  // No iteration is at or below 4 or 8: the first checkpoint is after 16.
  EXPECT_EQ(write, (std::vector<bool>{true, true, true, true}));
  std::vector<int> small{1, 2, 3, 4, 5, 6, 7, 8};
  EXPECT_EQ(checkpoint_iterations(small, 4, true), std::vector<bool>(8, true));
  // The total is always checkpointed, even off the doubling sequence.
  std::vector<int> odd{3, 6, 9, 12, 13};
  // Ideals 4 8 13 -> iterations at 3, 6, 13.
  EXPECT_EQ(checkpoint_iterations(odd, 4), (std::vector<bool>{true, true, false, false, true}));
}

TEST(IterationTasks, RunInSlotOrderWhateverTheRegistrationOrder) {
  IterationTasks tasks;
  std::vector<std::string> ran;
  tasks.add(BetweenIterationSlot::Checkpoint, [&](const IterationInfo&) { ran.push_back("checkpoint"); });
  tasks.add(BetweenIterationSlot::RecorderSkipRateUpdate, [&](const IterationInfo&) { ran.push_back("skip"); });
  tasks.add(BetweenIterationSlot::GuidingUpdate, [&](const IterationInfo&) { ran.push_back("guiding"); });
  tasks.add(BetweenIterationSlot::AdaptiveSamplerUpdate, [&](const IterationInfo&) { ran.push_back("adaptive"); });
  tasks.add(BetweenIterationSlot::CachePointUpdate, [&](const IterationInfo&) { ran.push_back("cache"); });
  tasks.on_begin([&](const IterationInfo& it) { ran.push_back("begin" + std::to_string(it.index)); });
  tasks.on_end([&](const IterationInfo& it) { ran.push_back("end" + std::to_string(it.index)); });
  IterationInfo it;
  it.index = 3;
  it.count = 4;
  EXPECT_TRUE(it.last());
  tasks.begin_iteration(it);
  tasks.end_iteration(it);
  EXPECT_EQ(ran, (std::vector<std::string>{"begin3", "end3", "guiding", "cache", "adaptive", "skip", "checkpoint"}));
  EXPECT_GE(tasks.seconds(BetweenIterationSlot::Checkpoint), 0.0);
}

namespace {
// A 1x1 film whose even samples average `even` and odd ones `odd` (weight 1 each).
void set_halves(Film& f, float even, float odd) {
  f.clear();
  for (uint32_t s = 0; s < 2; ++s) {
    f.add_weight(0, s, 1.0f);
    float v = s ? odd : even;
    f.splat(0, s, RGB(v));
  }
}
}  // namespace

TEST(Combination, HalfBufferVarianceOfThePixelEstimate) {
  Film f(1, 1);
  set_halves(f, 1.0f, 3.0f);
  EXPECT_FLOAT_EQ(half_buffer_variance(f)[0], 1.0f);  // ((1 - 3) / 2)^2
  f.clear();
  f.add_weight(0, 0, 1.0f);
  EXPECT_EQ(half_buffer_variance(f)[0], -1.0f);  // one sample: unknown
}

TEST(Combination, EqualWeightsEverySampleInverseVarianceWeightsWholeIterations) {
  Film it(1, 1);
  ImageAccumulator acc(1, 1);
  set_halves(it, 1.0f, 3.0f);  // mean 2, variance 1
  acc.fold(it);
  set_halves(it, 3.5f, 4.5f);  // mean 4, variance 1/4
  acc.fold(it);
  EXPECT_FLOAT_EQ(acc.resolve(Combination::Equal).data[0], 3.0f);
  // Weights 1 and 4: (2 + 16) / 5.
  EXPECT_FLOAT_EQ(acc.resolve(Combination::InverseVariance).data[0], 3.6f);
  // Only the last four iterations count.
  for (int k = 0; k < 4; ++k) {
    set_halves(it, 9.5f, 10.5f);
    acc.fold(it);
  }
  EXPECT_EQ(acc.recent.size(), kInverseVarianceWindow);
  EXPECT_FLOAT_EQ(acc.resolve(Combination::InverseVariance).data[0], 10.0f);
  EXPECT_EQ(parse_combination("inverse-variance"), Combination::InverseVariance);
  EXPECT_THROW(parse_combination("best"), Error);
}

// The film holds the working colour space (Rec.2020) and the output is linear
// sRGB: iterations of one saturated colour combine to that colour whichever
// combination is asked for (inverse-variance once mixed Rec.2020 values into
// the sRGB image: a 31% channel-mean error on the Cornell box).
TEST(Combination, InverseVarianceResolvesInTheOutputColourSpace) {
  Film it(1, 1);
  ImageAccumulator acc(1, 1);
  const RGB colour = srgb_to_working(RGB(0.9f, 0.1f, 0.05f));
  for (int k = 0; k < 2; ++k) {
    it.clear();
    for (uint32_t s = 0; s < 2; ++s) {
      it.add_weight(0, s, 1.0f);
      it.splat(0, s, colour * (s ? 1.2f : 0.8f));  // a known, non-zero variance
    }
    acc.fold(it);
  }
  ImageBuffer equal = acc.resolve(Combination::Equal), iv = acc.resolve(Combination::InverseVariance);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(equal.data[size_t(c)], RGB(0.9f, 0.1f, 0.05f)[c], 1e-5f) << c;
    EXPECT_NEAR(iv.data[size_t(c)], equal.data[size_t(c)], 1e-5f) << c;
  }
}
