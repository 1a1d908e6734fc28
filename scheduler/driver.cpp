#include "scheduler/driver.h"

#include "core/log.h"
#include "core/stats.h"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <numeric>
#include <optional>
#include <thread>

namespace theia {

namespace {

constexpr const char* kSchedulerSection = "scheduler";
constexpr uint32_t kSchedulerSectionVersion = 5;
// A WeightedRun's planes in a checkpoint image: runK.R .G .B (sum), .W (weight), .V (variance);
// the settled run's are settled.R ... settled.V.
constexpr const char* kRunChannels[5] = {"R", "G", "B", "W", "V"};

// Where the render is: restored from and saved into a checkpoint.
struct Position {
  int iteration = 0;            // the iteration to render next (or being rendered)
  uint64_t camera_done = 0;     // camera samples of that iteration already complete
  // Ended by its time limit: the first camera_done samples of `iteration` are
  // in the image, and nothing is left to render.
  bool finished = false;
  uint64_t generation = 0;      // of the last checkpoint written or read
  // The first iteration of a schedule switched to (IterationConfig::switch_schedule); -1: none.
  int switched_at = -1;
  // Wall and CPU seconds the iteration had run when it was interrupted
  // (camera_done > 0): a resumed iteration's time counts them, so that what
  // is judged by time (--guiding-auto's efficiency) sees the iteration's
  // whole cost, as an uninterrupted render does, not just the rest of it.
  double partial_seconds = 0.0, partial_cpu_seconds = 0.0;
};

// Raises `stop` with StopReason::TimeLimit at `at`, unless destroyed first.
class Deadline {
 public:
  Deadline(StopRequest& stop, std::chrono::steady_clock::time_point at)
      : thread_([this, &stop, at] {
          std::unique_lock lock(mutex_);
          if (!wake_.wait_until(lock, at, [this] { return done_; })) stop.raise(StopReason::TimeLimit);
        }) {}
  ~Deadline() {
    {
      std::lock_guard lock(mutex_);
      done_ = true;
    }
    wake_.notify_one();
    thread_.join();
  }

