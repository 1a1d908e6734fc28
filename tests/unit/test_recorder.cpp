// The radiance recorder on hand-fed events: the two worked examples of the
// Hyperion course notes (ch. 2, sections 3.1 and 3.2) in wave order, training
// modes, skipping arithmetic, and random orders / thread interleavings.
#include "core/hash.h"
#include "core/log.h"
#include "core/sampling.h"
#include "radiance_recorder/recorder.h"

#include <gtest/gtest.h>

#include <map>
#include <mutex>
#include <thread>

using namespace theia;

namespace {

PathVertexInfo vertex_info(RGB prefix, RGB local, int depth, bool nee, uint32_t pixel = 0, uint32_t sample = 0) {
  PathVertexInfo v;
  v.p = vec3(float(depth), 0.0f, 0.0f);
  v.n = vec3(0.0f, 0.0f, 1.0f);
  v.wi = glm::normalize(vec3(0.3f, 0.4f, 1.0f));
  v.prefix = prefix;
  v.local = local;
  v.pdf = 0.5f;
  v.pixel = pixel;
  v.sample = sample;
  v.depth = depth;
  v.is_nee = nee;
  return v;
}

void expect_rgb_near(const RGB& a, const RGB& b, const char* what) {
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 1e-5f * std::max(1.0f, std::abs(b[c]))) << what << " channel " << c;
}

RGB tp_of(const PathVertexInfo& v) { return RGB(glm::dvec3(v.prefix) * glm::dvec3(v.local)); }

}  // namespace

TEST(RadianceRecorder, SimpleExampleTwoVirtualLights) {
  StoringSampleSink sink;
  RadianceRecorder rec(RecorderOptions{}, &sink);
  rec.begin_iteration();
  const RGB e1(0.2f, 0.1f, 0.05f), e2(0.03f, 0.3f, 0.07f);
  // Wave 0: the camera ray hits x; P is created for its scattered ray.
  uint32_t cam = rec.path_started(0, 0);
  EXPECT_EQ(cam, kPVNone);
  auto info = vertex_info(RGB(0.9f, 0.8f, 0.7f), RGB(0.5f, 0.25f, 0.125f), 0, false);
  uint32_t P = rec.vertex_created(cam, info);
  rec.vertex_done(cam);
  // Waves 1 and 2: P's ray passes the virtual lights Q1 and Q2: remember, continue.
  for (RGB e : {e1, e2}) {
    rec.emission_added(P, 0, e, 1.0f);
    rec.vertex_continued(P);
    rec.vertex_done(P);
    EXPECT_EQ(rec.live_vertices(), 1u) << "nothing may be recorded before the path completes";
  }
  // Wave 3: the environment (no emission): P completes.
  rec.vertex_done(P);
  EXPECT_EQ(rec.live_vertices(), 0u);
  rec.end_iteration();
  ASSERT_EQ(sink.samples.size(), 1u) << "one vertex, one sample";
  expect_rgb_near(sink.samples[0].radiance, (e1 + e2) / tp_of(info), "P_rad = (e1 + e2) / P_tp");
  EXPECT_EQ(sink.samples[0].depth, 0);
  EXPECT_EQ(sink.samples[0].flags, 0);
}

namespace {

// Section 3.2: six vertices, three of them for NEE rays, fed wave by wave.
struct ComplexExample {
  RGB e[9];
  PathVertexInfo info[6];
  std::vector<uint64_t> live_after_wave;

  ComplexExample() {
    for (int i = 1; i <= 8; ++i) e[i] = RGB(0.01f * float(i), 0.02f + 0.005f * float(i), 0.1f / float(i));
    const int depth[6] = {0, 0, 1, 1, 2, 2};
    const bool nee[6] = {false, true, false, true, false, true};
    for (int i = 0; i < 6; ++i)
      info[i] = vertex_info(RGB(1.0f / float(i + 1), 0.5f, 0.75f), RGB(0.3f + 0.1f * float(i), 0.6f, 0.2f + 0.05f * float(i)),
                            depth[i], nee[i]);
  }

