// The `theia` command line.
#include "app/diff.h"
#include "app/render.h"
#include "core/log.h"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <unistd.h>

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
  render->add_flag("-q,--quiet", quiet, "Print only warnings and errors");

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
