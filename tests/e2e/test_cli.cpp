// The command line as a user meets it: outputs written, errors named, exit codes.
#include "render_helpers.h"

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

fs::path temp_dir(const std::string& name) {
  fs::path d = fs::temp_directory_path() / ("theia_cli_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

void write_file(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

const char* kSmallScene = R"(Film "rgb" "integer xresolution" [16] "integer yresolution" [12]
LookAt 0 0 -5  0 0 0  0 1 0
Camera "perspective" "float fov" [30]
WorldBegin
LightSource "infinite" "rgb L" [1 1 1]
Shape "sphere" "float radius" [1]
)";

}  // namespace

TEST(CommandLine, RenderWritesExrPngAndJsonLog) {
  fs::path d = temp_dir("render");
  write_file(d / "s.pbrt", kSmallScene);
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
  fs::remove_all(d);
}

TEST(CommandLine, MalformedSceneNamesFileLineAndColumnAndFails) {
  fs::path d = temp_dir("bad");
  write_file(d / "bad.pbrt", "Film \"rgb\"\nWorldBegin\n  Shape \"sphere\" \"float radius\" [ 1 \n");
  RunResult r = run("render " + (d / "bad.pbrt").string() + " -o " + (d / "out.exr").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("bad.pbrt:"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("error"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(d / "out.exr"));

  write_file(d / "unknown.pbrt", "WorldBegin\nFrobnicate 1 2 3\n");
  r = run("render " + (d / "unknown.pbrt").string() + " -o " + (d / "out.exr").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("unknown.pbrt:2:1"), std::string::npos) << r.output;
  fs::remove_all(d);
}

TEST(CommandLine, MissingSceneAndBadOptionsFail) {
  EXPECT_NE(run("render /nonexistent/scene.pbrt").exit_code, 0);
  fs::path d = temp_dir("opts");
  write_file(d / "s.pbrt", kSmallScene);
  EXPECT_NE(run("render " + (d / "s.pbrt").string() + " --sort maybe").exit_code, 0);
  EXPECT_NE(run("render " + (d / "s.pbrt").string() + " --spp 0 -o " + (d / "o.exr").string()).exit_code, 0);
  EXPECT_NE(run("render " + (d / "s.pbrt").string() + " -o " + (d / "o.png").string()).exit_code, 0);
  fs::remove_all(d);
}

TEST(CommandLine, HelpListsTheRenderOptions) {
  RunResult r = run("render --help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* opt : {"--spp", "--threads", "--seed", "--max-depth", "--batch-size", "--sort", "--log"})
    EXPECT_NE(r.output.find(opt), std::string::npos) << opt;
}

TEST(CommandLine, DiffReportsErrorAgainstItselfAsZero) {
  fs::path d = temp_dir("diff");
  write_file(d / "s.pbrt", kSmallScene);
  ASSERT_EQ(run("render " + (d / "s.pbrt").string() + " -o " + (d / "a.exr").string() + " --spp 2 -q").exit_code, 0);
  RunResult r = run("diff " + (d / "a.exr").string() + " " + (d / "a.exr").string() + " --error-image " +
                    (d / "err.png").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("relMSE 0"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(d / "err.png"));
  fs::remove_all(d);
}
