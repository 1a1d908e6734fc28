// The `theia` command line.
#include "app/diff.h"
#include "app/farm_commands.h"
#include "app/render.h"
#include "core/log.h"

#include <CLI/CLI.hpp>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <unistd.h>

namespace {
theia::StopRequest g_stop;
extern "C" void on_stop_signal(int) { g_stop.raise(theia::StopReason::Signal); }
}  // namespace

int main(int argc, char** argv) {
  using namespace theia;
  CLI::App app{"theia: a sorted-deferred (wavefront) path tracer for pbrt-v4 scenes"};
  app.require_subcommand(1);

  RenderConfig rc;
  bool quiet = false;
  CLI::App* render = app.add_subcommand("render", "Render a pbrt-v4 scene to OpenEXR + PNG + JSON log");
  render->add_option("scene", rc.scene_path, "pbrt-v4 scene file")->required();
  render->add_option("-o,--output", rc.output, "Output .exr (default: the scene's Film filename)");
  render->add_option("--log", rc.log_path, "JSON log file (default: OUTPUT with .json)");
  render->add_option("--reference", rc.reference_path,
                     "Reference image (linear sRGB EXR): log time, spp and relMSE/RMSE/MAPE at every iteration");
  render->add_option("--sample-range", rc.sample_range,
                     "BEGIN:END: render samples [BEGIN, END) of every pixel as a part of a split frame (theia merge)");
  render->add_flag("-q,--quiet", quiet, "Print only warnings and errors");
  OptionBinder binder(*render);
  declare_render_options(binder, rc);
  // Tests only: raise SIGTERM in iteration I once a fraction F of its camera rays were generated.
  std::string test_sigterm;
  render->add_option("--test-sigterm-at", test_sigterm, "")->group("");

  std::string diff_a, diff_b, diff_image;
  CLI::App* diff = app.add_subcommand("diff", "Compare two images: relMSE, RMSE and more");
  diff->add_option("a", diff_a, "Test image")->required();
  diff->add_option("b", diff_b, "Reference image")->required();
  diff->add_option("--error-image", diff_image, "Write a false-colour relative-error PNG");

  FarmCommands farm(app);

  CLI11_PARSE(app, argc, argv);
  try {
    if (render->parsed()) {
      if (quiet) set_verbosity(Verbosity::Quiet);
      rc.progress = !quiet && isatty(fileno(stderr));
      // A farm stops a job with SIGTERM: finish what is in flight, checkpoint, exit 75.
      std::signal(SIGTERM, on_stop_signal);
      std::signal(SIGINT, on_stop_signal);
      rc.stop = &g_stop;
      if (!test_sigterm.empty()) {
        int it = std::stoi(test_sigterm.substr(0, test_sigterm.find(':')));
        double at = std::stod(test_sigterm.substr(test_sigterm.find(':') + 1));
        rc.on_iteration_progress = [it, at](int i, double f) {
          if (i == it && f >= at && !g_stop.raised()) std::raise(SIGTERM);
        };
      }
      return run_render(rc);
    }
    if (diff->parsed()) return run_diff(diff_a, diff_b, diff_image);
    if (farm.parsed()) return farm.run();
  } catch (const Error& e) {
    std::fprintf(stderr, "%s\n", error_line(e.what()).c_str());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", error_line(e.what()).c_str());
    return 1;
  }
  return 0;
}
