#include "guiding/sd_tree.h"

#include "core/hash.h"
#include "core/huge_pages.h"
#include "core/log.h"
#include "core/stats.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <bit>
#include <atomic>
#include <cmath>
#include <limits>
#include <optional>

namespace theia {

namespace {

// atan2(y, x) in [-pi, pi] without libm's call (atan2f and its atanf were
// ~2.6% of a guided veach-ajar render's CPU after training: every pdf() and
// every training deposit maps a direction).  Cephes atanf: the ratio of the
// smaller to the larger component, reduced by atan(a) = pi/4 + atan((a-1) /
// (a+1)) above tan(pi/8), then its degree-9 odd polynomial, within ~2 ulp
// of atan; the quadrant's pi/2 - r, pi - r add one more rounding of pi.
// So phi is off by a few 1e-7 at most, the size of atan2f's own rounding
// and of the float phi / 2 pi after it: a direction that close to a quad's
// edge could read its neighbour either way (sample() says the same of the
// map back).
inline float atan2_poly(float y, float x) {
  const float ax = std::abs(x), ay = std::abs(y);
  const float hi = std::max(ax, ay), lo = std::min(ax, ay);
  if (!(hi > 0.0f)) return 0.0f;
  const float a = lo / hi;
  const bool reduce = a > 0.41421356237f;
  const float t = reduce ? (a - 1.0f) / (a + 1.0f) : a;
  const float z = t * t;
  // Explicit fmas, so that every inlined copy rounds alike.
  const float p = std::fma(std::fma(std::fma(8.05374449538e-2f, z, -1.38776856032e-1f), z, 1.99777106478e-1f), z,
                           -3.33329491539e-1f);
  float r = std::fma(p * z, t, t);
  if (reduce) r += 0.25f * kPi;
  if (ay > ax) r = 0.5f * kPi - r;
  if (x < 0.0f) r = kPi - r;
  return y < 0.0f ? -r : r;
}

}  // namespace

vec2 sd_direction_to_square(const vec3& wi) {
  float x = std::clamp(0.5f * (wi.z + 1.0f), 0.0f, kOneMinusEpsilon);
  float phi = atan2_poly(wi.y, wi.x);
  if (phi < 0.0f) phi += 2.0f * kPi;
  float y = std::clamp(phi * kInv2Pi, 0.0f, kOneMinusEpsilon);
  return {x, y};
}

vec3 sd_square_to_direction(vec2 c) {
  float cos_theta = 2.0f * c.x - 1.0f;
  float sin_theta = safe_sqrt(1.0f - cos_theta * cos_theta);
  const vec2 cs = cos_sin_turn(c.y);
  return {sin_theta * cs.x, sin_theta * cs.y, cos_theta};
}

namespace {

using glm::dvec2;

constexpr uint32_t kMaxNodes = std::numeric_limits<uint32_t>::max() - 2;

// Picks the quadrant of c in a node and rescales c to the quadrant's own
// [0,1)^2; exact in binary floating point.
// Without branches: a direction's quadrant is a coin flip at every level,
// which a predictor cannot learn (2c - 0 and 2c - 1 are both exact).
inline int descend(vec2& c) {
  const int right = c.x >= 0.5f, upper = c.y >= 0.5f;
  c.x = 2.0f * c.x - float(right);
  c.y = 2.0f * c.y - float(upper);
  return right | upper << 1;
}

template <typename T>
T node_total(const QuadNode<T>& n) {
  return n.flux[0] + n.flux[1] + n.flux[2] + n.flux[3];
}

// The building quadtree for the next iteration: the accumulated tree's
// topology refined by its flux (Müller 2017 DTree::reset), keeping the flux.
// A quad holding more than rho of the leaf's flux is subdivided, one holding
// less becomes a leaf (its subtree's flux summed into it).  A quad subdivided
// now has its flux split evenly among its children, which resolves nothing,
// so refinement goes at most one level below what `prev` resolved per update
// (shallow refinement: deeper quads wait for deposits that justify them).  A
// tree with no flux refines uniformly to the depth where a quad holds at most
// rho.  `prev` carries inner sums (sum_flux_bottom_up); the result holds
// flux at its leaves only.
std::vector<BuildingQuadNode> refine_quadtree(const std::vector<BuildingQuadNode>& prev, double rho,
                                              int max_depth) {
  constexpr uint32_t kNone = 0xffffffffu;
  struct Item {
    uint32_t index, src;  // src: node of prev, or kNone (split node_flux evenly)
    double node_flux;
    int depth;            // depth of this node's quadrants (the root's are 1)
  };
  const double total = prev.empty() ? 0.0 : node_total(prev[0]);
  const bool learned = total > 0.0 && std::isfinite(total);
  std::vector<BuildingQuadNode> out(1);
  std::vector<Item> stack{{0, prev.empty() ? kNone : 0u, total, 1}};
  while (!stack.empty()) {
    Item it = stack.back();
    stack.pop_back();
    for (int i = 0; i < 4; ++i) {
      double quad_flux = it.src != kNone ? prev[it.src].flux[i] : 0.25 * it.node_flux;
      double fraction = learned ? quad_flux / total : std::pow(0.25, it.depth);
      // A quad of prev subdivides; a quad made here only without learned flux (the uniform start).
      bool may_split = it.src != kNone || !learned;
      if (!may_split || it.depth >= max_depth || !(fraction > rho) || out.size() >= kMaxNodes) {
        if (learned) out[it.index].flux[i] = quad_flux;
        continue;
      }
      uint32_t src = it.src != kNone && prev[it.src].child[i] != 0 ? prev[it.src].child[i] : kNone;
      uint32_t child = uint32_t(out.size());
      out[it.index].child[i] = child;
      out.emplace_back();
      stack.push_back({child, src, quad_flux, it.depth + 1});
    }
  }
  return out;
}

// Inner quadrants get the sum of their subtree; children follow parents, so
// one reverse pass suffices.
void sum_flux_bottom_up(std::vector<BuildingQuadNode>& nodes) {
  for (size_t n = nodes.size(); n-- > 0;)
    for (int i = 0; i < 4; ++i)
      if (nodes[n].child[i] != 0) nodes[n].flux[i] = node_total(nodes[nodes[n].child[i]]);
}

// Area-weighted deposit of density * overlap into the leaf quads that the box
// [b0, b1) overlaps, in a node spanning [origin, origin + size)^2.
void deposit_box(BuildingQuadNode* nodes, uint32_t index, dvec2 origin, double size, dvec2 b0, dvec2 b1,
                 double density) {
  const double half = 0.5 * size;
  for (int i = 0; i < 4; ++i) {
    dvec2 o = origin + dvec2((i & 1) ? half : 0.0, (i & 2) ? half : 0.0);
    double wx = std::min(b1.x, o.x + half) - std::max(b0.x, o.x);
    double wy = std::min(b1.y, o.y + half) - std::max(b0.y, o.y);
    if (!(wx > 0.0 && wy > 0.0)) continue;
    if (nodes[index].child[i] == 0) nodes[index].flux[i] += density * wx * wy;
    else deposit_box(nodes, nodes[index].child[i], o, half, b0, b1, density);
  }
}

// A uniform float in [0,1) from 21 bits of h, `slot` 0..2.
inline float hash_unit(uint64_t h, int slot) { return float((h >> (21 * slot)) & 0x1fffffu) * 0x1p-21f; }

bool finite3(const vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

}  // namespace

void SDTree::check_options(const SDTreeOptions& options) {
  if (!(options.spatial_threshold > 0.0) || !std::isfinite(options.spatial_threshold))
    throw_error("SD-tree: spatial threshold must be positive and finite, got {}", options.spatial_threshold);
  if (!(options.flux_threshold > 0.0 && options.flux_threshold < 1.0))
    throw_error("SD-tree: flux threshold must be in (0, 1), got {}", options.flux_threshold);
  if (options.max_quadtree_depth < 1 || options.max_quadtree_depth > 24)
    throw_error("SD-tree: max quadtree depth must be in [1, 24], got {}", options.max_quadtree_depth);
  // Above 1/2 the halves of a busy leaf could stay above the threshold forever.
  if (!(options.split_decay > 0.0 && options.split_decay <= 0.5))
    throw_error("SD-tree: split decay must be in (0, 0.5], got {}", options.split_decay);
  if (!(options.pdf_floor >= 0.0f) || !std::isfinite(options.pdf_floor))
    throw_error("SD-tree: pdf floor must be zero or positive, got {}", options.pdf_floor);
  if (!(options.selection_probability >= 0.0f && options.selection_probability <= 1.0f))
    throw_error("SD-tree: selection probability must be in [0, 1], got {}", options.selection_probability);
  if (options.learn_selection && !(options.selection_probability > 0.0f && options.selection_probability < 1.0f))
    throw_error("SD-tree: a learned selection probability starts in (0, 1), got {}", options.selection_probability);
}

SDTree::SDTree(const Bounds3& scene_bounds, const SDTreeOptions& options) : options_(options) {
  check_options(options);

  // A cube around the scene, 1% larger (Müller makes the box cubic so that
  // halving along x, y, z in turn keeps leaves near cubes), with an absolute
  // margin so that a flat or point-like scene still gets a box with volume.
  vec3 centre(0.0f);
  float half = 0.0f;
  if (!scene_bounds.empty()) {
    if (!finite3(scene_bounds.min) || !finite3(scene_bounds.max))
      throw_error("SD-tree: scene bounds are not finite");
    centre = scene_bounds.centroid();
    vec3 d = scene_bounds.diagonal();
    half = 0.5f * std::max(d.x, std::max(d.y, d.z));
  }
  float scale = std::max({std::abs(centre.x), std::abs(centre.y), std::abs(centre.z), half});
  half = 1.01f * half + std::max(1e-4f * scale, 1e-6f);
  root_ = Bounds3(centre - vec3(half), centre + vec3(half));
  root_size_ = root_.max - root_.min;

  nodes_.push_back(SpatialNode{0, 0, 0});
  leaves_.emplace_back();
  leaves_[0].sampling.resize(1);
  leaves_[0].selection = options_.selection_probability;
  if (options_.learn_selection) {
    const float start = options_.selection_probability;
    leaves_[0].learner.theta = std::log(start / (1.0f - start));
  }
  leaves_[0].building = refine_quadtree({}, options_.flux_threshold, options_.max_quadtree_depth);
  index_lookups();
}

SDTree::Lookup SDTree::find_leaf(const vec3& p) const {
  vec3 q = (p - root_.min) / root_size_;
  for (int a = 0; a < 3; ++a) q[a] = std::clamp(q[a], 0.0f, kOneMinusEpsilon);
  Lookup at{0, root_.min, root_size_};
  uint32_t n = 0;
  while (nodes_[n].first_child != 0) {
    int a = nodes_[n].axis;
    at.size[a] *= 0.5f;
    if (q[a] < 0.5f) {
      q[a] *= 2.0f;
      n = nodes_[n].first_child;
    } else {
      q[a] = 2.0f * q[a] - 1.0f;
      at.lo[a] += at.size[a];
      n = nodes_[n].first_child + 1;
    }
  }
  at.leaf = nodes_[n].leaf;
  return at;
}

namespace {
// A two-way split's share of its first side, a / (a + b), as GuideNode keeps
// it: the smaller side's share in float, negated when it is the second
// side's, so that 1 - share is never taken of a rounded float (a quad of
// 1e-7 of its node would keep no correct digit).  Both sides 0: 1/2.
float stored_share(double a, double b) {
  const double total = a + b;
  if (!(total > 0.0)) return 0.5f;
  return a <= b ? float(a / total) : -float(b / total);
}
// Either side's share, chosen by a select rather than a branch (the side a
// lookup takes is unpredictable).
inline double side_share(float s, bool second) {
  const double kept = std::abs(double(s));
  return std::signbit(s) == second ? kept : 1.0 - kept;
}
inline double first_share(float s) { return side_share(s, false); }

// Every index_lookups() takes a new generation, so that a thread's last leaf
// is never read against another tree or another update's boxes.
std::atomic<uint64_t> next_lookup_generation{1};
struct LastLeaf {
  uint64_t generation = 0;
  uint32_t leaf = 0;
};
thread_local LastLeaf last_leaf;
}  // namespace

uint32_t SDTree::leaf_at(const vec3& p) const {
  const vec3 q = (p - root_.min) / root_size_;  // as find_leaf computes it
  // As a clamp to [0, 1), but a NaN lands in cell 0 too: it indexes the grid below.
  auto unit = [](float x) { return x > 0.0f ? std::min(x, kOneMinusEpsilon) : 0.0f; };
  const float c[3] = {unit(q.x), unit(q.y), unit(q.z)};
  // The box test and the descent compare with the same planes, so they agree
  // exactly: the leaf does not depend on what the thread looked up before.
  LastLeaf& last = last_leaf;
  if (last.generation == lookup_generation_) {
    const LeafBox& b = leaf_box_[last.leaf];
    bool inside = true;
    for (int a = 0; a < 3; ++a) inside &= double(c[a]) >= b.lo[a] && double(c[a]) < b.hi[a];
    if (inside) return last.leaf;
  }
  const RegionNode* nodes = region_nodes_.data();
  constexpr float kCells = float(1 << kLookupGridBits);
  uint32_t n = lookup_grid_[(uint32_t(c[2] * kCells) << kLookupGridBits | uint32_t(c[1] * kCells)) << kLookupGridBits |
                            uint32_t(c[0] * kCells)];
  while (nodes[n].first_child != 0)
    n = nodes[n].first_child + uint32_t(double(c[nodes[n].axis_or_leaf]) >= nodes[n].split);
  last = {lookup_generation_, nodes[n].axis_or_leaf};
  return nodes[n].axis_or_leaf;
}

void SDTree::index_lookups() {
  // Each node's box in unit coordinates (dyadic, so exact in double), and
  // in world units halved as find_leaf halves it.
  struct Item {
    uint32_t node;
    glm::dvec3 lo, size;
    vec3 world_size;
  };
  region_nodes_.assign(nodes_.size(), RegionNode{});
  leaf_size_.assign(leaves_.size(), vec3(0.0f));
  leaf_box_.assign(leaves_.size(), LeafBox{});
  lookup_generation_ = next_lookup_generation.fetch_add(1, std::memory_order_relaxed);
  std::vector<Item> stack{{0, glm::dvec3(0.0), glm::dvec3(1.0), root_size_}};
  while (!stack.empty()) {
    Item it = stack.back();
    stack.pop_back();
    const SpatialNode& n = nodes_[it.node];
    RegionNode& r = region_nodes_[it.node];
    if (n.first_child == 0) {
      r.axis_or_leaf = n.leaf;
      leaf_size_[n.leaf] = it.world_size;
      for (int a = 0; a < 3; ++a) {
        leaf_box_[n.leaf].lo[a] = it.lo[a];
        leaf_box_[n.leaf].hi[a] = it.lo[a] + it.size[a];
      }
      continue;
    }
    r.first_child = n.first_child;
    r.axis_or_leaf = n.axis;
    it.size[n.axis] *= 0.5;
    it.world_size[n.axis] *= 0.5f;
    r.split = it.lo[n.axis] + it.size[n.axis];
    stack.push_back({n.first_child, it.lo, it.size, it.world_size});
    it.lo[n.axis] = r.split;
    stack.push_back({n.first_child + 1, it.lo, it.size, it.world_size});
  }
  // The grid: a node's box in cells [lo, lo + size) per axis; a node whose
  // split falls inside a cell (or a leaf) names all of its cells.
  constexpr uint32_t kCells = 1u << kLookupGridBits;
  lookup_grid_.assign(size_t(kCells) * kCells * kCells, 0);
  struct Cells {
    uint32_t node;
    uint32_t lo[3], size[3];
  };
  std::vector<Cells> cells{{0, {0, 0, 0}, {kCells, kCells, kCells}}};
  while (!cells.empty()) {
    Cells it = cells.back();
    cells.pop_back();
    const RegionNode& r = region_nodes_[it.node];
    const uint32_t a = r.axis_or_leaf;
    if (r.first_child != 0 && it.size[a] >= 2) {
      it.size[a] /= 2;
      cells.push_back({r.first_child, {it.lo[0], it.lo[1], it.lo[2]}, {it.size[0], it.size[1], it.size[2]}});
      it.lo[a] += it.size[a];
      it.node = r.first_child + 1;
      cells.push_back(it);
      continue;
    }
    for (uint32_t z = it.lo[2]; z < it.lo[2] + it.size[2]; ++z)
      for (uint32_t y = it.lo[1]; y < it.lo[1] + it.size[1]; ++y)
        for (uint32_t x = it.lo[0]; x < it.lo[0] + it.size[0]; ++x)
          lookup_grid_[(size_t(z) * kCells + y) * kCells + x] = it.node;
  }
  // The guide's nodes: each leaf with energy gets its sampling quadtree's
  // nodes, breadth-first, after the previous leaf's (a leaf without energy
  // is never descended).  Breadth-first puts a node's children side by side
  // and the upper levels, which every descent reads, in a few lines.
  guide_leaves_.assign(leaves_.size(), GuideLeaf{});
  uint32_t total_nodes = 0;
  for (size_t l = 0; l < leaves_.size(); ++l) {
    const SpatialLeaf& leaf = leaves_[l];
    GuideLeaf& g = guide_leaves_[l];
    g.first_node = total_nodes;
    g.has_energy = leaf.has_energy ? 1u : 0u;
    g.selection = leaf.selection;
    g.radiance_integral = leaf.radiance_integral;
    if (!leaf.has_energy) continue;
    // The link word holds a child's index in 27 bits; refinement at rho
    // makes at most ~depth / rho nodes, far below that.
    if (leaf.sampling.size() >= (size_t(1) << 27) || leaf.sampling.size() >= size_t(kMaxNodes) - total_nodes)
      throw_error("SD-tree: leaf {}'s quadtree has {} nodes, more than lookups can index", l, leaf.sampling.size());
    total_nodes += uint32_t(leaf.sampling.size());
  }
  guide_nodes_.assign(total_nodes, GuideNode{});
  tbb::parallel_for(size_t(0), leaves_.size(), [&](size_t l) {
    const SpatialLeaf& leaf = leaves_[l];
    if (!leaf.has_energy) return;
    GuideNode* out = guide_nodes_.data() + guide_leaves_[l].first_node;
    // Breadth-first: order[k] is the sampling node laid out at k.  A
    // quadtree is a tree (the reader checks it), so each node comes once.
    std::vector<uint32_t> order{0};
    order.reserve(leaf.sampling.size());
    for (size_t k = 0; k < order.size(); ++k) {
      const SamplingQuadNode& node = leaf.sampling[order[k]];
      GuideNode& g = out[k];
      const double left = double(node.flux[0]) + double(node.flux[2]);
      const double right = double(node.flux[1]) + double(node.flux[3]);
      const double total = left + right;
      const bool empty = !(total > 0.0);
      if (!empty) {
        // A column or quadrant without flux gets probability 0, so that
        // neither the draw nor the density ever reaches it.
        g.column = stored_share(left, right);
        g.row[0] = stored_share(double(node.flux[0]), double(node.flux[2]));
        g.row[1] = stored_share(double(node.flux[1]), double(node.flux[3]));
      }
      uint32_t mask = 0;
      const uint32_t first_child = uint32_t(order.size());
      for (int i = 0; i < 4; ++i)
        if (node.child[i] != 0) {
          mask |= 1u << i;
          order.push_back(node.child[i]);
        }
      g.link = first_child << 5 | (empty ? 16u : 0u) | mask;
    }
  });
}

Bounds3 SDTree::leaf_bounds(const vec3& p) const {
  Lookup at = find_leaf(p);
  return {at.lo, at.lo + at.size};
}

std::vector<Bounds3> SDTree::leaf_boxes() const {
  std::vector<Bounds3> boxes(leaves_.size());
  std::vector<std::pair<uint32_t, Lookup>> stack{{0, Lookup{0, root_.min, root_size_}}};
  while (!stack.empty()) {
    auto [n, at] = stack.back();
    stack.pop_back();
    if (nodes_[n].first_child == 0) {
      boxes[nodes_[n].leaf] = {at.lo, at.lo + at.size};
      continue;
    }
    // The halves find_leaf descends into, computed the same way.
    const int a = nodes_[n].axis;
    at.size[a] *= 0.5f;
    stack.push_back({nodes_[n].first_child, at});
    at.lo[a] += at.size[a];
    stack.push_back({nodes_[n].first_child + 1, at});
  }
  return boxes;
}

void SDTree::deposit(BuildingQuadNode* nodes, vec2 c, double value) const {
  if (!options_.directional_filter) {
    uint32_t n = 0;
    for (;;) {
      int i = descend(c);
      if (nodes[n].child[i] == 0) {
        nodes[n].flux[i] += value;
        return;
      }
      n = nodes[n].child[i];
    }
  }
  // The footprint is the quad holding c, centred on c (seeds/001 10.4).
  double size = 1.0;
  {
    vec2 d = c;
    uint32_t n = 0;
    for (;;) {
      int i = descend(d);
      size *= 0.5;
      if (nodes[n].child[i] == 0) break;
      n = nodes[n].child[i];
    }
  }
  const double density = value / (size * size);
  // phi is periodic, so the box wraps; cos theta is not, so a box reaching
  // past a pole is shifted back inside (Müller drops the part outside, which
  // would darken the quads at the poles).  Either way all of `value` lands.
  double x0 = std::clamp(double(c.x) - 0.5 * size, 0.0, 1.0 - size);
  double y0 = double(c.y) - 0.5 * size, y1 = y0 + size;
  dvec2 zero(0.0);
  if (y0 < 0.0) {
    deposit_box(nodes, 0, zero, 1.0, {x0, y0 + 1.0}, {x0 + size, 1.0}, density);
    deposit_box(nodes, 0, zero, 1.0, {x0, 0.0}, {x0 + size, y1}, density);
  } else if (y1 > 1.0) {
    deposit_box(nodes, 0, zero, 1.0, {x0, y0}, {x0 + size, 1.0}, density);
    deposit_box(nodes, 0, zero, 1.0, {x0, 0.0}, {x0 + size, y1 - 1.0}, density);
  } else {
    deposit_box(nodes, 0, zero, 1.0, {x0, y0}, {x0 + size, y1}, density);
  }
}

uint32_t SDTree::target_leaf(const vec3& p, const vec3& wi, float radiance, float pdf, uint64_t key) const {
  float len = glm::length(wi);
  if (!finite3(p) || !finite3(wi) || !(len > 0.0f) || !std::isfinite(radiance) || !(radiance >= 0.0f) ||
      !(pdf > 0.0f) || !std::isfinite(pdf))
    return kInvalidLeaf;
  const uint32_t leaf = leaf_at(p);
  if (options_.spatial_filter) {
    // Stochastic box filter: jitter p uniformly over a box the size of its
    // leaf, centred on p; a jitter leaving the root box is reflected back in
    // (clamping would pile samples onto the boundary leaves).
    uint64_t h = hash(key);
    vec3 q = p;
    for (int a = 0; a < 3; ++a) {
      q[a] += (hash_unit(h, a) - 0.5f) * leaf_size_[leaf][a];
      if (q[a] < root_.min[a]) q[a] = 2.0f * root_.min[a] - q[a];
      if (q[a] > root_.max[a]) q[a] = 2.0f * root_.max[a] - q[a];
    }
    return leaf_at(q);
  }
  return leaf;
}

// Not inlined: add_sample and add_samples must deposit bit for bit alike,
// and two inlined copies may be contracted (fma) differently.
[[gnu::noinline]] void SDTree::deposit_sample(SpatialLeaf& leaf, const SDTreeSample& s) {
  leaf.sample_count += 1.0;
  double value = double(s.radiance) / double(std::max(s.pdf, options_.pdf_floor));
  if (value > 0.0) deposit(leaf.building.data(), sd_direction_to_square(s.wi / glm::length(s.wi)), value);
  if (options_.learn_selection) learn_selection_step(leaf.learner, s);
}

// Eq. 13 of seeds/001 for the guide's share s of the mixture
// q = s g + (1 - s) p_bsdf: d KL / d s ~ -product / pdf * (g - p_bsdf) / q,
// times ds / dtheta = s (1 - s) (eq. 15), plus the L2 term that keeps theta
// out of the sigmoid's flat tails (eq. 16).  The densities enter as ratios to
// the drawing density, which cancels in (g - p_bsdf) / q.  The product is
// divided by the mean product the leaf has seen (an estimate of its
// integral), so the gradient is the normalised one of eq. 11 and the L2 term
// weighs the same in dim and bright regions (Algorithm 3 leaves that balance
// to the scene's radiance scale).
namespace {

constexpr float kAdamBeta1 = 0.9f, kAdamBeta2 = 0.999f, kAdamLearningRate = 0.01f;

// Adam's bias-corrected step size at step t >= 1, tabulated: two std::pow per
// training sample were a sixth of training's instructions.  Past the table
// 1 - beta^t is 1 in double (0.999^65536 ~ 3e-29), so the step is the plain
// rate, as the formula gives it.
float adam_rate(uint32_t t) {
  constexpr uint32_t kSteps = 1u << 16;
  static const std::vector<float> table = [] {
    std::vector<float> r(kSteps);
    for (uint32_t k = 1; k < kSteps; ++k) {
      const double t = double(k);
      r[k] = kAdamLearningRate * float(std::sqrt(1.0 - std::pow(double(kAdamBeta2), t)) /
                                       (1.0 - std::pow(double(kAdamBeta1), t)));
    }
    return r;
  }();
  return t < kSteps ? table[t] : kAdamLearningRate;
}

}  // namespace

void learn_selection_step(SelectionLearner& l, const SDTreeSample& s) {
  constexpr float kBeta1 = kAdamBeta1, kBeta2 = kAdamBeta2, kEpsilon = 1e-8f, kRegularization = 0.01f;
  if (!(s.bsdf_ratio > 0.0f || s.guide_ratio > 0.0f) || !(s.product_weight >= 0.0f) ||
      !std::isfinite(s.product_weight))
    return;
  const float sel = learned_selection(l);
  const float mixture = sel * s.guide_ratio + (1.0f - sel) * s.bsdf_ratio;
  if (!(mixture > 0.0f)) return;
  l.product_sum += s.product_weight;
  const double mean_product = l.product_sum / double(l.steps + 1);
  const float product = mean_product > 0.0 ? float(s.product_weight / mean_product) : 0.0f;
  const float d_sel = -product * (s.guide_ratio - s.bsdf_ratio) / mixture;
  const float gradient = d_sel * sel * (1.0f - sel) + kRegularization * l.theta;
  if (!std::isfinite(gradient)) return;
  ++l.steps;
  const float rate = adam_rate(l.steps);
  l.m = kBeta1 * l.m + (1.0f - kBeta1) * gradient;
  l.v = kBeta2 * l.v + (1.0f - kBeta2) * gradient * gradient;
  l.theta -= rate * l.m / (std::sqrt(l.v) + kEpsilon);
}

void SDTree::add_sample(const vec3& p, const vec3& wi, float radiance, float pdf, uint64_t key) {
  add_sample(SDTreeSample{p, wi, radiance, pdf, key});
}

void SDTree::add_sample(const SDTreeSample& s) {
  const uint32_t leaf = target_leaf(s.p, s.wi, s.radiance, s.pdf, s.key);
  if (leaf == kInvalidLeaf) {
    ++dropped_;
    return;
  }
  ++recorded_;
  deposit_sample(leaves_[leaf], s);
}

void SDTree::add_samples(std::span<const SDTreeSample> samples) {
  // The leaf of every sample, then the samples of each leaf in index order
  // (a counting sort), then the leaves in parallel.
  const size_t count = samples.size();
  reserve_huge(leaf_of_, count);
  if (leaf_of_.size() < count) leaf_of_.resize(count);
  std::optional<ScopedTimer> timer(std::in_place, times_.classify);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      const SDTreeSample& s = samples[i];
      leaf_of_[i] = target_leaf(s.p, s.wi, s.radiance, s.pdf, s.key);
    }
  });
  timer.emplace(times_.order);
  const size_t leaves = leaves_.size();
  first_.assign(leaves + 1, 0);
  for (size_t i = 0; i < count; ++i)
    if (leaf_of_[i] != kInvalidLeaf) ++first_[leaf_of_[i] + 1];
  busiest_.clear();
  for (uint32_t l = 0; l < leaves; ++l)
    if (first_[l + 1] > 0) busiest_.push_back(l);
  // Longest first, so that the last leaf a thread takes is a short one (the
  // order the leaves are trained in does not change what each learns).
  std::sort(busiest_.begin(), busiest_.end(),
            [&](uint32_t a, uint32_t b) { return first_[a + 1] != first_[b + 1] ? first_[a + 1] > first_[b + 1] : a < b; });
  for (size_t l = 0; l < leaves; ++l) first_[l + 1] += first_[l];
  const uint64_t valid = first_.back();
  recorded_ += valid;
  dropped_ += count - valid;
  reserve_huge(order_, valid);
  if (order_.size() < valid) order_.resize(valid);
  for (size_t i = 0; i < count; ++i)
    if (leaf_of_[i] != kInvalidLeaf) order_[first_[leaf_of_[i]]++] = uint32_t(i);
  // first_[l] is now where leaf l's samples end: shift back to their starts.
  for (size_t l = leaves; l-- > 0;) first_[l + 1] = first_[l];
  first_[0] = 0;
  timer.emplace(times_.deposit);
  std::atomic<size_t> next{0};
  const size_t workers = std::min(busiest_.size(), size_t(tbb::this_task_arena::max_concurrency()));
  tbb::parallel_for(size_t(0), workers, [&](size_t) {
    for (size_t k; (k = next.fetch_add(1, std::memory_order_relaxed)) < busiest_.size();) {
      const uint32_t l = busiest_[k];
      for (uint32_t j = first_[l]; j < first_[l + 1]; ++j) deposit_sample(leaves_[l], samples[order_[j]]);
    }
  });
}

