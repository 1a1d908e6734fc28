// Cache points (cachepoints/cache_points.h) and the locally optimal sampler
// (cachepoints/local_sampler.h): the pmf is a distribution over
// every emitter (a mesh light's triangles each one), sample() draws from it
// (chi-square over emitters), learned visibility lowers occluded lights and is
// a pure function of the counts (thread count, checkpoint round trip), the
// build's tables do not depend on the thread count, and degenerate light sets
// build and sample.
#include "cachepoints/cache_points.h"
#include "cachepoints/light_sampler.h"
#include "cachepoints/local_sampler.h"
#include "chi2.h"
#include "core/hash.h"
#include "core/log.h"
#include "scene/parser.h"
#include "tests/street_scene.h"
#include "tests/test_util.h"
#include "tests/unit/light_fixture.h"

#include <gtest/gtest.h>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <iterator>
#include <map>
#include <memory>
#include <string>

using namespace theia;
using namespace theia::test;

namespace {

// Shading points on the floor on both sides of the wall, on the wall, and one in the air (no normal).
std::vector<LightSampleContext> vertices() {
  return {LightSampleContext{vec3(-3, 0, 1), vec3(0), vec3(0, 1, 0), vec3(0, 1, 0)},
          LightSampleContext{vec3(2, 0, -4), vec3(0), vec3(0, 1, 0), vec3(0, 1, 0)},
          LightSampleContext{vec3(0, 2, 3), vec3(0), vec3(-1, 0, 0), vec3(-1, 0, 0)},
          LightSampleContext{vec3(4, 3, 5), vec3(0), vec3(0), vec3(0)}};
}

// For cache points and the locally optimal sampler alike: both choose among emitters().
template <class Sampler>
double pmf_sum(const Sampler& s, const LightSampleContext& ctx) {
  double sum = 0.0;
  for (const Emitter& e : s.emitters().emitters) sum += double(s.pmf_primitive(ctx, e.light, e.primitive));
  return sum;
}

// Sampling draws what pmf_primitive says (chi-square over emitters, 200k
// samples at each vertex unless told), and the pmf sums to one.
template <class Sampler>
void expect_sampling_matches_pmf(const Sampler& s, int n_tests, int samples = 200000) {
  const size_t n = s.emitters().size();
  for (const LightSampleContext& ctx : vertices()) {
    EXPECT_NEAR(pmf_sum(s, ctx), 1.0, 1e-4);
    std::vector<double> observed(n, 0.0), expected(n, 0.0);
    for (int i = 0; i < samples; ++i) {
      auto sl = s.sample(ctx, to_unit_float(uint32_t(hash(uint64_t(i), 77u))));
      ASSERT_TRUE(sl);
      const int e = s.emitters().find(sl->light, sl->primitive);
      ASSERT_GE(e, 0);
      ASSERT_EQ(sl->pmf, s.pmf_primitive(ctx, sl->light, sl->primitive));
      observed[size_t(e)] += 1.0;
    }
    for (size_t e = 0; e < n; ++e)
      expected[e] = samples * double(s.pmf_primitive(ctx, s.emitters().emitters[e].light,
                                                      s.emitters().emitters[e].primitive));
    Chi2Result r = chi2_counts(observed, expected, 1e-3, n_tests);
    EXPECT_TRUE(r.passed) << r.report;
  }
}

// Few points, so that each sees enough shadow rays to learn from (24 misses
// in a row bring R to R_min).
CachePointParams few_points() {
  CachePointParams few;
  few.object_candidates = 64;
  few.pilot_width = 8;
  few.pilot_height = 6;
  return few;
}

// Shadow rays from vertices all over the floor left of the wall, every light
// on the -z half occluded, then update(): what the learning tests teach.
void learn_occluded_half(CachePointSampler& s) {
  std::vector<SampledLight> chosen;
  for (int i = 0; i < 200000; ++i) {
    const float x = -9.0f + 8.5f * to_unit_float(uint32_t(hash(uint64_t(i), 6u)));
    const float z = -9.0f + 18.0f * to_unit_float(uint32_t(hash(uint64_t(i), 7u)));
    const LightSampleContext v{vec3(x, 0, z), vec3(0), vec3(0, 1, 0), vec3(0, 1, 0)};
    if (auto sl = s.sample(v, to_unit_float(uint32_t(hash(uint64_t(i), 5u))))) chosen.push_back(*sl);
  }
  tbb::parallel_for(size_t(0), chosen.size(), [&](size_t i) {
    const Emitter& e = s.emitters().emitters[size_t(s.emitters().find(chosen[i].light, chosen[i].primitive))];
    s.record_shadow(chosen[i], e.center.z > 0.0f);
  });
  s.update();
}

// 1,000,000 emitters: a two-sided ceiling of 1000 x 500 quads (two triangles
// each, one mesh light, so one emitter per triangle) over the floor, as a
// binary PLY.
std::string million_light_scene(const TempDir& dir) {
  constexpr int nx = 1000, nz = 500;
  std::string ply = fmt::format(
      "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n"
      "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
      (nx + 1) * (nz + 1), 2 * nx * nz);
  auto put = [&](const auto& v) { ply.append(reinterpret_cast<const char*>(&v), sizeof(v)); };
  for (int j = 0; j <= nz; ++j)
    for (int i = 0; i <= nx; ++i) {
      put(-10.0f + 20.0f * float(i) / float(nx));
      put(5.0f);
      put(-5.0f + 10.0f * float(j) / float(nz));
    }
  for (int j = 0; j < nz; ++j)
    for (int i = 0; i < nx; ++i) {
      const int a = j * (nx + 1) + i, b = a + 1, c = a + nx + 1, d = c + 1;
      for (const std::array<int, 3>& t : {std::array<int, 3>{a, b, d}, std::array<int, 3>{a, d, c}}) {
        put(uint8_t(3));
        for (int v : t) put(v);
      }
    }
  const std::string path = dir.write("ceiling.ply", ply);
  return "Film \"rgb\" \"integer xresolution\" [32] \"integer yresolution\" [24]\n"
         "LookAt 0 3 -12  0 1 0  0 1 0\nCamera \"perspective\" \"float fov\" [50]\nWorldBegin\n"
         "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
         "Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point3 P\" [-10 0 -10 10 0 -10 10 0 10 -10 0 10]\n"
         "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"bool twosided\" true\n"
         "Shape \"plymesh\" \"string filename\" \"" + path + "\"\nAttributeEnd\n";
}

}  // namespace

