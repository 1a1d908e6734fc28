// Cache points in whole renders (cachepoints/cache_points.h): the image is
// unbiased (it converges to what power sampling converges to), learned
// visibility reaches the log, and a render stopped inside an iteration and
// resumed equals an uninterrupted one.
#include "core/metrics.h"
#include "render_helpers.h"
#include "tests/street_scene.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <fstream>

using namespace theia;
using namespace theia::test;

namespace {

// 6 x 6 emitters each side of the wall, a camera looking at the left side.
std::string street_scene() {
  return test::street_scene(6, [](int k) { return 0.5f + float((k * 7) % 5); }, true, false,
                            "LookAt -6 3 -10  0 1 0  0 1 0\n", 0.3f);
}

}  // namespace

TEST(CachePointsRender, ConvergesToWhatPowerSamplingConvergesTo) {
  Scene scene = load_test_scene(street_scene());
  RenderConfig power = quick_config(512), cache = quick_config(512);
  power.light_sampler = "power";
  cache.light_sampler = "cachepoints";
  cache.seed = 1;
  RenderResult a = render_scene(scene, power), b = render_scene(scene, cache);
  EXPECT_EQ(b.log["light_sampler"]["name"], "cachepoints");
  EXPECT_GT(b.log["light_sampler"]["points"].get<double>(), 0.0);
  const RGB ma = image_mean(a.image), mb = image_mean(b.image);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mb[c], ma[c], 0.01 * ma[c]) << "channel " << c;
  // Per 8x8 block too: no region is biased.
  EXPECT_LT(compute_error_metrics(b.image, a.image).block_rel_mse, 2e-3);
  EXPECT_EQ(b.log["dropped_samples"].get<uint64_t>(), 0u);
}

TEST(CachePointsRender, ResumedInsideAnIterationEqualsUninterrupted) {
  TempDir dir("theia_cache_points_resume");
  const std::string scene = (dir.path / "s.pbrt").string();
  std::ofstream(scene) << street_scene();
  auto render = [&](const std::string& out, const std::string& more) {
    return run_theia("render " + scene + " -o " + (dir.path / out).string() +
                     " --light-sampler cachepoints --spp 40 --max-paths 1024 -q" + more);
  };
  ASSERT_EQ(render("ref.exr", "").exit_code, 0);
  ImageBuffer ref = read_image_file((dir.path / "ref.exr").string());
  const std::string ck = (dir.path / "ck").string();
  // Schedule for 40 spp: 16 16 8; stop inside the second iteration, after one update.
  ASSERT_EQ(render("out.exr", " --checkpoint-dir " + ck + " --test-sigterm-at 1:0.5").exit_code, 75);
  RunResult r = render("out.exr", " --checkpoint-dir " + ck + " --resume");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_LT(max_relative_difference(read_image_file((dir.path / "out.exr").string()), ref), 1e-5);
  nlohmann::json log = nlohmann::json::parse(std::ifstream((dir.path / "out.json").string()));
  EXPECT_GT(log["light_sampler"]["shadow_attempts"].get<double>(), 0.0);
  EXPECT_LT(log["light_sampler"]["shadow_successes"].get<double>(), log["light_sampler"]["shadow_attempts"].get<double>());
}
