// The saved guiding field (guiding/field_file.h): exact round trip, corrupt and
// other-version files refused, per-leaf statistics against the tree's own
// counters and an independent count, the saved quadtrees against SDTree::pdf.
#include "guiding/field_file.h"

#include "core/hash.h"
#include "core/log.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <map>
#include <random>

using namespace theia;

namespace {

const Bounds3 kBox(vec3(-1.0f), vec3(1.0f));

// A light above +z: radiance 1 within 0.3 rad of +z, otherwise 0 (a third of the samples are zero).
std::vector<SDTreeSample> iteration_samples(std::mt19937& rng, size_t n, bool with_invalid) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<SDTreeSample> out;
  for (size_t i = 0; i < n; ++i) {
    SDTreeSample s;
    s.p = vec3(2.0f * u(rng) - 1.0f, 2.0f * u(rng) - 1.0f, 0.5f * u(rng) - 1.0f);
    const float z = 2.0f * u(rng) - 1.0f, phi = 2.0f * kPi * u(rng), r = std::sqrt(std::max(0.0f, 1.0f - z * z));
    s.wi = vec3(r * std::cos(phi), r * std::sin(phi), z);
    s.radiance = z > std::cos(0.3f) ? 2.0f : (u(rng) < 0.5f ? 0.0f : 0.1f);
    s.pdf = 1.0f / (4.0f * kPi);
    s.key = hash(uint64_t(rng()), uint64_t(i));
    if (with_invalid && i % 97 == 0) s.radiance = std::nanf("");  // dropped by the tree
    out.push_back(s);
  }
  return out;
}

SDTreeOptions small_threshold() {
  SDTreeOptions o;
  o.spatial_threshold = 2000.0;
  return o;
}

// Trains `iterations` iterations, the recorder watching; returns every snapshot.
std::vector<FieldSnapshot> train(SDTree& tree, FieldRecorder& recorder, int iterations, size_t n, uint32_t seed,
                                 std::vector<std::vector<SDTreeSample>>* batches = nullptr) {
  std::mt19937 rng(seed);
  std::vector<FieldSnapshot> snaps;
  for (int it = 0; it < iterations; ++it) {
    std::vector<SDTreeSample> s = iteration_samples(rng, n, true);
    recorder.add(tree, s);
    tree.add_samples(s);
    tree.update();
    snaps.push_back(recorder.snapshot(tree, it, uint32_t(it + 1)));
    if (batches) batches->push_back(std::move(s));
  }
  return snaps;
}

FieldFile sample_file() {
  SDTree tree(kBox, small_threshold());
  FieldRecorder recorder;
  FieldFile f;
  f.camera.eye = vec3(0, 0, -5);
  f.camera.fov_y_degrees = 40.0f;
  f.camera.width = 64, f.camera.height = 48, f.camera.mirrored = 1;
  f.scene_bounds = kBox;
  f.root_bounds = tree.root_bounds();
  f.wireframe.p = {vec3(0), vec3(1, 0, 0), vec3(0, 1, 0)};
  f.wireframe.scene_triangles = 1;
  f.snapshots = train(tree, recorder, 3, 6000, 7);
  return f;
}

}  // namespace