TEST(CachePoints, BuildsPointsAndEmittersPerTriangle) {
  LightFixture f(street_scene(8, varied, true));
  CachePointSampler s(f.lights, f.accel);
  EXPECT_EQ(s.emitters().size(), 2u * 64u * 2u + 1u);  // two triangles per quad, and the sky
  EXPECT_GE(s.point_count(), 10u);
  EXPECT_TRUE(s.chooses_primitives());
  EXPECT_TRUE(s.wants_feedback());
}

TEST(CachePoints, PmfSumsToOne) {
  LightFixture f(street_scene(8, varied, true));
  CachePointSampler s(f.lights, f.accel);
  for (const LightSampleContext& ctx : vertices()) EXPECT_NEAR(pmf_sum(s, ctx), 1.0, 1e-4);
}

TEST(CachePoints, SampledPmfIsThePmfAndFrequenciesMatch) {
  LightFixture f(street_scene(8, varied, true));
  CachePointSampler s(f.lights, f.accel);
  expect_sampling_matches_pmf(s, 1);
}

// Selection chooses a far entry by a group of bins, then a binary search in
// that group's CDF (the learned visibility folded in): on a street of 1,025
// emitters, where the 256-per-bin cap and the 97% rule both cut, it draws
// what the pmf says before and after learning.
TEST(CachePoints, BinFirstSamplingMatchesThePmfBeforeAndAfterLearning) {
  LightFixture f(street_scene(16, varied, true));
  CachePointSampler s(f.lights, f.accel, few_points());
  expect_sampling_matches_pmf(s, 2);
  learn_occluded_half(s);
  int lowered = 0;
  for (size_t e = 0; e < s.emitters().size(); ++e) lowered += s.visibility(vertices()[0].p, int(e)) < 1.0f;
  EXPECT_GT(lowered, 0);
  expect_sampling_matches_pmf(s, 2);
}

TEST(CachePoints, PrefersTheLightsOnItsSideOfTheWall) {
  LightFixture f(street_scene(8, [](int) { return 1.0f; }, false));
  CachePointSampler s(f.lights, f.accel);
  // On the floor left of the wall (x < 0) the lights facing -x carry almost all probability.
  const LightSampleContext ctx{vec3(-3, 0, 1), vec3(0), vec3(0, 1, 0), vec3(0, 1, 0)};
  double left = 0.0;
  for (const Emitter& e : s.emitters().emitters)
    if (e.normal.x < 0.0f) left += double(s.pmf_primitive(ctx, e.light, e.primitive));
  EXPECT_GT(left, 0.95);
}

