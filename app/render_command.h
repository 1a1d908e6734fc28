// The `theia render` command's flags, declared once: for the command line,
// and to check `farm submit --render-options` when the farm is submitted
// rather than when its tasks start hours later.
#pragma once

#include "app/render.h"

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace theia {

struct RenderCommand {
  CLI::App* cmd = nullptr;
  RenderConfig config;
  bool quiet = false;
  std::string test_sigterm;  // tests only: I:F, raise SIGTERM in iteration I at fraction F
};

// Adds the "render" subcommand to `app`, its flags bound to `r`.
void add_render_command(CLI::App& app, RenderCommand& r);

// Parses `words` as `theia render SCENE words...` parses them, then checks
// the options as a render does before it reads its scene (check_config).
// Throws theia::Error naming `what` and the first problem.
void check_render_words(const std::vector<std::string>& words, const std::string& what);

}  // namespace theia
