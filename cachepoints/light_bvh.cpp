#include "cachepoints/light_bvh.h"

#include "core/stats.h"
#include "scene/shapes.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace theia {

namespace {

// Angles are widened by this much (radians) and cosines never bounded below it,
// so that rounding in the cone unions and bounds cannot zero a node that lights a point.
constexpr float kSlack = 1e-4f;
// Beyond this depth, median splits: depth stays below kMaxSahDepth + log2(emitters).
constexpr int kMaxSahDepth = 48;
constexpr int kMaxDepth = 128;
constexpr int kBuckets = 12;
// Inside a node's bounding sphere its emitters may be anywhere: the distance
// is the centre's, clamped at a quarter of the radius only against the
// singularity.  (Clamping at the radius, as if every emitter were that far,
// starves the nodes around the point: many-lights-city at 64 spp, seed 3,
// relMSE 0.44 against 0.12; a clamp at r/16 gives 0.12 too.)
constexpr float kInsideDistance2 = 1.0f / 16.0f;

struct Cone {
  vec3 axis{0.0f, 0.0f, 1.0f};
  float cos_o = -1.0f;
};

// The smallest cone (up to kSlack) holding both.
Cone cone_union(const Cone& a, const Cone& b) {
  if (a.cos_o <= -1.0f || b.cos_o <= -1.0f) return Cone{a.axis, -1.0f};
  const float ta = safe_acos(a.cos_o), tb = safe_acos(b.cos_o);
  const float td = safe_acos(glm::dot(a.axis, b.axis));
  if (std::min(td + tb, kPi) <= ta) return a;
  if (std::min(td + ta, kPi) <= tb) return b;
  const float to = 0.5f * (ta + td + tb) + kSlack;
  if (to >= kPi) return Cone{a.axis, -1.0f};
  const vec3 perp = b.axis - a.axis * glm::dot(a.axis, b.axis);
  const float len = glm::length(perp);
  if (!(len > 1e-7f)) return Cone{a.axis, -1.0f};
  const float tr = to - ta;
  return Cone{glm::normalize(std::cos(tr) * a.axis + std::sin(tr) * (perp / len)), std::cos(to)};
}

float surface_area(const vec3& lo, const vec3& hi) {
  const vec3 d = hi - lo;
  return 2.0f * (d.x * d.y + d.y * d.z + d.z * d.x);
}

// Conty Estevez & Kulla's orientation measure of a bound (its cone and emission spread).
float orientation_measure(const LightBounds& b) {
  const float to = safe_acos(b.cos_o), te = safe_acos(b.cos_e);
  const float tw = std::min(to + te, kPi);
  const float so = safe_sqrt(1.0f - b.cos_o * b.cos_o);
  return 2.0f * kPi * (1.0f - b.cos_o) +
         0.5f * kPi * (2.0f * tw * so - std::cos(to - 2.0f * tw) - 2.0f * to * so + b.cos_o);
}

// The split cost of a bound: power x orientation x size.  A flat or linear box
// (coplanar or collinear emitters) keeps a size from its longest side.
float split_cost(const LightBounds& b) {
  const vec3 d = b.hi - b.lo;
  const float size = std::max(surface_area(b.lo, b.hi), sqr(std::max({d.x, d.y, d.z})));
  return b.intensity * orientation_measure(b) * size;
}

// The peak intensity of a point-like light: the largest over a spiral of
// directions and the axis, and never below the isotropic mean power / 4 pi (so
// a narrow spot the spiral misses is still in the tree).
float point_intensity(const LightSet& lights, int light) {
  const Light& l = lights.scene->lights[size_t(light)];
  float peak = std::max(0.0f, luminance(light_intensity(lights, light, l.direction)));
  constexpr int kDirections = 256;
  for (int i = 0; i < kDirections; ++i) {
    const float z = 1.0f - 2.0f * (float(i) + 0.5f) / kDirections;
    const float phi = float(i) * 2.39996323f;  // the golden angle
    const float r = safe_sqrt(1.0f - z * z);
    peak = std::max(peak, luminance(light_intensity(lights, light, vec3(r * std::cos(phi), r * std::sin(phi), z))));
  }
  return std::max(peak, light_power(lights, light) / (4.0f * kPi));
}

// A mesh triangle's own box; anything else: the cube about its bounding sphere.
void emitter_box(const LightSet& lights, const Emitter& e, LightBounds& b) {
  b.lo = e.center - vec3(e.radius);
  b.hi = e.center + vec3(e.radius);
  if (e.primitive < 0) return;
  const Light& l = lights.scene->lights[size_t(e.light)];
  const TriangleMesh& m = lights.scene->meshes[size_t(lights.scene->shapes[size_t(l.shape)].mesh)];
  b.lo = b.hi = m.p[m.indices[3 * size_t(e.primitive)]];
  for (size_t k = 1; k < 3; ++k) {
    b.lo = glm::min(b.lo, m.p[m.indices[3 * size_t(e.primitive) + k]]);
    b.hi = glm::max(b.hi, m.p[m.indices[3 * size_t(e.primitive) + k]]);
  }
}

LightBounds emitter_bounds(const LightSet& lights, const Emitter& e) {
  LightBounds b;
  emitter_box(lights, e, b);
  if (e.kind == EmitterKind::PointLike) {
    b.intensity = point_intensity(lights, e.light);
    return b;
  }
  // An area emitter's peak intensity is at most radiance x area (along the
  // normal of a flat one); without a normal (sphere, cylinder) every direction.
  b.intensity = std::max(0.0f, e.radiance * e.area);
  if (glm::dot(e.normal, e.normal) > 0.0f) {
    b.axis = e.normal;
    b.cos_o = 1.0f;
    b.two_sided = e.two_sided;
  }
  return b;
}

// The probability of the first of two importances; -1 when neither is positive.
float first_probability(float a, float b) {
  const float sum = a + b;
  if (!(sum > 0.0f)) return -1.0f;
  if (std::isinf(sum)) return std::isinf(a) ? (std::isinf(b) ? 0.5f : 1.0f) : 0.0f;
  return a / sum;
}

// u rescaled into the chosen part of [0, 1).
float remap(float u, float lo, float width) { return std::min((u - lo) / width, kOneMinusEpsilon); }

struct BuildItem {
  LightBounds bounds;
  vec3 centroid{0.0f};
  int emitter = -1;
};

struct Builder {
  std::vector<BuildItem> items;
  std::vector<LightBvhNode>& nodes;
  int depth = 0;

