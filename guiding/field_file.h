// The saved guiding field (`theia render --save-field FILE`), what `theia
// field view|stats|image` read: the render camera, the scene bounds, a
// decimated triangle list of the scene for a wireframe, and one snapshot per
// saved iteration.  A snapshot holds every spatial leaf's box, its sampling
// quadtree or, with --guiding-field vmm, its mixture (what the renderer
// samples from the next iteration on), a bounded
// reservoir of the training directions recorded in it, and a table of
// per-leaf statistics as named columns of doubles, so that a statistic added
// to the table needs no change in the readers (they list what the file has).
//
// Layout (little-endian, as the host writes it):
//   "THEIAFLD" | u32 version | camera | bounds | wireframe | snapshots | u64 hash_bytes(everything before)
// Version 2 adds each leaf's mixture (lobes, pivot) after its samples; a file
// without mixtures (an SD-tree field) is written as version 1, as before.
// The reader checks length, magic, version, checksum and structure and throws
// theia::Error naming the file and what is wrong.
#pragma once

#include "core/bounds.h"
#include "guiding/sd_tree.h"
#include "guiding/vmm.h"

#include <cstdint>
#include <array>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace theia {

// The render camera as a viewer places its own: eye, unit forward / up /
// right (image x) in world space, the vertical field of view.  `mirrored`:
// right is up x forward (pbrt-v4's left-handed camera space) rather than
// forward x up, so a right-handed viewer mirrors the world to show the image.
struct FieldCamera {
  vec3 eye{0.0f}, forward{0.0f, 0.0f, 1.0f}, up{0.0f, 1.0f, 0.0f}, right{1.0f, 0.0f, 0.0f};
  float fov_y_degrees = 90.0f;  // 0: not a perspective camera (the viewer frames the scene)
  int32_t width = 1, height = 1;
  int32_t mirrored = 0;  // 0 or 1 (no padding: the struct is written as it lies in memory)
};

// Triangles of the scene's meshes (a subset of them when there are many).
struct FieldWireframe {
  std::vector<vec3> p;  // 3 per triangle
  uint64_t scene_triangles = 0;
};

// One recorded training direction and its weight (radiance / max(pdf, floor)).
struct FieldSample {
  vec3 wi{0.0f};
  float value = 0.0f;
};

struct FieldLeaf {
  Bounds3 box;
  std::vector<SamplingQuadNode> quadtree;  // empty: nothing learned (no guiding here) or a mixture field
  std::vector<FieldSample> samples;        // the reservoir (FieldRecorder)
  // A mixture field's region (kVMMLobes lobes; empty: an SD-tree leaf, or a
  // region that learned nothing): the lobes as seen from `pivot`.  A lookup at
  // p re-points them (vmm_at(lobes, pivot, p)); inverse distances are 0 where
  // the render did not use parallax.
  std::vector<VMMLobe> lobes;
  vec3 pivot{0.0f};
};

struct FieldSnapshot {
  int32_t iteration = 0;  // 0-based, the iteration whose end this is
  uint32_t spp = 0;       // samples per pixel rendered so far
  // Field-wide numbers (name, value) and the per-leaf table: columns.size()
  // values per leaf, row-major.
  std::vector<std::pair<std::string, double>> summary;
  std::vector<std::string> columns;
  std::vector<double> table;
  std::vector<FieldLeaf> leaves;

  int column(std::string_view name) const;  // -1 when absent
  double value(size_t leaf, int column) const { return table[leaf * columns.size() + size_t(column)]; }
  // The leaf whose box holds p (the nearest box's when none does).
  size_t leaf_at(const vec3& p) const;
};

struct FieldFile {
  FieldCamera camera;
  Bounds3 scene_bounds, root_bounds;
  FieldWireframe wireframe;
  std::vector<FieldSnapshot> snapshots;
};

std::vector<uint8_t> serialize_field(const FieldFile& field);
// `name` prefixes every message (the file's path).
FieldFile deserialize_field(std::span<const uint8_t> bytes, const std::string& name);
// Written to PATH.tmp and renamed; throws theia::Error.
void save_field(const std::string& path, const FieldFile& field);
FieldFile load_field(const std::string& path);

// The quadtree's density per unit area of Müller's square at c in [0,1)^2
// (the solid-angle pdf times 4 pi); 0 where it learned nothing.
double field_density(std::span<const SamplingQuadNode> nodes, vec2 c);
// The leaf's mixture as the renderer samples it at p (lobes re-pointed from the pivot).
VMMixture field_mixture_at(const FieldLeaf& leaf, const vec3& p);
// What the leaf guides with, as a density per unit area of Müller's square at
// c (the solid-angle pdf x 4 pi), seen from p: the quadtree's (p does not
// matter) or the mixture's at p; 0 where it learned nothing.
double field_leaf_density(const FieldLeaf& leaf, const vec3& p, vec2 c);

// Turns a training run into snapshots.  add() keeps the iteration's samples
// (only those the tree records); snapshot(), called after tree.update(),
// files them under the updated tree's leaves by position and accumulates,
// per leaf, what it has seen since it was made (a leaf from a split starts
// afresh, as Hyperion's visualizer shows a voxel's samples since its last
// split).  Deterministic: samples are taken in the order given, and each
// leaf's reservoir keeps the kReservoir samples of smallest hash(key), a
// choice that does not depend on order.
class FieldRecorder {
 public:
  static constexpr size_t kReservoir = 256;
  using BoxKey = std::array<float, 6>;
  void add(const SDTree& tree, std::span<const SDTreeSample> samples);
  // With `vmm` (the field the render samples, after its update) each leaf
  // carries its region's mixture instead of the quadtree, and the table the
  // mixture's columns (vmm_*).
  FieldSnapshot snapshot(const SDTree& tree, int iteration, uint32_t spp, const VMMField* vmm = nullptr);
  // Everything it has seen, for a checkpoint: a resumed render's field file
  // counts every sample, not only those since the resume.  restore() throws
  // theia::Error (prefixed `what`) for bytes it cannot take.
  std::vector<uint8_t> serialize() const;
  void restore(std::span<const uint8_t> bytes, const std::string& what);

 private:
  struct Reservoir {
    uint64_t priority;
    FieldSample sample;
  };
  struct LeafRecord {
    double samples = 0, nonzero = 0, iteration_samples = 0, iteration_nonzero = 0, radiance = 0;
    double clamped = 0;  // samples whose pdf the training raised to the SD-tree's pdf floor
    Bounds3 seen;  // positions of the samples recorded
    std::vector<Reservoir> reservoir;
  };
  void record(LeafRecord& r, const SDTreeSample& s, float pdf_floor);
  std::vector<SDTreeSample> pending_;
  std::map<BoxKey, LeafRecord> records_;
};

}  // namespace theia
