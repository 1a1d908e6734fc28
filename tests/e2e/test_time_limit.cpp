// --time-limit: the render ends early but normally.  The in-process tests
// raise the time-limit stop from the progress callback at a chosen point (no
// clock involved), so what they check is exact: every sample rendered is in
// the image, each pixel's weight is what the log says, nothing is left to
// resume.  The command-line tests run a real limit and assert on behaviour only.
#include "render_helpers.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

namespace fs = std::filesystem;
using namespace theia;

namespace {

// A box filter: every sample weighs 1, so a pixel's weight is its sample count.
const char* kScene = R"(Film "rgb" "integer xresolution" [24] "integer yresolution" [16]
PixelFilter "box"
LookAt 0 1 -5  0 0 0  0 1 0
Camera "perspective" "float fov" [35]
WorldBegin
LightSource "infinite" "rgb L" [1 1 1]
Material "diffuse" "rgb reflectance" [0.7 0.5 0.3]
Shape "sphere" "float radius" [1]
Shape "trianglemesh" "point3 P" [-4 -1 -4  4 -1 -4  4 -1 4  -4 -1 4] "integer indices" [0 1 2 0 2 3]
)";

// Iterations 4 4 8 8 (24 spp); a small pool, so an iteration takes many generations.
RenderConfig config(int spp = 24) {
  RenderConfig c;
  c.spp = spp;
  c.iteration.first = 4;
  c.iteration.repeat = 2;
  c.iteration.growth = 2.0;
  c.iteration.max = 8;
  c.max_paths = 64;
  c.batch_size = 32;
  return c;
}

// Renders with the time-limit stop raised once iteration `it` has generated a fraction `at` of its camera rays.
RenderResult render_stopped_by_time(const Scene& scene, RenderConfig c, int it, double at, StopRequest& stop) {
  c.stop = &stop;
  c.on_iteration_progress = [&stop, it, at](int i, double f) {
    if (i == it && f >= at) stop.raise(StopReason::TimeLimit);
  };
  return render_scene(scene, c);
}

bool all_finite(const ImageBuffer& img) {
  return std::all_of(img.data.begin(), img.data.end(), [](float v) { return std::isfinite(v); });
}

// The log's spp range is the pixels' weights' range, and every pixel has a whole number of samples.
void expect_spp_matches_weights(const RenderResult& r) {
  const uint32_t lo = r.log["scheduler"]["spp_per_pixel"]["min"], hi = r.log["scheduler"]["spp_per_pixel"]["max"];
  ASSERT_FALSE(r.weight.empty());
  auto [wmin, wmax] = std::minmax_element(r.weight.begin(), r.weight.end());
  EXPECT_EQ(*wmin, float(lo));
  EXPECT_EQ(*wmax, float(hi));
  for (float w : r.weight) EXPECT_EQ(w, std::round(w));
}

}  // namespace

TEST(TimeLimit, StopInsideAnIterationKeepsItsSamplesAndEndsNormally) {
  Scene scene = test::load_test_scene(kScene);
  StopRequest stop;
  RenderResult r = render_stopped_by_time(scene, config(), 2, 0.5, stop);
  ASSERT_FALSE(r.interrupted);
  ASSERT_FALSE(r.image.data.empty());
  EXPECT_TRUE(all_finite(r.image));
  const nlohmann::json& s = r.log["scheduler"];
  EXPECT_TRUE(s["time_limit"]["reached"].get<bool>());
  // Iteration 2 (samples 8..16) stopped part-way: the first pixels have 16, the last 8.
  EXPECT_EQ(s["spp_per_pixel"]["min"].get<uint32_t>(), 8u);
  EXPECT_EQ(s["spp_per_pixel"]["max"].get<uint32_t>(), 16u);
  expect_spp_matches_weights(r);
  // Every camera sample rendered is in the image.
  double weight = 0.0;
  for (float w : r.weight) weight += w;
  EXPECT_EQ(uint64_t(weight), r.log["rays"]["camera"].get<uint64_t>());
  EXPECT_EQ(s["iterations"].size(), 3u);
  EXPECT_LT(s["iterations"][2]["stopped_after_camera_samples"].get<uint64_t>(),
            s["iterations"][2]["of_camera_samples"].get<uint64_t>());
  // Its CPU time is logged like a finished iteration's (what per-sample costs are computed from).
  EXPECT_GT(s["iterations"][2]["cpu_seconds"].get<double>(), 0.0);

  // Unbiased: the mean is an uninterrupted render's, within the noise of 8-16 spp.
  RenderResult full = render_scene(scene, config());
  EXPECT_EQ(full.log["scheduler"]["spp_per_pixel"]["min"].get<uint32_t>(), 24u);
  EXPECT_FALSE(full.log["scheduler"]["time_limit"]["reached"].get<bool>());
  RGB a = test::image_mean(r.image), b = test::image_mean(full.image);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c] / b[c], 1.0, 0.03) << c;
}

