// The PathObserver sees every path event, each vertex finishes exactly once,
// and attaching an observer does not change the image.
#include "render_helpers.h"
#include "cachepoints/light_sampler.h"
#include "scene/accel.h"
#include "scene/camera.h"
#include "scene/filter.h"
#include "wavefront/engine.h"

#include <gtest/gtest.h>

#include <atomic>
#include <memory>
#include <mutex>

using namespace theia;
using namespace theia::test;

namespace {

class CountingObserver final : public PathObserver {
 public:
  explicit CountingObserver(size_t max_vertices) : done_(max_vertices) {}
  uint32_t path_started(uint32_t, uint32_t) override {
    ++started;
    return next_++;
  }
  uint32_t vertex_created(uint32_t parent, const PathVertexInfo& v) override {
    if (parent >= next_.load()) ++bad_parent;
    if (v.is_nee) ++nee;
    ++created;
    return next_++;
  }
  void emission_added(uint32_t vertex, uint32_t, const RGB& L, float w) override {
    if (vertex >= next_.load() || !is_finite(L) || !(w >= 0.0f && w <= 1.0f)) ++bad_parent;
    ++emissions;
  }
  void vertex_continued(uint32_t) override {}
  void vertex_done(uint32_t vertex) override {
    if (vertex >= done_.size()) {
      ++bad_parent;
      return;
    }
    done_[vertex].fetch_add(1);
  }
  int count_done_not_once() const {
    int bad = 0;
    for (uint32_t i = 0; i < next_.load(); ++i) bad += done_[i].load() != 1;
    return bad;
  }

  std::atomic<uint64_t> started{0}, created{0}, nee{0}, emissions{0}, bad_parent{0};

 private:
  std::atomic<uint32_t> next_{0};
  std::vector<std::atomic<int>> done_;
};

}  // namespace

TEST(PathObserver, EveryVertexFinishesExactlyOnceAndImageIsUnchanged) {
  Scene scene = load_test_scene_file(std::string(THEIA_SCENES) + "/cornell-box/scene.pbrt");
  scene.film.width = scene.film.height = 24;
  RenderableScene rs(scene);
  EngineOptions opt;
  opt.max_depth = 16;
  opt.batch_size = 2048;

  Film plain(24, 24), observed(24, 24);
  WavefrontEngine(rs, plain, opt).render(0, 8);
  CountingObserver obs(24 * 24 * 8 * 64);
  WavefrontEngine engine(rs, observed, opt, EngineHooks{.observer = &obs});
  engine.render(0, 8);

  EXPECT_EQ(obs.started.load(), uint64_t(24 * 24 * 8));
  EXPECT_GT(obs.created.load(), obs.started.load());
  EXPECT_GT(obs.nee.load(), 0u);
  EXPECT_GT(obs.emissions.load(), 0u);
  EXPECT_EQ(obs.bad_parent.load(), 0u);
  EXPECT_EQ(obs.count_done_not_once(), 0);
  ImageBuffer a = resolve_film(plain), b = resolve_film(observed);
  EXPECT_LT(max_relative_difference(a, b), 1e-4);
}
