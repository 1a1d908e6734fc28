// Iteration schedules, checkpoint skipping, the between-iteration task order
// and the combination of per-iteration images.
#include "core/color.h"
#include "core/log.h"
#include "scheduler/combine.h"
#include "scheduler/schedule.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

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

// Once nothing learns between iterations, the rest of a render goes on in the
// iterations the regular schedule has from there, not in guiding's 16-spp ones.
TEST(Schedule, SwitchedScheduleIsTheRegularOneFromThatPoint) {
  const std::vector<int> guiding = make_schedule(guiding_schedule(), 1024);
  // After iteration 13 (54 spp): the regular schedule's iteration 32..64 cut
  // at 54 is 10 spp, below its first size, so it joins the next (64..128).
  std::vector<int> expect(guiding.begin(), guiding.begin() + 13);
  expect.insert(expect.end(), {74, 128, 256, 256, 256});
  const std::vector<int> switched = switch_schedule(guiding, 13, regular_schedule());
  EXPECT_EQ(switched, expect);
  EXPECT_EQ(cumulative_spp(switched).back(), 1024);
  // At 38 spp (iteration 12): 26 spp to 64, then on as the regular schedule.
  std::vector<int> at38(guiding.begin(), guiding.begin() + 12);
  at38.insert(at38.end(), {26, 64, 128, 256, 256, 256});
  EXPECT_EQ(switch_schedule(guiding, 12, regular_schedule()), at38);
  // From the start it is the regular schedule; past the end, nothing changes.
  EXPECT_EQ(switch_schedule(guiding, 0, regular_schedule()), make_schedule(regular_schedule(), 1024));
  EXPECT_EQ(switch_schedule(guiding, int(guiding.size()), regular_schedule()), guiding);
  // A short render: what is left is one iteration.
  EXPECT_EQ(switch_schedule({1, 1, 2, 4}, 2, regular_schedule()), (std::vector<int>{1, 1, 6}));
}

// A time limit's last iteration is cut to what the time left fits, the rest
// of its samples after it: the total stays, so a checkpoint's schedule still
// follows the plan.
TEST(Schedule, TheIterationATimeLimitEndsInIsCutToWhatFits) {
  const std::vector<int> sizes{16, 16, 32, 64, 128, 256};
  EXPECT_EQ(fit_iteration(sizes, 5, 3.3, 0.02), (std::vector<int>{16, 16, 32, 64, 128, 165, 91}));
  EXPECT_EQ(fit_iteration(sizes, 5, 10.0, 0.02), sizes);  // it fits
  EXPECT_EQ(fit_iteration(sizes, 2, 0.001, 0.02), (std::vector<int>{16, 16, 1, 31, 64, 128, 256}));  // at least 1
  EXPECT_EQ(fit_iteration(sizes, 2, -1.0, 0.02), (std::vector<int>{16, 16, 1, 31, 64, 128, 256}));
  EXPECT_EQ(fit_iteration(sizes, 5, 1.0, 0.0), sizes);  // no pace known yet
  EXPECT_EQ(fit_iteration(sizes, 6, 1.0, 0.02), sizes);  // past the end
  EXPECT_EQ(cumulative_spp(fit_iteration(sizes, 4, 1.0, 0.02)).back(), cumulative_spp(sizes).back());
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
    f.splat(0, s, RGB(v), kEventEmission);
  }
}

// A synthetic iteration of `n` spp (n even) on a W x H grey image whose true
// value is `truth`: every sample has weight 1 and value truth + sigma * z.
// Antithetic (z = +1 on even samples, -1 on odd): every pixel's half-buffer
// variance is exactly sigma^2 / n, and the pixel exact.  Otherwise z is
// standard normal from `rng`.
constexpr int kW = 48, kH = 32;
constexpr float kTruth = 0.5f;

void synthetic_iteration(Film& f, uint32_t spp_begin, uint32_t n, float sigma, std::mt19937* rng) {
  f.clear();
  std::normal_distribution<float> normal;
  for (uint32_t p = 0; p < f.pixel_count(); ++p)
    for (uint32_t s = spp_begin; s < spp_begin + n; ++s) {
      float z = rng ? normal(*rng) : (s % 2 ? -1.0f : 1.0f);
      f.add_weight(p, s, 1.0f);
      f.splat(p, s, RGB(kTruth + sigma * z), kEventEmission);
    }
}

