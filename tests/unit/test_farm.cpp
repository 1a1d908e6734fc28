// The farm's pieces that need no cluster: sample ranges, clipped schedules,
// the checks on a split frame's parts, frame patterns, the batch scripts.
#include "farm/part.h"
#include "farm/slurm.h"
#include "scheduler/driver.h"
#include "scheduler/schedule.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

using namespace theia;

namespace {

// Throws, with a message that contains `says`.
template <class F>
void expect_error(F&& f, const std::string& says) {
  try {
    f();
    ADD_FAILURE() << "no error; expected one saying " << says;
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
  }
}

Part part(const std::string& path, uint32_t begin, uint32_t end, int spp = 16) {
  Part p;
  p.path = path;
  p.info.range = {begin, end};
  p.info.spp = spp;
  p.info.scene_fingerprint = 1;
  p.info.options_fingerprint = 2;
  p.image.width = 4;
  p.image.height = 2;
  return p;
}

}  // namespace

TEST(FarmSampleRange, ParsesBeginEndAndRefusesTheRest) {
  SampleRange r = parse_sample_range("8:24");
  EXPECT_EQ(r.begin, 8u);
  EXPECT_EQ(r.end, 24u);
  expect_error([] { parse_sample_range("8"); }, "expected BEGIN:END");
  expect_error([] { parse_sample_range("a:4"); }, "expected BEGIN:END");
  expect_error([] { parse_sample_range("-1:4"); }, "expected BEGIN:END");
  expect_error([] { parse_sample_range("4:4"); }, "BEGIN must be below END");
  expect_error([] { parse_sample_range("4:9x"); }, "expected BEGIN:END");
}

TEST(FarmSampleRange, ClippedScheduleKeepsTheWholeRendersIterationsInTheRange) {
  const std::vector<int> sizes = {16, 16, 32, 64};  // [0,16) [16,32) [32,64) [64,128)
  EXPECT_EQ(clip_schedule(sizes, 0, 128), sizes);
  EXPECT_EQ(clip_schedule(sizes, 8, 40), (std::vector<int>{8, 16, 8}));
  EXPECT_EQ(clip_schedule(sizes, 16, 32), (std::vector<int>{16}));
  EXPECT_EQ(clip_schedule(sizes, 100, 128), (std::vector<int>{28}));
}

// A part that learns renders the schedule of a whole render of its range's
// length: its own small training iterations first, with the global sample
// indices of its range.
TEST(FarmSampleRange, LearningPartRendersItsOwnScheduleFromItsFirstSample) {
  IterationConfig c;
  c.schedule = guiding_schedule();
  c.total_spp = 64;
  c.sample_begin = 24;
  c.sample_end = 48;
  EXPECT_EQ(iteration_sizes(c), (std::vector<int>{14, 10}));  // the frame's [22, 38) and [38, 54), clipped
  c.part_learns = true;
  EXPECT_EQ(iteration_sizes(c), (std::vector<int>{1, 1, 1, 1, 1, 1, 1, 1, 2, 4, 8, 2}));
  EXPECT_EQ(iteration_sizes(c), make_schedule(guiding_schedule(), 24));
  c.sample_end = 65;
  expect_error([&] { iteration_sizes(c); }, "not within the frame's 64 samples per pixel");
}

