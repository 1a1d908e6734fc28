// Split frames: `theia render --sample-range` parts merged by `theia merge`
// equal the whole render (every channel, to float summation order), and the
// merge refuses parts that are not of one frame or do not tile its samples.
// Parts in which something learns (guiding, cache points' visibility) learn
// on their own: their merge is unbiased, not the whole render.
#include "core/image.h"
#include "core/metrics.h"
#include "light_sampler_checks.h"
#include "render_helpers.h"
#include "scheduler/schedule.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

namespace fs = std::filesystem;
using namespace theia;

namespace {

struct SplitFixture {
  fs::path dir;
  std::string scene;
  SplitFixture(const std::string& name, const std::string& text) {
    dir = fs::temp_directory_path() / ("theia_split_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    scene = (dir / "s.pbrt").string();
    std::ofstream(scene) << text;
  }
  ~SplitFixture() { fs::remove_all(dir); }
  std::string out(const std::string& name) const { return (dir / name).string(); }
  test::RunResult render(const std::string& output, const std::string& more) const {
    return test::run_theia("render " + scene + " -o " + out(output) + " -q " + more);
  }
  test::RunResult merge(const std::vector<std::string>& parts, const std::string& output) const {
    std::string cmd = "merge";
    for (const std::string& p : parts) {
      cmd += ' ';
      cmd += out(p);
    }
    return test::run_theia(cmd + " -o " + out(output));
  }
};

// Renders the parts [cuts[k], cuts[k+1]) and the whole frame; merges the parts.
void render_split(const SplitFixture& f, const std::vector<int>& cuts, const std::string& options) {
  ASSERT_EQ(f.render("whole.exr", options).exit_code, 0);
  std::vector<std::string> parts;
  // Given out of order: the merge sorts them by range.
  for (size_t k = cuts.size() - 1; k-- > 0;) {
    parts.push_back("part" + std::to_string(k) + ".exr");
    test::RunResult r = f.render(parts.back(), options + " --sample-range " + std::to_string(cuts[k]) + ":" +
                                                   std::to_string(cuts[k + 1]));
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  test::RunResult r = f.merge(parts, "merged.exr");
  ASSERT_EQ(r.exit_code, 0) << r.output;
}

}  // namespace

TEST(Split, FourPartsMergeToTheWholeRenderInEveryChannel) {
  SplitFixture f("four", test::sphere_floor_scene(1.0f));
  // Cuts inside and across the schedule's iterations (16 16 8); the event
  // layers are film planes like the beauty's and must merge as exactly.
  render_split(f, {0, 7, 16, 33, 40}, "--threads 2 --aov-events");
  const ImageBuffer whole = read_image_file(f.out("whole.exr")), merged = read_image_file(f.out("merged.exr"));
  EXPECT_GE(whole.channel_index("diffuse.R"), 0);
  EXPECT_GE(whole.channel_index("emission.B"), 0);
  EXPECT_LT(test::max_channel_difference(merged, whole), 1e-5);
  // The parts differ from one another (each is a quarter of the samples), so equality is not trivial.
  const ImageBuffer part = read_image_file(f.out("part0.exr"));
  EXPECT_GT(test::max_relative_difference(part, whole), 1e-3);
  nlohmann::json log = nlohmann::json::parse(std::ifstream(f.out("merged.json")));
  EXPECT_EQ(log["merged_from"].size(), 4u);
  EXPECT_EQ(log["scheduler"]["spp_per_pixel"]["min"], 40);
  EXPECT_TRUE(fs::exists(f.out("merged.png")));
  nlohmann::json part_log = nlohmann::json::parse(std::ifstream(f.out("part1.json")));
  EXPECT_EQ(part_log["part"]["sample_range"], nlohmann::json({7, 16}));
  EXPECT_EQ(part_log["scheduler"]["spp_per_pixel"]["min"], 9);
}

TEST(Split, CausticPassPartsMergeToTheWholeRender) {
  // A mirror ceiling over the light: the light-traced caustic pass is on, and
  // stays on in every part (farm/README.md); with 24x16 pixels it traces too
  // few paths for the whole render to switch it off.  Cuts inside each of the
  // schedule's iterations (16 16 32): a light path's splat is part of its
  // camera sample, so the parts hold exactly their samples' caustics.
  SplitFixture f("caustic", test::mirror_room_scene(24, 16, 0.05f));
  render_split(f, {0, 5, 23, 41, 64}, "--spp 64");
  nlohmann::json log = nlohmann::json::parse(std::ifstream(f.out("whole.json")));
  ASSERT_GT(log["caustics"]["splats"].get<uint64_t>(), 1000u) << log["caustics"].dump();
  ASSERT_EQ(log["caustics"]["switched_off_after_passes"], -1);
  const ImageBuffer whole = read_image_file(f.out("whole.exr")), merged = read_image_file(f.out("merged.exr"));
  EXPECT_LT(test::max_channel_difference(merged, whole), 1e-5);
  // The caustic pass carries most of the floor's light here (camera paths alone estimate it with other noise).
  ASSERT_EQ(f.render("camera-only.exr", "--spp 64 --no-caustics").exit_code, 0);
  EXPECT_GT(test::max_channel_difference(read_image_file(f.out("camera-only.exr")), whole), 0.1);
}

TEST(Split, MergeRefusesPartsOfAnotherFrameAndRangesThatDoNotTile) {
  SplitFixture f("refuse", test::sphere_floor_scene(1.0f));
  auto part = [&](const std::string& name, const std::string& range, const std::string& more = "") {
    test::RunResult r = f.render(name, "--spp 16 --sample-range " + range + more);
    ASSERT_EQ(r.exit_code, 0) << r.output;
  };
  part("a.exr", "0:8");
  part("b.exr", "8:16");
  part("late.exr", "4:16");
  part("seed.exr", "8:16", " --seed 3");
  part("depth.exr", "8:16", " --max-depth 2");
  ASSERT_EQ(f.merge({"a.exr", "b.exr"}, "ok.exr").exit_code, 0);
  auto refused = [&](const std::vector<std::string>& parts, const std::string& says) {
    test::RunResult r = f.merge(parts, "bad.exr");
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find(says), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(f.out("bad.exr")));
  };
  refused({"a.exr", "late.exr"}, "overlap");
  refused({"a.exr"}, "samples [8, 16) of the frame's 16 are in no part");
  refused({"b.exr"}, "samples [0, 8) of the frame's 16 are in no part");
  refused({"a.exr", "seed.exr"}, "different seeds (0 vs 3)");
  refused({"a.exr", "depth.exr"}, "max_depth (5 vs 2)");
  // Another scene: the same file with one value changed.
  std::ofstream(f.scene) << test::sphere_floor_scene(1.1f);
  part("other.exr", "8:16");
  refused({"a.exr", "other.exr"}, "different scenes");
  // A whole render is not a part.
  ASSERT_EQ(f.render("whole.exr", "--spp 16").exit_code, 0);
  refused({"whole.exr"}, "not a part of a split frame");
}

TEST(Split, RefusesAdaptiveSamplingInverseVarianceAndBadRanges) {
  SplitFixture f("learn", test::sphere_floor_scene(1.0f));
  auto refused = [&](const std::string& more, const std::string& says) {
    test::RunResult r = f.render("p.exr", "--spp 16 " + more);
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find(says), std::string::npos) << r.output;
  };
  refused("--sample-range 0:8 --adaptive", "--sample-range cannot be combined with --adaptive");
  refused("--sample-range 0:8 --combine inverse-variance", "--combine inverse-variance");
  refused("--sample-range 0:8 --time-limit 5", "--time-limit");
  refused("--sample-range 8:4", "BEGIN must be below END");
  refused("--sample-range 8", "expected BEGIN:END");
  refused("--sample-range 0:17", "--sample-range 0:17 is not within the frame's 16 samples per pixel");
}