TEST(CachePoints, LearnedVisibilityLowersOccludedLightsAndIsDeterministic) {
  const std::string text = street_scene(8, varied, true);
  LightFixture f(text);
  const LightSampleContext ctx = vertices()[0];
  // The same shadow-ray outcomes reported on 1 and on 4 threads.
  const CachePointParams few = few_points();
  auto learn = [&](int threads) {
    auto s = std::make_unique<CachePointSampler>(f.lights, f.accel, few);
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
    learn_occluded_half(*s);
    return s;
  };
  auto one = learn(1), four = learn(4);
  EXPECT_EQ(one->save_state(), four->save_state());
  EXPECT_NEAR(pmf_sum(*one, ctx), 1.0, 1e-4);
  // The occluded half lost probability to the visible half.
  LightFixture fresh(text);
  CachePointSampler before(fresh.lights, fresh.accel, few);
  double occluded_before = 0.0, occluded_after = 0.0;
  int lowered = 0;
  for (size_t e = 0; e < one->emitters().size(); ++e) {
    const Emitter& em = one->emitters().emitters[e];
    if (em.kind != EmitterKind::Area || em.center.z > 0.0f) continue;
    occluded_before += double(before.pmf_primitive(ctx, em.light, em.primitive));
    occluded_after += double(one->pmf_primitive(ctx, em.light, em.primitive));
    if (one->visibility(ctx.p, int(e)) < 1.0f) ++lowered;
  }
  EXPECT_GT(lowered, 0);
  EXPECT_LT(occluded_after, 0.6 * occluded_before);
  // A checkpoint round trip: the restored sampler samples as the learned one.
  CachePointSampler restored(f.lights, f.accel, few);
  restored.restore(one->save_state());
  for (const LightSampleContext& c : vertices())
    for (const Emitter& e : one->emitters().emitters)
      ASSERT_EQ(restored.pmf_primitive(c, e.light, e.primitive), one->pmf_primitive(c, e.light, e.primitive));
  EXPECT_THROW(restored.restore(std::vector<uint8_t>(5, 0)), Error);
}

// The build's tables (points, lists, far values) do not depend on the thread
// count: 1,025 emitters, so that the 256-per-bin cap and the energy rule both cut.
TEST(CachePoints, BuildIsDeterministicAcrossThreadCounts) {
  LightFixture f(street_scene(16, varied, true));
  auto checksum = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
    CachePointSampler s(f.lights, f.accel);
    for (const auto& [key, value] : s.statistics())
      if (key == "tables_checksum") return value;
    return -1.0;
  };
  const double one = checksum(1);
  EXPECT_GT(one, 0.0);
  EXPECT_EQ(one, checksum(2));
  EXPECT_EQ(one, checksum(4));
}

// The culled build (the light tree rules emitters out) lists nearly what
// evaluating every emitter at every point lists, on streets of 1,025 and
// 4,097 emitters: the entries it drops are at the lists' tails (a node is
// left out only when its brightest emitter delivers under 1e-3 of what was
// found), so at the test vertices the two samplers' pmfs differ little in
// total variation (measured: 0.8% and 0.4% of the entries, total variation
// at most 0.0042).
TEST(CachePoints, CulledBuildListsWhatTheFullBuildLists) {
  for (int n : {16, 32}) {
    LightFixture f(street_scene(n, varied, true));
    CachePointParams full;
    full.cull = 0.0f;
    CachePointSampler all(f.lights, f.accel, full), culled(f.lights, f.accel);
    ASSERT_EQ(all.point_count(), culled.point_count());
    size_t entries = 0, differ = 0;
    for (size_t c = 0; c < all.point_count(); ++c) {
      std::vector<uint32_t> a = all.listed(c), b = culled.listed(c);
      std::sort(a.begin(), a.end());
      std::sort(b.begin(), b.end());
      std::vector<uint32_t> only;
      std::set_symmetric_difference(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(only));
      entries += a.size();
      differ += only.size();
    }
    EXPECT_LT(double(differ), 0.03 * double(entries)) << n << ": " << differ << " of " << entries;
    for (const LightSampleContext& ctx : vertices()) {
      double tv = 0.0;
      for (const Emitter& e : all.emitters().emitters)
        tv += 0.5 * std::abs(double(all.pmf_primitive(ctx, e.light, e.primitive)) -
                             double(culled.pmf_primitive(ctx, e.light, e.primitive)));
      EXPECT_LT(tv, 0.01) << n << " at " << ctx.p.x << " " << ctx.p.y << " " << ctx.p.z;
    }
  }
}

