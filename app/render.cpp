#include "app/render.h"

#include "app/progress.h"
#include "cachepoints/light_sampler.h"
#include "core/log.h"
#include "core/metrics.h"
#include "core/stats.h"
#include "guiding/sd_tree.h"
#include "radiance_recorder/recorder.h"
#include "scene/parser.h"
#include "scene/mipmap.h"
#include "scene/texture.h"
#include "checkpoint/fingerprint.h"
#include "core/hash.h"
#include "scheduler/driver.h"
#include "wavefront/engine.h"

#include <tbb/global_control.h>
#include <tbb/info.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>

namespace theia {

namespace fs = std::filesystem;

static void check_config(const RenderConfig& c) {
  if (c.spp == 0 || c.spp < -1) throw_error("--spp must be positive, got {}", c.spp);
  if (c.max_depth < -1) throw_error("--max-depth must be zero or positive, got {}", c.max_depth);
  if (c.threads < 0) throw_error("--threads must be zero (all cores) or positive, got {}", c.threads);
  if (c.batch_size == 0) throw_error("--batch-size must be positive");
  if (c.max_paths == 0) throw_error("--max-paths must be positive");
  if (c.recorder_debug_bounce < -1) throw_error("--recorder-debug-bounce must be zero or positive, got {}", c.recorder_debug_bounce);
  if (c.throughput_reset_bounce < -1)
    throw_error("--throughput-reset-bounce must be zero or positive, got {}", c.throughput_reset_bounce);
  if (!(c.recorder_budget >= 0.0f)) throw_error("--recorder-budget must be zero (off) or positive, got {}", c.recorder_budget);
  if (!(c.recorder_vertex_skip >= 0.0f && c.recorder_vertex_skip < 1.0f))
    throw_error("--recorder-vertex-skip must be in [0, 1), got {}", c.recorder_vertex_skip);
  if (!(c.recorder_min_distance >= 0.0f))
    throw_error("--recorder-min-distance must be zero or positive, got {}", c.recorder_min_distance);
  if ((c.recorder_debug || c.recorder_debug_bounce >= 0) && !c.checkpoint_dir.empty())
    throw_error("--recorder-debug cannot be combined with --checkpoint-dir: the debug buffers are not checkpointed");
  if (!(c.guiding_fraction >= 0.0f && c.guiding_fraction < 1.0f))
    throw_error("--guiding-fraction must be in [0, 1) (the BSDF must keep some share, or directions the guide "
                "has not learned would never be sampled), got {}", c.guiding_fraction);
  if (!(c.guiding_min_roughness >= 0.0f))
    throw_error("--guiding-min-roughness must be zero or positive, got {}", c.guiding_min_roughness);
  if (!(c.guiding_spatial_threshold > 0.0f && std::isfinite(c.guiding_spatial_threshold)))
    throw_error("--guiding-spatial-threshold must be positive, got {}", c.guiding_spatial_threshold);
  if (!(c.caustic_roughness >= 0.0f && c.caustic_roughness <= 1.0f))
    throw_error("--caustic-roughness must be in [0, 1], got {}", c.caustic_roughness);
  if (!c.schedule.empty() && c.schedule != "regular" && c.schedule != "guiding")
    throw_error("--schedule {}: expected regular or guiding", c.schedule);
  if (c.checkpoint_first_ideal <= 0)
    throw_error("--checkpoint-first must be positive, got {}", c.checkpoint_first_ideal);
}

// Guiding learns between iterations, so it wants its small early iterations.
static std::string schedule_name(const RenderConfig& c) {
  return !c.schedule.empty() ? c.schedule : c.guiding ? "guiding" : "regular";
}

static ScheduleOptions schedule_options(const RenderConfig& c) {
  ScheduleOptions o = schedule_name(c) == "guiding" ? guiding_schedule() : regular_schedule();
  if (c.iteration_first >= 0) o.first_size = c.iteration_first;
  if (c.iteration_repeat >= 0) o.repeat_first = c.iteration_repeat;
  if (c.iteration_max >= 0) o.max_size = c.iteration_max;
  if (c.iteration_growth != 0.0) o.growth = c.iteration_growth;
  return o;
}

// The options that change the image; threads, batch size, pool size and
// sorting change only the floating-point summation order.
static uint64_t options_fingerprint(const RenderConfig& c, int spp, int max_depth, const ScheduleOptions& s) {
  std::string text = fmt::format("{} {} {} {} {} {} {} {} {} {} {}", spp, max_depth, c.seed, c.light_sampler,
                                 s.first_size, s.repeat_first, s.growth, s.max_size, c.combine,
                                 c.checkpoint_first_ideal, c.adaptive);
  if (c.caustics) text += fmt::format(" caustics {}", c.caustic_roughness);
  if (c.guiding)
    text += fmt::format(" guiding {} {} {} {} {} {}", c.guiding_fraction, c.guiding_min_roughness,
                        c.guiding_spatial_threshold, c.recorder_budget, c.recorder_vertex_skip, c.recorder_min_distance);
  return hash_bytes(text.data(), text.size());
}

// The recorder's training samples, as the SD-tree takes them: scalar
// (luminance) radiance, only from directions that had a density (a delta
// lobe's sample says nothing about a directional distribution).  The key
// names the vertex, so the field's spatial jitter is a function of the path.
class SDTreeTrainer final : public TrainingSampleSink {
 public:
  explicit SDTreeTrainer(SDTree& tree) : tree_(tree) {}
  void consume(std::span<const TrainingSample> samples) override {
    for (const TrainingSample& s : samples) {
      if (s.flags & kVertexDelta) continue;
      tree_.add_sample(s.p, s.wi, luminance(s.radiance), s.pdf, hash(s.pixel, s.sample, s.depth, s.flags));
    }
  }