TEST(Split, StoppedPartResumesExactlyAndOnlyForItsOwnRange) {
  SplitFixture f("resume", test::sphere_floor_scene(1.0f));
  const std::string opt = "--spp 40 --threads 2 --max-paths 512 --sample-range 8:40";
  ASSERT_EQ(f.render("ref.exr", opt).exit_code, 0);
  const std::string ck = " --checkpoint-dir " + f.out("ck");
  EXPECT_EQ(f.render("p.exr", opt + ck + " --test-sigterm-at 1:0.5").exit_code, 75);
  // Another range is refused: its samples would land on this one's.
  test::RunResult r = f.render("q.exr", "--spp 40 --sample-range 0:32" + ck);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("refusing to resume"), std::string::npos) << r.output;
  r = f.render("p.exr", opt + ck);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_LT(test::max_channel_difference(read_image_file(f.out("p.exr")), read_image_file(f.out("ref.exr"))), 1e-5);
}

namespace {

nlohmann::json read_json(const std::string& path) { return nlohmann::json::parse(std::ifstream(path)); }

}  // namespace

// Guiding in a part learns on its own from the part's first sample: the part
// renders the schedule of a whole render of its length (its own training
// iterations first), says so in its log, and the merge is unbiased but not the
// single-process image, and says so.  Unbiased: against an unguided render of
// 16x the samples, the merged image is as close as the unsplit guided render
// and has the same mean (a part's samples or weights lost or counted twice
// would move the mean by a third or more).  --guiding-auto's verdicts are
// measurements of time, so they may differ between the parts and the unsplit
// render: its merged error is held to the larger of the two unsplit errors
// (guiding on costs variance in this scene, lit by the environment alone).
TEST(Split, GuidedPartsLearnOnTheirOwnAndMergeWithoutBias) {
  SplitFixture f("guided", test::sphere_floor_scene(1.0f));
  ASSERT_EQ(f.render("ref.exr", "--spp 1024 --seed 7").exit_code, 0);
  const ImageBuffer ref = read_image_file(f.out("ref.exr"));
  double guided_error = 0.0;
  for (const std::string mode : {"--guiding", "--guiding-auto"}) {
    SCOPED_TRACE(mode);
    // Training 16 spp: with --guiding-auto the probe's pair (from 8 spp) lies in each part.
    render_split(f, {0, 32, 64}, "--spp 64 --guiding-training-spp 16 " + mode);
    const nlohmann::json whole = read_json(f.out("whole.json"));
    for (const std::string part : {"part0", "part1"}) {
      SCOPED_TRACE(part);
      const nlohmann::json log = read_json(f.out(part + ".json"));
      EXPECT_EQ(log["part"]["learns"], nlohmann::json({"guiding"}));
      EXPECT_EQ(log["scheduler"]["schedule"].get<std::vector<int>>(), make_schedule(guiding_schedule(), 32));
      // The field trained on the part's first 16 samples, as the whole render's on its first 16.
      EXPECT_EQ(log["guiding"]["updates"], whole["guiding"]["updates"]);
      if (mode == "--guiding-auto") {
        EXPECT_TRUE(log["guiding"]["auto"]["probe"]["measured"].get<bool>());
      }
    }
    const nlohmann::json merged_log = read_json(f.out("merged.json"));
    EXPECT_EQ(merged_log["learned_per_part"], nlohmann::json({"guiding"}));
    EXPECT_FALSE(merged_log["equals_single_process_render"].get<bool>());
    const ImageBuffer merged = read_image_file(f.out("merged.exr")), unsplit = read_image_file(f.out("whole.exr"));
    // Not the whole render: the second part's field learned from other samples.
    EXPECT_GT(test::max_relative_difference(merged, unsplit), 1e-3);
    const double merged_error = rel_mse(merged, ref), unsplit_error = rel_mse(unsplit, ref);
    std::printf("%s: relMSE merged %.3g, unsplit %.3g; mean deviation merged %.3g, unsplit %.3g\n", mode.c_str(),
                merged_error, unsplit_error, channel_mean_deviation(merged, ref), channel_mean_deviation(unsplit, ref));
    if (mode == "--guiding") guided_error = unsplit_error;
    EXPECT_LT(merged_error, 1.5 * std::max(unsplit_error, guided_error));
    EXPECT_LT(channel_mean_deviation(merged, ref), 0.01);
  }
}

