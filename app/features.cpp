#include "app/features.h"

#include "cachepoints/light_sampler.h"
#include "core/hash.h"
#include "core/huge_pages.h"
#include "core/log.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace theia {

// --- Light sampler ----------------------------------------------------------

void check(const LightSamplerOptions& o) {
  if (!light_sampler_name_known(o.light_sampler))
    throw_error("--light-sampler {}: expected uniform, power, bvh, cachepoints, local or auto", o.light_sampler);
}

void LightSamplerFeature::add_tasks(IterationTasks& tasks) {
  if (sampler_.wants_feedback())
    tasks.add(BetweenIterationSlot::CachePointUpdate, [this](const IterationInfo&) { sampler_.update(); });
}

void LightSamplerFeature::add_participants(std::vector<CheckpointParticipant>& participants) {
  if (!sampler_.wants_feedback()) return;
  participants.push_back({"light-sampler", 1, [this] { return sampler_.save_state(); },
                          [this](const CheckpointSection& section) { sampler_.restore(section.bytes); }});
}

void LightSamplerFeature::write_log(nlohmann::json& log) const {
  nlohmann::json& j = log["light_sampler"];
  j["name"] = sampler_.name();
  for (const auto& [key, value] : sampler_.statistics()) j[key] = value;
}

// --- Radiance recorder ------------------------------------------------------

void check(const RecorderOptions& o) {
  if (o.debug_bounce < -1) throw_error("--recorder-debug-bounce must be zero or positive, got {}", o.debug_bounce);
  if (!(o.vertex_budget >= 0.0f))
    throw_error("--recorder-vertex-budget must be zero (off) or positive, got {}", o.vertex_budget);
  if (!(o.vertex_skip_probability >= 0.0f && o.vertex_skip_probability < 1.0f))
    throw_error("--recorder-vertex-skip-probability must be in [0, 1), got {}", o.vertex_skip_probability);
  if (!(o.medium_skip_probability >= 0.0f && o.medium_skip_probability < 1.0f))
    throw_error("--recorder-medium-skip-probability must be in [0, 1), got {}", o.medium_skip_probability);
  if (!(o.min_distance >= 0.0f))
    throw_error("--recorder-min-distance must be zero or positive, got {}", o.min_distance);
  parse_training_mode(o.training);
}

RecorderFeature::RecorderFeature(const RecorderOptions& options, bool guiding, uint32_t seed, int width, int height,
                                 TrainingSampleSink* sink)
    : options_(options) {
  if (!guiding && !debug_layers(options)) return;
  options_.seed = seed;
  options_.width = width;
  options_.height = height;
  recorder_ = std::make_unique<RadianceRecorder>(options_, sink);
}

void RecorderFeature::add_tasks(IterationTasks& tasks) {
  if (!recorder_) return;
  tasks.on_begin([this](const IterationInfo&) { recorder_->begin_iteration(); });
  tasks.on_end([this](const IterationInfo& it) {
    const RecorderStats before = recorder_->stats();
    recorder_->end_iteration();
    const RecorderStats after = recorder_->stats();
    iteration_times_.push_back({double(it.spp_end), double(after.samples - before.samples),
                                after.sort_seconds - before.sort_seconds,
                                after.consume_seconds - before.consume_seconds});
  });
  tasks.add(BetweenIterationSlot::RecorderSkipRateUpdate, [this](const IterationInfo&) { recorder_->update_skip_rate(); });
}

// A resumed render continues the skip rate and an interrupted iteration's
// training samples exactly where the interrupted one left them, so it trains
// the same.  (Debug layers are not checkpointed: check_config refuses them
// with --checkpoint-dir.)
void RecorderFeature::add_participants(std::vector<CheckpointParticipant>& participants) {
  if (!recorder_) return;
  participants.push_back({"recorder", 1,
                          [this] {
                            ByteWriter w;
                            RadianceRecorder::ResumeState st = recorder_->resume_state();
                            w.put(st.skip_rate);
                            w.put(st.iteration_paths);
                            w.put(st.iteration_events);
                            w.put_vector(st.samples);
                            return w.bytes;
                          },
                          [this](const CheckpointSection& section) {
                            ByteReader r(section.bytes, "checkpoint section 'recorder'");
                            RadianceRecorder::ResumeState st;
                            st.skip_rate = r.get<double>();
                            st.iteration_paths = r.get<uint64_t>();
                            st.iteration_events = r.get<uint64_t>();
                            st.samples = r.get_vector<TrainingSample>();
                            recorder_->restore(st);
                          }});
}

