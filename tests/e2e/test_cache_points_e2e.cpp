// Cache points in whole renders (cachepoints/cache_points.h): the image is
// unbiased (it converges to what the locally optimal sampler converges to), learned
// visibility reaches the log, and a render stopped inside an iteration and
// resumed equals an uninterrupted one.
#include "light_sampler_checks.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <fstream>

using namespace theia;
using namespace theia::test;

TEST(CachePointsRender, ConvergesToTheLocallyOptimalImage) {
  RenderResult r = expect_converges_to_local("cachepoints");
  EXPECT_GT(r.log["light_sampler"]["points"].get<double>(), 0.0);
}

TEST(CachePointsRender, ResumedInsideAnIterationEqualsUninterrupted) {
  TempDir dir("theia_cache_points_resume");
  const std::string scene = (dir.path / "s.pbrt").string();
  std::ofstream(scene) << lit_street();
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