// Folds iterations of the given sizes and per-sample standard deviations;
// from the iteration that begins at `settled` on, fold is told so.
void accumulate(ImageAccumulator& acc, const std::vector<uint32_t>& sizes, const std::vector<float>& sigmas,
                std::mt19937* rng, uint32_t settled = std::numeric_limits<uint32_t>::max()) {
  Film it(kW, kH);
  uint32_t begin = 0;
  for (size_t k = 0; k < sizes.size(); ++k) {
    synthetic_iteration(it, begin, sizes[k], sigmas[k], rng);
    acc.fold(it, begin, begin + sizes[k], begin >= settled ? settled : std::numeric_limits<uint32_t>::max());
    begin += sizes[k];
  }
}

// Two accumulators folding the very same samples (a trial's seed).
void accumulate_both(ImageAccumulator& a, ImageAccumulator& b, const std::vector<uint32_t>& sizes,
                     const std::vector<float>& sigmas, uint32_t seed,
                     uint32_t b_settled = std::numeric_limits<uint32_t>::max()) {
  std::mt19937 rng_a(seed), rng_b(seed);
  accumulate(a, sizes, sigmas, &rng_a);
  accumulate(b, sizes, sigmas, &rng_b, b_settled);
}

ImageBuffer equal_image(const ImageAccumulator& acc) { return resolve_film(acc.total); }

double mse_against_truth(const ImageBuffer& img) {
  double sum = 0.0;
  for (size_t i = 0; i < img.pixel_count(); ++i) {
    double d = img.data[i * img.channels.size()] - working_to_srgb(RGB(kTruth)).x;
    sum += d * d;
  }
  return sum / double(img.pixel_count());
}