std::vector<FilmLayer> RecorderFeature::layers() const {
  std::vector<FilmLayer> layers;
  if (recorder_ && options_.debug) layers.push_back({"recorder", recorder_->debug_primary()});
  if (recorder_ && options_.debug_bounce >= 0)
    layers.push_back({fmt::format("recorder_bounce{}", options_.debug_bounce), recorder_->debug_bounce()});
  return layers;
}

void RecorderFeature::write_log(nlohmann::json& log) const {
  if (!recorder_) return;
  RecorderStats rs = recorder_->stats();
  log["recorder"] = {{"vertex_bytes", RadianceRecorder::vertex_bytes()},
                     {"peak_live_vertices", rs.peak_live_vertices},
                     {"peak_bytes", recorder_->peak_bytes()},
                     {"blocks", rs.peak_blocks},
                     {"paths", rs.paths},
                     {"skipped_paths", rs.skipped_paths},
                     {"path_skip_rate", rs.path_skip_rate},
                     {"vertex_events", rs.vertex_events},
                     {"recorded_vertices", rs.recorded},
                     {"skipped_vertices", rs.skipped_vertices},
                     {"merged_vertices", rs.merged_vertices},
                     {"untrainable_vertices", rs.untrainable},
                     {"untrainable_merged", rs.untrainable_merged},
                     {"samples", rs.samples},
                     {"sort_seconds", rs.sort_seconds},
                     {"consume_seconds", rs.consume_seconds},
                     {"dropped", rs.dropped},
                     {"iterations_columns", {"spp_end", "samples", "sort_seconds", "consume_seconds"}},
                     {"iterations", iteration_times_}};
  log["memory"]["recorder"] = recorder_->peak_bytes();
}

// --- Path guiding -----------------------------------------------------------

void check(const GuidingOptions& o) {
  if (!(o.selection_probability >= 0.0f && o.selection_probability < 1.0f))
    throw_error("--guiding-selection-probability must be in [0, 1) (the BSDF must keep some share, or directions "
                "the guide has not learned would never be sampled), got {}",
                o.selection_probability);
  if (!(o.min_roughness >= 0.0f))
    throw_error("--guiding-min-roughness must be zero or positive, got {}", o.min_roughness);
  if (o.sampling != "ris" && o.sampling != "mis" && o.sampling != "mis-learned")
    throw_error("--guiding-sampling {}: expected ris, mis or mis-learned", o.sampling);
  if (o.field != "sdtree" && o.field != "vmm")
    throw_error("--guiding-field {}: expected sdtree or vmm", o.field);
  if (o.sampling == "mis-learned" && !(o.selection_probability > 0.0f))
    throw_error("--guiding-sampling mis-learned starts from --guiding-selection-probability, which must then be above 0");
  if (!(o.selection_max > 0.0f && o.selection_max <= 1.0f))
    throw_error("--guiding-selection-max must be in (0, 1] (1: no cap), got {}", o.selection_max);
  // The cap applies to a fixed share too: refuse a fixed one above it rather than change it silently.
  if (o.sampling == "mis" && o.selection_probability > o.selection_max)
    throw_error("--guiding-sampling mis takes --guiding-selection-probability {} as the guide's share, above "
                "--guiding-selection-max {}: raise the cap (1: none)",
                o.selection_probability, o.selection_max);
  if (!(o.roulette_floor > 0.0f && o.roulette_floor <= 1.0f))
    throw_error("--guiding-roulette-floor must be in (0, 1] (1: no adjoint-driven roulette at guided vertices), got {}",
                o.roulette_floor);
  if (!(o.defensive >= 0.0f && o.defensive <= 1.0f))
    throw_error("--guiding-defensive must be in [0, 1], got {}", o.defensive);
  if (!(o.split_decay > 0.0 && o.split_decay <= 0.5))
    throw_error("--guiding-split-decay must be in (0, 0.5] (above, a busy leaf's halves could split forever), got {}",
                o.split_decay);
  if (!(o.pdf_floor >= 0.0f) || !std::isfinite(o.pdf_floor))
    throw_error("--guiding-pdf-floor must be zero or positive, got {}", o.pdf_floor);
  if (!(o.spatial_threshold > 0.0 && std::isfinite(o.spatial_threshold)))
    throw_error("--guiding-spatial-threshold must be positive, got {}", o.spatial_threshold);
  if (o.training_spp < 0)
    throw_error("--guiding-training-spp must be zero (learn from every sample) or positive, got {}", o.training_spp);
  if (!(o.training_share > 0.0f && o.training_share <= 1.0f))
    throw_error("--guiding-training-share must be in (0, 1], got {}", o.training_share);
}

