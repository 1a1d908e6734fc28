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
#include <string>
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

struct DiffArgs {
  std::string a, b, error_image;
  CLI::App* cmd = nullptr;
};

void add_diff_command(CLI::App& app, DiffArgs& d) {
  d.cmd = app.add_subcommand("diff", "Compare two images: relMSE, RMSE and more");
  d.cmd->add_option("a", d.a, "Test image")->required();
  d.cmd->add_option("b", d.b, "Reference image")->required();
  d.cmd->add_option("--error-image", d.error_image, "Write a false-colour relative-error PNG");
}

// A mistyped command is named (CLI11 would only say a subcommand is required).
bool names_a_command(CLI::App& app, int argc, char** argv) {
  if (argc < 2 || argv[1][0] == '-') return true;
  std::string known;
  bool found = false;
  for (const CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) {
    known += (known.empty() ? "" : ", ") + sub->get_name();
    found = found || sub->get_name() == argv[1];
  }
  if (!found) std::fprintf(stderr, "error: unknown command \"%s\" (commands: %s)\n", argv[1], known.c_str());
  return found;
}

// --test-sigterm ITERATION:FRACTION raises SIGTERM once that far into that iteration.
void arm_test_sigterm(theia::RenderConfig& rc, const std::string& spec) {
  if (spec.empty()) return;
  int it = std::stoi(spec.substr(0, spec.find(':')));
  double at = std::stod(spec.substr(spec.find(':') + 1));
  rc.on_iteration_progress = [it, at](int i, double f) {
    if (i == it && f >= at && !g_stop.raised()) std::raise(SIGTERM);
  };
}

// Every error, whatever threw it, is one line on stderr and exit status 1.
template <class Run>
int run_reporting_errors(Run&& run) {
  using namespace theia;
  try {
    return run();
  } catch (const Error& e) {
    std::fprintf(stderr, "%s\n", error_line(e.what()).c_str());
  } catch (const std::bad_alloc&) {
    // The last resort: sizes are checked against --memory-limit before the
    // film and the pool are allocated, so this is memory the check missed.
    std::fprintf(stderr, "error: out of memory (the scene, its images or the render did not fit; see --memory-limit)\n");
  } catch (const std::length_error& e) {
    std::fprintf(stderr, "error: out of memory: a size beyond what can be allocated (%s)\n", e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", error_line(e.what()).c_str());
  }
  return 1;
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

  RenderCommand render;
  add_render_command(app, render);
  DiffArgs diff;
  add_diff_command(app, diff);
  FarmCommands farm(app);
  FieldCommands field(app);

  if (!names_a_command(app, argc, argv)) return 1;
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help is a success (0); every parse error exits 1 as other errors
    // do, with the one message of failure_message (not CLI11's own codes).
    return app.exit(e) == 0 ? 0 : 1;
  }
  return run_reporting_errors([&] {
    if (render.cmd->parsed()) {
      RenderConfig& rc = render.config;
      if (render.quiet) set_verbosity(Verbosity::Quiet);
      rc.progress = !render.quiet && isatty(fileno(stderr));
      rc.stop = &g_stop;
      arm_test_sigterm(rc, render.test_sigterm);
      return run_render(rc);
    }
    // Nothing to keep: a stop signal ends a diff, a field command, a farm
    // submit, status or collect as it ends any program.
    default_stop_signals();
    if (diff.cmd->parsed()) return run_diff(diff.a, diff.b, diff.error_image);
    if (field.parsed()) return field.run();
    if (farm.parsed()) return farm.run();
    return 0;
  });
}