 private:
  std::mutex mutex_;
  std::condition_variable wake_;
  bool done_ = false;
  std::thread thread_;  // last: it starts once the members it uses exist
};

// Colour samples per pixel, smallest and largest, counted from what was
// rendered: every iteration before pos.iteration and the first
// pos.camera_done camera samples of it (pixel-sample order, engine.h).
std::pair<uint32_t, uint32_t> spp_range(const Position& pos, const std::vector<int>& sizes,
                                        const std::vector<int>& cumulative, size_t pixels,
                                        const AdaptiveSampler* adaptive) {
  if (pixels == 0) return {0, 0};
  if (adaptive) {
    // Its ranges are those of pos.iteration (the last one's once all are done).
    const SampleRanges& r = adaptive->ranges();
    const uint64_t done = pos.iteration >= int(sizes.size()) ? r.total() : pos.camera_done;
    uint32_t lo = UINT32_MAX, hi = 0;
    for (size_t p = 0; p < pixels; ++p) {
      uint64_t rays = r.offset[p + 1] - r.offset[p];
      uint64_t got = std::min(rays, done > r.offset[p] ? done - r.offset[p] : 0);
      uint32_t n = r.begin[p] + uint32_t(std::min<uint64_t>(got, r.colour_end[p] - r.begin[p]));
      lo = std::min(lo, n);
      hi = std::max(hi, n);
    }
    return {lo, hi};
  }
  if (pos.iteration >= int(sizes.size())) return {uint32_t(cumulative.back()), uint32_t(cumulative.back())};
  const uint64_t n = uint64_t(sizes[size_t(pos.iteration)]);
  const uint32_t before = uint32_t(cumulative[size_t(pos.iteration)]) - uint32_t(n);
  auto got = [&](uint64_t pixel) {
    uint64_t first = pixel * n;
    return uint32_t(std::min(n, pos.camera_done > first ? pos.camera_done - first : 0));
  };
  return {before + got(pixels - 1), before + got(0)};
}

void put_planes(ImageBuffer& img, const std::string& prefix, const Film& f, std::vector<const float*>& src,
                std::vector<size_t>& stride) {
  for (size_t p = 0; p < f.plane_count(); ++p) {
    img.channels.push_back(prefix + Film::plane_name(p));
    src.push_back(f.plane(p)->data());
    stride.push_back(1);
  }
}

std::vector<float> channel(const ImageBuffer& img, const std::string& name, const std::string& what) {
  int c = img.channel_index(name);
  if (c < 0) throw_error("{}: the checkpoint image lacks channel {}", what, name);
  std::vector<float> v(img.pixel_count());
  for (size_t i = 0; i < v.size(); ++i) v[i] = img.data[i * img.channels.size() + size_t(c)];
  return v;
}

void get_planes(const ImageBuffer& img, const std::string& prefix, Film& f, const std::string& what) {
  for (size_t p = 0; p < f.plane_count(); ++p) *f.plane(p) = channel(img, prefix + Film::plane_name(p), what);
}

Checkpoint make_checkpoint(const IterationConfig& cfg, const std::vector<int>& sizes, const Position& pos,
                           const ImageAccumulator& acc, const Film& partial) {
  Checkpoint c;
  c.generation = pos.generation;
  c.scene_hash = cfg.scene_hash;
  c.options_hash = cfg.options_hash;

  // R G B A first: what a user opening the file sees is the image so far.
  ImageBuffer view = acc.resolve();
  ImageBuffer& img = c.image;
  img.width = acc.total.width;
  img.height = acc.total.height;
  std::vector<const float*> src;
  std::vector<size_t> src_stride;
  for (int ch = 0; ch < 4; ++ch) {
    img.channels.push_back(view.channels[size_t(ch)]);
    src.push_back(view.data.data() + ch);
    src_stride.push_back(view.channels.size());
  }
  put_planes(img, "total.", acc.total, src, src_stride);
  if (pos.camera_done > 0 && !pos.finished) put_planes(img, "partial.", partial, src, src_stride);
  auto put_run = [&](const WeightedRun& r, const std::string& prefix) {
    for (int ch = 0; ch < 5; ++ch) {
      img.channels.push_back(fmt::format("{}.{}", prefix, kRunChannels[ch]));
      src.push_back(ch < 3 ? r.sum.data() + ch : ch == 3 ? r.weight.data() : r.variance.data());
      src_stride.push_back(ch < 3 ? 3 : 1);
    }
  };
  for (size_t k = 0; k < acc.runs.size(); ++k) put_run(acc.runs[k], fmt::format("run{}", k));
  if (!acc.settled.empty()) put_run(acc.settled, "settled");
  const size_t nc = img.channels.size(), n = img.pixel_count();
  img.data.resize(n * nc);
  for (size_t c2 = 0; c2 < nc; ++c2)
    for (size_t i = 0; i < n; ++i) img.data[i * nc + c2] = src[c2][i * src_stride[c2]];

  ByteWriter w;
  w.put<int32_t>(cfg.total_spp);
  w.put_vector(sizes);
  w.put<int32_t>(pos.iteration);
  w.put<uint64_t>(pos.camera_done);
  w.put<uint8_t>(pos.finished);
  w.put<uint32_t>(cfg.seed);
  w.put<uint64_t>(acc.total.dropped.load());
  w.put<uint64_t>(partial.dropped.load());
  std::vector<uint32_t> run_spp;
  for (const WeightedRun& r : acc.runs) run_spp.insert(run_spp.end(), {r.spp_begin, r.spp_end});
  w.put_vector(run_spp);
  w.put<uint32_t>(acc.settled.spp_begin);
  w.put<uint32_t>(acc.settled.spp_end);
  w.put<uint32_t>(acc.skipped);
  w.put<int32_t>(pos.switched_at);
  w.put<double>(pos.partial_seconds);
  w.put<double>(pos.partial_cpu_seconds);
  c.sections.push_back({kSchedulerSection, kSchedulerSectionVersion, std::move(w.bytes)});
  for (const auto& p : cfg.participants) c.sections.push_back({p.name, p.version, p.save()});
  return c;
}

// A checkpoint's schedule is the one planned up front or, when it switched
// (switched_at >= 0), that one up to the switch and as many samples in all.
bool follows_plan(const std::vector<int>& planned, const std::vector<int>& saved, int switched_at) {
  if (switched_at < 0) return saved == planned;
  const size_t at = size_t(switched_at);
  return at <= planned.size() && at <= saved.size() &&
         std::equal(planned.begin(), planned.begin() + switched_at, saved.begin()) &&
         std::accumulate(planned.begin(), planned.end(), 0) == std::accumulate(saved.begin(), saved.end(), 0);
}

void restore(const Checkpoint& c, const IterationConfig& cfg, std::vector<int>& sizes, Position& pos,
             ImageAccumulator& acc, Film& partial) {
  const std::string what = checkpoint_bin_path(cfg.checkpoint.dir, c.generation);
  if (c.scene_hash != cfg.scene_hash)
    throw_error("{}: this checkpoint was written for a different scene (the scene file or something it loads has "
                "changed); refusing to resume. Remove the checkpoints or use another --checkpoint-dir",
                what);
  if (c.options_hash != cfg.options_hash)
    throw_error("{}: this checkpoint was written with different image-affecting options (all but threads, "
                "batch size, pool size, sorting and the checkpoint options); refusing to resume. Use the same options, remove the "
                "checkpoints or use another --checkpoint-dir",
                what);
  const CheckpointSection* s = c.find(kSchedulerSection);
  if (!s) throw_error("{}: no scheduler section", what);
  if (s->version != kSchedulerSectionVersion)
    throw_error("{}: scheduler section version {}, expected {}", what, s->version, kSchedulerSectionVersion);
  ByteReader r(s->bytes, what);
  int total = r.get<int32_t>();
  std::vector<int> saved_sizes = r.get_vector<int>();
  if (total != cfg.total_spp) throw_error("{}: written for a different schedule", what);
  pos.iteration = r.get<int32_t>();
  pos.camera_done = r.get<uint64_t>();
  pos.finished = r.get<uint8_t>() != 0;
  if (r.get<uint32_t>() != cfg.seed) throw_error("{}: written with a different seed", what);
  uint64_t dropped_total = r.get<uint64_t>(), dropped_partial = r.get<uint64_t>();
  std::vector<uint32_t> run_spp = r.get_vector<uint32_t>();
  const uint32_t settled_begin = r.get<uint32_t>(), settled_end = r.get<uint32_t>();
  const uint32_t skipped = r.get<uint32_t>();
  pos.switched_at = r.get<int32_t>();
  pos.partial_seconds = r.get<double>();
  pos.partial_cpu_seconds = r.get<double>();
  // At most 1e9 s (31 years): a clock set back further would overflow.
  if (!(pos.partial_seconds >= 0.0 && pos.partial_seconds <= 1e9 && pos.partial_cpu_seconds >= 0.0 &&
        pos.partial_cpu_seconds <= 1e9))
    throw_error("{}: bad interrupted-iteration times ({} s, {} CPU-s)", what, pos.partial_seconds,
                pos.partial_cpu_seconds);
  if (!follows_plan(sizes, saved_sizes, pos.switched_at)) throw_error("{}: written for a different schedule", what);
  sizes = saved_sizes;
  if (run_spp.size() % 2 != 0 || run_spp.size() / 2 > ImageAccumulator::kMaxBlocks || settled_end < settled_begin)
    throw_error("{}: bad inverse-variance runs", what);
  if (pos.iteration < 0 || pos.iteration > int(sizes.size())) throw_error("{}: iteration out of range", what);
  if (c.image.width != acc.total.width || c.image.height != acc.total.height)
    throw_error("{}: image size differs from the scene's film", what);

  get_planes(c.image, "total.", acc.total, what);
  acc.total.dropped = dropped_total;
  partial.clear();
  if (pos.camera_done > 0 && !pos.finished) {
    get_planes(c.image, "partial.", partial, what);
    partial.dropped = dropped_partial;
  }
  acc.runs.clear();
  acc.skipped = skipped;
  auto get_run = [&](uint32_t spp_begin, uint32_t spp_end, const std::string& prefix) {
    WeightedRun run{spp_begin, spp_end, {}, {}, {}};
    run.sum.resize(c.image.pixel_count() * 3);
    for (int ch = 0; ch < 3; ++ch) {
      std::vector<float> v = channel(c.image, fmt::format("{}.{}", prefix, kRunChannels[ch]), what);
      for (size_t i = 0; i < v.size(); ++i) run.sum[3 * i + size_t(ch)] = v[i];
    }
    run.weight = channel(c.image, fmt::format("{}.{}", prefix, kRunChannels[3]), what);
    run.variance = channel(c.image, fmt::format("{}.{}", prefix, kRunChannels[4]), what);
    return run;
  };
  for (size_t k = 0; k < run_spp.size() / 2; ++k)
    acc.runs.push_back(get_run(run_spp[2 * k], run_spp[2 * k + 1], fmt::format("run{}", k)));
  acc.settled = settled_end > settled_begin ? get_run(settled_begin, settled_end, "settled") : WeightedRun{};
  for (const auto& p : cfg.participants) {
    const CheckpointSection* ps = c.find(p.name);
    if (!ps) throw_error("{}: no section '{}' for a subsystem this render uses", what, p.name);
    p.load(*ps);
  }
  pos.generation = c.generation;
}

}  // namespace

std::pair<uint32_t, uint32_t> checkpoint_spp(const Checkpoint& c) {
  const CheckpointSection* s = c.find(kSchedulerSection);
  if (!s || s->version != kSchedulerSectionVersion) throw_error("checkpoint {}: no scheduler section", c.generation);
  ByteReader r(s->bytes, "checkpoint scheduler section");
  r.get<int32_t>();  // total spp
  const std::vector<int> sizes = r.get_vector<int>();
  Position pos;
  pos.iteration = r.get<int32_t>();
  pos.camera_done = r.get<uint64_t>();
  if (pos.iteration < 0 || pos.iteration > int(sizes.size())) throw_error("checkpoint {}: iteration out of range", c.generation);
  // Adaptive sampling's per-pixel ranges are its own section: counted here as if uniform.
  return spp_range(pos, sizes, cumulative_spp(sizes), c.image.pixel_count(), nullptr);
}

std::vector<int> iteration_sizes(const IterationConfig& config) {
  std::vector<int> sizes = make_schedule(config.schedule, config.total_spp);
  if (config.sample_end == 0) return sizes;
  if (config.sample_begin >= config.sample_end || config.sample_end > uint32_t(config.total_spp))
    throw_error("--sample-range {}:{} is not within the frame's {} samples per pixel", config.sample_begin,
                config.sample_end, config.total_spp);
  if (config.part_learns) return make_schedule(config.schedule, int(config.sample_end - config.sample_begin));
  return clip_schedule(sizes, int(config.sample_begin), int(config.sample_end));
}

namespace {

// One call of render_iterations: the schedule, where the render is, the
// image accumulated so far, the checkpoints written and the log of each
// iteration.  Its steps are render_iterations'.
class IterationRun {
 public:
  IterationRun(WavefrontEngine& engine, Film& film, IterationTasks& tasks, const IterationConfig& config);
  void resume_from_newest_checkpoint();
  void add_between_iteration_tasks();
  void start_deadline();
  // Where this iteration's camera samples must stop for its tail to end by the time limit.
  void reserve_tail(uint64_t camera_total);
  // Under a time limit, shortens the iteration about to begin to what the time left fits.
  void fit_to_time_left();
  bool done() const { return pos_.finished || pos_.iteration >= int(sizes_.size()); }
  // Renders iteration pos_.iteration (from pos_.camera_done); false when the render stops there.
  bool render_iteration();
  IterationResult finish();