void SDTree::update() {
  std::optional<ScopedTimer> timer(std::in_place, times_.copy);
  // Building (every deposit so far) becomes sampling, as fractions of the
  // leaf's flux.  Leaves are independent here and in the refinement below:
  // in parallel, with the results any order gives.
  tbb::parallel_for(size_t(0), leaves_.size(), [&](size_t l) {
    SpatialLeaf& leaf = leaves_[l];
    sum_flux_bottom_up(leaf.building);
    double total = node_total(leaf.building[0]);
    leaf.has_energy = total > 0.0 && std::isfinite(total);
    // Each deposit estimates the radiance over its quad's solid angle, so
    // their sum over the samples (zero-valued ones counted) estimates the
    // integral over the sphere.
    leaf.radiance_integral =
        leaf.has_energy && leaf.sample_count > 0.0 ? float(std::min(total / leaf.sample_count, 1e30)) : 0.0f;
    if (options_.learn_selection) leaf.selection = learned_selection(leaf.learner);
    leaf.sampling.resize(leaf.building.size());
    for (size_t n = 0; n < leaf.building.size(); ++n)
      for (int i = 0; i < 4; ++i) {
        leaf.sampling[n].child[i] = leaf.building[n].child[i];
        leaf.sampling[n].flux[i] = leaf.has_energy ? float(leaf.building[n].flux[i] / total) : 0.0f;
      }
  });
  timer.emplace(times_.split);
  refine_spatial();
  timer.emplace(times_.refine);
  tbb::parallel_for(size_t(0), leaves_.size(), [&](size_t l) {
    leaves_[l].building = refine_quadtree(leaves_[l].building, options_.flux_threshold, options_.max_quadtree_depth);
  });
  timer.emplace(times_.index);
  index_lookups();
  timer.reset();
  last_recorded_ = recorded_;
  last_dropped_ = dropped_;
  recorded_ = dropped_ = 0;
  ++updates_;
}

