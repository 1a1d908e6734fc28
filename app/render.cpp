#include "app/render.h"

#include "app/progress.h"
#include "checkpoint/fingerprint.h"
#include "core/atomic_file.h"
#include "core/hash.h"
#include "core/log.h"
#include "core/metrics.h"
#include "core/stats.h"
#include "farm/part.h"
#include "scene/mipmap.h"
#include "scene/parser.h"
#include "scene/texture.h"
#include "scheduler/driver.h"
#include "wavefront/engine.h"

#include <tbb/global_control.h>
#include <tbb/info.h>

#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>

#include <unistd.h>

namespace theia {

namespace fs = std::filesystem;

// 2^32 and more would overflow the engine's 32-bit path slots and ray counts.
static constexpr size_t kMaxEngineSize = size_t(1) << 32;

void check(const RenderOptions& c) {
  if (c.spp == 0 || c.spp < -1) throw_error("--spp must be positive, got {}", c.spp);
  if (c.max_depth < -1) throw_error("--max-depth must be zero or positive, got {}", c.max_depth);
  if (c.threads < 0) throw_error("--threads must be zero (all cores) or positive, got {}", c.threads);
  if (c.batch_size >= kMaxEngineSize)
    throw_error("--batch-size must be 0 (auto) or below 2^32, got {}", c.batch_size);
  if (c.max_paths >= kMaxEngineSize) throw_error("--max-paths must be 0 (auto) or below 2^32, got {}", c.max_paths);
  if (!(c.memory_limit >= 0.0 && std::isfinite(c.memory_limit)))
    throw_error("--memory-limit must be zero (the machine's memory) or a positive number of MB, got {}",
                c.memory_limit);
  if (!(c.roughening >= 0.0f && c.roughening <= 1.0f))
    throw_error("--roughening must be a number in [0, 1], got {}", c.roughening);
  if (c.throughput_reset_bounce < -1)
    throw_error("--throughput-reset-bounce must be zero or positive, got {}", c.throughput_reset_bounce);
}

// A split frame's parts must merge without bias: guiding learns within each
// part on its own (part_learning), but adaptive sampling's per-pixel counts
// and inverse-variance weights do not fit a part's range and sums
// (farm/README.md says why), and a part must render its whole range (no time
// limit).
static void check_split(const RenderConfig& c) {
  parse_sample_range(c.sample_range);
  auto refuse = [&](const char* flag, const char* why) {
    throw_error("--sample-range cannot be combined with {}: {}", flag, why);
  };
  if (c.adaptive.enabled)
    refuse("--adaptive", "a pixel's extra samples would take the sample indices of the next part's range (capped "
                         "at the part's range, nothing is left to adapt)");
  if (c.combine == "inverse-variance") refuse("--combine inverse-variance", "its weights compare the iterations of one render");
  if (RecorderFeature::debug_layers(c.recorder)) refuse("--recorder-debug", "its buffers are not part of the film");
  if (c.time_limit > 0) refuse("--time-limit", "a part must render its whole range");
}

void check_config(const RenderConfig& c) {
  check(static_cast<const RenderOptions&>(c));
  check(static_cast<const LightSamplerOptions&>(c));
  check(static_cast<const SchedulingOptions&>(c));
  check(c.recorder);
  check(c.guiding);
  check(static_cast<const FieldOptions&>(c), c.guiding.on());
  check(c.caustics);
  check(c.checkpoint);
  if (RecorderFeature::debug_layers(c.recorder) && !c.checkpoint.dir.empty())
    throw_error("--recorder-debug cannot be combined with --checkpoint-dir: the debug buffers are not checkpointed");
  if (c.aov_events && c.combine == "inverse-variance")
    throw_error("--aov-events cannot be combined with --combine {}: the layers are equal-weight sums and would not "
                "add up to a weighted beauty",
                c.combine);
  if (!c.sample_range.empty()) check_split(c);
}

uint64_t options_fingerprint(const RenderConfig& c) {
  RenderConfig declared = c;
  OptionFingerprintText text;
  declare_render_options(text, declared);
  return hash_bytes(text.text.data(), text.text.size());
}

// Where --guiding-auto cannot pay, it is off from the first sample.  A
// render shorter than guiding's training budget cannot earn back what
// training costs (each training sample 1.4-2.5x an unguided one; on
// cornell-box at 64 spp --guiding-auto took 1.6-1.9x the CPU time), and the
// recorder's debug layers need the recorder on every sample, which auto stops
// when it turns guiding off.
static std::string guiding_auto_off_because(const RenderConfig& c) {
  if (!c.guiding.judged()) return {};
  if (RecorderFeature::debug_layers(c.recorder)) return "--recorder-debug";
  const int training = judged_training_spp(c.guiding.training_spp);
  // Guiding pays for its training with the samples after it: a render that
  // ends within training has none.
  if (c.spp <= training)
    return fmt::format("the render's {} spp leave none after training's {}", c.spp, training);
  return {};
}

// The options with the scene's choices filled in (spp, maximum depth) and
// the schedule named: what the render, its fingerprint and its log use.
static RenderConfig resolve(const RenderConfig& config, const Scene& scene) {
  RenderConfig c = config;
  if (c.spp < 0) c.spp = scene.settings.spp;
  if (c.max_depth < 0) c.max_depth = scene.settings.max_depth;
  if (c.spp <= 0) throw_error("{}: the scene asks for {} samples per pixel; use --spp", scene.path, c.spp);
  c.guiding_off_because = guiding_auto_off_because(c);
  if (!c.guiding_off_because.empty()) c.guiding.enabled = OnOffAuto::Off;
  c.schedule = schedule_name(c, c.guiding.on());
  c.combine = combine_name(c, c.guiding.on(),
                           !c.sample_range.empty() || c.aov_events || RecorderFeature::debug_layers(c.recorder));
  if (!c.sample_range.empty()) c.caustics.may_switch_off = false;
  return c;
}

// Read before the render clock starts: the reference is not part of the render.
static ImageBuffer read_reference(const std::string& path, const Scene& scene) {
  if (path.empty()) return {};
  ImageBuffer reference = read_image_file(path);
  if (reference.width != scene.film.width || reference.height != scene.film.height)
    throw_error("--reference {}: the image is {}x{}, the film is {}x{}", path, reference.width, reference.height,
                scene.film.width, scene.film.height);
  if (reference.channels.size() < 3)
    throw_error("--reference {}: expected an RGB image, found {} channel(s)", path, reference.channels.size());
  return reference;
}

static std::unique_ptr<tbb::global_control> limit_threads(int threads) {
  if (threads <= 0) return nullptr;
  return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);
}