double max_abs_difference(const ImageBuffer& a, const ImageBuffer& b) {
  double worst = 0.0;
  for (size_t i = 0; i < a.data.size(); ++i) worst = std::max(worst, double(std::abs(a.data[i] - b.data[i])));
  return worst;
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

// The verdict statistic of --guiding-auto on a synthetic pair: the "guided"
// iteration has half the noise of the "unguided" one but a firefly (one
// sample of 200 where the pixel is 0.5) in 0.5% of its pixels, as guiding's
// rare high-weight paths are.  The robust figure (1% trimmed) calls it better,
// the full one worse, as relMSE would.  The pixel's mean comes from the
// iterations before: with the iteration's own (the firefly pulls it to ~13),
// a firefly pixel's figure stays near the spp and the full figure hides it.
TEST(Combination, FullRelativeVarianceSeesFirefliesTheRobustOneLeavesOut) {
  std::mt19937 rng(7);
  Film prior(kW, kH), unguided(kW, kH), guided(kW, kH);
  synthetic_iteration(prior, 0, 64, 0.2f, nullptr);  // antithetic: every pixel exactly kTruth
  synthetic_iteration(unguided, 64, 16, 0.2f, &rng);
  synthetic_iteration(guided, 80, 16, 0.1f, &rng);
  const uint32_t n = guided.pixel_count(), fireflies = n / 200;
  for (uint32_t k = 0; k < fireflies; ++k) {
    const uint32_t p = k * 197 % n;
    guided.splat(p, 80, RGB(200.0f - kTruth), kEventEmission);  // sample 80 of pixel p: kTruth + noise + 199.5
  }
  const RelativeVariance u = relative_variance(unguided, half_buffer_variance(unguided), &prior);
  const RelativeVariance g = relative_variance(guided, half_buffer_variance(guided), &prior);
  ASSERT_TRUE(u.known() && g.known());
  EXPECT_LT(g.robust, 0.5 * u.robust);  // a quarter of the variance where there is no firefly
  EXPECT_GT(g.full, 10.0 * u.full);     // the fireflies dominate what relMSE sees
  EXPECT_NEAR(u.full, 0.04 / 0.26, 0.02);  // sigma^2 / (0.5^2 + 0.01)
  // Without the prior, each firefly pixel's figure is ~15 and the full figure
  // would call the guided iteration better.
  const RelativeVariance own = relative_variance(guided, half_buffer_variance(guided));
  EXPECT_LT(own.full, u.full);
  // Too few pixels with two samples: unknown.
  Film one(kW, kH);
  synthetic_iteration(one, 0, 1, 0.2f, &rng);
  EXPECT_FALSE(relative_variance(one, half_buffer_variance(one), &prior).known());
}

TEST(Combination, EqualWeightingSumsEverySampleAndKeepsNoIterationImages) {
  Film it(1, 1);
  ImageAccumulator acc(1, 1);
  set_halves(it, 1.0f, 3.0f);
  acc.fold(it, 0, 2);
  set_halves(it, 3.5f, 4.5f);
  acc.fold(it, 2, 4);
  EXPECT_FLOAT_EQ(acc.resolve().data[0], 3.0f);
  EXPECT_TRUE(acc.runs.empty());
  EXPECT_EQ(acc.choice().used, Combination::Equal);
  EXPECT_EQ(parse_combination("inverse-variance"), Combination::InverseVariance);
  EXPECT_THROW(parse_combination("best"), Error);
}

// (a) Iterations of equal per-sample variance get equal weights per sample:
// the weighted image is the equal one, whatever the iteration sizes.
TEST(Combination, EqualPerSampleVarianceGivesTheEqualWeightImage) {
  const std::vector<uint32_t> sizes = {2, 2, 4, 8, 16, 16};
  for (uint32_t window : {0u, 48u}) {
    SCOPED_TRACE(window);
    ImageAccumulator acc(kW, kH, Combination::InverseVariance, window);
    accumulate(acc, sizes, std::vector<float>(sizes.size(), 0.3f), nullptr);
    EXPECT_LT(max_abs_difference(acc.resolve(), equal_image(acc)), 1e-6);
  }
  // With noise drawn at random and a window of the last 32 of 48 spp, the
  // weighted image has fewer samples at the same per-sample variance: equal
  // weights are used.
  std::mt19937 rng(7);
  ImageAccumulator acc(kW, kH, Combination::InverseVariance, 32);
  accumulate(acc, sizes, std::vector<float>(sizes.size(), 0.3f), &rng);
  CombinationChoice c = acc.choice();
  EXPECT_EQ(c.used, Combination::Equal) << c.why;
  EXPECT_GT(c.weighted_variance, 1.25 * c.equal_variance);  // 48 / 32 spp: 1.5 expected
  EXPECT_EQ(max_abs_difference(acc.resolve(), equal_image(acc)), 0.0);
}

// (b) Later iterations much less noisy (guiding that has learned): they are
// weighted, and the image is closer to the truth than with equal weights.
TEST(Combination, MuchBetterLaterIterationsAreWeighted) {
  std::mt19937 rng(11);
  ImageAccumulator acc(kW, kH, Combination::InverseVariance, 0);
  accumulate(acc, {16, 16, 16, 16, 16, 16, 16, 16}, {1, 1, 1, 1, 0.05f, 0.05f, 0.05f, 0.05f}, &rng);
  CombinationChoice c = acc.choice();
  ASSERT_EQ(c.used, Combination::InverseVariance) << c.why;
  EXPECT_EQ(c.window_begin, 0u);  // every iteration: the noisy ones with 1/400 of the weight
  EXPECT_EQ(c.window_end, 128u);
  EXPECT_LT(c.weighted_variance, 0.1 * c.equal_variance);
  const double weighted = mse_against_truth(acc.resolve()), equal = mse_against_truth(equal_image(acc));
  EXPECT_LT(weighted, 0.1 * equal);
  // Its variance estimate is right to within its own noise.
  EXPECT_NEAR(weighted / c.weighted_variance, 1.0, 0.2);
  EXPECT_NEAR(equal / c.equal_variance, 1.0, 0.2);
}

// (c) Never worse than equal weights: what resolve() uses is never estimated
// noisier than the equal image, and is no noisier in fact, over schedules and
// variance sequences of every shape (better, worse, mixed, noisy at the end).
TEST(Combination, NeverWorseThanEqualWeights) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> sigma(0.05f, 2.0f);
  const std::vector<uint32_t> sizes = {4, 4, 8, 8, 16, 16, 16, 16, 16};
  int weighted = 0;
  for (int trial = 0; trial < 12; ++trial) {
    SCOPED_TRACE(trial);
    std::vector<float> sigmas(sizes.size());
    for (float& s : sigmas) s = sigma(rng);
    ImageAccumulator acc(kW, kH, Combination::InverseVariance, trial % 2 ? 0 : 64);
    accumulate(acc, sizes, sigmas, &rng);
    CombinationChoice c = acc.choice();
    ASSERT_GE(c.equal_variance, 0.0);
    if (c.used == Combination::InverseVariance) {
      ++weighted;
      EXPECT_LT(c.weighted_variance, c.equal_variance);
    }
    EXPECT_LE(mse_against_truth(acc.resolve()), 1.1 * mse_against_truth(equal_image(acc)));
  }
  EXPECT_GT(weighted, 0);  // the cases include some the weighting wins
}