// Splits every leaf whose accumulated count exceeds the threshold; the halves
// inherit its quadtrees and statistics times the split decay, and split
// again while still above the threshold (Müller 2017 STree::refine, on
// counts accumulated over iterations).
void SDTree::refine_spatial() {
  const double decay = options_.split_decay;
  std::vector<uint32_t> stack{0};
  while (!stack.empty()) {
    uint32_t n = stack.back();
    stack.pop_back();
    if (nodes_[n].first_child == 0) {
      uint32_t leaf = nodes_[n].leaf;
      if (!(leaves_[leaf].sample_count > options_.spatial_threshold) || nodes_.size() >= kMaxNodes) continue;
      uint8_t axis = nodes_[n].axis;
      uint8_t next = uint8_t((axis + 1) % 3);
      uint32_t first = uint32_t(nodes_.size());
      SpatialLeaf& parent = leaves_[leaf];
      parent.sample_count *= decay;
      // The sampling tree is a normalised distribution: only the statistics decay.
      for (BuildingQuadNode& q : parent.building)
        for (double& f : q.flux) f *= decay;
      parent.draw_failures = 0;  // the halves count their own
      leaves_.push_back(leaves_[leaf]);
      nodes_.push_back(SpatialNode{0, leaf, next});
      nodes_.push_back(SpatialNode{0, uint32_t(leaves_.size() - 1), next});
      nodes_[n].first_child = first;
      nodes_[n].leaf = 0;
    }
    stack.push_back(nodes_[n].first_child + 1);
    stack.push_back(nodes_[n].first_child);
  }
}

