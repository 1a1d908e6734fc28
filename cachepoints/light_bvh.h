// The light BVH (`--light-sampler bvh`): the importance-based light hierarchy
// of Conty Estevez & Kulla 2018 ("Importance sampling of many lights with
// adaptive tree splitting"), the many-lights sampler of pbrt-v4 and Cycles,
// here as the baseline cache points are measured against.  It knows nothing
// of occlusion and learns nothing.
//
// Every finite emitter (cachepoints/emitters.h: a mesh light's triangles each
// one) is a leaf; a node bounds its emitters by a box, an orientation cone
// (axis, spread of the normals theta_o, spread of the emission about a normal
// theta_e) and the sum of their peak intensities.  The importance of a node
// at a shading point is that intensity over the squared distance to the box's
// centre (inside its bounding sphere clamped at a quarter of its radius), times the cosine of the smallest angle
// any emitter in the box could emit towards the point at, and times the
// receiver cosine bound under the geometric normal (either side: receivers are
// two-sided, as for cache points); zero only where no emitter in the node can
// light the point.  sample() walks from the root choosing a child in
// proportion to the importances; pmf() walks the same path again from the
// emitter's leaf upwards, so that both multiply the same factors in the same
// order.  Infinite and distant lights are outside the tree: they are chosen
// with the share their fluence has of theirs plus the root's (normal-free)
// importance, and among themselves by fluence.  An emitter whose peak
// intensity is zero (black, zero area) emits nothing and is not in the tree.
//
// Build: binned splits minimising the summed cost intensity x orientation
// measure x box surface area (the paper's SAOH), on a single thread, a pure
// function of the emitters; a split that separates nothing, or depth beyond
// kMaxSahDepth, splits at the median instead, so depth stays bounded.
#pragma once

#include "cachepoints/emitters.h"
#include "core/light_sampler.h"
#include "core/sampling.h"

#include <vector>

namespace theia {

// cos(max(0, theta_a - theta_b)) and sin of it, from the cosines and sines.
inline float cos_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
  return cos_a >= cos_b ? 1.0f : cos_a * cos_b + sin_a * sin_b;
}
inline float sin_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
  return cos_a >= cos_b ? 0.0f : sin_a * cos_b - cos_a * sin_b;
}

// A node's emission bound.  cos_o: the normals lie within theta_o of `axis`;
// cos_e: each emitter sends light within theta_e of its normal (pi/2 for area
// emitters and points; cos_o = -1 is every direction).
struct LightBounds {
  vec3 lo{0.0f}, hi{0.0f};
  vec3 axis{0.0f, 0.0f, 1.0f};
  float cos_o = -1.0f;
  float cos_e = 0.0f;
  float intensity = 0.0f;  // summed peak intensity (luminance, W/sr-like)
  bool two_sided = false;
};

// The union of two bounds (box, cone, intensity).
LightBounds merge(const LightBounds& a, const LightBounds& b);

// What traversal reads of a node's bounds, precomputed: the box's centre and
// squared half diagonal (its bounding sphere), the cone's sine.
struct NodeBounds {
  vec3 center{0.0f};
  float radius2 = 0.0f;
  vec3 axis{0.0f, 0.0f, 1.0f};
  float cos_o = -1.0f, sin_o = 0.0f, cos_e = 0.0f;
  float intensity = 0.0f;
  bool two_sided = false;
};
NodeBounds node_bounds(const LightBounds& b);
// What the node can deliver to p under normal n (zero n: no receiver cosine).
float importance(const NodeBounds& b, const vec3& p, const vec3& n);

struct LightBvhNode {
  NodeBounds bounds;
  int child = -1;     // interior: the first child (the second follows it); leaf: -1
  int emitter = -1;   // leaf: the emitter
  int parent = -1;
};

// The hierarchy over the finite emitters of positive peak intensity (the
// infinite and distant ones, and black ones, are not in it): nodes[0] is the
// root, children follow their parents; empty when there is no such emitter.
// A pure function of the emitters.  `depth`, if given, gets the tree's depth.
std::vector<LightBvhNode> build_light_tree(const LightSet& lights, const EmitterSet& emitters, int* depth = nullptr);

class LightBvhSampler final : public LightSampler {
 public:
  explicit LightBvhSampler(const LightSet& lights);

  std::optional<SampledLight> sample(const LightSampleContext& ctx, float u) const override;
  // The light's triangles summed for a mesh light.
  float pmf(const LightSampleContext& ctx, int light) const override;
  float pmf_primitive(const LightSampleContext& ctx, int light, int primitive) const override;
  const char* name() const override { return "bvh"; }
  bool chooses_primitives() const override { return true; }
  std::vector<std::pair<std::string, double>> statistics() const override;

  // For tests.
  const EmitterSet& emitters() const { return emitters_; }
  const std::vector<LightBvhNode>& nodes() const { return nodes_; }
  // Emitter e's probability by sampling's own arithmetic (0 outside the tree).
  float emitter_pmf(const LightSampleContext& ctx, int e) const;

 private:
  // The probability of the infinite / distant group at ctx.
  float infinite_share(const LightSampleContext& ctx) const;
  float tree_pmf(const LightSampleContext& ctx, int e) const;

  EmitterSet emitters_;
  std::vector<LightBvhNode> nodes_;          // nodes_[0] is the root when not empty
  std::vector<int> leaf_;                    // per emitter: its leaf, -1 if not in the tree
  std::vector<int> infinite_;                // the infinite and distant emitters
  std::vector<float> infinite_fluence_;      // their fluence, per entry of infinite_
  float infinite_total_ = 0.0f;
  Distribution1D infinite_pick_;
  int depth_ = 0;
  double build_seconds_ = 0.0;
};

}  // namespace theia
