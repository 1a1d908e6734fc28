#include "cachepoints/cache_point_build.h"

#include "cachepoints/light_bvh.h"

#include "core/hash.h"
#include "core/sampling.h"
#include "scene/camera.h"
#include "scene/shapes.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <numeric>

namespace theia {

namespace {

// The cull evaluates a light-tree node of at most this many emitters whole
// (one loop over consecutive arrays) rather than open it: opening a node costs
// cache misses, evaluating is a branch-free loop.  (many-lights-city at --spp
// 1, cull 3e-4: 11.2 CPU s with buckets of 8, 10.3 with 32, 14.2 opening
// every node at 1e-4; cull 1e-3 with 16: 6.6.)
constexpr size_t kCullBucket = 16;

float rnd(uint32_t seed, uint64_t i, uint32_t dim) { return to_unit_float(uint32_t(hash(seed, i, dim))); }

// ---------------------------------------------------------------- candidates

// Uniform in the (slightly padded) bounds of every non-emissive top-level
// mesh, by volume: where shading can happen away from the camera's paths.
std::vector<vec3> object_candidates(const Scene& scene, const CachePointParams& prm, float pad) {
  std::vector<Bounds3> boxes;
  std::vector<float> volume;
  for (int index : scene.top_level_shapes) {
    const Shape& s = scene.shapes[size_t(index)];
    if (s.area_light >= 0 || s.kind != ShapeKind::TriangleMesh) continue;
    const TriangleMesh& m = scene.meshes[size_t(s.mesh)];
    if (m.p.empty()) continue;
    Bounds3 b(m.p[0]);
    for (const vec3& p : m.p) b = Bounds3(glm::min(b.min, p), glm::max(b.max, p));
    b = Bounds3(b.min - vec3(pad), b.max + vec3(pad));
    const vec3 d = b.diagonal();
    boxes.push_back(b);
    volume.push_back(d.x * d.y * d.z);
  }
  std::vector<vec3> out;
  if (boxes.empty()) return out;
  Distribution1D choose(volume);
  for (int i = 0; i < prm.object_candidates; ++i) {
    const Bounds3& b = boxes[size_t(choose.sample_discrete(rnd(prm.seed, uint64_t(i), 0)))];
    vec3 t(rnd(prm.seed, uint64_t(i), 1), rnd(prm.seed, uint64_t(i), 2), rnd(prm.seed, uint64_t(i), 3));
    out.push_back(b.min + t * (b.max - b.min));
  }
  return out;
}

// The non-emissive vertices of short diffuse paths from the camera, one per
// cell of a grid over the film, a stride-selected subset above the cap.
std::vector<vec3> pilot_candidates(const Scene& scene, const Accel& accel, const CachePointParams& prm) {
  const Camera camera = make_camera(scene.camera, scene.film);
  const int cells = prm.pilot_width * prm.pilot_height;
  std::vector<std::vector<vec3>> per_path(size_t(std::max(cells, 0)));
  tbb::parallel_for(0, cells, [&](int i) {
    const uint32_t seed = prm.seed + 1;
    vec2 film((float(i % prm.pilot_width) + rnd(seed, uint64_t(i), 0)) / float(prm.pilot_width) * float(scene.film.width),
              (float(i / prm.pilot_width) + rnd(seed, uint64_t(i), 1)) / float(prm.pilot_height) *
                  float(scene.film.height));
    Ray ray = generate_camera_ray(camera, film, vec2(rnd(seed, uint64_t(i), 2), rnd(seed, uint64_t(i), 3)));
    for (int depth = 0; depth < prm.pilot_depth; ++depth) {
      const Hit hit = accel.intersect1(ray);
      if (!hit.hit()) break;
      const SurfaceInteraction si = compute_interaction(scene, accel, ray, hit);
      if (si.area_light < 0) per_path[size_t(i)].push_back(si.p);
      const vec3 n = glm::dot(si.ng, si.wo) < 0.0f ? -si.ng : si.ng;
      const uint32_t dim = 4 + 2 * uint32_t(depth);
      const vec3 d = Frame::from_z(n).from_local(
          sample_cosine_hemisphere(vec2(rnd(seed, uint64_t(i), dim), rnd(seed, uint64_t(i), dim + 1))));
      ray = spawn_ray(si, d);
    }
  });
  std::vector<vec3> all;
  for (const auto& v : per_path) all.insert(all.end(), v.begin(), v.end());
  if (all.size() <= size_t(prm.max_pilot_candidates)) return all;
  std::vector<vec3> out(size_t(prm.max_pilot_candidates));
  for (size_t k = 0; k < out.size(); ++k) out[k] = all[k * all.size() / out.size()];
  return out;
}

// Section 3.1.2: of points within `radius` of each other (among 20
// neighbours) only the lowest index survives.
std::vector<vec3> merge_duplicates(std::vector<vec3> candidates, float radius) {
  if (candidates.empty()) return candidates;
  PointTree tree(std::move(candidates));
  const size_t n = tree.points.size();
  std::vector<uint8_t> drop(n, 0);
  tbb::parallel_for(size_t(0), n, [&](size_t i) {
    uint32_t index[20];
    float d2[20];
    size_t found = tree.knn(tree.points[i], 20, index, d2);
    for (size_t k = 0; k < found; ++k)
      if (index[k] < i && d2[k] <= radius * radius) drop[i] = 1;
  });
  std::vector<vec3> out;
  for (size_t i = 0; i < n; ++i)
    if (!drop[i]) out.push_back(tree.points[i]);
  return out;
}

// ---------------------------------------------------------------- distributions

// The emitters as arrays, index-aligned with the EmitterSet, for the loop
// over all of them at every point (the build's cost): an area emitter's
// estimate is emitter_sensors' arithmetic, operation for operation, in one
// branch-free loop without calls; the others (point-like, infinite, distant:
// few) go through emitter_sensors itself.
struct EmitterArrays {
  std::vector<float> cx, cy, cz, nx, ny, nz, radius, power;  // power: radiance x area
  std::vector<uint32_t> one_sided, planar;                   // area emitters; planar: a nonzero normal
  std::vector<uint32_t> other;                               // the emitters that are not Area

