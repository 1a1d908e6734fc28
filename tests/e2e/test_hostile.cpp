// Hostile command lines and scenes (issue 16), as a user or a farm meets
// them: one clear error before the render starts, or a warning, never a crash.
#include "render_helpers.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <string>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

namespace fs = std::filesystem;
using theia::test::RunResult;
using theia::test::TempDir;

namespace {

RunResult run(const std::string& args) { return theia::test::run_theia(args); }

const char* kLitScene = R"(Film "rgb" "integer xresolution" [16] "integer yresolution" [12]
LookAt 0 0 -5  0 0 0  0 1 0
Camera "perspective" "float fov" [30]
WorldBegin
LightSource "point" "rgb I" [10 10 10] "point3 from" [0 0 -4]
Shape "sphere" "float radius" [1]
)";

// No .tmp, no image: the error came before anything was written.
void expect_nothing_written(const fs::path& d) {
  for (const auto& e : fs::directory_iterator(d)) {
    std::string name = e.path().filename().string();
    EXPECT_TRUE(name.ends_with(".pbrt") || e.is_directory()) << name;
  }
}

}  // namespace

TEST(Hostile, OutputAndLogPathsAreCheckedBeforeTheRender) {
  TempDir tmp("theia_hostile_out");
  const fs::path& d = tmp.path;
  const std::string scene = tmp.write("s.pbrt", kLitScene);
  fs::create_directories(d / "dir.exr");
  fs::create_directories(d / "logdir");
  RunResult r = run("render " + scene + " --spp 1 -q -o " + (d / "dir.exr").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.output, "error: -o " + (d / "dir.exr").string() + ": is a directory, expected a file name\n");
  r = run("render " + scene + " --spp 1 -q -o " + (d / "o.exr").string() + " --log " + (d / "logdir").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.output, "error: --log " + (d / "logdir").string() + ": is a directory, expected a file name\n");
  const std::string missing = (d / "missing/dir/x.json").string();
  r = run("render " + scene + " --spp 1 -q -o " + (d / "o.exr").string() + " --log " + missing);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.output,
            "error: --log " + missing + ": the directory " + (d / "missing/dir").string() + " does not exist\n");
  expect_nothing_written(d);
}

TEST(Hostile, HugeSizesAreClearErrorsNotBadAlloc) {
  TempDir tmp("theia_hostile_mem");
  const fs::path& d = tmp.path;
  const std::string scene = tmp.write("s.pbrt", kLitScene);
  const std::string out = " -q -o " + (d / "o.exr").string();
  RunResult r = run("render " + scene + " --spp 1 --max-paths 4294967295" + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("path pool of 4294967295 paths 2199023 MB), over the memory limit of"), std::string::npos)
      << r.output;
  r = run("render " + scene + " --spp 1 --max-paths 4000000000" + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("path pool of 4000000000 paths 2048000 MB), over the memory limit of"), std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("bad_alloc"), std::string::npos);
  // 60000 x 60000 fits 32-bit pixel indices, not memory.
  std::string big_text = kLitScene;
  big_text.replace(0, big_text.find('\n'), "Film \"rgb\" \"integer xresolution\" [60000] \"integer yresolution\" [60000]");
  const std::string big = tmp.write("big.pbrt", big_text);
  r = run("render " + big + " --spp 1" + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("film 60000x60000 648000 MB"), std::string::npos) << r.output;
  r = run("render " + scene + " --spp 1 --memory-limit 1" + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("over the memory limit of 1 MB (--memory-limit"), std::string::npos) << r.output;
  r = run("render " + scene + " --spp 1 --memory-limit -3" + out);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(r.output, "error: --memory-limit: must not be negative, got -3 (leave the option out for its default)\n"
                      "(--help lists the options)\n");
  r = run("render " + scene + " --spp 1 --memory-limit nan" + out);
  EXPECT_EQ(r.exit_code, 1);
  expect_nothing_written(d);
  r = run("render " + scene + " --spp 1 --memory-limit 4000" + out);
  EXPECT_EQ(r.exit_code, 0) << r.output;
}

