// The vMF mixture field (guiding/vmm.h): sampling against its pdf
// (chi-square), the pdf's integral, EM recovering a known mixture from
// weighted samples, the MAP prior with few samples, parallax re-pointing of
// a point source, the field's regions over the SD-tree's leaves, and
// determinism across thread counts.
#include "guiding/vmm.h"

#include "core/hash.h"
#include "core/log.h"
#include "core/sampling.h"
#include "guiding/sd_tree.h"
#include "tests/unit/chi2.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstring>
#include <functional>

using namespace theia;

namespace {

vec2 u2(uint64_t h) { return {to_unit_float(uint32_t(h)), to_unit_float(uint32_t(h >> 32))}; }

// Integral over the sphere by the midpoint rule on an n x n grid of the
// equal-area square (d omega = 4 pi dx dy).
double integrate_sphere(const std::function<double(const vec3&)>& f, int n = 1024) {
  double sum = 0.0;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) sum += f(sd_square_to_direction(vec2((x + 0.5f) / n, (y + 0.5f) / n)));
  return sum * 4.0 * double(kPi) / (double(n) * n);
}

VMMixture mixture(std::initializer_list<VMMLobe> lobes) {
  VMMixture m;
  for (VMMLobe& l : m.lobes) l = VMMLobe{vec3(0, 0, 1), 0.0f, 0.0f, 0.0f};
  size_t i = 0;
  for (const VMMLobe& l : lobes) m.lobes[i++] = l;
  return m;
}

Chi2Result chi2(const VMMixture& m, const std::string& name, int n_tests) {
  return chi2_test_sphere(
      [&](vec2 u, float) -> std::optional<vec3> {
        GuideSample s = vmm_sample(m, u);
        if (!(s.pdf > 0.0f)) return std::nullopt;
        return s.wi;
      },
      [&](vec3 w) { return vmm_pdf(m, w); }, 200'000, 32, 64, 0.01, n_tests, name);
}

const Bounds3 kUnitBox(vec3(-1.0f), vec3(1.0f));

// An SD-tree that splits space at `spatial_threshold` samples (1e15: one leaf).
SDTreeOptions splitting_at(double spatial_threshold) {
  SDTreeOptions o;
  o.spatial_threshold = spatial_threshold;
  return o;
}

}  // namespace

TEST(VMMChi2, SampleMatchesPdf) {
  const vec3 a = glm::normalize(vec3(0.3f, -0.5f, 0.8f)), b = glm::normalize(vec3(-0.4f, 0.7f, 0.2f));
  const std::vector<std::pair<std::string, VMMixture>> cases = {
      {"uniform", mixture({{a, 0.0f, 1.0f, 0.0f}})},
      {"wide", mixture({{a, 0.7f, 1.0f, 0.0f}})},
      {"three lobes", mixture({{a, 40.0f, 0.5f, 0.0f}, {b, 3.0f, 0.3f, 0.0f}, {-a, 400.0f, 0.2f, 0.0f}})},
      {"narrow", mixture({{b, 5000.0f, 0.9f, 0.0f}, {a, 1.0f, 0.1f, 0.0f}})},
      {"initial", vmm_initial()},
      {"re-pointed", vmm_at(mixture({{a, 40.0f, 0.6f, 0.5f}, {b, 100.0f, 0.4f, 2.0f}}), vec3(0.0f),
                            vec3(0.3f, 0.2f, -0.1f))},
  };
  for (const auto& [name, m] : cases) {
    Chi2Result r = chi2(m, name, int(cases.size()));
    EXPECT_TRUE(r.passed) << r.report;
  }
}

