// The locally optimal sampler (cachepoints/local_sampler.h) as the unbiased
// reference of the light samplers: power sampling converges to its image (as
// cache points and the light BVH do, in their own tests), and the command
// line warns where it gets expensive.
#include "light_sampler_checks.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <fstream>

using namespace theia;
using namespace theia::test;

TEST(LocalSamplerRender, PowerConvergesToTheLocallyOptimalImage) { expect_converges_to_local("power"); }

TEST(LocalSamplerRender, WarnsFromKLocalWarnEmitters) {
  TempDir dir("theia_local_sampler");
  auto run = [&](int n) {
    const std::string scene = dir.write("s" + std::to_string(n) + ".pbrt", street_scene(n, [](int) { return 1.0f; }, true));
    return run_theia("render " + scene + " -o " + dir.file("out.exr") + " --light-sampler local --spp 1");
  };
  const RunResult small = run(4), large = run(16);  // 65 and 1,025 emitters
  ASSERT_EQ(small.exit_code, 0) << small.output;
  ASSERT_EQ(large.exit_code, 0) << large.output;
  EXPECT_EQ(small.output.find("--light-sampler local evaluates"), std::string::npos) << small.output;
  EXPECT_NE(large.output.find("--light-sampler local evaluates all 1025 emitters"), std::string::npos) << large.output;
}