// A "not given" default is not a value to type (issue 16: `--spp -1` was taken
// as the scene's spp): every number option refuses a negative value, as the
// command line's first error (tests/e2e/test_resume.cpp checks every flag).
TEST(Hostile, NegativeCountsOnTheCommandLineAreErrors) {
  TempDir tmp("theia_hostile_negative");
  const std::string scene = tmp.write("s.pbrt", kLitScene);
  const std::string out = " -q -o " + (tmp.path / "o.exr").string();
  for (const char* bad : {"--spp -1", "--max-depth -1", "--iteration-first -1", "--iteration-growth -1",
                          "--threads -2", "--seed -1", "--max-paths -1", "--recorder-debug-bounce -1"}) {
    RunResult r = run("render " + scene + " " + bad + out);
    EXPECT_NE(r.exit_code, 0) << bad;
    const std::string flag = std::string(bad).substr(0, std::string(bad).find(' '));
    EXPECT_EQ(r.output.rfind("error: " + flag + ": must not be negative, got -", 0), 0u) << bad << ": " << r.output;
  }
  expect_nothing_written(tmp.path);
}

// Iteration sizes that cannot make progress name the flag that set them.
TEST(Hostile, ImpossibleIterationSizesNameTheirFlag) {
  TempDir tmp("theia_hostile_iterations");
  const std::string scene = tmp.write("s.pbrt", kLitScene);
  const std::string out = " -q -o " + (tmp.path / "o.exr").string();
  const std::pair<const char*, const char*> cases[] = {{"--iteration-first 0", "--iteration-first"},
                                                       {"--iteration-growth 0.5", "--iteration-growth"},
                                                       {"--iteration-repeat 0", "--iteration-repeat"},
                                                       {"--iteration-first 8 --iteration-max 4", "--iteration-max"}};
  for (const auto& [bad, flag] : cases) {
    RunResult r = run("render " + scene + " " + bad + out);
    EXPECT_NE(r.exit_code, 0) << bad;
    EXPECT_NE(r.output.find(std::string("error: ") + flag), std::string::npos) << bad << ": " << r.output;
  }
  expect_nothing_written(tmp.path);
}

// An image texture's pixels count against --memory-limit before they are
// allocated: the error names the scene line and the image.
TEST(Hostile, ATextureBeyondTheMemoryLimitIsALocatedError) {
  TempDir tmp("theia_hostile_texmem");
  std::string pfm = "PF\n64 64\n-1.0\n";
  pfm += std::string(64 * 64 * 3 * sizeof(float), '\0');
  tmp.write("wood.pfm", pfm);
  std::string text = kLitScene;
  text.insert(text.find("Shape"), "Texture \"wood\" \"spectrum\" \"imagemap\" \"string filename\" \"wood.pfm\"\n"
                                  "Material \"diffuse\" \"texture reflectance\" \"wood\"\n");
  const std::string scene = tmp.write("s.pbrt", text);
  const std::string out = " --spp 1 -q -o " + (tmp.path / "o.exr").string();
  // 1 MB leaves nothing once the program itself is loaded.
  RunResult r = run("render " + scene + " --memory-limit 1" + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.output.rfind(scene + ":6:38: error: " + (tmp.path / "wood.pfm").string() +
                               ": its 64x64x3 float values need 49152 bytes, "
                           "over the 0 bytes the memory limit leaves for the scene's images (--memory-limit)", 0),
            0u)
      << r.output;
  EXPECT_FALSE(fs::exists(tmp.path / "o.exr"));
  r = run("render " + scene + out);
  EXPECT_EQ(r.exit_code, 0) << r.output;
}

TEST(Hostile, ASceneWithoutLightSaysSo) {
  TempDir tmp("theia_hostile_nolight");
  std::string text = kLitScene;
  text.erase(text.find("LightSource"), text.find("Shape") - text.find("LightSource"));
  const std::string scene = tmp.write("s.pbrt", text);
  RunResult r = run("render " + scene + " --spp 1 -q -o " + (tmp.path / "o.exr").string());
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_EQ(r.output, "warning: " + scene +
                          ": the scene has no light source (LightSource, or AreaLightSource before a Shape); the "
                          "image will be black\n");
  // A lit scene says nothing.
  r = run("render " + tmp.write("lit.pbrt", kLitScene) + " --spp 1 -q -o " + (tmp.path / "o.exr").string());
  EXPECT_EQ(r.output, "");
}