  // Weights: the MIS weight reported with e[i] (1 everywhere unless a test changes it).
  float w[9] = {1, 1, 1, 1, 1, 1, 1, 1, 1};

  void run(RadianceRecorder& rec) {
    rec.begin_iteration();
    uint32_t cam = rec.path_started(0, 0);
    // Wave 0: camera ray hits x1: create P0 and P1.
    uint32_t P0 = rec.vertex_created(cam, info[0]);
    uint32_t P1 = rec.vertex_created(cam, info[1]);
    rec.vertex_done(cam);
    live_after_wave.push_back(rec.live_vertices());
    // Wave 1: P0 hits x2: create P2, P3.  P1 hits Q1: e1, continue.
    uint32_t P2 = rec.vertex_created(P0, info[2]);
    uint32_t P3 = rec.vertex_created(P0, info[3]);
    rec.vertex_done(P0);
    add(rec, P1, 1);
    rec.vertex_continued(P1);
    rec.vertex_done(P1);
    live_after_wave.push_back(rec.live_vertices());
    // Wave 2: P1 hits the environment: e2, P1 records.  P2 hits x3: create P4, P5.  P3 hits Q1: e3, continue.
    add(rec, P1, 2);
    rec.vertex_done(P1);
    uint32_t P4 = rec.vertex_created(P2, info[4]);
    uint32_t P5 = rec.vertex_created(P2, info[5]);
    rec.vertex_done(P2);
    add(rec, P3, 3);
    rec.vertex_continued(P3);
    rec.vertex_done(P3);
    live_after_wave.push_back(rec.live_vertices());
    // Wave 3: P3 env e4 (records).  P4 env e5 (records).  P5 hits Q2: e6, continue.
    add(rec, P3, 4);
    rec.vertex_done(P3);
    add(rec, P4, 5);
    rec.vertex_done(P4);
    add(rec, P5, 6);
    rec.vertex_continued(P5);
    rec.vertex_done(P5);
    live_after_wave.push_back(rec.live_vertices());
    // Wave 4: P5 hits Q3: e7, continue.
    add(rec, P5, 7);
    rec.vertex_continued(P5);
    rec.vertex_done(P5);
    live_after_wave.push_back(rec.live_vertices());
    // Wave 5: P5 env e8: P5, P2 and P0 record.
    add(rec, P5, 8);
    rec.vertex_done(P5);
    live_after_wave.push_back(rec.live_vertices());
    rec.end_iteration();
  }
  void add(RadianceRecorder& rec, uint32_t v, int i) { rec.emission_added(v, 0, e[i], w[i]); }
  RGB tp(int i) const { return tp_of(info[i]); }
};

std::map<std::pair<int, int>, TrainingSample> by_vertex(const std::vector<TrainingSample>& s) {
  std::map<std::pair<int, int>, TrainingSample> m;
  for (const auto& x : s) m[{int(x.depth), int(x.flags & kVertexNEE)}] = x;
  return m;
}

}  // namespace

TEST(RadianceRecorder, ComplexExampleSixVerticesWithNEE) {
  StoringSampleSink sink;
  RadianceRecorder rec(RecorderOptions{}, &sink);
  ComplexExample ex;
  ex.run(rec);
  // Vertices alive after each wave: P1 records in wave 2, P3 and P4 in wave 3, the rest in wave 5.
  EXPECT_EQ(ex.live_after_wave, (std::vector<uint64_t>{2, 4, 5, 3, 3, 0}));
  ASSERT_EQ(sink.samples.size(), 6u) << "six vertices, six samples";
  auto m = by_vertex(sink.samples);
  ASSERT_EQ(m.size(), 6u) << "each vertex records exactly once";
  const RGB* e = ex.e;
  expect_rgb_near(m[{0, 0}].radiance, (e[3] + e[4] + e[5] + e[6] + e[7] + e[8]) / ex.tp(0), "P0");
  expect_rgb_near(m[{0, 1}].radiance, (e[1] + e[2]) / ex.tp(1), "P1");
  expect_rgb_near(m[{1, 0}].radiance, (e[5] + e[6] + e[7] + e[8]) / ex.tp(2), "P2");
  expect_rgb_near(m[{1, 1}].radiance, (e[3] + e[4]) / ex.tp(3), "P3");
  expect_rgb_near(m[{2, 0}].radiance, e[5] / ex.tp(4), "P4");
  expect_rgb_near(m[{2, 1}].radiance, (e[6] + e[7] + e[8]) / ex.tp(5), "P5");
  for (const auto& s : sink.samples) {
    EXPECT_FLOAT_EQ(s.pdf, 0.5f);
  }
}

