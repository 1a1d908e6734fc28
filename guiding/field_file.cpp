#include "guiding/field_file.h"

#include "core/atomic_file.h"
#include "core/bytes.h"
#include "core/hash.h"
#include "core/log.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>

namespace theia {

namespace {

constexpr char kMagic[8] = {'T', 'H', 'E', 'I', 'A', 'F', 'L', 'D'};
// 2: each leaf's mixture (lobes, pivot) after its samples.  Written only
// when some leaf has one, so an SD-tree field's file is what it was.
constexpr uint32_t kVersion = 2;

void put_box(ByteWriter& w, const Bounds3& b) { w.put(b.min), w.put(b.max); }

Bounds3 get_box(ByteReader& r, const char* what) {
  Bounds3 b;
  b.min = r.get<vec3>();
  b.max = r.get<vec3>();
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(b.min[a]) || !std::isfinite(b.max[a]) || b.min[a] > b.max[a])
      throw_error("{}: field file corrupt: {} is not a finite box", r.what, what);
  return b;
}

// A count of records of at least `record_bytes` each, refused when the rest cannot hold them.
uint64_t get_count(ByteReader& r, const char* what, size_t record_bytes) {
  const uint64_t n = r.get<uint64_t>();
  if (n > (r.size - r.pos) / record_bytes)
    throw_error("{}: field file corrupt: {} count {} at byte {} does not fit in the {} bytes left", r.what, what, n,
                r.pos, r.size - r.pos);
  return n;
}

void put_snapshot(ByteWriter& w, const FieldSnapshot& s, uint32_t version) {
  w.put(s.iteration);
  w.put(s.spp);
  w.put(uint64_t(s.summary.size()));
  for (const auto& [key, value] : s.summary) w.put_string(key), w.put(value);
  w.put(uint64_t(s.columns.size()));
  for (const std::string& c : s.columns) w.put_string(c);
  w.put_vector(s.table);
  w.put(uint64_t(s.leaves.size()));
  for (const FieldLeaf& leaf : s.leaves) {
    put_box(w, leaf.box);
    w.put_vector(leaf.quadtree);
    w.put_vector(leaf.samples);
    if (version >= 2) w.put_vector(leaf.lobes), w.put(leaf.pivot);
  }
}

// Children after parents and in range (so no cycles), finite non-negative flux.
void check_quadtree(const std::vector<SamplingQuadNode>& nodes, const std::string& name, size_t leaf) {
  for (size_t n = 0; n < nodes.size(); ++n)
    for (int i = 0; i < 4; ++i) {
      const uint32_t c = nodes[n].child[i];
      if ((c != 0 && (c <= n || c >= nodes.size())) || !(nodes[n].flux[i] >= 0.0f) || !std::isfinite(nodes[n].flux[i]))
        throw_error("{}: field file corrupt: leaf {} quadtree node {} is malformed", name, leaf, n);
    }
}

// None or kVMMLobes lobes, every number finite, weights and concentrations
// non-negative: the map then has a finite density everywhere.
void check_lobes(const std::vector<VMMLobe>& lobes, const vec3& pivot, const std::string& name, size_t leaf) {
  bool ok = (lobes.empty() || lobes.size() == size_t(kVMMLobes)) && std::isfinite(pivot.x) &&
            std::isfinite(pivot.y) && std::isfinite(pivot.z);
  for (const VMMLobe& l : lobes)
    ok = ok && std::isfinite(l.mu.x) && std::isfinite(l.mu.y) && std::isfinite(l.mu.z) && l.kappa >= 0.0f &&
         std::isfinite(l.kappa) && l.weight >= 0.0f && l.weight <= 1.0f && l.inv_distance >= 0.0f &&
         std::isfinite(l.inv_distance);
  if (!ok) throw_error("{}: field file corrupt: leaf {} mixture is malformed", name, leaf);
}

FieldSnapshot get_snapshot(ByteReader& r, uint32_t version) {
  FieldSnapshot s;
  s.iteration = r.get<int32_t>();
  s.spp = r.get<uint32_t>();
  const uint64_t summary = get_count(r, "summary", sizeof(uint64_t) + sizeof(double));
  for (uint64_t i = 0; i < summary; ++i) {
    std::string key = r.get_string();
    s.summary.emplace_back(std::move(key), r.get<double>());
  }
  const uint64_t columns = get_count(r, "column", sizeof(uint64_t));
  for (uint64_t i = 0; i < columns; ++i) s.columns.push_back(r.get_string());
  s.table = r.get_vector<double>();
  const uint64_t leaves = get_count(r, "leaf", 2 * sizeof(vec3) + 2 * sizeof(uint64_t));
  if (columns == 0 ? !s.table.empty() : s.table.size() % columns != 0 || s.table.size() / columns != leaves)
    throw_error("{}: field file corrupt: {} statistics for {} leaves of {} columns", r.what, s.table.size(), leaves,
                columns);
  for (uint64_t l = 0; l < leaves; ++l) {
    FieldLeaf leaf;
    leaf.box = get_box(r, "a leaf box");
    leaf.quadtree = r.get_vector<SamplingQuadNode>();
    check_quadtree(leaf.quadtree, r.what, l);
    leaf.samples = r.get_vector<FieldSample>();
    if (version >= 2) {
      leaf.lobes = r.get_vector<VMMLobe>();
      leaf.pivot = r.get<vec3>();
      check_lobes(leaf.lobes, leaf.pivot, r.what, l);
    }
    s.leaves.push_back(std::move(leaf));
  }
  return s;
}

}  // namespace

