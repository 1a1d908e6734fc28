// The wavefront's parts on their own: the radix sort, the queue tables, the
// sample-dimension table, the pool sizes, the camera samples' order and the
// film.
#include "core/radix_sort.h"
#include "wavefront/camera_samples.h"
#include "wavefront/engine.h"
#include "wavefront/engine_impl.h"
#include "wavefront/film.h"
#include "wavefront/path_state.h"
#include "wavefront/queues.h"
#include "wavefront/sample_dims.h"

#include <gtest/gtest.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <random>
#include <set>

namespace theia {
namespace {

std::vector<SortPair> random_pairs(size_t n, uint64_t key_mask, uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<SortPair> pairs(n);
  for (size_t i = 0; i < n; ++i) pairs[i] = SortPair{rng() & key_mask, uint32_t(i)};
  return pairs;
}

void expect_stable_sorted(std::vector<SortPair> pairs, int key_bits) {
  std::vector<SortPair> expected = pairs, scratch;
  std::stable_sort(expected.begin(), expected.end(), [](const SortPair& a, const SortPair& b) { return a.key < b.key; });
  radix_sort(pairs, scratch, key_bits);
  ASSERT_EQ(pairs.size(), expected.size());
  for (size_t i = 0; i < pairs.size(); ++i) {
    ASSERT_EQ(pairs[i].key, expected[i].key) << "at " << i;
    ASSERT_EQ(pairs[i].index, expected[i].index) << "at " << i << ": the sort must be stable";
  }
}

TEST(RadixSort, MatchesStableSortSerialAndParallel) {
  // 1000 pairs take the serial path, 300k the chunked parallel one; few
  // distinct keys make ties, where stability shows.
  for (size_t n : {size_t(1), size_t(2), size_t(1000), size_t(300000)}) {
    expect_stable_sorted(random_pairs(n, ~uint64_t(0), 1), 64);
    expect_stable_sorted(random_pairs(n, 0xff, 2), 64);
    expect_stable_sorted(random_pairs(n, (uint64_t(1) << 42) - 1, 3), 42);
  }
}

TEST(RadixSort, SortsOnlyTheLowKeyBits) {
  std::vector<SortPair> pairs = {{(uint64_t(1) << 50) | 2, 0}, {1, 1}, {uint64_t(1) << 50, 2}}, scratch;
  radix_sort(pairs, scratch, 22);
  // The high bit is ignored: keys 0 (index 2), 1 and 2 (index 0) in that order.
  EXPECT_EQ(pairs[0].index, 2u);
  EXPECT_EQ(pairs[1].index, 1u);
  EXPECT_EQ(pairs[2].index, 0u);
}

TEST(RadixSort, MortonCodeInterleavesAxes) {
  EXPECT_EQ(morton3(0, 0, 0), 0u);
  EXPECT_EQ(morton3(1, 1, 1), (1u << 30) - 1);
  EXPECT_EQ(morton3(0.5f, 0, 0), 1u << 29);  // x's top bit is the code's top bit
  EXPECT_EQ(morton3(0, 0, 0.5f), 1u << 27);
}

Ray ray_at(float x) {
  Ray r;
  r.o = vec3(x, 0, 0);
  r.d = vec3(0, 0, 1);
  return r;
}

TEST(Queues, AppendGatherAndClearEveryFieldThatIsPresent) {
  ShadowQueue a, b, scratch;
  for (int i = 0; i < 3; ++i) {
    a.rays.push_back(ray_at(float(i)));
    a.contribution.push_back(RGB(float(i)));
    a.pixel.push_back(uint32_t(10 + i));
    a.sample.push_back(uint32_t(i));
    a.vertex.push_back(kNoVertex);
  }
  b = a;
  queue_append(a, b);
  EXPECT_EQ(a.size(), 6u);
  EXPECT_EQ(a.pixel.size(), 6u);
  // The feature fields were empty on both sides and stay empty.
  EXPECT_TRUE(a.mis_weight.empty());
  EXPECT_TRUE(a.skip.empty());

  const std::vector<uint32_t> order = {5, 0, 4, 1, 3, 2};
  queue_gather(a, order, scratch);
  for (size_t k = 0; k < order.size(); ++k) {
    uint32_t i = order[k] % 3;
    EXPECT_EQ(a.rays[k].o.x, float(i));
    EXPECT_EQ(a.contribution[k].y, float(i));
    EXPECT_EQ(a.pixel[k], 10 + i);
  }
  EXPECT_TRUE(a.mis_weight.empty());

  // A range [1, 3) of b: its items in order, every present field alike.
  ShadowQueue c;
  queue_append(c, b, 1, 3);
  ASSERT_EQ(c.size(), 2u);
  for (uint32_t k = 0; k < 2; ++k) {
    EXPECT_EQ(c.rays[k].o.x, float(k + 1));
    EXPECT_EQ(c.contribution[k].y, float(k + 1));
    EXPECT_EQ(c.pixel[k], 11 + k);
    EXPECT_EQ(c.vertex[k], kNoVertex);
  }
  EXPECT_TRUE(c.mis_weight.empty());

  queue_clear(a);
  EXPECT_EQ(a.size(), 0u);
  EXPECT_TRUE(a.pixel.empty());
}

TEST(Queues, BytesFollowTheTable) {
  EXPECT_EQ(RayQueue::kItemBytes, sizeof(Ray) + sizeof(uint32_t));
  EXPECT_EQ(ShadowQueue::kItemBytes,
            sizeof(Ray) + sizeof(RGB) + 3 * sizeof(uint32_t) + sizeof(float) + sizeof(SampledLight) + sizeof(PrimRef) +
                sizeof(int32_t) + sizeof(uint8_t) + sizeof(DeferredNeeMIS));
  ShadowQueue q;
  q.rays.reserve(100);
  q.pixel.reserve(100);
  EXPECT_GE(queue_bytes(q), 100 * (sizeof(Ray) + sizeof(uint32_t)));
  EXPECT_LT(queue_bytes(q), 100 * (sizeof(Ray) + sizeof(uint32_t)) + 4096);
}

TEST(PathState, ColdTablesExistOnlyForFeaturesThatAreOn) {
  PathStatePool plain(1000, PathFeatures{});
  PathStatePool curves(1000, PathFeatures{.curves = true});
  EXPECT_TRUE(plain.curve_skip.empty());
  EXPECT_EQ(curves.curve_skip.size(), 1000u);
  EXPECT_EQ(curves.memory_bytes() - plain.memory_bytes(), 1000 * sizeof(PrimRef));
  // Media: the path's medium and its stratified-flight depth, nothing else.
  PathStatePool media(1000, PathFeatures{.media = true});
  EXPECT_TRUE(plain.medium.empty() && plain.flight_depth.empty());
  EXPECT_EQ(media.memory_bytes() - plain.memory_bytes(), 1000 * (sizeof(int32_t) + sizeof(uint16_t)));
  // Slots are handed out low first.
  EXPECT_EQ(plain.free_slots.back(), 0u);
  EXPECT_EQ(plain.live(), 0u);
}

TEST(SampleDims, SurfacePageKeepsItsLayoutAndNothingOverlaps) {
  // The layout every render has drawn since the engine was written: camera
  // 0..3, bounce d at 4 + 8d (light point, choice, primitive, direction,
  // lobe, roulette).  Changing it changes every image.
  for (uint32_t d : {0u, 1u, 7u}) {
    BounceDims b = bounce_dims(d);
    EXPECT_EQ(b.light_point, 4 + 8 * d);
    EXPECT_EQ(b.light_choice, 6 + 8 * d);
    EXPECT_EQ(b.light_prim, 7 + 8 * d);
    EXPECT_EQ(b.bsdf_dir, 8 + 8 * d);
    EXPECT_EQ(b.bsdf_lobe, 10 + 8 * d);
    EXPECT_EQ(b.roulette, 11 + 8 * d);
  }
  std::set<uint32_t> used = {CameraDims::film, CameraDims::film + 1, CameraDims::lens, CameraDims::lens + 1};
  for (uint32_t d = 0; d < 200; ++d) {
    BounceDims b = bounce_dims(d);
    for (auto [dim, width] : {std::pair{b.light_point, 2u}, {b.light_choice, 1u}, {b.light_prim, 1u},
                              {b.bsdf_dir, 2u}, {b.bsdf_lobe, 1u}, {b.roulette, 1u}})
      for (uint32_t k = 0; k < width; ++k) EXPECT_TRUE(used.insert(dim + k).second) << "dimension " << dim + k;
    EXPECT_EQ(b.light_point % 2, 0u);  // 2D slots are jointly stratified pairs
    EXPECT_EQ(b.bsdf_dir % 2, 0u);
  }
}

TEST(EngineSizes, FollowTheFrameUnlessSet) {
  EngineOptions o;
  // Unsorted, a lane holds kUnsortedLanePaths at any frame size, in batches
  // of 1024 rays: continuation rays over its six bins fill a batch.
  for (uint64_t pixels : {uint64_t(64 * 64), uint64_t(1920 * 1080)}) {
    EngineSizes s = engine_sizes(o, pixels, 2);
    EXPECT_EQ(s.lanes, 2u);
    EXPECT_EQ(s.lane_paths(), kUnsortedLanePaths);
    EXPECT_EQ(s.batch_size, 1024u);
    EXPECT_GE(s.lane_paths(), s.batch_size * 6);
  }
  EXPECT_EQ(engine_sizes(o, 64 * 64, 1).lanes, 1u);
  EXPECT_EQ(engine_sizes(o, 64 * 64, 64).lane_paths(), kUnsortedLanePaths);
  // Sorted, the pool follows the frame, and batches are an eighth of a
  // lane's pool, so that a production frame's sort has rays to order.
  o.sort = true;
  EngineSizes small = engine_sizes(o, 64 * 64, 2), big = engine_sizes(o, 1920 * 1080, 2);
  EXPECT_LT(small.max_paths, big.max_paths);
  EXPECT_EQ(big.max_paths, size_t(1) << 19);
  EXPECT_GE(small.max_paths, size_t(2) << 14);  // 2^14 paths a lane
  EXPECT_EQ(small.lane_paths(), small.max_paths / 2);
  EXPECT_EQ(big.batch_size, big.lane_paths() / 8);
  EXPECT_EQ(small.batch_size, std::max<size_t>(small.lane_paths() / 8, 1024));
  // A farm node's 64 threads: the floor of 2^14 paths a lane holds for any
  // frame (past 32 threads it was clamped below it: 2^13 a lane at 64).
  for (uint64_t pixels : {uint64_t(64 * 64), uint64_t(1920 * 1080)}) {
    EngineSizes many = engine_sizes(o, pixels, 64);
    EXPECT_EQ(many.lanes, 64u);
    EXPECT_EQ(many.lane_paths(), size_t(1) << 14);
  }
  o.sort = false;
  o.max_paths = 12345;
  o.batch_size = 77;
  EngineSizes set = engine_sizes(o, 64 * 64, 2);
  EXPECT_EQ(set.max_paths, 12345u);
  EXPECT_EQ(set.batch_size, 77u);
  // Never a lane without a path.
  o.max_paths = 1;
  EXPECT_EQ(engine_sizes(o, 64 * 64, 2).lanes, 1u);
}

// The camera stage finds its first sample by division (or search) and steps
// to the next: every step must land where a walk started there would be,
// across pixels, and over adaptive ranges with pixels that have no samples.
TEST(CameraSamples, AWalkStepsToWhatEachSampleIsByItself) {
  auto same = [](const PixelSample& a, const PixelSample& b) {
    return a.pixel == b.pixel && a.sample == b.sample && a.alpha_only == b.alpha_only;
  };
  // The whole frame: pixel-sample order, samples [5, 8) of each pixel.
  {
    CameraSampleWalk walk(2, nullptr, 5, 3);
    for (uint64_t g = 2; g < 12; ++g, walk.step()) {
      EXPECT_EQ(walk->pixel, uint32_t(g / 3)) << g;
      EXPECT_EQ(walk->sample, 5 + uint32_t(g % 3)) << g;
      EXPECT_FALSE(walk->alpha_only);
    }
  }
  // Adaptive ranges: pixel p has samples [begin, begin + count), colour
  // below colour_end; pixels 1, 2 and 5 have none.
  SampleRanges ranges;
  ranges.begin = {4, 0, 0, 1, 7, 0};
  ranges.colour_end = {5, 0, 0, 3, 9, 0};
  ranges.offset = {0, 2, 2, 2, 5, 6, 6};
  const PixelSample expected[] = {{0, 4, false}, {0, 5, true}, {3, 1, false}, {3, 2, false}, {3, 3, true}, {4, 7, false}};
  for (uint64_t start = 0; start < 6; ++start) {
    CameraSampleWalk walk(start, &ranges, 0, 0);
    for (uint64_t g = start; g < 6; ++g, walk.step())
      EXPECT_TRUE(same(*walk, expected[g])) << "from " << start << " at " << g << ": pixel " << walk->pixel
                                            << " sample " << walk->sample;
    EXPECT_LT(walk->pixel, 6u) << "a walk past the last sample stays in the frame";
  }
}

// The camera stage draws a block of samples' film offsets at once, with one
// film pair per pixel: each must be what camera_filter_sample (which the
// caustic pass re-draws) gives that sample alone, across pixels, over
// adaptive ranges with empty pixels, and in blocks of any length.
TEST(CameraSamples, ABlockOfFilmDrawsIsEachSamplesOwn) {
  FilterParams params;  // pbrt-v4's default: a Gaussian of radius 1.5
  const Filter filter = make_filter(params);
  SampleRanges ranges;
  ranges.begin = {4, 0, 0, 1, 7, 0, 2};
  ranges.colour_end = {5, 0, 0, 3, 9, 0, 90};
  ranges.offset = {0, 2, 2, 2, 5, 6, 6, 106};
  for (const SampleRanges* r : {static_cast<const SampleRanges*>(nullptr), static_cast<const SampleRanges*>(&ranges)}) {
    const uint64_t total = r ? 106 : 300;  // the whole frame: samples [3, 40) of each pixel
    for (size_t block : {size_t(1), size_t(7), kFilmBlock}) {
      CameraSampleWalk walk(0, r, 3, 37);
      CameraFilmDraws draw(filter, 11, walk->pixel);
      std::array<PixelSample, kFilmBlock> samples;
      std::array<FilterSample, kFilmBlock> film;
      for (uint64_t g = 0; g < total; g += block) {
        const size_t m = size_t(std::min<uint64_t>(block, total - g));
        draw(walk, std::span(samples.data(), m), std::span(film.data(), m));
        for (size_t i = 0; i < m; ++i) {
          const FilterSample own = camera_filter_sample(filter, 11, samples[i].pixel, samples[i].sample);
          ASSERT_EQ(own.p, film[i].p) << "sample " << g + i << ", blocks of " << block;
          ASSERT_EQ(own.weight, film[i].weight) << "sample " << g + i << ", blocks of " << block;
        }
      }
    }
  }
}

// A camera sample's filter weight goes to the colour weights (the odd half
// only from odd samples) unless the sample is coverage-only, and to the alpha
// weight where it counts for alpha; the same with per-thread sums and without.
TEST(Film, ACameraSamplesWeightsGoWhereTheyCount) {
  for (bool thread_sums : {false, true}) {
    Film film(4, 1);
    if (thread_sums) film.use_thread_sums(1);
    film.add_weights(0, 3, 0.5f, true, true);   // odd, colour and alpha
    film.add_weights(1, 2, 0.25f, true, false); // even, past the alpha samples
    film.add_weights(2, 5, 2.0f, false, true);  // coverage only
    film.add_weights(3, 1, 8.0f, false, false); // neither: nothing
    if (thread_sums) film.flush();
    const float weight[] = {0.5f, 0.25f, 0.0f, 0.0f}, odd[] = {0.5f, 0.0f, 0.0f, 0.0f},
                alpha[] = {0.5f, 0.0f, 2.0f, 0.0f};
    for (int p = 0; p < 4; ++p) {
      EXPECT_EQ(film.weight[size_t(p)], weight[p]) << "pixel " << p << ", thread sums " << thread_sums;
      EXPECT_EQ(film.weight_odd[size_t(p)], odd[p]) << "pixel " << p << ", thread sums " << thread_sums;
      EXPECT_EQ(film.alpha_weight[size_t(p)], alpha[p]) << "pixel " << p << ", thread sums " << thread_sums;
    }
  }
}

TEST(Film, SplatsSumsHalfBuffersAndDropsNonFiniteSamples) {
  Film film(2, 1);
  film.add_weight(0, 0, 1.0f);
  film.add_weight(0, 1, 1.0f);
  film.splat(0, 0, RGB(1, 2, 3), kEventEmission);
  film.splat(0, 1, RGB(3, 2, 1), kEventEmission);
  film.splat(0, 1, RGB(std::numeric_limits<float>::infinity(), 0, 0), kEventEmission);
  film.splat(1, 0, RGB(std::numeric_limits<float>::quiet_NaN()), kEventEmission);
  EXPECT_EQ(film.dropped.load(), 2u);
  EXPECT_EQ(film.r[0], 4.0f);
  EXPECT_EQ(film.r_odd[0], 3.0f);  // sample 1 only
  EXPECT_EQ(film.weight_odd[0], 1.0f);
  EXPECT_EQ(film.r[1], 0.0f);
  ImageBuffer img = resolve_film(film);
  // Grey (2, 2, 2) in the working space is grey in the output's sRGB.
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(img.at(0, 0, c), 2.0f, 1e-5f);
  EXPECT_EQ(img.at(1, 0, 0), 0.0f);  // no weight: black, not NaN
}

// Without per-thread sums (a production frame, or --aov-events) the threads
// add into the planes under a lock per block of pixels: splats of whole
// numbers from every thread onto a few pixels, which share their locks, must
// all arrive, to the exact count (an unguarded += loses some here), and the
// event layers with them.
TEST(Film, LockedSplatsFromManyThreadsLoseNothing) {
  constexpr uint32_t kPixels = 2 * Film::kPixelsPerLock, kSplats = 400000;
  for (bool events : {false, true}) {
    Film film(int(kPixels), 1, events);
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, kSplats, 256), [&](const tbb::blocked_range<uint32_t>& r) {
      for (uint32_t k = r.begin(); k < r.end(); ++k) {
        const uint32_t px = k % kPixels, sample = k / kPixels;
        film.add_weight(px, sample, 1.0f);
        film.add_alpha_weight(px, 1.0f);
        film.splat(px, sample, RGB(1.0f, 2.0f, 3.0f), kEventGlossy);
        film.splat_first_hit(px, 1.0f, true, RGB(1.0f), vec3(1.0f), 1.0f);
      }
    });
    const float n = float(kSplats / kPixels), odd = float(kSplats / kPixels / 2);
    for (uint32_t px = 0; px < kPixels; ++px) {
      SCOPED_TRACE(events ? "event layers" : "beauty only");
      ASSERT_EQ(film.weight[px], n) << "pixel " << px;
      ASSERT_EQ(film.weight_odd[px], odd);
      ASSERT_EQ(film.alpha_weight[px], n);
      ASSERT_EQ(film.r[px], n);
      ASSERT_EQ(film.b[px], 3.0f * n);
      ASSERT_EQ(film.g_odd[px], 2.0f * odd);
      ASSERT_EQ(film.alpha[px], n);
      ASSERT_EQ(film.normal[2][px], n);
      ASSERT_EQ(film.depth[px], n);
      if (events) {
        ASSERT_EQ(film.events[kEventGlossy][1][px], 2.0f * n);
      }
    }
  }
}

