// Stopping and resuming the `theia` binary as a render farm does: SIGTERM in
// different iterations (at a boundary and in the middle), checkpoint files
// damaged, the scene or options changed between runs.
#include "app/options.h"
#include "checkpoint/checkpoint.h"
#include "core/log.h"
#include "core/image.h"
#include "render_helpers.h"
#include "tests/test_util.h"

#include "guiding/field_file.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <string>

namespace fs = std::filesystem;
using namespace theia;

namespace {

constexpr int kInterrupted = 75;  // app/render.h kExitInterrupted

using test::RunResult;
using test::run_shell;
RunResult run(const std::string& args) { return test::run_theia(args); }

fs::path temp_dir(const std::string& name) {
  fs::path d = fs::temp_directory_path() / ("theia_resume_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

using test::sphere_floor_scene;

struct Fixture {
  fs::path dir;
  std::string scene, common;
  explicit Fixture(const std::string& name, const std::string& extra = "") : dir(temp_dir(name)) {
    scene = (dir / "s.pbrt").string();
    std::ofstream(scene) << sphere_floor_scene(1.0f);
    // A small pool so that one iteration takes many camera-ray generations:
    // a stop can land in the middle of it.
    common = " --max-paths 1024 -q " + extra;
  }
  ~Fixture() { fs::remove_all(dir); }
  std::string out(const std::string& name) const { return (dir / name).string(); }
  RunResult render(const std::string& output, const std::string& more = "") const {
    return run("render " + scene + " -o " + out(output) + common + more);
  }
  // Stopped at each of `stops` in turn (with checkpoints in `ck`), then resumed
  // to the end: the largest relative difference from `ref` (infinity if a run failed).
  double resumed_difference(const std::string& ck, const std::vector<std::string>& stops, const ImageBuffer& ref) const {
    for (const std::string& at : stops) {
      const RunResult r = render("out.exr", " --checkpoint-dir " + ck + " --test-sigterm-at " + at);
      EXPECT_EQ(r.exit_code, kInterrupted) << at << "\n" << r.output;
      if (r.exit_code != kInterrupted) return kInfinity;
    }
    const RunResult r = render("out.exr", " --checkpoint-dir " + ck + " --resume");
    EXPECT_EQ(r.exit_code, 0) << r.output;
    if (r.exit_code != 0) return kInfinity;
    const double difference = test::max_relative_difference(read_image_file(out("out.exr")), ref);
    fs::remove(out("out.exr"));
    return difference;
  }
};

}  // namespace

// With --aov-events, so that the event planes are checkpointed and restored
// (the total's and the stopped iteration's) as exactly as the beauty's.
TEST(Resume, SigtermInDifferentIterationsThenResumeEqualsAnUninterruptedRender) {
  Fixture f("kill", " --aov-events");
  ASSERT_EQ(f.render("ref.exr").exit_code, 0);
  ImageBuffer ref = read_image_file(f.out("ref.exr"));
  // Schedule for 40 spp: 16 16 8.  Stops at the very start, mid-way through the
  // first, second and last iterations; one run is stopped twice before it finishes.
  const std::vector<std::vector<std::string>> stops = {{"0:0"}, {"0:0.5"}, {"1:0.3", "2:0.6"}, {"2:0.9"}};
  for (size_t k = 0; k < stops.size(); ++k) {
    std::string ck = f.out("ck" + std::to_string(k));
    for (const std::string& at : stops[k]) {
      RunResult r = f.render("out.exr", " --checkpoint-dir " + ck + " --test-sigterm-at " + at);
      ASSERT_EQ(r.exit_code, kInterrupted) << at << "\n" << r.output;
      EXPECT_FALSE(fs::exists(f.out("out.exr"))) << "an interrupted render writes no image";
    }
    RunResult r = f.render("out.exr", " --checkpoint-dir " + ck + " --resume");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    ImageBuffer img = read_image_file(f.out("out.exr"));
    EXPECT_LT(test::max_channel_difference(img, ref), 1e-5) << "stopped at " << stops[k][0];
    EXPECT_GE(img.channel_index("diffuse.G"), 0);
    nlohmann::json log = nlohmann::json::parse(std::ifstream(f.out("out.json")));
    EXPECT_TRUE(log["scheduler"]["resumed"].get<bool>());
    fs::remove(f.out("out.exr"));
  }
}

TEST(Resume, GuidingScheduleWithInverseVarianceWeightingResumesExactly) {
  Fixture f("guiding", " --schedule guiding --combine inverse-variance --spp 24");
  ASSERT_EQ(f.render("ref.exr").exit_code, 0);
  ImageBuffer ref = read_image_file(f.out("ref.exr"));
  std::string ck = f.out("ck");
  // Guiding schedule for 24 spp: 1 x8, 2 4 8 2: stop inside the 4-spp iteration (index 9).
  ASSERT_EQ(f.render("out.exr", " --checkpoint-dir " + ck + " --test-sigterm-at 9:0.5").exit_code, kInterrupted);
  ASSERT_EQ(f.render("out.exr", " --checkpoint-dir " + ck).exit_code, 0);
  EXPECT_LT(test::max_relative_difference(read_image_file(f.out("out.exr")), ref), 1e-5);
  // The weighted runs were restored: the weighting's own variance estimate
  // (which it compares with equal weights' to choose) is the uninterrupted one's.
  auto used = [&](const std::string& log) {
    return nlohmann::json::parse(std::ifstream(f.out(log)))["scheduler"]["combination_used"];
  };
  const nlohmann::json a = used("ref.json"), b = used("out.json");
  ASSERT_GT(a["estimated_variance"]["inverse_variance"].get<double>(), 0.0) << a;
  EXPECT_NEAR(b["estimated_variance"]["inverse_variance"].get<double>() /
                  a["estimated_variance"]["inverse_variance"].get<double>(),
              1.0, 1e-5);
  EXPECT_EQ(a["window_spp"], b["window_spp"]);
  EXPECT_EQ(a["used"], b["used"]);
}

TEST(Resume, CorruptNewestCheckpointFallsBackToThePreviousOrFailsClearly) {
  Fixture f("corrupt");
  ASSERT_EQ(f.render("ref.exr").exit_code, 0);
  ImageBuffer ref = read_image_file(f.out("ref.exr"));
  std::string ck = f.out("ck");
  // Checkpoints after every iteration, stopped in the last one: generations 1 2 3 on disk (1 dropped).
  RunResult r = f.render("out.exr", " --checkpoint-dir " + ck + " --checkpoint-every-iteration --test-sigterm-at 2:0.5");
  ASSERT_EQ(r.exit_code, kInterrupted) << r.output;
  ASSERT_TRUE(fs::exists(checkpoint_bin_path(ck, 3)));
  ASSERT_TRUE(fs::exists(checkpoint_bin_path(ck, 2)));
  fs::resize_file(checkpoint_bin_path(ck, 3), fs::file_size(checkpoint_bin_path(ck, 3)) / 2);
  r = f.render("out.exr", " --checkpoint-dir " + ck + " --checkpoint-every-iteration");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("skipping a bad checkpoint"), std::string::npos) << r.output;
  EXPECT_LT(test::max_relative_difference(read_image_file(f.out("out.exr")), ref), 1e-5);

  // Every checkpoint damaged: one clear error, non-zero exit.
  for (const auto& e : fs::directory_iterator(ck))
    if (e.path().extension() == ".exr") fs::resize_file(e.path(), 100);
  r = f.render("out2.exr", " --checkpoint-dir " + ck);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.exit_code, kInterrupted);
  EXPECT_NE(r.output.find("no valid checkpoint"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(f.out("out2.exr")));
}

TEST(Resume, RefusedOnAChangedSceneOrImageOption) {
  Fixture f("changed");
  std::string ck = f.out("ck");
  ASSERT_EQ(f.render("out.exr", " --checkpoint-dir " + ck + " --test-sigterm-at 1:0.5").exit_code, kInterrupted);
  RunResult r = f.render("out.exr", " --checkpoint-dir " + ck + " --seed 7");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("different image-affecting options"), std::string::npos) << r.output;
  std::ofstream(f.scene) << sphere_floor_scene(1.1f);
  r = f.render("out.exr", " --checkpoint-dir " + ck);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("different scene"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(f.out("out.exr")));
  // Back to the same scene; threads do not change the image: accepted.
  std::ofstream(f.scene) << sphere_floor_scene(1.0f);
  r = f.render("out.exr", " --checkpoint-dir " + ck + " --threads 1");
  EXPECT_EQ(r.exit_code, 0) << r.output;