TEST(FieldFile, RoundTripsExactly) {
  const FieldFile f = sample_file();
  ASSERT_GT(f.snapshots.back().leaves.size(), 1u) << "the test wants a field that split";
  const std::vector<uint8_t> bytes = serialize_field(f);
  const FieldFile g = deserialize_field(bytes, "test.field");
  EXPECT_EQ(serialize_field(g), bytes);
  ASSERT_EQ(g.snapshots.size(), f.snapshots.size());
  for (size_t s = 0; s < f.snapshots.size(); ++s) {
    const FieldSnapshot &a = f.snapshots[s], &b = g.snapshots[s];
    EXPECT_EQ(a.columns, b.columns);
    EXPECT_EQ(a.table, b.table);
    EXPECT_EQ(a.summary, b.summary);
    ASSERT_EQ(a.leaves.size(), b.leaves.size());
    for (size_t l = 0; l < a.leaves.size(); ++l) {
      EXPECT_EQ(a.leaves[l].quadtree.size(), b.leaves[l].quadtree.size());
      EXPECT_EQ(0, std::memcmp(a.leaves[l].quadtree.data(), b.leaves[l].quadtree.data(),
                               a.leaves[l].quadtree.size() * sizeof(SamplingQuadNode)));
      EXPECT_EQ(a.leaves[l].samples.size(), b.leaves[l].samples.size());
    }
  }
  EXPECT_EQ(g.camera.eye, f.camera.eye);
  EXPECT_EQ(g.camera.mirrored, 1);
  EXPECT_EQ(g.wireframe.p, f.wireframe.p);
}

TEST(FieldFile, CorruptTruncatedOrOtherVersionIsRefused) {
  const std::vector<uint8_t> good = serialize_field(sample_file());
  auto refused = [](std::vector<uint8_t> bytes, const std::string& expect) {
    try {
      deserialize_field(bytes, "f.field");
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("f.field: "), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(expect), std::string::npos) << e.what();
      return;
    }
    ADD_FAILURE() << "accepted: expected '" << expect << "'";
  };
  std::vector<uint8_t> flipped = good;
  flipped[flipped.size() / 2] ^= 0x10;
  refused(flipped, "checksum");
  refused(std::vector<uint8_t>(good.begin(), good.end() - 9), "checksum");
  refused(std::vector<uint8_t>(good.begin(), good.begin() + 10), "not a theia field file");
  std::vector<uint8_t> version = good;
  version[8] = 99;
  refused(version, "version 99");
  std::vector<uint8_t> magic = good;
  magic[0] = 'X';
  refused(magic, "not a theia field file");

  // A well-formed checksum over a malformed quadtree (a child pointing back at its parent).
  FieldFile f = sample_file();
  FieldLeaf& leaf = f.snapshots.back().leaves.front();
  ASSERT_GT(leaf.quadtree.size(), 1u);
  leaf.quadtree[1].child[0] = 1;
  refused(serialize_field(f), "malformed");
}

// Random bytes changed and the checksum made to match again: the reader
// either reads a field or throws theia::Error, never anything else.
TEST(FieldFile, AnyModifiedByteIsReadOrRefusedCleanly) {
  const std::vector<uint8_t> good = serialize_field(sample_file());
  std::mt19937 rng(17);
  int refused = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    std::vector<uint8_t> bytes = good;
    const int changes = 1 + trial % 4;
    for (int c = 0; c < changes; ++c) {
      // Headers and counts sit early in the file: half the changes land in the first 256 bytes.
      const size_t limit = trial % 2 ? 256 : bytes.size() - 8;
      bytes[12 + rng() % (limit - 12)] = uint8_t(rng());
    }
    const uint64_t checksum = hash_bytes(bytes.data(), bytes.size() - 8);
    std::memcpy(bytes.data() + bytes.size() - 8, &checksum, 8);
    try {
      const FieldFile f = deserialize_field(bytes, "f.field");
      for (const FieldSnapshot& s : f.snapshots) EXPECT_EQ(s.table.size(), s.leaves.size() * s.columns.size());
    } catch (const Error&) {
      ++refused;
    }
  }
  EXPECT_GT(refused, 100);
}