namespace {

// The recorder's training samples, as the SD-tree takes them: scalar
// (luminance) radiance.  The recorder sends only directions that had a
// density at guidable BSDFs (a delta lobe's sample says nothing about a
// directional distribution), and no NEE rays: what NEE samples is the light
// it already finds, and the BSDF-sampled vertices carry its MIS-weighted
// share (seeds/001 section 10.7, seeds/000 ch. 1 eq. 23).  The key names the
// vertex, so the field's spatial jitter is a function of the path.
class SDTreeTrainer final : public TrainingSampleSink {
 public:
  // `training`: false once the field is frozen (a recorder kept for its
  // debug layers still hands samples over).  `vmm`: also trains it (null: off).
  SDTreeTrainer(SDTree& tree, VMMField* vmm, const bool& training) : tree_(tree), vmm_(vmm), training_(training) {}
  bool wants_nee_samples() const override { return false; }
  void consume(std::span<const TrainingSample> samples) override {
    if (!training_) {
      if (!converted_.empty()) converted_ = {}, vmm_samples_ = {}, tree_.release_training_buffers();
      return;
    }
    // Each sample converted once, into a buffer kept across iterations.
    reserve_huge(converted_, samples.size());
    if (converted_.size() < samples.size()) converted_.resize(samples.size());
    if (vmm_) reserve_huge(vmm_samples_, samples.size());
    if (vmm_ && vmm_samples_.size() < samples.size()) vmm_samples_.resize(samples.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, samples.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) {
        converted_[i] = sd_tree_sample(samples[i]);
        if (vmm_) vmm_samples_[i] = vmm_sample(samples, i);
      }
    });
    tree_.add_samples(std::span(converted_).first(samples.size()));
    if (vmm_) vmm_->add_samples(std::span(vmm_samples_).first(samples.size()));
  }

 private:
  // The source distance of sample i is how far its ray went: to the next
  // vertex of its path, the sample one depth further (samples come sorted by
  // pixel, sample, depth).  Unknown (0) where that vertex made no sample (it
  // was skipped, merged or could not train, or the ray escaped or ended the path).
  static VMMSample vmm_sample(std::span<const TrainingSample> samples, size_t i) {
    const TrainingSample& s = samples[i];
    VMMSample v{s.p, s.wi, luminance(s.radiance), s.pdf, 0.0f};
    for (size_t j = i + 1; j < samples.size(); ++j) {
      const TrainingSample& c = samples[j];
      if (c.pixel != s.pixel || c.sample != s.sample || c.depth > s.depth + 1) break;
      if (c.depth == s.depth + 1) {
        v.distance = glm::distance(c.p, s.p);
        break;
      }
    }
    return v;
  }

  SDTree& tree_;
  VMMField* vmm_;
  const bool& training_;
  std::vector<SDTreeSample> converted_;
  std::vector<VMMSample> vmm_samples_;
};

}  // namespace

SDTreeSample sd_tree_sample(const TrainingSample& s) {
  const float radiance = luminance(s.radiance);
  return {s.p,
          s.wi,
          radiance,
          s.pdf,
          hash(s.pixel, s.sample, s.depth, s.flags),
          radiance * s.scattering_weight,
          s.bsdf_ratio,
          s.guide_ratio};
}

int guiding_holdout_iteration(const std::vector<int>& schedule, int from_spp, int length) {
  const size_t n = size_t(2 * length);
  int begin = 0;
  for (size_t i = 0; i + n <= schedule.size(); begin += schedule[i], ++i) {
    if (begin < from_spp || schedule[i] < 4) continue;
    bool fits = true;
    for (size_t k = 1; k < n; ++k) fits = fits && schedule[i + k] >= 2;
    if (fits) return int(i);
  }
  return -1;
}


int guiding_probe_iteration(const std::vector<int>& schedule, int training_spp) {
  return guiding_holdout_iteration(schedule, std::clamp(judged_training_spp(training_spp) / 16, 8, 16),
                                   kProbeLength);
}

int guiding_recheck_iteration(const std::vector<int>& schedule, int training_spp) {
  const int probe = guiding_probe_iteration(schedule, training_spp);
  if (probe < 0) return -1;
  int after_probe = 0;  // where the probe's pair ends
  for (int i = 0; i < probe + 2 * kProbeLength; ++i) after_probe += schedule[size_t(i)];
  return guiding_holdout_iteration(schedule, after_probe + std::max(judged_training_spp(training_spp) / 8, 16), 1);
}

int guiding_final_iteration(const std::vector<int>& schedule, int64_t trained_spp, int now_spp) {
  const int64_t from = std::max<int64_t>(trained_spp >= 0 ? trained_spp : judged_training_spp(0), now_spp);
  return from > std::numeric_limits<int>::max() ? -1 : guiding_holdout_iteration(schedule, int(from), kFinalLength);
}