// The caustic pass's light paths cannot be counted with per-pixel sample
// ranges (adaptive sampling) or by the recorder's debug comparisons, which
// see camera paths only; it has nothing to do below maximum depth 2.
static std::string caustics_conflict(const RenderConfig& c, const Scene& scene) {
  if (scene.has_media()) return "participating media (its light paths do not track them)";
  if (c.adaptive.enabled) return "adaptive sampling";
  if (RecorderFeature::debug_layers(c.recorder)) return "recorder debug layers";
  if (c.throughput_reset_bounce >= 0) return "--throughput-reset-bounce";
  if (c.max_depth < 2) return "a maximum depth below 2 (no camera path reaches a light through a caster)";
  return {};
}

// Every feature, built in the order they feed each other (guiding's trainer
// takes the recorder's samples).
struct Features {
  LightSamplerFeature light_sampler;
  GuidingFeature guiding;
  FieldFeature field;
  RecorderFeature recorder;
  CausticsFeature caustics;
  AdaptiveFeature adaptive;

  Features(const RenderConfig& c, RenderableScene& rs, const std::vector<int>& schedule, uint32_t first_sample)
      : light_sampler(*rs.light_sampler),
        guiding(c.guiding, rs.accel.bounds(), schedule, RecorderFeature::debug_layers(c.recorder), first_sample,
                c.time_limit),
        field(c, rs.scene, guiding),
        recorder(c.recorder, c.guiding.on(), c.seed, rs.scene.film.width, rs.scene.film.height, field.sink()),
        caustics(c.caustics, caustics_conflict(c, rs.scene), c.seed, rs),
        adaptive(c.adaptive, rs.scene.film.width, rs.scene.film.height, schedule, c.spp) {}
  // Guiding before field: the field is saved after guiding's update.
  std::array<Feature*, 6> all() { return {&light_sampler, &guiding, &field, &recorder, &caustics, &adaptive}; }
};

