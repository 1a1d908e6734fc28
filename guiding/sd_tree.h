// The SD-tree (Müller et al. 2017, with the production extensions of
// seeds/001 ch. 10): a spatial binary tree whose leaves each hold a
// directional quadtree over Müller's world-space cylindrical map
// ((cos theta + 1) / 2, phi / 2 pi).  That map is equal-area, so a quadtree
// that is piecewise constant over the square is piecewise constant per unit
// solid angle and pdf(w) = pdf_square / (4 pi).
//
// Every leaf keeps two quadtrees: the *sampling* one (what the previous
// iterations learned; region/sample/pdf read it) and the *building* one (the
// deposits of every iteration so far, on a topology refined at each update).
// update() copies building into sampling, splits busy spatial leaves, and
// refines building around its flux.  Nothing is forgotten between
// iterations: with the small iterations of a guiding schedule a field that
// starts over each time learns from a few thousand samples at most.  Trees are flat vectors of plain nodes linked
// by index; a child's index is always greater than its parent's, which lets
// update() sum flux bottom-up in one reverse pass and lets deserialize()
// reject cycles.
#pragma once

#include "core/bounds.h"
#include "core/directional_guide.h"
#include "core/math.h"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace theia {

struct SDTreeOptions {
  // A spatial leaf splits once the samples it has accumulated (over every
  // iteration, decayed on each split) exceed this.  Müller counts per
  // iteration against c * sqrt(spp) with c = 4000 (seeds/001 10.4); counted
  // over iterations, a leaf splits as soon as it has seen enough, however
  // small the iterations are (OpenPGL's rule, which Hyperion's capped
  // schedule relies on).
  double spatial_threshold = 4000.0;
  // On a split both halves inherit the leaf's quadtree and count times this:
  // what the leaf learned over its whole box is a prior, soon outweighed by
  // what each half sees itself.
  double split_decay = 0.25;
  // Training samples weigh radiance / max(pdf, pdf_floor): one direction drawn
  // at a tiny density (a grazing cosine sample) would otherwise deposit an
  // outlier that builds deep quads around itself (OpenPGL uses 0.1).  0: the
  // unbiased weight.
  float pdf_floor = 0.1f;
  // A quad is subdivided while it holds more than rho of its leaf's flux.
  double flux_threshold = 0.01;
  int max_quadtree_depth = 20;
  // One-sample-MIS share of guided directions: fixed, or where learned
  // (seeds/001 10.5) the start of every leaf's learning.
  float selection_probability = 0.5f;
  // Learn the share per spatial leaf: Adam on the KL divergence between the
  // mixture and the product of radiance and BSDF (samples that carry their
  // densities, SDTreeSample::bsdf_ratio).  Set by --guiding-sampling mis-learned.
  bool learn_selection = false;
  // Stochastic box over the containing leaf's footprint (seeds/001 10.4).
  bool spatial_filter = true;
  // Deterministic box over the containing quad's footprint, weighted by area
  // overlap in the cylindrical domain (seeds/001 10.4).
  bool directional_filter = true;
};

// The options a render sets, each once (flags --guiding-NAME; see
// app/options.h for what image means); the others keep their defaults.
template <class V>
void declare_options(V& v, SDTreeOptions& o) {
  v.image("spatial_threshold", o.spatial_threshold,
          "SD-tree: split a spatial leaf once it has accumulated this many training samples");
  v.image("split_decay", o.split_decay, "SD-tree: share of a leaf's statistics each half keeps on a split, (0, 0.5]");
  v.image("pdf_floor", o.pdf_floor, "SD-tree: training weight radiance / max(pdf, this); 0: unbiased");
  v.image("selection_probability", o.selection_probability,
          "Probability of sampling the guide rather than the BSDF where it applies, in [0, 1) (learned: where "
          "learning starts)");
}

