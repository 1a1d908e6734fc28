// `theia render`: load a scene, render it with the wavefront engine, write
// the EXR, the PNG preview and the JSON log.  Tests call render_scene()
// in-process; the command line calls run_render().
#pragma once

#include "core/image.h"
#include "scene/scene.h"

#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <functional>
#include <optional>
#include <string>

namespace theia {

struct RenderConfig {
  std::string scene_path;
  std::string output;               // .exr path; empty: the scene's Film filename
  int spp = -1;                     // -1: the scene's Sampler pixelsamples
  int threads = 0;                  // 0: all cores
  uint32_t seed = 0;
  int max_depth = -1;               // -1: the scene's Integrator maxdepth
  size_t batch_size = size_t(1) << 16;
  size_t max_paths = size_t(1) << 19;
  bool sort = true;
  std::string light_sampler = "power";
  std::string log_path;             // empty: OUTPUT with .json
  // --reference: at every iteration boundary log wall and render time, cumulative spp and
  // relMSE / RMSE / MAPE against this image (linear sRGB, the film's size).  Empty: none.
  std::string reference_path;
  // When the command started (scene loading included), for the log's wall time; unset: when
  // render_scene was called.
  std::optional<std::chrono::steady_clock::time_point> wall_start;
  bool progress = false;            // progress bar (the command line turns it on for a terminal)
  // Radiance recorder (radiance_recorder/): built only when something consumes it.
  bool recorder_debug = false;      // layer "recorder": primary-hit samples re-splatted (== beauty)
  int recorder_debug_bounce = -1;   // >= 0: layer "recorder_bounceN", compare with throughput_reset_bounce
  float recorder_budget = 4.0f;     // vertices per path (path skip rate from the last iteration); 0: off
  float recorder_vertex_skip = 0.0f;// stochastic vertex-skipping probability
  float recorder_min_distance = 0.0f;
  int throughput_reset_bounce = -1; // >= 0: the beauty is the "throughput reset at bounce N" image

  // Path guiding (guiding/): an SD-tree trained from the recorder after every
  // iteration and sampled, mixed with the BSDF, in the next.
  bool guiding = false;
  float guiding_fraction = 0.5f;            // probability of sampling the guide where it applies
  float guiding_min_roughness = 0.05f;      // guide only BSDFs with a lobe rougher than this
  float guiding_spatial_threshold = 4000.0f;// SD-tree leaf split: this many samples times 2^(k/2)

  // Directly seen caustics traced from the lights (wavefront/caustics.h).
  bool caustics = true;
  float caustic_roughness = 0.1f;   // casters: conductors and dielectrics no rougher than this

  // Iterations (scheduler/schedule.h): a named schedule, then any of its
  // numbers overridden (-1 / 0: keep the schedule's).
  std::string schedule;              // regular | guiding; empty: guiding with --guiding, else regular
  int iteration_first = -1, iteration_repeat = -1, iteration_max = -1;
  double iteration_growth = 0.0;
  std::string combine = "equal";     // equal | inverse-variance
  bool adaptive = false;             // adaptive sampling, alpha at a fixed spp per pixel
  // Checkpoints (checkpoint/checkpoint.h); none without a directory.
  std::string checkpoint_dir;
  bool resume = false;               // fail unless a checkpoint is found
  bool checkpoint_every_iteration = false;
  int checkpoint_first_ideal = 4;
  // Raised to stop early (the command line's SIGTERM/SIGINT handler).
  const std::atomic<bool>* stop = nullptr;
  // Called with (iteration, fraction of its camera samples generated).
  std::function<void(int, double)> on_iteration_progress;
};

// `theia render` exits with this when a stop was requested (SIGTERM, SIGINT)
// before the render finished: the state is in the checkpoint (if any), and
// running the same command again resumes.  75 is EX_TEMPFAIL: "try again".
inline constexpr int kExitInterrupted = 75;

struct RenderResult {
  ImageBuffer image;                // R G B A albedo.* N.* depth.Z
  nlohmann::json log;
  bool interrupted = false;         // stopped early: no image; resume from the checkpoint
};

// Renders an already-loaded scene (images must be loaded).  Throws theia::Error on bad options.
RenderResult render_scene(const Scene& scene, const RenderConfig& config);

// The whole command: load, render, write outputs atomically.  Returns the process exit code.
int run_render(const RenderConfig& config);

}  // namespace theia