TEST(RadianceRecorder, TrainingModesSplitDirectAndIndirect) {
  auto run = [](const char* mode) {
    StoringSampleSink sink;
    RecorderOptions o;
    o.training = mode;
    RadianceRecorder rec(o, &sink);
    ComplexExample ex;
    ex.w[1] = 0.5f;  // e1 is MIS-weighted: the unweighted direct light is 2 e1
    ex.w[6] = 0.25f;
    ex.run(rec);
    return std::make_pair(by_vertex(sink.samples), ex);
  };
  auto [mis, ex] = run("mis-direct");
  auto [all, ex2] = run("all");
  auto [ind, ex3] = run("indirect");
  EXPECT_THROW(parse_training_mode("direct"), Error);
  const RGB* e = ex.e;
  // P1 sees only direct light (its own ray passes Q1 and meets the environment).
  expect_rgb_near(mis[{0, 1}].radiance, (e[1] + e[2]) / ex.tp(1), "MIS-weighted direct at P1");
  expect_rgb_near(all[{0, 1}].radiance, (e[1] / 0.5f + e[2]) / ex.tp(1), "unweighted direct at P1");
  expect_rgb_near(ind[{0, 1}].radiance, RGB(0.0f), "no indirect light at P1");
  // P5: direct only.
  expect_rgb_near(all[{2, 1}].radiance, (e[6] / 0.25f + e[7] + e[8]) / ex.tp(5), "P5 all");
  expect_rgb_near(ind[{2, 1}].radiance, RGB(0.0f), "P5 indirect");
  // P0 and P2 receive everything through children: indirect, the same in every mode
  // (the MIS-weighted emission is what reached the film, so it is what propagates).
  for (auto* m : {&mis, &all, &ind}) {
    expect_rgb_near((*m)[{0, 0}].radiance, (e[3] + e[4] + e[5] + e[6] + e[7] + e[8]) / ex.tp(0), "P0");
    expect_rgb_near((*m)[{1, 0}].radiance, (e[5] + e[6] + e[7] + e[8]) / ex.tp(2), "P2");
  }
}

// Guiding's trainer wants no NEE samples (seeds/001 10.7: what NEE samples
// is not guided): on the section-3.2 example it gets exactly the three
// scattering vertices' samples, as a sink that takes all six does.
TEST(RadianceRecorder, SinkWithoutNEESamplesGetsTheSameScatteringSamples) {
  struct NoNEE final : TrainingSampleSink {
    std::vector<TrainingSample> samples;
    void consume(std::span<const TrainingSample> s) override { samples.insert(samples.end(), s.begin(), s.end()); }
    bool wants_nee_samples() const override { return false; }
  } no_nee;
  StoringSampleSink all;
  for (TrainingSampleSink* sink : {static_cast<TrainingSampleSink*>(&no_nee), static_cast<TrainingSampleSink*>(&all)}) {
    RadianceRecorder rec(RecorderOptions{}, sink);
    ComplexExample ex;
    ex.run(rec);
  }
  ASSERT_EQ(all.samples.size(), 6u);
  ASSERT_EQ(no_nee.samples.size(), 3u);
  auto m = by_vertex(all.samples), n = by_vertex(no_nee.samples);
  for (int depth = 0; depth < 3; ++depth) {
    const std::pair<int, int> key{depth, 0};
    ASSERT_EQ(n.count(key), 1u) << depth;
    expect_rgb_near(n[key].radiance, m[key].radiance, "a scattering vertex's sample");
  }
}

