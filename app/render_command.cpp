#include "app/render_command.h"

#include "core/log.h"

namespace theia {

void add_render_command(CLI::App& app, RenderCommand& r) {
  RenderConfig& rc = r.config;
  CLI::App* render = app.add_subcommand("render", "Render a pbrt-v4 scene to OpenEXR + PNG + JSON log");
  r.cmd = render;
  render->add_option("scene", rc.scene_path, "pbrt-v4 scene file")->required();
  render->add_option("-o,--output", rc.output, "Output .exr (default: the scene's Film filename)");
  render->add_option("--log", rc.log_path, "JSON log file (default: OUTPUT with .json)");
  render->add_option("--reference", rc.reference_path,
                     "Reference image (linear sRGB EXR): log time, spp and relMSE/RMSE/MAPE at every iteration");
  render->add_option("--sample-range", rc.sample_range,
                     "BEGIN:END: render samples [BEGIN, END) of every pixel as a part of a split frame (theia merge)");
  render->add_flag("-q,--quiet", r.quiet, "Print only warnings and errors");
  OptionBinder binder(*render);
  declare_render_options(binder, rc);
  // Tests only: raise SIGTERM in iteration I once a fraction F of its camera rays were generated.
  render->add_option("--test-sigterm-at", r.test_sigterm, "")->group("");
  // Tests only: abandon paths in flight this many seconds after a stop signal (default 2).
  render->add_option("--test-abandon-after", rc.abandon_after_seconds, "")->group("");
  // Tests only: every --guiding-auto round judges "on" or "off".
  render->add_option("--test-guiding-verdict", rc.guiding.test_verdict, "")
      ->group("")
      ->check(CLI::IsMember({"on", "off"}));
}

void check_render_words(const std::vector<std::string>& words, const std::string& what) {
  CLI::App app;
  RenderCommand r;
  add_render_command(app, r);
  // CLI11 takes a vector of arguments last first.
  std::vector<std::string> args(words.rbegin(), words.rend());
  args.push_back("scene.pbrt");
  args.push_back("render");
  try {
    app.parse(args);
  } catch (const CLI::ParseError& e) {
    throw_error("{}: {}", what, e.what());
  }
  try {
    check_config(r.config);
  } catch (const Error& e) {
    throw_error("{}: {}", what, e.what());
  }
}

}  // namespace theia