 private:
  void plan();
  void write();
  StopReason stop_reason() const { return cfg_.stop ? cfg_.stop->reason() : StopReason::None; }
  bool signalled() const { return stop_reason() == StopReason::Signal; }
  bool time_up() const { return stop_reason() == StopReason::TimeLimit; }
  uint32_t settled_from() const {
    const std::optional<uint32_t> s = cfg_.settled_from ? cfg_.settled_from() : std::nullopt;
    return s ? *s : std::numeric_limits<uint32_t>::max();
  }
  void log_switch();
  // The three ways an iteration ends.
  void keep_stopped_iteration(uint64_t done, uint64_t camera_total);
  void save_interrupted_iteration(uint64_t done);
  bool fold_finished_iteration();
  nlohmann::json log() const;

  WavefrontEngine& engine_;
  Film& film_;
  IterationTasks& tasks_;
  IterationConfig cfg_;
  std::chrono::steady_clock::time_point t0_ = std::chrono::steady_clock::now();
  // The schedule planned up front; a switch (or a resumed one) replaces its tail.
  std::vector<int> sizes_, cumulative_;
  std::vector<bool> planned_;  // checkpoint after iteration i
  const bool checkpoints_;
  ImageAccumulator acc_;
  Position pos_;
  bool resumed_ = false;
  int first_iteration_ = 0;
  double checkpoint_seconds_ = 0.0;
  int checkpoints_written_ = 0, failed_checkpoint_writes_ = 0;
  // The newest generation on disk and the iteration it resumes at: what a
  // failed write falls back on.
  std::optional<std::pair<uint64_t, int>> kept_;
  bool wrote_this_iteration_ = false;
  std::optional<Deadline> deadline_;
  bool interrupted_ = false, ended_by_time_limit_ = false;
  double tail_seconds_before_ = 0.0;  // reserve_tail's
  double seconds_per_spp_ = 0.0;      // the last finished iteration's, its tasks included
  uint64_t camera_rays_before_ = 0;
  IterationInfo info_;
  // The iteration in progress: its clocks.
  std::chrono::steady_clock::time_point iteration_t0_;
  double iteration_cpu0_ = 0.0;
  double seconds_before_resume_ = 0.0;  // Position::partial_seconds of a resumed iteration, else 0
  nlohmann::json iterations_ = nlohmann::json::array();
  nlohmann::json switch_log_;  // null: the schedule planned up front throughout
};

IterationRun::IterationRun(WavefrontEngine& engine, Film& film, IterationTasks& tasks, const IterationConfig& config)
    : engine_(engine), film_(film), tasks_(tasks), cfg_(config), checkpoints_(!config.checkpoint.dir.empty()),
      acc_(film.width, film.height, config.combination, config.combine_window, film.aov_events()) {
  if (cfg_.adaptive) cfg_.participants.push_back(cfg_.adaptive->participant());
  sizes_ = iteration_sizes(cfg_);
  plan();
  if (cfg_.resume && !checkpoints_) throw_error("--resume needs --checkpoint-dir");
  if (cfg_.time_limit > 0 && !cfg_.stop) throw_error("internal: a time limit needs the engine's stop request");
  film_.clear();
  info_.count = int(sizes_.size());
}

void IterationRun::plan() {
  cumulative_ = cumulative_spp(sizes_);
  planned_ = checkpoint_iterations(cumulative_, cfg_.checkpoint.first, cfg_.checkpoint.every_iteration);
}

void IterationRun::resume_from_newest_checkpoint() {
  if (checkpoints_) {
    if (auto c = read_latest_checkpoint(cfg_.checkpoint.dir)) {
      restore(*c, cfg_, sizes_, pos_, acc_, film_);
      plan();
      info_.count = int(sizes_.size());
      resumed_ = true;
      kept_ = {pos_.generation, pos_.iteration};
      if (pos_.switched_at >= 0) log_switch();
      if (pos_.finished)
        log_info("{} holds a render its time limit ended; writing its image, rendering nothing",
                 checkpoint_bin_path(cfg_.checkpoint.dir, c->generation));
      else
        log_info("resuming from {} at iteration {} of {} ({} camera samples of it done)",
                 checkpoint_bin_path(cfg_.checkpoint.dir, c->generation), pos_.iteration + 1, sizes_.size(),
                 pos_.camera_done);
    } else if (cfg_.resume) {
      throw_error("--resume: no checkpoint in {}", cfg_.checkpoint.dir);
    }
  }
  first_iteration_ = pos_.iteration;
}

void IterationRun::write() {
  ScopedTimer timer(checkpoint_seconds_);
  ++pos_.generation;
  try {
    write_checkpoint(cfg_.checkpoint.dir, make_checkpoint(cfg_, sizes_, pos_, acc_, film_));
  } catch (const std::exception& e) {
    // A full disk must not end a render that still has a checkpoint to
    // resume from; without one, the checkpoint the user asked for is missing.
    if (!kept_) throw;
    --pos_.generation;
    auto spp_done = [&](int iteration) { return iteration > 0 ? cumulative_[size_t(iteration) - 1] : 0; };
    log_warning("{}; rendering on: a stop now resumes from generation {} and loses the {} spp rendered since",
                e.what(), kept_->first, spp_done(pos_.iteration) - spp_done(kept_->second));
    ++failed_checkpoint_writes_;
    return;
  }
  kept_ = {pos_.generation, pos_.iteration};
  ++checkpoints_written_;
}

void IterationRun::log_switch() {
  const int at = pos_.switched_at;
  switch_log_ = {{"at_iteration", at}, {"at_spp", at > 0 ? cumulative_[size_t(at) - 1] : 0}};
}

// Adaptive sampling's update, the schedule switch and the checkpoint (the
// skipping logic's choice, or any boundary where a stop was asked for).
void IterationRun::add_between_iteration_tasks() {
  if (cfg_.adaptive)
    tasks_.add(BetweenIterationSlot::AdaptiveSamplerUpdate,
               [this](const IterationInfo& it) { cfg_.adaptive->update(acc_.total, it.index); });
  if (cfg_.switch_schedule && !cfg_.adaptive)
    tasks_.add(BetweenIterationSlot::ScheduleSwitch, [this](const IterationInfo& it) {
      if (pos_.switched_at >= 0 || it.last()) return;
      const std::optional<ScheduleOptions> to = cfg_.switch_schedule(it);
      if (!to) return;
      sizes_ = switch_schedule(sizes_, it.index + 1, *to);
      plan();
      pos_.switched_at = it.index + 1;
      info_.count = int(sizes_.size());
      log_switch();
      log_info("schedule: switched from iteration {} ({} spp) on: {} more iteration(s), the first of {} spp",
               it.index + 2, cumulative_[size_t(it.index)], sizes_.size() - size_t(it.index) - 1,
               sizes_[size_t(it.index) + 1]);
    });
  if (checkpoints_)
    tasks_.add(BetweenIterationSlot::Checkpoint, [this](const IterationInfo& it) {
      wrote_this_iteration_ = planned_[size_t(it.index)] || (signalled() && !it.last());
      if (wrote_this_iteration_) write();
    });
}

void IterationRun::start_deadline() {
  if (cfg_.time_limit > 0 && !pos_.finished)
    deadline_.emplace(*cfg_.stop, cfg_.clock_start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                         std::chrono::duration<double>(cfg_.time_limit)));
}

// Once an iteration's camera samples are in (all, or those a time limit let
// through), the caustic pass traces its light paths: one per camera sample
// of the whole iteration, since the samples rendered are whole pixels' (the
// pixel-sample order) and a pixel's splats come from every light path.
// Stopping only the camera samples at the limit, that tail overran it
// (veach-mis: 32.3 s for --time-limit 30), so they stop short of it by the
// tail this iteration will have, at the last iteration's rate.
void IterationRun::reserve_tail(uint64_t camera_total) {
  if (cfg_.time_limit <= 0) return;
  using namespace std::chrono;
  const EngineStats& stats = engine_.stats();
  // The last iteration's alone: the caustic pass may have switched itself off since.
  const double tail = stats.phases[Phase::Caustics] - tail_seconds_before_;
  const uint64_t samples = stats.camera_rays - camera_rays_before_;
  tail_seconds_before_ = stats.phases[Phase::Caustics];
  camera_rays_before_ = stats.camera_rays;
  if (!(tail > 0.0 && samples > 0)) return engine_.stop_camera_samples_at(std::nullopt);
  const double reserve = tail / double(samples) * double(camera_total);
  engine_.stop_camera_samples_at(cfg_.clock_start +
                                 duration_cast<steady_clock::duration>(duration<double>(cfg_.time_limit - reserve)));
}

// The iteration that would overrun a time limit is cut to the samples the
// time left fits, at the last iteration's pace (the rest of its samples
// become an iteration after it): every pixel then ends with as many samples,
// and the caustic pass, which traces the whole iteration's light paths
// however few camera samples a stop let through (reserve_tail), is not paid
// for a strip of pixels.  The stop at the limit still ends a slow one.
void IterationRun::fit_to_time_left() {
  if (cfg_.time_limit <= 0 || cfg_.adaptive || pos_.camera_done > 0) return;
  const int i = pos_.iteration;
  const double left = cfg_.time_limit - seconds_since(cfg_.clock_start);
  std::vector<int> cut = fit_iteration(sizes_, i, left, seconds_per_spp_);
  if (cut == sizes_) return;
  log_info("schedule: iteration {} cut from {} to {} spp, what the time limit's {:.3g} s left fit", i + 1,
           sizes_[size_t(i)], cut[size_t(i)], left);
  sizes_ = std::move(cut);
  plan();
  // A checkpoint's schedule may differ from the planned one only after a switch.
  if (pos_.switched_at < 0) {
    pos_.switched_at = i;
    log_switch();
  }
  info_.count = int(sizes_.size());
}

bool IterationRun::render_iteration() {
  if (time_up()) {  // between iterations: the render ends with the ones done
    pos_.finished = ended_by_time_limit_ = true;
    return false;
  }
  fit_to_time_left();
  const int i = pos_.iteration;
  info_.index = i;
  info_.spp_begin = cfg_.sample_begin + uint32_t(cumulative_[size_t(i)] - sizes_[size_t(i)]);
  info_.spp_end = cfg_.sample_begin + uint32_t(cumulative_[size_t(i)]);
  // A resumed iteration's clocks start where its interruption stopped them.
  const bool resumed_inside = pos_.camera_done > 0;
  seconds_before_resume_ = resumed_inside ? pos_.partial_seconds : 0.0;
  iteration_t0_ = std::chrono::steady_clock::now() -
                  std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                      std::chrono::duration<double>(resumed_inside ? pos_.partial_seconds : 0.0));
  iteration_cpu0_ = process_cpu_seconds() - (resumed_inside ? pos_.partial_cpu_seconds : 0.0);
  info_.elapsed_seconds = seconds_since(cfg_.clock_start);
  tasks_.begin_iteration(info_);
  auto progress = [&](double f) {
    if (!cfg_.progress) return;
    const double before = cumulative_[size_t(i)] - sizes_[size_t(i)];
    cfg_.progress(i, f, (before + f * sizes_[size_t(i)]) / cumulative_.back());
  };
  const uint64_t camera_total = cfg_.adaptive ? cfg_.adaptive->ranges().total()
                                              : uint64_t(film_.pixel_count()) * uint64_t(sizes_[size_t(i)]);
  reserve_tail(camera_total);
  const uint64_t done = cfg_.adaptive ? engine_.render(cfg_.adaptive->ranges(), progress, pos_.camera_done)
                                      : engine_.render(info_.spp_begin, info_.spp_end, progress, pos_.camera_done);
  if (engine_.abandoned()) {
    // Paths still in flight seconds after the signal were dropped: this
    // iteration is incomplete and is not written; the newest checkpoint
    // stays what a resume continues from (an uninterrupted image still).
    log_warning("paths still in flight after the signal's grace time were abandoned: iteration {} is lost{}", i,
                checkpoints_ ? "; the resume continues from the newest checkpoint" : "");
    iterations_.push_back({{"spp", {info_.spp_begin, info_.spp_end}}, {"seconds", seconds_since(iteration_t0_)},
                           {"abandoned_after_camera_samples", done}});
    interrupted_ = true;
    return false;
  }
  if (done < camera_total) {
    // Not stopped by a signal or the limit itself: by reserve_tail's time, which is the limit's.
    if (cfg_.stop && !cfg_.stop->raised()) cfg_.stop->raise(StopReason::TimeLimit);
    if (time_up())
      keep_stopped_iteration(done, camera_total);
    else
      save_interrupted_iteration(done);
    return false;
  }
  return fold_finished_iteration();
}