TEST(RadianceRecorder, OccludedNEEGivesZeroSample) {
  StoringSampleSink sink;
  RadianceRecorder rec(RecorderOptions{}, &sink);
  rec.begin_iteration();
  uint32_t cam = rec.path_started(3, 1);
  uint32_t v = rec.vertex_created(cam, vertex_info(RGB(1.0f), RGB(0.5f), 0, true, 3, 1));
  rec.vertex_done(v);  // blocked: no emission, but it finishes
  rec.end_iteration();
  ASSERT_EQ(sink.samples.size(), 1u);
  EXPECT_EQ(sink.samples[0].radiance, RGB(0.0f));
  EXPECT_EQ(sink.samples[0].flags, kVertexNEE);
  EXPECT_EQ(sink.samples[0].pixel, 3u);
}

TEST(RadianceRecorder, PathSkipRateArithmetic) {
  EXPECT_DOUBLE_EQ(path_skip_rate(8, 64, 4.0), 0.5);  // the course notes' example
  EXPECT_DOUBLE_EQ(path_skip_rate(8, 16, 4.0), 0.0);  // paths shorter than the budget: keep all
  EXPECT_DOUBLE_EQ(path_skip_rate(10, 100, 2.0), 0.8);
  EXPECT_DOUBLE_EQ(path_skip_rate(8, 64, 0.0), 0.0);  // budget off
  EXPECT_DOUBLE_EQ(path_skip_rate(0, 0, 4.0), 0.0);   // no previous iteration

  // The recorder sets it from the previous iteration: 8 paths of 8 vertices, budget 4.
  StoringSampleSink sink;
  RadianceRecorder rec(RecorderOptions{}, &sink);
  rec.begin_iteration();
  EXPECT_EQ(rec.stats().path_skip_rate, 0.0);
  for (uint32_t p = 0; p < 8; ++p) {
    uint32_t h = rec.path_started(p, 0);
    for (int d = 0; d < 8; ++d) {
      uint32_t c = rec.vertex_created(h, vertex_info(RGB(1.0f), RGB(0.5f), d, false, p, 0));
      rec.vertex_done(h);
      h = c;
    }
    rec.vertex_done(h);
  }
  rec.end_iteration();
  EXPECT_EQ(sink.samples.size(), 64u);
  EXPECT_DOUBLE_EQ(rec.stats().average_path_length, 8.0);
  EXPECT_EQ(rec.stats().path_skip_rate, 0.0);  // only the scheduler's skip-rate task changes it
  rec.update_skip_rate();
  rec.begin_iteration();
  EXPECT_DOUBLE_EQ(rec.stats().path_skip_rate, 0.5);
  // Skipped paths carry SKIPPED, never allocate and have no children.
  const uint32_t n = 20000;
  uint32_t skipped = 0;
  for (uint32_t p = 0; p < n; ++p) {
    uint32_t h = rec.path_started(p, 1);
    if (h != kPVSkipped) continue;
    ++skipped;
    EXPECT_EQ(rec.vertex_created(h, vertex_info(RGB(1.0f), RGB(0.5f), 0, false, p, 1)), kPVSkipped);
    rec.emission_added(h, p, RGB(1.0f), 1.0f);
    rec.vertex_done(h);
  }
  EXPECT_EQ(rec.live_vertices(), 0u);
  // Binomial(20000, 0.5): sigma = 0.0035; allow 5 sigma.
  EXPECT_NEAR(double(skipped) / n, 0.5, 0.018);
  rec.end_iteration();
}