TEST(Hostile, AStrayCheckpointFileDoesNotBlockResume) {
  TempDir tmp("theia_hostile_ck");
  const std::string scene = tmp.write("s.pbrt", kLitScene);
  const std::string ck = (tmp.path / "ck").string();
  tmp.write("ck/checkpoint-abcdef.bin", "stray");
  RunResult r = run("render " + scene + " --spp 4 -q -o " + (tmp.path / "o.exr").string() + " --checkpoint-dir " + ck);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output, "");
}

// True once `pid` catches SIGTERM (its SigCgt mask in /proc).
bool catches_sigterm(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(f, line))
    if (line.starts_with("SigCgt:")) return (std::stoull(line.substr(7), nullptr, 16) >> (SIGTERM - 1)) & 1;
  return false;
}

TEST(Hostile, SigtermWhileTheSceneLoadsCheckpointsAndExits75) {
  TempDir tmp("theia_hostile_early");
  // A scene that takes a while to read (a mesh of 2e5 triangles in text).
  std::string text = std::string(kLitScene) + "Shape \"trianglemesh\" \"point3 P\" [";
  for (int i = 0; i < 200000; ++i) text += "0 0 " + std::to_string(i) + " 1 0 0 0 1 0 ";
  text += "] \"integer indices\" [";
  for (int i = 0; i < 600000; ++i) text += std::to_string(i) + " ";
  text += "]\n";
  const std::string scene = tmp.write("s.pbrt", text);
  const std::string ck = (tmp.path / "ck").string(), out = (tmp.path / "o.exr").string();
  pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    execl(THEIA_BINARY, THEIA_BINARY, "render", scene.c_str(), "--spp", "100000", "-q", "-o", out.c_str(),
          "--checkpoint-dir", ck.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  // The handler is the first thing main installs: wait for it, then signal
  // at once (the scene is still being read).
  auto t0 = std::chrono::steady_clock::now();
  while (!catches_sigterm(pid) && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(10))
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  ::kill(pid, SIGTERM);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << WTERMSIG(status);
  EXPECT_EQ(WEXITSTATUS(status), 75);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 5.0);
}

namespace {

// Diffuse sphere in a closed diffuse box, lit from inside: paths of a few
// bounces; pixels and iterations enough for a stop to land mid-iteration.
const char* kBoxScene = R"(Film "rgb" "integer xresolution" [24] "integer yresolution" [16]
LookAt 0 0 -3  0 0 0  0 1 0
Camera "perspective" "float fov" [60]
Sampler "zsobol" "integer pixelsamples" [40]
Integrator "volpath" "integer maxdepth" [12]
WorldBegin
LightSource "point" "rgb I" [5 5 5] "point3 from" [0.5 0.5 -1]
Material "diffuse" "rgb reflectance" [0.8 0.6 0.4]
Shape "sphere" "float radius" [0.7]
ReverseOrientation
Shape "sphere" "float radius" [6]
)";

struct Renders {
  TempDir tmp{"theia_hostile_resume"};
  std::string scene = tmp.write("s.pbrt", kBoxScene);
  std::string out(const std::string& name) const { return tmp.file(name); }
  RunResult render(const std::string& output, const std::string& more = "") const {
    return run("render " + scene + " -o " + out(output) + " --max-paths 1024 -q" + more);
  }
};

}  // namespace

