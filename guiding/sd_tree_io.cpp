// SD-tree serialisation: everything the tree holds (options, both quadtrees
// of every leaf, sample counts, the update count k), so a resumed render
// continues training exactly as an uninterrupted one.  Layout, all
// little-endian as the host writes it (theia targets x86-64 and arm64):
//   "THEIASDT" | u32 version | payload | u64 hash_bytes(everything before)
// The reader checks length, magic, version and checksum, then the structure
// (indices in range and pointing forward, so no cycles; finite non-negative
// flux), so no input can make region()/sample()/pdf() read out of bounds.
#include "guiding/sd_tree.h"

#include "core/hash.h"
#include "core/log.h"

#include <cmath>
#include <cstring>
#include <string_view>
#include <type_traits>

namespace theia {

namespace {

constexpr char kMagic[8] = {'T', 'H', 'E', 'I', 'A', 'S', 'D', 'T'};
// 2: statistics accumulated over iterations; 3: radiance integral per leaf;
// 4: learned selection probability per leaf
constexpr uint32_t kVersion = 4;

struct Writer {
  std::vector<uint8_t> out;
  template <typename T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const auto* b = reinterpret_cast<const uint8_t*>(&v);
    out.insert(out.end(), b, b + sizeof(T));
  }
  void put_vec3(const vec3& v) {
    for (int a = 0; a < 3; ++a) put(v[a]);
  }
};

struct Reader {
  std::span<const uint8_t> in;
  size_t at = 0;
  template <typename T>
  T get(std::string_view what) {
    static_assert(std::is_trivially_copyable_v<T>);
    if (in.size() - at < sizeof(T))
      throw_error("SD-tree data truncated: {} at byte {} needs {} bytes, {} left", what, at, sizeof(T),
                  in.size() - at);
    T v;
    std::memcpy(&v, in.data() + at, sizeof(T));
    at += sizeof(T);
    return v;
  }
  vec3 get_vec3(std::string_view what) {
    vec3 v;
    for (int a = 0; a < 3; ++a) v[a] = get<float>(what);
    return v;
  }
  // A count of records of `record_bytes` each, refused before allocating if
  // the input cannot hold them.
  uint32_t get_count(std::string_view what, size_t record_bytes) {
    uint32_t n = get<uint32_t>(what);
    if (uint64_t(n) * record_bytes > in.size() - at)
      throw_error("SD-tree data corrupt: {} = {} needs {} bytes at byte {}, {} left", what, n,
                  uint64_t(n) * record_bytes, at, in.size() - at);
    return n;
  }
};

template <typename T>
void put_quadtree(Writer& w, const std::vector<QuadNode<T>>& nodes) {
  w.put(uint32_t(nodes.size()));
  for (const QuadNode<T>& n : nodes) {
    for (int i = 0; i < 4; ++i) w.put(n.flux[i]);
    for (int i = 0; i < 4; ++i) w.put(n.child[i]);
  }
}

template <typename T>
std::vector<QuadNode<T>> get_quadtree(Reader& r, const char* which, size_t leaf) {
  uint32_t count = r.get_count(which, 4 * (sizeof(T) + sizeof(uint32_t)));
  if (count == 0) throw_error("SD-tree data corrupt: leaf {} has an empty {} quadtree", leaf, which);
  std::vector<QuadNode<T>> nodes(count);
  // Each node is one node's child (a tree, as update() makes it): the
  // lookups lay a quadtree out breadth-first, one slot per node.
  std::vector<uint8_t> parented(count, 0);
  for (uint32_t n = 0; n < count; ++n) {
    for (int i = 0; i < 4; ++i) {
      T f = r.get<T>(which);
      if (!(f >= T(0)) || !std::isfinite(f))
        throw_error("SD-tree data corrupt: leaf {} {} node {} has flux {}", leaf, which, n, double(f));
      nodes[n].flux[i] = f;
    }
    for (int i = 0; i < 4; ++i) {
      uint32_t c = r.get<uint32_t>(which);
      if (c != 0 && (c <= n || c >= count || parented[c]++))
        throw_error("SD-tree data corrupt: leaf {} {} node {} has child index {} (of {}, or another node's child)",
                    leaf, which, n, c, count);
      nodes[n].child[i] = c;
    }
  }
  return nodes;
}

}  // namespace

