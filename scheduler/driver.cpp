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
// 4: camera_done counts camera samples in sample-major order (camera_samples.h).
constexpr uint32_t kSchedulerSectionVersion = 4;
// A WeightedRun's planes in a checkpoint image: runK.R .G .B (sum), .W (weight), .V (variance).
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
// pos.camera_done camera samples of it (CameraSampleOrder).
std::pair<uint32_t, uint32_t> spp_range(const Position& pos, const std::vector<int>& sizes,
                                        const std::vector<int>& cumulative, size_t pixels,
                                        const AdaptiveSampler* adaptive) {
  if (pixels == 0) return {0, 0};
  if (adaptive) {
    // Its ranges are those of pos.iteration (the last one's once all are done).
    const SampleRanges& r = adaptive->ranges();
    const CameraSampleOrder order(r);
    const uint64_t done = pos.iteration >= int(sizes.size()) ? r.total() : pos.camera_done;
    uint32_t lo = UINT32_MAX, hi = 0;
    for (size_t p = 0; p < pixels; ++p) {
      const uint32_t got = order.samples_in(uint32_t(p), done);
      const uint32_t n = r.begin[p] + std::min(got, r.colour_end[p] - r.begin[p]);
      lo = std::min(lo, n);
      hi = std::max(hi, n);
    }
    return {lo, hi};
  }
  if (pos.iteration >= int(sizes.size())) return {uint32_t(cumulative.back()), uint32_t(cumulative.back())};
  const uint32_t end = uint32_t(cumulative[size_t(pos.iteration)]);
  const uint32_t before = end - uint32_t(sizes[size_t(pos.iteration)]);
  const CameraSampleOrder order(pixels, before, end);
  return {before + order.samples_in(uint32_t(pixels - 1), pos.camera_done), before + order.samples_in(0, pos.camera_done)};
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
  for (size_t k = 0; k < acc.runs.size(); ++k) {
    const WeightedRun& r = acc.runs[k];
    for (int ch = 0; ch < 5; ++ch) {
      img.channels.push_back(fmt::format("run{}.{}", k, kRunChannels[ch]));
      src.push_back(ch < 3 ? r.sum.data() + ch : ch == 3 ? r.weight.data() : r.variance.data());
      src_stride.push_back(ch < 3 ? 3 : 1);
    }
  }
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
  w.put<uint32_t>(acc.skipped);
  w.put<int32_t>(pos.switched_at);
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
  const uint32_t skipped = r.get<uint32_t>();
  pos.switched_at = r.get<int32_t>();
  if (!follows_plan(sizes, saved_sizes, pos.switched_at)) throw_error("{}: written for a different schedule", what);
  sizes = saved_sizes;
  if (run_spp.size() % 2 != 0 || run_spp.size() / 2 > ImageAccumulator::kMaxBlocks)
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
  for (size_t k = 0; k < run_spp.size() / 2; ++k) {
    WeightedRun run{run_spp[2 * k], run_spp[2 * k + 1], {}, {}, {}};
    run.sum.resize(c.image.pixel_count() * 3);
    for (int ch = 0; ch < 3; ++ch) {
      std::vector<float> v = channel(c.image, fmt::format("run{}.{}", k, kRunChannels[ch]), what);
      for (size_t i = 0; i < v.size(); ++i) run.sum[3 * i + size_t(ch)] = v[i];
    }
    run.weight = channel(c.image, fmt::format("run{}.{}", k, kRunChannels[3]), what);
    run.variance = channel(c.image, fmt::format("run{}.{}", k, kRunChannels[4]), what);
    acc.runs.push_back(std::move(run));
  }
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

IterationResult render_iterations(WavefrontEngine& engine, Film& film, IterationTasks tasks,
                                  const IterationConfig& config) {
  IterationConfig cfg = config;
  if (cfg.adaptive) cfg.participants.push_back(cfg.adaptive->participant());
  auto t0 = std::chrono::steady_clock::now();
  // The schedule planned up front; a switch (or a resumed one) replaces its tail.
  std::vector<int> sizes = iteration_sizes(cfg);
  std::vector<int> cumulative;
  std::vector<bool> planned;
  auto plan = [&] {
    cumulative = cumulative_spp(sizes);
    planned = checkpoint_iterations(cumulative, cfg.checkpoint.first, cfg.checkpoint.every_iteration);
  };
  plan();
  const bool checkpoints = !cfg.checkpoint.dir.empty();
  if (cfg.resume && !checkpoints) throw_error("--resume needs --checkpoint-dir");
  if (cfg.time_limit > 0 && !cfg.stop) throw_error("internal: a time limit needs the engine's stop request");

  ImageAccumulator acc(film.width, film.height, cfg.combination, cfg.combine_window, film.aov_events());
  Position pos;
  film.clear();
  bool resumed = false;
  if (checkpoints) {
    if (auto c = read_latest_checkpoint(cfg.checkpoint.dir)) {
      restore(*c, cfg, sizes, pos, acc, film);
      plan();
      resumed = true;
      if (pos.finished)
        log_info("{} holds a render its time limit ended; writing its image, rendering nothing",
                 checkpoint_bin_path(cfg.checkpoint.dir, c->generation));
      else
        log_info("resuming from {} at iteration {} of {} ({} camera samples of it done)",
                 checkpoint_bin_path(cfg.checkpoint.dir, c->generation), pos.iteration + 1, sizes.size(),
                 pos.camera_done);
    } else if (cfg.resume) {
      throw_error("--resume: no checkpoint in {}", cfg.checkpoint.dir);
    }
  }
  const int first_iteration = pos.iteration;

  double checkpoint_seconds = 0.0;
  int checkpoints_written = 0;
  int failed_checkpoint_writes = 0;
  // The newest generation on disk and the iteration it resumes at: what a
  // failed write falls back on.
  std::optional<std::pair<uint64_t, int>> kept;
  if (resumed) kept = {pos.generation, pos.iteration};
  auto write = [&] {
    ScopedTimer timer(checkpoint_seconds);
    ++pos.generation;
    try {
      write_checkpoint(cfg.checkpoint.dir, make_checkpoint(cfg, sizes, pos, acc, film));
    } catch (const std::exception& e) {
      // A full disk must not end a render that still has a checkpoint to
      // resume from; without one, the checkpoint the user asked for is missing.
      if (!kept) throw;
      --pos.generation;
      auto spp_done = [&](int iteration) { return iteration > 0 ? cumulative[size_t(iteration) - 1] : 0; };
      log_warning("{}; rendering on: a stop now resumes from generation {} and loses the {} spp rendered since",
                  e.what(), kept->first, spp_done(pos.iteration) - spp_done(kept->second));
      ++failed_checkpoint_writes;
      return;
    }
    kept = {pos.generation, pos.iteration};
    ++checkpoints_written;
  };
  auto stop_reason = [&] { return cfg.stop ? cfg.stop->reason() : StopReason::None; };
  auto signalled = [&] { return stop_reason() == StopReason::Signal; };
  auto time_up = [&] { return stop_reason() == StopReason::TimeLimit; };
  std::optional<Deadline> deadline;
  if (cfg.time_limit > 0 && !pos.finished)
    deadline.emplace(*cfg.stop, cfg.clock_start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                      std::chrono::duration<double>(cfg.time_limit)));

  nlohmann::json iterations = nlohmann::json::array();
  bool interrupted = false;
  IterationInfo info;
  info.count = int(sizes.size());
  // The checkpoint task: the skipping logic's choice, or any boundary where a stop was asked for.
  bool wrote_this_iteration = false;
  if (cfg.adaptive)
    tasks.add(BetweenIterationSlot::AdaptiveSamplerUpdate,
              [&](const IterationInfo& it) { cfg.adaptive->update(acc.total, it.index); });
  nlohmann::json switch_log;  // null: the schedule planned up front throughout
  auto log_switch = [&] {
    const int at = pos.switched_at;
    switch_log = {{"at_iteration", at}, {"at_spp", at > 0 ? cumulative[size_t(at) - 1] : 0}};
  };
  if (pos.switched_at >= 0) log_switch();
  if (cfg.switch_schedule && !cfg.adaptive)
    tasks.add(BetweenIterationSlot::ScheduleSwitch, [&](const IterationInfo& it) {
      if (pos.switched_at >= 0 || it.last()) return;
      const std::optional<ScheduleOptions> to = cfg.switch_schedule(it);
      if (!to) return;
      sizes = switch_schedule(sizes, it.index + 1, *to);
      plan();
      pos.switched_at = it.index + 1;
      info.count = int(sizes.size());
      log_switch();
      log_info("schedule: switched from iteration {} ({} spp) on: {} more iteration(s), the first of {} spp",
               it.index + 2, cumulative[size_t(it.index)], sizes.size() - size_t(it.index) - 1,
               sizes[size_t(it.index) + 1]);
    });
  if (checkpoints)
    tasks.add(BetweenIterationSlot::Checkpoint, [&](const IterationInfo& it) {
      wrote_this_iteration = planned[size_t(it.index)] || (signalled() && !it.last());
      if (wrote_this_iteration) write();
    });

  bool ended_by_time_limit = false;
  for (int i = pos.iteration; i < int(sizes.size()) && !pos.finished; ++i) {
    if (time_up()) {  // between iterations: the render ends with the ones done
      pos.finished = ended_by_time_limit = true;
      break;
    }
    info.index = i;
    info.spp_begin = cfg.sample_begin + uint32_t(cumulative[size_t(i)] - sizes[size_t(i)]);
    info.spp_end = cfg.sample_begin + uint32_t(cumulative[size_t(i)]);
    auto ti = std::chrono::steady_clock::now();
    const double cpu0 = process_cpu_seconds();
    info.elapsed_seconds = seconds_since(cfg.clock_start);
    tasks.begin_iteration(info);
    auto progress = [&](double f) {
      if (!cfg.progress) return;
      const double before = cumulative[size_t(i)] - sizes[size_t(i)];
      cfg.progress(i, f, (before + f * sizes[size_t(i)]) / cumulative.back());
    };
    uint64_t camera_total, done;
    if (cfg.adaptive) {
      camera_total = cfg.adaptive->ranges().total();
      done = engine.render(cfg.adaptive->ranges(), progress, pos.camera_done);
    } else {
      camera_total = uint64_t(film.pixel_count()) * uint64_t(sizes[size_t(i)]);
      done = engine.render(info.spp_begin, info.spp_end, progress, pos.camera_done);
    }
    if (engine.abandoned()) {
      // Paths still in flight seconds after the signal were dropped: this
      // iteration is incomplete and is not written; the newest checkpoint
      // stays what a resume continues from (an uninterrupted image still).
      log_warning("paths still in flight after the signal's grace time were abandoned: iteration {} is lost{}", i,
                  checkpoints ? "; the resume continues from the newest checkpoint" : "");
      iterations.push_back({{"spp", {info.spp_begin, info.spp_end}}, {"seconds", seconds_since(ti)},
                            {"abandoned_after_camera_samples", done}});
      interrupted = true;
      break;
    }
    if (done < camera_total && time_up()) {
      // The time limit ends the render inside the iteration: its samples are
      // kept, folded in like a finished iteration's (each pixel's estimate
      // divides by the weight it got).  No between-iteration task runs: they
      // would prepare an iteration that will not come.
      engine.finish_stopped_iteration();
      acc.fold(film, info.spp_begin, info.spp_end);
      film.clear();
      pos.iteration = i;
      pos.camera_done = done;
      pos.finished = ended_by_time_limit = true;
      iterations.push_back({{"spp", {info.spp_begin, info.spp_end}},
                            {"seconds", seconds_since(ti)},
                            {"cpu_seconds", process_cpu_seconds() - cpu0},
                            {"stopped_after_camera_samples", done},
                            {"of_camera_samples", camera_total}});
      if (cfg.evaluate) iterations.back().update(cfg.evaluate(info, acc));
      break;
    }
    if (done < camera_total) {
      // Stopped inside the iteration: keep exactly the pixel-samples done.
      pos.iteration = i;
      pos.camera_done = done;
      if (checkpoints) write();
      iterations.push_back({{"spp", {info.spp_begin, info.spp_end}}, {"seconds", seconds_since(ti)},
                            {"stopped_after_camera_samples", done}});
      interrupted = true;
      break;
    }
    info.seconds = seconds_since(ti);
    info.cpu_seconds = process_cpu_seconds() - cpu0;
    if (tasks.measures_variance()) {
      const RelativeVariance v = relative_variance(film, half_buffer_variance(film), &acc.total);
      info.sample_variance = v.robust;
      info.sample_variance_full = v.full;
    }
    acc.fold(film, info.spp_begin, info.spp_end);
    film.clear();
    pos.iteration = i + 1;
    pos.camera_done = 0;
    nlohmann::json evaluation;
    if (cfg.evaluate) evaluation = cfg.evaluate(info, acc);
    double before = checkpoint_seconds;
    tasks.end_iteration(info);
    iterations.push_back({{"spp", {info.spp_begin, info.spp_end}},
                          {"seconds", seconds_since(ti)},
                          // The between-iteration tasks included, as in "seconds".
                          {"cpu_seconds", process_cpu_seconds() - cpu0},
                          {"checkpoint", wrote_this_iteration},
                          {"checkpoint_seconds", checkpoint_seconds - before}});
    if (evaluation.is_object()) iterations.back().update(evaluation);
    if (signalled() && !info.last()) {
      interrupted = true;
      break;
    }
  }
  deadline.reset();
  // The finished render replaces any checkpoint a re-run would continue from.
  if (ended_by_time_limit && checkpoints) write();

  IterationResult result;
  result.interrupted = interrupted;
  result.ended_by_time_limit = pos.finished;
  std::tie(result.spp_min, result.spp_max) = spp_range(pos, sizes, cumulative, film.pixel_count(), cfg.adaptive);
  result.dropped_samples = acc.total.dropped.load() + film.dropped.load();
  if (!interrupted) {
    result.image = acc.resolve();
    result.weight = acc.total.weight;
    if (cfg.keep_sums) result.sums = film_sums_image(acc.total, "sum.");
  }
  double wall = seconds_since(t0);
  nlohmann::json slot_seconds;
  for (size_t s = 0; s < size_t(BetweenIterationSlot::Count); ++s)
    slot_seconds[kSlotNames[s]] = tasks.seconds(BetweenIterationSlot(s));
  slot_seconds["end_hooks"] = tasks.end_hook_seconds();  // the recorder's end_iteration(): sort and training
  result.log = {{"schedule", sizes},
                {"schedule_switch", switch_log},
                {"combination", combination_name(cfg.combination)},
                {"combination_used", acc.choice().log()},
                {"resumed", resumed},
                {"resumed_at_iteration", first_iteration},
                {"time_limit",
                 {{"seconds", cfg.time_limit},
                  {"reached", pos.finished},
                  {"reached_in_this_run", ended_by_time_limit},
                  {"elapsed_seconds", seconds_since(cfg.clock_start)}}},
                {"spp_per_pixel", {{"min", result.spp_min}, {"max", result.spp_max}}},
                {"iterations", iterations},
                {"between_iteration_seconds", slot_seconds},
                {"checkpoint",
                 {{"dir", cfg.checkpoint.dir},
                  {"skipping", !cfg.checkpoint.every_iteration},
                  {"written", checkpoints_written},
                  {"failed_writes", failed_checkpoint_writes},
                  {"seconds", checkpoint_seconds},
                  {"wall_seconds", wall},
                  {"share_of_wall", wall > 0 ? checkpoint_seconds / wall : 0.0}}}};
  if (checkpoints)
    log_info("checkpoints: {} written, {:.3f} s = {:.2f}% of {:.2f} s wall ({})", checkpoints_written,
             checkpoint_seconds, wall > 0 ? 100.0 * checkpoint_seconds / wall : 0.0, wall,
             cfg.checkpoint.every_iteration ? "after every iteration" : "with skipping");
  return result;
}

}  // namespace theia