 private:
  SDTree& tree_;
};

RenderResult render_scene(const Scene& scene, const RenderConfig& config) {
  check_config(config);
  std::unique_ptr<tbb::global_control> threads;
  if (config.threads > 0)
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, config.threads);

  const int spp = config.spp > 0 ? config.spp : scene.settings.spp;
  const int max_depth = config.max_depth >= 0 ? config.max_depth : scene.settings.max_depth;
  if (spp <= 0) throw_error("{}: the scene asks for {} samples per pixel; use --spp", scene.path, spp);

  const auto wall_start = config.wall_start.value_or(std::chrono::steady_clock::now());
  // Read before the render clock starts: the reference is not part of the render.
  ImageBuffer reference;
  if (!config.reference_path.empty()) {
    reference = read_image_file(config.reference_path);
    if (reference.width != scene.film.width || reference.height != scene.film.height)
      throw_error("--reference {}: the image is {}x{}, the film is {}x{}", config.reference_path, reference.width,
                  reference.height, scene.film.width, scene.film.height);
    if (reference.channels.size() < 3)
      throw_error("--reference {}: expected an RGB image, found {} channel(s)", config.reference_path,
                  reference.channels.size());
  }

  auto t0 = std::chrono::steady_clock::now();
  RenderableScene rs(scene, config.light_sampler);
  Film film(scene.film.width, scene.film.height);

  EngineOptions opt;
  EngineHooks hooks;
  opt.max_depth = max_depth;
  opt.seed = config.seed;
  opt.batch_size = config.batch_size;
  opt.max_paths = config.max_paths;
  opt.sort = config.sort;
  opt.throughput_reset_bounce = config.throughput_reset_bounce;

  // Guiding: the field the engine samples, trained from the recorder's samples.
  std::unique_ptr<SDTree> sd_tree;
  std::unique_ptr<SDTreeTrainer> trainer;
  if (config.guiding) {
    SDTreeOptions go;
    go.selection_probability = config.guiding_fraction;
    go.spatial_threshold = config.guiding_spatial_threshold;
    sd_tree = std::make_unique<SDTree>(rs.accel.bounds(), go);
    trainer = std::make_unique<SDTreeTrainer>(*sd_tree);
    hooks.guide = sd_tree.get();
    opt.guiding_min_roughness = config.guiding_min_roughness;
  }
  // The caustic pass (on by default) stays off where its light paths could
  // not be counted: per-pixel sample ranges (adaptive sampling) and the
  // recorder's debug comparisons, which see camera paths only.
  std::unique_ptr<CausticTracer> caustics;
  std::string caustics_off;
  if (!config.caustics) caustics_off = "--no-caustics";
  else if (config.adaptive) caustics_off = "adaptive sampling";
  else if (config.recorder_debug || config.recorder_debug_bounce >= 0) caustics_off = "recorder debug layers";
  else if (config.throughput_reset_bounce >= 0) caustics_off = "--throughput-reset-bounce";
  else if (max_depth < 2) caustics_off = "a maximum depth below 2 (no camera path reaches a light through a caster)";
  if (caustics_off.empty()) {
    caustics = std::make_unique<CausticTracer>(rs.scene, rs.accel, rs.lights, rs.camera, rs.filter,
                                               CausticOptions{config.caustic_roughness, config.seed});
    caustics_off = caustics->inactive_reason();
    if (caustics->active()) hooks.caustics = caustics.get();
  }
  // The recorder costs nothing unless a debug buffer or guiding consumes it.
  std::unique_ptr<RadianceRecorder> recorder;
  if (config.recorder_debug || config.recorder_debug_bounce >= 0 || config.guiding) {
    RecorderOptions ro;
    ro.vertex_budget = config.recorder_budget;
    ro.vertex_skip_probability = config.recorder_vertex_skip;
    ro.min_distance = config.recorder_min_distance;
    ro.seed = config.seed;
    ro.width = scene.film.width;
    ro.height = scene.film.height;
    ro.debug_primary = config.recorder_debug;
    ro.debug_bounce = config.recorder_debug_bounce;
    recorder = std::make_unique<RadianceRecorder>(ro, trainer.get());
  }
  opt.stop = config.stop;
  // Consistent alpha: with adaptive sampling alpha counts exactly spp samples per pixel.
  opt.alpha_spp = config.adaptive ? uint32_t(spp) : 0;
  opt.footprint_spp = spp;
  const ScheduleOptions schedule = schedule_options(config);
  hooks.observer = recorder.get();
  WavefrontEngine engine(rs, film, opt, hooks);