TEST(RadianceRecorder, VertexSkippingAndMinimumDistanceMergeIntoTheParent) {
  StoringSampleSink sink;
  RecorderOptions o;
  o.min_distance = 0.5f;
  RadianceRecorder rec(o, &sink);
  rec.begin_iteration();
  uint32_t cam = rec.path_started(0, 0);
  auto a = vertex_info(RGB(1.0f), RGB(0.5f), 0, false);
  uint32_t A = rec.vertex_created(cam, a);
  auto b = vertex_info(RGB(0.5f), RGB(0.5f), 1, false);
  b.p = a.p + vec3(0.1f, 0.0f, 0.0f);  // too close: A is continued instead
  uint32_t B = rec.vertex_created(A, b);
  EXPECT_EQ(B, A | kPVMergedBit);
  rec.vertex_done(A);
  rec.emission_added(B, 0, RGB(0.25f), 1.0f);  // arrives at A as indirect light
  rec.vertex_done(B);
  EXPECT_EQ(rec.live_vertices(), 0u);
  rec.end_iteration();
  ASSERT_EQ(sink.samples.size(), 1u);
  expect_rgb_near(sink.samples[0].radiance, RGB(0.25f) / tp_of(a), "merged emission reaches the parent");
  EXPECT_EQ(rec.stats().merged_vertices, 1u);

  // Stochastic vertex skipping: about the asked fraction is skipped, deep vertices still record.
  StoringSampleSink sink2;
  RecorderOptions o2;
  o2.vertex_skip_probability = 0.3f;
  RadianceRecorder rec2(o2, &sink2);
  rec2.begin_iteration();
  const uint32_t paths = 4000, len = 5;
  for (uint32_t p = 0; p < paths; ++p) {
    uint32_t h = rec2.path_started(p, 0);
    for (uint32_t d = 0; d < len; ++d) {
      uint32_t c = rec2.vertex_created(h, vertex_info(RGB(1.0f), RGB(0.5f), int(d), false, p, 0));
      rec2.vertex_done(h);
      h = c;
    }
    rec2.emission_added(h, p, RGB(1.0f), 1.0f);
    rec2.vertex_done(h);
  }
  EXPECT_EQ(rec2.live_vertices(), 0u);
  rec2.end_iteration();
  RecorderStats st = rec2.stats();
  EXPECT_NEAR(double(st.skipped_vertices) / double(paths * len), 0.3, 0.02);
  EXPECT_EQ(sink2.samples.size(), st.recorded);
  size_t deep = 0;
  for (const auto& s : sink2.samples) deep += s.depth == len - 1;
  EXPECT_NEAR(double(deep) / paths, 0.7, 0.04);
}

TEST(RadianceRecorder, BlocksAreReused) {
  RadianceRecorder rec(RecorderOptions{});
  rec.begin_iteration();
  for (uint32_t p = 0; p < 50000; ++p) {
    uint32_t h = rec.path_started(p, 0);
    uint32_t v = rec.vertex_created(h, vertex_info(RGB(1.0f), RGB(0.5f), 0, false, p, 0));
    rec.vertex_done(v);
  }
  rec.end_iteration();
  EXPECT_EQ(rec.stats().peak_blocks, 1u);
  EXPECT_EQ(rec.stats().peak_live_vertices, 1u);
  EXPECT_EQ(RadianceRecorder::vertex_bytes(), 128u);
}