  struct Split {
    float cost = std::numeric_limits<float>::infinity();
    int axis = -1, bucket = -1;
  };

  static int bucket_of(const BuildItem& it, int axis, const vec3& clo, const vec3& extent) {
    return std::clamp(int(kBuckets * (it.centroid[axis] - clo[axis]) / extent[axis]), 0, kBuckets - 1);
  }

  // The cheapest bucket boundary on one axis (kr: the box's elongation penalty).
  void best_on_axis(size_t begin, size_t end, int axis, const vec3& clo, const vec3& extent, float kr, Split& best) {
    // Empty bounds have zero intensity, which merge() treats as nothing.
    std::array<LightBounds, kBuckets> bins{}, right{};
    for (size_t i = begin; i < end; ++i) {
      const size_t k = size_t(bucket_of(items[i], axis, clo, extent));
      bins[k] = merge(bins[k], items[i].bounds);
    }
    for (int k = kBuckets - 1; k >= 0; --k)
      right[size_t(k)] = k + 1 < kBuckets ? merge(bins[size_t(k)], right[size_t(k + 1)]) : bins[size_t(k)];
    LightBounds left;
    for (int s = 0; s + 1 < kBuckets; ++s) {
      left = merge(left, bins[size_t(s)]);
      const LightBounds& r = right[size_t(s + 1)];
      if (!(left.intensity > 0.0f) || !(r.intensity > 0.0f)) continue;
      const float cost = (split_cost(left) + split_cost(r)) * kr;
      if (cost < best.cost) best = Split{cost, axis, s};
    }
  }

