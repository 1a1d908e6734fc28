// render --save-field and `theia field stats|image` end to end: the file a
// guided render writes agrees with the recorder's and the tree's counts in the
// log, saving it changes no pixel, and the commands read it (or name what is wrong).
#include "core/log.h"
#include "guiding/field_file.h"
#include "render_helpers.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>

using namespace theia;
using namespace theia::test;

namespace {

const std::string kCornell = std::string(THEIA_SCENES) + "/cornell-box/scene.pbrt";

Scene small_cornell() {
  Scene s = load_test_scene_file(kCornell);
  s.film.width = s.film.height = 24;
  return s;
}

RenderConfig guided(int spp) {
  RenderConfig c = quick_config(spp);
  c.guiding.enabled = true;
  c.threads = 2;
  return c;
}

}  // namespace

TEST(FieldSave, EveryIterationsSnapshotAgreesWithTheLogAndChangesNoPixel) {
  TempDir tmp("theia_field_save");
  const Scene scene = small_cornell();
  RenderConfig c = guided(8);
  // Bit for bit, so on one thread: across threads the film's sums (and the
  // recorder's) follow the scheduler's order, which design.md allows to move
  // last bits between any two runs (Determinism.IndependentOfThreadCount).
  c.threads = 1;
  const RenderResult plain = render_scene(scene, c);
  c.save_field = tmp.file("f.field");
  c.save_field_every_iteration = true;
  const RenderResult saved = render_scene(scene, c);
  EXPECT_EQ(plain.image.data, saved.image.data) << "saving the field must not change the render";

  const FieldFile f = load_field(c.save_field);
  const nlohmann::json& log = saved.log;
  ASSERT_EQ(f.snapshots.size(), log["scheduler"]["iterations"].size());
  double handed = 0.0;
  for (const FieldSnapshot& s : f.snapshots)
    for (const auto& [key, value] : s.summary)
      if (key == "samples_recorded" || key == "samples_dropped") handed += value;
  EXPECT_EQ(handed, log["recorder"]["samples"].get<double>()) << "every sample the recorder handed over, once";
  const FieldSnapshot& last = f.snapshots.back();
  EXPECT_EQ(last.leaves.size(), log["guiding"]["spatial_leaves"].get<size_t>());
  EXPECT_EQ(last.spp, 8u);
  EXPECT_EQ(f.wireframe.p.size(), 3u * f.wireframe.scene_triangles) << "the Cornell box is small: every triangle";
  EXPECT_EQ(log["guiding"]["field_file"]["snapshots"].get<size_t>(), f.snapshots.size());
}

TEST(FieldSave, NeedsGuiding) {
  RenderConfig c = quick_config(1);
  c.save_field = "x.field";
  EXPECT_THROW(check_config(c), Error);
  c.save_field.clear();
  c.save_field_every_iteration = true;
  c.guiding.enabled = true;
  EXPECT_THROW(check_config(c), Error);
}

TEST(FieldCommands, StatsAndImageReadTheFileAndNameABadOne) {
  TempDir tmp("theia_field_cmd");
  RenderConfig c = guided(4);
  c.save_field = tmp.file("f.field");
  render_scene(small_cornell(), c);
  RunResult r = run_theia("field stats --json " + c.save_field);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json j = nlohmann::json::parse(r.output);
  const FieldFile f = load_field(c.save_field);
  EXPECT_EQ(j["leaves"].get<size_t>(), f.snapshots.back().leaves.size());
  EXPECT_EQ(j["per_leaf"]["samples"].size(), f.snapshots.back().leaves.size());
  EXPECT_EQ(j["columns"]["samples_iteration"]["sum"].get<double>(), j["summary"]["samples_recorded"].get<double>());

  r = run_theia("field image " + c.save_field + " --point 0 1 0 --width 64 -o " + tmp.file("d.png"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const ImageBuffer png = read_image_file(tmp.file("d.png"));
  EXPECT_EQ(png.width, 64);
  EXPECT_EQ(png.height, 32);

  static const char kBad[] = "THEIAFLD\x01\0\0\0garbage that is no field";
  tmp.write("bad.field", std::string(kBad, sizeof(kBad) - 1));
  r = run_theia("field stats " + tmp.file("bad.field"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("bad.field: field file corrupt: checksum"), std::string::npos) << r.output;
  r = run_theia("render " + kCornell + " --guiding --spp 1 -o " + tmp.file("x.exr") + " --save-field " +
                tmp.file("missing/f.field"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("--save-field " + tmp.file("missing/f.field") + ": the directory"), std::string::npos)
      << r.output;
  EXPECT_FALSE(std::filesystem::exists(tmp.file("x.exr"))) << "refused before rendering";
  r = run_theia("field image " + c.save_field + " --point 0 0 0 --iteration 99 -o " + tmp.file("x.png"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("no snapshot of iteration 99"), std::string::npos) << r.output;
}