// Random path trees whose events are processed in random order by several
// threads from one shared queue: siblings finish on different threads, so
// parents are decremented concurrently.  Nothing may stay allocated, every
// recorded vertex records once, and all emission reaches the camera's
// vertices (checked through the primary-hit debug buffer).
TEST(RadianceRecorder, RandomOrdersAndThreadInterleavingsLeaveNothingAllocated) {
  for (float skip : {0.0f, 0.4f}) {
    StoringSampleSink sink;
    RecorderOptions o;
    o.width = 64;
    o.height = 1;
    o.debug = true;
    o.vertex_skip_probability = skip;
    RadianceRecorder rec(o, &sink);
    rec.begin_iteration();

    struct Ray {
      uint32_t handle, pixel, sample;
      int depth;
      uint64_t rng;
    };
    std::mutex m;
    std::vector<Ray> queue;
    const uint32_t paths = 3000;
    std::atomic<uint64_t> created{0};
    std::vector<double> injected(64, 0.0);  // per pixel, first channel, guarded by m
    for (uint32_t p = 0; p < paths; ++p) {
      uint32_t pixel = p % 64;
      uint32_t h = rec.path_started(pixel, p);
      // The camera ray's hit creates 1..2 vertices at depth 0.
      int n = 1 + int(hash(p, 7u) % 2);
      for (int k = 0; k < n; ++k) {
        auto info = vertex_info(RGB(1.0f), RGB(0.5f, 0.25f, 1.0f), 0, k == 1, pixel, p);
        queue.push_back({rec.vertex_created(h, info), pixel, p, 0, hash(p, uint32_t(k))});
        ++created;
      }
      rec.vertex_done(h);
    }
    auto worker = [&](uint32_t id) {
      uint64_t state = hash(id, 99u);
      while (true) {
        Ray r;
        {
          std::lock_guard lock(m);
          if (queue.empty()) return;
          state = mix_bits(state + 1);
          size_t pick = state % queue.size();
          r = queue[pick];
          queue[pick] = queue.back();
          queue.pop_back();
        }
        uint64_t u = mix_bits(r.rng);
        // Emission: film units (throughput x 0.1), tracked per pixel for the final check.
        if (u % 3 == 0) {
          float e = 0.1f * float((u >> 8) % 7 + 1);
          rec.emission_added(r.handle, r.pixel, RGB(e), 1.0f);
          std::lock_guard lock(m);
          injected[r.pixel] += e;
        }
        std::vector<Ray> next;
        if ((u >> 16) % 4 == 0) {  // a virtual light: continue the same vertex
          rec.vertex_continued(r.handle);
          next.push_back({r.handle, r.pixel, r.sample, r.depth, u});
        } else if (r.depth < 6 && (u >> 20) % 3 != 0) {  // a surface: scatter (+ NEE)
          int n = 1 + int((u >> 24) % 2);
          for (int k = 0; k < n; ++k) {
            auto info = vertex_info(RGB(0.5f), RGB(0.5f), r.depth + 1, k == 1, r.pixel, r.sample);
            next.push_back({rec.vertex_created(r.handle, info), r.pixel, r.sample, r.depth + 1, u + uint64_t(k) + 1});
            ++created;
          }
        }
        rec.vertex_done(r.handle);
        std::lock_guard lock(m);
        queue.insert(queue.end(), next.begin(), next.end());
      }
    };
    std::vector<std::thread> threads;
    for (uint32_t t = 0; t < 4; ++t) threads.emplace_back(worker, t);
    for (auto& t : threads) t.join();

    EXPECT_EQ(rec.live_vertices(), 0u) << "skip " << skip;
    EXPECT_NO_THROW(rec.end_iteration());
    RecorderStats st = rec.stats();
    EXPECT_EQ(st.vertex_events, created.load());
    EXPECT_EQ(sink.samples.size(), st.recorded);
    EXPECT_EQ(st.recorded + st.skipped_vertices, created.load());
    if (skip == 0.0f) {
      // Everything injected reaches a depth-0 vertex and is splatted once.
      for (int px = 0; px < 64; ++px)
        EXPECT_NEAR(rec.debug_primary()[3 * size_t(px)], injected[size_t(px)], 1e-3 * (1.0 + injected[size_t(px)]));
    }
  }
}

// ---------------------------------------------------------------- dense media