// Section 3.1.4's second merge (merge_similar, off by default): fewer
// points, the same survivors at any thread count (parallel marks, a serial
// sweep), and still a distribution over every emitter that sampling draws.
TEST(CachePoints, SimilarityMergeIsDeterministicAndKeepsADistribution) {
  LightFixture f(street_scene(16, varied, true));
  CachePointParams on;
  on.merge_similar = true;
  auto build = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
    return std::make_unique<CachePointSampler>(f.lights, f.accel, on);
  };
  const auto one = build(1), two = build(2);
  const CachePointSampler plain(f.lights, f.accel);
  EXPECT_LT(one->point_count(), plain.point_count());
  EXPECT_GE(one->point_count(), size_t(on.min_points));
  ASSERT_EQ(one->point_count(), two->point_count());
  for (size_t c = 0; c < one->point_count(); ++c) ASSERT_EQ(one->listed(c), two->listed(c)) << c;
  expect_sampling_matches_pmf(*one, 4, 100000);
}

TEST(CachePoints, DegenerateLightSets) {
  // Every light at the same place inside the wall; a third of them black.
  for (const std::string& text : {street_scene(6, varied, false, true), street_scene(6, dark, true)}) {
    LightFixture f(text);
    CachePointSampler s(f.lights, f.accel);
    for (const LightSampleContext& ctx : vertices()) {
      EXPECT_NEAR(pmf_sum(s, ctx), 1.0, 1e-4);
      for (int i = 0; i < 64; ++i)
        if (auto sl = s.sample(ctx, (float(i) + 0.5f) / 64.0f)) {
          EXPECT_TRUE(std::isfinite(sl->pmf));
          EXPECT_GT(sl->pmf, 0.0f);
        }
    }
  }
  // One light: nothing to choose, nothing built.
  LightFixture one(street_scene(0, varied, true));
  EXPECT_STREQ(make_light_sampler("cachepoints", one.lights, one.accel)->name(), "power");
  EXPECT_STREQ(make_light_sampler("auto", one.lights, one.accel)->name(), "power");
  EXPECT_THROW(make_light_sampler("bvh2", one.lights, one.accel), Error);
}

// The locally optimal sampler: a distribution over every emitter that sampling
// draws from (chi-square), on a street of varied radiances and on one where a
// third of the quads are black (only the uniform share reaches them).  Small
// streets (65 and 64 emitters) and 50k samples: every sample and pmf costs a
// pass over all emitters.
TEST(LocalSampler, SamplingMatchesItsPmfWhichSumsToOne) {
  for (const std::string& text : {street_scene(4, varied, true), street_scene(4, dark, false)}) {
    LightFixture f(text);
    LocalLightSampler s(f.lights, CachePointParams{}.uniform_share);
    EXPECT_STREQ(s.name(), "local");
    EXPECT_TRUE(s.chooses_primitives());
    EXPECT_FALSE(s.wants_feedback());
    expect_sampling_matches_pmf(s, 2, 50000);
  }
}

// It proportions to the estimate: an emitter of zero importance gets only the
// uniform share, and among the others the pmf minus that share is in
// proportion to emitter_importance.
TEST(LocalSampler, PmfIsTheUniformShareAndTheImportanceShare) {
  LightFixture f(street_scene(6, dark, false));
  const float share = CachePointParams{}.uniform_share;
  LocalLightSampler s(f.lights, share);
  const size_t n = s.emitters().size();
  for (const LightSampleContext& ctx : vertices()) {
    double total = 0.0;
    for (const Emitter& e : s.emitters().emitters) total += double(emitter_importance(f.lights, e, ctx.p, ctx.ng));
    ASSERT_GT(total, 0.0);
    for (const Emitter& e : s.emitters().emitters) {
      const double w = double(emitter_importance(f.lights, e, ctx.p, ctx.ng));
      EXPECT_NEAR(double(s.pmf_primitive(ctx, e.light, e.primitive)),
                  double(share) / double(n) + (1.0 - double(share)) * w / total, 1e-6);
    }
  }
}