  // Items [begin, end) reordered so that [begin, mid) and [mid, end) are the children; returns mid.
  size_t split(size_t begin, size_t end, int level) {
    vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
    vec3 clo = lo, chi = hi;
    for (size_t i = begin; i < end; ++i) {
      lo = glm::min(lo, items[i].bounds.lo), hi = glm::max(hi, items[i].bounds.hi);
      clo = glm::min(clo, items[i].centroid), chi = glm::max(chi, items[i].centroid);
    }
    const vec3 extent = chi - clo, box = hi - lo;
    Split best;
    for (int axis = 0; level < kMaxSahDepth && axis < 3; ++axis)
      if (extent[axis] > 0.0f)
        best_on_axis(begin, end, axis, clo, extent, std::max({box.x, box.y, box.z}) / std::max(box[axis], 1e-30f), best);
    if (best.axis >= 0) {
      auto mid = std::partition(items.begin() + std::ptrdiff_t(begin), items.begin() + std::ptrdiff_t(end),
                                [&](const BuildItem& it) { return bucket_of(it, best.axis, clo, extent) <= best.bucket; });
      const size_t m = size_t(mid - items.begin());
      if (m > begin && m < end) return m;
    }
    return median_split(begin, end, extent);
  }

  // Half the items each side, by centroid along the widest axis (ties by emitter index).
  size_t median_split(size_t begin, size_t end, const vec3& extent) {
    const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
    const size_t mid = begin + (end - begin) / 2;
    std::nth_element(items.begin() + std::ptrdiff_t(begin), items.begin() + std::ptrdiff_t(mid),
                     items.begin() + std::ptrdiff_t(end), [axis](const BuildItem& a, const BuildItem& b) {
                       return a.centroid[axis] < b.centroid[axis] ||
                              (a.centroid[axis] == b.centroid[axis] && a.emitter < b.emitter);
                     });
    return mid;
  }

  // Fills nodes[index] from items [begin, end); children are appended in pairs.
  // Returns the node's bounds.
  LightBounds build(int index, size_t begin, size_t end, int parent, int level) {
    depth = std::max(depth, level + 1);
    nodes[size_t(index)].parent = parent;
    LightBounds b = items[begin].bounds;
    if (end - begin == 1) {
      nodes[size_t(index)].emitter = items[begin].emitter;
    } else {
      const size_t mid = split(begin, end, level);
      const int child = int(nodes.size());
      nodes.resize(nodes.size() + 2);
      nodes[size_t(index)].child = child;
      b = merge(build(child, begin, mid, index, level + 1), build(child + 1, mid, end, index, level + 1));
    }
    nodes[size_t(index)].bounds = node_bounds(b);
    return b;
  }
};

}  // namespace

LightBounds merge(const LightBounds& a, const LightBounds& b) {
  if (a.intensity == 0.0f) return b;
  if (b.intensity == 0.0f) return a;
  const Cone c = cone_union(Cone{a.axis, a.cos_o}, Cone{b.axis, b.cos_o});
  LightBounds m;
  m.lo = glm::min(a.lo, b.lo);
  m.hi = glm::max(a.hi, b.hi);
  m.axis = c.axis;
  m.cos_o = c.cos_o;
  m.cos_e = std::min(a.cos_e, b.cos_e);
  m.intensity = a.intensity + b.intensity;
  m.two_sided = a.two_sided || b.two_sided;
  return m;
}

NodeBounds node_bounds(const LightBounds& b) {
  NodeBounds n;
  n.center = 0.5f * (b.lo + b.hi);
  n.radius2 = 0.25f * glm::dot(b.hi - b.lo, b.hi - b.lo);
  n.axis = b.axis;
  n.cos_o = b.cos_o;
  n.sin_o = safe_sqrt(1.0f - b.cos_o * b.cos_o);
  n.cos_e = b.cos_e;
  n.intensity = b.intensity;
  n.two_sided = b.two_sided;
  return n;
}