namespace {

struct WalkResult {
  uint64_t peak_live = 0;
  RecorderStats stats;
  double debug = 0.0, injected = 0.0;  // the primary buffer's red sum against the emission fed in
  uint64_t deep_samples = 0;           // training samples past depth 1000
};

// One path per pixel as a dense medium makes it (seeds/000 ch. 2 section
// 3.4.4): a surface vertex at depth 0, then `steps` in-medium scattering
// events a random walk of unit mean free path apart, each with an NEE ray,
// emission arriving along every ray.  The events come in wave order, one
// path after the other, as an engine with a pool of one would send them.
WalkResult dense_walk(const RecorderOptions& base, int paths, int steps) {
  RecorderOptions o = base;
  o.debug = true;
  o.width = paths;
  o.height = 1;
  o.vertex_budget = 0.0f;
  StoringSampleSink sink;
  RadianceRecorder rec(o, &sink);
  rec.begin_iteration();
  WalkResult out;
  for (uint32_t px = 0; px < uint32_t(paths); ++px) {
    uint32_t h = rec.path_started(px, 0);
    vec3 p(0.0f);
    for (int d = 0; d <= steps; ++d) {
      const uint64_t u = hash(px, uint32_t(d), 0xd1ceu);
      PathVertexInfo v = vertex_info(RGB(std::pow(0.99f, float(d))), RGB(1.0f), d, false, px, 0);
      v.p = p;
      v.in_medium = d > 0;
      PathVertexInfo nee = v;
      nee.is_nee = true;
      const uint32_t shadow = rec.vertex_created(h, nee);
      const uint32_t child = rec.vertex_created(h, v);
      rec.vertex_done(h);
      const float e = 0.01f * float(u % 5);
      rec.emission_added(shadow, px, RGB(e), 0.5f);
      rec.vertex_done(shadow);
      rec.emission_added(child, px, RGB(e), 1.0f);
      out.injected += 2.0 * e;
      out.peak_live = std::max(out.peak_live, rec.live_vertices());
      h = child;
      // The next scattering point: an exponential step in a uniform direction.
      const vec3 w = sample_uniform_sphere(vec2(to_unit_float(uint32_t(u >> 32)), to_unit_float(uint32_t(u >> 8))));
      p += w * -std::log(1.0f - to_unit_float(uint32_t(hash(u))));
    }
    rec.vertex_done(h);
  }
  EXPECT_EQ(rec.live_vertices(), 0u);
  rec.end_iteration();
  out.stats = rec.stats();
  for (int px = 0; px < paths; ++px) out.debug += rec.debug_primary()[3 * size_t(px)];
  for (const TrainingSample& s : sink.samples) out.deep_samples += s.depth > 1000;
  return out;
}

}  // namespace

// A path of 2000 scattering events in a dense medium holds all of them (the
// chain of parents lives until the path ends) unless in-medium vertices are
// skipped or merged by distance; either way every skipped vertex's light
// reaches its nearest recorded ancestor, so the depth-0 (surface) vertex
// sums exactly what was emitted along the path.
TEST(RadianceRecorder, DenseMediumPathKeepsMemoryBoundedAndSumsExactly) {
  const int paths = 4, steps = 2000;
  RecorderOptions none;
  const WalkResult all = dense_walk(none, paths, steps);
  EXPECT_GE(all.peak_live, uint64_t(steps)) << "without skipping the whole chain is live";
  EXPECT_NEAR(all.debug, all.injected, 1e-4 * all.injected);

  RecorderOptions skip;
  skip.medium_skip_probability = 0.9f;
  const WalkResult skipped = dense_walk(skip, paths, steps);
  EXPECT_LT(skipped.peak_live, uint64_t(0.15 * steps)) << "about a tenth of the in-medium vertices kept";
  EXPECT_GT(skipped.peak_live, uint64_t(0.05 * steps)) << "and they are recorded all along the path";
  EXPECT_NEAR(double(skipped.stats.skipped_vertices) / double(2 * paths * steps), 0.9, 0.02);
  EXPECT_NEAR(skipped.debug, all.injected, 1e-4 * all.injected) << "skipped vertices merge into their ancestors";
  EXPECT_GT(skipped.deep_samples, 0u) << "vertices past the first thousand bounces record";

  // A walk of exponential unit-mean steps (mean square 2) moves d away in
  // about d^2 / 2 steps: a minimum distance of 6 merges all but about one
  // vertex in eighteen.
  RecorderOptions near;
  near.min_distance = 6.0f;
  const WalkResult merged = dense_walk(near, paths, steps);
  EXPECT_LT(merged.peak_live, uint64_t(0.15 * steps));
  EXPECT_GT(merged.stats.merged_vertices, uint64_t(0.8 * paths * steps));
  EXPECT_NEAR(merged.debug, all.injected, 1e-4 * all.injected);
}