TEST(FarmParts, TilingAndSameFrameChecks) {
  std::vector<Part> parts = {part("c", 10, 16), part("a", 0, 4), part("b", 4, 10)};
  EXPECT_EQ(check_parts(parts), (std::vector<size_t>{1, 2, 0}));
  expect_error([&] { check_parts({part("a", 0, 4), part("b", 3, 16)}); }, "a [0, 4) and b [3, 16) overlap");
  expect_error([&] { check_parts({part("a", 0, 4), part("b", 5, 16)}); }, "samples [4, 5) of the frame's 16");
  expect_error([&] { check_parts({part("a", 0, 4)}); }, "samples [4, 16) of the frame's 16 are in no part");
  expect_error([&] { check_parts({part("a", 0, 4), part("b", 4, 16, 32)}); }, "different spp");
  std::vector<Part> seeds = {part("a", 0, 4), part("b", 4, 16)};
  seeds[1].info.seed = 7;
  expect_error([&] { check_parts(seeds); }, "different seeds (0 vs 7)");
  std::vector<Part> options = {part("a", 0, 4), part("b", 4, 16)};
  options[0].info.image_options = {{"max_depth", 5}, {"seed", 0}};
  options[1].info.image_options = {{"max_depth", 3}, {"seed", 0}};
  options[1].info.options_fingerprint = 3;
  expect_error([&] { check_parts(options); }, "different image options: max_depth (5 vs 3)");
  std::vector<Part> scenes = {part("a", 0, 4), part("b", 4, 16)};
  scenes[1].info.scene_fingerprint = 9;
  expect_error([&] { check_parts(scenes); }, "different scenes");
  expect_error([&] { check_parts({}); }, "no parts");
  // Parts that learned on their own merge with each other, not with parts that did not.
  std::vector<Part> learning = {part("a", 0, 4), part("b", 4, 16)};
  for (Part& p : learning) p.info.learns = {"guiding"};
  EXPECT_EQ(check_parts(learning), (std::vector<size_t>{0, 1}));
  learning[1].info.learns.clear();
  learning[0].info.image_options = {{"guiding", true}};
  learning[1].info.image_options = {{"guiding", false}};
  learning[1].info.options_fingerprint = 3;
  expect_error([&] { check_parts(learning); },
               "a learned guiding on its own but b learned nothing: parts of one frame learn the same way (image "
               "options that differ: guiding (true vs false))");
}

TEST(FarmParts, PartLogRoundTripsAndAWholeRenderLogIsRefused) {
  PartInfo p;
  p.range = {4, 12};
  p.spp = 16;
  p.scene_fingerprint = 0x0123456789abcdefull;
  p.options_fingerprint = 0xfedcba9876543210ull;
  p.seed = 5;
  p.image_options = {{"spp", 16}};
  p.learns = {"guiding", "cachepoints"};
  nlohmann::json log = {{"part", part_json(p)}};
  PartInfo q = part_from_json(log, "x.json");
  EXPECT_EQ(q.range.begin, 4u);
  EXPECT_EQ(q.range.end, 12u);
  EXPECT_EQ(q.scene_fingerprint, p.scene_fingerprint);
  EXPECT_EQ(q.options_fingerprint, p.options_fingerprint);
  EXPECT_EQ(q.seed, 5u);
  EXPECT_EQ(q.learns, p.learns);
  // A part written before parts could learn: nothing learned.
  nlohmann::json older = log;
  older["part"].erase("learns");
  EXPECT_TRUE(part_from_json(older, "x.json").learns.empty());
  expect_error([] { part_from_json(nlohmann::json{{"options", {}}}, "w.json"); }, "w.json: not a part");
  log["part"]["sample_range"] = {4, 20};
  expect_error([&] { part_from_json(log, "x.json"); }, "not within its 16 spp");
}

TEST(FarmSubmit, FramePatternExpandsRangeAndStep) {
  EXPECT_EQ(expand_frame_pattern("shot/frame.%04d.pbrt", "1-3"),
            (std::vector<std::string>{"shot/frame.0001.pbrt", "shot/frame.0002.pbrt", "shot/frame.0003.pbrt"}));
  EXPECT_EQ(expand_frame_pattern("f%d.pbrt", "10-20:5"), (std::vector<std::string>{"f10.pbrt", "f15.pbrt", "f20.pbrt"}));
  expect_error([] { expand_frame_pattern("f.pbrt", "1-2"); }, "expected one %d");
  expect_error([] { expand_frame_pattern("f%s.pbrt", "1-2"); }, "expected one %d");
  expect_error([] { expand_frame_pattern("f%d.pbrt", "3-1"); }, "A <= B");
  expect_error([] { expand_frame_pattern("f%d.pbrt", "1-x"); }, "not a whole number");
}