// Every recorded sample is filed under exactly one leaf: the per-iteration
// counts add up to the tree's recorded count, and each leaf's counts are the
// ones an independent bucketing by SDTree::leaf_bounds gives.
TEST(FieldRecorder, StatisticsAgreeWithTheTrainersCounters) {
  SDTree tree(kBox, small_threshold());
  FieldRecorder recorder;
  std::vector<std::vector<SDTreeSample>> batches;
  const std::vector<FieldSnapshot> snaps = train(tree, recorder, 3, 6000, 11, &batches);
  for (size_t it = 0; it < snaps.size(); ++it) {
    const FieldSnapshot& s = snaps[it];
    const int iteration = s.column("samples_iteration"), nonzero = s.column("samples_nonzero_iteration");
    ASSERT_GE(iteration, 0);
    ASSERT_GE(nonzero, 0);
    double sum = 0.0;
    for (size_t l = 0; l < s.leaves.size(); ++l) sum += s.value(l, iteration);
    const auto recorded = std::find_if(s.summary.begin(), s.summary.end(),
                                       [](const auto& kv) { return kv.first == "samples_recorded"; });
    ASSERT_NE(recorded, s.summary.end());
    EXPECT_EQ(sum, recorded->second) << "iteration " << it;
    const auto dropped = std::find_if(s.summary.begin(), s.summary.end(),
                                      [](const auto& kv) { return kv.first == "samples_dropped"; });
    EXPECT_EQ(dropped->second, double((6000 + 96) / 97)) << "one NaN sample in 97 is dropped";
  }
  // The last iteration's samples, bucketed by the final tree through its own lookup.
  const FieldSnapshot& last = snaps.back();
  std::map<std::array<float, 6>, std::pair<double, double>> expected;
  for (const SDTreeSample& s : batches.back()) {
    if (!std::isfinite(s.radiance)) continue;
    const Bounds3 b = tree.leaf_bounds(s.p);
    auto& [n, nz] = expected[{b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z}];
    n += 1.0, nz += s.radiance > 0.0f ? 1.0 : 0.0;
  }
  size_t checked = 0;
  for (size_t l = 0; l < last.leaves.size(); ++l) {
    const Bounds3& b = last.leaves[l].box;
    const auto [n, nz] = expected[{b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z}];
    EXPECT_EQ(last.value(l, last.column("samples_iteration")), n) << "leaf " << l;
    EXPECT_EQ(last.value(l, last.column("samples_nonzero_iteration")), nz) << "leaf " << l;
    EXPECT_GE(last.value(l, last.column("samples")), n);
    EXPECT_EQ(last.value(l, last.column("tree_sample_count")), tree.leaf(uint32_t(l)).sample_count);
    EXPECT_LE(last.leaves[l].samples.size(), FieldRecorder::kReservoir);
    checked += n > 0;
  }
  EXPECT_GT(checked, 1u);
}

// Without the spatial filter a sample trains the leaf holding it, so in a
// field that has never split the leaf's count is the tree's own.
TEST(FieldRecorder, CountsEqualTheTreesWhereNothingSplit) {
  SDTreeOptions o;
  o.spatial_filter = false;
  o.spatial_threshold = 1e9;
  SDTree tree(kBox, o);
  FieldRecorder recorder;
  const std::vector<FieldSnapshot> snaps = train(tree, recorder, 2, 3000, 5);
  const FieldSnapshot& s = snaps.back();
  ASSERT_EQ(s.leaves.size(), 1u);
  EXPECT_EQ(s.value(0, s.column("samples")), tree.leaf(0).sample_count);
  EXPECT_EQ(s.value(0, s.column("samples")), 2.0 * (3000 - (3000 + 96) / 97));
  EXPECT_EQ(s.leaves[0].samples.size(), FieldRecorder::kReservoir);
}

