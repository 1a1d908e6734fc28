// Command-line mistakes (issue 16): every parse error exits 1 with one
// "error: ..." line (CLI11's own exit codes, 105 and up, do not leak), and
// `farm submit --render-options` is parsed by the render command's own
// parser when the farm is submitted, so a typo fails there and not in every
// task on the farm.
#include "render_helpers.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

namespace fs = std::filesystem;
using theia::test::RunResult;
using theia::test::TempDir;

namespace {

const auto run = theia::test::run_theia;

const char* kScene = R"(Film "rgb" "integer xresolution" [8] "integer yresolution" [8]
Camera "perspective"
WorldBegin
LightSource "point" "rgb I" [1 1 1]
Shape "sphere"
)";

void expect_one_error(const RunResult& r, const std::string& what, const std::string& args) {
  EXPECT_EQ(r.exit_code, 1) << args << ": " << r.output;
  EXPECT_EQ(r.output.rfind("error: ", 0), 0u) << args << ": " << r.output;
  size_t errors = 0;
  for (size_t at = r.output.find("error"); at != std::string::npos; at = r.output.find("error", at + 1)) ++errors;
  EXPECT_EQ(errors, 1u) << args << ": " << r.output;
  EXPECT_NE(r.output.find(what), std::string::npos) << args << ": " << r.output;
}

}  // namespace

TEST(CommandLineErrors, ParseErrorsExitOneWithOneMessage) {
  TempDir tmp("theia_cli_errors");
  const std::string scene = tmp.write("s.pbrt", kScene);
  const std::string out = " -q -o " + (tmp.path / "o.exr").string();
  const std::pair<std::string, std::string> cases[] = {
      {"render " + scene + " --frobnicate" + out, "--frobnicate"},  // an unknown flag (CLI11: 109)
      {"render " + scene + " --spp abc" + out, "--spp"},            // not a number (CLI11: 105)
      {"render " + scene + out + " --spp", "--spp"},                // a missing value (CLI11: 107)
      {"render" + out, "scene"},                                    // the scene missing (CLI11: 106)
      {"render " + scene + " extra.pbrt" + out, "extra.pbrt"},      // one positional too many (CLI11: 109)
      {"rendr " + scene, "unknown command \"rendr\" (commands: render"},  // an unknown command, named
      {"", "subcommand"},                                           // no command at all
  };
  for (const auto& [args, what] : cases) expect_one_error(run(args), what, args);
  EXPECT_FALSE(fs::exists(tmp.path / "o.exr"));
  // Asking for help is no error.
  EXPECT_EQ(run("render --help").exit_code, 0);
  EXPECT_EQ(run("--help").exit_code, 0);
}

TEST(CommandLineErrors, FarmRenderOptionsAreCheckedAtSubmit) {
  TempDir tmp("theia_cli_farm");
  const std::string scene = tmp.write("s.pbrt", kScene);
  const std::string submit = "farm submit " + scene + " --dry-run -d " + (tmp.path / "farm").string();
  // A typo, a bad value and an impossible combination each fail the submit.
  const std::pair<std::string, std::string> bad[] = {
      {"--sortt none", "--sortt"},
      {"--max-depth lots", "--max-depth"},
      {"--guiding-selection-probability 1", "--guiding-selection-probability"},
  };
  for (const auto& [options, what] : bad) {
    const std::string args = submit + " --render-options '" + options + "'";
    const RunResult r = run(args);
    expect_one_error(r, what, args);
    EXPECT_NE(r.output.find("farm submit --render-options: "), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("#SBATCH"), std::string::npos) << "nothing planned: " << r.output;
  }
  EXPECT_FALSE(fs::exists(tmp.path / "farm"));
  // Good options go through to the tasks' command lines.
  const RunResult ok = run(submit + " --render-options '--max-depth 3 --seed 5'");
  EXPECT_EQ(ok.exit_code, 0) << ok.output;
  EXPECT_NE(ok.output.find("'--max-depth' '3' '--seed' '5'"), std::string::npos) << ok.output;
}
