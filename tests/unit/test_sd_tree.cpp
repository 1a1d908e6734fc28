// The SD-tree guiding field (guiding/sd_tree.h): sampling against its own
// pdf (chi-square) on fields learned from analytic incident radiance,
// convergence to L / integral(L), unbiased deposits under a non-uniform
// training pdf, spatial subdivision and its growing threshold, the
// stochastic spatial filter, region() where nothing was learned,
// serialisation, and extreme inputs.
#include "guiding/sd_tree.h"

#include "core/hash.h"
#include "core/log.h"
#include "core/sampling.h"
#include "tests/unit/chi2.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <chrono>
#include <cstdio>
#include <functional>

using namespace theia;

namespace {

using Field = std::function<float(const vec3&)>;

float lobe(const vec3& w, const vec3& axis, float kappa) {
  return std::exp(kappa * (glm::dot(w, glm::normalize(axis)) - 1.0f));
}

// A narrow vMF-like lobe over a small constant.
float field_lobe(const vec3& w) { return 0.02f + 10.0f * lobe(w, vec3(0.3f, -0.5f, 0.8f), 100.0f); }
// A wide lobe and a narrow one on the phi = 0 seam.
float field_two_lobes(const vec3& w) {
  return lobe(w, vec3(-0.4f, 0.7f, 0.2f), 30.0f) + 0.5f * lobe(w, vec3(0.8f, 0.0f, 0.6f), 200.0f);
}
// Light from below only.
float field_lower(const vec3& w) {
  return w.z < 0.0f ? 1.0f + 3.0f * lobe(w, vec3(0.2f, 0.4f, -0.6f), 20.0f) : 0.0f;
}

vec2 u2(uint64_t h) { return {to_unit_float(uint32_t(h)), to_unit_float(uint32_t(h >> 32))}; }

const Bounds3 kUnitBox(vec3(0.0f), vec3(1.0f));
const vec3 kCentre(0.3f, 0.6f, 0.4f);

// Directional tests use one spatial leaf: the threshold is never reached.
SDTreeOptions one_leaf() {
  SDTreeOptions o;
  o.spatial_threshold = 1e15;
  return o;
}

enum class Training { Uniform, Cosine };

// `iterations` iterations of n directions each at p, each followed by update().
void train(SDTree& t, const Field& L, int n, int iterations, uint64_t seed, const vec3& p = kCentre,
           Training how = Training::Uniform) {
  for (int it = 0; it < iterations; ++it) {
    for (int i = 0; i < n; ++i) {
      uint64_t key = hash(seed, uint64_t(it), uint64_t(i));
      vec2 u = u2(hash(key, 1));
      vec3 w;
      float pdf;
      if (how == Training::Uniform) {
        w = sample_uniform_sphere(u);
        pdf = uniform_sphere_pdf();
      } else {
        w = sample_cosine_hemisphere(u);
        pdf = cosine_hemisphere_pdf(w.z);
      }
      t.add_sample(p, w, L(w), pdf, key);
    }
    t.update();
  }
}

// Integral over the sphere of f, by the midpoint rule on an n x n grid of the
// equal-area square (d omega = 4 pi dx dy).
double integrate_sphere(const std::function<double(const vec3&)>& f, int n = 1024) {
  double sum = 0.0;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) sum += f(sd_square_to_direction(vec2((x + 0.5f) / n, (y + 0.5f) / n)));
  return sum * 4.0 * double(kPi) / (double(n) * n);
}

// L1 distance between the learned pdf at p and L / integral(L).
double l1_to_field(const SDTree& t, const vec3& p, const Field& L) {
  double norm = integrate_sphere([&](const vec3& w) { return double(L(w)); });
  uint32_t r = t.region(p);
  return integrate_sphere([&](const vec3& w) { return std::abs(double(t.pdf(r, w)) - double(L(w)) / norm); }, 512);
}

double l1_between(const SDTree& a, const SDTree& b, const vec3& p) {
  uint32_t ra = a.region(p), rb = b.region(p);
  return integrate_sphere([&](const vec3& w) { return std::abs(double(a.pdf(ra, w)) - double(b.pdf(rb, w))); },
                          512);
}

// Probability mass of the learned pdf over directions with w.z > 0 (< 0).
double hemisphere_mass(const SDTree& t, const vec3& p, bool upper) {
  uint32_t r = t.region(p);
  return integrate_sphere([&](const vec3& w) { return (w.z > 0.0f) == upper ? double(t.pdf(r, w)) : 0.0; }, 256);
}
double upper_mass(const SDTree& t, const vec3& p) { return hemisphere_mass(t, p, true); }
double lower_mass(const SDTree& t, const vec3& p) { return hemisphere_mass(t, p, false); }

Chi2Result chi2(const SDTree& t, uint32_t r, const std::string& name, int n_tests) {
  return chi2_test_sphere(
      [&](vec2 u, float) -> std::optional<vec3> {
        GuideSample s = t.sample(r, u);
        if (!(s.pdf > 0.0f)) return std::nullopt;
        return s.wi;
      },
      [&](vec3 w) { return t.pdf(r, w); }, 100'000, 32, 64, 0.01, n_tests, name);
}

}  // namespace