  // --resume with nothing to resume is an error; without --resume it starts afresh.
  r = f.render("o2.exr", " --checkpoint-dir " + f.out("empty") + " --resume");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("no checkpoint"), std::string::npos) << r.output;
}

TEST(Resume, CheckpointShareOfWallTimeIsLoggedWithAndWithoutSkipping) {
  Fixture f("share", " --schedule guiding --spp 24");
  ASSERT_EQ(f.render("a.exr", " --checkpoint-dir " + f.out("ck_skip")).exit_code, 0);
  nlohmann::json skip = nlohmann::json::parse(std::ifstream(f.out("a.json")))["scheduler"];
  ASSERT_EQ(f.render("b.exr", " --checkpoint-dir " + f.out("ck_all") + " --checkpoint-every-iteration").exit_code, 0);
  nlohmann::json all = nlohmann::json::parse(std::ifstream(f.out("b.json")))["scheduler"];
  // 1 x8, 2 4 8 2 = cumulative 1..8 10 14 22 24; ideals 4 8 16 24 -> 4 written.
  EXPECT_EQ(skip["checkpoint"]["written"].get<int>(), 4);
  EXPECT_EQ(all["checkpoint"]["written"].get<int>(), 12);
  // Logged for both; which share is larger is a measurement of time (two
  // processes on a shared machine), so it is not asserted here.
  for (const nlohmann::json* s : {&skip, &all}) {
    EXPECT_GT((*s)["checkpoint"]["share_of_wall"].get<double>(), 0.0);
    EXPECT_LT((*s)["checkpoint"]["share_of_wall"].get<double>(), 1.0);
  }
  EXPECT_EQ(skip["iterations"].size(), 12u);
}