// The time limit ends the render inside the iteration: its samples are kept,
// folded in like a finished iteration's (each pixel's estimate divides by the
// weight it got).  No between-iteration task runs: they would prepare an
// iteration that will not come.
void IterationRun::keep_stopped_iteration(uint64_t done, uint64_t camera_total) {
  engine_.finish_stopped_iteration();
  acc_.fold(film_, info_.spp_begin, info_.spp_end, settled_from());
  film_.clear();
  pos_.camera_done = done;
  pos_.finished = ended_by_time_limit_ = true;
  iterations_.push_back({{"spp", {info_.spp_begin, info_.spp_end}},
                         {"seconds", seconds_since(iteration_t0_)},
                         {"cpu_seconds", process_cpu_seconds() - iteration_cpu0_},
                         {"stopped_after_camera_samples", done},
                         {"of_camera_samples", camera_total}});
  if (cfg_.evaluate) iterations_.back().update(cfg_.evaluate(info_, acc_));
}

// Stopped by a signal inside the iteration: keep exactly the camera samples done.
void IterationRun::save_interrupted_iteration(uint64_t done) {
  pos_.camera_done = done;
  pos_.partial_seconds = seconds_since(iteration_t0_);
  pos_.partial_cpu_seconds = process_cpu_seconds() - iteration_cpu0_;
  if (checkpoints_) write();
  iterations_.push_back({{"spp", {info_.spp_begin, info_.spp_end}}, {"seconds", seconds_since(iteration_t0_)},
                         {"stopped_after_camera_samples", done}});
  interrupted_ = true;
}