TEST(FieldRecorder, IsIndependentOfSampleOrder) {
  SDTree a(kBox, small_threshold()), b(kBox, small_threshold());
  FieldRecorder ra, rb;
  std::mt19937 rng(3);
  std::vector<SDTreeSample> s = iteration_samples(rng, 5000, false);
  ra.add(a, s);
  a.add_samples(s);
  a.update();
  std::vector<SDTreeSample> shuffled = s;
  std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937(9));
  rb.add(b, shuffled);
  b.add_samples(s);
  b.update();
  const FieldSnapshot sa = ra.snapshot(a, 0, 1), sb = rb.snapshot(b, 0, 1);
  ASSERT_EQ(sa.leaves.size(), sb.leaves.size());
  for (size_t l = 0; l < sa.leaves.size(); ++l) {
    ASSERT_EQ(sa.leaves[l].samples.size(), sb.leaves[l].samples.size());
    for (size_t k = 0; k < sa.leaves[l].samples.size(); ++k)
      EXPECT_EQ(sa.leaves[l].samples[k].wi, sb.leaves[l].samples[k].wi);
    for (const char* c : {"samples", "samples_nonzero", "samples_min_x", "samples_max_z"})
      EXPECT_EQ(sa.value(l, sa.column(c)), sb.value(l, sb.column(c))) << c;
  }
}

// The saved quadtree gives the density the renderer samples with: SDTree::pdf x 4 pi.
TEST(FieldDensity, MatchesTheTreesPdf) {
  SDTree tree(kBox, small_threshold());
  FieldRecorder recorder;
  const FieldSnapshot s = train(tree, recorder, 3, 6000, 13).back();
  const std::vector<Bounds3> boxes = tree.leaf_boxes();
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  size_t compared = 0;
  for (size_t l = 0; l < s.leaves.size(); ++l) {
    EXPECT_EQ(s.leaves[l].box.min, boxes[l].min);
    const vec3 centre = boxes[l].centroid();
    EXPECT_EQ(tree.leaf_index(centre), l);
    EXPECT_EQ(tree.leaf_bounds(centre).min, boxes[l].min);
    EXPECT_EQ(tree.leaf_bounds(centre).max, boxes[l].max);
    EXPECT_EQ(s.leaf_at(centre), l);
    if (s.leaves[l].quadtree.empty()) continue;
    for (int k = 0; k < 200; ++k) {
      const vec3 w = sd_square_to_direction(vec2(u(rng), u(rng)));
      const double saved = field_density(s.leaves[l].quadtree, sd_direction_to_square(w)) / (4.0 * M_PI);
      EXPECT_NEAR(saved, double(tree.pdf(uint32_t(l), w)), 1e-6 * saved) << "leaf " << l;
      ++compared;
    }
  }
  EXPECT_GT(compared, 0u);
}

namespace {

// A mixture field trained beside its tree, the recorder taking snapshots with it.
struct MixtureRun {
  SDTree tree{kBox, small_threshold()};
  VMMField field{tree, VMMOptions{}};
  FieldRecorder recorder;
  FieldSnapshot last;
  MixtureRun() {
    std::mt19937 rng(5);
    for (int it = 0; it < 3; ++it) {
      const std::vector<SDTreeSample> s = iteration_samples(rng, 6000, false);
      std::vector<VMMSample> v;
      for (const SDTreeSample& t : s) v.push_back({t.p, t.wi, t.radiance, t.pdf, 1.5f});
      recorder.add(tree, s);
      tree.add_samples(s);
      field.add_samples(v);
      tree.update();
      field.update();
      last = recorder.snapshot(tree, it, uint32_t(it + 1), &field);
    }
  }
};

}  // namespace