// A guided render's field froze at 32 spp of 256: a window of the last half
// would weigh only 128 of the 224 settled samples; told where the estimator
// settled, the window keeps all of them and the image is less noisy.
TEST(Combination, EverySampleSinceTheEstimatorSettledStaysInTheWindow) {
  const std::vector<uint32_t> sizes = {8, 8, 16, 32, 32, 32, 32, 32, 32, 32};
  const std::vector<float> sigmas = {2, 2, 2, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f};
  double settled_mse = 0.0, half_mse = 0.0;
  for (int trial = 0; trial < 8; ++trial) {
    ImageAccumulator half(kW, kH, Combination::InverseVariance, 128),
        settled(kW, kH, Combination::InverseVariance, 128);
    accumulate_both(half, settled, sizes, sigmas, uint32_t(100 + trial), 32);
    ASSERT_EQ(half.choice().window_begin, 128u);
    const CombinationChoice c = settled.choice();
    ASSERT_EQ(c.used, Combination::InverseVariance) << c.why;
    EXPECT_LE(c.window_begin, 32u);
    EXPECT_EQ(c.window_end, 256u);
    settled_mse += mse_against_truth(settled.resolve());
    half_mse += mse_against_truth(half.resolve());
  }
  // 224 settled samples against 128: about 0.57x the variance.
  EXPECT_LT(settled_mse, 0.75 * half_mse);
}

// The default weighs every iteration: a learning phase whose samples are
// noisier (here 2x, then 1.4x the standard deviation of the settled ones)
// adds to the image with its lower weight.  Equal weights let its noise in
// at full weight; a window of the last half drops its samples and those of
// the first settled iteration, and is then estimated noisier than equal weights.
TEST(Combination, TheDefaultWeighsTheLearningIterationsToo) {
  const std::vector<uint32_t> sizes = {8, 8, 16, 32, 64, 64, 64};
  const std::vector<float> sigmas = {1.0f, 1.0f, 0.7f, 0.7f, 0.5f, 0.5f, 0.5f};
  double every_mse = 0.0, equal_mse = 0.0;
  for (int trial = 0; trial < 8; ++trial) {
    ImageAccumulator every(kW, kH, Combination::InverseVariance, 0),
        half(kW, kH, Combination::InverseVariance, 128);
    accumulate_both(every, half, sizes, sigmas, uint32_t(200 + trial));
    const CombinationChoice c = every.choice(), h = half.choice();
    ASSERT_EQ(c.used, Combination::InverseVariance) << c.why;
    EXPECT_EQ(c.window_begin, 0u);
    EXPECT_EQ(h.window_begin, 128u);
    EXPECT_GT(h.weighted_variance, h.equal_variance);  // 128 settled samples: 0.00195 against 0.00134
    every_mse += mse_against_truth(every.resolve());
    equal_mse += mse_against_truth(equal_image(every));
  }
  // Per pixel, equal weights: (16 x 1 + 48 x 0.49 + 192 x 0.25) / 256^2 = 0.00134;
  // inverse variance: 0.25 / (16 / 4 + 48 / 1.96 + 192) = 0.00113, 0.85x.
  EXPECT_LT(every_mse, 0.9 * equal_mse);
}

// However many iterations, the weighting keeps at most kMaxBlocks runs, all in the window.
TEST(Combination, MemoryIsBoundedAndTheWindowSlides) {
  std::mt19937 rng(5);
  ImageAccumulator acc(kW, kH, Combination::InverseVariance, 80);
  Film it(kW, kH);
  uint32_t begin = 0;
  for (int k = 0; k < 30; ++k, begin += 8) {
    synthetic_iteration(it, begin, 8, 0.2f, &rng);
    acc.fold(it, begin, begin + 8);
    ASSERT_LE(acc.runs.size(), ImageAccumulator::kMaxBlocks);
    EXPECT_GT(acc.runs.front().spp_end, begin + 8 > 80 ? begin + 8 - 80 : 0);  // inside the window
    EXPECT_EQ(acc.runs.back().spp_end, begin + 8);
  }
  // The runs cover at least the window and are contiguous.
  EXPECT_LE(acc.runs.front().spp_begin, begin - 80);
  for (size_t k = 1; k < acc.runs.size(); ++k) EXPECT_EQ(acc.runs[k].spp_begin, acc.runs[k - 1].spp_end);
}