int FieldSnapshot::column(std::string_view name) const {
  for (size_t i = 0; i < columns.size(); ++i)
    if (columns[i] == name) return int(i);
  return -1;
}

size_t FieldSnapshot::leaf_at(const vec3& p) const {
  size_t best = 0;
  float best_distance = kInfinity;
  for (size_t i = 0; i < leaves.size(); ++i) {
    const vec3 outside = glm::max(glm::max(leaves[i].box.min - p, p - leaves[i].box.max), vec3(0.0f));
    const float d = glm::dot(outside, outside);
    if (d < best_distance) best = i, best_distance = d;
    if (d == 0.0f) break;
  }
  return best;
}

std::vector<uint8_t> serialize_field(const FieldFile& f) {
  bool mixtures = false;
  for (const FieldSnapshot& s : f.snapshots)
    for (const FieldLeaf& leaf : s.leaves) mixtures = mixtures || !leaf.lobes.empty();
  const uint32_t version = mixtures ? kVersion : 1;
  ByteWriter w;
  w.bytes.assign(std::begin(kMagic), std::end(kMagic));
  w.put(version);
  w.put(f.camera);
  put_box(w, f.scene_bounds);
  put_box(w, f.root_bounds);
  w.put_vector(f.wireframe.p);
  w.put(f.wireframe.scene_triangles);
  w.put(uint64_t(f.snapshots.size()));
  for (const FieldSnapshot& s : f.snapshots) put_snapshot(w, s, version);
  w.put(hash_bytes(w.bytes.data(), w.bytes.size()));
  return std::move(w.bytes);
}