  IterationConfig ic;
  ic.schedule = schedule;
  ic.total_spp = spp;
  ic.combination = parse_combination(config.combine);
  ic.seed = config.seed;
  ic.checkpoint_dir = config.checkpoint_dir;
  ic.resume_required = config.resume;
  ic.checkpoint_every_iteration = config.checkpoint_every_iteration;
  ic.checkpoint_first_ideal = config.checkpoint_first_ideal;
  ic.scene_hash = scene_fingerprint(scene);
  ic.options_hash = options_fingerprint(config, spp, max_depth, ic.schedule);
  ic.stop = config.stop;
  std::unique_ptr<AdaptiveSampler> adaptive;
  if (config.adaptive) {
    adaptive = std::make_unique<AdaptiveSampler>(film.width, film.height, make_schedule(schedule, spp), uint32_t(spp));
    ic.adaptive = adaptive.get();
  }
  const std::vector<int> cumulative = cumulative_spp(make_schedule(ic.schedule, spp));
  ProgressBar bar(config.progress);
  const EngineStats& st = engine.stats();
  ic.progress = [&](int it, double fraction) {
    double before = it > 0 ? cumulative[size_t(it) - 1] : 0;
    bar.update((before + fraction * (cumulative[size_t(it)] - before)) / spp, st.total_rays());
    if (config.on_iteration_progress) config.on_iteration_progress(it, fraction);
  };
  // Subsystems register their between-iteration work here, one line each
  // (guiding update, cache-point update, adaptive sampler, recorder skip rate).
  IterationTasks tasks;
  if (recorder) {
    tasks.on_begin([&](const IterationInfo&) { recorder->begin_iteration(); });
    tasks.on_end([&](const IterationInfo&) { recorder->end_iteration(); });
    tasks.add(BetweenIterationSlot::RecorderSkipRateUpdate, [&](const IterationInfo&) { recorder->update_skip_rate(); });
  }
  // The caustic pass's switch-off counters survive a resume, so a resumed
  // render switches it off (or not) where an uninterrupted one does.
  if (hooks.caustics)
    ic.participants.push_back({"caustics", 1,
                               [&] {
                                 ByteWriter w;
                                 w.put(caustics->stats());
                                 w.put(int32_t(caustics->passes()));
                                 return w.bytes;
                               },
                               [&](const CheckpointSection& section) {
                                 ByteReader r(section.bytes, "checkpoint section 'caustics'");
                                 CausticStats cs = r.get<CausticStats>();
                                 int passes = r.get<int32_t>();
                                 caustics->restore_stats(cs, passes);
                               }});
  // The field learns from each iteration's samples (handed over by the
  // recorder at the iteration's end); the next iteration samples it.
  if (sd_tree) {
    tasks.add(BetweenIterationSlot::GuidingUpdate,
              [&](const IterationInfo& it) { sd_tree->update(double(it.spp_end - it.spp_begin)); });
    // A resumed render continues the field and the skip rate exactly where
    // the interrupted one left them, so it trains and guides the same.
    ic.participants.push_back({"guiding", 1,
                               [&] {
                                 ByteWriter w;
                                 w.put_vector(sd_tree->serialize());
                                 RadianceRecorder::ResumeState st = recorder->resume_state();
                                 w.put(st.skip_rate);
                                 w.put(st.iteration_paths);
                                 w.put(st.iteration_events);
                                 w.put_vector(st.samples);
                                 return w.bytes;
                               },
                               [&](const CheckpointSection& section) {
                                 ByteReader r(section.bytes, "checkpoint section 'guiding'");
                                 std::vector<uint8_t> tree = r.get_vector<uint8_t>();
                                 *sd_tree = SDTree::deserialize(tree);
                                 RadianceRecorder::ResumeState st;
                                 st.skip_rate = r.get<double>();
                                 st.iteration_paths = r.get<uint64_t>();
                                 st.iteration_events = r.get<uint64_t>();
                                 st.samples = r.get_vector<TrainingSample>();
                                 recorder->restore(st);
                               }});
  }
  // Error against run time: the render clock (accel build onwards, scene loading
  // excluded) does not count the time spent here measuring the error.
  double evaluation_seconds = 0.0;
  if (!config.reference_path.empty())
    ic.evaluate = [&](const IterationInfo& it, const ImageAccumulator& acc) {
      auto te = std::chrono::steady_clock::now();
      ImageBuffer image = acc.resolve(ic.combination);
      nlohmann::json e = {{"spp_total", it.spp_end},
                          {"wall_seconds", seconds_since(wall_start)},
                          {"render_seconds", seconds_since(t0) - evaluation_seconds},
                          {"rel_mse", rel_mse(image, reference)},
                          {"rmse", rmse(image, reference)},
                          {"mape", mape(image, reference)},
                          {"dropped_samples", acc.total.dropped.load()}};
      evaluation_seconds += seconds_since(te);
      e["evaluation_seconds"] = evaluation_seconds;
      return e;
    };
  IterationResult iterations = render_iterations(engine, film, tasks, ic);
  RenderResult result;
  result.image = std::move(iterations.image);
  // The recorder's debug buffers sum over every iteration: they share the
  // combined film's per-pixel weight (compare them with --combine equal).
  std::vector<FilmLayer> layers;
  if (recorder && config.recorder_debug) layers.push_back({"recorder", recorder->debug_primary()});
  if (recorder && config.recorder_debug_bounce >= 0)
    layers.push_back({fmt::format("recorder_bounce{}", config.recorder_debug_bounce), recorder->debug_bounce()});
  if (!iterations.interrupted) append_film_layers(result.image, layers, iterations.weight);
  result.interrupted = iterations.interrupted;