// An iteration a time limit stopped reached only the first pixels: the
// others get nothing from it (not black), and weighting stays unbiased.
TEST(Combination, APartIterationWeighsOnlyWhereItHasSamples) {
  std::mt19937 rng(9);
  ImageAccumulator acc(kW, kH, Combination::InverseVariance, 0);
  Film part(kW, kH);
  synthetic_iteration(part, 0, 16, 1.0f, &rng);
  acc.fold(part, 0, 16);
  synthetic_iteration(part, 16, 16, 0.05f, &rng);
  const size_t reached = part.pixel_count() / 3;
  for (size_t p = reached; p < part.pixel_count(); ++p)
    for (size_t q = 0; q < Film::kPlaneCount; ++q) (*part.plane(q))[p] = 0.0f;
  acc.fold(part, 16, 32);
  ImageBuffer img = acc.resolve();
  const float truth = working_to_srgb(RGB(kTruth)).x;
  double far = 0.0;
  for (size_t p = reached; p < img.pixel_count(); ++p) far += img.data[p * img.channels.size()];
  EXPECT_NEAR(far / double(img.pixel_count() - reached), truth, 0.05);
}

// The film holds the working colour space (Rec.2020) and the output is linear
// sRGB: iterations of one saturated colour combine to that colour whichever
// combination is asked for (inverse-variance once mixed Rec.2020 values into
// the sRGB image: a 31% channel-mean error on the Cornell box).
TEST(Combination, InverseVarianceResolvesInTheOutputColourSpace) {
  Film it(1, 1);
  ImageAccumulator acc(1, 1, Combination::InverseVariance, 0);
  const RGB colour = srgb_to_working(RGB(0.9f, 0.1f, 0.05f));
  for (int k = 0; k < 2; ++k) {
    it.clear();
    for (uint32_t s = 0; s < 2; ++s) {
      it.add_weight(0, s, 1.0f);
      it.splat(0, s, colour * (s ? 1.2f : 0.8f), kEventEmission);  // a known, non-zero variance
    }
    acc.fold(it, uint32_t(2 * k), uint32_t(2 * k + 2));
  }
  ImageBuffer equal = resolve_film(acc.total), iv = acc.resolve();
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(equal.data[size_t(c)], RGB(0.9f, 0.1f, 0.05f)[c], 1e-5f) << c;
    EXPECT_NEAR(iv.data[size_t(c)], equal.data[size_t(c)], 1e-5f) << c;
  }
}

// An iteration of a few spp (a time limit's last) is in the equal image only:
// its variance estimate is too noisy to weigh it by.  Here its estimate is
// 2500x lower per sample, as one that missed an image's rare bright paths
// would be, and it would otherwise outweigh the 64 spp before it.
TEST(Combination, AFewSppIterationIsNotWeighted) {
  ImageAccumulator acc(kW, kH, Combination::InverseVariance, 0);
  accumulate(acc, {32, 32, 2}, {0.5f, 0.5f, 0.01f}, nullptr);
  EXPECT_EQ(acc.skipped, 1u);
  const CombinationChoice c = acc.choice();
  EXPECT_EQ(c.window_begin, 0u);
  EXPECT_EQ(c.window_end, 64u);
}