uint32_t SDTree::region(const vec3& p) const {
  if (updates_ == 0 || !finite3(p)) return kNoGuideRegion;
  uint32_t leaf = leaf_at(p);
  return guide_leaves_[leaf].has_energy ? leaf : kNoGuideRegion;
}

float SDTree::selection_probability(uint32_t region) const {
  return region < guide_leaves_.size() ? guide_leaves_[region].selection : options_.selection_probability;
}

void SDTree::count_failed_draw(uint32_t region) const {
  if (region >= leaves_.size()) return;
  std::atomic_ref<uint64_t>(leaves_[region].draw_failures).fetch_add(1, std::memory_order_relaxed);
  std::atomic_ref<uint64_t>(draw_failures_).fetch_add(1, std::memory_order_relaxed);
}

float SDTree::radiance_integral(uint32_t region) const {
  return region < guide_leaves_.size() ? guide_leaves_[region].radiance_integral : 0.0f;
}

namespace {

// The probabilities a node's draw took to reach quadrant i (column, then
// row within it) and so the density's factor, 4 x their product: one
// expression for sample() and pdf(), which then agree bit for bit.
inline double quadrant_factor(const GuideNode& node, int i) {
  const double px = side_share(node.column, i & 1);
  const double py = side_share(node.row[i & 1], i & 2);
  return 4.0 * px * py;
}

// Quadrant i's child among the leaf's nodes, or 0 (a leaf quadrant: no
// node's child is the root).
inline uint32_t quadrant_child(const GuideNode& node, int i) {
  const uint32_t mask = node.link & 15u;
  if (!(mask >> i & 1u)) return 0;
  return (node.link >> 5) + uint32_t(std::popcount(mask & ((1u << i) - 1u)));
}

constexpr uint32_t kGuideNodeEmpty = 16u;

}  // namespace

