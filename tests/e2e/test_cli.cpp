// The command line as a user meets it: outputs written, errors named, exit codes.
#include "render_helpers.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace fs = std::filesystem;

namespace {

using theia::test::RunResult;
RunResult run(const std::string& args) { return theia::test::run_theia(args); }


const char* kSmallScene = R"(Film "rgb" "integer xresolution" [16] "integer yresolution" [12]
LookAt 0 0 -5  0 0 0  0 1 0
Camera "perspective" "float fov" [30]
WorldBegin
LightSource "infinite" "rgb L" [1 1 1]
Shape "sphere" "float radius" [1]
)";

}  // namespace

TEST(CommandLine, RenderWritesExrPngAndJsonLog) {
  theia::test::TempDir tmp("theia_cli_render");
  const fs::path& d = tmp.path;
  tmp.write("s.pbrt", kSmallScene);
  RunResult r = run("render " + (d / "s.pbrt").string() + " -o " + (d / "out.exr").string() + " --spp 4 -q");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(d / "out.exr"));
  EXPECT_TRUE(fs::exists(d / "out.png"));
  ASSERT_TRUE(fs::exists(d / "out.json"));
  EXPECT_FALSE(fs::exists(d / "out.exr.tmp"));
  nlohmann::json log = nlohmann::json::parse(std::ifstream(d / "out.json"));
  for (const char* phase : {"generate", "sort", "trace", "shade"}) EXPECT_TRUE(log["time"]["phases"].contains(phase));
  EXPECT_EQ(log["rays"]["camera"].get<uint64_t>(), 16u * 12u * 4u);
  EXPECT_GT(log["mrays_per_second"]["render"].get<double>(), 0.0);
  EXPECT_GT(log["memory"]["peak_rss"].get<uint64_t>(), 0u);
  EXPECT_GT(log["paths"]["average_length"].get<double>(), 0.0);
}

TEST(CommandLine, MalformedSceneNamesFileLineAndColumnAndFails) {
  theia::test::TempDir tmp("theia_cli_bad");
  const fs::path& d = tmp.path;
  tmp.write("bad.pbrt", "Film \"rgb\"\nWorldBegin\n  Shape \"sphere\" \"float radius\" [ 1 \n");
  RunResult r = run("render " + (d / "bad.pbrt").string() + " -o " + (d / "out.exr").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("bad.pbrt:"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("error"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(d / "out.exr"));

  tmp.write("unknown.pbrt", "WorldBegin\nFrobnicate 1 2 3\n");
  r = run("render " + (d / "unknown.pbrt").string() + " -o " + (d / "out.exr").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("unknown.pbrt:2:1"), std::string::npos) << r.output;
  // One "error:" per message, after the location.
  EXPECT_EQ(r.output.find("error: " + (d / "unknown.pbrt").string()), std::string::npos) << r.output;
  EXPECT_NE(r.output.find((d / "unknown.pbrt").string() + ":2:1: error: "), std::string::npos) << r.output;
}

TEST(CommandLine, MissingSceneAndBadOptionsFail) {
  EXPECT_NE(run("render /nonexistent/scene.pbrt").exit_code, 0);
  theia::test::TempDir tmp("theia_cli_opts");
  const fs::path& d = tmp.path;
  tmp.write("s.pbrt", kSmallScene);
  EXPECT_NE(run("render " + (d / "s.pbrt").string() + " --sort maybe").exit_code, 0);
  EXPECT_NE(run("render " + (d / "s.pbrt").string() + " --spp 0 -o " + (d / "o.exr").string()).exit_code, 0);
  EXPECT_NE(run("render " + (d / "s.pbrt").string() + " -o " + (d / "o.png").string()).exit_code, 0);
  // Combinations that would give a wrong image are refused with the reason.
  const std::string out = " -o " + (d / "o.exr").string();
  for (const char* bad : {" --guiding-selection-probability 1", " --caustics-caster-roughness -1", " --guiding-spatial-threshold 0",
                          " --guiding-selection-max 0", " --guiding-selection-max 1.5",
                          " --guiding-roulette-floor 0", " --guiding-roulette-floor 1.5",
                          " --guiding --guiding-sampling mis --guiding-selection-probability 0.9"}) {
    RunResult r = run("render " + (d / "s.pbrt").string() + out + bad);
    EXPECT_NE(r.exit_code, 0) << bad;
    EXPECT_NE(r.output.find("--"), std::string::npos) << bad << ": " << r.output;
  }
  EXPECT_FALSE(fs::exists(d / "o.exr"));
}

TEST(CommandLine, HelpListsTheRenderOptions) {
  RunResult r = run("render --help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* opt : {"--spp", "--threads", "--seed", "--max-depth", "--batch-size", "--sort", "--log",
                          "--guiding", "--caustics", "--no-caustics"})
    EXPECT_NE(r.output.find(opt), std::string::npos) << opt;
}

TEST(CommandLine, DiffReportsErrorAgainstItselfAsZero) {
  theia::test::TempDir tmp("theia_cli_diff");
  const fs::path& d = tmp.path;
  tmp.write("s.pbrt", kSmallScene);
  ASSERT_EQ(run("render " + (d / "s.pbrt").string() + " -o " + (d / "a.exr").string() + " --spp 2 -q").exit_code, 0);
  RunResult r = run("diff " + (d / "a.exr").string() + " " + (d / "a.exr").string() + " --error-image " +
                    (d / "err.png").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("relMSE 0"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(d / "err.png"));
}