TEST(VMMPdf, IntegratesToOneAndSamplesAreUnit) {
  const vec3 mu = glm::normalize(vec3(0.2f, 0.9f, -0.3f));
  for (float kappa : {0.0f, 1e-4f, 0.5f, 10.0f, 200.0f, 3000.0f}) {
    const double integral = integrate_sphere([&](const vec3& w) { return double(vmf_pdf(mu, kappa, w)); }, 2048);
    EXPECT_NEAR(integral, 1.0, 2e-3) << kappa;
    for (int i = 0; i < 1000; ++i) {
      const vec3 w = vmf_sample(mu, kappa, u2(hash(uint64_t(i), 5)));
      ASSERT_NEAR(glm::length(w), 1.0f, 1e-5f);
      ASSERT_GT(vmf_pdf(mu, kappa, w), 0.0f);
    }
  }
  // The extremes of u stay finite (xi = 1 - u never reaches 0).
  for (vec2 u : {vec2(0.0f), vec2(kOneMinusEpsilon), vec2(0.0f, kOneMinusEpsilon)}) {
    const vec3 w = vmf_sample(mu, 10000.0f, u);
    EXPECT_TRUE(std::isfinite(w.x) && std::isfinite(w.y) && std::isfinite(w.z));
    EXPECT_TRUE(std::isfinite(vmf_pdf(mu, 10000.0f, w)));
  }
  for (float r : {0.0f, 0.3f, 0.9f, 0.999f}) EXPECT_NEAR(vmf_mean_cosine(vmf_kappa_from_mean_cosine(r)), r, 0.02f);
  EXPECT_NEAR(integrate_sphere([&](const vec3& w) { return double(vmm_pdf(vmm_initial(), w)); }), 1.0, 1e-3);
}

// Radiance that is a known 2-lobe mixture, seen through uniformly drawn
// directions (weights L / pdf): EM finds it.
TEST(VMMFit, RecoversAKnownTwoLobeMixtureFromWeightedSamples) {
  const VMMixture truth = mixture({{glm::normalize(vec3(0.5f, -0.2f, 0.8f)), 20.0f, 0.3f, 0.0f},
                                   {glm::normalize(vec3(-0.6f, 0.6f, -0.1f)), 200.0f, 0.7f, 0.0f}});
  VMMOptions o;
  o.pdf_floor = 0.0f;
  VMMRegion region;
  for (int it = 0; it < 4; ++it) {
    std::vector<VMMSample> samples;
    for (int i = 0; i < 20'000; ++i) {
      const vec3 w = sample_uniform_sphere(u2(hash(uint64_t(it), uint64_t(i), 11)));
      samples.push_back({vec3(0.0f), w, 3.0f * vmm_pdf(truth, w), uniform_sphere_pdf(), 0.0f});
    }
    vmm_fit(region, samples, o);
  }
  ASSERT_TRUE(region.fitted);
  const double l1 = integrate_sphere(
      [&](const vec3& w) { return std::abs(double(vmm_pdf(region.mixture, w)) - double(vmm_pdf(truth, w))); }, 512);
  EXPECT_LT(l1, 0.1);
  double weights = 0.0;
  for (const VMMLobe& l : region.mixture.lobes) weights += l.weight;
  EXPECT_NEAR(weights, 1.0, 1e-5);
}

// A handful of samples from one direction: the prior keeps the lobe wide
// enough that the field still samples around it, and nothing is NaN.
TEST(VMMFit, FewSamplesKeepLobesWideAndFinite) {
  VMMRegion region;
  std::vector<VMMSample> samples(3, VMMSample{vec3(0.0f), vec3(0, 0, 1), 5.0f, 1.0f, 0.0f});
  samples.push_back({vec3(0.0f), vec3(0, 0, 1), std::numeric_limits<float>::quiet_NaN(), 1.0f, 0.0f});
  samples.push_back({vec3(0.0f), vec3(1, 0, 0), 1.0f, 0.0f, 0.0f});  // pdf 0: dropped
  vmm_fit(region, samples, VMMOptions{});
  ASSERT_TRUE(region.fitted);
  float kappa_max = 0.0f;
  for (const VMMLobe& l : region.mixture.lobes) {
    EXPECT_TRUE(std::isfinite(l.kappa) && std::isfinite(l.weight) && std::isfinite(l.mu.x));
    kappa_max = std::max(kappa_max, l.kappa);
  }
  EXPECT_LT(kappa_max, 50.0f);
  EXPECT_GT(vmm_pdf(region.mixture, vec3(0, 0, 1)), 0.5f);
  EXPECT_GT(vmm_pdf(region.mixture, vec3(0, 0, -1)), 0.0f);
}