// Splats from many threads into per-thread sums: after flush() every plane
// holds what locked adds into the planes give (up to summation order), a
// second flush adds nothing, clear() empties the sums too, and a film too
// large for them keeps the locked adds.
TEST(Film, PerThreadSumsEqualLockedAddsAfterFlush) {
  constexpr int kW = 40, kH = 30;
  Film locked(kW, kH), sharded(kW, kH);
  sharded.use_thread_sums(4);
  EXPECT_GT(sharded.memory_bytes(), locked.memory_bytes());
  auto splat_all = [](Film& f) {
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, 20000, 64), [&](const tbb::blocked_range<uint32_t>& r) {
      for (uint32_t k = r.begin(); k < r.end(); ++k) {
        const uint32_t px = (k * 7919u) % uint32_t(kW * kH), sample = k / 97u;
        const float v = 0.25f + float(k % 13);
        f.add_weight(px, sample, 0.5f);
        f.add_alpha_weight(px, 0.5f);
        f.splat(px, sample, RGB(v, 2.0f * v, 3.0f * v), kEventDiffuse);
        f.splat_first_hit(px, 0.5f, true, RGB(0.1f, 0.2f, 0.3f), vec3(0, 0, 1), v);
      }
    });
  };
  splat_all(locked);
  splat_all(sharded);
  sharded.flush();
  for (size_t i = 0; i < Film::kPlaneCount; ++i)
    for (size_t px = 0; px < locked.pixel_count(); ++px)
      ASSERT_NEAR((*sharded.plane(i))[px], (*locked.plane(i))[px], 1e-4f * std::abs((*locked.plane(i))[px]) + 1e-6f)
          << Film::plane_name(i) << " pixel " << px;
  const std::vector<float> r = sharded.r;
  sharded.flush();
  EXPECT_EQ(sharded.r, r);
  // A restored film's sums continue in this thread's own: one running sum.
  Film restored(kW, kH);
  restored.use_thread_sums(1);
  restored.r[3] = 1.0f;
  restored.continue_in_thread_sums();
  EXPECT_EQ(restored.r[3], 0.0f);
  restored.splat(3, 0, RGB(1e-8f), kEventEmission);
  restored.flush();
  EXPECT_EQ(restored.r[3], 1.0f + 1e-8f);  // 1 + 1e-8 rounds to 1, as an atomic add onto 1 would
  sharded.splat(0, 0, RGB(1.0f), kEventEmission);
  sharded.clear();
  sharded.flush();
  EXPECT_EQ(sharded.r[0], 0.0f);

  Film large(4096, 2048);
  large.use_thread_sums(2);
  const size_t locks = large.pixel_count() / Film::kPixelsPerLock;  // a byte each
  EXPECT_EQ(large.memory_bytes(), large.pixel_count() * Film::kPlaneCount * sizeof(float) + locks);
  large.splat(5, 0, RGB(1.0f), kEventEmission);
  EXPECT_EQ(large.r[5], 1.0f);  // locked adds: in the plane at once
}