FieldFile deserialize_field(std::span<const uint8_t> bytes, const std::string& name) {
  if (bytes.size() < sizeof(kMagic) + sizeof(uint32_t) + sizeof(uint64_t) ||
      std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0)
    throw_error("{}: not a theia field file (no THEIAFLD header)", name);
  uint32_t version;
  std::memcpy(&version, bytes.data() + sizeof(kMagic), sizeof(version));
  if (version < 1 || version > kVersion)
    throw_error("{}: field file version {}, this theia reads versions 1 to {} (save the field again)", name, version,
                kVersion);
  const size_t body = bytes.size() - sizeof(uint64_t);
  uint64_t checksum;
  std::memcpy(&checksum, bytes.data() + body, sizeof(checksum));
  if (checksum != hash_bytes(bytes.data(), body))
    throw_error("{}: field file corrupt: checksum mismatch (truncated or modified)", name);

  ByteReader r(bytes.first(body), name);
  r.pos = sizeof(kMagic) + sizeof(uint32_t);
  FieldFile f;
  f.camera = r.get<FieldCamera>();
  f.scene_bounds = get_box(r, "the scene bounds");
  f.root_bounds = get_box(r, "the root bounds");
  f.wireframe.p = r.get_vector<vec3>();
  if (f.wireframe.p.size() % 3 != 0) throw_error("{}: field file corrupt: the wireframe is not triangles", name);
  f.wireframe.scene_triangles = r.get<uint64_t>();
  const uint64_t snapshots = get_count(r, "snapshot", 2 * sizeof(uint32_t) + 4 * sizeof(uint64_t));
  for (uint64_t i = 0; i < snapshots; ++i) f.snapshots.push_back(get_snapshot(r, version));
  if (r.pos != body) throw_error("{}: field file corrupt: {} bytes after the last snapshot", name, body - r.pos);
  return f;
}

void save_field(const std::string& path, const FieldFile& field) {
  const std::vector<uint8_t> bytes = serialize_field(field);
  write_text_atomically(path, std::string(bytes.begin(), bytes.end()));
}

FieldFile load_field(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_error("{}: cannot open the field file", path);
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return deserialize_field(bytes, path);
}

// The square-domain form of SDTree::pdf: each level scales the density by
// 4 * flux(quad) / flux(node), summed in the same order.
double field_density(std::span<const SamplingQuadNode> nodes, vec2 c) {
  if (nodes.empty()) return 0.0;
  double density = 1.0;
  uint32_t n = 0;
  for (;;) {
    const SamplingQuadNode& node = nodes[n];
    const double total = (double(node.flux[0]) + double(node.flux[2])) + (double(node.flux[1]) + double(node.flux[3]));
    if (!(total > 0.0)) return n == 0 ? 0.0 : density;
    const int i = (c.x >= 0.5f ? 1 : 0) | (c.y >= 0.5f ? 2 : 0);
    c = glm::fract(2.0f * c);
    density *= 4.0 * double(node.flux[i]) / total;
    if (node.child[i] == 0 || density == 0.0) return density;
    n = node.child[i];
  }
}

VMMixture field_mixture_at(const FieldLeaf& leaf, const vec3& p) {
  VMMixture m;
  for (VMMLobe& l : m.lobes) l = VMMLobe{vec3(0.0f, 0.0f, 1.0f), 0.0f, 0.0f, 0.0f};
  std::copy_n(leaf.lobes.begin(), std::min(leaf.lobes.size(), m.lobes.size()), m.lobes.begin());
  return vmm_at(m, leaf.pivot, p);
}

double field_leaf_density(const FieldLeaf& leaf, const vec3& p, vec2 c) {
  if (leaf.lobes.empty()) return field_density(leaf.quadtree, c);
  return double(vmm_pdf(field_mixture_at(leaf, p), sd_square_to_direction(c))) * 4.0 * 3.14159265358979323846;
}

// --- FieldRecorder -----------------------------------------------------------

void FieldRecorder::add(const SDTree& tree, std::span<const SDTreeSample> samples) {
  for (const SDTreeSample& s : samples)
    if (tree.records(s)) pending_.push_back(s);
}

void FieldRecorder::record(LeafRecord& r, const SDTreeSample& s, float pdf_floor) {
  r.samples += 1.0, r.iteration_samples += 1.0;
  if (s.radiance > 0.0f) r.nonzero += 1.0, r.iteration_nonzero += 1.0;
  r.radiance += double(s.radiance);
  if (s.pdf < pdf_floor) r.clamped += 1.0;
  r.seen.min = glm::min(r.seen.min, s.p);
  r.seen.max = glm::max(r.seen.max, s.p);
  // Bottom-k by a hash of the key: the same kReservoir samples whatever the order.
  Reservoir e{hash(s.key, uint64_t(0x5eed)), {glm::normalize(s.wi), s.radiance / std::max(s.pdf, pdf_floor)}};
  auto less = [](const Reservoir& a, const Reservoir& b) { return a.priority < b.priority; };
  if (r.reservoir.size() == kReservoir && !less(e, r.reservoir.back())) return;
  r.reservoir.insert(std::upper_bound(r.reservoir.begin(), r.reservoir.end(), e, less), e);
  if (r.reservoir.size() > kReservoir) r.reservoir.pop_back();
}