TEST(SDTreeChi2, SampleMatchesPdfOnLearnedFields) {
  const std::vector<std::pair<std::string, Field>> fields = {
      {"lobe+constant", field_lobe}, {"two lobes", field_two_lobes}, {"lower hemisphere", field_lower}};
  for (const auto& [name, L] : fields) {
    SDTree t(kUnitBox, one_leaf());
    train(t, L, 50'000, 3, 7);
    uint32_t r = t.region(kCentre);
    ASSERT_NE(r, kNoGuideRegion) << name;
    Chi2Result res = chi2(t, r, name, int(fields.size()));
    EXPECT_TRUE(res.passed) << res.report;
    double integral = integrate_sphere([&](const vec3& w) { return double(t.pdf(r, w)); });
    EXPECT_NEAR(integral, 1.0, 2e-3) << name;
    // sample()'s pdf, accumulated on its way down, is pdf() at the sampled
    // direction bit for bit (the same factors in the same order); only a
    // direction rounded across a quad's edge could differ, and none of these does.
    int mismatches = 0;
    for (int i = 0; i < 10'000; ++i) {
      GuideSample s = t.sample(r, u2(hash(uint64_t(i), 99)));
      if (s.pdf != t.pdf(r, s.wi) || !(s.pdf > 0.0f)) ++mismatches;
    }
    EXPECT_EQ(mismatches, 0) << name;
  }
}

// pdf() reads the sampling quadtree as laid out for lookups (GuideNode:
// breadth-first, shares rounded to float): its density is the quadtree's own
// (4 flux / total per level, in double) to within that rounding, on fields
// whose quadtrees end shallow and deep, and at the square's edges and
// corners, where descend() must pick the same quadrants.
TEST(SDTreeGuideNodes, DensityIsTheSamplingQuadtrees) {
  auto quadtree_density = [](const SpatialLeaf& leaf, const vec3& wi) {
    const std::vector<SamplingQuadNode>& nodes = leaf.sampling;
    vec2 c = sd_direction_to_square(wi);
    double density = 1.0;
    uint32_t n = 0;
    for (;;) {
      const double total = double(nodes[n].flux[0]) + double(nodes[n].flux[1]) + double(nodes[n].flux[2]) +
                           double(nodes[n].flux[3]);
      if (!(total > 0.0)) break;
      int i = 0;
      for (int a = 0; a < 2; ++a) {
        if (c[a] >= 0.5f) {
          i |= 1 << a;
          c[a] = 2.0f * c[a] - 1.0f;
        } else {
          c[a] *= 2.0f;
        }
      }
      density *= 4.0 * double(nodes[n].flux[i]) / total;
      if (nodes[n].child[i] == 0 || density == 0.0) break;
      n = nodes[n].child[i];
    }
    return density / (4.0 * 3.14159265358979323846);
  };
  const Field narrow = [](const vec3& w) { return 1e-3f + lobe(w, vec3(0.1f, 0.2f, 0.9f), 3000.0f); };
  const std::vector<std::pair<std::string, Field>> fields = {
      {"lobe+constant", field_lobe}, {"two lobes", field_two_lobes}, {"narrow", narrow}, {"lower", field_lower}};
  for (const auto& [name, L] : fields) {
    SDTree t(kUnitBox, one_leaf());
    train(t, L, 50'000, 3, 11);
    const uint32_t r = t.region(kCentre);
    ASSERT_NE(r, kNoGuideRegion) << name;
    const SpatialLeaf& leaf = t.leaf(r);
    int mismatches = 0;
    auto check = [&](const vec3& w) {
      const double expect = quadtree_density(leaf, w), got = double(t.pdf(r, w));
      if (!(std::abs(got - expect) <= 1e-5 * expect) && !(expect < 1e-30 && got < 1e-30)) ++mismatches;
    };
    for (int i = 0; i < 100'000; ++i) check(sample_uniform_sphere(u2(hash(uint64_t(i), 5))));
    // Directions drawn from the field itself land in its deepest quads.
    for (int i = 0; i < 20'000; ++i) check(t.sample(r, u2(hash(uint64_t(i), 6))).wi);
    // Corners and the square's edges (x = 0 and 1 - eps: the poles; y: the seam).
    for (int y = 0; y <= 64; ++y)
      for (int x = 0; x <= 64; ++x)
        check(sd_square_to_direction(glm::min(vec2(float(x), float(y)) / 64.0f, vec2(kOneMinusEpsilon))));
    EXPECT_EQ(mismatches, 0) << name;
    // Some descents go deep: a node at depth 5 or more (the lobes' trees).
    std::vector<int> depth(leaf.sampling.size(), 0);
    int deepest = 0;
    for (size_t n = 0; n < leaf.sampling.size(); ++n)
      for (uint32_t child : leaf.sampling[n].child)
        if (child != 0) deepest = std::max(deepest, depth[child] = depth[n] + 1);
    if (name != "lower") {
      EXPECT_GE(deepest, 5) << name;
    }
  }
}

// The radiance integral a leaf reports (what adjoint-driven roulette weighs
// by) is the mean of radiance / pdf over its samples: the integral of the
// field over the sphere, with the unbiased weight (no pdf floor).
// The map's angle comes from a polynomial, not atan2f: within a few 1e-7 of
// atan2 (in double) everywhere, on the axes and diagonals too, and in
// [0, 1) with y = 0 exactly along +x.
TEST(SDTreeMap, DirectionToSquareMatchesAtan2) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<vec3> dirs;
  for (int i = 0; i < 200000; ++i) dirs.push_back(sd_square_to_direction(vec2(u(rng), u(rng))));
  for (float x : {-1.0f, -0.7071068f, 0.0f, 0.7071068f, 1.0f})
    for (float y : {-1.0f, -0.7071068f, -1e-30f, 0.0f, 1e-30f, 0.7071068f, 1.0f})
      if (x != 0.0f || y != 0.0f) dirs.push_back(glm::normalize(vec3(x, y, 0.3f)));
  double worst = 0.0;
  for (const vec3& w : dirs) {
    const vec2 c = sd_direction_to_square(w);
    ASSERT_GE(c.y, 0.0f);
    ASSERT_LT(c.y, 1.0f);
    double phi = std::atan2(double(w.y), double(w.x));
    if (phi < 0.0) phi += 2.0 * M_PI;
    double d = std::abs(double(c.y) - phi / (2.0 * M_PI));
    d = std::min(d, 1.0 - d);  // across the seam at phi = 0
    worst = std::max(worst, d);
  }
  EXPECT_LT(worst, 2e-7);
  EXPECT_EQ(sd_direction_to_square(vec3(1.0f, 0.0f, 0.0f)).y, 0.0f);
}

TEST(SDTreeRadianceIntegral, EstimatesTheFieldsIntegralOverTheSphere) {
  const std::vector<std::pair<std::string, Field>> fields = {
      {"lobe+constant", field_lobe}, {"two lobes", field_two_lobes}, {"lower hemisphere", field_lower}};
  for (const auto& [name, L] : fields) {
    SDTreeOptions o = one_leaf();
    o.pdf_floor = 0.0f;
    SDTree t(kUnitBox, o);
    train(t, L, 200'000, 2, 11);
    const double expect = integrate_sphere([&](const vec3& w) { return double(L(w)); });
    EXPECT_NEAR(t.radiance_integral(t.region(kCentre)), expect, 0.05 * expect) << name;
    std::printf("%s: radiance integral %.4f, field %.4f\n", name.c_str(), t.radiance_integral(t.region(kCentre)), expect);
  }
  SDTree untrained(kUnitBox, one_leaf());
  EXPECT_EQ(untrained.radiance_integral(0), 0.0f);
  EXPECT_EQ(untrained.radiance_integral(kNoGuideRegion), 0.0f);
}

// Without the directional filter nothing is learned above the horizon; with
// it, a sample just below the horizon puts part of itself into the quad
// above, which may be a large one (quads without flux collapse), so a little
// mass spreads over the upper hemisphere.
TEST(SDTreeChi2, LowerHemisphereFieldLearnsLittleAbove) {
  SDTree filtered(kUnitBox, one_leaf());
  train(filtered, field_lower, 50'000, 3, 11);
  double leak = upper_mass(filtered, kCentre);
  std::printf("upper-hemisphere mass with the directional filter: %.4f\n", leak);
  EXPECT_LT(leak, 0.02);
  SDTreeOptions o = one_leaf();
  o.directional_filter = false;
  SDTree t(kUnitBox, o);
  train(t, field_lower, 50'000, 3, 11);
  uint32_t r = t.region(kCentre);
  for (int i = 0; i < 10'000; ++i) ASSERT_LT(t.sample(r, u2(hash(uint64_t(i), 6))).wi.z, 0.0f);
  for (int i = 0; i < 2000; ++i) {
    vec2 u = u2(hash(uint64_t(i), 5));
    vec3 w = sd_square_to_direction(vec2(0.5f + 0.5f * u.x, u.y));
    ASSERT_EQ(t.pdf(r, w), 0.0f) << w.z;
  }
}

// Learned from N uniform directions per iteration, the pdf approaches
// L / integral(L) as N grows, down to the floor of a piecewise-constant fit
// at rho = 1% (L1 ~ 0.04 for this lobe; ~0.12, 0.063, 0.046 at the counts
// below, over four accumulated iterations).
TEST(SDTreeConvergence, LearnedPdfApproachesNormalisedRadiance) {
  auto L = [](const vec3& w) { return 0.1f + lobe(w, vec3(0.3f, -0.5f, 0.8f), 30.0f); };
  std::vector<double> l1;
  for (int n : {2'000, 20'000, 200'000}) {
    SDTree t(kUnitBox, one_leaf());
    train(t, L, n, 4, 3);
    l1.push_back(l1_to_field(t, kCentre, L));
  }
  std::printf("L1 distance to L / integral(L): %.4f %.4f %.4f\n", l1[0], l1[1], l1[2]);
  EXPECT_LT(l1[1], 0.7 * l1[0]);
  EXPECT_LT(l1[2], 0.85 * l1[1]);  // near the fit's floor
  EXPECT_LT(l1[2], 0.06);
}

// Deposits are radiance / pdf, so cosine-weighted training directions learn
// the same field as uniform ones; recording radiance alone would learn
// L cos instead, which is far from it.
TEST(SDTreeUnbiased, CosineTrainingLearnsTheUniformTrainingField) {
  auto L = [](const vec3& w) {
    return w.z > 0.0f ? w.z * (1.0f + 20.0f * lobe(w, vec3(0.5f, 0.3f, 0.4f), 40.0f)) : 0.0f;
  };
  SDTreeOptions o = one_leaf();
  o.pdf_floor = 0.0f;  // the unbiased weight (the floor would cap the grazing cosine samples)
  SDTree uniform(kUnitBox, o), uniform2(kUnitBox, o), cosine(kUnitBox, o);
  train(uniform, L, 200'000, 4, 21, kCentre, Training::Uniform);
  train(uniform2, L, 200'000, 4, 23, kCentre, Training::Uniform);
  train(cosine, L, 200'000, 4, 22, kCentre, Training::Cosine);
  // Two uniform trainings differ by their noise; the cosine one must be no
  // further from either than that, and far from L cos.
  double noise = l1_between(uniform, uniform2, kCentre);
  double d = l1_between(uniform, cosine, kCentre);
  auto biased = [&](const vec3& w) { return L(w) * std::max(w.z, 0.0f); };
  double d_biased = l1_to_field(cosine, kCentre, biased);
  std::printf("uniform vs uniform %.4f, uniform vs cosine %.4f, cosine vs L cos %.4f\n", noise, d, d_biased);
  EXPECT_LT(d, 1.5 * noise);
  EXPECT_GT(d_biased, 3.0 * noise);
}

// Samples in one octant: the first update splits the root once (both halves
// keep a quarter of its count), and from then on only leaves in that octant
// keep splitting.
TEST(SDTreeSpatial, ConcentratedSamplesSplitOnlyThere) {
  SDTreeOptions o;
  SDTree t(kUnitBox, o);
  std::vector<size_t> leaves;
  std::vector<double> inside, outside;
  for (int it = 0; it < 4; ++it) {
    for (int i = 0; i < 16'000; ++i) {
      uint64_t key = hash(uint64_t(it), uint64_t(i));
      vec2 a = u2(hash(key, 1)), b = u2(hash(key, 2));
      vec3 p = 0.5f * vec3(a.x, a.y, b.x);  // [0, 0.5)^3
      vec3 w = sample_uniform_sphere(u2(hash(key, 3)));
      t.add_sample(p, w, 1.0f, uniform_sphere_pdf(), key);
    }
    t.update();
    leaves.push_back(t.stats().spatial_leaves);
    auto volume = [&](const vec3& p) {
      vec3 d = t.leaf_bounds(p).diagonal();
      return double(d.x) * d.y * d.z;
    };
    inside.push_back(volume(vec3(0.25f, 0.25f, 0.25f)));
    outside.push_back(volume(vec3(0.75f, 0.75f, 0.75f)));
  }
  // 16000 > 4000 splits the root; its halves keep 4000, not above the threshold.
  EXPECT_EQ(leaves[0], 2u);
  for (int it = 1; it < 4; ++it) EXPECT_GT(leaves[it], leaves[it - 1]);
  // Far from the octant only the spatial filter's reach brings samples.
  std::printf("leaf volume inside %.4g -> %.4g, outside %.4g -> %.4g\n", inside[0], inside[3], outside[0], outside[3]);
  EXPECT_LE(inside[3], inside[0] / 16.0);
  EXPECT_GT(outside[3], 8.0 * inside[3]);
}

// A leaf splits once the samples it accumulated over any number of
// iterations exceed the threshold; each half keeps split_decay of the count.
// leaf_at tries the calling thread's last leaf before descending: whatever
// was looked up before (nearby points, far ones, another tree, the same tree
// before an update), every point gets the leaf whose box holds it.
TEST(SDTreeSpatial, LastLeafShortcutGivesTheDescentsLeaf) {
  SDTreeOptions o;
  o.spatial_threshold = 500.0;
  SDTree a(kUnitBox, o), b(Bounds3(vec3(-3.0f), vec3(2.0f)), o);
  auto train = [](SDTree& t, int it) {
    for (int i = 0; i < 8'000; ++i) {
      uint64_t key = hash(uint64_t(it), uint64_t(i), 77);
      vec2 u = u2(hash(key, 1)), v = u2(hash(key, 2));
      vec3 p = t.root_bounds().min + t.root_bounds().diagonal() * vec3(u.x * u.x, u.y, v.x);
      t.add_sample(p, sample_uniform_sphere(u2(hash(key, 3))), 1.0f, uniform_sphere_pdf(), key);
    }
    t.update();
  };
  auto check = [](const SDTree& t, uint64_t seed) {
    const std::vector<Bounds3> boxes = t.leaf_boxes();
    vec3 p = t.root_bounds().centroid();
    for (int i = 0; i < 4'000; ++i) {
      const uint64_t h = hash(seed, uint64_t(i));
      const vec2 u = u2(h), v = u2(hash(h, 1));
      // Mostly small steps (the shortcut's case), now and then a jump anywhere.
      const vec3 d = t.root_bounds().diagonal();
      p = i % 7 == 0 ? t.root_bounds().min + d * vec3(u.x, u.y, v.x)
                     : glm::clamp(p + 0.02f * d * (vec3(u.x, u.y, v.x) - 0.5f), t.root_bounds().min,
                                  t.root_bounds().max);
      const Bounds3 box = boxes[t.leaf_index(p)], want = t.leaf_bounds(p);
      ASSERT_EQ(box.min, want.min) << i;
      ASSERT_EQ(box.max, want.max) << i;
    }
  };
  for (int it = 0; it < 3; ++it) {
    train(a, it);
    train(b, it);
    check(a, 10 + it);
    check(b, 20 + it);  // the last leaf is a's: it must not be read against b
    check(a, 30 + it);
  }
  EXPECT_GT(a.leaf_count(), 20u);
  EXPECT_GT(b.leaf_count(), 20u);
}

TEST(SDTreeSpatial, SplitsOnCountsAccumulatedOverIterations) {
  SDTreeOptions o;
  o.spatial_filter = false;  // every sample lands in the leaf holding kCentre
  auto leaves_after = [&](const std::vector<int>& per_iteration, float radiance = 1.0f) {
    SDTree t(kUnitBox, o);
    int key = 0;
    for (int n : per_iteration) {
      for (int i = 0; i < n; ++i) t.add_sample(kCentre, vec3(0, 0, 1), radiance, 1.0f, uint64_t(key++));
      t.update();
    }
    return t.stats().spatial_leaves;
  };
  EXPECT_EQ(leaves_after({4000}), 1u);
  EXPECT_EQ(leaves_after({4001}), 2u);
  EXPECT_EQ(leaves_after({4001}, 0.0f), 2u);  // zero-valued samples count too
  EXPECT_EQ(leaves_after({2000, 2000}), 1u);
  EXPECT_EQ(leaves_after({2000, 2001}), 2u);  // accumulated, not per iteration
  EXPECT_EQ(leaves_after({0, 0, 0, 1000, 0, 3001}), 2u);
  // After a split at 4001 the half holding kCentre keeps 1000.25: 2999 more
  // samples stay below the threshold, 3000 pass it.
  EXPECT_EQ(leaves_after({4001, 2999}), 2u);
  EXPECT_EQ(leaves_after({4001, 3000}), 3u);
  // One update splits as deep as the count calls for, blindly (each half
  // keeps a quarter): 64001 -> 16000.25 -> 4000.06 -> 1000.02, 8 leaves.
  EXPECT_EQ(leaves_after({64001}), 8u);
}

// Directions depend on the side of x = 0.5: from above (z > 0) left of it,
// from below right of it.  The tree is split 4 x 4 x 4 by the first update,
// so x = 0.5 is a leaf boundary; the second iteration's learned field is then
// pure in leaves beyond the filter's reach and mixed in the leaves beside the
// edge, where a uniform jitter of one leaf width brings 1/8 of the samples
// from across the edge.
namespace {
SDTree train_edge(bool spatial_filter, uint64_t seed) {
  SDTreeOptions o;
  o.spatial_threshold = 4000.0;
  o.split_decay = 0.5;
  o.spatial_filter = spatial_filter;
  o.directional_filter = false;  // keeps the hemispheres apart
  SDTree t(kUnitBox, o);
  // Zero-valued samples first: they split the tree into 4 x 4 x 4 leaves of
  // 130000 / 64 = 2031 each and deposit nothing.  The lit iteration's 100000
  // then add 1562 each, well short of another split.
  for (int it = 0; it < 2; ++it) {
    for (int i = 0; i < (it == 0 ? 130'000 : 100'000); ++i) {
      uint64_t key = hash(seed, uint64_t(it), uint64_t(i));
      vec2 a = u2(hash(key, 1)), b = u2(hash(key, 2));
      vec3 p(a.x, a.y, b.x);
      vec3 w = sample_uniform_sphere(u2(hash(key, 3)));
      bool lit = it == 1 && (p.x < 0.5f ? w.z > 0.0f : w.z < 0.0f);
      t.add_sample(p, w, lit ? 1.0f : 0.0f, uniform_sphere_pdf(), key);
    }
    t.update();
  }
  return t;
}
}  // namespace

TEST(SDTreeSpatialFilter, SharpEdgeBlursAboutOneLeafDeterministically) {
  SDTree sharp = train_edge(false, 1), blurred = train_edge(true, 1);
  ASSERT_EQ(sharp.stats().spatial_leaves, 64u);
  ASSERT_EQ(blurred.stats().spatial_leaves, 64u);
  float h = blurred.leaf_bounds(kCentre).diagonal().x;  // about 1/4
  ASSERT_NEAR(h, 0.25f, 0.01f);
  for (float yz : {0.4f, 0.9f}) {
    auto at = [&](float x) { return vec3(x, yz, 1.0f - yz); };
    // Without the filter the edge stays sharp.
    EXPECT_EQ(upper_mass(sharp, at(0.5f + 0.5f * h)), 0.0);
    EXPECT_EQ(lower_mass(sharp, at(0.5f - 0.5f * h)), 0.0);
    // With it, the leaves beside the edge take ~1/8 from across it ...
    EXPECT_NEAR(upper_mass(blurred, at(0.5f + 0.5f * h)), 0.125, 0.04);
    EXPECT_NEAR(lower_mass(blurred, at(0.5f - 0.5f * h)), 0.125, 0.04);
    // ... and the next ones nothing.
    EXPECT_EQ(upper_mass(blurred, at(0.5f + 1.5f * h)), 0.0);
    EXPECT_EQ(lower_mass(blurred, at(0.5f - 1.5f * h)), 0.0);
  }
  // The jitter is a function of the keys alone.
  EXPECT_EQ(blurred.serialize(), train_edge(true, 1).serialize());
  EXPECT_NE(blurred.serialize(), train_edge(true, 2).serialize());
}

TEST(SDTreeRegion, NoRegionBeforeTheFirstUpdateOrWithoutEnergy) {
  SDTreeOptions o;
  o.spatial_threshold = 1000.0;
  o.spatial_filter = false;
  SDTree t(kUnitBox, o);
  auto feed = [&](int it) {
    for (int i = 0; i < 8000; ++i) {
      uint64_t key = hash(uint64_t(it), uint64_t(i));
      vec2 a = u2(hash(key, 1)), b = u2(hash(key, 2));
      vec3 p(a.x, a.y, b.x);
      vec3 w = sample_uniform_sphere(u2(hash(key, 3)));
      t.add_sample(p, w, p.x < 0.5f ? 1.0f : 0.0f, uniform_sphere_pdf(), key);
    }
  };
  feed(0);
  for (float x : {0.1f, 0.9f}) EXPECT_EQ(t.region(vec3(x, 0.5f, 0.5f)), kNoGuideRegion);
  t.update();
  // The first iteration's single leaf had energy; its halves inherit it.
  for (float x : {0.1f, 0.9f}) EXPECT_NE(t.region(vec3(x, 0.5f, 0.5f)), kNoGuideRegion);
  feed(1);
  t.update();
  // Zero-valued samples alone leave the halves' inherited field (a prior) in place.
  for (float x : {0.1f, 0.9f}) EXPECT_NE(t.region(vec3(x, 0.5f, 0.5f)), kNoGuideRegion);
  t.update();  // an iteration without samples: the field keeps what it learned
  for (float x : {0.1f, 0.9f}) EXPECT_NE(t.region(vec3(x, 0.5f, 0.5f)), kNoGuideRegion);
  // A field that never saw energy guides nowhere.
  SDTree dark(kUnitBox, o);
  for (int i = 0; i < 8000; ++i) dark.add_sample(vec3(0.5f), vec3(0, 0, 1), 0.0f, 1.0f, uint64_t(i));
  dark.update();
  EXPECT_EQ(dark.region(vec3(0.5f)), kNoGuideRegion);
  EXPECT_EQ(t.pdf(kNoGuideRegion, vec3(0, 0, 1)), 0.0f);
  EXPECT_EQ(t.sample(kNoGuideRegion, vec2(0.5f)).pdf, 0.0f);
  EXPECT_EQ(t.selection_probability(0), 0.5f);
}

namespace {
// Two iterations learned, a third half recorded (pending deposits and counts).
SDTree trained_for_serialisation() {
  SDTreeOptions o;
  o.spatial_threshold = 300.0;
  o.learn_selection = true;  // the learners' state comes along too
  SDTree t(kUnitBox, o);
  for (int it = 0; it < 3; ++it) {
    for (int i = 0; i < 12'000; ++i) {
      uint64_t key = hash(uint64_t(40 + it), uint64_t(i));
      vec2 a = u2(hash(key, 1)), b = u2(hash(key, 2));
      vec3 p(a.x, a.y, b.x);
      vec3 w = sample_uniform_sphere(u2(hash(key, 3)));
      const float radiance = field_two_lobes(w) * (0.5f + p.x);
      t.add_sample({p, w, radiance, uniform_sphere_pdf(), key, radiance, 0.5f + b.y, 1.5f - b.y});
    }
    t.add_sample(kCentre, vec3(0, 0, 1), std::nanf(""), 1.0f, 0);  // a dropped one
    if (it < 2) t.update();
  }
  return t;
}

void continue_training(SDTree& t) {
  for (int i = 0; i < 20'000; ++i) {
    uint64_t key = hash(uint64_t(77), uint64_t(i));
    vec2 a = u2(hash(key, 1)), b = u2(hash(key, 2));
    vec3 w = sample_uniform_sphere(u2(hash(key, 3)));
    t.add_sample(vec3(a.x, a.y, b.x), w, field_lobe(w), uniform_sphere_pdf(), key);
  }
  t.update();
}

std::string error_of(const std::vector<uint8_t>& bytes) {
  try {
    SDTree::deserialize(bytes);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(SDTreeSerialize, RoundTripIsExactAndTrainingContinuesIdentically) {
  SDTree a = trained_for_serialisation();
  std::vector<uint8_t> bytes = a.serialize();
  SDTree b = SDTree::deserialize(bytes);
  EXPECT_EQ(b.serialize(), bytes);
  SDTreeStats sa = a.stats(), sb = b.stats();
  EXPECT_EQ(sa.spatial_leaves, sb.spatial_leaves);
  EXPECT_EQ(sa.pending_recorded, sb.pending_recorded);
  EXPECT_EQ(sa.pending_dropped, 1u);
  EXPECT_EQ(sb.pending_dropped, 1u);
  ASSERT_GT(sa.spatial_leaves, 8u);
  int guided = 0;
  for (int i = 0; i < 20'000; ++i) {
    uint64_t h = hash(uint64_t(i), 123);
    vec3 p(to_unit_float(uint32_t(h)), to_unit_float(uint32_t(h >> 32)), to_unit_float(uint32_t(hash(h))));
    uint32_t r = a.region(p);
    ASSERT_EQ(r, b.region(p));
    if (r == kNoGuideRegion) continue;
    ++guided;
    vec2 u = u2(hash(h, 1));
    GuideSample ga = a.sample(r, u), gb = b.sample(r, u);
    ASSERT_EQ(ga.wi, gb.wi);
    ASSERT_EQ(ga.pdf, gb.pdf);
    vec3 w = sample_uniform_sphere(u2(hash(h, 2)));
    ASSERT_EQ(a.pdf(r, w), b.pdf(r, w));
  }
  EXPECT_GT(guided, 10'000);
  // The building state came along: finishing the iteration and training on
  // gives the same tree as never having stopped.
  a.update();
  b.update();
  continue_training(a);
  continue_training(b);
  EXPECT_EQ(a.serialize(), b.serialize());
}

TEST(SDTreeSerialize, TruncatedOrCorruptInputThrows) {
  std::vector<uint8_t> bytes = trained_for_serialisation().serialize();
  for (size_t len : {size_t(0), size_t(5), size_t(12), size_t(19), bytes.size() / 2, bytes.size() - 1}) {
    std::string msg = error_of(std::vector<uint8_t>(bytes.begin(), bytes.begin() + std::ptrdiff_t(len)));
    EXPECT_NE(msg.find("SD-tree data"), std::string::npos) << len << ": " << msg;
  }
  // One flipped bit anywhere, at 400 spread positions.
  for (int k = 0; k < 400; ++k) {
    size_t bit = size_t(hash(uint64_t(k)) % (bytes.size() * 8));
    std::vector<uint8_t> flipped = bytes;
    flipped[bit / 8] ^= uint8_t(1u << (bit % 8));
    std::string msg = error_of(flipped);
    ASSERT_NE(msg.find("SD-tree data"), std::string::npos) << "bit " << bit << ": " << msg;
  }
  std::vector<uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_FALSE(error_of(longer).empty());
}

TEST(SDTreeExtreme, HugeTinyAndBadValues) {
  SDTree t(kUnitBox, one_leaf());
  uint64_t dropped = 0, recorded = 0;
  for (int i = 0; i < 20'000; ++i) {
    uint64_t key = hash(uint64_t(i), 9);
    vec3 w = sample_uniform_sphere(u2(key));
    // 1e30 / 1e-20 = 1e50 overflows float; 1e-30 next to it underflows
    // relative to it.
    float L = w.z > 0.5f ? 1e30f : 1e-30f;
    t.add_sample(kCentre, w, L, i % 2 ? 1e-20f : uniform_sphere_pdf(), key);
    ++recorded;
  }
  const float nan = std::nanf(""), inf = kInfinity;
  for (auto [L, pdf] : std::vector<std::pair<float, float>>{
           {nan, 1.0f}, {inf, 1.0f}, {-inf, 1.0f}, {1.0f, nan}, {1.0f, inf}, {1.0f, 0.0f}, {1.0f, -1.0f}, {-1.0f, 1.0f}}) {
    t.add_sample(kCentre, vec3(0, 0, 1), L, pdf, 1);
    ++dropped;
  }
  t.add_sample(vec3(nan), vec3(0, 0, 1), 1.0f, 1.0f, 1);
  t.add_sample(kCentre, vec3(0.0f), 1.0f, 1.0f, 1);
  t.add_sample(kCentre, vec3(inf, 0, 0), 1.0f, 1.0f, 1);
  dropped += 3;
  EXPECT_EQ(t.stats().pending_dropped, dropped);
  EXPECT_EQ(t.stats().pending_recorded, recorded);
  t.update();
  EXPECT_EQ(t.stats().samples_dropped, dropped);
  EXPECT_EQ(t.stats().samples_recorded, recorded);
  uint32_t r = t.region(kCentre);
  ASSERT_NE(r, kNoGuideRegion);
  EXPECT_NEAR(integrate_sphere([&](const vec3& w) { return double(t.pdf(r, w)); }), 1.0, 2e-3);
  // The energy is in the 1e30 cap (z > 0.5) but for what the directional
  // filter spreads across its rim; the 1e-30 side is 1e-80 of it: nothing.
  int below_rim = 0;
  for (int i = 0; i < 10'000; ++i) {
    GuideSample s = t.sample(r, u2(hash(uint64_t(i), 10)));
    ASSERT_TRUE(std::isfinite(s.pdf) && s.pdf > 0.0f);
    ASSERT_GT(s.wi.z, 0.0f);
    below_rim += s.wi.z < 0.45f;
  }
  EXPECT_LT(below_rim, 500);
  EXPECT_EQ(t.region(vec3(nan)), kNoGuideRegion);
}

TEST(SDTreeExtreme, CornersOutsidePointsAndFlatScenes) {
  const std::vector<Bounds3> boxes = {kUnitBox, Bounds3(vec3(-1, -2, 3), vec3(4, 5, 3)),  // flat in z
                                      Bounds3(vec3(2.0f), vec3(2.0f)),                     // a point
                                      Bounds3(vec3(1e6f), vec3(1e6f + 1e-3f)), Bounds3()};
  for (const Bounds3& box : boxes) {
    SDTreeOptions o;
    o.spatial_threshold = 100.0;
    SDTree t(box, o);
    Bounds3 root = t.root_bounds();
    ASSERT_TRUE(root.contains(box.empty() ? vec3(0.0f) : box.min) && (box.empty() || root.contains(box.max)));
    vec3 d = root.diagonal();
    ASSERT_GT(d.x, 0.0f);
    ASSERT_EQ(d.x, d.y);
    ASSERT_EQ(d.x, d.z);
    std::vector<vec3> points;
    for (int c = 0; c < 8; ++c) {
      for (const Bounds3& b : {root, box.empty() ? root : box})
        points.push_back(vec3(c & 1 ? b.max.x : b.min.x, c & 2 ? b.max.y : b.min.y, c & 4 ? b.max.z : b.min.z));
    }
    points.push_back(root.max + d);  // outside: clamped in
    points.push_back(vec3(-1e30f));
    for (int it = 0; it < 3; ++it) {
      for (size_t k = 0; k < points.size(); ++k)
        for (int i = 0; i < 300; ++i) {
          uint64_t key = hash(uint64_t(it), k, uint64_t(i));
          vec3 w = sample_uniform_sphere(u2(key));
          t.add_sample(points[k], w, 1.0f + w.x, uniform_sphere_pdf(), key);
        }
      t.update();
    }
    EXPECT_EQ(t.stats().samples_dropped, 0u);
    EXPECT_GT(t.stats().spatial_leaves, 8u);
    for (const vec3& p : points) {
      uint32_t r = t.region(p);
      ASSERT_NE(r, kNoGuideRegion);
      GuideSample s = t.sample(r, vec2(0.3f, 0.7f));
      ASSERT_TRUE(std::isfinite(s.pdf) && s.pdf > 0.0f);
      ASSERT_TRUE(root.contains(t.leaf_bounds(p).centroid()));
    }
  }
}

TEST(SDTreeOptionChecks, BadOptionsThrow) {
  auto throws = [](auto change) {
    SDTreeOptions o;
    change(o);
    try {
      SDTree t(kUnitBox, o);
    } catch (const Error&) {
      return true;
    }
    return false;
  };
  EXPECT_TRUE(throws([](SDTreeOptions& o) { o.spatial_threshold = 0.0; }));
  EXPECT_TRUE(throws([](SDTreeOptions& o) { o.flux_threshold = 1.0; }));
  EXPECT_TRUE(throws([](SDTreeOptions& o) { o.max_quadtree_depth = 0; }));
  EXPECT_TRUE(throws([](SDTreeOptions& o) { o.selection_probability = 1.5f; }));
  EXPECT_FALSE(throws([](SDTreeOptions&) {}));
  EXPECT_THROW(SDTree(Bounds3(vec3(0.0f), vec3(kInfinity)), SDTreeOptions{}), Error);
}

// Not run by default: add_sample throughput and update() time for the report
// (--gtest_also_run_disabled_tests --gtest_filter=SDTreeTiming*).
TEST(SDTreeTiming, DISABLED_Throughput) {
  using clock = std::chrono::steady_clock;
  SDTree t(kUnitBox, SDTreeOptions{});
  for (int it = 0; it < 6; ++it) {
    const int n = 1'000'000;
    std::vector<vec3> ps(n), ws(n);
    std::vector<float> ls(n);
    for (int i = 0; i < n; ++i) {
      uint64_t key = hash(uint64_t(it), uint64_t(i));
      vec2 a = u2(hash(key, 1)), b = u2(hash(key, 2));
      ps[i] = vec3(a.x, a.y, b.x * b.x);
      ws[i] = sample_uniform_sphere(u2(hash(key, 3)));
      ls[i] = field_two_lobes(ws[i]) * (ps[i].x + 0.1f);
    }
    auto t0 = clock::now();
    for (int i = 0; i < n; ++i) t.add_sample(ps[i], ws[i], ls[i], uniform_sphere_pdf(), hash(uint64_t(it), uint64_t(i)));
    auto t1 = clock::now();
    t.update();
    auto t2 = clock::now();
    SDTreeStats s = t.stats();
    std::printf("iteration %d: add_sample %.1f ns/sample (%.3f s per million), update %.1f ms; %zu leaves, %zu "
                "quad nodes, %.1f MB, %.0f bytes/leaf\n",
                it, std::chrono::duration<double, std::nano>(t1 - t0).count() / n,
                std::chrono::duration<double>(t1 - t0).count() * 1e6 / n,
                std::chrono::duration<double, std::milli>(t2 - t1).count(), s.spatial_leaves, s.quadtree_nodes,
                double(s.bytes) / 1e6, double(s.bytes) / double(s.spatial_leaves));
  }
}

// Training in parallel over leaves builds exactly the tree that add_sample
// in a row builds, at any thread count (dropped samples counted the same).
TEST(SDTreeParallel, AddSamplesEqualsAddSampleInARow) {
  SDTreeOptions o;
  o.spatial_threshold = 500.0;
  o.learn_selection = true;
  std::vector<SDTreeSample> batch;
  for (int i = 0; i < 30'000; ++i) {
    uint64_t key = hash(uint64_t(i), 71);
    vec2 a = u2(hash(key, 1)), b = u2(hash(key, 2));
    vec3 w = sample_uniform_sphere(u2(hash(key, 3)));
    float pdf = i % 997 == 0 ? 0.0f : uniform_sphere_pdf();  // some dropped
    // Every other sample carries mixture densities: the learners step in leaf order too.
    const float ratio = i % 2 ? 0.5f + b.y : 0.0f;
    batch.push_back({vec3(a.x, a.y, b.x), w, field_two_lobes(w), pdf, key, field_two_lobes(w), ratio, 2.0f - ratio});
  }
  auto train = [&](bool parallel, int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
    SDTree t(kUnitBox, o);
    for (int it = 0; it < 3; ++it) {
      if (parallel) {
        t.add_samples(batch);
      } else {
        for (const SDTreeSample& s : batch) t.add_sample(s);
      }
      if (it < 2) t.update();
    }
    return t.serialize();
  };
  const std::vector<uint8_t> serial = train(false, 1);
  EXPECT_EQ(train(true, 1), serial);
  EXPECT_EQ(train(true, 2), serial);
}

// The learned selection probability (seeds/001 10.5) on a direction domain of
// two halves of equal measure, the BSDF uniform and the guide 1.6 / 0.4.
// Adam with unbiased gradients settles where the regularised objective
// KL(p || s g + (1 - s) p_bsdf) + 0.005 theta^2 is smallest (s = sigmoid(theta));
// found here by a search over theta for three products: one the mixture
// matches exactly at s = 1/3 (0.385 with the L2 term), one equal to the guide, one equal to the BSDF
// (where the KL divergence flattens towards s = 1 and s = 0, so the L2 term
// holds the share back).  Directions are drawn from the current mixture, as
// rendering does, and the product's scale (x 50) must not matter.
TEST(SDTreeSelection, AdamSettlesAtTheRegularisedKLOptimum) {
  constexpr float kGuide[2] = {1.6f, 0.4f};
  auto optimum = [&](float pa, float pb) {
    double best = 0.0, best_j = 1e30;
    for (double theta = -8.0; theta <= 8.0; theta += 1e-3) {
      const double s = 1.0 / (1.0 + std::exp(-theta));
      double j = 0.005 * theta * theta;
      for (int h = 0; h < 2; ++h) {
        const double p = h == 0 ? pa : pb, q = s * kGuide[h] + (1.0 - s);
        j += 0.5 * p * std::log(p / q);
      }
      if (j < best_j) best_j = j, best = s;
    }
    return best;
  };
  auto learn = [&](float pa, float pb, float scale) {
    SelectionLearner l;
    for (int i = 0; i < 40'000; ++i) {
      const float sel = learned_selection(l);
      const uint64_t h = hash(uint64_t(i), 5);
      const int half = to_unit_float(uint32_t(h)) < 0.5f * (sel * kGuide[0] + (1.0f - sel)) ? 0 : 1;
      const float mixture = sel * kGuide[half] + (1.0f - sel);
      SDTreeSample s;
      s.product_weight = scale * (half == 0 ? pa : pb) / mixture;
      s.bsdf_ratio = 1.0f / mixture;
      s.guide_ratio = kGuide[half] / mixture;
      learn_selection_step(l, s);
    }
    EXPECT_EQ(l.steps, 40'000u);
    return double(learned_selection(l));
  };
  for (auto [pa, pb] : {std::pair{1.2f, 0.8f}, {1.6f, 0.4f}, {1.0f, 1.0f}}) {
    const double want = optimum(pa, pb), got = learn(pa, pb, 1.0f), scaled = learn(pa, pb, 50.0f);
    std::printf("product %.1f / %.1f: learned %.3f (x50: %.3f), regularised KL optimum %.3f\n", pa, pb, got, scaled,
                want);
    EXPECT_NEAR(got, want, 0.04);
    EXPECT_NEAR(scaled, want, 0.04);
  }
  // The exact match sits at 1/3 without the L2 term; with it, 0.385.
  EXPECT_GT(optimum(1.2f, 0.8f), 1.0 / 3.0);
  EXPECT_LT(optimum(1.2f, 0.8f), 0.4);
}

// A tree that learns its selection starts every leaf at the option's value,
// moves it only at update() (rendering reads what earlier iterations
// learned), and hands it to both halves of a split.
TEST(SDTreeSelection, LearnedShareIsReadAfterUpdateAndSurvivesSplits) {
  SDTreeOptions o;
  o.learn_selection = true;
  o.selection_probability = 0.3f;
  o.spatial_threshold = 1000.0;
  SDTree t(kUnitBox, o);
  for (int i = 0; i < 3000; ++i) {
    const uint64_t key = hash(uint64_t(i), 9);
    const vec3 w = sample_uniform_sphere(u2(hash(key, 1)));
    const vec3 p(0.5f);
    // The guide's density is always the larger: the product follows the guide.
    t.add_sample({p, w, 1.0f, uniform_sphere_pdf(), key, 1.0f, 0.5f, 1.5f});
  }
  for (size_t l = 0; l < t.leaf_count(); ++l) EXPECT_FLOAT_EQ(t.leaf(uint32_t(l)).selection, 0.3f);
  t.update();
  ASSERT_GT(t.leaf_count(), 1u);
  for (size_t l = 0; l < t.leaf_count(); ++l) {
    EXPECT_GT(t.leaf(uint32_t(l)).selection, 0.6f) << l;
    EXPECT_EQ(t.selection_probability(uint32_t(l)), t.leaf(uint32_t(l)).selection);
  }
  // Not learning: the option's value everywhere, whatever the samples say.
  o.learn_selection = false;
  SDTree fixed(kUnitBox, o);
  fixed.add_sample({vec3(0.5f), vec3(0, 0, 1), 1.0f, 1.0f, 1, 1.0f, 0.5f, 1.5f});
  fixed.update();
  EXPECT_FLOAT_EQ(fixed.selection_probability(0), 0.3f);
}
