// A von Mises-Fisher mixture field with parallax compensation (after Herholz
// et al. 2016 and Ruppert et al. 2020, "Robust fitting of parallax-aware
// mixtures for path guiding"): per spatial region a mixture of kVMMLobes
// lobes fitted by weighted EM with MAP priors, each lobe keeping the mean
// inverse distance to the points its light came from, so that a lookup at p
// re-points the lobe from the region's pivot (the mean training position)
// towards the source pivot + mu / inv_distance.
//
// The regions are the SD-tree's spatial leaves (the tree splits them on its
// accumulated counts): the field reads the tree's spatial structure through
// its public API and keeps one mixture per leaf.  The tree still learns its
// radiance integral (adjoint roulette) and selection share, which the field
// forwards.
//
// Plain structs and free functions for the mixture (tests call them), one
// class for the field.  Training is deterministic: each region fits its
// samples in the order given (the recorder's sorted order), regions are
// independent, and nothing draws random numbers.
#pragma once

#include "core/bounds.h"
#include "core/directional_guide.h"
#include "core/math.h"

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace theia {

class SDTree;

inline constexpr int kVMMLobes = 8;

struct VMMLobe {
  vec3 mu{0.0f, 0.0f, 1.0f};  // mean direction, unit, seen from the region's pivot
  float kappa = 0.0f;         // concentration (0: uniform)
  float weight = 0.0f;        // mixture weight (the lobes' sum to 1)
  float inv_distance = 0.0f;  // mean of 1 / distance from the pivot to the source (0: at infinity or unknown)
};

struct VMMixture {
  std::array<VMMLobe, kVMMLobes> lobes;
};

// The vMF density exp(kappa (mu.w - 1)) kappa / (2 pi (1 - exp(-2 kappa))),
// per unit solid angle; uniform below kappa 1e-3 (where the two agree to ~1e-3).
float vmf_pdf(const vec3& mu, float kappa, const vec3& w);
// A direction drawn from it (closed form, stable for large kappa), u in [0,1)^2.
vec3 vmf_sample(const vec3& mu, float kappa, vec2 u);
// The normalisation kappa / (2 pi (1 - exp(-2 kappa))) (1 / 4 pi below kappa 1e-3).
float vmf_norm(float kappa);
// kappa from the mean cosine r (Banerjee et al. 2005's approximation) and back.
float vmf_kappa_from_mean_cosine(float r);
float vmf_mean_cosine(float kappa);

float vmm_pdf(const VMMixture& m, const vec3& w);
// The same with each lobe's vmf_norm(kappa) given (what the field keeps per region).
float vmm_pdf(const VMMixture& m, const std::array<float, kVMMLobes>& norm, const vec3& w);
// The lobe is chosen by u.x (rescaled and reused), so that a stratified u
// stays stratified within each lobe.  Returns the mixture's density of the direction.
GuideSample vmm_sample(const VMMixture& m, vec2 u);
GuideSample vmm_sample(const VMMixture& m, const std::array<float, kVMMLobes>& norm, vec2 u);
// The mixture every region starts from: lobes spread evenly over the sphere,
// equal weights, kappa `kappa`.
VMMixture vmm_initial(float kappa = 5.0f);
// Each lobe re-pointed from `pivot` to `p`: towards pivot + mu / inv_distance
// (unchanged where inv_distance is 0 or the source is at p).
VMMixture vmm_at(const VMMixture& m, const vec3& pivot, const vec3& p);

// What the log and the saved field say about a mixture: how many lobes carry
// at least kVMMActiveWeight of it (the MAP prior keeps every lobe's weight
// above 0; a lobe below 1% guides next to nothing), and their concentrations
// (min and max over those lobes; the mean weighted by the lobes' weights).
inline constexpr float kVMMActiveWeight = 0.01f;
struct VMMSummary {
  int active_lobes = 0;
  float kappa_min = 0.0f, kappa_max = 0.0f, kappa_mean = 0.0f;
};
VMMSummary vmm_summary(const VMMixture& m);

struct VMMOptions {
  int em_iterations = 8;               // per update, over that iteration's samples
  float weight_prior = 0.01f;          // Dirichlet prior per lobe, in samples (MAP, keeps lobes alive)
  float mean_cosine_prior = 0.0f;      // prior on each lobe's mean cosine (0: towards wide lobes) ...
  float mean_cosine_strength = 0.2f;   // ... worth this many samples
  float max_kappa = 10000.0f;
  // Statistics of earlier iterations are multiplied by this at each update:
  // their responsibilities came from an earlier (worse) fit.
  double decay = 0.5;
  bool parallax = true;
  // As SDTreeOptions: training weight radiance / max(pdf, pdf_floor).
  float pdf_floor = 0.1f;
  // On a split each half keeps this share of the statistics (SDTreeOptions::split_decay).
  double split_decay = 0.25;
};

// One training sample: radiance arriving at p from wi, drawn with density
// pdf, its source at `distance` along wi (0: unknown, +inf: at infinity).
struct VMMSample {
  vec3 p{0.0f}, wi{0.0f};
  float radiance = 0.0f, pdf = 0.0f;
  float distance = 0.0f;
};

// A lobe's sufficient statistics (sums over samples of weight x
// responsibility, of that x direction, and of that x 1 / distance over the
// samples whose distance is known with the weight of those).
struct VMMLobeStats {
  double weight = 0.0;
  dvec3 direction{0.0};
  double inv_distance = 0.0, distance_weight = 0.0;
};

struct VMMRegion {
  VMMixture mixture = vmm_initial();
  std::array<VMMLobeStats, kVMMLobes> stats{};
  dvec3 position_sum{0.0};
  double position_count = 0.0;  // samples (zero-valued ones too), decayed
  vec3 pivot{0.0f};
  double weight_sum = 0.0;      // of the normalised weights: effective non-zero samples, decayed
  bool fitted = false;          // has learned from at least one sample with energy
  std::array<float, kVMMLobes> norm{};  // vmf_norm of each lobe's kappa (lookups: no logs)
};

// One update of a region from its new samples (taken in order): the pivot
// moves to the mean position (lobes and statistics re-pointed with it), the
// samples are re-pointed to the pivot through their distance, their weights
// normalised to one per non-zero sample, then EM runs over them with the
// earlier statistics (times options.decay) as a prior.  Invalid samples (as
// SDTree::add_sample drops them) are skipped.
void vmm_fit(VMMRegion& region, std::span<const VMMSample> samples, const VMMOptions& options);

// The field: regions are the SD-tree's spatial leaves.  A region handle is
// the leaf index and the lookup position quantised within the leaf's box
// (kVMMCellBits bits per axis at most, fewer once there are many leaves), so
// that sample() and pdf() re-point the lobes from one position, the same for
// both; the engine never looks inside a handle.
class VMMField final : public DirectionalGuide {
 public:
  // `tree` provides the regions and must outlive the field; update() is
  // called right after each tree.update().
  VMMField(const SDTree& tree, const VMMOptions& options);

  // The iteration's samples; kept until update().
  void add_samples(std::span<const VMMSample> samples);
  // Follows the tree's splits (halves inherit their leaf's mixture and
  // statistics times split_decay), then fits every region to its new samples.
  void update();

  uint32_t region(const vec3& p) const override;
  GuideSample sample(uint32_t region, vec2 u) const override;
  float pdf(uint32_t region, const vec3& wi) const override;
  float selection_probability(uint32_t region) const override;
  float radiance_integral(uint32_t region) const override;
  void count_failed_draw(uint32_t region) const override;

  const VMMOptions& options() const { return options_; }
  size_t region_count() const { return regions_.size(); }
  const VMMRegion& region_state(uint32_t leaf) const { return regions_[leaf]; }
  size_t memory_bytes() const;
  // The mixture the handle's lookup samples (re-pointed to its position).
  VMMixture mixture_at(uint32_t region) const;
  double fit_seconds() const { return fit_seconds_; }

  // Everything update() and the lookups read (every region's mixture,
  // statistics, pivot and position sums, the leaf boxes, samples not yet
  // fitted, the handle's cell bits), for a checkpoint: a restored field fits
  // and samples as the saved one would have.  Layout as the host writes it:
  //   "THEIAVMM" | u32 version | options | regions | boxes | pending | u64 hash_bytes(everything before)
  std::vector<uint8_t> serialize() const;
  // Replaces the state with `bytes` (all or nothing), once the tree has been
  // restored: the regions must be the tree's leaves.  Throws theia::Error,
  // prefixed `what`, for a truncated or corrupt input, another version, other
  // options or another tree; nothing is allocated beyond what the input holds.
  void restore(std::span<const uint8_t> bytes, const std::string& what);

  static constexpr int kVMMCellBits = 8;

 private:
  uint32_t leaf_of(uint32_t region) const { return region >> (3 * cell_bits_); }

  const SDTree& tree_;
  VMMOptions options_;
  std::vector<VMMRegion> regions_;  // per leaf
  std::vector<Bounds3> boxes_;      // per leaf, at the last update
  std::vector<VMMSample> pending_;
  int cell_bits_ = kVMMCellBits;
  double fit_seconds_ = 0.0;
};

}  // namespace theia