// The iterations since the estimator settled are one estimator and share one
// weight.  Here they are heavy-tailed, as a guided render's are: a sample is
// kTruth / p with probability p, else 0, so an iteration's estimated
// variance grows with the rare samples it happened to get, and so does its
// image.  Weighing each by its own estimate favours the darker ones (the
// weighted mean is about a harmonic mean of the iterations': ~2% low at ~48
// rare samples an iteration).  Pooled, they weigh alike: with nothing
// learning before them, the weighted image is the equal one.
TEST(Combination, SettledIterationsShareOneWeightAndStayUnbiased) {
  constexpr float p = 1.0f / 512.0f;
  constexpr uint32_t kIterations = 8, kSize = 16;
  constexpr int kTrials = 20;
  double each_bias = 0.0;  // image mean against the equal image of the same samples
  int each_weighted = 0;
  for (int trial = 0; trial < kTrials; ++trial) {
    std::mt19937 rng(uint32_t(700 + trial));
    std::uniform_real_distribution<float> u01;
    ImageAccumulator pooled(kW, kH, Combination::InverseVariance, 0), each(kW, kH, Combination::InverseVariance, 0);
    Film it(kW, kH);
    for (uint32_t begin = 0; begin < kIterations * kSize; begin += kSize) {
      it.clear();
      for (uint32_t px = 0; px < it.pixel_count(); ++px)
        for (uint32_t s = begin; s < begin + kSize; ++s) {
          it.add_weight(px, s, 1.0f);
          it.splat(px, s, RGB(u01(rng) < p ? kTruth / p : 0.0f), kEventEmission);
        }
      pooled.fold(it, begin, begin + kSize, 0);
      each.fold(it, begin, begin + kSize);
    }
    EXPECT_TRUE(pooled.runs.empty() && each.settled.empty());
    EXPECT_EQ(pooled.settled.spp_end, kIterations * kSize);
    const ImageBuffer equal = equal_image(pooled);
    EXPECT_LT(max_abs_difference(pooled.resolve(), equal), 1e-5);
    auto image_mean = [](const ImageBuffer& img) {
      double sum = 0.0;
      for (size_t i = 0; i < img.pixel_count(); ++i) sum += img.data[i * img.channels.size()];
      return sum / double(img.pixel_count());
    };
    if (each.choice().used == Combination::InverseVariance) ++each_weighted;
    each_bias += (image_mean(each.resolve()) / image_mean(equal) - 1.0) / kTrials;
  }
  EXPECT_GT(each_weighted, kTrials / 2);  // fooled by the same noise into weighting (14 of 20)
  EXPECT_LT(each_bias, -0.01);  // -0.0146
}

// Settled iterations pool whatever their size: a time limit's last, short
// iteration joins them instead of being left out of the weighted image.
TEST(Combination, AShortSettledIterationJoinsThePool) {
  ImageAccumulator acc(kW, kH, Combination::InverseVariance, 0);
  std::mt19937 rng(3);
  accumulate(acc, {16, 16, 32, 2}, {2.0f, 2.0f, 0.5f, 0.5f}, &rng, 32);
  EXPECT_EQ(acc.skipped, 0u);
  EXPECT_EQ(acc.runs.size(), 2u);
  const CombinationChoice c = acc.choice();
  ASSERT_EQ(c.used, Combination::InverseVariance) << c.why;
  EXPECT_EQ(c.pooled_begin, 32u);
  EXPECT_EQ(c.pooled_end, 66u);
  EXPECT_EQ(c.window_end, 66u);
}

// A settled run without noise (a frozen estimator that sees a constant, as a
// guided render of a lit white wall nearly does) has a pooled variance of 0:
// nothing to weigh it by.  It stays out of the weighted image, which then
// holds only the noisy learning iterations and so cannot beat the equal image
// of every sample: the choice falls to equal weights, never to an image that
// dropped the settled samples.
TEST(Combination, ANoiselessSettledRunLeavesTheEqualImage) {
  ImageAccumulator acc(kW, kH, Combination::InverseVariance, 0);
  std::mt19937 rng(5);
  accumulate(acc, {16, 16, 32, 32}, {2.0f, 2.0f, 0.0f, 0.0f}, &rng, 32);
  EXPECT_EQ(acc.runs.size(), 2u);
  EXPECT_EQ(acc.settled.spp_end, 96u);
  const CombinationChoice c = acc.choice();
  EXPECT_EQ(c.used, Combination::Equal) << c.why;
  EXPECT_EQ(c.pooled_end, 0u);  // the noiseless run was not pooled
  EXPECT_EQ(max_abs_difference(acc.resolve(), equal_image(acc)), 0.0);

  // Noiseless from the first sample: no iteration has a variance estimate.
  ImageAccumulator flat(kW, kH, Combination::InverseVariance, 0);
  accumulate(flat, {16, 16}, {0.0f, 0.0f}, &rng, 0);
  EXPECT_EQ(flat.choice().used, Combination::Equal);
  EXPECT_EQ(max_abs_difference(flat.resolve(), equal_image(flat)), 0.0);
}