bool IterationRun::fold_finished_iteration() {
  info_.seconds = seconds_since(iteration_t0_);
  info_.cpu_seconds = process_cpu_seconds() - iteration_cpu0_;
  if (tasks_.measures_variance()) {
    const RelativeVariance v = relative_variance(film_, half_buffer_variance(film_), &acc_.total);
    info_.sample_variance = v.robust;
    info_.sample_variance_full = v.full;
  }
  acc_.fold(film_, info_.spp_begin, info_.spp_end, settled_from());
  film_.clear();
  pos_.iteration = info_.index + 1;
  pos_.camera_done = 0;
  pos_.partial_seconds = pos_.partial_cpu_seconds = 0.0;
  nlohmann::json evaluation;
  if (cfg_.evaluate) evaluation = cfg_.evaluate(info_, acc_);
  const double checkpoint_before = checkpoint_seconds_;
  tasks_.end_iteration(info_);
  seconds_per_spp_ = seconds_since(iteration_t0_) / double(std::max(info_.spp_end - info_.spp_begin, 1u));
  iterations_.push_back({{"spp", {info_.spp_begin, info_.spp_end}},
                         {"seconds", seconds_since(iteration_t0_)},
                         // The between-iteration tasks included, as in "seconds".
                         {"cpu_seconds", process_cpu_seconds() - iteration_cpu0_},
                         {"checkpoint", wrote_this_iteration_},
                         {"checkpoint_seconds", checkpoint_seconds_ - checkpoint_before}});
  if (seconds_before_resume_ > 0.0) iterations_.back()["seconds_before_resume"] = seconds_before_resume_;
  if (evaluation.is_object()) iterations_.back().update(evaluation);
  if (signalled() && !info_.last()) {
    interrupted_ = true;
    return false;
  }
  return true;
}