  std::vector<uint32_t> order;                               // per position, its emitter

  explicit EmitterArrays(const EmitterSet& set) : EmitterArrays(set, identity(set.size())) {}
  // The emitters `order` names, in that order.
  EmitterArrays(const EmitterSet& set, std::vector<uint32_t> emitters) : order(std::move(emitters)) {
    const size_t n = order.size();
    for (auto* v : {&cx, &cy, &cz, &nx, &ny, &nz, &radius, &power}) v->resize(n);
    one_sided.resize(n);
    planar.resize(n);
    for (size_t i = 0; i < n; ++i) {
      const Emitter& e = set.emitters[order[i]];
      if (e.kind != EmitterKind::Area) other.push_back(uint32_t(i));
      cx[i] = e.center.x, cy[i] = e.center.y, cz[i] = e.center.z;
      nx[i] = e.normal.x, ny[i] = e.normal.y, nz[i] = e.normal.z;
      radius[i] = e.radius;
      power[i] = e.radiance * e.area;
      one_sided[i] = e.kind == EmitterKind::Area && !e.two_sided;
      planar[i] = glm::dot(e.normal, e.normal) > 0.0f;
    }
  }
  static std::vector<uint32_t> identity(size_t n) {
    std::vector<uint32_t> v(n);
    std::iota(v.begin(), v.end(), 0u);
    return v;
  }
};

// An emitter evaluated at a point: its sensor values and distance squared.
struct Evaluated {
  uint32_t emitter;
  float d2;
  SensorValues value;
};

// A light-tree node waiting in the cull's queue: its power over its
// smallest distance squared (infinite: it may hold a near emitter).
struct Pending {
  float key;
  uint32_t node;
};

// One build thread's buffers, sized once and reused from point to point.
// The candidates at the current point are `count` emitters: `emitter[j]`
// with its values `value[b][j]` and distance squared `d2[j]` (infinite: never
// near); all emitters in their order, or the cull's in the order it found
// them (a fixed order: ties in the selection go to the earlier).
struct BuildScratch {
  size_t count = 0;
  std::vector<uint32_t> emitter;
  std::array<std::vector<float>, kSensorBins> value;
  std::vector<float> d2;
  std::vector<std::pair<float, uint32_t>> near, top;
  std::vector<uint32_t> chosen;
  std::vector<Pending> queue;        // the cull's, a heap
  std::vector<float> nearest;        // nearest_bound2's, a heap of the closest distances squared
  std::array<double, kSensorBins> rest{};  // the cull's estimate of what it left out
  std::vector<FarEntry> merged;      // the blur
  std::vector<int32_t> slot;         // per emitter: its place in `merged`, -1 none, -2 a near light
  std::vector<uint8_t> mark;         // select_far's: per candidate, chosen by some bin; zero between calls