struct SDTreeStats {
  size_t spatial_leaves = 0;
  size_t quadtree_nodes = 0;  // sampling + building, all leaves
  size_t bytes = 0;           // memory_bytes()
  int updates = 0;            // update() calls so far
  uint64_t draw_failures = 0; // guide draws the BSDF did not scatter into, all leaves, ever
  // The last finished iteration (the one the last update() consumed).
  uint64_t samples_recorded = 0;
  uint64_t samples_dropped = 0;
  // The iteration being recorded now.
  uint64_t pending_recorded = 0;
  uint64_t pending_dropped = 0;
};

// Where training's time goes (seconds, accumulated over the render; wall
// clock, so a parallel part counts once): add_samples's leaf per sample,
// counting sort and deposits; update()'s building-to-sampling copy, spatial
// splits, quadtree refinement and lookup tables.
struct SDTreeTimes {
  double classify = 0.0, order = 0.0, deposit = 0.0;
  double copy = 0.0, split = 0.0, refine = 0.0, index = 0.0;
};

// One quadtree node: four quadrants (index = x_high | y_high << 1), each a
// leaf (child 0: the root is never anyone's child) or an inner node.
template <typename T>
struct QuadNode {
  T flux[4] = {0, 0, 0, 0};
  uint32_t child[4] = {0, 0, 0, 0};
};
// Sampling flux is stored as a fraction of the leaf's total; deposits are
// double because one sample can be 1e30 / 1e-20 and millions are summed.
using SamplingQuadNode = QuadNode<float>;
using BuildingQuadNode = QuadNode<double>;

struct SpatialNode {
  uint32_t first_child = 0;  // children at first_child and first_child + 1; 0: a leaf
  uint32_t leaf = 0;         // index into the leaves, for a leaf
  uint8_t axis = 0;          // split axis of an inner node (x, y, z by depth)
};

// The learned selection probability of a leaf (seeds/001 10.5, Algorithm 3):
// selection = sigmoid(theta), theta moved by Adam one training sample at a time.
struct SelectionLearner {
  float theta = 0.0f;
  float m = 0.0f, v = 0.0f;  // Adam's first and second moments
  uint32_t steps = 0;
  double product_sum = 0.0;  // of the samples' product weights: their mean scales the gradient
};

// A sampling node as sample() and pdf() read it (index_lookups): 16 bytes,
// each leaf's nodes breadth-first in one array of all leaves, so that a
// descent's dependent loads land on few, mostly cached lines.  The guide
// draws the left column (quadrants 0, 2) by `column`, then quadrant 0
// within it by row[0] (quadrant 1 within the right column by row[1]); each
// share is the smaller side's probability in float, negated when it is the
// second side's (sd_tree.cpp, stored_share).  The density's factor for a
// quadrant is 4 times the product of the two probabilities that chose it, in
// double, so sample() and pdf() agree with each other and with the warp,
// though the shares are rounded to float.
struct GuideNode {
  float column = 0.5f;
  float row[2] = {0.5f, 0.5f};
  // Bits 0-3: quadrant i has a child; bit 4: the node has no flux (a uniform
  // leaf); bits 5-31: the first child's index among the leaf's nodes (the
  // others follow it in quadrant order).
  uint32_t link = 0;
};
static_assert(sizeof(GuideNode) == 16);

struct SpatialLeaf {
  std::vector<SamplingQuadNode> sampling;
  std::vector<BuildingQuadNode> building;
  double sample_count = 0;    // samples accumulated into building (zero-valued ones too), decayed on splits
  bool has_energy = false;    // sampling holds positive flux
  float radiance_integral = 0.0f;  // sampling's: deposits / samples at the last update
  float selection = 0.5f;          // sampling's share of guided directions (learner's at the last update)
  SelectionLearner learner;        // building's
  // Guide draws the BSDF did not scatter into, since the leaf was made
  // (count_failed_draw; atomic increments from the render's threads).
  mutable uint64_t draw_failures = 0;
};