void GuidingVerdict::Side::add(const IterationInfo& it) {
  const int64_t n = int64_t(it.spp_end - it.spp_begin);
  ++iterations;
  spp += n;
  cpu_seconds += it.cpu_seconds;
  wall_seconds += it.seconds;
  variance += std::max(it.sample_variance, 0.0) * double(n);
  variance_full += std::max(it.sample_variance_full, 0.0) * double(n);
}

double GuidingVerdict::Round::efficiency_ratio(bool full) const {
  const double u = unguided.per_sample(full) * unguided.cpu_seconds_per_spp();
  const double g = guided.per_sample(full) * guided.cpu_seconds_per_spp();
  return u > 0.0 && g > 0.0 ? u / g : 0.0;
}

double GuidingVerdict::Round::variance_ratio(bool full) const {
  const double u = unguided.per_sample(full), g = guided.per_sample(full);
  return u > 0.0 && g > 0.0 ? g / u : 0.0;
}

int GuidingVerdict::Round::side_of(int index) const {
  if (unguided_iteration < 0 || index < unguided_iteration) return -1;
  const int k = index - unguided_iteration;
  return k < length ? 0 : k < 2 * length ? 1 : -1;
}

bool guiding_pays(const GuidingVerdict::Round& round, const GuidingRule& rule) {
  for (bool full : {false, true}) {
    const double e = round.efficiency_ratio(full);
    if ((!full || rule.full) && e != 0.0 && !(e > rule.threshold)) return false;
  }
  return true;
}

GuidingFeature::GuidingFeature(const GuidingOptions& options, const Bounds3& scene_bounds,
                               const std::vector<int>& schedule, bool keep_recorder, uint32_t first_sample,
                               double time_limit)
    : options_(options), keep_recorder_(keep_recorder), first_sample_(first_sample), time_limit_(time_limit) {
  if (!options.on()) return;
  SDTreeOptions tree = options;
  tree.learn_selection = options.sampling == "mis-learned";
  tree_ = std::make_unique<SDTree>(scene_bounds, tree);
  if (options.field == "vmm") {
    VMMOptions vo;
    vo.pdf_floor = options.pdf_floor;
    vo.split_decay = options.split_decay;
    vmm_ = std::make_unique<VMMField>(*tree_, vo);
  }
  trainer_ = std::make_unique<SDTreeTrainer>(*tree_, vmm_.get(), training_);
  if (options.judged()) {
    schedule_ = schedule;
    verdict_.probe.length = kProbeLength;
    verdict_.final.length = kFinalLength;
    verdict_.probe.unguided_iteration = guiding_probe_iteration(schedule, options.training_spp);
    verdict_.recheck.unguided_iteration = guiding_recheck_iteration(schedule, options.training_spp);
  }
}

GuidingFeature::~GuidingFeature() = default;

namespace {
constexpr float kTrainingPoolShare = 0.25f;
}  // namespace

void GuidingFeature::configure(EngineOptions& engine, EngineHooks& hooks) const {
  if (!tree_) return;
  hooks.guide = vmm_ ? static_cast<const DirectionalGuide*>(vmm_.get()) : tree_.get();
  engine.guiding.mixing = options_.sampling == "ris" ? GuideMixing::Resampled : GuideMixing::OneSampleMIS;
  engine.guiding.min_roughness = options_.min_roughness;
  engine.guiding.defensive = options_.defensive;
  engine.guiding.selection_max = options_.selection_max;
  engine.guiding.roulette_correction = options_.roulette_correction;
  engine.guiding.adjoint_roulette = options_.adjoint_roulette;
  engine.guiding.roulette_floor = options_.roulette_floor;
  // Training iterations keep a quarter of the pool's paths in flight (on
  // veach-ajar the frame's pixel count): the recorder's vertices stay warmer.
  hooks.observed_pool_share = kTrainingPoolShare;
}

void GuidingFeature::attach(WavefrontEngine& engine) {
  engine_ = &engine;
  guided_hooks_ = engine.hooks();
}

// Without the guide the render pays for neither it nor the recorder, which
// exists for guiding alone unless it also feeds debug layers.
void GuidingFeature::set_hooks(bool guide, bool record) {
  training_ = guide && record;
  EngineHooks h = guided_hooks_;
  if (!guide) h.guide = nullptr;
  if (!training_ && !keep_recorder_) h.observer = nullptr;
  engine_->set_hooks(h);
}

bool GuidingFeature::trains(const IterationInfo& it) {
  // --guiding-auto turned guiding off: nothing learns from here on.
  if (verdict_.state == GuidingVerdict::Off && trained_spp_ < 0) trained_spp_ = it.spp_begin - first_sample_;
  const bool budget_spent =
      options_.training_spp != 0 && it.spp_begin - first_sample_ >= uint32_t(options_.training_spp);
  const bool time_spent = time_limit_ > 0.0 && it.elapsed_seconds >= double(options_.training_share) * time_limit_;
  if ((budget_spent || time_spent) && trained_spp_ < 0) {
    trained_spp_ = it.spp_begin - first_sample_;
    if (time_spent && !budget_spent)
      log_info("guiding: training ends at {} spp, {:.3g} s into the render ({:.3g} of --time-limit)", trained_spp_,
               it.elapsed_seconds, options_.training_share);
  }
  return trained_spp_ < 0;
}