TEST(Resume, AdaptiveSamplingResumesExactly) {
  // 40 spp as 4 8 16 12: the sampler's plan and its partial iteration are in the checkpoint.
  Fixture f("adaptive", " --adaptive --iteration-first 4 --iteration-repeat 1");
  ASSERT_EQ(f.render("ref.exr").exit_code, 0);
  ImageBuffer ref = read_image_file(f.out("ref.exr"));
  for (const char* at : {"2:0.5", "3:0.3"}) {
    std::string ck = f.out(std::string("ck") + at[0]);
    ASSERT_EQ(f.render("out.exr", " --checkpoint-dir " + ck + " --test-sigterm-at " + at).exit_code, kInterrupted);
    RunResult r = f.render("out.exr", " --checkpoint-dir " + ck);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_LT(test::max_relative_difference(read_image_file(f.out("out.exr")), ref), 1e-5) << at;
  }
}

TEST(Resume, SigtermFromAnotherProcess) {
  // As a farm does it: kill -TERM from outside, once the render is under way
  // (a checkpoint exists).  Any generation: the first is deleted once the
  // third is written, and a poll that missed it would wait for the end.
  Fixture f("external", " --spp 512 --threads 1");
  ASSERT_EQ(f.render("ref.exr").exit_code, 0);
  std::string ck = f.out("ck");
  std::string cmd = "sh -c '" + std::string(THEIA_BINARY) + " render " + f.scene + " -o " + f.out("out.exr") +
                    f.common + " --checkpoint-dir " + ck + " & pid=$!; while ! ls " + ck + "/checkpoint-*.bin >/dev/null 2>&1 && kill -0 $pid 2>/dev/null;" +
                    " do sleep 0.02; done; kill -TERM $pid; wait $pid; echo exit=$?'";
  RunResult r = run_shell(cmd);
  ASSERT_NE(r.output.find("exit=75"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(f.out("out.exr")));
  r = f.render("out.exr", " --checkpoint-dir " + ck);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  nlohmann::json log = nlohmann::json::parse(std::ifstream(f.out("out.json")));
  EXPECT_GT(log["scheduler"]["resumed_at_iteration"].get<int>(), 0);
  EXPECT_LT(test::max_relative_difference(read_image_file(f.out("out.exr")), read_image_file(f.out("ref.exr"))), 1e-5);
}

// With path guiding the checkpoint carries the SD-tree, the recorder's skip
// rate and what an interrupted iteration had recorded, so that a resumed
// render trains, guides and renders exactly as an uninterrupted one.
TEST(Resume, PathGuidingResumesExactly) {
  Fixture f("pathguiding", " --guiding --guiding-training-spp 10 --spp 24");
  ASSERT_EQ(f.render("ref.exr").exit_code, 0);
  ImageBuffer ref = read_image_file(f.out("ref.exr"));
  // Guiding schedule for 24 spp: 1 x8, 2 4 8 2; the field trains on the
  // first 10 spp.  Stop at a boundary after training began, and inside the
  // 4-spp iteration (index 9, the first with the frozen field) twice over.
  const std::vector<std::vector<std::string>> stops = {{"3:0"}, {"9:0.5"}, {"8:0.4", "9:0.7"}};
  for (size_t k = 0; k < stops.size(); ++k)
    EXPECT_LT(f.resumed_difference(f.out("ck" + std::to_string(k)), stops[k], ref), 1e-5) << "stopped at " << stops[k][0];
  // Guiding changed the image (the field was used, not only trained).
  ASSERT_EQ(run("render " + f.scene + " -o " + f.out("plain.exr") + " --max-paths 1024 -q --spp 24 --schedule guiding")
                .exit_code,
            0);
  EXPECT_GT(test::max_relative_difference(read_image_file(f.out("plain.exr")), ref), 1e-3);
}

// With --guiding-field vmm the checkpoint also carries the mixture (section
// 'guiding-vmm': every region's lobes, statistics and pivot), so that a
// resumed render fits, guides and renders as an uninterrupted one.  On one
// thread, so that the film's sums are in one order: stopped at a boundary
// during training (3:0), inside a training iteration (6:0.5) and at the
// boundary after training (10:0), the image is the uninterrupted one bit for
// bit.  Stopped inside the first iteration with the frozen field (9:0.5, and
// twice over across the end of training) it is within 1e-5, as the
// SD-tree's is (Resume.PathGuidingResumesExactly): there the partial
// iteration's sums are restored and added in another order (cornell-box,
// sdtree or vmm alike: relMSE ~1e-17).
TEST(Resume, MixtureFieldResumesExactly) {
  Fixture f("vmm", " --threads 1 --guiding --guiding-field vmm --guiding-training-spp 10 --spp 24");
  ASSERT_EQ(f.render("ref.exr").exit_code, 0);
  ImageBuffer ref = read_image_file(f.out("ref.exr"));
  const std::vector<std::vector<std::string>> stops = {{"3:0"}, {"6:0.5"}, {"10:0"}, {"9:0.5"}, {"8:0.4", "9:0.7"}};
  for (size_t k = 0; k < stops.size(); ++k) {
    const double difference = f.resumed_difference(f.out("ck" + std::to_string(k)), stops[k], ref);
    if (k < 3) EXPECT_EQ(difference, 0.0) << "stopped at " << stops[k][0];
    else EXPECT_LT(difference, 1e-5) << "stopped at " << stops[k][0];
  }
  // The mixture guided (the image is not the SD-tree's).
  ASSERT_EQ(run("render " + f.scene + " -o " + f.out("sdtree.exr") +
                " --max-paths 1024 -q --threads 1 --guiding --guiding-training-spp 10 --spp 24")
                .exit_code,
            0);
  EXPECT_GT(test::max_relative_difference(read_image_file(f.out("sdtree.exr")), ref), 1e-3);
}

// A damaged mixture section (the checkpoint's own checksum made to match) is
// one clear error naming it, not a crash, and writes no image.
TEST(Resume, DamagedMixtureSectionIsRefusedClearly) {
  Fixture f("vmmdamaged", " --guiding --guiding-field vmm --guiding-training-spp 10 --spp 24");
  const std::string ck = f.out("ck");
  ASSERT_EQ(f.render("out.exr", " --checkpoint-dir " + ck + " --test-sigterm-at 5:0").exit_code, kInterrupted);
  const Checkpoint good = *read_latest_checkpoint(ck);
  auto section = [](Checkpoint& c) {
    for (CheckpointSection& s : c.sections)
      if (s.name == "guiding-vmm") return &s;
    return static_cast<CheckpointSection*>(nullptr);
  };
  auto damaged = [&](const std::function<void(std::vector<uint8_t>&)>& damage, const std::string& expect) {
    Checkpoint c = good;
    CheckpointSection* s = section(c);
    ASSERT_NE(s, nullptr);
    damage(s->bytes);
    fs::remove_all(ck);
    write_checkpoint(ck, c);
    RunResult r = f.render("out.exr", " --checkpoint-dir " + ck + " --resume");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.exit_code, kInterrupted);
    EXPECT_NE(r.output.find("checkpoint section 'guiding-vmm'"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(expect), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(f.out("out.exr")));
  };
  damaged([](std::vector<uint8_t>& b) { b.resize(b.size() / 2); }, "checksum mismatch");
  damaged([](std::vector<uint8_t>& b) { b.resize(5); }, "truncated");
  damaged([](std::vector<uint8_t>& b) { b[b.size() / 3] ^= 0x40; }, "corrupt");
  // The section put back as it was: the render resumes.
  Checkpoint c = good;
  fs::remove_all(ck);
  write_checkpoint(ck, c);
  RunResult r = f.render("out.exr", " --checkpoint-dir " + ck + " --resume");
  ASSERT_EQ(r.exit_code, 0) << r.output;
}

// --guiding-auto's state is in the checkpoint: the verdict, each round's
// partial sums and the final round's plan.  The resumed render must continue
// the rounds it had begun (without the checkpoint's state, the probe, already
// past, would never be measured, and a final round stopped half-way never
// completed).  Every round is forced to pass: a probe that said "off" would
// end the rounds and switch the schedule before the second stop.
TEST(Resume, GuidingAutoContinuesItsRoundsAfterResume) {
  Fixture f("guidingauto", " --guiding-auto --test-guiding-verdict on --guiding-training-spp 32 --spp 96");
  // Guiding schedule for 96 spp: 1 x8, 2 4 8 16 16 16 16 10.  The probe holds
  // out iteration 9 (4 spp from 10) against 10; training ends at 38 spp
  // (iteration 12), where the final round holds out 12 and 13 against 14 and 15.
  // Stopped after the probe, then inside the final round's second held-out iteration.
  std::string ck = f.out("ck");
  for (const std::string at : {"11:0", "13:0.5"}) {
    RunResult r = f.render("out.exr", " --checkpoint-dir " + ck + " --test-sigterm-at " + at);
    ASSERT_EQ(r.exit_code, kInterrupted) << at << "\n" << r.output;
  }
  RunResult r = f.render("out.exr", " --checkpoint-dir " + ck + " --resume");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json log = nlohmann::json::parse(std::ifstream(f.out("out.json")));
  ASSERT_TRUE(log["scheduler"]["resumed"].get<bool>());
  const nlohmann::json& a = log["guiding"]["auto"];
  SCOPED_TRACE(a.dump());
  EXPECT_EQ(a["probe"]["unguided_iteration"].get<int>(), 9);
  EXPECT_TRUE(a["probe"]["measured"].get<bool>());
  EXPECT_EQ(a["probe"]["unguided"]["spp"].get<int64_t>(), 4);
  EXPECT_EQ(a["probe"]["guided"]["spp"].get<int64_t>(), 8);
  EXPECT_EQ(log["guiding"]["trained_spp"].get<int64_t>(), 38);
  EXPECT_EQ(a["final"]["unguided_iteration"].get<int>(), 12);
  EXPECT_TRUE(a["final"]["measured"].get<bool>());
  EXPECT_EQ(a["final"]["unguided"]["spp"].get<int64_t>(), 32);  // 12 before the stops, 13 after
  EXPECT_EQ(a["final"]["guided"]["spp"].get<int64_t>(), 26);
  EXPECT_EQ(a["verdict"].get<std::string>(), "on");
  // Decided in the last iteration: nothing left to switch.
  EXPECT_TRUE(log["scheduler"]["schedule_switch"].is_null());
}

// Where --guiding-auto switched to the regular schedule is in the checkpoint:
// stopped before the switch (in the probe's judged iteration) and after it
// (inside the first switched iteration), the resumed render renders the
// schedule and the image an uninterrupted one does.  The verdict is forced
// ("off"), so the uninterrupted image is known.
TEST(Resume, GuidingAutoScheduleSwitchResumesExactly) {
  // Training 255 of 256 spp: a render that ends within training has auto off from the start.
  Fixture f("autoswitch", " --guiding-auto --test-guiding-verdict off --spp 256 --guiding-training-spp 255");
  // Guiding schedule for 256 spp: 1 x8, 2 4 8 16 16 ...; the probe holds out
  // 11 (22 spp) against 12; from 13 (54 spp) the regular schedule: 74, 128.
  ASSERT_EQ(f.render("ref.exr").exit_code, 0);
  const nlohmann::json ref = nlohmann::json::parse(std::ifstream(f.out("ref.json")));
  const std::vector<int> switched = switch_schedule(make_schedule(guiding_schedule(), 256), 13, regular_schedule());
  EXPECT_EQ(switched, (std::vector<int>{1, 1, 1, 1, 1, 1, 1, 1, 2, 4, 8, 16, 16, 74, 128}));
  EXPECT_EQ(ref["scheduler"]["schedule"].get<std::vector<int>>(), switched);
  EXPECT_EQ(ref["scheduler"]["schedule_switch"]["at_iteration"].get<int>(), 13);
  for (const std::string at : {"12:0.5", "13:0.5"}) {
    SCOPED_TRACE(at);
    const std::string ck = f.out("ck" + at.substr(0, 2));
    ASSERT_EQ(f.render("out.exr", " --checkpoint-dir " + ck + " --test-sigterm-at " + at).exit_code, kInterrupted);
    RunResult r = f.render("out.exr", " --checkpoint-dir " + ck + " --resume");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const nlohmann::json log = nlohmann::json::parse(std::ifstream(f.out("out.json")));
    EXPECT_TRUE(log["scheduler"]["resumed"].get<bool>());
    EXPECT_EQ(log["scheduler"]["schedule"].get<std::vector<int>>(), switched);
    EXPECT_EQ(log["scheduler"]["schedule_switch"], ref["scheduler"]["schedule_switch"]);
    EXPECT_LT(test::max_relative_difference(read_image_file(f.out("out.exr")), read_image_file(f.out("ref.exr"))),
              1e-5);
  }
}

// The learned selection probability (Adam's state per leaf) is part of the
// field's checkpoint: stopped mid-training, the resumed render learns on as
// the uninterrupted one did.
TEST(Resume, LearnedSelectionResumesExactly) {
  Fixture f("learnedselection", " --guiding --guiding-sampling mis-learned --guiding-training-spp 10 --spp 16");
  ASSERT_EQ(f.render("ref.exr").exit_code, 0);
  const std::string ck = f.out("ck");
  ASSERT_EQ(f.render("out.exr", " --checkpoint-dir " + ck + " --test-sigterm-at 6:0.5").exit_code, kInterrupted);
  RunResult r = f.render("out.exr", " --checkpoint-dir " + ck + " --resume");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_LT(test::max_relative_difference(read_image_file(f.out("out.exr")), read_image_file(f.out("ref.exr"))), 1e-5);
}

// --save-field's file after a resume is the file of the uninterrupted render:
// its snapshots so far and what each leaf has seen are in the checkpoint.
TEST(Resume, SavedFieldCountsEverySampleAfterResume) {
  Fixture f("savedfield", " --guiding --guiding-training-spp 10 --spp 16 --save-field-every-iteration");
  ASSERT_EQ(f.render("ref.exr", " --save-field " + f.out("ref.field")).exit_code, 0);
  const std::string ck = f.out("ck");
  ASSERT_EQ(f.render("out.exr", " --save-field " + f.out("out.field") + " --checkpoint-dir " + ck +
                                    " --test-sigterm-at 5:0.5")
                .exit_code,
            kInterrupted);
  RunResult r = f.render("out.exr", " --save-field " + f.out("out.field") + " --checkpoint-dir " + ck + " --resume");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const FieldFile ref = load_field(f.out("ref.field")), out = load_field(f.out("out.field"));
  ASSERT_EQ(out.snapshots.size(), ref.snapshots.size());
  const FieldSnapshot &a = ref.snapshots.back(), &b = out.snapshots.back();
  EXPECT_EQ(a.columns, b.columns);
  EXPECT_EQ(a.table, b.table) << "every leaf's statistics, counted over the whole render";
  // Every snapshot, the memory the tree held aside ("bytes": vectors read
  // back from a checkpoint have other capacities).
  auto without_bytes = [](std::vector<std::pair<std::string, double>> summary) {
    std::erase_if(summary, [](const auto& kv) { return kv.first == "bytes"; });
    return summary;
  };
  for (size_t k = 0; k < ref.snapshots.size(); ++k) {
    const FieldSnapshot &x = ref.snapshots[k], &y = out.snapshots[k];
    EXPECT_EQ(x.iteration, y.iteration);
    EXPECT_EQ(without_bytes(x.summary), without_bytes(y.summary)) << k;
    EXPECT_EQ(x.table, y.table) << k;
    ASSERT_EQ(x.leaves.size(), y.leaves.size()) << k;
    for (size_t l = 0; l < x.leaves.size(); ++l) {
      EXPECT_EQ(x.leaves[l].samples.size(), y.leaves[l].samples.size()) << k << " " << l;
      for (size_t i = 0; i < std::min(x.leaves[l].samples.size(), y.leaves[l].samples.size()); ++i)
        EXPECT_EQ(x.leaves[l].samples[i].value, y.leaves[l].samples[i].value) << k << " " << l << " " << i;
      EXPECT_EQ(x.leaves[l].quadtree.size(), y.leaves[l].quadtree.size()) << k << " " << l;
    }
  }
}

// The caustic pass runs once an iteration's camera samples are all in, so an
// iteration interrupted half-way and resumed gets it exactly once.
TEST(Resume, CausticPassResumesExactly) {
  fs::path dir = temp_dir("caustics");
  std::string scene = (dir / "s.pbrt").string();
  std::ofstream(scene) << test::mirror_room_scene(24, 16, 0.05f);
  auto render = [&](const std::string& out, const std::string& more) {
    return run("render " + scene + " -o " + (dir / out).string() + " --spp 40 --max-paths 256 -q --caustics" + more);
  };
  ASSERT_EQ(render("ref.exr", "").exit_code, 0);
  ImageBuffer ref = read_image_file((dir / "ref.exr").string());
  std::string ck = (dir / "ck").string();
  // Schedule for 40 spp: 16 16 8; stop inside the second iteration.
  ASSERT_EQ(render("out.exr", " --checkpoint-dir " + ck + " --test-sigterm-at 1:0.5").exit_code, kInterrupted);
  ASSERT_EQ(render("out.exr", " --checkpoint-dir " + ck + " --resume").exit_code, 0);
  EXPECT_LT(test::max_relative_difference(read_image_file((dir / "out.exr").string()), ref), 1e-5);
  nlohmann::json log = nlohmann::json::parse(std::ifstream((dir / "out.json").string()));
  EXPECT_GT(log["caustics"]["splats"].get<uint64_t>(), 0u);
  fs::remove_all(dir);
}

// A checkpoint is resumed only with the options it was written with, where
// they change the image: every image option, changed alone, is refused; the
// options that change only summation order or where checkpoints go resume.
// The options come from the same declarations the command line binds
// (app/options.h), so an option added without a case here fails the test.
// In-process, through the command line's parser: fast.
namespace {

// 8 spp in iterations of 2 4 2; a small pool so an iteration takes several generations.
const std::vector<std::string> kBase = {"--spp", "8", "--iteration-first", "2", "--iteration-repeat", "1",
                                        "--max-paths", "256", "--batch-size", "128"};

// Each image option and a valid value other than kBase's (or the default).
const std::map<std::string, std::vector<std::string>> kChanged = {
    {"--spp", {"9"}},
    {"--seed", {"1"}},
    {"--max-depth", {"3"}},
    {"--throughput-reset-bounce", {"1"}},
    {"--aov-events", {}},
    {"--roughening", {"0.01"}},
    {"--light-sampler", {"uniform"}},
    {"--schedule", {"guiding"}},
    {"--combine", {"inverse-variance"}},
    {"--recorder-vertex-budget", {"2"}},
    {"--recorder-training", {"all"}},
    {"--recorder-vertex-skip-probability", {"0.25"}},
    {"--recorder-medium-skip-probability", {"0.5"}},
    {"--recorder-min-distance", {"0.1"}},
    {"--recorder-debug", {}},
    {"--recorder-debug-bounce", {"1"}},
    {"--guiding", {}},
    {"--guiding-min-roughness", {"0.1"}},
    {"--guiding-spatial-threshold", {"2000"}},
    {"--guiding-selection-probability", {"0.25"}},
    {"--guiding-sampling", {"mis"}},
    {"--guiding-field", {"vmm"}},
    {"--guiding-defensive", {"0.3"}},
    {"--guiding-selection-max", {"0.8"}},
    {"--guiding-roulette-correction", {"off"}},
    {"--guiding-split-decay", {"0.5"}},
    {"--guiding-pdf-floor", {"0"}},
    {"--guiding-training-spp", {"8"}},
    {"--guiding-adjoint-roulette", {"off"}},
    {"--guiding-roulette-floor", {"0.2"}},
    {"--guiding-training-share", {"0.5"}},
    {"--guiding-regular-after-training", {"off"}},
    {"--caustics", {"off"}},
    {"--caustics-caster-roughness", {"0.2"}},
    {"--adaptive", {}},
    {"--combine-window", {"4"}},
    {"--iteration-first", {"1"}},
    {"--iteration-repeat", {"2"}},
    {"--iteration-growth", {"3"}},
    {"--iteration-max", {"4"}},
};

// The debug layers are refused with any checkpoint directory, before the fingerprint is compared.
bool refused_with_checkpoints(const std::string& flag) {
  return flag.rfind("--recorder-debug", 0) == 0;
}

OptionFlags declared_flags() {
  RenderConfig c;
  OptionFlags flags;
  declare_render_options(flags, c);
  return flags;
}

// The command line's parse of these arguments (after the scene and -o).
RenderConfig parse(std::vector<std::string> args) {
  CLI::App app;
  RenderConfig c;
  OptionBinder binder(app);
  declare_render_options(binder, c);
  std::reverse(args.begin(), args.end());  // CLI11 takes a vector last argument first
  app.parse(args);
  return c;
}

struct ResumeOptionsCheckpoint : ::testing::Test {
  test::TempDir tmp{"theia_resume_options"};
  Scene scene = test::load_test_scene(sphere_floor_scene(1.0f));
  std::string checkpoints = (tmp.path / "ck").string();
  StopRequest stop;

  RenderResult render(const std::vector<std::string>& args) {
    RenderConfig c = parse(args);
    c.checkpoint.dir = checkpoints;
    c.stop = &stop;
    return render_scene(scene, c);
  }
  // Stopped half-way through the second iteration: a checkpoint to resume.
  void write_checkpoint() {
    RenderConfig c = parse(kBase);
    c.checkpoint.dir = checkpoints;
    c.stop = &stop;
    c.on_iteration_progress = [this](int it, double f) {
      if (it == 1 && f >= 0.5) stop.raise(StopReason::Signal);
    };
    ASSERT_TRUE(render_scene(scene, c).interrupted);
    stop.clear();
  }
};

}  // namespace

TEST(ResumeOptions, EveryImageOptionHasACase) {
  OptionFlags flags = declared_flags();
  std::vector<std::string> cases;
  for (const auto& [flag, value] : kChanged) cases.push_back(flag);
  std::sort(flags.image_flags.begin(), flags.image_flags.end());
  EXPECT_EQ(flags.image_flags, cases) << "an image option without a case in kChanged (or a case for none)";
  // The fingerprint covers throughput_reset_bounce, which changes the beauty.
  EXPECT_TRUE(std::count(flags.image_flags.begin(), flags.image_flags.end(), "--throughput-reset-bounce"));
}

TEST_F(ResumeOptionsCheckpoint, EachImageOptionChangedAloneIsRefused) {
  write_checkpoint();
  for (const auto& [flag, value] : kChanged) {
    std::vector<std::string> args = kBase;
    // Replace the base's value where it sets this option, else append it.
    auto at = std::find(args.begin(), args.end(), flag);
    if (at != args.end()) args.erase(at, at + 2);
    args.push_back(flag);
    args.insert(args.end(), value.begin(), value.end());
    try {
      render(args);
      ADD_FAILURE() << flag << ": resumed a checkpoint written with another value";
    } catch (const Error& e) {
      const std::string want = refused_with_checkpoints(flag) ? "cannot be combined with --checkpoint-dir"
                                                              : "different image-affecting options";
      EXPECT_NE(std::string(e.what()).find(want), std::string::npos) << flag << ": " << e.what();
    }
  }
  // The checkpoint was left as it was: the unchanged options resume it.
  RenderResult r = render(kBase);
  EXPECT_FALSE(r.interrupted);
  EXPECT_TRUE(r.log["scheduler"]["resumed"].get<bool>());
}

TEST_F(ResumeOptionsCheckpoint, SummationOrderAndCheckpointOptionsResume) {
  OptionFlags flags = declared_flags();
  std::sort(flags.order_flags.begin(), flags.order_flags.end());
  EXPECT_EQ(flags.order_flags, (std::vector<std::string>{"--batch-size", "--max-paths", "--sort", "--threads"}));
  std::sort(flags.output_flags.begin(), flags.output_flags.end());
  EXPECT_EQ(flags.output_flags,
            (std::vector<std::string>{"--checkpoint-dir", "--checkpoint-every-iteration", "--checkpoint-first",
                                      "--memory-limit", "--resume", "--save-field", "--save-field-every-iteration",
                                      "--time-limit"}));

  RenderConfig plain = parse(kBase);
  const ImageBuffer uninterrupted = render_scene(scene, plain).image;
  write_checkpoint();
  // Every order option and every checkpoint option other than the directory, changed at once.
  RenderResult r = render({"--spp", "8", "--iteration-first", "2", "--iteration-repeat", "1", "--max-paths", "64",
                           "--batch-size", "1000", "--threads", "1", "--sort", "on", "--resume",
                           "--checkpoint-first", "2", "--checkpoint-every-iteration"});
  ASSERT_FALSE(r.interrupted);
  EXPECT_TRUE(r.log["scheduler"]["resumed"].get<bool>());
  EXPECT_EQ(r.log["options"]["threads"].get<int>(), 1);
  EXPECT_TRUE(r.log["options"]["sort"].get<bool>());
  EXPECT_LT(test::max_relative_difference(r.image, uninterrupted), 1e-5);
}

TEST(ResumeOptions, ParsedFlagsReachTheirFields) {
  RenderConfig c = parse({"--guiding", "--guiding-selection-probability", "0.25", "--no-caustics", "--sort", "off",
                          "--recorder-vertex-budget", "2", "--checkpoint-first", "8", "--max-paths", "0"});
  EXPECT_EQ(c.guiding.enabled, OnOffAuto::On);
  EXPECT_EQ(parse({"--guiding-auto"}).guiding.enabled, OnOffAuto::Auto);
  EXPECT_EQ(parse({"--guiding", "--no-guiding"}).guiding.enabled, OnOffAuto::Off);
  EXPECT_EQ(parse({}).guiding.enabled, OnOffAuto::Auto);  // the default since issue 12's bars hold
  EXPECT_EQ(c.guiding.selection_probability, 0.25f);
  EXPECT_FALSE(c.caustics.enabled);
  EXPECT_FALSE(c.sort);
  EXPECT_EQ(c.recorder.vertex_budget, 2.0f);
  EXPECT_EQ(c.checkpoint.first, 8);
  EXPECT_EQ(c.max_paths, 0u);  // auto
  EXPECT_TRUE(parse({}).caustics.enabled);
  EXPECT_FALSE(parse({}).sort);  // sorting is off by default (README, Performance)
  EXPECT_TRUE(parse({"--sort", "on"}).sort);
  EXPECT_TRUE(parse({"--sort"}).sort);
  EXPECT_THROW(parse({"--sort", "maybe"}), CLI::ParseError);
}

// No option takes a negative number, and a "not given" default (-1: the
// scene's spp) is not a value to type: every number flag refuses -1 in the
// one place that binds them (app/options.h), and still takes 0 or more.
TEST(ResumeOptions, EveryNumberOptionRefusesANegativeValue) {
  const std::vector<std::string> numbers = declared_flags().number_flags;
  for (const char* flag : {"--spp", "--max-depth", "--seed", "--threads", "--max-paths", "--iteration-first",
                           "--iteration-repeat", "--iteration-growth", "--iteration-max", "--combine-window",
                           "--checkpoint-first", "--throughput-reset-bounce", "--recorder-debug-bounce",
                           "--memory-limit", "--time-limit", "--guiding-pdf-floor"})
    EXPECT_TRUE(std::count(numbers.begin(), numbers.end(), flag)) << flag;
  for (const std::string& flag : numbers) {
    for (const char* negative : {"-1", "-0.5", "-1e9"}) {
      try {
        parse({flag, negative});
        ADD_FAILURE() << flag << " " << negative << " was accepted";
      } catch (const CLI::ValidationError& e) {
        EXPECT_EQ(std::string(e.what()),
                  flag + ": must not be negative, got " + negative + " (leave the option out for its default)");
      }
    }
    EXPECT_NO_THROW(parse({flag, "1"})) << flag;
  }
  EXPECT_EQ(parse({}).spp, -1);  // left out: the scene's
}

// A scene with a medium around the camera: its per-path medium state starts
// afresh with every camera sample, so a stop anywhere resumes exactly.
TEST(Resume, MediaSceneResumesExactly) {
  Fixture f("media");
  std::ofstream(f.scene) << R"(Film "rgb" "integer xresolution" [32] "integer yresolution" [24]
Sampler "sobol" "integer pixelsamples" [40]
MakeNamedMedium "fog" "string type" "homogeneous" "rgb sigma_a" [0.05 0.1 0.2] "rgb sigma_s" [0.3 0.3 0.3] "float g" 0.4
MediumInterface "fog" "fog"
LookAt 0 1 -5  0 0 0  0 1 0
Camera "perspective" "float fov" [35]
WorldBegin
MediumInterface "fog" "fog"
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [4 4 4]
  Shape "sphere" "float radius" [0.3]
AttributeEnd
Material "diffuse" "rgb reflectance" [0.7 0.5 0.3]
Shape "trianglemesh" "point3 P" [-4 -1 -4  4 -1 -4  4 -1 4  -4 -1 4] "integer indices" [0 1 2 0 2 3]
)";
  ASSERT_EQ(f.render("ref.exr").exit_code, 0);
  ImageBuffer ref = read_image_file(f.out("ref.exr"));
  EXPECT_GT(test::image_mean(ref).x, 0.01f) << "the fog should be lit";
  std::string ck = f.out("ck");
  ASSERT_EQ(f.render("out.exr", " --checkpoint-dir " + ck + " --test-sigterm-at 2:0.5").exit_code, kInterrupted);
  RunResult r = f.render("out.exr", " --checkpoint-dir " + ck);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_LT(test::max_relative_difference(read_image_file(f.out("out.exr")), ref), 1e-5);
}