// A file with mixtures is version 2 and round-trips them; one without (an
// SD-tree field) is still written as version 1, byte for byte as before.
TEST(FieldFile, MixturesRoundTripAndAnSDTreeFileStaysVersion1) {
  const FieldFile sdtree = sample_file();
  const std::vector<uint8_t> v1 = serialize_field(sdtree);
  EXPECT_EQ(v1[8], 1);
  EXPECT_EQ(serialize_field(deserialize_field(v1, "v1")), v1);

  MixtureRun run;
  FieldFile f = sample_file();
  f.snapshots.push_back(run.last);
  const std::vector<uint8_t> v2 = serialize_field(f);
  EXPECT_EQ(v2[8], 2);
  const FieldFile g = deserialize_field(v2, "v2");
  EXPECT_EQ(serialize_field(g), v2);
  const FieldSnapshot& s = g.snapshots.back();
  size_t mixtures = 0;
  for (size_t l = 0; l < s.leaves.size(); ++l) {
    ASSERT_EQ(s.leaves[l].lobes.size(), run.last.leaves[l].lobes.size());
    EXPECT_EQ(s.leaves[l].pivot, run.last.leaves[l].pivot);
    if (s.leaves[l].lobes.empty()) continue;
    ++mixtures;
    EXPECT_EQ(std::memcmp(s.leaves[l].lobes.data(), run.field.region_state(uint32_t(l)).mixture.lobes.data(),
                          sizeof(VMMLobe) * kVMMLobes),
              0);
  }
  EXPECT_GT(mixtures, 1u);

  // A well-formed checksum over a malformed mixture (three lobes) is refused.
  FieldFile bad = f;
  for (FieldLeaf& leaf : bad.snapshots.back().leaves)
    if (!leaf.lobes.empty()) leaf.lobes.resize(3);
  try {
    deserialize_field(serialize_field(bad), "bad.field");
    ADD_FAILURE() << "a three-lobe mixture was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("mixture is malformed"), std::string::npos) << e.what();
  }
}

// The saved mixture gives the density the field samples with, seen from any
// point in the leaf (each lobe re-pointed from the pivot: vmm_at), x 4 pi; the
// columns say how many lobes are active and how concentrated they are.
TEST(FieldDensity, MixtureMatchesTheFieldsPdfWithParallax) {
  MixtureRun run;
  const FieldSnapshot& s = run.last;
  const int active = s.column("vmm_active_lobes"), kappa_max = s.column("vmm_kappa_max");
  ASSERT_GE(active, 0);
  ASSERT_GE(kappa_max, 0);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  size_t compared = 0;
  for (size_t l = 0; l < s.leaves.size(); ++l) {
    const VMMRegion& region = run.field.region_state(uint32_t(l));
    EXPECT_EQ(s.leaves[l].lobes.empty(), !region.fitted);
    EXPECT_TRUE(s.leaves[l].quadtree.empty());
    if (!region.fitted) continue;
    const VMMSummary m = vmm_summary(region.mixture);
    EXPECT_EQ(s.value(l, active), double(m.active_lobes));
    EXPECT_EQ(s.value(l, kappa_max), double(m.kappa_max));
    EXPECT_GE(m.active_lobes, 1);
    for (int k = 0; k < 50; ++k) {
      const Bounds3& b = s.leaves[l].box;
      const vec3 p = b.min + vec3(u(rng), u(rng), u(rng)) * b.diagonal();
      const vec2 c(u(rng), u(rng));
      const vec3 w = sd_square_to_direction(c);
      const double expected = double(vmm_pdf(vmm_at(region.mixture, region.pivot, p), w));
      EXPECT_NEAR(field_leaf_density(s.leaves[l], p, c) / (4.0 * M_PI), expected, 1e-6 * expected) << l;
      ++compared;
    }
    // At the centre of the field's lookup cell (VMMField::mixture_at: 2^bits cells per axis), the renderer's own pdf.
    const Bounds3& box = s.leaves[l].box;
    const int bits = std::min(VMMField::kVMMCellBits, (31 - int(std::bit_width(s.leaves.size()))) / 3);
    const vec3 q = glm::floor(box.offset(box.centroid()) * float(1u << bits));
    const vec3 cell = box.min + (q + 0.5f) / float(1u << bits) * box.diagonal();
    const uint32_t handle = run.field.region(cell);
    ASSERT_NE(handle, kNoGuideRegion);
    const vec2 c(0.8f, 0.3f);
    const double renderer = run.field.pdf(handle, sd_square_to_direction(c));
    EXPECT_NEAR(field_leaf_density(s.leaves[l], cell, c) / (4.0 * M_PI), renderer, 1e-6 * renderer) << l;
  }
  EXPECT_GT(compared, 0u);
}
