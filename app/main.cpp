// The `theia` command line.
#include "app/diff.h"
#include "app/render.h"
#include "core/log.h"

#include <CLI/CLI.hpp>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <unistd.h>

namespace {
std::atomic<bool> g_stop{false};
extern "C" void on_stop_signal(int) { g_stop.store(true); }
}  // namespace

int main(int argc, char** argv) {
  using namespace theia;
  CLI::App app{"theia: a sorted-deferred (wavefront) path tracer for pbrt-v4 scenes"};
  app.require_subcommand(1);

  RenderConfig rc;
  std::string sort = "on";
  bool quiet = false;
  CLI::App* render = app.add_subcommand("render", "Render a pbrt-v4 scene to OpenEXR + PNG + JSON log");
  render->add_option("scene", rc.scene_path, "pbrt-v4 scene file")->required();
  render->add_option("-o,--output", rc.output, "Output .exr (default: the scene's Film filename)");
  render->add_option("--spp", rc.spp, "Samples per pixel (default: the scene's)");
  render->add_option("--threads", rc.threads, "Worker threads (0: all cores)");
  render->add_option("--seed", rc.seed, "Random seed");
  render->add_option("--max-depth", rc.max_depth, "Maximum path depth (default: the scene's)");
  render->add_option("--batch-size", rc.batch_size, "Rays per wavefront batch")->capture_default_str();
  render->add_option("--max-paths", rc.max_paths, "Capacity of the path-state pool")->capture_default_str();
  render->add_option("--sort", sort, "Sort rays and hits: on or off")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  render->add_option("--light-sampler", rc.light_sampler, "Light selection: uniform or power")
      ->check(CLI::IsMember({"uniform", "power"}))
      ->capture_default_str();
  render->add_flag("--recorder-debug", rc.recorder_debug,
                   "Radiance recorder: write its primary-hit debug layer 'recorder' (equals the beauty)");
  render->add_option("--recorder-debug-bounce", rc.recorder_debug_bounce,
                     "Radiance recorder: also write layer 'recorder_bounceN' (compare with --throughput-reset-bounce N)");
  render->add_option("--recorder-budget", rc.recorder_budget, "Recorded vertices per path (path skipping); 0: off")
      ->capture_default_str();
  render->add_option("--recorder-vertex-skip", rc.recorder_vertex_skip, "Probability of skipping a path vertex")
      ->capture_default_str();
  render->add_option("--recorder-min-distance", rc.recorder_min_distance,
                     "Closer than this to its parent, a vertex is merged into the parent")
      ->capture_default_str();
  render->add_option("--throughput-reset-bounce", rc.throughput_reset_bounce,
                     "Render the 'throughput reset at bounce N' image as the beauty");
  render->add_option("--log", rc.log_path, "JSON log file (default: OUTPUT with .json)");
  render->add_option("--reference", rc.reference_path,
                     "Reference image (linear sRGB EXR): log time, spp and relMSE/RMSE/MAPE at every iteration");
  render->add_flag("-q,--quiet", quiet, "Print only warnings and errors");
  render->add_flag("--guiding", rc.guiding,
                   "Path guiding: an SD-tree learned every iteration from the radiance recorder, mixed with BSDF sampling");
  render->add_option("--guiding-fraction", rc.guiding_fraction, "Probability of sampling the guide where it applies, in [0, 1)")
      ->capture_default_str();
  render->add_option("--guiding-min-roughness", rc.guiding_min_roughness,
                     "Guide only where a BSDF lobe is rougher than this")
      ->capture_default_str();
  render->add_option("--guiding-spatial-threshold", rc.guiding_spatial_threshold,
                     "SD-tree: split a spatial leaf after this many samples times sqrt(spp of the iteration)")
      ->capture_default_str();
  render->add_flag("--caustics,!--no-caustics", rc.caustics,
                   "Trace directly seen caustics (light -> near-mirror or glass -> diffuse -> camera) from the lights "
                   "(default: on; off by itself where it finds nothing)");
  render->add_option("--caustic-roughness", rc.caustic_roughness,
                     "Caustic casters: conductors and dielectrics no rougher than this")
      ->capture_default_str();
  render->add_option("--schedule", rc.schedule,
                     "Iteration schedule: regular (16 16 32 ... 256) or guiding (1 x8, 2 ... 16); default: guiding with "
                     "--guiding, else regular")
      ->check(CLI::IsMember({"regular", "guiding"}));
  render->add_option("--iteration-first", rc.iteration_first, "First iteration size in spp (default: the schedule's)");
  render->add_option("--iteration-repeat", rc.iteration_repeat, "Iterations of the first size (default: the schedule's)");
  render->add_option("--iteration-growth", rc.iteration_growth, "Growth factor of iteration sizes (default: the schedule's)");
  render->add_option("--iteration-max", rc.iteration_max, "Largest iteration size in spp (default: the schedule's)");
  render->add_option("--combine", rc.combine, "Combining iterations: equal, or inverse-variance (last four)")
      ->check(CLI::IsMember({"equal", "inverse-variance"}))
      ->capture_default_str();
  render->add_flag("--adaptive", rc.adaptive,
                   "Adaptive sampling: --spp is a budget over the frame; alpha keeps --spp samples in every pixel");
  render->add_option("--checkpoint-dir", rc.checkpoint_dir,
                     "Write checkpoints here; if it holds one, resume from it (exit code 75 when stopped)");
  render->add_flag("--resume", rc.resume, "Resume from --checkpoint-dir; fail if there is no checkpoint");
  render->add_flag("--checkpoint-every-iteration", rc.checkpoint_every_iteration,
                   "Checkpoint after every iteration instead of at 4 8 16 ... spp (skipping)");
  render->add_option("--checkpoint-first", rc.checkpoint_first_ideal, "Cumulative spp of the first ideal checkpoint")
      ->capture_default_str();
  // Tests only: raise SIGTERM in iteration I once a fraction F of its camera rays were generated.
  std::string test_sigterm;
  render->add_option("--test-sigterm-at", test_sigterm, "")->group("");

  std::string diff_a, diff_b, diff_image;
  CLI::App* diff = app.add_subcommand("diff", "Compare two images: relMSE, RMSE and more");
  diff->add_option("a", diff_a, "Test image")->required();
  diff->add_option("b", diff_b, "Reference image")->required();
  diff->add_option("--error-image", diff_image, "Write a false-colour relative-error PNG");

  CLI11_PARSE(app, argc, argv);
  try {
    if (render->parsed()) {
      if (quiet) set_verbosity(Verbosity::Quiet);
      rc.sort = sort == "on";
      rc.progress = !quiet && isatty(fileno(stderr));
      // A farm stops a job with SIGTERM: finish what is in flight, checkpoint, exit 75.
      std::signal(SIGTERM, on_stop_signal);
      std::signal(SIGINT, on_stop_signal);
      rc.stop = &g_stop;
      if (!test_sigterm.empty()) {
        int it = std::stoi(test_sigterm.substr(0, test_sigterm.find(':')));
        double at = std::stod(test_sigterm.substr(test_sigterm.find(':') + 1));
        rc.on_iteration_progress = [it, at](int i, double f) {
          if (i == it && f >= at && !g_stop.load()) std::raise(SIGTERM);
        };
      }
      return run_render(rc);
    }
    if (diff->parsed()) return run_diff(diff_a, diff_b, diff_image);
  } catch (const Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