struct SDTreeSerializer {
  static std::vector<uint8_t> write(const SDTree& t) {
    Writer w;
    w.out.insert(w.out.end(), std::begin(kMagic), std::end(kMagic));
    w.put(kVersion);
    const SDTreeOptions& o = t.options_;
    w.put(o.spatial_threshold);
    w.put(o.split_decay);
    w.put(o.pdf_floor);
    w.put(o.flux_threshold);
    w.put(int32_t(o.max_quadtree_depth));
    w.put(o.selection_probability);
    w.put(uint8_t(o.spatial_filter));
    w.put(uint8_t(o.directional_filter));
    w.put(uint8_t(o.learn_selection));
    w.put_vec3(t.root_.min);
    w.put_vec3(t.root_.max);
    w.put_vec3(t.root_size_);
    w.put(int32_t(t.updates_));
    w.put(t.recorded_);
    w.put(t.dropped_);
    w.put(t.last_recorded_);
    w.put(t.last_dropped_);
    w.put(t.draw_failures_);
    w.put(uint32_t(t.nodes_.size()));
    for (const SpatialNode& n : t.nodes_) {
      w.put(n.first_child);
      w.put(n.leaf);
      w.put(n.axis);
    }
    w.put(uint32_t(t.leaves_.size()));
    for (const SpatialLeaf& leaf : t.leaves_) {
      w.put(leaf.sample_count);
      w.put(uint8_t(leaf.has_energy));
      w.put(leaf.radiance_integral);
      w.put(leaf.selection);
      w.put(leaf.learner);
      w.put(leaf.draw_failures);
      put_quadtree(w, leaf.sampling);
      put_quadtree(w, leaf.building);
    }
    w.put(hash_bytes(w.out.data(), w.out.size()));
    return std::move(w.out);
  }

