// The light BVH (cachepoints/light_bvh.h) in whole renders: unbiased, so the
// street converges to what the locally optimal sampler converges to, and many-lights-city
// at 64 spp meets the validation bar (test_validation.cpp) scaled from
// 256 spp by the variance's 1/spp, against the converged reference.
#include "light_sampler_checks.h"

#include <gtest/gtest.h>

#include <algorithm>

using namespace theia;
using namespace theia::test;

TEST(LightBvhRender, ConvergesToTheLocallyOptimalImage) {
  RenderResult r = expect_converges_to_local("bvh");
  EXPECT_GT(r.log["light_sampler"]["nodes"].get<double>(), 1.0);
}

TEST(LightBvhRender, ManyLightsCityMeetsTheValidationBarAt64spp) {
  Scene scene = load_test_scene_file(std::string(THEIA_SCENES) + "/many-lights-city/scene.pbrt");
  RenderConfig config = quick_config(64);
  config.light_sampler = "bvh";
  RenderResult r = render_scene(scene, config);
  ImageBuffer ref = read_image_file(std::string(THEIA_TEST_DATA) + "/many-lights-city.exr");
  ErrorMetrics m = compute_error_metrics(r.image, ref);
  // pbrt-v4's own 256-spp render (its BVH light sampler): relMSE 0.051, block
  // relMSE 0.00055, mean deviation 0.0021; variance scales as 1/spp.
  constexpr double kScale = 256.0 / 64.0;
  std::printf("many-lights-city bvh 64 spp: relMSE %.4f, block relMSE %.2e, mean deviation %.4f, %.1f s\n", m.rel_mse,
              m.block_rel_mse, m.channel_mean_deviation, r.log["time"]["render"].get<double>());
  EXPECT_LE(m.rel_mse, 2.0 * 0.051 * kScale);
  EXPECT_LE(m.block_rel_mse, std::max(3.0 * 0.00055 * kScale, 5e-4));
  EXPECT_LE(m.channel_mean_deviation, 0.0021 + 0.02);
  EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
}