// A point source seen from positions spread over a region: with parallax the
// lobe found from the pivot, re-pointed to two lookup positions, points at
// the source from each; without it, one direction for both.
TEST(VMMParallax, PointSourceIsRepointedFromEachPosition) {
  const vec3 source(0.2f, 2.0f, 0.5f);
  auto train = [&](bool parallax) {
    VMMOptions o;
    o.parallax = parallax;
    VMMRegion region;
    for (int it = 0; it < 3; ++it) {
      std::vector<VMMSample> samples;
      for (int i = 0; i < 4000; ++i) {
        const uint64_t h = hash(uint64_t(it), uint64_t(i), 3);
        const vec3 p = vec3(u2(h).x, 0.0f, u2(h).y) * 1.2f - vec3(0.6f, 0.0f, 0.6f);
        const vec3 d = source - p;
        samples.push_back({p, glm::normalize(d), 1.0f, 1.0f, glm::length(d)});
      }
      vmm_fit(region, samples, o);
    }
    return region;
  };
  const VMMRegion with = train(true), without = train(false);
  EXPECT_NEAR(glm::length(with.pivot), 0.0f, 0.05f);
  for (const vec3& q : {vec3(0.5f, 0.0f, -0.5f), vec3(-0.5f, 0.0f, 0.4f)}) {
    const vec3 to_source = glm::normalize(source - q);
    const VMMixture m = vmm_at(with.mixture, with.pivot, q);
    // EM may share the source between lobes: what points at it counts.
    float towards = 0.0f;
    for (const VMMLobe& l : m.lobes) {
      if (!(glm::dot(l.mu, to_source) > std::cos(radians(1.0f)))) continue;
      towards += l.weight;
      EXPECT_NEAR(1.0f / l.inv_distance, glm::length(source - with.pivot), 0.05f);
    }
    EXPECT_GT(towards, 0.9f) << q.x;
    // Re-pointed, the lobe is narrow (one direction per position): far
    // denser towards the source than the blurred lobe fitted without parallax.
    EXPECT_GT(vmm_pdf(m, to_source), 5.0f * vmm_pdf(without.mixture, to_source)) << q.x;
  }
}

// The field over the SD-tree's leaves: no region before training, handles
// that re-point to the lookup position, sample() and pdf() agreeing.
TEST(VMMField, RegionsFollowTheTreeAndRepointPerPosition) {
  SDTree tree(kUnitBox, splitting_at(1e15));
  VMMField field(tree, VMMOptions{});
  EXPECT_EQ(field.region(vec3(0.0f)), kNoGuideRegion);
  const vec3 source(0.0f, 0.9f, 0.0f);
  std::vector<VMMSample> samples;
  for (int i = 0; i < 5000; ++i) {
    const vec2 u = u2(hash(uint64_t(i), 21));
    const vec3 p(u.x - 0.5f, -0.9f, u.y - 0.5f);
    const vec3 d = source - p;
    samples.push_back({p, glm::normalize(d), 1.0f, 1.0f, glm::length(d)});
    tree.add_sample(p, glm::normalize(d), 1.0f, 1.0f, uint64_t(i));
  }
  field.add_samples(samples);
  tree.update();
  field.update();
  for (const vec3& q : {vec3(0.45f, -0.9f, 0.45f), vec3(-0.45f, -0.9f, 0.0f)}) {
    const uint32_t r = field.region(q);
    ASSERT_NE(r, kNoGuideRegion);
    const vec3 to_source = glm::normalize(source - q);
    double mean_cos = 0.0;
    for (int i = 0; i < 1000; ++i) {
      const GuideSample s = field.sample(r, u2(hash(uint64_t(i), 77)));
      ASSERT_GT(s.pdf, 0.0f);
      EXPECT_NEAR(s.pdf, field.pdf(r, s.wi), 1e-3f * s.pdf);
      mean_cos += glm::dot(s.wi, to_source) / 1000.0;
    }
    EXPECT_GT(mean_cos, 0.98) << q.x;
  }
  EXPECT_EQ(field.selection_probability(kNoGuideRegion), tree.selection_probability(kNoGuideRegion));
  EXPECT_EQ(field.pdf(kNoGuideRegion, vec3(0, 0, 1)), 0.0f);
}