GuidingVerdict::Round* GuidingFeature::round_of(const IterationInfo& it) {
  for (GuidingVerdict::Round* r : {&verdict_.probe, &verdict_.recheck, &verdict_.final}) {
    const bool deciding = r == &verdict_.probe ? verdict_.state == GuidingVerdict::Undecided
                                               : verdict_.state == GuidingVerdict::Provisional;
    if (deciding && !r->measured() && r->side_of(it.index) >= 0) return r;
  }
  return nullptr;
}

void GuidingFeature::plan_final_round(const IterationInfo& it) {
  if (verdict_.state != GuidingVerdict::Provisional || verdict_.final.unguided_iteration >= 0) return;
  // Training that still goes on (budget and time left) is judged once it ends.
  if (trained_spp_ < 0 && options_.training_spp != 0) return;
  GuidingVerdict::Round& recheck = verdict_.recheck;
  if (recheck.unguided_iteration >= 0 && !recheck.measured()) {
    if (recheck.unguided.iterations > 0) return;  // under way: the final round comes after it
    recheck.unguided_iteration = -1;              // not begun: the final round judges now
  }
  verdict_.final.unguided_iteration =
      guiding_final_iteration(schedule_, trained_spp_, int(it.spp_begin - first_sample_));
}

const GuidingRule& GuidingFeature::rule_of(const GuidingVerdict::Round& round) const {
  return &round == &verdict_.probe ? kProbeRule : &round == &verdict_.recheck ? kRecheckRule : kFinalRule;
}

void GuidingFeature::judge(GuidingVerdict::Round& round) {
  const bool is_final = &round == &verdict_.final;
  const char* name = &round == &verdict_.probe ? "probe" : is_final ? "final" : "recheck";
  const bool pays =
      options_.test_verdict.empty() ? guiding_pays(round, rule_of(round)) : options_.test_verdict == "on";
  verdict_.state = !pays ? GuidingVerdict::Off : is_final ? GuidingVerdict::On : GuidingVerdict::Provisional;
  static const char* kSays[] = {"", "guiding stays on", "guiding off for the rest of the render",
                                "guiding and training go on, to be judged again once training ends"};
  log_info("guiding ({} round): guided / unguided efficiency {:.3g} robust, {:.3g} full (per-sample variance {:.3g}, "
           "{:.3g}; CPU s/spp {:.3g}): {}",
           name, round.efficiency_ratio(false), round.efficiency_ratio(true),
           round.variance_ratio(false), round.variance_ratio(true),
           round.guided.cpu_seconds_per_spp() / std::max(round.unguided.cpu_seconds_per_spp(), 1e-300),
           kSays[verdict_.state]);
}

std::optional<uint32_t> GuidingFeature::settled_from() const {
  if (trained_spp_ < 0) return std::nullopt;
  return first_sample_ + uint32_t(trained_spp_);
}

std::optional<ScheduleOptions> GuidingFeature::schedule_after(const IterationInfo&) const {
  if (!tree_ || !options_.regular_after_training) return std::nullopt;
  const bool done = options_.judged() ? verdict_.state == GuidingVerdict::Off ||
                                            (verdict_.state == GuidingVerdict::On && trained_spp_ >= 0)
                                      : trained_spp_ >= 0;
  if (!done) return std::nullopt;
  return regular_schedule();
}

// The field learns from each training iteration's samples (handed over by
// the recorder at the iteration's end); the next iteration samples it.  With
// --guiding-auto each round's held-out iterations (no guide, no recorder) are
// judged against the ones after them, guided as the render after training
// will be: by the field without recording, unless training never ends.
void GuidingFeature::add_tasks(IterationTasks& tasks) {
  if (!tree_) return;
  const bool judging = options_.judged() && verdict_.probe.unguided_iteration >= 0;
  if (judging) tasks.measure_variance();
  tasks.on_begin([this](const IterationInfo& it) {
    const bool train = trains(it);
    plan_final_round(it);
    const GuidingVerdict::Round* round = round_of(it);
    const int side = round ? round->side_of(it.index) : -1;  // 0 held out, 1 judged
    const bool guide = verdict_.state != GuidingVerdict::Off && side != 0;
    set_hooks(guide, train && side != 0 && !(side == 1 && options_.training_spp != 0));
  });
  if (judging) {
    tasks.on_end([this](const IterationInfo& it) {
      GuidingVerdict::Round* round = round_of(it);
      if (!round) return;
      const int side = round->side_of(it.index);
      (side == 0 ? round->unguided : round->guided).add(it);
      if (round->measured()) judge(*round);
    });
  }
  tasks.add(BetweenIterationSlot::GuidingUpdate, [this](const IterationInfo& it) {
    if (!training_) return;
    const SDTreeTimes before = logged_times_;
    tree_->update();
    if (vmm_) vmm_->update();
    const SDTreeTimes& t = tree_->times();
    training_times_.push_back({double(it.spp_end), it.seconds, it.cpu_seconds, t.classify - before.classify,
                               t.order - before.order, t.deposit - before.deposit, t.copy - before.copy,
                               t.split - before.split, t.refine - before.refine, t.index - before.index});
    logged_times_ = t;
  });
}