// Algorithm 2 of seeds/001: each level scales the density by the quadrant's
// factor (4 x its share of the node).  A node whose flux underflowed to 0
// counts as a uniform leaf, in sample() too.
float SDTree::pdf(uint32_t region, const vec3& wi) const {
  if (region >= guide_leaves_.size() || !guide_leaves_[region].has_energy) return 0.0f;
  const GuideNode* nodes = guide_nodes_.data() + guide_leaves_[region].first_node;
  vec2 c = sd_direction_to_square(wi);
  double density = 1.0;
  uint32_t n = 0;
  for (;;) {
    const GuideNode& node = nodes[n];
    if (node.link & kGuideNodeEmpty) break;
    const int i = descend(c);
    density *= quadrant_factor(node, i);
    n = quadrant_child(node, i);
    if (n == 0 || density == 0.0) break;
  }
  return float(density * (1.0 / (4.0 * 3.14159265358979323846)));
}

// The density is accumulated on the way down (the factors pdf() multiplies
// for the same quads), which spares a second descent and the atan2 of the
// map back.  Rounding in sd_square_to_direction can put the direction within
// an ulp of a neighbouring quad, where pdf(wi) would read that quad instead: a
// set of measure zero in the continuous domain, so both are the density.
GuideSample SDTree::sample(uint32_t region, vec2 u) const {
  if (region >= guide_leaves_.size() || !guide_leaves_[region].has_energy) return {};
  const GuideNode* nodes = guide_nodes_.data() + guide_leaves_[region].first_node;
  // u is rescaled at every level (hierarchical warping, McCool and Harwood
  // 1997), in double so that a depth-20 descent keeps bits for the leaf.
  constexpr double kBelowOne = 0x1.fffffffffffffp-1;
  double ux = std::min(double(u.x), kBelowOne), uy = std::min(double(u.y), kBelowOne);
  double ox = 0.0, oy = 0.0, size = 1.0, density = 1.0;
  uint32_t n = 0;
  for (;;) {
    const GuideNode& node = nodes[n];
    if (node.link & kGuideNodeEmpty) break;
    // Column first (x: quadrants 0,2 vs 1,3), then the row within it; a
    // share of 0 or 1 is never crossed (u < 1).
    // Selects, not branches: u's side is a coin flip (same doubles either way).
    double b = first_share(node.column);
    const bool right = ux >= b;
    ux = (right ? ux - b : ux) / side_share(node.column, right);
    int i = int(right);
    b = first_share(node.row[i]);
    const bool upper = uy >= b;
    uy = (upper ? uy - b : uy) / side_share(node.row[i], upper);
    i |= int(upper) << 1;
    ux = std::min(ux, kBelowOne);
    uy = std::min(uy, kBelowOne);
    density *= quadrant_factor(node, i);
    size *= 0.5;
    if (i & 1) ox += size;
    if (i & 2) oy += size;
    n = quadrant_child(node, i);
    if (n == 0 || density == 0.0) break;
  }
  vec2 c(float(ox + ux * size), float(oy + uy * size));
  c = glm::min(c, vec2(kOneMinusEpsilon));
  GuideSample s;
  s.wi = sd_square_to_direction(c);
  s.pdf = float(density * (1.0 / (4.0 * 3.14159265358979323846)));
  return s;
}

