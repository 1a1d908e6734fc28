// The features a render assembles, each one object that owns its options
// (a plain struct with defaults, declared once: app/options.h), their
// validation, and what it adds to a render: engine hooks, between-iteration
// tasks, checkpoint sections and its log section.  A feature that is off
// builds nothing and adds nothing.  render_scene (app/render.cpp) builds
// them and asks each in turn; the objects they own live in their folders
// (guiding/, radiance_recorder/, wavefront/caustics.h, scheduler/).
#pragma once

#include "app/options.h"
#include "core/light_sampler.h"
#include "guiding/sd_tree.h"
#include "guiding/vmm.h"
#include "radiance_recorder/recorder.h"
#include "scheduler/driver.h"
#include "wavefront/caustics.h"
#include "wavefront/engine.h"

#include <nlohmann/json.hpp>

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace theia {

class Feature {
 public:
  virtual ~Feature() = default;
  // Before the engine is built: the hooks it calls.
  virtual void configure(EngineOptions&, EngineHooks&) const {}
  // Once the engine is built, for a feature that changes its hooks between iterations.
  virtual void attach(WavefrontEngine&) {}
  virtual void add_tasks(IterationTasks&) {}
  // What a resumed render needs to continue exactly where this one stopped.
  virtual void add_participants(std::vector<CheckpointParticipant>&) {}
  // After the render: the feature's section of the JSON log.
  virtual void write_log(nlohmann::json&) const {}
};

// --- Light sampler (group: none) --------------------------------------------

struct LightSamplerOptions {
  // uniform | power | bvh | cachepoints | local | auto (cachepoints/light_sampler.h): auto
  // builds cache points for many emitters, the light BVH for several, else power.
  std::string light_sampler = "auto";
};

template <class V>
void declare_options(V& v, LightSamplerOptions& o) {
  v.image("light_sampler", o.light_sampler,
          "Light selection: uniform, power, bvh (light hierarchy), cachepoints (occlusion-aware many-lights sampling), local "
          "(every emitter's unoccluded estimate at every vertex: the exact locally optimal choice, for small test scenes; "
          "warns from 1024 emitters) or auto (cache points from 1024 emitters, the light BVH from 8, else power)");
}
void check(const LightSamplerOptions& o);

// The scene's light sampler (RenderableScene builds it from the option):
// one that learns from shadow rays folds what it learned in between
// iterations, checkpoints it, and reports its costs in the log.
class LightSamplerFeature final : public Feature {
 public:
  explicit LightSamplerFeature(LightSampler& sampler) : sampler_(sampler) {}
  void add_tasks(IterationTasks& tasks) override;
  void add_participants(std::vector<CheckpointParticipant>& participants) override;
  void write_log(nlohmann::json& log) const override;

 private:
  LightSampler& sampler_;
};

// --- Radiance recorder (group "recorder") -----------------------------------

void check(const RecorderOptions& o);

// Built only when something consumes it: guiding's training, or a debug layer.
class RecorderFeature final : public Feature {
 public:
  RecorderFeature(const RecorderOptions& options, bool guiding, uint32_t seed, int width, int height,
                  TrainingSampleSink* sink);
  static bool debug_layers(const RecorderOptions& o) { return o.debug || o.debug_bounce >= 0; }
  // The engine's path observer; null when not built.
  RadianceRecorder* recorder() const { return recorder_.get(); }
  void add_tasks(IterationTasks& tasks) override;
  void add_participants(std::vector<CheckpointParticipant>& participants) override;
  void write_log(nlohmann::json& log) const override;
  // The debug layers of the EXR (they sum over every iteration, like the film).
  std::vector<FilmLayer> layers() const;

 private:
  RecorderOptions options_;
  std::unique_ptr<RadianceRecorder> recorder_;
  // Per iteration: [spp_end, samples, sort seconds, consume seconds] (the log's recorder.iterations).
  std::vector<std::array<double, 4>> iteration_times_;
};

// --- Path guiding (group "guiding") -----------------------------------------

struct GuidingOptions : SDTreeOptions {
  // --guiding: on; --no-guiding: off; --guiding-auto (the default): guiding
  // measures whether it pays and turns itself off where it does not
  // (GuidingVerdict below), so a scene whose light guiding cannot help pays
  // for a probe (2-4% of a 30 s render), not for guiding.
  OnOffAuto enabled = OnOffAuto::Auto;
  bool on() const { return enabled != OnOffAuto::Off; }
  bool judged() const { return enabled == OnOffAuto::Auto; }
  // ris | mis | mis-learned: EngineOptions::guiding.mixing, and for
  // mis-learned SDTreeOptions::learn_selection.
  // One-sample MIS with a learned share: per sample it ties RIS on
  // guiding-panel and veach-ajar and costs less (shorter guided paths).
  std::string sampling = "mis-learned";
  // sdtree | vmm: the directional distribution the engine samples.  vmm: a
  // von Mises-Fisher mixture per SD-tree leaf with parallax
  // (guiding/vmm.h); the tree still splits the space and learns the
  // radiance integral and the selection share.
  std::string field = "sdtree";
  float min_roughness = 0.05f;   // EngineOptions::guiding (core/directional_guide.h)
  float defensive = 0.5f;
  // EngineOptions::guiding: the cap on the guide's one-sample-MIS share.  0.75
  // cut the median fixed-spp relMSE (seeds 0-2) by 16% on veach-ajar and 13%
  // on guiding-panel at the same rays (guiding/README.md): a leaf's learned
  // share reaches 0.92-0.98, and the paths its guide missed were fireflies.
  float selection_max = 0.75f;
  bool roulette_correction = true;
  // On veach-ajar the throughput rule ends the dark room's paths before they
  // find the lit patch: adjoint-driven survival halves the per-sample
  // variance of the frozen field's samples for 19% more rays; on
  // guiding-panel it ties, with 6% fewer rays.
  bool adjoint_roulette = true;
  // EngineOptions::guiding: adjoint-driven roulette's least survival
  // probability, in (0, 1].  On veach-ajar (256 spp, 96 of training, seeds
  // 0-2) relMSE x rays fell from 6.6 at 0.1 to 4.0 at 0.5 (3.9 at 0.7, with
  // 17% more rays; 6.6 again at 1, where paths run to the depth limit); on
  // guiding-panel 0.5 ties 0.1.  The engine's default, in one place.
  float roulette_floor = GuidedSampling{}.roulette_floor;
  // The field learns from samples [0, training_spp) of every pixel (a split
  // frame's part: the first training_spp of its range), then is frozen and
  // the recorder detached, so the rest of the render pays for guided
  // sampling alone (0: it learns from every sample).
  int training_spp = 256;
  // With --time-limit, training also ends once this share of the limit has
  // passed: a training sample costs about 1.4x a frozen one (the recorder and
  // the update), so a short budget cannot train for long.  0.4 against 0.25
  // on veach-ajar at 30 s: relMSE lower on each of 6 seeds, median 0.369 of
  // unguided's against 0.430 (0.12: 0.45; 0.6: 0.38, too few samples left).
  float training_share = 0.4f;
  // Once training is over (the field frozen, nothing left to decide), the
  // rest of the render on the regular schedule: guiding's 16-spp iterations
  // pay only while the field learns, and each ends with a drain of the
  // wavefront during which a core idles.
  bool regular_after_training = true;
  // Tests only (--test-guiding-verdict, outside the fingerprint): every
  // --guiding-auto round says "on" or "off", whatever it measured.
  std::string test_verdict;
};

template <class V>
void declare_options(V& v, GuidingOptions& o) {
  v.image("enabled", o.enabled,
          "Path guiding: an SD-tree learned every iteration from the radiance recorder, combined with BSDF "
          "sampling.  --guiding-auto: guiding measures whether it pays (relative variance, robust and with "
          "fireflies, x CPU time per sample of held-out unguided against guided iterations: early in training and "
          "again once it ends) and turns itself off where it does not; once decided (and trained), the rest "
          "renders on the regular schedule");
  v.image("sampling", o.sampling,
          "Guided directions: ris (resampling one BSDF and one guide candidate), mis (one-sample MIS with a fixed "
          "share) or mis-learned (one-sample MIS, the share learned per region)");
  v.image("field", o.field,
          "Guiding field: sdtree (directional quadtrees per spatial leaf) or vmm (a parallax-aware von "
          "Mises-Fisher mixture per spatial leaf)");
  v.image("min_roughness", o.min_roughness, "Guide only where a BSDF lobe is rougher than this");
  v.image("defensive", o.defensive, "RIS: uniform share of the target's radiance estimate, in [0, 1]");
  v.image("selection_max", o.selection_max,
          "One-sample MIS: the guide's share of directions (learned or fixed) at most this, in (0, 1] (1: no cap); "
          "bounds the weight of a path the guide missed by f / ((1 - cap) p_bsdf)");
  v.image("roulette_correction", o.roulette_correction,
          "Guided paths: Russian roulette on the throughput BSDF sampling would have given");
  v.image("adjoint_roulette", o.adjoint_roulette,
          "Guided paths: adjoint-driven Russian roulette (survival from the field's estimate of the continuation's "
          "contribution against the path's pixel estimate)");
  v.image("roulette_floor", o.roulette_floor,
          "Adjoint-driven roulette: a guided continuation survives with at least this probability, in (0, 1]; "
          "bounds the weight roulette adds at a guided vertex by 1 / floor");
  v.image("training_spp", o.training_spp,
          "The field learns from the first this many samples per pixel, then is frozen and the recorder stops "
          "(0: it learns from every sample)");
  v.image("training_share", o.training_share,
          "With --time-limit: the field also stops learning once this share of the limit has passed, in (0, 1]");
  v.image("regular_after_training", o.regular_after_training,
          "Once training is over (and --guiding-auto decided), render the rest on the regular schedule's larger "
          "iterations");
  declare_options(v, static_cast<SDTreeOptions&>(o));
}
void check(const GuidingOptions& o);

// Guiding's efficiency estimate (seeds/000 ch. 2 section 6.3), for
// --guiding-auto, in rounds.  A round renders `length` iterations without the
// guide and without the recorder (held out), then as many guided as the
// render after training is (without recording); each side's efficiency is
// 1 / (per-sample relative variance x CPU seconds per spp), by two variance
// figures (combine.h: relative_variance): the robust one, which one firefly
// does not decide, and the full one, which sees guiding's fireflies as relMSE
// does but from one 16-spp pair swings with a single firefly (veach-ajar,
// 0.37 where the final rounds said 2.9-3.5).  The one-pair early rounds judge
// by the robust figure; the two-pair final round needs both.  CPU time, not
// wall time: another process on the machine does not tilt the verdict.
// - The probe, one pair once the field has learned from a sixteenth of the
//   training budget (8 to 16 spp): it turns guiding off for the rest of the
//   render unless it already comes close to paying (an early field is worse
//   than the one training will end with); if it does, guiding stays on
//   *provisionally* and training goes on.  Early, because where it says no,
//   the training samples so far (each 1.4-2.5x an unguided one) are what
//   deciding cost.
// - The recheck, one pair after an eighth of the budget more (at least 16
//   spp) of training: guiding must nearly pay by now.  A probe passed by luck
//   (veach-mis, seed 1: 0.85) then costs that much training, not the whole
//   budget.  Skipped when training ends first.
// - The final round, two pairs from the iteration where training ends (by
//   its budget or by --guiding-training-share of --time-limit): guiding
//   stays on only if it pays with the field it will keep, by a margin.
struct GuidingVerdict {
  // One side of a round: sums over its iterations.
  struct Side {
    int iterations = 0;
    int64_t spp = 0;
    double cpu_seconds = 0.0, wall_seconds = 0.0;
    double variance = 0.0, variance_full = 0.0;  // per-sample relative variance x spp (unknown: 0)
    void add(const IterationInfo& it);
    double cpu_seconds_per_spp() const { return spp > 0 ? cpu_seconds / double(spp) : 0.0; }
    double per_sample(bool full) const { return spp > 0 ? (full ? variance_full : variance) / double(spp) : 0.0; }
  };
  struct Round {
    int unguided_iteration = -1;  // the first held-out iteration (-1: none planned or none to spare)
    int length = 1;               // iterations per side
    Side unguided, guided;
    // Guided over unguided, by the robust or the full variance; 0 when either side is unknown.
    double efficiency_ratio(bool full = false) const;
    double variance_ratio(bool full = false) const;
    bool measured() const { return guided.iterations == length; }
    // Which side iteration `index` renders: 0 held out, 1 guided, -1 neither.
    int side_of(int index) const;
  };
  Round probe, recheck, final;
  enum State : int32_t { Undecided, On, Off, Provisional } state = Undecided;
};
// What a round must show: guided / unguided efficiency above `threshold`,
// by the robust figure and, with `full`, by the full one too.
struct GuidingRule {
  double threshold = 1.0;
  bool full = false;
};
// The probe must see a clear gain: a scene whose early field only breaks
// even ends near it (cornell-box: probe 1.12-1.13, final rounds 1.15-1.30
// robust, 0.92-1.21 full), and the training on the way, each sample ~1.6-2x
// an unguided one, is then lost.  Where guiding pays in the end the probe
// read 1.77-1.84 (veach-ajar) and 3.3-3.6 (guiding-panel); where it does
// not, 0.74-0.82 (veach-mis), 0.90-0.99 (living-room), 0.92-1.01
// (material-testball), 1.12-1.13 (cornell-box).  (30 s renders, 2026-12-04.)
inline constexpr GuidingRule kProbeRule{1.4, false};
// veach-ajar's recheck: 1.38-1.41 (guiding-panel 4.3; its final rounds 1.26-1.38 robust, 2.05-3.57 full).
inline constexpr GuidingRule kRecheckRule{1.1, false};
// The final verdict holds for the rest of the render, and a pair's CPU-time
// ratio still moves by ~10-20% with the machine's load (other processes'
// cache and memory use): a margin.  living-room's robust figure (1.10, 1.12)
// would keep guiding on; its full one (0.84, 0.83) does not.
inline constexpr GuidingRule kFinalRule{1.1, true};
inline constexpr int kProbeLength = 1, kFinalLength = 2;
// Whether a measured round says guiding pays by `rule` (an unknown figure, as
// from a noiseless image, does not say it loses).
bool guiding_pays(const GuidingVerdict::Round& round, const GuidingRule& rule);
// The first iteration at or after `from_spp` that begins `length` held-out
// iterations followed by `length` judged ones, the first of at least 4 spp and
// the others of at least 2 (the variance needs two samples per pixel).  -1 if
// none.
int guiding_holdout_iteration(const std::vector<int>& schedule, int from_spp, int length = 1);
// The training budget --guiding-auto judges by: never-ending training (0) as the default's.
inline int judged_training_spp(int training_spp) { return training_spp > 0 ? training_spp : 256; }
// The probe's held-out iteration (-1 where the schedule has none).
int guiding_probe_iteration(const std::vector<int>& schedule, int training_spp);
// The recheck's (-1 where the schedule has none or no probe).
int guiding_recheck_iteration(const std::vector<int>& schedule, int training_spp);
// The final round's, for training that ends at `trained_spp` (-1: never; then
// judged at 256 spp) with the render at `now_spp`.
int guiding_final_iteration(const std::vector<int>& schedule, int64_t trained_spp, int now_spp);

// A recorder sample as the SD-tree trains on it: luminance, and a key naming the vertex.
SDTreeSample sd_tree_sample(const TrainingSample& s);

// The SD-tree the engine samples, trained from the recorder's samples after
// every iteration.
class GuidingFeature final : public Feature {
 public:
  // `keep_recorder`: the recorder also feeds debug layers, so it stays
  // attached once training ends.  `first_sample`: where the render's samples
  // begin (a split frame's part learns on its own from there: its training
  // budget counts from it, and `schedule` is its own).
  // `time_limit`: the render's --time-limit (0: none), for training_share.
  GuidingFeature(const GuidingOptions& options, const Bounds3& scene_bounds, const std::vector<int>& schedule,
                 bool keep_recorder, uint32_t first_sample = 0, double time_limit = 0.0);
  ~GuidingFeature() override;
  // Where the recorder hands its training samples; null when off.
  TrainingSampleSink* trainer() const { return trainer_.get(); }
  const SDTree* tree() const { return tree_.get(); }
  // With --guiding-field vmm, what the engine samples (null otherwise).
  const VMMField* vmm() const { return vmm_.get(); }
  void configure(EngineOptions& engine, EngineHooks& hooks) const override;
  void attach(WavefrontEngine& engine) override;
  void add_tasks(IterationTasks& tasks) override;
  void add_participants(std::vector<CheckpointParticipant>& participants) override;
  void write_log(nlohmann::json& log) const override;
  // Once nothing is left to learn (training over; with --guiding-auto also
  // decided for good: off, or on with training over): the regular schedule
  // for the rest of the render (IterationConfig::switch_schedule), as an
  // unguided render has it; none with --no-guiding-regular-after-training.  Guiding's small iterations
  // pay only while the field learns and rounds measure; after that each one
  // costs its fixed work (fold, variance pass, tasks, the wavefront's drain).
  std::optional<ScheduleOptions> schedule_after(const IterationInfo& it) const;
  // The first sample rendered with the frozen field (or, --guiding-auto
  // having said no, unguided): IterationConfig::settled_from.
  std::optional<uint32_t> settled_from() const;

 private:
  // The engine's hooks with or without the guide and the recorder.
  void set_hooks(bool guide, bool record);
  void judge(GuidingVerdict::Round& round);
  const GuidingRule& rule_of(const GuidingVerdict::Round& round) const;
  // The log's guiding.auto: the verdict and every round's figures.
  nlohmann::json auto_log() const;
  // The round an iteration belongs to (held out or judged), if it is being decided now.
  GuidingVerdict::Round* round_of(const IterationInfo& it);
  // Once the probe has passed, plans the final round (from where training
  // ends), which replaces a recheck not yet begun.
  void plan_final_round(const IterationInfo& it);
  // Whether the iteration's samples train the field; once it says no, it
  // never says yes again (a time-limited render may end training early).
  bool trains(const IterationInfo& it);

  GuidingOptions options_;
  std::unique_ptr<SDTree> tree_;
  std::unique_ptr<VMMField> vmm_;
  std::unique_ptr<TrainingSampleSink> trainer_;
  WavefrontEngine* engine_ = nullptr;
  EngineHooks guided_hooks_;
  GuidingVerdict verdict_;
  std::vector<int> schedule_;
  bool keep_recorder_ = false;
  uint32_t first_sample_ = 0;
  double time_limit_ = 0.0;
  // Once training has ended, the samples per pixel the field learned from
  // (its first sample counted from first_sample_); -1 while it learns.
  // Checkpointed: a resumed render keeps the field frozen.
  int64_t trained_spp_ = -1;
  bool training_ = true;  // this iteration's samples train the field
  // Per training iteration: spp_end, the render's wall and CPU seconds, then
  // SDTreeTimes' deltas (the log's guiding.training_iterations).
  std::vector<std::array<double, 10>> training_times_;
  SDTreeTimes logged_times_;  // the tree's times at the last entry
};

// --- Caustics traced from the lights (group "caustics") ---------------------

struct CausticsOptions : CausticOptions {
  bool enabled = true;
};

template <class V>
void declare_options(V& v, CausticsOptions& o) {
  v.image("enabled", o.enabled,
          "Trace directly seen caustics (light -> near-mirror or glass -> diffuse -> camera) from the lights "
          "(off by itself where it finds nothing)");
  declare_options(v, static_cast<CausticOptions&>(o));
}
void check(const CausticsOptions& o);

// On by default; stays off (and says why in the log) where its light paths
// could not be counted or cannot exist.  `off_because` is the reason another
// feature gives (adaptive sampling, recorder debug layers, ...), empty if none.
class CausticsFeature final : public Feature {
 public:
  CausticsFeature(const CausticsOptions& options, std::string off_because, uint32_t seed,
                  const RenderableScene& rs);
  ~CausticsFeature() override;
  void configure(EngineOptions& engine, EngineHooks& hooks) const override;
  void add_participants(std::vector<CheckpointParticipant>& participants) override;
  void write_log(nlohmann::json& log) const override;

 private:
  std::unique_ptr<CausticTracer> tracer_;
  std::string off_because_;
  bool traced_ = false;  // active when the render began (it may switch itself off during it)
};

// --- Adaptive sampling (group "adaptive") -----------------------------------

struct AdaptiveOptions {
  bool enabled = false;
};

template <class V>
void declare_options(V& v, AdaptiveOptions& o) {
  v.image("enabled", o.enabled,
          "Adaptive sampling: --spp is a budget over the frame; alpha keeps --spp samples in every pixel");
}

// The scheduler drives it (its update task and checkpoint section are the
// driver's); the engine counts exactly spp samples per pixel for alpha.
class AdaptiveFeature final : public Feature {
 public:
  AdaptiveFeature(const AdaptiveOptions& options, int width, int height, const std::vector<int>& schedule, int spp);
  ~AdaptiveFeature() override;
  AdaptiveSampler* sampler() const { return sampler_.get(); }
  void configure(EngineOptions& engine, EngineHooks& hooks) const override;

 private:
  std::unique_ptr<AdaptiveSampler> sampler_;
  int spp_;
};

// --- Iterations and checkpoints (groups: none, "iteration", "checkpoint") ---

struct SchedulingOptions {
  std::string schedule;           // regular | guiding; empty: guiding with --guiding, else regular
  std::string combine;            // equal | inverse-variance; empty: combine_name()
  int combine_window = 0;         // spp; 0: every iteration
  bool resume = false;            // fail unless a checkpoint is found
  double time_limit = 0.0;        // seconds of render clock; 0: none (IterationConfig::time_limit)
};

template <class V>
void declare_options(V& v, SchedulingOptions& o) {
  v.image("schedule", o.schedule,
          "Iteration schedule: regular (16 16 32 ... 256) or guiding (1 x8, 2 ... 16); default: guiding with "
          "--guiding, else regular");
  v.image("combine", o.combine,
          "Combining iterations: equal, or inverse-variance (whole-image weights per iteration, "
          "used only where estimated less noisy than equal weights); default: inverse-variance with --guiding "
          "(equal with --sample-range, --aov-events or --recorder-debug), else equal");
  v.image("combine_window", o.combine_window,
          "Inverse-variance weighting: only the iterations in the last this many spp (0: every iteration)");
  v.output("resume", o.resume, "Resume from --checkpoint-dir; fail if there is no checkpoint");
  // Where the render ends, not what a sample is: outside the fingerprint, so
  // a checkpoint resumes with another limit or none.
  v.output("time_limit", o.time_limit,
           "Stop after this many seconds of rendering (wall clock from the end of scene loading: acceleration "
           "build included), finish the paths in flight and write the image with every sample so far; exit 0. "
           "With --spp the render ends at whichever comes first (0: no limit)");
}
void check(const SchedulingOptions& o);

// Overrides of the named schedule's ScheduleOptions, field by field (-1: keep).
struct IterationOptions {
  int first = -1;
  int repeat = -1;
  double growth = -1.0;
  int max = -1;
};

template <class V>
void declare_options(V& v, IterationOptions& o) {
  v.image("first", o.first, "First iteration size in spp (default: the schedule's)");
  v.image("repeat", o.repeat, "Iterations of the first size (default: the schedule's)");
  v.image("growth", o.growth, "Growth factor of iteration sizes (default: the schedule's)");
  v.image("max", o.max, "Largest iteration size in spp (default: the schedule's)");
}

void check(const CheckpointOptions& o);

// Guiding learns between iterations, so it wants its small early iterations.
std::string schedule_name(const SchedulingOptions& o, bool guiding);
// --combine's default: a guided render's early iterations sample from a field
// still learning, so weighting them by their noise pays; a split frame's parts,
// the event layers and the recorder's debug layers need the equal-weight sums.
std::string combine_name(const SchedulingOptions& o, bool guiding, bool equal_sums_needed);
ScheduleOptions schedule_options(const std::string& name, const IterationOptions& overrides);

}  // namespace theia