TEST(Hostile, PathsAbandonedAfterASignalResumeToTheUninterruptedImage) {
  Renders f;
  ASSERT_EQ(f.render("ref.exr").exit_code, 0);
  const std::string ck = " --checkpoint-dir " + f.out("ck") + " --checkpoint-every-iteration";
  // Abandon at once: the paths in flight of iteration 1 are dropped, its
  // samples not written; generation 1 (after iteration 0) is what resumes.
  RunResult r = f.render("out.exr", ck + " --test-sigterm-at 1:0.4 --test-abandon-after 0");
  ASSERT_EQ(r.exit_code, 75) << r.output;
  EXPECT_NE(r.output.find("warning: paths still in flight after the signal's grace time were abandoned: iteration 1 "
                          "is lost; the resume continues from the newest checkpoint"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(f.out("ck/checkpoint-000002.bin")));
  r = f.render("out.exr", ck);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_LT(theia::test::max_relative_difference(theia::read_image_file(f.out("out.exr")),
                                                 theia::read_image_file(f.out("ref.exr"))),
            1e-5);  // summation order (test_resume.cpp)
}

TEST(Hostile, AFailedCheckpointWriteKeepsRenderingWhenAnOlderGenerationExists) {
  Renders f;
  ASSERT_EQ(f.render("ref.exr").exit_code, 0);
  const std::string ck = " --checkpoint-dir " + f.out("ck") + " --checkpoint-every-iteration";
  // Generation 2 cannot be written (a directory stands where its image goes), as on a full disk.
  fs::create_directories(f.out("ck/checkpoint-000002.exr"));
  RunResult r = f.render("out.exr", ck);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("; rendering on: a stop now resumes from generation 1 and loses the"), std::string::npos)
      << r.output;
  EXPECT_LT(theia::test::max_relative_difference(theia::read_image_file(f.out("out.exr")),
                                                 theia::read_image_file(f.out("ref.exr"))),
            1e-5);  // summation order (test_resume.cpp)
  // Stopped while the writes fail: the resume starts from generation 1 and still gives the image.
  fs::remove_all(f.out("ck2"));
  fs::create_directories(f.out("ck2/checkpoint-000002.exr"));
  const std::string ck2 = " --checkpoint-dir " + f.out("ck2") + " --checkpoint-every-iteration";
  ASSERT_EQ(f.render("out2.exr", ck2 + " --test-sigterm-at 2:0.5").exit_code, 75);
  fs::remove_all(f.out("ck2/checkpoint-000002.exr"));
  ASSERT_EQ(f.render("out2.exr", ck2).exit_code, 0);
  EXPECT_LT(theia::test::max_relative_difference(theia::read_image_file(f.out("out2.exr")),
                                                 theia::read_image_file(f.out("ref.exr"))),
            1e-5);  // summation order (test_resume.cpp)
  // Without an older generation the first write's failure is the error it was.
  fs::create_directories(f.out("ck3/checkpoint-000001.exr"));
  r = f.render("out3.exr", " --checkpoint-dir " + f.out("ck3") + " --checkpoint-every-iteration");
  EXPECT_EQ(r.exit_code, 1) << r.output;
}

// A closed sphere of albedo 0.9999 seen from inside: paths of ~10^4 bounces
// (scenes/extreme/closed-sphere.pbrt with a whiter wall).  Finishing the paths
// in flight after a SIGTERM took tens of seconds; a farm kills the job first.
TEST(Hostile, SigtermStopsRendersOfVeryLongPathsWithinFiveSeconds) {
  TempDir tmp("theia_hostile_long");
  const std::string scene = tmp.write("s.pbrt", R"(Film "rgb" "integer xresolution" [64] "integer yresolution" [64]
Sampler "zsobol" "integer pixelsamples" [1024]
Integrator "volpath" "integer maxdepth" [100000]
LookAt 0 0 0  0 0 1  0 1 0
Camera "perspective" "float fov" [60]
WorldBegin
AreaLightSource "diffuse" "rgb L" [1 1 1] "bool twosided" true
Material "diffuse" "rgb reflectance" [0.9999 0.9999 0.9999]
Shape "sphere" "float radius" [1]
)");
  const std::string out = tmp.file("o.exr"), ck = tmp.file("ck");
  pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    execl(THEIA_BINARY, THEIA_BINARY, "render", scene.c_str(), "-q", "-o", out.c_str(), "--checkpoint-dir",
          ck.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  auto t0 = std::chrono::steady_clock::now();
  ::kill(pid, SIGTERM);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 75);
  EXPECT_LT(seconds, 5.0);
}