SDTreeStats SDTree::stats() const {
  SDTreeStats s;
  s.spatial_leaves = leaves_.size();
  for (const SpatialLeaf& leaf : leaves_) s.quadtree_nodes += leaf.sampling.size() + leaf.building.size();
  s.bytes = memory_bytes();
  s.updates = updates_;
  s.samples_recorded = last_recorded_;
  s.samples_dropped = last_dropped_;
  s.pending_recorded = recorded_;
  s.pending_dropped = dropped_;
  s.draw_failures = draw_failures_;
  return s;
}

size_t SDTree::memory_bytes() const {
  size_t bytes = sizeof(*this) + nodes_.capacity() * sizeof(SpatialNode) + leaves_.capacity() * sizeof(SpatialLeaf);
  for (const SpatialLeaf& leaf : leaves_)
    bytes += leaf.sampling.capacity() * sizeof(SamplingQuadNode) + leaf.building.capacity() * sizeof(BuildingQuadNode);
  bytes += guide_nodes_.capacity() * sizeof(GuideNode) + guide_leaves_.capacity() * sizeof(GuideLeaf);
  bytes += region_nodes_.capacity() * sizeof(RegionNode) + leaf_size_.capacity() * sizeof(vec3) +
           leaf_box_.capacity() * sizeof(LeafBox);
  bytes += (leaf_of_.capacity() + order_.capacity() + first_.capacity() + busiest_.capacity() +
            lookup_grid_.capacity()) *
           sizeof(uint32_t);
  return bytes;
}

}  // namespace theia
