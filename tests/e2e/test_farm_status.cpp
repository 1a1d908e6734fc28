// `theia farm status` and `collect` read what the tasks leave: the wrapper's
// start/end lines, the renders' logs and checkpoints.  A farm directory is
// laid out here by hand, with real renders, as four tasks would leave it.
#include "render_helpers.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

namespace fs = std::filesystem;
using namespace theia;

TEST(FarmStatus, DoneRequeuedFailedPendingAndWhatCollectMisses) {
  const fs::path dir = fs::temp_directory_path() / ("theia_farm_status_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  for (const char* sub : {"shot", "frames", "logs", "checkpoints"}) fs::create_directories(dir / sub);
  const std::string scene = (dir / "shot" / "s.pbrt").string();
  std::ofstream(scene) << test::sphere_floor_scene(1.0f);
  nlohmann::json manifest = {{"frames", nlohmann::json::array()}};
  for (const char* name : {"a", "b", "c", "d"}) {
    const std::string out = (dir / "frames" / (std::string(name) + ".exr")).string();
    manifest["frames"].push_back({{"name", name},
                                  {"scene", scene},
                                  {"output", out},
                                  {"tasks",
                                   {{{"log", (dir / "logs" / (std::string(name) + ".out")).string()},
                                     {"checkpoint", (dir / "checkpoints" / name).string()},
                                     {"output", out}}}}});
  }
  std::ofstream(dir / "farm.json") << manifest.dump(2);
  auto render = [&](const std::string& name, const std::string& more) {
    return test::run_theia("render " + scene + " -q --spp 40 --max-paths 512 -o " +
                           (dir / "frames" / (name + ".exr")).string() + " --checkpoint-dir " +
                           (dir / "checkpoints" / name).string() + more);
  };
  // a: done in one run of 12 s.
  ASSERT_EQ(render("a", "").exit_code, 0);
  std::ofstream(dir / "logs" / "a.out") << "farm: start task=0 restart=0 job=1 time=100 host=h\n"
                                        << "farm: end task=0 exit=0 time=112\n";
  // b: stopped mid-render (exit 75), requeued, running again: its checkpoint holds part of the samples.
  ASSERT_EQ(render("b", " --test-sigterm-at 2:0.5").exit_code, 75);
  const long now = long(std::time(nullptr));
  std::ofstream(dir / "logs" / "b.out") << "farm: start task=1 restart=0 job=2 time=100 host=h\n"
                                        << "farm: end task=1 exit=75 time=105\n"
                                        << "farm: start task=1 restart=1 job=2 time=" << now << " host=h\n";
  // c: failed.  d: never started.
  std::ofstream(dir / "logs" / "c.out") << "farm: start task=2 restart=0 job=3 time=100 host=h\n"
                                        << "farm: end task=2 exit=1 time=101\n";

  test::RunResult r = test::run_theia("farm status " + dir.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::istringstream lines(r.output);
  std::map<std::string, std::vector<std::string>> rows;
  for (std::string line; std::getline(lines, line);) {
    std::istringstream in(line);
    std::vector<std::string> words;
    for (std::string w; in >> w;) words.push_back(w);
    if (!words.empty()) rows[words[0]] = words;
  }
  ASSERT_EQ(rows["a"].size(), 5u) << r.output;
  EXPECT_EQ(rows["a"][1], "done");
  EXPECT_EQ(rows["a"][2], "0");
  EXPECT_EQ(rows["a"][3], "40");
  EXPECT_EQ(rows["a"][4], "12.0");
  ASSERT_EQ(rows["b"].size(), 5u) << r.output;
  EXPECT_EQ(rows["b"][1], "running");
  EXPECT_EQ(rows["b"][2], "1");
  // Stopped inside iteration 2 (samples [32, 40)): its checkpoint holds the first 32 in every pixel.
  EXPECT_EQ(rows["b"][3], "32");
  EXPECT_EQ(rows["c"][1], "failed");
  EXPECT_EQ(rows["d"][1], "pending");
  EXPECT_NE(r.output.find("1 of 4 frames done"), std::string::npos) << r.output;

  r = test::run_theia("farm collect " + dir.string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  for (const char* missing : {"NOT COMPLETE b: missing", "NOT COMPLETE c: missing", "NOT COMPLETE d: missing"})
    EXPECT_NE(r.output.find(missing), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("NOT COMPLETE a"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("1 of 4 frames complete"), std::string::npos) << r.output;
  fs::remove_all(dir);
}
