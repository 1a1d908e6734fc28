// The `theia` command line.
#include "app/diff.h"
#include "app/farm_commands.h"
#include "app/field_commands.h"
#include "app/render.h"
#include "app/render_command.h"
#include "core/log.h"

#include <CLI/CLI.hpp>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <new>
#include <stdexcept>
#include <cstdio>
#include <unistd.h>

namespace {
theia::StopRequest g_stop;
extern "C" void on_stop_signal(int) { g_stop.raise(theia::StopReason::Signal); }
// Back to the default action; a signal that came already is delivered now.
void default_stop_signals() {
  std::signal(SIGTERM, SIG_DFL);
  std::signal(SIGINT, SIG_DFL);
  if (g_stop.raised()) std::raise(SIGTERM);
}
}  // namespace

int main(int argc, char** argv) {
  using namespace theia;
  // First thing: a farm may send SIGTERM while the command line or the scene
  // is read; the render then stops at once, checkpoints and exits 75.
  std::signal(SIGTERM, on_stop_signal);
  std::signal(SIGINT, on_stop_signal);
  CLI::App app{"theia: a sorted-deferred (wavefront) path tracer for pbrt-v4 scenes"};
  app.require_subcommand(1);
  // A bad command line is an error like any other: "error: --spp: must not be negative, got -1".
  app.failure_message([](const CLI::App*, const CLI::Error& e) {
    return "error: " + std::string(e.what()) + "\n(--help lists the options)\n";
  });

  RenderCommand render_command;
  add_render_command(app, render_command);
  CLI::App* render = render_command.cmd;
  RenderConfig& rc = render_command.config;
  const bool& quiet = render_command.quiet;
  const std::string& test_sigterm = render_command.test_sigterm;

  std::string diff_a, diff_b, diff_image;
  CLI::App* diff = app.add_subcommand("diff", "Compare two images: relMSE, RMSE and more");
  diff->add_option("a", diff_a, "Test image")->required();
  diff->add_option("b", diff_b, "Reference image")->required();
  diff->add_option("--error-image", diff_image, "Write a false-colour relative-error PNG");

  FarmCommands farm(app);
  FieldCommands field(app);

  // A mistyped command is named (CLI11 would only say a subcommand is required).
  if (argc > 1 && argv[1][0] != '-') {
    std::string known;
    bool found = false;
    for (const CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) {
      known += (known.empty() ? "" : ", ") + sub->get_name();
      found = found || sub->get_name() == argv[1];
    }
    if (!found) {
      std::fprintf(stderr, "error: unknown command \"%s\" (commands: %s)\n", argv[1], known.c_str());
      return 1;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help is a success (0); every parse error exits 1 as other errors
    // do, with the one message of failure_message (not CLI11's own codes).
    return app.exit(e) == 0 ? 0 : 1;
  }
  try {
    if (render->parsed()) {
      if (quiet) set_verbosity(Verbosity::Quiet);
      rc.progress = !quiet && isatty(fileno(stderr));
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
    if (diff->parsed()) {
      // Nothing to keep: a stop signal ends a diff as it ends any program.
      default_stop_signals();
      return run_diff(diff_a, diff_b, diff_image);
    }
    if (field.parsed()) {
      default_stop_signals();
      return field.run();
    }
    if (farm.parsed()) {
      default_stop_signals();  // submit, status and collect keep nothing to checkpoint
      return farm.run();
    }
  } catch (const Error& e) {
    std::fprintf(stderr, "%s\n", error_line(e.what()).c_str());
    return 1;
  } catch (const std::bad_alloc&) {
    // The last resort: sizes are checked against --memory-limit before the
    // film and the pool are allocated, so this is memory the check missed.
    std::fprintf(stderr, "error: out of memory (the scene, its images or the render did not fit; see --memory-limit)\n");
    return 1;
  } catch (const std::length_error& e) {
    std::fprintf(stderr, "error: out of memory: a size beyond what can be allocated (%s)\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", error_line(e.what()).c_str());
    return 1;
  }
  return 0;
}