// An iteration interrupted and resumed costs what it cost before the stop
// plus the rest: the checkpoint carries the time it had run, and the
// resumed iteration's clocks start from it.  Without it --guiding-auto
// judged a resumed probe round by its remainder alone (a fifth of its cost:
// guiding looked 3x cheaper, the verdict flipped and the image was another
// render's; Resume.SigtermFromAnotherProcess failed so in CI).
TEST(Resume, AResumedIterationCountsTheTimeBeforeItsStop) {
  // 40 spp as 16 16 8; stopped 90% into the second iteration.
  Fixture f("partialtime", " --spp 40 --no-guiding --threads 1");
  const std::string ck = f.out("ck");
  ASSERT_EQ(f.render("out.exr", " --checkpoint-dir " + ck + " --test-sigterm-at 1:0.9").exit_code, kInterrupted);
  RunResult r = f.render("out.exr", " --checkpoint-dir " + ck);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  nlohmann::json log = nlohmann::json::parse(std::ifstream(f.out("out.json")));
  ASSERT_EQ(log["scheduler"]["resumed_at_iteration"].get<int>(), 1);
  const nlohmann::json& resumed = log["scheduler"]["iterations"][0];
  ASSERT_TRUE(resumed.contains("seconds_before_resume")) << resumed.dump();
  const double before = resumed["seconds_before_resume"].get<double>();
  EXPECT_GT(before, 0.0);
  EXPECT_GE(resumed["seconds"].get<double>(), before);
  // The next iteration ran whole in this process: nothing carried.
  EXPECT_FALSE(log["scheduler"]["iterations"][1].contains("seconds_before_resume"));
}