namespace {

void put_side(ByteWriter& w, const GuidingVerdict::Side& s) {
  w.put(int32_t(s.iterations));
  w.put(s.spp);
  w.put(s.cpu_seconds);
  w.put(s.wall_seconds);
  w.put(s.variance);
  w.put(s.variance_full);
}

void get_side(ByteReader& r, GuidingVerdict::Side& s) {
  s.iterations = r.get<int32_t>();
  s.spp = r.get<int64_t>();
  s.cpu_seconds = r.get<double>();
  s.wall_seconds = r.get<double>();
  s.variance = r.get<double>();
  s.variance_full = r.get<double>();
}

}  // namespace

// A resumed render continues the field (and guiding-auto's verdict, with a
// round's partial sums and the final round's plan) where the interrupted one
// left it, so it guides the same.
void GuidingFeature::add_participants(std::vector<CheckpointParticipant>& participants) {
  if (!tree_) return;
  participants.push_back({"guiding", 6,
                          [this] {
                            ByteWriter w;
                            w.put_vector(tree_->serialize());
                            w.put(int32_t(verdict_.state));
                            for (const GuidingVerdict::Round* round :
                                 {&verdict_.probe, &verdict_.recheck, &verdict_.final}) {
                              w.put(int32_t(round->unguided_iteration));
                              put_side(w, round->unguided);
                              put_side(w, round->guided);
                            }
                            w.put(trained_spp_);
                            return w.bytes;
                          },
                          [this](const CheckpointSection& section) {
                            if (section.version != 6)
                              throw_error("checkpoint section 'guiding' has version {}, this build reads 6",
                                          section.version);
                            ByteReader r(section.bytes, "checkpoint section 'guiding'");
                            std::vector<uint8_t> tree = r.get_vector<uint8_t>();
                            *tree_ = SDTree::deserialize(tree);
                            const int32_t state = r.get<int32_t>();
                            if (state < GuidingVerdict::Undecided || state > GuidingVerdict::Provisional)
                              throw_error("checkpoint section 'guiding': verdict {} is not one of 0 .. 3", state);
                            verdict_.state = GuidingVerdict::State(state);
                            for (GuidingVerdict::Round* round :
                                 {&verdict_.probe, &verdict_.recheck, &verdict_.final}) {
                              round->unguided_iteration = r.get<int32_t>();
                              get_side(r, round->unguided);
                              get_side(r, round->guided);
                            }
                            trained_spp_ = r.get<int64_t>();
                          }});
  // The mixture in a section of its own (an SD-tree render's checkpoint is
  // unchanged), restored after 'guiding': its regions are the tree's leaves.
  if (vmm_)
    participants.push_back({"guiding-vmm", 1, [this] { return vmm_->serialize(); },
                            [this](const CheckpointSection& section) {
                              const std::string what = "checkpoint section 'guiding-vmm'";
                              if (section.version != 1)
                                throw_error("{} has version {}, this build reads 1", what, section.version);
                              vmm_->restore(section.bytes, what);
                            }});
}