TEST(TimeLimit, StopBetweenIterationsEndsWithTheFinishedOnes) {
  Scene scene = test::load_test_scene(kScene);
  StopRequest stop;
  // Raised as iteration 1 generates its last rays: it finishes, iteration 2 never starts.
  RenderResult r = render_stopped_by_time(scene, config(), 1, 1.0, stop);
  ASSERT_FALSE(r.interrupted);
  EXPECT_TRUE(r.log["scheduler"]["time_limit"]["reached"].get<bool>());
  EXPECT_EQ(r.log["scheduler"]["spp_per_pixel"]["min"].get<uint32_t>(), 8u);
  EXPECT_EQ(r.log["scheduler"]["spp_per_pixel"]["max"].get<uint32_t>(), 8u);
  expect_spp_matches_weights(r);
}

// Adaptive sampling and inverse-variance combination were built for whole
// iterations; a stopped one must still give a valid image.
TEST(TimeLimit, AdaptiveAndInverseVarianceImagesStayValidWhenStoppedInsideAnIteration) {
  Scene scene = test::load_test_scene(kScene);
  RenderResult full = render_scene(scene, config());
  const RGB want = test::image_mean(full.image);
  for (const char* mode : {"adaptive", "inverse-variance", "guided inverse-variance"}) {
    SCOPED_TRACE(mode);
    RenderConfig c = config();
    const std::string m = mode;
    if (m == "adaptive") c.adaptive.enabled = true;
    if (m != "adaptive") c.combine = "inverse-variance";
    if (m == "guided inverse-variance") c.guiding.enabled = OnOffAuto::On;
    StopRequest stop;
    RenderResult r = render_stopped_by_time(scene, c, 3, 0.4, stop);
    ASSERT_FALSE(r.interrupted);
    EXPECT_TRUE(all_finite(r.image));
    EXPECT_TRUE(r.log["scheduler"]["time_limit"]["reached"].get<bool>());
    expect_spp_matches_weights(r);
    // No pixel black for want of samples: each has some, and the image is the full render's on average.
    EXPECT_GT(r.log["scheduler"]["spp_per_pixel"]["min"].get<uint32_t>(), 0u);
    RGB got = test::image_mean(r.image);
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(got[ch] / want[ch], 1.0, 0.05) << ch;
  }
}

// The light-traced caustic pass runs once an iteration's camera samples are
// in; a time-stopped iteration keeps its samples, so it needs the pass too.
// The pixels the stopped iteration finished have the uninterrupted render's
// samples exactly, caustic included (without the pass the floor, lit almost
// only by the caustic, comes out darker there).
TEST(TimeLimit, AStoppedIterationGetsItsCausticPass) {
  Scene scene = test::load_test_scene(test::mirror_room_scene(24, 16, 0.05f));
  RenderConfig c = config();
  RenderResult full = render_scene(scene, c);
  ASSERT_TRUE(full.log["caustics"]["traced"].get<bool>());
  ASSERT_GT(full.log["caustics"]["receiver_hits"].get<uint64_t>(), 0u);
  StopRequest stop;
  RenderResult r = render_stopped_by_time(scene, c, 3, 0.75, stop);
  ASSERT_FALSE(r.interrupted);
  ASSERT_LT(r.log["scheduler"]["spp_per_pixel"]["min"].get<uint32_t>(), 24u);
  // At least 3/4 of the pixels (in pixel order: the first rows) finished the last iteration.
  double got = 0.0, want = 0.0;
  for (int y = 0; y < r.image.height * 3 / 4 - 1; ++y)
    for (int x = 0; x < r.image.width; ++x) {
      got += test::pixel_channel(r.image, x, y, 1);
      want += test::pixel_channel(full.image, x, y, 1);
    }
  ASSERT_GT(want, 0.0);
  EXPECT_NEAR(got / want, 1.0, 1e-4);
}

