// `theia render`: load a scene, render it with the wavefront engine, write
// the EXR, the PNG preview and the JSON log.  Tests call render_scene()
// in-process; the command line calls run_render().
#pragma once

#include "app/features.h"
#include "app/field_feature.h"
#include "core/image.h"
#include "core/stop.h"
#include "scene/scene.h"

#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <functional>
#include <optional>
#include <string>

namespace theia {

// The render's own options (no group: --spp, options.spp).
struct RenderOptions {
  int spp = -1;                      // -1: the scene's Sampler pixelsamples
  int threads = 0;                   // 0: all cores
  uint32_t seed = 0;
  int max_depth = -1;                // -1: the scene's Integrator maxdepth
  size_t batch_size = 0;             // 0: auto (the engine sizes it from the frame and thread count)
  size_t max_paths = 0;              // 0: auto
  // Off: measured not to pay on 2 cores at any scene size tried, 1080p over
  // 10.5M triangles included (README, Performance).
  bool sort = false;
  int throughput_reset_bounce = -1;  // >= 0: the beauty is the "throughput reset at bounce N" image
  // The beauty split by each path's first scattering event into EXR layers
  // emission, diffuse, glossy, specular, volume (wavefront/film.h PathEvent).
  bool aov_events = false;
  double memory_limit = 0.0;         // MB the scene, film and path pool may take; 0: the machine's memory
  float roughening = 0.0f;           // path-space regularisation gamma in [0, 1] (EngineOptions::roughening); 0: off
};

template <class V>
void declare_options(V& v, RenderOptions& o) {
  v.image("spp", o.spp, "Samples per pixel (default: the scene's)");
  v.order("threads", o.threads, "Worker threads (0: all cores)");
  v.image("seed", o.seed, "Random seed");
  v.image("max_depth", o.max_depth, "Maximum path depth (default: the scene's)");
  v.order("batch_size", o.batch_size,
          "Rays per batch of each thread's wavefront (0: 1024; sorted, an eighth of a thread's paths)");
  v.order("max_paths", o.max_paths,
          "Paths in flight, all threads' together (0: 8192 a thread; sorted, sized from the frame and thread count)");
  v.order("sort", o.sort, "Sort rays and hits (--sort on|off, --no-sort)");
  v.image("throughput_reset_bounce", o.throughput_reset_bounce,
          "Render the 'throughput reset at bounce N' image as the beauty (default: off)");
  v.image("aov_events", o.aov_events,
          "Also write the beauty split by each path's first scattering event: EXR layers emission, diffuse, "
          "glossy, specular, volume (they sum to R G B)");
  v.image("roughening", o.roughening,
          "Path-space regularisation strength gamma in [0, 1]: each bounce roughens the next vertex's glossy and "
          "specular lobes by the roughness of the lobe that sampled it (0: off; 0.01 blurs caustics a little and "
          "finds them sooner; biased)");
  v.output("memory_limit", o.memory_limit,
           "MB the scene, film and path pool may take, checked before they are allocated (0: the machine's memory)");
}
void check(const RenderOptions& o);

struct RenderConfig : RenderOptions, LightSamplerOptions, SchedulingOptions, FieldOptions {
  // What to render and where to write it: not options of the image.
  std::string scene_path;
  std::string output;               // .exr path; empty: the scene's Film filename
  std::string log_path;             // empty: OUTPUT with .json
  // --reference: at every iteration boundary log wall and render time, cumulative spp and
  // relMSE / RMSE / MAPE against this image (linear sRGB, the film's size).  Empty: none.
  std::string reference_path;
  // --sample-range BEGIN:END: render samples [BEGIN, END) of the frame's spp
  // and write them as a part of a split frame (farm/part.h), for `theia merge`.
  // Empty: the whole frame.
  std::string sample_range;
  // When the command started (scene loading included), for the log's wall time; unset: when
  // render_scene was called.
  std::optional<std::chrono::steady_clock::time_point> wall_start;
  bool progress = false;            // progress bar (the command line turns it on for a terminal)
  // After a stop signal, paths still in flight this long are abandoned
  // (EngineOptions::abandon_after_seconds); tests shorten it.
  double abandon_after_seconds = 2.0;
  // Raised to stop early: the command line's SIGTERM/SIGINT handler, and the
  // time limit (--time-limit; render_scene makes a request of its own when
  // this is null).
  StopRequest* stop = nullptr;
  // Called with (iteration, fraction of its camera samples generated).
  std::function<void(int, double)> on_iteration_progress;
  // Set by the render's resolution of the options: why --guiding-auto is off
  // from the start (the log's guiding.auto.why; empty: it was not).
  std::string guiding_off_because;

  // The features' options (app/features.h), each under its group's name.
  RecorderOptions recorder;
  GuidingOptions guiding;
  CausticsOptions caustics;
  AdaptiveOptions adaptive;
  IterationOptions iteration;
  CheckpointOptions checkpoint;
};

// Every option, group by group: the one list the command line, the log and
// the checkpoint fingerprint are made from (app/options.h).
template <class V>
void declare_render_options(V& v, RenderConfig& c) {
  v.group = "";
  declare_options(v, static_cast<RenderOptions&>(c));
  declare_options(v, static_cast<LightSamplerOptions&>(c));
  declare_options(v, static_cast<SchedulingOptions&>(c));
  declare_options(v, static_cast<FieldOptions&>(c));
  v.group = "recorder";
  declare_options(v, c.recorder);
  v.group = "guiding";
  declare_options(v, c.guiding);
  v.group = "caustics";
  declare_options(v, c.caustics);
  v.group = "adaptive";
  declare_options(v, c.adaptive);
  v.group = "iteration";
  declare_options(v, c.iteration);
  v.group = "checkpoint";
  declare_options(v, c.checkpoint);
  v.group = "";
}

// Every option's validation (each struct's check, then the combinations that
// would give a wrong image); throws theia::Error naming the flag.
void check_config(const RenderConfig& c);

// The hash a checkpoint must match to be resumed: every image option, by name, as
// render_scene resolves them (spp and maximum depth from the scene, the schedule named).
uint64_t options_fingerprint(const RenderConfig& c);

// `theia render` exits with this when a stop was requested (SIGTERM, SIGINT)
// before the render finished: the state is in the checkpoint (if any), and
// running the same command again resumes.  75 is EX_TEMPFAIL: "try again".
inline constexpr int kExitInterrupted = 75;

struct RenderResult {
  ImageBuffer image;                // R G B A albedo.* N.* depth.Z
  nlohmann::json log;
  bool interrupted = false;         // stopped early: no image; resume from the checkpoint
  std::vector<float> weight;        // per-pixel sum of filter weights (box filter: samples per pixel)
  ImageBuffer sums;                 // --sample-range: the film's sums (sum.NAME), what the merge adds
};

// Renders an already-loaded scene (images must be loaded).  Throws theia::Error on bad options.
RenderResult render_scene(const Scene& scene, const RenderConfig& config);

// The whole command: load, render, write outputs atomically.  Returns the process exit code.
int run_render(const RenderConfig& config);

}  // namespace theia