// Batch size and pool size 0 (auto): the engine sizes them from the frame (engine_sizes).
static EngineOptions engine_options(const RenderConfig& c, const StopRequest* stop) {
  EngineOptions o;
  o.max_depth = c.max_depth;
  o.seed = c.seed;
  o.batch_size = c.batch_size;
  o.max_paths = c.max_paths;
  o.sort = c.sort;
  o.throughput_reset_bounce = c.throughput_reset_bounce;
  o.stop = stop;
  o.abandon_after_seconds = c.abandon_after_seconds;
  o.footprint_spp = c.spp;
  o.roughening = c.roughening;
  return o;
}

// What learns between iterations: in a split frame's part each learns on its
// own from the part's first sample (farm/README.md), so the merge is
// unbiased but is not the single-process image.
static std::vector<std::string> part_learning(const RenderConfig& c, const RenderableScene& rs) {
  std::vector<std::string> learns;
  if (c.guiding.on()) learns.push_back("guiding");
  if (rs.light_sampler->wants_feedback()) learns.push_back(rs.light_sampler->name());
  return learns;
}

static IterationConfig iteration_config(const RenderConfig& c, const RenderableScene& rs, StopRequest* stop,
                                        std::chrono::steady_clock::time_point render_start) {
  const Scene& scene = rs.scene;
  IterationConfig ic;
  ic.schedule = schedule_options(c.schedule, c.iteration);
  ic.total_spp = c.spp;
  ic.combination = parse_combination(c.combine);
  ic.combine_window = uint32_t(c.combine_window);
  ic.seed = c.seed;
  ic.checkpoint = c.checkpoint;
  ic.resume = c.resume;
  ic.scene_hash = scene_fingerprint(scene);
  ic.options_hash = options_fingerprint(c);
  ic.stop = stop;
  ic.time_limit = c.time_limit;
  ic.clock_start = render_start;
  if (!c.sample_range.empty()) {
    const SampleRange r = parse_sample_range(c.sample_range);
    ic.sample_begin = r.begin;
    ic.sample_end = r.end;
    ic.keep_sums = true;
    ic.part_learns = !part_learning(c, rs).empty();
    // A part's checkpoint is resumed only by the same range.
    ic.options_hash = hash(ic.options_hash, uint64_t(r.begin), uint64_t(r.end));
  }
  return ic;
}

// Error against run time (--reference): the render clock (accel build
// onwards, scene loading excluded) does not count the time spent measuring.
struct ReferenceEvaluation {
  const ImageBuffer& reference;
  std::chrono::steady_clock::time_point wall_start, render_start;
  double seconds = 0.0;

  nlohmann::json operator()(const IterationInfo& it, const ImageAccumulator& acc) {
    auto te = std::chrono::steady_clock::now();
    ImageBuffer image = acc.resolve();
    nlohmann::json e = {{"spp_total", it.spp_end},
                        {"wall_seconds", seconds_since(wall_start)},
                        {"render_seconds", seconds_since(render_start) - seconds},
                        {"rel_mse", rel_mse(image, reference)},
                        {"rmse", rmse(image, reference)},
                        {"mape", mape(image, reference)},
                        {"dropped_samples", acc.total.dropped.load()}};
    seconds += seconds_since(te);
    e["evaluation_seconds"] = seconds;
    return e;
  }
};