float importance(const NodeBounds& b, const vec3& p, const vec3& n) {
  if (!(b.intensity > 0.0f)) return 0.0f;
  const vec3 d = p - b.center;
  const float d2_raw = glm::dot(d, d);
  const float d2 = std::max({d2_raw, kInsideDistance2 * b.radius2, 1e-20f});
  // Inside the bounding sphere every direction is possible (theta_b = pi).
  if (d2_raw <= b.radius2 || d2_raw == 0.0f) return b.intensity / d2;
  const float inv_d = 1.0f / std::sqrt(d2_raw);
  const vec3 wi = d * inv_d;
  const float sin_b2 = b.radius2 / d2_raw;
  const float sin_b = std::sqrt(sin_b2), cos_b = safe_sqrt(1.0f - sin_b2);
  float cos_w = glm::dot(b.axis, wi);
  if (b.two_sided) cos_w = std::abs(cos_w);
  const float sin_w = safe_sqrt(1.0f - cos_w * cos_w);
  const float cos_x = cos_sub_clamped(sin_w, cos_w, b.sin_o, b.cos_o);
  const float sin_x = sin_sub_clamped(sin_w, cos_w, b.sin_o, b.cos_o);
  const float cos_p = cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
  if (cos_p <= b.cos_e - kSlack) return 0.0f;
  float value = b.intensity * std::max(cos_p, kSlack) / d2;
  if (glm::dot(n, n) > 0.0f) {
    const float cos_i = std::abs(glm::dot(wi, n));
    const float cos_ip = cos_sub_clamped(safe_sqrt(1.0f - cos_i * cos_i), cos_i, sin_b, cos_b);
    value *= std::max(cos_ip, kSlack);
  }
  return value;
}

std::vector<LightBvhNode> build_light_tree(const LightSet& lights, const EmitterSet& emitters, int* depth) {
  std::vector<LightBvhNode> nodes;
  Builder builder{{}, nodes};
  for (size_t e = 0; e < emitters.size(); ++e) {
    const Emitter& em = emitters.emitters[e];
    if (em.kind == EmitterKind::Infinite || em.kind == EmitterKind::Distant) continue;
    LightBounds b = emitter_bounds(lights, em);
    if (b.intensity > 0.0f && std::isfinite(b.intensity)) builder.items.push_back({b, em.center, int(e)});
  }
  if (!builder.items.empty()) {
    nodes.resize(1);
    builder.build(0, 0, builder.items.size(), -1, 0);
  }
  if (depth) *depth = builder.depth;
  return nodes;
}

LightBvhSampler::LightBvhSampler(const LightSet& lights) {
  ScopedTimer timer(build_seconds_);
  emitters_ = build_emitters(lights);
  leaf_.assign(emitters_.size(), -1);
  for (size_t e = 0; e < emitters_.size(); ++e) {
    const Emitter& em = emitters_.emitters[e];
    if (em.kind != EmitterKind::Infinite && em.kind != EmitterKind::Distant) continue;
    infinite_.push_back(int(e));
    infinite_fluence_.push_back(std::max(0.0f, emitter_importance(lights, em, vec3(0.0f), vec3(0.0f))));
    infinite_total_ += infinite_fluence_.back();
  }
  if (!infinite_.empty()) infinite_pick_ = Distribution1D(infinite_fluence_);
  nodes_ = build_light_tree(lights, emitters_, &depth_);
  for (size_t i = 0; i < nodes_.size(); ++i)
    if (nodes_[i].child < 0) leaf_[size_t(nodes_[i].emitter)] = int(i);
}

float LightBvhSampler::infinite_share(const LightSampleContext& ctx) const {
  const float tree = nodes_.empty() ? 0.0f : importance(nodes_[0].bounds, ctx.p, vec3(0.0f));
  return first_probability(infinite_total_, tree);
}