TEST(FarmSubmit, SequenceIsOneArrayWithRequeueAndAdvanceSignal) {
  FarmSubmitOptions o;
  o.scenes = {"/s/a.pbrt", "/s/b.pbrt", "/s/c.pbrt"};
  o.dir = "/out";
  o.theia = "/bin/theia";
  o.partition = "preempt";
  o.time = "00:10:00";
  o.cpus_per_task = 2;
  o.mem = "2G";
  o.sbatch_args = {"--qos=low"};
  o.signal_seconds = 90;
  o.render_options = "--max-depth 5";
  FarmPlan plan = plan_farm(o);
  ASSERT_EQ(plan.jobs.size(), 1u);
  ASSERT_EQ(plan.jobs[0].commands.size(), 3u);
  EXPECT_NE(plan.jobs[0].commands[1].find("'/s/b.pbrt' '-o' '/out/frames/b.exr' '--checkpoint-dir' "
                                          "'/out/checkpoints/b'"),
            std::string::npos)
      << plan.jobs[0].commands[1];
  EXPECT_NE(plan.jobs[0].commands[1].find("'--threads' '2'"), std::string::npos);
  EXPECT_NE(plan.jobs[0].commands[1].find("'--max-depth' '5'"), std::string::npos);
  const std::string s = batch_script(plan.jobs[0]);
  for (const char* line : {"#SBATCH --array=0-2\n", "#SBATCH --requeue\n", "#SBATCH --signal=B:TERM@90\n",
                           "#SBATCH --partition=preempt\n", "#SBATCH --time=00:10:00\n", "#SBATCH --mem=2G\n",
                           "#SBATCH --cpus-per-task=2\n", "#SBATCH --qos=low\n", "#SBATCH --open-mode=append\n",
                           "#SBATCH --output=/out/logs/frame-%a.out\n",
                           "me=${SLURM_ARRAY_JOB_ID}_${SLURM_ARRAY_TASK_ID}", "scontrol requeue \"$me\""})
    EXPECT_NE(s.find(line), std::string::npos) << line << " not in\n" << s;
  EXPECT_EQ(plan.manifest["frames"].size(), 3u);
  EXPECT_EQ(plan.manifest["frames"][2]["tasks"][0]["log"], "/out/logs/frame-2.out");
}

TEST(FarmSubmit, SplitIsAnArrayPerFrameOverSampleRangesThenAMerge) {
  FarmSubmitOptions o;
  o.scenes = {"/s/a.pbrt", "/s/b.pbrt"};
  o.dir = "/out";
  o.theia = "/bin/theia";
  o.split = 3;
  o.spp = 16;
  FarmPlan plan = plan_farm(o);
  ASSERT_EQ(plan.jobs.size(), 4u);  // a's parts, a's merge, b's parts, b's merge
  ASSERT_EQ(plan.jobs[0].commands.size(), 3u);
  EXPECT_NE(plan.jobs[0].commands[0].find("'--sample-range' '0:5'"), std::string::npos);
  EXPECT_NE(plan.jobs[0].commands[1].find("'--sample-range' '5:10'"), std::string::npos);
  EXPECT_NE(plan.jobs[0].commands[2].find("'--sample-range' '10:16'"), std::string::npos);
  EXPECT_NE(plan.jobs[0].commands[2].find("'/out/checkpoints/a.part-2'"), std::string::npos);
  EXPECT_EQ(plan.jobs[1].name, "theia-a-merge");
  EXPECT_NE(plan.jobs[1].commands[0].find("'merge' '/out/parts/a.part-0.exr' '/out/parts/a.part-1.exr' "
                                          "'/out/parts/a.part-2.exr' '-o' '/out/frames/a.exr'"),
            std::string::npos)
      << plan.jobs[1].commands[0];
  EXPECT_EQ(batch_script(plan.jobs[1]).find("--array"), std::string::npos);
}

TEST(FarmSubmit, RefusesOptionsItCannotHonour) {
  FarmSubmitOptions o;
  o.scenes = {"/s/a.pbrt"};
  o.dir = "/out";
  o.theia = "/bin/theia";
  FarmSubmitOptions split = o;
  split.split = 4;
  expect_error([&] { plan_farm(split); }, "--split needs --spp");
  FarmSubmitOptions own = o;
  own.render_options = "--spp 64";
  expect_error([&] { plan_farm(own); }, "may not set --spp");
  FarmSubmitOptions none = o;
  none.scenes.clear();
  expect_error([&] { plan_farm(none); }, "give the scene files or --pattern");
  FarmSubmitOptions twice = o;
  twice.scenes = {"/s/a.pbrt", "/t/a.pbrt"};
  expect_error([&] { plan_farm(twice); }, "two frames are named a");
}