// The engine's share of the log: time per phase, rays, paths, memory.
static void write_engine_log(nlohmann::json& log, const WavefrontEngine& engine, const RenderableScene& rs,
                             const Film& film) {
  const EngineStats& st = engine.stats();
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
                  {"peak_live", st.peak_live_paths},
                  {"pool", engine.sizes().max_paths},
                  {"batch_size", engine.sizes().batch_size},
                  {"lanes", engine.sizes().lanes}};
  log["memory"] = {{"peak_rss", peak_rss_bytes()},
                   {"accel", rs.accel.memory_bytes()},
                   {"film", film.memory_bytes()},
                   {"textures", texture_memory_bytes(rs.scene)},
                   {"texture_mips", mip_memory_bytes(rs.scene)},
                   {"wavefront", engine.memory_bytes()},
                   {"peak_queued_rays", st.peak_queued_rays},
                   {"peak_queued_shadow_rays", st.peak_queued_shadow_rays}};
}

// log["options"]: every option under its one name, as the render used it.
static nlohmann::json options_log(const RenderConfig& c) {
  RenderConfig used = c;
  if (used.threads <= 0) used.threads = tbb::info::default_concurrency();
  OptionLog log;
  declare_render_options(log, used);
  return log.json;
}

// What the merge checks a split frame's part against the others with.
static PartInfo part_info(const RenderConfig& c, const IterationConfig& ic, const RenderableScene& rs) {
  PartInfo p;
  p.learns = part_learning(c, rs);
  p.range = {ic.sample_begin, ic.sample_end};
  p.spp = c.spp;
  p.scene_fingerprint = ic.scene_hash;
  p.options_fingerprint = options_fingerprint(c);
  p.seed = c.seed;
  RenderConfig declared = c;
  OptionLog log;
  log.image_only = true;
  declare_render_options(log, declared);
  p.image_options = log.json;
  return p;
}

static RenderResult make_result(IterationResult iterations, Features& features, const RenderConfig& c,
                                const WavefrontEngine& engine, const RenderableScene& rs, const Film& film) {
  RenderResult result;
  result.image = std::move(iterations.image);
  result.interrupted = iterations.interrupted;
  result.weight = iterations.weight;
  result.sums = std::move(iterations.sums);
  // The recorder's debug buffers sum over every iteration: they share the
  // combined film's per-pixel weight (compare them with --combine equal).
  if (!iterations.interrupted) append_film_layers(result.image, features.recorder.layers(), iterations.weight);
  nlohmann::json& log = result.log;
  write_engine_log(log, engine, rs, film);
  log["scheduler"] = iterations.log;
  log["scene"] = rs.scene.path;
  log["resolution"] = {rs.scene.film.width, rs.scene.film.height};
  log["options"] = options_log(c);
  for (Feature* f : features.all()) f->write_log(log);
  if (!c.guiding_off_because.empty()) log["guiding"]["auto"] = {{"verdict", "off"}, {"why", c.guiding_off_because}};
  if (!c.reference_path.empty()) log["reference"] = c.reference_path;
  log["dropped_samples"] = iterations.dropped_samples;
  if (c.aov_events) log["aov_event_layers"] = event_layer_names();
  log["warnings"] = warning_count();
  return result;
}

// --memory-limit in bytes; 0 means the machine's physical memory.
static double memory_limit_bytes(const RenderConfig& c) {
  if (c.memory_limit > 0.0) return c.memory_limit * 1e6;
  return double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGESIZE));
}

// What --memory-limit leaves for the scene's images once its geometry is
// loaded: each image's pixels are checked against it before they are allocated.
static uint64_t image_bytes_left(const RenderConfig& c) {
  const double left = memory_limit_bytes(c) - double(peak_rss_bytes());
  return left > 0.0 ? uint64_t(left) : 0;
}

// A path's share of the engine at its peak: its 64-byte state, a
// continuation and a shadow ray with their hits, sort keys and queue slots
// (memory.wavefront / paths.pool in a log is below this).
static constexpr double kBytesPerPath = 512.0;