IterationResult IterationRun::finish() {
  deadline_.reset();
  // The finished render replaces any checkpoint a re-run would continue from.
  if (ended_by_time_limit_ && checkpoints_) write();
  IterationResult result;
  result.interrupted = interrupted_;
  result.ended_by_time_limit = pos_.finished;
  std::tie(result.spp_min, result.spp_max) = spp_range(pos_, sizes_, cumulative_, film_.pixel_count(), cfg_.adaptive);
  result.dropped_samples = acc_.total.dropped.load() + film_.dropped.load();
  if (!interrupted_) {
    result.image = acc_.resolve();
    result.weight = acc_.total.weight;
    if (cfg_.keep_sums) result.sums = film_sums_image(acc_.total, "sum.");
  }
  result.log = log();
  result.log["spp_per_pixel"] = {{"min", result.spp_min}, {"max", result.spp_max}};
  if (checkpoints_)
    log_info("checkpoints: {} written, {:.3f} s = {:.2f}% of {:.2f} s wall ({})", checkpoints_written_,
             checkpoint_seconds_, 100.0 * checkpoint_seconds_ / std::max(seconds_since(t0_), 1e-9),
             seconds_since(t0_), cfg_.checkpoint.every_iteration ? "after every iteration" : "with skipping");
  return result;
}