std::optional<SampledLight> LightBvhSampler::sample(const LightSampleContext& ctx, float u) const {
  const float share = infinite_share(ctx);
  if (share < 0.0f) return std::nullopt;
  if (u < share) {
    const int i = infinite_pick_.sample_discrete(remap(u, 0.0f, share));
    const Emitter& e = emitters_.emitters[size_t(infinite_[size_t(i)])];
    const float pmf = share * infinite_pick_.discrete_pmf(i);
    if (!(pmf > 0.0f)) return std::nullopt;
    return SampledLight{e.light, pmf, 0, e.primitive};
  }
  u = remap(u, share, 1.0f - share);
  float pmf = 1.0f;
  int node = 0;
  while (nodes_[size_t(node)].child >= 0) {
    const int c = nodes_[size_t(node)].child;
    const float p = first_probability(importance(nodes_[size_t(c)].bounds, ctx.p, ctx.ng),
                                      importance(nodes_[size_t(c + 1)].bounds, ctx.p, ctx.ng));
    if (p < 0.0f) return std::nullopt;
    if (u < p) {
      u = remap(u, 0.0f, p);
      pmf *= p;
      node = c;
    } else {
      u = remap(u, p, 1.0f - p);
      pmf *= 1.0f - p;
      node = c + 1;
    }
  }
  pmf *= 1.0f - share;
  if (!(pmf > 0.0f)) return std::nullopt;
  const Emitter& e = emitters_.emitters[size_t(nodes_[size_t(node)].emitter)];
  return SampledLight{e.light, pmf, 0, e.primitive};
}

float LightBvhSampler::tree_pmf(const LightSampleContext& ctx, int e) const {
  // The path from the root, then the same products sample() takes along it.
  std::array<int, kMaxDepth> path{};
  int n = 0;
  for (int node = leaf_[size_t(e)]; node >= 0 && n < kMaxDepth; node = nodes_[size_t(node)].parent) path[size_t(n++)] = node;
  float pmf = 1.0f;
  for (int k = n - 1; k > 0; --k) {
    const int c = nodes_[size_t(path[size_t(k)])].child;
    const float p = first_probability(importance(nodes_[size_t(c)].bounds, ctx.p, ctx.ng),
                                      importance(nodes_[size_t(c + 1)].bounds, ctx.p, ctx.ng));
    if (p < 0.0f) return 0.0f;
    pmf *= path[size_t(k - 1)] == c ? p : 1.0f - p;
  }
  return pmf;
}

float LightBvhSampler::emitter_pmf(const LightSampleContext& ctx, int e) const {
  if (e < 0 || size_t(e) >= emitters_.size()) return 0.0f;
  const float share = infinite_share(ctx);
  if (share < 0.0f) return 0.0f;
  const auto inf = std::find(infinite_.begin(), infinite_.end(), e);
  if (inf != infinite_.end()) return share * infinite_pick_.discrete_pmf(int(inf - infinite_.begin()));
  if (leaf_[size_t(e)] < 0) return 0.0f;
  return tree_pmf(ctx, e) * (1.0f - share);
}

float LightBvhSampler::pmf_primitive(const LightSampleContext& ctx, int light, int primitive) const {
  return emitter_pmf(ctx, emitters_.find(light, primitive));
}

float LightBvhSampler::pmf(const LightSampleContext& ctx, int light) const {
  if (light < 0 || size_t(light) >= emitters_.first.size()) return 0.0f;
  float sum = 0.0f;
  const int first = emitters_.first[size_t(light)];
  for (int e = first; e < first + emitters_.count[size_t(light)]; ++e) sum += emitter_pmf(ctx, e);
  return sum;
}

std::vector<std::pair<std::string, double>> LightBvhSampler::statistics() const {
  const double bytes = double(nodes_.size() * sizeof(LightBvhNode) + emitters_.size() * (sizeof(Emitter) + sizeof(int)) +
                              infinite_.size() * (sizeof(int) + 2 * sizeof(float)));
  return {{"build_seconds", build_seconds_},
          {"emitters", double(emitters_.size())},
          {"emitters_in_tree", double((nodes_.size() + 1) / 2)},
          {"infinite_emitters", double(infinite_.size())},
          {"nodes", double(nodes_.size())},
          {"depth", double(depth_)},
          {"memory_bytes", bytes}};
}

}  // namespace theia