  explicit BuildScratch(size_t emitters) : emitter(emitters), d2(emitters), slot(emitters, -1), mark(emitters, 0) {
    for (auto& v : value) v.resize(emitters);
  }
};

// cos(max(theta - alpha, 0)) as emitters.cpp's cos_bound, without a branch.
inline float cos_bound_select(float c, float sin_a, float cos_a) {
  const float bound = std::max(0.0f, c * cos_a + std::sqrt(std::max(0.0f, 1.0f - c * c)) * sin_a);
  return c >= cos_a ? 1.0f : bound;
}

// The area emitters' part of evaluate_emitters, a loop without branches over
// restrict-qualified arrays.  (It vectorises with -fno-math-errno
// -fno-trapping-math, but then fuses multiply-adds unlike emitter_sensors.)
void evaluate_area(size_t n, float px, float py, float pz, const float* __restrict cx, const float* __restrict cy,
                   const float* __restrict cz, const float* __restrict nx, const float* __restrict ny,
                   const float* __restrict nz, const float* __restrict radius, const float* __restrict power,
                   const uint32_t* __restrict one_sided, const uint32_t* __restrict planar, float* __restrict o0,
                   float* __restrict o1, float* __restrict o2, float* __restrict o3, float* __restrict o4,
                   float* __restrict o5, float* __restrict o6, float* __restrict out_d2) {
  constexpr float kNever = std::numeric_limits<float>::infinity();
  // Everything computed, then selected.
  for (size_t i = 0; i < n; ++i) {
    const float dx = cx[i] - px, dy = cy[i] - py, dz = cz[i] - pz;
    const vec3 d(dx, dy, dz), normal(nx[i], ny[i], nz[i]);
    const float d2 = glm::dot(d, d);  // glm's, as emitters.cpp: the same fused multiply-adds
    const float r = radius[i];
    const float facing = glm::dot(normal, d);
    const bool behind = (one_sided[i] != 0) & (facing > r);
    const float dist = std::sqrt(d2);
    const float qx = dx / dist, qy = dy / dist, qz = dz / dist;
    const bool apart = dist > 0.0f;
    const float wx = apart ? qx : 0.0f, wy = apart ? qy : 0.0f, wz = apart ? qz : 1.0f;
    const float ratio = r / dist;
    const float sin_a = dist > r ? ratio : 1.0f;
    const float cos_a = std::sqrt(std::max(0.0f, 1.0f - sin_a * sin_a));
    const float c = glm::dot(normal, -vec3(wx, wy, wz));
    const float toward = cos_bound_select(one_sided[i] ? c : std::abs(c), sin_a, cos_a);
    const float cos_e = planar[i] ? toward : 1.0f;
    const float value = power[i] * cos_e / std::max(d2, r * r);
    const bool keep = !behind & (value > 0.0f);
    o0[i] = keep ? value * cos_bound_select(wx, sin_a, cos_a) : 0.0f;
    o1[i] = keep ? value * cos_bound_select(-wx, sin_a, cos_a) : 0.0f;
    o2[i] = keep ? value * cos_bound_select(wy, sin_a, cos_a) : 0.0f;
    o3[i] = keep ? value * cos_bound_select(-wy, sin_a, cos_a) : 0.0f;
    o4[i] = keep ? value * cos_bound_select(wz, sin_a, cos_a) : 0.0f;
    o5[i] = keep ? value * cos_bound_select(-wz, sin_a, cos_a) : 0.0f;
    o6[i] = keep ? value : 0.0f;
    out_d2[i] = behind ? kNever : d2;
  }
}

// An emitter that is not an area emitter (point-like, infinite, distant) at p:
// emitter_sensors, zero where its fluence is not positive; its distance
// squared (infinite for the infinite and distant ones).
Evaluated evaluate_other(const LightSet& lights, const EmitterSet& set, uint32_t i, const vec3& p) {
  const Emitter& em = set.emitters[i];
  const vec3 d = em.center - p;
  const bool behind = em.kind == EmitterKind::Area && !em.two_sided && glm::dot(em.normal, d) > em.radius;
  const SensorValues v = behind ? SensorValues{} : emitter_sensors(lights, em, p);
  const bool keep = v[kFluenceBin] > 0.0f;
  Evaluated out{i, std::numeric_limits<float>::infinity(), {}};
  for (int b = 0; b < kSensorBins; ++b) out.value[size_t(b)] = keep ? v[size_t(b)] : 0.0f;
  const bool finite = em.kind == EmitterKind::Area || em.kind == EmitterKind::PointLike;
  if (finite && !behind) out.d2 = glm::dot(d, d);
  return out;
}

// Positions [first, first + count) of `a` at p by evaluate_area, appended to s's candidates.
void evaluate_range(const EmitterArrays& a, size_t first, size_t count, const vec3& p, BuildScratch& s) {
  const size_t at = s.count;
  evaluate_area(count, p.x, p.y, p.z, &a.cx[first], &a.cy[first], &a.cz[first], &a.nx[first], &a.ny[first],
                &a.nz[first], &a.radius[first], &a.power[first], &a.one_sided[first], &a.planar[first],
                &s.value[0][at], &s.value[1][at], &s.value[2][at], &s.value[3][at], &s.value[4][at], &s.value[5][at],
                &s.value[6][at], &s.d2[at]);
  std::copy_n(a.order.begin() + std::ptrdiff_t(first), count, s.emitter.begin() + std::ptrdiff_t(at));
  s.count += count;
}

// An evaluated emitter appended to s's candidates.
void append(const Evaluated& e, BuildScratch& s) {
  s.emitter[s.count] = e.emitter;
  s.d2[s.count] = e.d2;
  for (int b = 0; b < kSensorBins; ++b) s.value[size_t(b)][s.count] = e.value[size_t(b)];
  ++s.count;
}

// Every emitter's seven sensor values at p (emitter_sensors), zero where its
// fluence is not positive or p is behind its one-sided face by more than its
// radius; and its distance squared for the near test.  The candidates are
// all emitters, in their order.
void evaluate_emitters(const LightSet& lights, const EmitterSet& set, const EmitterArrays& a, const vec3& p,
                       BuildScratch& s) {
  s.count = 0;
  evaluate_range(a, 0, set.size(), p, s);
  for (uint32_t i : a.other) {
    const Evaluated e = evaluate_other(lights, set, i, p);
    for (int b = 0; b < kSensorBins; ++b) s.value[size_t(b)][i] = e.value[size_t(b)];
    s.d2[i] = e.d2;
  }
}

// ---------------------------------------------------------------- the cull

// A node of the light tree (light_bvh.h) with what bounds its area emitters'
// sensor values anywhere: the box of their centres, their radii, their summed
// power (radiance x area) and the tree's cone of their normals.  The other
// emitters are few and always evaluated; a node without power is skipped.
struct CullNode {
  vec3 lo{std::numeric_limits<float>::max()}, hi{-std::numeric_limits<float>::max()};
  float rmin = std::numeric_limits<float>::max(), rmax = 0.0f;
  float power = 0.0f, max_power = 0.0f;
  vec3 axis{0.0f, 0.0f, 1.0f};
  float cos_o = -1.0f, sin_o = 0.0f;
  bool two_sided = true;
  int child = -1;
  uint32_t first = 0, count = 0;  // its area emitters' positions in the tree's arrays
};

// The light tree with its area emitters as arrays in leaf order: a node's
// are positions [first, first + count) of `arrays`.
struct CullTree {
  std::vector<CullNode> nodes;
  EmitterArrays arrays;
};

// The distance squared from p to the box of a node's centres.
float box_distance2(const CullNode& n, const vec3& p) {
  const vec3 q = glm::clamp(p, n.lo, n.hi);
  return glm::dot(p - q, p - q);
}

// The cull's and the nearest search's queues: heaps of nodes, `first` on top.
template <class First>
void queue_push(std::vector<Pending>& queue, Pending item, First first) {
  queue.push_back(item);
  std::push_heap(queue.begin(), queue.end(), [&](const Pending& x, const Pending& y) { return first(y, x); });
}
template <class First>
Pending queue_pop(std::vector<Pending>& queue, First first) {
  std::pop_heap(queue.begin(), queue.end(), [&](const Pending& x, const Pending& y) { return first(y, x); });
  const Pending item = queue.back();
  queue.pop_back();
  return item;
}

CullTree cull_tree(const LightSet& lights, const EmitterSet& set, const EmitterArrays& a) {
  const std::vector<LightBvhNode> tree = build_light_tree(lights, set);
  std::vector<CullNode> nodes(tree.size());
  std::vector<uint32_t> order;
  auto visit = [&](auto&& self, size_t i) -> void {
    const LightBvhNode& t = tree[i];
    CullNode& n = nodes[i];
    n.axis = t.bounds.axis;
    n.cos_o = t.bounds.cos_o;
    n.sin_o = t.bounds.sin_o;
    n.two_sided = t.bounds.two_sided;
    n.child = t.child;
    n.first = uint32_t(order.size());
    if (t.child < 0) {
      const size_t e = size_t(t.emitter);
      if (set.emitters[e].kind == EmitterKind::Area) {
        order.push_back(uint32_t(e));
        n.lo = n.hi = set.emitters[e].center;
        n.rmin = n.rmax = a.radius[e];
        n.power = n.max_power = a.power[e];
      }
    } else {
      for (int c : {t.child, t.child + 1}) {
        self(self, size_t(c));
        const CullNode& k = nodes[size_t(c)];
        if (!(k.power > 0.0f)) continue;
        n.lo = glm::min(n.lo, k.lo);
        n.hi = glm::max(n.hi, k.hi);
        n.rmin = std::min(n.rmin, k.rmin);
        n.rmax = std::max(n.rmax, k.rmax);
        n.power += k.power;
        n.max_power = std::max(n.max_power, k.max_power);
      }
    }
    n.count = uint32_t(order.size()) - n.first;
  };
  if (!tree.empty()) visit(visit, 0);
  return {std::move(nodes), EmitterArrays(set, std::move(order))};
}

// Per unit power over distance squared, upper bounds at p of the sensor
// values of the node's emitters (what evaluate_area gives them, in exact
// arithmetic, with a margin for its rounding): the largest emission cosine
// towards p, the normal cone widened by the angle that the sphere around all
// their balls subtends (as the light BVH's importance), times per plane the
// largest cosine between its normal and a direction into the box around the
// balls.
SensorValues cull_factors(const CullNode& n, const vec3& p) {
  float emit = 1.001f;
  const vec3 to_p = p - 0.5f * (n.lo + n.hi);
  const float d2 = glm::dot(to_p, to_p);
  const float r = 0.5f * glm::length(n.hi - n.lo) + n.rmax;
  if (n.cos_o > -1.0f && d2 > r * r) {
    const float d = std::sqrt(d2);
    float cos_w = glm::dot(n.axis, to_p) / d;
    if (n.two_sided) cos_w = std::abs(cos_w);
    const float sin_w = safe_sqrt(1.0f - cos_w * cos_w);
    const float cos_x = cos_sub_clamped(sin_w, cos_w, n.sin_o, n.cos_o);
    const float sin_x = sin_sub_clamped(sin_w, cos_w, n.sin_o, n.cos_o);
    const float sin_s = r / d;
    const float cos_p = cos_sub_clamped(sin_x, cos_x, sin_s, safe_sqrt(1.0f - sin_s * sin_s));
    emit *= std::clamp(cos_p + 1e-3f, 0.0f, 1.0f);
  }
  const vec3 lo = n.lo - vec3(n.rmax), hi = n.hi + vec3(n.rmax);
  const vec3 out = glm::max(lo - p, vec3(0.0f)) + glm::max(p - hi, vec3(0.0f));  // per axis, outside the box
  SensorValues v{};
  for (int axis = 0; axis < 3; ++axis) {
    const float m2 = glm::dot(out, out) - out[axis] * out[axis];
    const float up = hi[axis] - p[axis], down = p[axis] - lo[axis];
    v[size_t(2 * axis)] = up > 0.0f ? emit * up / std::sqrt(up * up + m2) : 0.0f;
    v[size_t(2 * axis + 1)] = down > 0.0f ? emit * down / std::sqrt(down * down + m2) : 0.0f;
  }
  v[kFluenceBin] = emit;
  return v;
}

// The squared radius, at most near_radius2, that holds the max_near emitters
// nearest p (build_lists' near ones): a best-first search of the light tree
// by the distance to its nodes' boxes of centres, over the nodes the cull
// visits (those with power, down to its buckets), among the candidates
// already in `s` (the emitters outside the tree).  The distance as
// evaluate_area computes it, one-sided emitters p is behind excluded, as
// there.  The cull then evaluates whole only the nodes that may lie within
// this radius (its 1.001 margin covers rounding between the two
// computations), not every node within the near radius: where points are
// sparse among dense emitters that radius holds nearly all of them.
float nearest_bound2(const CullTree& tree, const vec3& p, float near_radius2, int max_near, BuildScratch& s) {
  const size_t k = size_t(std::clamp(max_near, 0, kMaxNear));
  if (k == 0) return -1.0f;
  std::vector<float>& best = s.nearest;  // a max-heap of the k smallest distances squared
  best.clear();
  auto offer = [&](float d2) {
    if (!(d2 <= near_radius2)) return;
    if (best.size() < k) {
      best.push_back(d2);
      std::push_heap(best.begin(), best.end());
    } else if (d2 < best.front()) {
      std::pop_heap(best.begin(), best.end());
      best.back() = d2;
      std::push_heap(best.begin(), best.end());
    }
  };
  auto bound = [&] { return best.size() < k ? near_radius2 : best.front(); };
  for (size_t j = 0; j < s.count; ++j) offer(s.d2[j]);
  const EmitterArrays& a = tree.arrays;
  auto nearer = [](const Pending& x, const Pending& y) { return x.key < y.key; };
  s.queue.clear();
  auto push = [&](int index) {
    const CullNode& n = tree.nodes[size_t(index)];
    const float dmin2 = box_distance2(n, p);
    if (n.power > 0.0f && dmin2 <= 1.001f * bound()) queue_push(s.queue, Pending{dmin2, uint32_t(index)}, nearer);
  };
  if (!tree.nodes.empty()) push(0);
  while (!s.queue.empty()) {
    const Pending item = queue_pop(s.queue, nearer);
    if (item.key > 1.001f * bound()) break;  // the rest are farther still
    const CullNode& n = tree.nodes[item.node];
    if (n.count > kCullBucket) {
      push(n.child);
      push(n.child + 1);
      continue;
    }
    for (size_t i = n.first; i < n.first + n.count; ++i) {
      const vec3 d(a.cx[i] - p.x, a.cy[i] - p.y, a.cz[i] - p.z);
      const bool behind = a.one_sided[i] != 0 && glm::dot(vec3(a.nx[i], a.ny[i], a.nz[i]), d) > a.radius[i];
      if (!behind) offer(glm::dot(d, d));
    }
  }
  return bound();
}

// The candidates at p without evaluating every emitter (lightcuts-like):
// those outside the tree; every one whose centre may lie within the radius
// of the max_near nearest (nearest_bound2); and the tree's leaves under the
// nodes that the single brightest emitter they could hold (their largest
// power at their nearest centre) puts above `cull` of what the candidates
// found so far hold, in any of the four groups sampling weighs, or whose
// summed bound is above a tenth of the share the 97% rule leaves out (many
// dim emitters close by: left out, their estimate would swell the totals and
// so the lists; street of 1,025 emitters: 3.3% of the full build's entries
// differ without this, 0.8% with it).  The largest (summed) bounds are
// expanded first, so that the totals grow before small nodes are judged;
// what is found only grows, so a node left out would be left out later too.
// Every near emitter is evaluated; what is left out delivers under `cull` of
// its group's total each, so the lists lose only tail entries
// (many-lights-city: 567 far entries per point against the full build's 622,
// 2,922 of 40,001 emitters evaluated per point).  The nodes left out add
// their estimate (the bound at their centre's distance) to `s.rest`, the
// totals the 97% rule compares against.
void evaluate_culled(const LightSet& lights, const EmitterSet& set, const EmitterArrays& a, const CullTree& tree,
                     const vec3& p, float near_radius2, const CachePointParams& prm, BuildScratch& s) {
  s.count = 0;
  s.rest.fill(0.0);
  std::array<double, 4> found{};
  for (uint32_t i : a.other) append(evaluate_other(lights, set, a.order[i], p), s);
  near_radius2 = nearest_bound2(tree, p, near_radius2, prm.max_near, s);
  const double cull = double(prm.cull), tail = 0.1 * (1.0 - double(prm.far_energy));
  auto count_found = [&](size_t from) {
    for (size_t j = from; j < s.count; ++j) {
      if (s.d2[j] <= near_radius2) continue;
      found[0] += double(s.value[0][j] + s.value[1][j]);
      found[1] += double(s.value[2][j] + s.value[3][j]);
      found[2] += double(s.value[4][j] + s.value[5][j]);
      found[3] += double(s.value[kFluenceBin][j]);
    }
  };
  count_found(0);
  auto larger = [](const Pending& x, const Pending& y) { return x.key > y.key; };
  s.queue.clear();
  auto push = [&](int index) {
    const CullNode& n = tree.nodes[size_t(index)];
    if (!(n.power > 0.0f)) return;
    const float dmin2 = box_distance2(n, p);
    const bool near = dmin2 <= 1.001f * near_radius2;
    const float key = n.power / std::max({dmin2, n.rmin * n.rmin, 1e-30f});
    queue_push(s.queue, Pending{near ? std::numeric_limits<float>::infinity() : key, uint32_t(index)}, larger);
  };
  if (!tree.nodes.empty()) push(0);
  while (!s.queue.empty()) {
    const Pending item = queue_pop(s.queue, larger);
    const CullNode& n = tree.nodes[item.node];
    if (item.key != std::numeric_limits<float>::infinity()) {
      const SensorValues f = cull_factors(n, p);
      const std::array<float, 4> g = groups(f);
      const float single = item.key * n.max_power / n.power;
      bool significant = false;
      for (size_t k = 0; k < 4; ++k)
        significant |= double(single * g[k]) > cull * found[k] || double(item.key * g[k]) > tail * found[k];
      if (!significant) {
        const vec3 to_centre = p - 0.5f * (n.lo + n.hi);
        const float estimate = n.power / std::max({glm::dot(to_centre, to_centre), n.rmin * n.rmin, 1e-30f});
        for (int b = 0; b < kSensorBins; ++b) s.rest[size_t(b)] += double(estimate * f[size_t(b)]);
        continue;
      }
    }
    if (n.count <= kCullBucket) {
      const size_t from = s.count;
      evaluate_range(tree.arrays, n.first, n.count, p, s);
      count_found(from);
      continue;
    }
    push(n.child);
    push(n.child + 1);
  }
}

// Per bin, the largest values (ties: the lower index first) that carry
// `far_energy` of the bin's total (plus `rest`, what is not among them),
// min_far..max_far of them: a heap of the max_far largest, then the energy
// walk.  `s.chosen` gets the union over the bins, sorted.  value(b, i) for
// i < n; only positive values count.
template <class Value>
void select_far(size_t n, Value&& value, const std::array<double, kSensorBins>& rest, const CachePointParams& prm,
                BuildScratch& s) {
  using Ranked = std::pair<float, uint32_t>;
  // Largest first, ties by index: a strict order, so the selection is deterministic.
  auto larger = [](const Ranked& a, const Ranked& c) { return a.first > c.first || (a.first == c.first && a.second < c.second); };
  const size_t cap = size_t(std::max(prm.max_far, 0));
  for (int b = 0; b < kSensorBins && cap > 0; ++b) {
    // The bin's total, summed in index order in the same pass, is what the energy walk compares against.
    double total = rest[size_t(b)];
    s.top.clear();  // a heap whose front is the smallest kept
    for (size_t i = 0; i < n; ++i) {
      const float v = value(b, i);
      if (!(v > 0.0f)) continue;
      total += double(v);
      if (s.top.size() < cap) {
        s.top.emplace_back(v, uint32_t(i));
        std::push_heap(s.top.begin(), s.top.end(), larger);
      } else if (v > s.top.front().first) {  // a later index wins only by a larger value
        std::pop_heap(s.top.begin(), s.top.end(), larger);
        s.top.back() = {v, uint32_t(i)};
        std::push_heap(s.top.begin(), s.top.end(), larger);
      }
    }
    std::sort(s.top.begin(), s.top.end(), larger);
    double sum = 0.0;
    for (size_t k = 0; k < s.top.size(); ++k) {
      if (k >= size_t(prm.min_far) && sum >= double(prm.far_energy) * total) break;
      s.mark[s.top[k].second] = 1;
      sum += double(s.top[k].first);
    }
  }
  // The union in index order by one pass over the marks: the bins' choices
  // overlap, and sorting their concatenation cost more than the pass.
  s.chosen.clear();
  for (size_t i = 0; i < n; ++i)
    if (s.mark[i]) {
      s.chosen.push_back(uint32_t(i));
      s.mark[i] = 0;
    }
}

// Section 3.1.3 at one point: the closest lights within near_radius are near
// (at most max_near), every other one is estimated at the point's seven
// sensors: all emitters, or (cull > 0) those the light tree cannot rule out.
PointLists build_lists(const LightSet& lights, const EmitterSet& set, const EmitterArrays& arrays,
                       const CullTree& tree, const vec3& p, float near_radius,
                       const CachePointParams& prm, BuildScratch& s) {
  const float r2 = near_radius * near_radius;
  if (prm.cull > 0.0f)
    evaluate_culled(lights, set, arrays, tree, p, r2, prm, s);
  else
    evaluate_emitters(lights, set, arrays, p, s);
  s.near.clear();
  for (size_t j = 0; j < s.count; ++j)
    if (s.d2[j] <= r2) s.near.emplace_back(s.d2[j], uint32_t(j));
  const size_t near_count = std::min(s.near.size(), size_t(std::clamp(prm.max_near, 0, kMaxNear)));
  if (near_count < s.near.size())
    std::nth_element(s.near.begin(), s.near.begin() + ptrdiff_t(near_count), s.near.end());
  PointLists lists;
  lists.near.reserve(near_count);
  for (size_t k = 0; k < near_count; ++k) {
    const uint32_t j = s.near[k].second;
    lists.near.push_back(s.emitter[j]);
    for (auto& v : s.value) v[j] = 0.0f;  // near: evaluated at the vertex, not a far candidate
  }
  std::sort(lists.near.begin(), lists.near.end());
  if (!(prm.cull > 0.0f)) s.rest.fill(0.0);
  select_far(s.count, [&](int b, size_t j) { return s.value[size_t(b)][j]; }, s.rest, prm, s);
  lists.far.reserve(s.chosen.size());
  for (uint32_t j : s.chosen) {
    FarEntry f{s.emitter[j], {}};
    for (int b = 0; b < kSensorBins; ++b) f.value[size_t(b)] = s.value[size_t(b)][j];
    lists.far.push_back(f);
  }
  std::sort(lists.far.begin(), lists.far.end(), [](const FarEntry& a, const FarEntry& c) { return a.emitter < c.emitter; });
  return lists;
}
// ---------------------------------------------------------------- the second merge

// A point's light distribution for the similarity metric: its near lights'
// fluence at the point and its far fluence values, normalised, by emitter.
std::vector<std::pair<uint32_t, float>> fluence_distribution(const LightSet& lights, const EmitterSet& set,
                                                             const PointLists& l, const vec3& p) {
  std::vector<std::pair<uint32_t, float>> d;
  d.reserve(l.near.size() + l.far.size());
  for (uint32_t e : l.near) d.emplace_back(e, std::max(0.0f, emitter_sensors(lights, set.emitters[e], p)[kFluenceBin]));
  for (const FarEntry& f : l.far) d.emplace_back(f.emitter, f.value[kFluenceBin]);
  std::sort(d.begin(), d.end());
  double total = 0.0;
  for (const auto& x : d) total += double(x.second);
  for (auto& x : d) x.second = total > 0.0 ? float(double(x.second) / total) : 0.0f;
  return d;
}

// Eqs. 2 and 3: twice the intersection's size, each common light weighted by
// 1 - |pA - pB| / (pA + pB), over the two sizes.
float similarity(const std::vector<std::pair<uint32_t, float>>& a, const std::vector<std::pair<uint32_t, float>>& b) {
  if (a.empty() && b.empty()) return 1.0f;
  double common = 0.0;
  for (size_t i = 0, j = 0; i < a.size() && j < b.size();) {
    if (a[i].first < b[j].first) {
      ++i;
    } else if (b[j].first < a[i].first) {
      ++j;
    } else {
      const double pa = a[i].second, pb = b[j].second;
      common += pa + pb > 0.0 ? 1.0 - std::abs(pb - pa) / (pa + pb) : 1.0;
      ++i, ++j;
    }
  }
  return float(2.0 * common / double(a.size() + b.size()));
}

// Section 3.1.4: per point, its 20 nearest neighbours' mean similarity M_avg
// scales their mean distance (to no less than a quarter of it); of the point
// and the neighbours within that radius only the lowest index survives.
// Marks in parallel (every write sets the same value), then a serial sweep:
// the survivors, ascending, a pure function of the points and their lists.
// (The paper's floor of 3 pixels of projected size is not applied: points
// only merge less for it.)
std::vector<uint32_t> similar_survivors(const LightSet& lights, const EmitterSet& set, const PointTree& tree,
                                        const std::vector<PointLists>& lists, int neighbours) {
  const size_t n = tree.points.size();
  std::vector<std::vector<std::pair<uint32_t, float>>> dist(n);
  tbb::parallel_for(size_t(0), n, [&](size_t i) { dist[i] = fluence_distribution(lights, set, lists[i], tree.points[i]); });
  std::vector<std::atomic<uint8_t>> drop(n);
  for (auto& d : drop) d.store(0, std::memory_order_relaxed);
  tbb::parallel_for(size_t(0), n, [&](size_t i) {
    const size_t k = size_t(neighbours) + 1;
    std::vector<uint32_t> index(k);
    std::vector<float> d2(k);
    const size_t found = tree.knn(tree.points[i], k, index.data(), d2.data());
    double m = 0.0, distance = 0.0;
    size_t count = 0;
    for (size_t j = 0; j < found; ++j) {
      if (index[j] == i) continue;
      m += double(similarity(dist[i], dist[index[j]]));
      distance += std::sqrt(double(d2[j]));
      ++count;
    }
    if (count == 0) return;
    const double radius = distance / double(count) * std::max(m / double(count), 0.25);
    uint32_t lowest = uint32_t(i);
    for (size_t j = 0; j < found; ++j)
      if (double(d2[j]) <= radius * radius) lowest = std::min(lowest, index[j]);
    for (size_t j = 0; j < found; ++j)
      if (double(d2[j]) <= radius * radius && index[j] != lowest) drop[index[j]].store(1, std::memory_order_relaxed);
    if (lowest != i) drop[i].store(1, std::memory_order_relaxed);
  });
  std::vector<uint32_t> keep;
  for (size_t i = 0; i < n; ++i)
    if (!drop[i].load(std::memory_order_relaxed)) keep.push_back(uint32_t(i));
  return keep;
}

// Eq. 4: weight 1 for the point and its nearest neighbour, falling to 1/16 at
// the farthest of the 16; normalised to sum to one.
Neighbours blur_neighbours(const PointTree& tree, int count) {
  const size_t n = tree.points.size();
  const size_t k = std::min(size_t(count) + 1, n);
  std::vector<std::vector<std::pair<uint32_t, float>>> per(n);
  tbb::parallel_for(size_t(0), n, [&](size_t i) {
    std::vector<uint32_t> index(k);
    std::vector<float> d2(k);
    size_t found = tree.knn(tree.points[i], k, index.data(), d2.data());
    float far2 = found > 0 ? d2[found - 1] : 0.0f;
    per[i].emplace_back(uint32_t(i), 1.0f);
    for (size_t j = 0; j < found; ++j) {
      if (index[j] == i) continue;
      float t = far2 > 0.0f ? d2[j] / far2 : 0.0f;
      per[i].emplace_back(index[j], 1.0f + (1.0f / 16.0f - 1.0f) * t);
    }
    float sum = 0.0f;
    for (const auto& w : per[i]) sum += w.second;
    for (auto& w : per[i]) w.second /= sum;
  });
  Neighbours nb;
  nb.begin.push_back(0);
  for (const auto& v : per) {
    for (const auto& w : v) {
      nb.index.push_back(w.first);
      nb.weight.push_back(w.second);
    }
    nb.begin.push_back(uint32_t(nb.index.size()));
  }
  return nb;
}

// Section 3.1.5: the far values of a point and its neighbours, weighted and
// summed per emitter in neighbour order; minus the point's near lights; then
// selected again (4..256 per bin, 97%), so that lists stay bounded.  Ties in
// the selection go to the emitter met first (a fixed order); the list comes
// out sorted by emitter.
std::vector<FarEntry> blurred_far(const std::vector<PointLists>& lists, const Neighbours& nb, size_t i,
                                  const CachePointParams& prm, BuildScratch& s) {
  const std::vector<uint32_t>& near = lists[i].near;
  for (uint32_t e : near) s.slot[e] = -2;
  s.merged.clear();
  for (uint32_t k = nb.begin[i]; k < nb.begin[i + 1]; ++k) {
    const float w = nb.weight[k];
    for (const FarEntry& f : lists[nb.index[k]].far) {
      int32_t& at = s.slot[f.emitter];
      if (at == -2) continue;
      if (at < 0) {
        at = int32_t(s.merged.size());
        s.merged.push_back(FarEntry{f.emitter, {}});
      }
      SensorValues& sum = s.merged[size_t(at)].value;
      for (int b = 0; b < kSensorBins; ++b) sum[size_t(b)] += w * f.value[size_t(b)];
    }
  }
  for (const FarEntry& f : s.merged) s.slot[f.emitter] = -1;
  for (uint32_t e : near) s.slot[e] = -1;
  select_far(s.merged.size(), [&](int b, size_t j) { return s.merged[j].value[size_t(b)]; }, {}, prm, s);
  std::vector<FarEntry> out;
  out.reserve(s.chosen.size());
  for (uint32_t j : s.chosen) out.push_back(s.merged[j]);
  std::sort(out.begin(), out.end(), [](const FarEntry& a, const FarEntry& c) { return a.emitter < c.emitter; });
  return out;
}

}  // namespace

CachePointTables build_cache_points(const LightSet& lights, const EmitterSet& set, const Accel& accel,
                                    const CachePointParams& prm) {
  CachePointTables t;
  const Scene& scene = *lights.scene;
  std::vector<vec3> candidates = object_candidates(scene, prm, 1e-3f * lights.scene_radius);
  t.object_count = candidates.size();
  std::vector<vec3> pilot = pilot_candidates(scene, accel, prm);
  t.pilot_count = pilot.size();
  candidates.insert(candidates.end(), pilot.begin(), pilot.end());
  std::vector<vec3> points = merge_duplicates(std::move(candidates), prm.merge_radius * lights.scene_radius);
  t.merged_points = points.size();
  if (points.size() < size_t(prm.min_points)) return t;
  t.tree = std::make_unique<PointTree>(std::move(points));
  const PointTree& tree = *t.tree;
  const size_t n = tree.points.size();
  const EmitterArrays arrays(set);
  const CullTree cull = prm.cull > 0.0f ? cull_tree(lights, set, arrays) : CullTree{{}, EmitterArrays(set, {})};
  tbb::enumerable_thread_specific<BuildScratch> scratch([&] { return BuildScratch(set.size()); });
  std::vector<PointLists>& lists = t.lists;
  lists.resize(n);
  std::vector<uint32_t> evaluated(n);
  tbb::parallel_for(size_t(0), n, [&](size_t i) {
    // A point's radius: the distance to its radius_neighbours-th neighbour.
    const size_t k = size_t(prm.radius_neighbours) + 1;
    std::vector<uint32_t> index(k);
    std::vector<float> d2(k);
    size_t found = tree.knn(tree.points[i], k, index.data(), d2.data());
    float radius = found > 0 ? std::sqrt(d2[found - 1]) : 0.0f;
    BuildScratch& s = scratch.local();
    lists[i] = build_lists(lights, set, arrays, cull, tree.points[i], prm.near_factor * radius, prm, s);
    evaluated[i] = uint32_t(s.count);
  });
  for (uint32_t e : evaluated) t.cull_evaluated += e;
  if (prm.merge_similar) {
    const std::vector<uint32_t> keep = similar_survivors(lights, set, tree, lists, prm.similar_neighbours);
    if (keep.size() < n && keep.size() >= size_t(prm.min_points)) {
      std::vector<vec3> kept_points;
      std::vector<PointLists> kept_lists;
      for (uint32_t i : keep) {
        kept_points.push_back(tree.points[i]);
        kept_lists.push_back(std::move(lists[i]));
      }
      lists = std::move(kept_lists);
      t.tree = std::make_unique<PointTree>(std::move(kept_points));  // `tree` is gone from here on
    }
  }
  const size_t m = t.tree->points.size();
  t.neighbours = blur_neighbours(*t.tree, prm.blur_neighbours);
  std::vector<std::vector<FarEntry>> blurred(m);
  tbb::parallel_for(size_t(0), m, [&](size_t i) { blurred[i] = blurred_far(lists, t.neighbours, i, prm, scratch.local()); });
  scratch.clear();
  for (size_t i = 0; i < m; ++i) lists[i].far = std::move(blurred[i]);
  return t;
}

}  // namespace theia