namespace {

// Iteration `it` of a training run with splits: the tree's samples and the field's.
void train(SDTree& tree, VMMField& field, int it) {
  std::vector<VMMSample> samples;
  std::vector<SDTreeSample> tree_samples;
  for (int i = 0; i < 8000; ++i) {
    const uint64_t h = hash(uint64_t(it), uint64_t(i), 9);
    const vec3 p = vec3(u2(h).x, u2(hash(h, 1)).x, u2(h).y) * 2.0f - 1.0f;
    const vec3 w = sample_uniform_sphere(u2(hash(h, 2)));
    const float L = w.y > 0.7f ? 4.0f : 0.1f;
    samples.push_back({p, w, L, uniform_sphere_pdf(), 1.0f + u2(h).y});
    tree_samples.push_back({p, w, L, uniform_sphere_pdf(), h});
  }
  tree.add_samples(tree_samples);
  field.add_samples(samples);
  tree.update();
  field.update();
}

}  // namespace

// Training is a pure function of the samples: the same mixtures, bit for
// bit, with 1, 2 or 4 threads, through spatial splits.
TEST(VMMField, DeterministicAcrossThreadCountsThroughSplits) {
  auto run = [](int threads) {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, size_t(threads));
    SDTree tree(kUnitBox, splitting_at(2000.0));
    VMMField field(tree, VMMOptions{});
    for (int it = 0; it < 4; ++it) train(tree, field, it);
    std::vector<VMMixture> out;
    for (uint32_t l = 0; l < field.region_count(); ++l) out.push_back(field.region_state(l).mixture);
    return out;
  };
  const std::vector<VMMixture> one = run(1);
  EXPECT_GT(one.size(), 4u);
  for (int threads : {2, 4}) {
    const std::vector<VMMixture> other = run(threads);
    ASSERT_EQ(one.size(), other.size());
    for (size_t l = 0; l < one.size(); ++l)
      EXPECT_EQ(std::memcmp(&one[l], &other[l], sizeof(VMMixture)), 0) << threads << " threads, leaf " << l;
  }
}

// The checkpoint's state: a field restored after two iterations (over the
// tree restored from its own bytes) trains on and samples exactly as the one
// that never stopped, through further splits.
TEST(VMMCheckpoint, RestoredFieldContinuesBitForBit) {
  SDTree tree(kUnitBox, splitting_at(2000.0));
  VMMField field(tree, VMMOptions{});
  EXPECT_NO_THROW(VMMField(tree, VMMOptions{}).restore(field.serialize(), "fresh"));
  for (int it = 0; it < 2; ++it) train(tree, field, it);
  // Samples added but not yet fitted travel too.
  field.add_samples(std::vector<VMMSample>{{vec3(0.1f), vec3(0, 1, 0), 2.0f, 0.5f, 1.0f}});
  SDTree tree2 = SDTree::deserialize(tree.serialize());
  VMMField field2(tree2, VMMOptions{});
  field2.restore(field.serialize(), "test");
  EXPECT_EQ(field2.serialize(), field.serialize());
  for (int it = 2; it < 5; ++it) train(tree, field, it), train(tree2, field2, it);
  EXPECT_GT(field.region_count(), 4u);
  EXPECT_EQ(field2.serialize(), field.serialize());
  for (int i = 0; i < 200; ++i) {
    const vec3 p = vec3(u2(hash(uint64_t(i), 5)).x, u2(hash(uint64_t(i), 6)).x, u2(hash(uint64_t(i), 7)).x) * 2.0f - 1.0f;
    const uint32_t r = field.region(p);
    ASSERT_EQ(r, field2.region(p));
    if (r == kNoGuideRegion) continue;
    const GuideSample a = field.sample(r, u2(hash(uint64_t(i), 8))), b = field2.sample(r, u2(hash(uint64_t(i), 8)));
    EXPECT_EQ(a.wi, b.wi);
    EXPECT_EQ(a.pdf, b.pdf);
  }
}