namespace {

// The mixture's summary: per fitted region, lobes of weight >= kVMMActiveWeight and their concentrations.
nlohmann::json vmm_log(const VMMField& vmm) {
  size_t fitted = 0;
  double active_sum = 0.0, kappa_mean = 0.0, kappa_max = 0.0;
  int active_min = kVMMLobes, active_max = 0;
  for (uint32_t l = 0; l < vmm.region_count(); ++l) {
    const VMMRegion& r = vmm.region_state(l);
    if (!r.fitted) continue;
    const VMMSummary s = vmm_summary(r.mixture);
    ++fitted, active_sum += s.active_lobes, kappa_mean += s.kappa_mean;
    active_min = std::min(active_min, s.active_lobes), active_max = std::max(active_max, s.active_lobes);
    kappa_max = std::max(kappa_max, double(s.kappa_max));
  }
  const double n = std::max<double>(double(fitted), 1.0);
  return {{"regions", vmm.region_count()},
          {"lobes", kVMMLobes},
          {"fitted_regions", fitted},
          {"active_lobes", {{"min", fitted ? active_min : 0}, {"mean", active_sum / n}, {"max", active_max}}},
          {"kappa", {{"mean", kappa_mean / n}, {"max", kappa_max}}},
          {"fit_seconds", vmm.fit_seconds()},
          {"bytes", vmm.memory_bytes()}};
}

// The learned share of guided directions over the leaves that guide (as
// learned: the engine takes at most `cap` of it), and how many leaves the cap cuts.
nlohmann::json selection_log(const SDTree& tree, float cap) {
  double lo = 1.0, hi = 0.0, sum = 0.0;
  size_t n = 0, capped = 0;
  for (size_t l = 0; l < tree.leaf_count(); ++l) {
    const SpatialLeaf& leaf = tree.leaf(uint32_t(l));
    if (!leaf.has_energy) continue;
    lo = std::min(lo, double(leaf.selection)), hi = std::max(hi, double(leaf.selection));
    sum += leaf.selection, ++n;
    capped += leaf.selection > cap;
  }
  return {{"mean", n ? sum / double(n) : 0.0},
          {"min", n ? lo : 0.0},
          {"max", n ? hi : 0.0},
          {"cap", cap},
          {"capped_leaves", capped}};
}

}  // namespace

nlohmann::json GuidingFeature::auto_log() const {
  static const char* kStates[] = {"undecided", "on", "off", "provisional"};
  auto side_log = [](const GuidingVerdict::Side& s) {
    return nlohmann::json{{"iterations", s.iterations},
                          {"spp", s.spp},
                          {"variance", s.per_sample(false)},
                          {"variance_full", s.per_sample(true)},
                          {"cpu_seconds_per_spp", s.cpu_seconds_per_spp()},
                          {"wall_seconds_per_spp", s.spp > 0 ? s.wall_seconds / double(s.spp) : 0.0}};
  };
  auto round_log = [&](const GuidingVerdict::Round& r) {
    const GuidingRule& rule = rule_of(r);
    return nlohmann::json{{"unguided_iteration", r.unguided_iteration},
                          {"length", r.length},
                          {"measured", r.measured()},
                          {"unguided", side_log(r.unguided)},
                          {"guided", side_log(r.guided)},
                          // Guided / unguided; guiding pays if the robust figure, and with
                          // the rule's "full" the full one too, exceed the threshold.
                          {"efficiency_ratio", r.efficiency_ratio(false)},
                          {"efficiency_ratio_full", r.efficiency_ratio(true)},
                          {"variance_ratio", r.variance_ratio(false)},
                          {"variance_ratio_full", r.variance_ratio(true)},
                          {"threshold", rule.threshold},
                          {"full", rule.full},
                          {"pays", r.measured() && guiding_pays(r, rule)}};
  };
  return {{"verdict", kStates[verdict_.state]},
          {"probe", round_log(verdict_.probe)},
          {"recheck", round_log(verdict_.recheck)},
          {"final", round_log(verdict_.final)}};
}

void GuidingFeature::write_log(nlohmann::json& log) const {
  if (!tree_) return;
  SDTreeStats gs = tree_->stats();
  log["guiding"] = {{"spatial_leaves", gs.spatial_leaves},
                    {"quadtree_nodes", gs.quadtree_nodes},
                    {"bytes", tree_->memory_bytes()},
                    // The iterations that trained it (one update each) and the budget that ended training.
                    {"updates", gs.updates},
                    {"training_spp", options_.training_spp},
                    // What it learned from (-1: training never ended).
                    {"trained_spp", trained_spp_},
                    // Guide directions the BSDF did not scatter into (wasted draws).
                    {"draw_failures", gs.draw_failures},
                    // Where training's time went, per iteration (wall seconds; the samples
                    // were deposited at the iteration's end, the update after it).
                    {"training_iterations_columns",
                     {"spp_end", "render_seconds", "render_cpu_seconds", "classify", "order", "deposit", "copy",
                      "split", "refine", "index"}},
                    {"training_iterations", training_times_}};
  log["guiding"]["field"] = options_.field;
  if (vmm_) log["guiding"]["vmm"] = vmm_log(*vmm_);
  if (tree_->options().learn_selection) log["guiding"]["selection"] = selection_log(*tree_, options_.selection_max);
  if (options_.judged()) log["guiding"]["auto"] = auto_log();
  log["memory"]["guiding"] = tree_->memory_bytes() + (vmm_ ? vmm_->memory_bytes() : 0);
}

// --- Caustics ---------------------------------------------------------------