nlohmann::json IterationRun::log() const {
  const double wall = seconds_since(t0_);
  nlohmann::json slot_seconds;
  for (size_t s = 0; s < size_t(BetweenIterationSlot::Count); ++s)
    slot_seconds[kSlotNames[s]] = tasks_.seconds(BetweenIterationSlot(s));
  slot_seconds["end_hooks"] = tasks_.end_hook_seconds();  // the recorder's end_iteration(): sort and training
  return {{"schedule", sizes_},
          {"schedule_switch", switch_log_},
          {"combination", combination_name(cfg_.combination)},
          {"combination_used", acc_.choice().log()},
          {"resumed", resumed_},
          {"resumed_at_iteration", first_iteration_},
          {"time_limit",
           {{"seconds", cfg_.time_limit},
            {"reached", pos_.finished},
            {"reached_in_this_run", ended_by_time_limit_},
            {"elapsed_seconds", seconds_since(cfg_.clock_start)}}},
          {"iterations", iterations_},
          {"between_iteration_seconds", slot_seconds},
          {"checkpoint",
           {{"dir", cfg_.checkpoint.dir},
            {"skipping", !cfg_.checkpoint.every_iteration},
            {"written", checkpoints_written_},
            {"failed_writes", failed_checkpoint_writes_},
            {"seconds", checkpoint_seconds_},
            {"wall_seconds", wall},
            {"share_of_wall", wall > 0 ? checkpoint_seconds_ / wall : 0.0}}}};
}

}  // namespace

IterationResult render_iterations(WavefrontEngine& engine, Film& film, IterationTasks tasks,
                                  const IterationConfig& config) {
  IterationRun run(engine, film, tasks, config);
  run.resume_from_newest_checkpoint();
  run.add_between_iteration_tasks();
  run.start_deadline();
  while (!run.done() && run.render_iteration()) {
  }
  return run.finish();
}

}  // namespace theia