  nlohmann::json& log = result.log;
  log["scheduler"] = iterations.log;
  log["scene"] = scene.path;
  log["resolution"] = {scene.film.width, scene.film.height};
  log["options"] = {{"spp", spp},
                    {"max_depth", max_depth},
                    {"seed", config.seed},
                    {"threads", config.threads > 0 ? config.threads : tbb::info::default_concurrency()},
                    {"batch_size", config.batch_size},
                    {"max_paths", config.max_paths},
                    {"sort", config.sort},
                    {"light_sampler", rs.light_sampler->name()},
                    {"schedule", schedule_name(config)},
                    {"guiding", config.guiding},
                    {"caustics", config.caustics},
                    {"combine", config.combine},
                    {"adaptive", config.adaptive}};
  nlohmann::json phases;
  for (size_t p = 0; p < size_t(Phase::Count); ++p) phases[kPhaseNames[p]] = st.phases.seconds[p];
  phases["accel_build"] = rs.accel_seconds;
  log["time"] = {{"render", st.render_seconds}, {"phases", phases}};
  log["rays"] = {{"camera", st.camera_rays},
                 {"continuation", st.continuation_rays},
                 {"shadow", st.shadow_rays},
                 {"total", st.total_rays()},
                 {"batches", st.batches},
                 {"shadow_batches", st.shadow_batches}};
  double trace_seconds = st.phases[Phase::Trace] + st.phases[Phase::TraceShadow];
  log["mrays_per_second"] = {
      {"render", st.render_seconds > 0 ? double(st.total_rays()) / st.render_seconds * 1e-6 : 0.0},
      {"trace_only", trace_seconds > 0 ? double(st.total_rays()) / trace_seconds * 1e-6 : 0.0}};
  log["paths"] = {{"count", st.paths},
                  {"vertices", st.path_vertices},
                  {"average_length", st.paths ? double(st.path_vertices) / double(st.paths) : 0.0},
                  {"peak_live", st.peak_live_paths}};
  log["memory"] = {{"peak_rss", peak_rss_bytes()},
                   {"accel", rs.accel.memory_bytes()},
                   {"film", film.memory_bytes()},
                   {"textures", texture_memory_bytes(scene)},
                   {"texture_mips", mip_memory_bytes(scene)},
                   {"wavefront", engine.memory_bytes()},
                   {"peak_queued_rays", st.peak_queued_rays},
                   {"peak_queued_shadow_rays", st.peak_queued_shadow_rays}};
  if (recorder) {
    RecorderStats rs = recorder->stats();
    log["recorder"] = {{"vertex_bytes", RadianceRecorder::vertex_bytes()},
                       {"peak_live_vertices", rs.peak_live_vertices},
                       {"peak_bytes", recorder->peak_bytes()},
                       {"blocks", rs.peak_blocks},
                       {"paths", rs.paths},
                       {"skipped_paths", rs.skipped_paths},
                       {"path_skip_rate", rs.path_skip_rate},
                       {"vertex_events", rs.vertex_events},
                       {"recorded_vertices", rs.recorded},
                       {"skipped_vertices", rs.skipped_vertices},
                       {"merged_vertices", rs.merged_vertices},
                       {"dropped", rs.dropped}};
    log["memory"]["recorder"] = recorder->peak_bytes();
  }
  if (sd_tree) {
    SDTreeStats gs = sd_tree->stats();
    log["guiding"] = {{"fraction", config.guiding_fraction},
                      {"min_roughness", config.guiding_min_roughness},
                      {"spatial_threshold", config.guiding_spatial_threshold},
                      {"spatial_leaves", gs.spatial_leaves},
                      {"quadtree_nodes", gs.quadtree_nodes},
                      {"bytes", sd_tree->memory_bytes()}};
    log["memory"]["guiding"] = sd_tree->memory_bytes();
  }
  {
    CausticStats cs = caustics ? caustics->stats() : CausticStats{};
    log["caustics"] = {{"traced", hooks.caustics != nullptr},
                       {"off_because", caustics_off},
                       {"switched_off_after_passes", cs.switched_off_after},
                       {"caster_roughness", config.caustic_roughness},
                       {"paths", cs.paths},
                       {"caster_hits", cs.caster_hits},
                       {"receiver_hits", cs.receiver_hits},
                       {"splats", cs.splats},
                       {"dropped", cs.dropped},
                       {"seconds", cs.seconds}};
  }
  if (config.throughput_reset_bounce >= 0) log["options"]["throughput_reset_bounce"] = config.throughput_reset_bounce;
  if (!config.reference_path.empty()) log["reference"] = config.reference_path;
  log["dropped_samples"] = iterations.dropped_samples;
  log["warnings"] = warning_count();
  return result;
}