// A guided part is a pure function of its options and range (one thread: no
// summation order to vary), and one stopped and resumed equals the
// uninterrupted part: the checkpoint carries the field, and the resumed part
// trains on the first samples of its own range, not of the frame.
TEST(Split, GuidedPartIsDeterministicAndResumesExactly) {
  SplitFixture f("guided_resume", test::sphere_floor_scene(1.0f));
  const std::string opt = "--spp 40 --guiding --guiding-training-spp 10 --threads 1 --max-paths 512 --sample-range 8:40";
  ASSERT_EQ(f.render("ref.exr", opt).exit_code, 0);
  ASSERT_EQ(f.render("again.exr", opt).exit_code, 0);
  const ImageBuffer ref = read_image_file(f.out("ref.exr")), again = read_image_file(f.out("again.exr"));
  EXPECT_EQ(ref.channels, again.channels);
  EXPECT_TRUE(ref.data == again.data) << "two runs of one part differ";
  // Its own schedule for 32 spp: 1 x8, 2 4 8 10; training on [8, 18) is its first 9 iterations.
  EXPECT_EQ(read_json(f.out("ref.json"))["guiding"]["updates"], 9);
  // Stopped at a boundary while training, inside the last training iteration, inside a frozen one.
  for (const std::string at : {"3:0", "8:0.5", "9:0.5"}) {
    SCOPED_TRACE(at);
    const std::string ck = " --checkpoint-dir " + f.out("ck" + at.substr(0, 1));
    ASSERT_EQ(f.render("p.exr", opt + ck + " --test-sigterm-at " + at).exit_code, 75);
    test::RunResult r = f.render("p.exr", opt + ck + " --resume");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const nlohmann::json log = read_json(f.out("p.json"));
    EXPECT_GT(log["scheduler"]["resumed_at_iteration"].get<int>(), 0);
    EXPECT_EQ(log["guiding"]["updates"], 9);
    EXPECT_LT(test::max_channel_difference(read_image_file(f.out("p.exr")), ref), 1e-5);
  }
  // Guiding changed the part (the field was used, not only trained).
  ASSERT_EQ(f.render("plain.exr", "--spp 40 --threads 1 --sample-range 8:40").exit_code, 0);
  EXPECT_GT(test::max_relative_difference(read_image_file(f.out("plain.exr")), ref), 1e-3);
}