// Cache points with too few points choose exactly as `local` does (one
// implementation), and `auto` never picks `local`.
TEST(LocalSampler, IsTheCachePointsFallbackAndAutoNeverPicksIt) {
  LightFixture f(street_scene(4, varied, true));
  CachePointParams p;
  p.object_candidates = 0;
  p.pilot_width = p.pilot_height = 2;
  p.pilot_depth = 1;
  CachePointSampler few(f.lights, f.accel, p);
  ASSERT_EQ(few.point_count(), 0u);
  LocalLightSampler local(f.lights, p.uniform_share);
  for (const LightSampleContext& ctx : vertices()) {
    for (const Emitter& e : local.emitters().emitters)
      ASSERT_EQ(few.pmf_primitive(ctx, e.light, e.primitive), local.pmf_primitive(ctx, e.light, e.primitive));
    for (float u : {0.01f, 0.3f, 0.7f, 0.999f}) {
      auto a = few.sample(ctx, u), b = local.sample(ctx, u);
      ASSERT_EQ(bool(a), bool(b));
      if (a) {
        EXPECT_TRUE(a->light == b->light && a->primitive == b->primitive && a->pmf == b->pmf);
      }
    }
  }
  EXPECT_STREQ(make_light_sampler("local", f.lights, f.accel)->name(), "local");
  LightFixture many(street_scene(16, varied, true));  // 1,025 emitters
  EXPECT_STREQ(make_light_sampler("auto", many.lights, many.accel)->name(), "cachepoints");
  EXPECT_STREQ(make_light_sampler("auto", f.lights, f.accel)->name(), "bvh");
}

// Build and selection at scale: 1,000,000 emitters (one mesh light's
// triangles) build, each point's lists stay within what the parameters allow
// (max_near near, at most max_far per bin far), the tables' memory is what
// the lists need, not points x emitters, and the pmf sums to one at a vertex
// under the ceiling and one in the air.  25 points: the cost under test is
// the emitters'.  These sparse points' near radius, 4 point radii, covers the
// whole ceiling; the cull forces only what may hold the max_near nearest, so
// a point evaluates a small share of the emitters (measured 1.2%; all of them
// when everything within the near radius was forced).  About 9 CPU-s.
TEST(CachePoints, MillionEmittersBuildBoundedListsAndSumToOne) {
  TempDir dir("theia_million_emitters");
  LightFixture f(million_light_scene(dir));
  CachePointParams p;
  p.object_candidates = 16;
  p.pilot_width = 4;
  p.pilot_height = 3;
  CachePointSampler s(f.lights, f.accel, p);
  ASSERT_EQ(s.emitters().size(), 1000000u);
  ASSERT_GE(s.point_count(), size_t(p.min_points));
  const size_t bound = size_t(p.max_near + kSensorBins * p.max_far);
  size_t largest = 0;
  for (size_t c = 0; c < s.point_count(); ++c) largest = std::max(largest, s.listed(c).size());
  EXPECT_LE(largest, bound);
  EXPECT_GT(largest, 0u);
  std::map<std::string, double> stats;
  for (const auto& [key, value] : s.statistics()) stats[key] = value;
  EXPECT_LE(stats["mean_near_lights"], double(p.max_near));
  EXPECT_LT(stats["mean_emitters_evaluated"], 0.05 * double(s.emitters().size()));
  EXPECT_LT(stats["memory_bytes"], double(s.emitters().size() * sizeof(Emitter)) +
                                       double(s.point_count() * bound) * 64.0);
  for (const LightSampleContext& ctx : {vertices()[0], vertices()[3]}) {
    const auto& all = s.emitters().emitters;
    const double sum = tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, all.size()), 0.0,
        [&](const tbb::blocked_range<size_t>& r, double acc) {
          for (size_t e = r.begin(); e < r.end(); ++e) acc += double(s.pmf_primitive(ctx, all[e].light, all[e].primitive));
          return acc;
        },
        std::plus<double>());
    EXPECT_NEAR(sum, 1.0, 1e-4);
    for (int i = 0; i < 16; ++i) {
      auto sl = s.sample(ctx, (float(i) + 0.5f) / 16.0f);
      ASSERT_TRUE(sl);
      EXPECT_EQ(sl->pmf, s.pmf_primitive(ctx, sl->light, sl->primitive));
    }
  }
}