  static SDTree read(std::span<const uint8_t> bytes) {
    constexpr size_t kHeader = sizeof(kMagic) + sizeof(uint32_t);
    if (bytes.size() < kHeader + sizeof(uint64_t))
      throw_error("SD-tree data truncated: {} bytes, a header and checksum need {}", bytes.size(),
                  kHeader + sizeof(uint64_t));
    if (std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0)
      throw_error("SD-tree data corrupt: expected the magic \"THEIASDT\"");
    uint32_t version;
    std::memcpy(&version, bytes.data() + sizeof(kMagic), sizeof(version));
    if (version != kVersion) throw_error("SD-tree data has version {}, this build reads {}", version, kVersion);
    const size_t body = bytes.size() - sizeof(uint64_t);
    uint64_t stored;
    std::memcpy(&stored, bytes.data() + body, sizeof(stored));
    if (stored != hash_bytes(bytes.data(), body))
      throw_error("SD-tree data corrupt or truncated: checksum mismatch over {} bytes", body);

    Reader r{bytes.first(body), kHeader};
    SDTree t;
    SDTreeOptions& o = t.options_;
    o.spatial_threshold = r.get<double>("spatial threshold");
    o.split_decay = r.get<double>("split decay");
    o.pdf_floor = r.get<float>("pdf floor");
    o.flux_threshold = r.get<double>("flux threshold");
    o.max_quadtree_depth = r.get<int32_t>("max quadtree depth");
    o.selection_probability = r.get<float>("selection probability");
    o.spatial_filter = r.get<uint8_t>("spatial filter") != 0;
    o.directional_filter = r.get<uint8_t>("directional filter") != 0;
    o.learn_selection = r.get<uint8_t>("learn selection") != 0;
    SDTree::check_options(o);
    t.root_.min = r.get_vec3("root box");
    t.root_.max = r.get_vec3("root box");
    t.root_size_ = r.get_vec3("root size");
    for (int a = 0; a < 3; ++a)
      if (!(t.root_size_[a] > 0.0f) || !std::isfinite(t.root_size_[a]) || !std::isfinite(t.root_.min[a]) ||
          !std::isfinite(t.root_.max[a]))
        throw_error("SD-tree data corrupt: root box is not finite with positive size");
    t.updates_ = r.get<int32_t>("update count");
    if (t.updates_ < 0 || t.updates_ > 4096) throw_error("SD-tree data corrupt: update count {}", t.updates_);
    t.recorded_ = r.get<uint64_t>("sample counters");
    t.dropped_ = r.get<uint64_t>("sample counters");
    t.last_recorded_ = r.get<uint64_t>("sample counters");
    t.last_dropped_ = r.get<uint64_t>("sample counters");
    t.draw_failures_ = r.get<uint64_t>("draw failure count");

    uint32_t n_nodes = r.get_count("spatial node count", 9);
    if (n_nodes == 0) throw_error("SD-tree data corrupt: no spatial nodes");
    t.nodes_.resize(n_nodes);
    for (uint32_t n = 0; n < n_nodes; ++n) {
      SpatialNode& s = t.nodes_[n];
      s.first_child = r.get<uint32_t>("spatial node");
      s.leaf = r.get<uint32_t>("spatial node");
      s.axis = r.get<uint8_t>("spatial node");
      if (s.axis > 2 || (s.first_child != 0 && (s.first_child <= n || s.first_child >= n_nodes - 1)))
        throw_error("SD-tree data corrupt: spatial node {} (axis {}, children at {}) of {}", n, s.axis,
                    s.first_child, n_nodes);
    }
    uint32_t n_leaves = r.get_count("leaf count", 8 + 1 + 2 * 4);
    std::vector<uint8_t> referenced(n_leaves, 0);
    for (const SpatialNode& s : t.nodes_) {
      if (s.first_child != 0) continue;
      if (s.leaf >= n_leaves || referenced[s.leaf]++)
        throw_error("SD-tree data corrupt: spatial leaf index {} (of {}) out of range or repeated", s.leaf,
                    n_leaves);
    }
    for (uint32_t l = 0; l < n_leaves; ++l)
      if (!referenced[l]) throw_error("SD-tree data corrupt: leaf {} is not in the spatial tree", l);
    t.leaves_.resize(n_leaves);
    for (uint32_t l = 0; l < n_leaves; ++l) {
      SpatialLeaf& leaf = t.leaves_[l];
      leaf.sample_count = r.get<double>("leaf sample count");
      if (!(leaf.sample_count >= 0.0) || !std::isfinite(leaf.sample_count))
        throw_error("SD-tree data corrupt: leaf {} sample count {}", l, leaf.sample_count);
      leaf.has_energy = r.get<uint8_t>("leaf energy flag") != 0;
      leaf.radiance_integral = r.get<float>("leaf radiance integral");
      if (!(leaf.radiance_integral >= 0.0f) || !std::isfinite(leaf.radiance_integral))
        throw_error("SD-tree data corrupt: leaf {} radiance integral {}", l, leaf.radiance_integral);
      leaf.selection = r.get<float>("leaf selection probability");
      if (!(leaf.selection >= 0.0f && leaf.selection <= 1.0f))
        throw_error("SD-tree data corrupt: leaf {} selection probability {}", l, leaf.selection);
      leaf.learner = r.get<SelectionLearner>("leaf selection learner");
      leaf.draw_failures = r.get<uint64_t>("leaf draw failures");
      if (!std::isfinite(leaf.learner.theta) || !std::isfinite(leaf.learner.m) || !(leaf.learner.v >= 0.0f) ||
          !std::isfinite(leaf.learner.v) || !(leaf.learner.product_sum >= 0.0) || !std::isfinite(leaf.learner.product_sum))
        throw_error("SD-tree data corrupt: leaf {} selection learner", l);
      leaf.sampling = get_quadtree<float>(r, "sampling", l);
      leaf.building = get_quadtree<double>(r, "building", l);
    }
    if (r.at != body) throw_error("SD-tree data corrupt: {} unread bytes before the checksum", body - r.at);
    t.index_lookups();
    return t;
  }
};

std::vector<uint8_t> SDTree::serialize() const { return SDTreeSerializer::write(*this); }

SDTree SDTree::deserialize(std::span<const uint8_t> bytes) { return SDTreeSerializer::read(bytes); }

}  // namespace theia