// Continuation rays' direction bins, chosen without branches, are the bins of
// the axis comparisons they replace (largest |component|, ties to the
// earlier axis; its sign), for every direction, ties and zeros included.
TEST(DirectionBins, AreTheLargestComponentsAxisAndSign) {
  auto reference = [](const vec3& d) {
    const vec3 a = glm::abs(d);
    const int axis = a.x >= a.y ? (a.x >= a.z ? 0 : 2) : (a.y >= a.z ? 1 : 2);
    return 2 * axis + (d[axis] < 0.0f ? 1 : 0);
  };
  const float values[] = {-1.0f, -0.5f, -0.0f, 0.0f, 0.5f, 1.0f};
  for (float x : values)
    for (float y : values)
      for (float z : values) EXPECT_EQ(direction_bin(vec3(x, y, z)), reference(vec3(x, y, z))) << x << " " << y << " " << z;
  uint32_t state = 99u;
  auto next = [&] { return state = state * 1664525u + 1013904223u; };
  for (int i = 0; i < 100000; ++i) {
    const auto c = [&] { return static_cast<float>(static_cast<int32_t>(next())); };
    const vec3 d{c(), c(), c()};
    EXPECT_EQ(direction_bin(d), reference(d));
  }
}

}  // namespace
}  // namespace theia