static void write_text_atomically(const std::string& path, const std::string& text) {
  std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) throw_error("{}: cannot open for writing", tmp);
    f << text;
    f.flush();
    if (!f) throw_error("{}: write failed", tmp);
  }
  fs::rename(tmp, path);
}

int run_render(const RenderConfig& in) {
  RenderConfig config = in;
  check_config(config);
  auto t0 = std::chrono::steady_clock::now();
  if (!config.wall_start) config.wall_start = t0;
  Scene scene = load_scene(config.scene_path);
  load_images(scene);
  double load_seconds = seconds_since(t0);
  log_info("loaded {} in {:.2f} s: {} shapes, {} lights, {}x{}", config.scene_path, load_seconds, scene.shapes.size(),
           scene.lights.size(), scene.film.width, scene.film.height);

  if (config.output.empty()) config.output = fs::path(scene.film.filename).replace_extension(".exr").string();
  if (fs::path(config.output).extension() != ".exr") throw_error("-o {}: the output must be an .exr file", config.output);
  if (config.log_path.empty()) config.log_path = fs::path(config.output).replace_extension(".json").string();

  RenderResult result = render_scene(scene, config);
  if (result.interrupted) {
    if (config.checkpoint_dir.empty())
      log_warning("stopped before the end; without --checkpoint-dir nothing was kept");
    else
      log_info("stopped before the end; state saved in {}; run the same command to resume", config.checkpoint_dir);
    return kExitInterrupted;
  }
  std::string png = fs::path(config.output).replace_extension(".png").string();
  write_exr(config.output, result.image);
  write_png_srgb(png, result.image, 0, 1, 2);

  result.log["time"]["load"] = load_seconds;
  result.log["time"]["total"] = seconds_since(t0);
  result.log["outputs"] = {config.output, png};
  write_text_atomically(config.log_path, result.log.dump(2) + "\n");

  const auto& log = result.log;
  log_info("rendered {} spp in {:.2f} s ({:.2f} Mrays/s); wrote {}, {}, {}", log["options"]["spp"].get<int>(),
           log["time"]["render"].get<double>(), log["mrays_per_second"]["render"].get<double>(), config.output, png,
           config.log_path);
  if (log["dropped_samples"].get<uint64_t>() > 0)
    log_warning("{} non-finite samples were dropped", log["dropped_samples"].get<uint64_t>());
  return 0;
}

}  // namespace theia