namespace {

FieldRecorder::BoxKey box_key(const Bounds3& b) { return {b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z}; }

// Depth of the deepest quad (the root node's quads are at depth 1).
double quadtree_depth(const std::vector<SamplingQuadNode>& nodes) {
  std::vector<int> depth(nodes.size(), 1);
  int deepest = nodes.empty() ? 0 : 1;
  for (size_t n = 0; n < nodes.size(); ++n)
    for (uint32_t c : nodes[n].child)
      if (c != 0) depth[c] = depth[n] + 1, deepest = std::max(deepest, depth[c]);
  return deepest;
}

const std::vector<std::string> kColumns = {
    "samples",              "samples_nonzero",       "samples_iteration", "samples_nonzero_iteration",
    "mean_radiance",        "tree_sample_count",     "quadtree_depth",    "quadtree_nodes",
    "has_energy",           "selection_probability", "samples_min_x",     "samples_min_y",
    "samples_min_z",        "samples_max_x",         "samples_max_y",     "samples_max_z",
    "radiance_integral",    "samples_clamped",       "draw_failures"};

// With a mixture field: whether the region learned (fitted), its lobes of at
// least kVMMActiveWeight and their concentrations (vmm_summary), and the
// effective non-zero samples it has fitted (decayed, VMMRegion::weight_sum).
const std::vector<std::string> kMixtureColumns = {"vmm_fitted", "vmm_active_lobes", "vmm_kappa_min",
                                                  "vmm_kappa_max", "vmm_kappa_mean", "vmm_samples"};

}  // namespace