// A truncated, modified, other-version or other-tree input is one theia::Error
// naming the section, and leaves the field as it was.
TEST(VMMCheckpoint, CorruptTruncatedOrMismatchedIsRefused) {
  SDTree tree(kUnitBox, splitting_at(2000.0));
  VMMField field(tree, VMMOptions{});
  for (int it = 0; it < 2; ++it) train(tree, field, it);
  const std::vector<uint8_t> good = field.serialize();
  auto refused = [&](const std::vector<uint8_t>& bytes, const std::string& expect, const SDTree& over,
                     const VMMOptions& options = {}) {
    VMMField other(over, options);
    const std::vector<uint8_t> before = other.serialize();
    try {
      other.restore(bytes, "section 'x'");
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("section 'x'"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(expect), std::string::npos) << e.what();
      EXPECT_EQ(other.serialize(), before) << "a refused input changed the field";
      return;
    }
    ADD_FAILURE() << "accepted: expected '" << expect << "'";
  };
  std::vector<uint8_t> flipped = good;
  flipped[flipped.size() / 2] ^= 0x10;
  refused(flipped, "checksum", tree);
  refused(std::vector<uint8_t>(good.begin(), good.end() - 9), "checksum", tree);
  refused(std::vector<uint8_t>(good.begin(), good.begin() + 10), "truncated", tree);
  refused({}, "truncated", tree);
  std::vector<uint8_t> version = good;
  version[8] = 99;
  refused(version, "version 99", tree);
  std::vector<uint8_t> magic = good;
  magic[0] = 'X';
  refused(magic, "magic", tree);
  SDTree one(kUnitBox, splitting_at(1e15));
  refused(good, "regions for an SD-tree of 1 leaves", one);
  VMMOptions other_options;
  other_options.em_iterations = 3;
  refused(good, "other options", tree, other_options);
  // A well-formed checksum over a lobe weight of 2 (the first region's first lobe, after header, options, cell bits, count).
  std::vector<uint8_t> weight = good;
  const size_t at = 12 + 41 + 4 + 8 + sizeof(vec3) + sizeof(float);
  const float two = 2.0f;
  std::memcpy(weight.data() + at, &two, sizeof(two));
  const uint64_t checksum = hash_bytes(weight.data(), weight.size() - 8);
  std::memcpy(weight.data() + weight.size() - 8, &checksum, 8);
  refused(weight, "weight", tree);
}

// Random bytes changed and the checksum made to match again: restore() either
// takes the field (whose lookups then give finite densities) or throws
// theia::Error, never anything else.
TEST(VMMCheckpoint, AnyModifiedByteIsReadOrRefusedCleanly) {
  SDTree tree(kUnitBox, splitting_at(2000.0));
  VMMField field(tree, VMMOptions{});
  for (int it = 0; it < 2; ++it) train(tree, field, it);
  const std::vector<uint8_t> good = field.serialize();
  uint64_t state = 17;
  int refused = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    std::vector<uint8_t> bytes = good;
    for (int c = 0; c < 1 + trial % 4; ++c) {
      state = hash(state, uint64_t(trial), uint64_t(c));
      const size_t limit = trial % 2 ? 256 : bytes.size() - 8;
      bytes[12 + size_t(state % (limit - 12))] = uint8_t(state >> 32);
    }
    const uint64_t checksum = hash_bytes(bytes.data(), bytes.size() - 8);
    std::memcpy(bytes.data() + bytes.size() - 8, &checksum, 8);
    VMMField other(tree, VMMOptions{});
    try {
      other.restore(bytes, "x");
    } catch (const Error&) {
      ++refused;
      continue;
    }
    for (int i = 0; i < 16; ++i) {
      const vec3 p = vec3(u2(hash(uint64_t(i), 3)).x, u2(hash(uint64_t(i), 4)).x, 0.5f) * 2.0f - 1.0f;
      const uint32_t r = other.region(p);
      if (r == kNoGuideRegion) continue;
      const GuideSample s = other.sample(r, u2(hash(uint64_t(i), 9)));
      EXPECT_TRUE(std::isfinite(s.pdf) && s.pdf >= 0.0f);
      EXPECT_TRUE(std::isfinite(other.pdf(r, vec3(0, 0, 1))));
    }
  }
  EXPECT_GT(refused, 100);
}
