// --reference: error against run time at every iteration boundary.
#include "core/log.h"
#include "core/metrics.h"
#include "render_helpers.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>

using namespace theia;
using namespace theia::test;

namespace {

const char* kScene = R"(
  Film "rgb" "integer xresolution" [16] "integer yresolution" [12]
  LookAt 0 0 -5  0 0 0  0 1 0
  Camera "perspective" "float fov" [30]
  WorldBegin
  LightSource "infinite" "rgb L" [1 1 1]
  AttributeBegin
    AreaLightSource "diffuse" "rgb L" [4 4 4]
    Translate 0 2 0
    Shape "sphere" "float radius" [0.4]
  AttributeEnd
  Material "diffuse" "rgb reflectance" [0.6 0.5 0.4]
  Shape "sphere" "float radius" [1]
)";

RenderConfig iterations_4_4_8_16(int spp) {
  RenderConfig c = quick_config(spp);
  c.iteration.first = 4;
  c.iteration.repeat = 2;
  c.iteration.growth = 2.0;
  return c;
}

}  // namespace

TEST(Reference, LogsTimeSppAndErrorAtEveryIteration) {
  TempDir tmp("theia_reference");
  Scene scene = load_test_scene(kScene);
  // A different seed: the reference's noise is independent of the render's.
  RenderConfig rc = quick_config(256);
  rc.seed = 7;
  RenderResult ref = render_scene(scene, rc);
  const std::string ref_path = tmp.file("ref.exr");
  write_exr(ref_path, ref.image);

  RenderConfig c = iterations_4_4_8_16(32);
  c.reference_path = ref_path;
  RenderResult r = render_scene(scene, c);
  const auto& its = r.log["scheduler"]["iterations"];
  ASSERT_EQ(its.size(), 4u);
  const int expected_spp[] = {4, 8, 16, 32};
  double prev_render = 0.0, prev_wall = 0.0;
  for (size_t i = 0; i < its.size(); ++i) {
    const auto& it = its[i];
    ASSERT_TRUE(it.contains("rel_mse")) << it.dump();
    EXPECT_EQ(it["spp_total"].get<int>(), expected_spp[i]);
    double render = it["render_seconds"].get<double>(), wall = it["wall_seconds"].get<double>();
    EXPECT_GT(render, prev_render);
    EXPECT_GT(wall, prev_wall);
    EXPECT_GE(wall, render);  // wall time includes what the render clock leaves out
    prev_render = render;
    prev_wall = wall;
    for (const char* k : {"rel_mse", "rmse", "mape"}) {
      EXPECT_TRUE(std::isfinite(it[k].get<double>())) << k;
      EXPECT_GT(it[k].get<double>(), 0.0) << k;
    }
    EXPECT_EQ(it["dropped_samples"].get<uint64_t>(), 0u);
  }
  // 8x the samples: the error against an independent reference falls.
  EXPECT_LT(its[3]["rel_mse"].get<double>(), 0.5 * its[0]["rel_mse"].get<double>());
  EXPECT_LT(its[3]["rmse"].get<double>(), its[0]["rmse"].get<double>());
  // The last boundary's numbers are those of the final image.
  ImageBuffer reread = read_image_file(ref_path);
  EXPECT_NEAR(its[3]["rel_mse"].get<double>(), rel_mse(r.image, reread), 1e-9);
  EXPECT_NEAR(its[3]["mape"].get<double>(), mape(r.image, reread), 1e-9);
  EXPECT_EQ(r.log["reference"].get<std::string>(), ref_path);
}

TEST(Reference, WithoutTheOptionNothingIsMeasured) {
  Scene scene = load_test_scene(kScene);
  RenderResult r = render_scene(scene, iterations_4_4_8_16(16));
  for (const auto& it : r.log["scheduler"]["iterations"]) EXPECT_FALSE(it.contains("rel_mse")) << it.dump();
  EXPECT_FALSE(r.log.contains("reference"));
}

TEST(Reference, WrongSizeOrMissingReferenceIsAClearError) {
  TempDir tmp("theia_reference_bad");
  Scene scene = load_test_scene(kScene);
  ImageBuffer small;
  small.width = 4;
  small.height = 4;
  small.channels = {"R", "G", "B"};
  small.data.assign(4 * 4 * 3, 0.5f);
  write_exr(tmp.file("small.exr"), small);
  RenderConfig c = quick_config(4);
  c.reference_path = tmp.file("small.exr");
  try {
    render_scene(scene, c);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("4x4"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("16x12"), std::string::npos) << e.what();
  }
  c.reference_path = tmp.file("missing.exr");
  EXPECT_THROW(render_scene(scene, c), Error);
}

TEST(Reference, CommandLineWritesTheErrorIntoTheJsonLog) {
  TempDir tmp("theia_reference_cli");
  Scene scene = load_test_scene(kScene);
  write_exr(tmp.file("ref.exr"), render_scene(scene, quick_config(16)).image);
  std::string s = tmp.write("s.pbrt", kScene);
  RunResult run = run_theia("render " + s + " -o " + tmp.file("out.exr") + " --spp 8 --iteration-first 4 -q --reference " +
                            tmp.file("ref.exr"));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  nlohmann::json log = nlohmann::json::parse(std::ifstream(tmp.file("out.json")));
  const auto& its = log["scheduler"]["iterations"];
  ASSERT_EQ(its.size(), 2u);
  EXPECT_EQ(its[1]["spp_total"].get<int>(), 8);
  // The command's wall clock starts before the scene is loaded.
  EXPECT_GT(its[1]["wall_seconds"].get<double>(), its[1]["render_seconds"].get<double>());
  EXPECT_GT(its[1]["rel_mse"].get<double>(), 0.0);
}