// One training sample as add_sample takes it.
struct SDTreeSample {
  vec3 p{0.0f}, wi{0.0f};
  float radiance = 0.0f, pdf = 0.0f;
  uint64_t key = 0;
  // For learning the selection probability: radiance x f |cos| / pdf (the
  // product over the density the direction was drawn with), and the BSDF's
  // and the guide's densities of wi over that density.  Both ratios 0: the
  // direction was not drawn from a guide-and-BSDF mixture, nothing to learn.
  float product_weight = 0.0f;
  float bsdf_ratio = 0.0f, guide_ratio = 0.0f;
};

// One Adam step of a leaf's learner on one sample (Algorithm 3 of seeds/001,
// with the share of the guide rather than of the BSDF as the learned
// probability).  No step for a sample without ratios.
void learn_selection_step(SelectionLearner& learner, const SDTreeSample& s);
inline float learned_selection(const SelectionLearner& l) { return 1.0f / (1.0f + std::exp(-l.theta)); }

class SDTree final : public DirectionalGuide {
 public:
  SDTree(const Bounds3& scene_bounds, const SDTreeOptions& options);

  // One training sample: luminance `radiance` arriving at p from the unit
  // world direction wi, drawn with solid-angle density `pdf`.  Records
  // radiance / pdf; the spatial jitter is a pure function of `key`.  Samples
  // with non-finite or negative radiance, pdf <= 0 or non-finite p / wi are
  // dropped and counted; zero radiance is recorded (it counts).
  void add_sample(const vec3& p, const vec3& wi, float radiance, float pdf, uint64_t key);
  void add_sample(const SDTreeSample& s);
  // add_sample for every sample, in parallel over spatial leaves (the
  // busiest first, each taken whole by one thread): each leaf takes its
  // samples in index order, so the tree is the one the same add_sample calls
  // in a row build, whatever the thread count.
  void add_samples(std::span<const SDTreeSample> samples);
  // Frees add_samples's working arrays (training is over).
  void release_training_buffers() { leaf_of_ = {}, order_ = {}, first_ = {}, busiest_ = {}; }
  // End of an iteration: what building accumulated becomes sampling, busy
  // leaves split, and building is refined around its flux (keeping it).
  void update();

  uint32_t region(const vec3& p) const override;
  // The returned pdf is the density of the quad the direction was drawn in:
  // pdf(region, wi) but for directions within rounding of a quad's edge.  A
  // pdf of 0 (flux that underflowed) means the sample failed.
  GuideSample sample(uint32_t region, vec2 u) const override;
  float pdf(uint32_t region, const vec3& wi) const override;
  float selection_probability(uint32_t region) const override;
  float radiance_integral(uint32_t region) const override;
  void count_failed_draw(uint32_t region) const override;

  std::vector<uint8_t> serialize() const;
  // Throws theia::Error naming what is wrong (truncation, checksum, version, structure).
  static SDTree deserialize(std::span<const uint8_t> bytes);

  SDTreeStats stats() const;
  const SDTreeTimes& times() const { return times_; }
  size_t memory_bytes() const;

  const SDTreeOptions& options() const { return options_; }
  const Bounds3& root_bounds() const { return root_; }
  int updates() const { return updates_; }
  // The leaf box holding p (p clamped into the root box).
  Bounds3 leaf_bounds(const vec3& p) const;

  // Read access for tools (guiding/field_file.h): leaves by index, their boxes
  // in leaf-index order, the leaf holding p, and whether add_sample records s.
  size_t leaf_count() const { return leaves_.size(); }
  const SpatialLeaf& leaf(uint32_t index) const { return leaves_[index]; }
  std::vector<Bounds3> leaf_boxes() const;
  uint32_t leaf_index(const vec3& p) const { return leaf_at(p); }
  bool records(const SDTreeSample& s) const { return target_leaf(s.p, s.wi, s.radiance, s.pdf, s.key) != kInvalidLeaf; }