// --- the command line, with a real clock ---------------------------------------

TEST(TimeLimit, CommandLineStopsAHugeRenderWritesItsImageAndExitsZero) {
  test::TempDir tmp("theia_time_limit");
  tmp.write("s.pbrt", kScene);
  const std::string scene = (tmp.path / "s.pbrt").string(), out = (tmp.path / "o.exr").string();
  const int spp = 1 << 24;  // hours at this size
  test::RunResult run = test::run_theia("render " + scene + " -o " + out + " --spp " + std::to_string(spp) +
                                        " --time-limit 0.5");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("--time-limit 0.5 s reached"), std::string::npos) << run.output;
  ImageBuffer img = read_image_file(out);
  EXPECT_TRUE(all_finite(img));
  nlohmann::json log = nlohmann::json::parse(std::ifstream(tmp.path / "o.json"));
  const nlohmann::json& s = log["scheduler"];
  EXPECT_TRUE(s["time_limit"]["reached"].get<bool>());
  EXPECT_EQ(s["time_limit"]["seconds"].get<double>(), 0.5);
  EXPECT_GE(s["time_limit"]["elapsed_seconds"].get<double>(), 0.5);
  const uint32_t lo = s["spp_per_pixel"]["min"], hi = s["spp_per_pixel"]["max"];
  EXPECT_GT(hi, 0u);
  EXPECT_LE(lo, hi);
  EXPECT_LT(hi, uint32_t(spp));
  // The camera rays are the samples the pixels got: between min and max each.
  const uint64_t camera = log["rays"]["camera"], pixels = 24 * 16;
  EXPECT_GE(camera, uint64_t(lo) * pixels);
  EXPECT_LE(camera, uint64_t(hi) * pixels);

  for (const char* bad : {"-1", "nan", "inf"}) {
    test::RunResult r = test::run_theia("render " + scene + " -o " + out + " --time-limit " + bad);
    EXPECT_NE(r.exit_code, 0) << bad;
    EXPECT_NE(r.output.find("--time-limit"), std::string::npos) << bad << ": " << r.output;
  }
}

// A time-limited render that finished is finished: its last checkpoint says
// so, and the same command run again writes the same image without rendering
// (it does not continue from an earlier checkpoint).
TEST(TimeLimit, WithCheckpointsARerunWritesTheSameImageAndRendersNothing) {
  test::TempDir tmp("theia_time_limit_ck");
  tmp.write("s.pbrt", kScene);
  const std::string cmd = "render " + (tmp.path / "s.pbrt").string() + " -o " + (tmp.path / "o.exr").string() +
                          " --spp 100000 --time-limit 0.5 --checkpoint-dir " + (tmp.path / "ck").string();
  ASSERT_EQ(test::run_theia(cmd).exit_code, 0);
  ImageBuffer first = read_image_file((tmp.path / "o.exr").string());
  nlohmann::json log1 = nlohmann::json::parse(std::ifstream(tmp.path / "o.json"));
  ASSERT_TRUE(log1["scheduler"]["time_limit"]["reached"].get<bool>());

  test::RunResult again = test::run_theia(cmd);
  ASSERT_EQ(again.exit_code, 0) << again.output;
  nlohmann::json log2 = nlohmann::json::parse(std::ifstream(tmp.path / "o.json"));
  EXPECT_TRUE(log2["scheduler"]["resumed"].get<bool>());
  EXPECT_EQ(log2["rays"]["camera"].get<uint64_t>(), 0u);
  EXPECT_TRUE(log2["scheduler"]["time_limit"]["reached"].get<bool>());
  EXPECT_FALSE(log2["scheduler"]["time_limit"]["reached_in_this_run"].get<bool>());
  EXPECT_EQ(log2["scheduler"]["spp_per_pixel"], log1["scheduler"]["spp_per_pixel"]);
  ImageBuffer second = read_image_file((tmp.path / "o.exr").string());
  EXPECT_EQ(first.data, second.data);
}