// The film (iteration film, running sum and the resolved image) and the path
// pool, checked before anything is allocated: a huge resolution or
// --max-paths is a clear error, not a std::bad_alloc.
static void check_memory(const RenderConfig& c, const Scene& scene) {
  const double limit = memory_limit_bytes(c);
  const double mb = 1e-6;
  const double scene_bytes = double(peak_rss_bytes());
  const double pixels = double(scene.film.width) * double(scene.film.height);
  const double planes = Film::kPlaneCount + (c.aov_events ? Film::kEventPlaneCount : 0);
  const double film_bytes = pixels * (2.0 * planes + 11.0 + (c.aov_events ? Film::kEventPlaneCount : 0)) * sizeof(float);
  const int threads = c.threads > 0 ? c.threads : tbb::info::default_concurrency();
  const EngineSizes sizes = engine_sizes(engine_options(c, nullptr), uint64_t(pixels), threads);
  const double pool_bytes = double(sizes.max_paths) * kBytesPerPath;
  if (scene_bytes + film_bytes + pool_bytes <= limit) return;
  throw_error("{}: the render needs about {:.0f} MB (scene {:.0f} MB as loaded, film {}x{} {:.0f} MB, path pool of {} "
              "paths {:.0f} MB), over the memory limit of {:.0f} MB (--memory-limit, 0: the machine's memory)",
              scene.path, (scene_bytes + film_bytes + pool_bytes) * mb, scene_bytes * mb, scene.film.width,
              scene.film.height, film_bytes * mb, sizes.max_paths, pool_bytes * mb, limit * mb);
}

// Builds every feature, hands their hooks, tasks and checkpoint sections to
// the engine and the scheduler, renders the iterations, collects the log.
RenderResult render_scene(const Scene& scene, const RenderConfig& config) {
  check_config(config);
  const RenderConfig c = resolve(config, scene);
  check_memory(c, scene);
  const auto threads = limit_threads(c.threads);
  const auto wall_start = c.wall_start.value_or(std::chrono::steady_clock::now());
  const ImageBuffer reference = read_reference(c.reference_path, scene);

  const auto render_start = std::chrono::steady_clock::now();
  StopRequest own_stop;
  StopRequest* stop = c.stop ? c.stop : &own_stop;
  RenderableScene rs(scene, c.light_sampler);
  Film film(scene.film.width, scene.film.height, c.aov_events);
  IterationConfig ic = iteration_config(c, rs, stop, render_start);
  const std::vector<int> sizes = iteration_sizes(ic);
  Features features(c, rs, sizes, ic.sample_begin);
  EngineOptions engine_opt = engine_options(c, stop);
  EngineHooks hooks{.observer = features.recorder.recorder()};
  IterationTasks tasks;
  for (Feature* f : features.all()) {
    f->configure(engine_opt, hooks);
    f->add_tasks(tasks);
    f->add_participants(ic.participants);
  }
  WavefrontEngine engine(rs, film, engine_opt, hooks);
  for (Feature* f : features.all()) f->attach(engine);
  ic.adaptive = features.adaptive.sampler();
  ic.switch_schedule = [&](const IterationInfo& it) { return features.guiding.schedule_after(it); };
  ic.settled_from = [&] { return features.guiding.settled_from(); };

  ProgressBar bar(c.progress);
  ic.progress = [&](int it, double fraction, double of_render) {
    bar.update(of_render, engine.stats().total_rays());
    if (c.on_iteration_progress) c.on_iteration_progress(it, fraction);
  };
  ReferenceEvaluation evaluation{reference, wall_start, render_start};
  if (!c.reference_path.empty()) ic.evaluate = std::ref(evaluation);

  IterationResult iterations = render_iterations(engine, film, tasks, ic);
  RenderResult result = make_result(std::move(iterations), features, c, engine, rs, film);
  if (!c.sample_range.empty()) result.log["part"] = part_json(part_info(c, ic, rs));
  return result;
}

// An output that cannot be written fails now, not after the render: a
// directory, a missing or read-only directory.
static void check_output_path(const std::string& flag, const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw_error("{} {}: is a directory, expected a file name", flag, path);
  fs::path dir = fs::path(path).parent_path();
  if (dir.empty()) dir = ".";
  if (!fs::is_directory(dir, ec)) throw_error("{} {}: the directory {} does not exist", flag, path, dir.string());
  if (::access(dir.c_str(), W_OK) != 0) throw_error("{} {}: the directory {} is not writable", flag, path, dir.string());
}