 private:
  SDTree() = default;
  // Throws theia::Error for an option outside its range.
  static void check_options(const SDTreeOptions& options);
  struct Lookup {
    uint32_t leaf;
    vec3 lo, size;  // the leaf box
  };
  Lookup find_leaf(const vec3& p) const;
  // find_leaf's leaf without its box: one comparison per level against the
  // node's split plane in the root box's unit coordinates.  find_leaf's
  // halvings are exact, so comparing with the dyadic plane takes its branch.
  uint32_t leaf_at(const vec3& p) const;
  // Rebuilds region_nodes_, leaf_size_ and the guide's nodes and leaf
  // records: after update() and deserialize().
  void index_lookups();
  // The leaf a valid sample deposits into (after the spatial jitter); kInvalidLeaf for one add_sample drops.
  static constexpr uint32_t kInvalidLeaf = 0xffffffffu;
  uint32_t target_leaf(const vec3& p, const vec3& wi, float radiance, float pdf, uint64_t key) const;
  void deposit_sample(SpatialLeaf& leaf, const SDTreeSample& s);
  void refine_spatial();
  void deposit(BuildingQuadNode* nodes, vec2 c, double value) const;

  SDTreeOptions options_;
  Bounds3 root_;
  vec3 root_size_{0.0f};
  int updates_ = 0;
  std::vector<SpatialNode> nodes_;
  std::vector<SpatialLeaf> leaves_;
  struct RegionNode {
    double split = 0.0;      // the plane, in unit coordinates along `axis`
    uint32_t first_child = 0;  // 0: a leaf
    uint32_t axis_or_leaf = 0;
  };
  std::vector<RegionNode> region_nodes_;  // nodes_, for leaf_at
  // A uniform grid of 2^kLookupGridBits cells per axis over the root box,
  // each naming the deepest node whose box holds the whole cell: leaf_at
  // starts its descent there.  The planes above that node lie on cell edges
  // (dyadic), so the cell decides them exactly as the comparisons would; it
  // spares the first levels of a dependent chain of loads (~20 cycles each).
  static constexpr int kLookupGridBits = 4;
  std::vector<uint32_t> lookup_grid_;
  // Each leaf's box in the root box's unit coordinates, [lo, hi) per axis
  // (the split planes that bound it, exactly): leaf_at tries the leaf it
  // found last on the calling thread first, since shading visits hits sorted
  // by primitive and the next point is mostly in the same leaf.
  struct LeafBox {
    double lo[3], hi[3];
  };
  std::vector<LeafBox> leaf_box_;
  uint64_t lookup_generation_ = 0;  // names this index_lookups(): a thread's last leaf is for it alone
  // What region(), sample() and pdf() read of a leaf, 16 bytes apiece: its
  // first node in guide_nodes_ (the sampling quadtree, breadth-first), and
  // its share and radiance integral (copies of the SpatialLeaf's).
  struct GuideLeaf {
    uint32_t first_node = 0;
    uint32_t has_energy = 0;
    float selection = 0.5f;
    float radiance_integral = 0.0f;
  };
  std::vector<GuideLeaf> guide_leaves_;
  std::vector<GuideNode> guide_nodes_;
  std::vector<vec3> leaf_size_;           // each leaf's box size, as find_leaf gives it (the spatial filter's)
  uint64_t recorded_ = 0, dropped_ = 0;            // pending iteration
  uint64_t last_recorded_ = 0, last_dropped_ = 0;  // last finished iteration
  mutable uint64_t draw_failures_ = 0;             // every leaf's, including split ones
  SDTreeTimes times_;
  // add_samples's working arrays, kept so that an iteration allocates nothing
  // once the largest has been seen: each sample's leaf, the samples grouped
  // by leaf, the groups' offsets, the leaves busiest first.
  std::vector<uint32_t> leaf_of_, order_, first_, busiest_;

  friend struct SDTreeSerializer;
};

// Müller's cylindrical map and its inverse, exposed for tests.
vec2 sd_direction_to_square(const vec3& wi);
vec3 sd_square_to_direction(vec2 c);

}  // namespace theia