// Guided and unguided parts, or parts guided in different ways, are not parts of one frame.
TEST(Split, MergeRefusesGuidedWithUnguidedParts) {
  SplitFixture f("guided_refuse", test::sphere_floor_scene(1.0f));
  auto part = [&](const std::string& name, const std::string& range, const std::string& more) {
    test::RunResult r = f.render(name, "--spp 16 --sample-range " + range + more);
    ASSERT_EQ(r.exit_code, 0) << r.output;
  };
  part("guided.exr", "0:8", " --guiding");
  part("plain.exr", "8:16", "");
  part("auto.exr", "8:16", " --guiding-auto --guiding-training-spp 8");  // shorter training than the render, or auto is off
  part("guided2.exr", "8:16", " --guiding");
  auto refused = [&](const std::vector<std::string>& parts, const std::string& says) {
    test::RunResult r = f.merge(parts, "bad.exr");
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find(says), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(f.out("bad.exr")));
  };
  refused({"guided.exr", "plain.exr"}, "learned guiding on its own but " + f.out("plain.exr") +
                                           " learned nothing: parts of one frame learn the same way");
  refused({"guided.exr", "plain.exr"}, "guiding (\"on\" vs \"off\")");
  refused({"guided.exr", "auto.exr"}, "different image options: guiding (\"on\" vs \"auto\")");
  test::RunResult r = f.merge({"guided.exr", "guided2.exr"}, "ok.exr");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("each part learned guiding on its own: the merged image is unbiased but is not the image "
                          "one process renders"),
            std::string::npos)
      << r.output;
}

// Cache points learn visibility between iterations (shadow rays' successes
// per point and light): a part starts from none, counts its own shadow rays
// and learns on its own like guiding, and says so; the merge is unbiased.
TEST(Split, CachePointPartsLearnVisibilityOnTheirOwn) {
  SplitFixture f("cachepoints", test::lit_street());
  const std::string opt = "--spp 64 --light-sampler cachepoints";
  render_split(f, {0, 24, 64}, opt);
  const nlohmann::json whole = read_json(f.out("whole.json")), last = read_json(f.out("part1.json"));
  EXPECT_EQ(last["part"]["learns"], nlohmann::json({"cachepoints"}));
  EXPECT_EQ(last["scheduler"]["schedule"].get<std::vector<int>>(), make_schedule(regular_schedule(), 40));
  // Its own shadow rays only: about 40/64 of the whole render's, not all of them.
  const double own = last["light_sampler"]["shadow_attempts"].get<double>(),
               all = whole["light_sampler"]["shadow_attempts"].get<double>();
  EXPECT_GT(own, 0.5 * all);
  EXPECT_LT(own, 0.75 * all);
  const nlohmann::json merged_log = read_json(f.out("merged.json"));
  EXPECT_EQ(merged_log["learned_per_part"], nlohmann::json({"cachepoints"}));
  EXPECT_FALSE(merged_log["equals_single_process_render"].get<bool>());
  const ImageBuffer merged = read_image_file(f.out("merged.exr")), unsplit = read_image_file(f.out("whole.exr"));
  EXPECT_LT(channel_mean_deviation(merged, unsplit), 0.01);
  // Power sampling learns nothing: its parts merge to the whole render.
  SplitFixture g("power", test::lit_street());
  render_split(g, {0, 24, 64}, "--spp 64 --light-sampler power");
  EXPECT_EQ(read_json(g.out("part1.json"))["part"]["learns"], nlohmann::json::array());
  EXPECT_TRUE(read_json(g.out("merged.json"))["equals_single_process_render"].get<bool>());
  EXPECT_LT(test::max_channel_difference(read_image_file(g.out("merged.exr")), read_image_file(g.out("whole.exr"))), 1e-5);
}