void check(const CausticsOptions& o) {
  if (!(o.caster_roughness >= 0.0f && o.caster_roughness <= 1.0f))
    throw_error("--caustics-caster-roughness must be in [0, 1], got {}", o.caster_roughness);
}

CausticsFeature::CausticsFeature(const CausticsOptions& options, std::string off_because, uint32_t seed,
                                 const RenderableScene& rs)
    : off_because_(options.enabled ? std::move(off_because) : "--no-caustics") {
  if (!off_because_.empty()) return;
  CausticOptions co = options;
  co.seed = seed;
  tracer_ = std::make_unique<CausticTracer>(rs.scene, rs.accel, rs.lights, rs.camera, rs.filter, co);
  off_because_ = tracer_->inactive_reason();
  traced_ = tracer_->active();
}

CausticsFeature::~CausticsFeature() = default;

void CausticsFeature::configure(EngineOptions&, EngineHooks& hooks) const {
  if (traced_) hooks.caustics = tracer_.get();
}

// The pass's switch-off counters survive a resume, so a resumed render
// switches it off (or not) where an uninterrupted one does.
void CausticsFeature::add_participants(std::vector<CheckpointParticipant>& participants) {
  if (!traced_) return;
  participants.push_back({"caustics", 1,
                          [this] {
                            ByteWriter w;
                            w.put(tracer_->stats());
                            w.put(int32_t(tracer_->passes()));
                            return w.bytes;
                          },
                          [this](const CheckpointSection& section) {
                            ByteReader r(section.bytes, "checkpoint section 'caustics'");
                            CausticStats cs = r.get<CausticStats>();
                            int passes = r.get<int32_t>();
                            tracer_->restore_stats(cs, passes);
                          }});
}

void CausticsFeature::write_log(nlohmann::json& log) const {
  CausticStats cs = tracer_ ? tracer_->stats() : CausticStats{};
  log["caustics"] = {{"traced", traced_},
                     {"off_because", off_because_},
                     {"switched_off_after_passes", cs.switched_off_after},
                     {"paths", cs.paths},
                     {"caster_hits", cs.caster_hits},
                     {"receiver_hits", cs.receiver_hits},
                     {"splats", cs.splats},
                     {"dropped", cs.dropped},
                     {"seconds", cs.seconds}};
}

// --- Adaptive sampling ------------------------------------------------------

AdaptiveFeature::AdaptiveFeature(const AdaptiveOptions& options, int width, int height,
                                 const std::vector<int>& schedule, int spp)
    : spp_(spp) {
  if (options.enabled) sampler_ = std::make_unique<AdaptiveSampler>(width, height, schedule, uint32_t(spp));
}

AdaptiveFeature::~AdaptiveFeature() = default;

// Consistent alpha: with adaptive sampling alpha counts exactly spp samples per pixel.
void AdaptiveFeature::configure(EngineOptions& engine, EngineHooks&) const {
  if (sampler_) engine.alpha_spp = uint32_t(spp_);
}

// --- Iterations and checkpoints ---------------------------------------------

void check(const SchedulingOptions& o) {
  if (!o.schedule.empty() && o.schedule != "regular" && o.schedule != "guiding")
    throw_error("--schedule {}: expected regular or guiding", o.schedule);
  if (!o.combine.empty() && o.combine != "equal" && o.combine != "inverse-variance")
    throw_error("--combine {}: expected equal or inverse-variance", o.combine);
  if (o.combine_window < 0) throw_error("--combine-window must be zero or positive, got {}", o.combine_window);
  if (!(o.time_limit >= 0.0 && std::isfinite(o.time_limit)))
    throw_error("--time-limit must be a positive, finite number of seconds (0: none), got {}", o.time_limit);
}

void check(const CheckpointOptions& o) {
  if (o.first <= 0) throw_error("--checkpoint-first must be positive, got {}", o.first);
}

std::string schedule_name(const SchedulingOptions& o, bool guiding) {
  return !o.schedule.empty() ? o.schedule : guiding ? "guiding" : "regular";
}

std::string combine_name(const SchedulingOptions& o, bool guiding, bool equal_sums_needed) {
  if (!o.combine.empty()) return o.combine;
  return guiding && !equal_sums_needed ? "inverse-variance" : "equal";
}

ScheduleOptions schedule_options(const std::string& name, const IterationOptions& overrides) {
  ScheduleOptions o = name == "guiding" ? guiding_schedule() : regular_schedule();
  if (overrides.first >= 0) o.first = overrides.first;
  if (overrides.repeat >= 0) o.repeat = overrides.repeat;
  if (overrides.growth >= 0.0) o.growth = overrides.growth;
  if (overrides.max >= 0) o.max = overrides.max;
  return o;
}

}  // namespace theia
