// The Cornell box against pbrt-v4's 4096-spp reference, and the engine's
// determinism: the image must not depend on threads, batch size or sorting.
#include "core/metrics.h"
#include "render_helpers.h"

#include <gtest/gtest.h>

using namespace theia;
using namespace theia::test;

namespace {
const std::string kCornell = std::string(THEIA_SCENES) + "/cornell-box/scene.pbrt";
}

TEST(Cornell, MatchesPbrtReferenceAt256spp) {
  Scene scene = load_test_scene_file(kCornell);
  RenderConfig c = quick_config(256);
  RenderResult r = render_scene(scene, c);
  ImageBuffer ref = read_image_file(std::string(THEIA_TEST_DATA) + "/cornell-box.exr");
  ASSERT_EQ(ref.width, r.image.width);
  ASSERT_EQ(ref.height, r.image.height);
  double rel = rel_mse(r.image, ref);
  double dev = channel_mean_deviation(r.image, ref);
  std::printf("cornell-box 256 spp: relMSE %.5f, block relMSE %.2e, channel-mean deviation %.4f, %.2f s\n", rel,
              block_rel_mse(r.image, ref, 8), dev, r.log["time"]["render"].get<double>());
  EXPECT_LT(rel, 0.005);
  EXPECT_LT(dev, 0.02);
  EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
}

class Determinism : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scene_ = new Scene(load_test_scene_file(kCornell));
    scene_->film.width = 48;
    scene_->film.height = 48;
  }
  static void TearDownTestSuite() { delete scene_; }
  static RenderResult render(int threads, size_t batch, bool sort, size_t max_paths = size_t(1) << 19) {
    RenderConfig c = quick_config(16);
    c.threads = threads;
    c.batch_size = batch;
    c.sort = sort;
    c.max_paths = max_paths;
    return render_scene(*scene_, c);
  }
  static Scene* scene_;
};
Scene* Determinism::scene_ = nullptr;

TEST_F(Determinism, IndependentOfThreadCount) {
  RenderResult a = render(1, 4096, true), b = render(2, 4096, true);
  EXPECT_LT(max_relative_difference(a.image, b.image), 1e-4);
  EXPECT_EQ(a.log["rays"]["total"], b.log["rays"]["total"]);  // two lanes, the same paths
  EXPECT_EQ(b.log["paths"]["lanes"].get<size_t>(), 2u);
}

TEST_F(Determinism, IndependentOfBatchSizeAndPoolSize) {
  RenderResult a = render(2, 1024, true, 4096), b = render(2, 65536, true);
  EXPECT_LT(max_relative_difference(a.image, b.image), 1e-4);
  EXPECT_EQ(a.log["rays"]["total"], b.log["rays"]["total"]);
}

TEST_F(Determinism, IndependentOfSorting) {
  RenderResult a = render(2, 4096, true), b = render(2, 4096, false);
  EXPECT_LT(max_relative_difference(a.image, b.image), 1e-4);
}

TEST_F(Determinism, SeedChangesTheNoiseNotTheMean) {
  RenderConfig c = quick_config(16);
  RenderResult a = render_scene(*scene_, c);
  c.seed = 7;
  RenderResult b = render_scene(*scene_, c);
  EXPECT_GT(max_relative_difference(a.image, b.image), 1e-2);
  RGB ma = image_mean(a.image), mb = image_mean(b.image);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(ma[i] / mb[i], 1.0f, 0.02f);
}

// Memory stays bounded by the pool, whatever the sample count.
TEST_F(Determinism, LivePathsNeverExceedThePool) {
  RenderResult r = render(2, 512, true, 2048);
  EXPECT_LE(r.log["paths"]["peak_live"].get<size_t>(), 2048u);
  EXPECT_EQ(r.log["paths"]["count"].get<uint64_t>(), uint64_t(48 * 48 * 16));
}