// The outputs default to the scene's film name; each is checked before rendering.
static void resolve_output_paths(RenderConfig& config, const Scene& scene) {
  if (config.output.empty()) config.output = fs::path(scene.film.filename).replace_extension(".exr").string();
  if (fs::path(config.output).extension() != ".exr") throw_error("-o {}: the output must be an .exr file", config.output);
  if (config.log_path.empty()) config.log_path = fs::path(config.output).replace_extension(".json").string();
  check_output_path("-o", config.output);
  check_output_path("--log", config.log_path);
  if (!config.save_field.empty()) check_output_path("--save-field", config.save_field);
}

// What was rendered, where it went, and what the user must know about it.
static void log_summary(const nlohmann::json& log, const RenderConfig& config, const std::string& png) {
  const nlohmann::json& spp = log["scheduler"]["spp_per_pixel"];
  const std::string samples = spp["min"] == spp["max"] ? fmt::format("{}", spp["min"].get<uint32_t>())
                                                       : fmt::format("{}-{}", spp["min"].get<uint32_t>(),
                                                                     spp["max"].get<uint32_t>());
  const nlohmann::json& limit = log["scheduler"]["time_limit"];
  const std::string ended =
      limit["reached"].get<bool>()
          ? fmt::format(" (of {}: --time-limit {} s reached at {:.2f} s)", log["options"]["spp"].get<int>(),
                        limit["seconds"].get<double>(), limit["elapsed_seconds"].get<double>())
          : "";
  log_info("rendered {} spp{} in {:.2f} s ({:.2f} Mrays/s); wrote {}, {}, {}", samples, ended,
           log["time"]["render"].get<double>(), log["mrays_per_second"]["render"].get<double>(), config.output, png,
           config.log_path);
  if (log.contains("aov_event_layers")) log_event_layers(config.output);
  if (limit["reached"].get<bool>() && spp["max"].get<uint32_t>() == 0)
    log_warning("--time-limit {} s was spent before the first sample: the image is black",
                limit["seconds"].get<double>());
  if (log["dropped_samples"].get<uint64_t>() > 0)
    log_warning("{} non-finite or overflowing (beyond 1e30) samples were dropped", log["dropped_samples"].get<uint64_t>());
}

int run_render(const RenderConfig& in) {
  RenderConfig config = in;
  check_config(config);
  if (!config.sample_range.empty() && !config.log_path.empty())
    throw_error("--sample-range cannot be combined with --log: a part's log is PART.json beside PART.exr, where the "
                "merge reads it");
  auto t0 = std::chrono::steady_clock::now();
  if (!config.wall_start) config.wall_start = t0;
  Scene scene = load_scene(config.scene_path);
  load_images(scene, image_bytes_left(config));
  double load_seconds = seconds_since(t0);
  log_info("loaded {} in {:.2f} s: {} shapes, {} lights, {}x{}", config.scene_path, load_seconds, scene.shapes.size(),
           scene.lights.size(), scene.film.width, scene.film.height);
  if (scene.lights.empty())
    log_warning("{}: the scene has no light source (LightSource, or AreaLightSource before a Shape); the image "
                "will be black", config.scene_path);

  resolve_output_paths(config, scene);

  RenderResult result = render_scene(scene, config);
  if (result.interrupted) {
    if (config.checkpoint.dir.empty())
      log_warning("stopped before the end; without --checkpoint-dir nothing was kept");
    else
      log_info("stopped before the end; state saved in {}; run the same command to resume", config.checkpoint.dir);
    return kExitInterrupted;
  }
  std::string png = fs::path(config.output).replace_extension(".png").string();
  write_exr(config.output, config.sample_range.empty() ? result.image : part_image(result.image, result.sums));
  write_png_srgb(png, result.image, 0, 1, 2);

  result.log["time"]["load"] = load_seconds;
  result.log["time"]["total"] = seconds_since(t0);
  result.log["outputs"] = {config.output, png};
  write_text_atomically(config.log_path, result.log.dump(2) + "\n");

  log_summary(result.log, config, png);
  return 0;
}

}  // namespace theia
