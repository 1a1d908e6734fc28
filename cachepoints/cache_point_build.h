// The cache points' build (seeds/002 section 3.1), shared by the build
// (cache_point_build.cpp) and the sampler (cache_points.cpp) only: the
// points and their KD-tree, each point's near and far lists, and the blur
// neighbours.  Internal to cachepoints/ (it includes nanoflann).
#pragma once

#include "cachepoints/cache_points.h"

#include <nanoflann.hpp>

#include <array>
#include <memory>
#include <vector>

namespace theia {

// At most this many near lights per point: selection keeps their weights on the stack.
constexpr int kMaxNear = 64;

// ---------------------------------------------------------------- KD-tree over points

struct Cloud {
  const std::vector<vec3>* points;
  size_t kdtree_get_point_count() const { return points->size(); }
  float kdtree_get_pt(size_t i, size_t d) const { return (*points)[i][int(d)]; }
  template <class B>
  bool kdtree_get_bbox(B&) const {
    return false;
  }
};
using KDTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Cloud>, Cloud, 3, uint32_t>;

// Points and their tree (the tree points into the vector: neither moves).
struct PointTree {
  std::vector<vec3> points;
  Cloud cloud{&points};
  std::unique_ptr<KDTree> tree;
  explicit PointTree(std::vector<vec3> p) : points(std::move(p)) {
    tree = std::make_unique<KDTree>(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  }
  PointTree(const PointTree&) = delete;
  PointTree& operator=(const PointTree&) = delete;
  // The k nearest (itself included for a point of the tree), nearest first.
  size_t knn(const vec3& p, size_t k, uint32_t* index, float* d2) const {
    return tree->knnSearch(&p.x, std::min(k, points.size()), index, d2);
  }
  uint32_t nearest(const vec3& p) const {
    uint32_t i = 0;
    float d2;
    knn(p, 1, &i, &d2);
    return i;
  }
};

struct FarEntry {
  uint32_t emitter;
  SensorValues value;
};

struct PointLists {
  std::vector<uint32_t> near;  // sorted by emitter
  std::vector<FarEntry> far;   // sorted by emitter
};

struct Neighbours {
  std::vector<uint32_t> index;  // the blur neighbours of each point (itself first)
  std::vector<float> weight;    // normalised, eq. 4
  std::vector<uint32_t> begin;  // per point, into index/weight; size points + 1
};

// The four sums sampling weighs (the bins of both sides of an axis, three axes, and the fluence).
inline std::array<float, 4> groups(const SensorValues& v) {
  return {v[0] + v[1], v[2] + v[3], v[4] + v[5], v[kFluenceBin]};
}

// What the build hands the sampler, and its counts for the log.
struct CachePointTables {
  std::unique_ptr<PointTree> tree;  // null: fewer than min_points points (the locally optimal fallback)
  std::vector<PointLists> lists;    // per point, far values blurred
  Neighbours neighbours;
  size_t object_count = 0, pilot_count = 0, merged_points = 0, cull_evaluated = 0;
};

// Candidates, merge, per-point lists (culled by the light tree), blur:
// deterministic, parallel (TBB).
CachePointTables build_cache_points(const LightSet& lights, const EmitterSet& set, const Accel& accel,
                                    const CachePointParams& prm);

}  // namespace theia