FieldSnapshot FieldRecorder::snapshot(const SDTree& tree, int iteration, uint32_t spp, const VMMField* vmm) {
  const std::vector<Bounds3> boxes = tree.leaf_boxes();
  // Leaves the update kept carry their records; a leaf from a split starts afresh.
  std::map<BoxKey, LeafRecord> records;
  std::vector<LeafRecord*> of_leaf(boxes.size());
  for (size_t l = 0; l < boxes.size(); ++l) {
    auto old = records_.find(box_key(boxes[l]));
    LeafRecord& r = records[box_key(boxes[l])];
    if (old != records_.end()) r = std::move(old->second);
    r.iteration_samples = r.iteration_nonzero = 0.0;
    of_leaf[l] = &r;
  }
  for (const SDTreeSample& s : pending_) record(*of_leaf[tree.leaf_index(s.p)], s, tree.options().pdf_floor);
  pending_.clear();
  records_ = std::move(records);

  const SDTreeStats st = tree.stats();
  FieldSnapshot snap;
  snap.iteration = iteration;
  snap.spp = spp;
  snap.summary = {{"spatial_leaves", double(st.spatial_leaves)}, {"quadtree_nodes", double(st.quadtree_nodes)},
                  {"bytes", double(st.bytes)},                   {"updates", double(st.updates)},
                  {"samples_recorded", double(st.samples_recorded)}, {"samples_dropped", double(st.samples_dropped)}};
  snap.columns = kColumns;
  // The mixture's regions are the tree's leaves once both have updated.
  if (vmm && vmm->region_count() != boxes.size()) vmm = nullptr;
  if (vmm) {
    snap.columns.insert(snap.columns.end(), kMixtureColumns.begin(), kMixtureColumns.end());
    snap.summary.emplace_back("vmm_lobes", double(kVMMLobes));
    snap.summary.emplace_back("vmm_bytes", double(vmm->memory_bytes()));
  }
  for (size_t l = 0; l < boxes.size(); ++l) {
    const SpatialLeaf& leaf = tree.leaf(uint32_t(l));
    const LeafRecord& r = *of_leaf[l];
    FieldLeaf out;
    out.box = boxes[l];
    const VMMRegion* region = vmm ? &vmm->region_state(uint32_t(l)) : nullptr;
    if (region) {
      // What the renderer samples here: the mixture where the region has learned, else nothing.
      if (region->fitted) {
        out.lobes.assign(region->mixture.lobes.begin(), region->mixture.lobes.end());
        if (!vmm->options().parallax)
          for (VMMLobe& lobe : out.lobes) lobe.inv_distance = 0.0f;
        out.pivot = region->pivot;
      }
    } else if (leaf.has_energy) {
      out.quadtree = leaf.sampling;
    }
    for (const Reservoir& e : r.reservoir) out.samples.push_back(e.sample);
    // Clipped to the leaf: the positions of samples, not the box they were filed under.
    const Bounds3 seen = r.samples > 0 ? Bounds3(glm::clamp(r.seen.min, out.box.min, out.box.max),
                                                 glm::clamp(r.seen.max, out.box.min, out.box.max))
                                       : out.box;
    const double row[] = {r.samples,
                          r.nonzero,
                          r.iteration_samples,
                          r.iteration_nonzero,
                          r.samples > 0 ? r.radiance / r.samples : 0.0,
                          leaf.sample_count,
                          quadtree_depth(out.quadtree),
                          double(out.quadtree.size()),
                          leaf.has_energy ? 1.0 : 0.0,
                          leaf.has_energy ? double(tree.selection_probability(uint32_t(l))) : 0.0,
                          seen.min.x, seen.min.y, seen.min.z, seen.max.x, seen.max.y, seen.max.z,
                          double(leaf.radiance_integral),
                          r.clamped,
                          double(leaf.draw_failures)};
    static_assert(std::size(row) == 19);
    snap.table.insert(snap.table.end(), std::begin(row), std::end(row));
    if (region) {
      const VMMSummary m = region->fitted ? vmm_summary(region->mixture) : VMMSummary{};
      const double mixture_row[] = {region->fitted ? 1.0 : 0.0, double(m.active_lobes), double(m.kappa_min),
                                    double(m.kappa_max),        double(m.kappa_mean),   region->weight_sum};
      static_assert(std::size(mixture_row) == 6);
      snap.table.insert(snap.table.end(), std::begin(mixture_row), std::end(mixture_row));
    }
    snap.leaves.push_back(std::move(out));
  }
  return snap;
}

std::vector<uint8_t> FieldRecorder::serialize() const {
  ByteWriter w;
  w.put_vector(pending_);
  w.put(uint64_t(records_.size()));
  for (const auto& [key, r] : records_) {
    w.put(key);
    for (double v : {r.samples, r.nonzero, r.iteration_samples, r.iteration_nonzero, r.radiance, r.clamped}) w.put(v);
    w.put(r.seen);
    w.put_vector(r.reservoir);
  }
  return w.bytes;
}

void FieldRecorder::restore(std::span<const uint8_t> bytes, const std::string& what) {
  ByteReader r(bytes, what);
  pending_ = r.get_vector<SDTreeSample>();
  records_.clear();
  const uint64_t n = r.get<uint64_t>();
  for (uint64_t i = 0; i < n; ++i) {
    const BoxKey key = r.get<BoxKey>();
    LeafRecord& rec = records_[key];
    for (double* v : {&rec.samples, &rec.nonzero, &rec.iteration_samples, &rec.iteration_nonzero, &rec.radiance,
                      &rec.clamped})
      *v = r.get<double>();
    rec.seen = r.get<Bounds3>();
    rec.reservoir = r.get_vector<Reservoir>();
    if (rec.reservoir.size() > kReservoir) throw_error("{}: a reservoir of {} samples", what, rec.reservoir.size());
  }
  if (r.pos != r.size) throw_error("{}: {} bytes after the field recorder's state", what, r.size - r.pos);
}

}  // namespace theia
