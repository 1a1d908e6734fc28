// The engine's stages on closed forms: the escaped-ray stage alone (a scene
// of infinite lights and nothing else), and the escaped-ray stage behind the
// surface stage (a sphere that hides part of the sky), with hits sorted and
// in traced order (two paths through shading); and the two orders against
// each other where every kind of traced ray meets: escapes, hits, and paths
// that leave the batch in a medium; and one wavefront a thread (lanes)
// against one for both.
#include "render_helpers.h"
#include "cachepoints/light_sampler.h"
#include "wavefront/engine.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>

namespace theia {
namespace {

using test::load_test_scene;

ImageBuffer render_engine(const Scene& scene, int spp, bool sort = false, int max_depth = 5) {
  RenderableScene rs(scene);
  Film film(scene.film.width, scene.film.height);
  EngineOptions opt;
  opt.max_depth = max_depth;
  opt.sort = sort;
  WavefrontEngine engine(rs, film, opt);
  engine.render(0, uint32_t(spp));
  EXPECT_EQ(film.dropped.load(), 0u);
  EXPECT_EQ(engine.stats().camera_rays, uint64_t(scene.film.width) * uint64_t(scene.film.height) * uint64_t(spp));
  return resolve_film(film);
}

TEST(EscapedRays, EveryCameraRayThatLeavesSeesTheSumOfTheInfiniteLights) {
  // Two constant environments: the stage adds every infinite light, and with
  // nothing to hit no ray is shaded, no path continues, alpha is zero.
  Scene scene = load_test_scene(R"(
    Film "rgb" "integer xresolution" [16] "integer yresolution" [12]
    LookAt 0 0 0  0 0 1  0 1 0
    Camera "perspective" "float fov" [60]
    WorldBegin
    LightSource "infinite" "rgb L" [0.25 0.5 1]
    LightSource "infinite" "rgb L" [0.25 0.25 0.25]
  )");
  for (bool sort : {false, true}) {
    ImageBuffer img = render_engine(scene, 4, sort);
    // The two radiances, 0.5 0.75 1.25 in linear sRGB: the same in the output.
    const float expected[3] = {0.5f, 0.75f, 1.25f};
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x) {
        for (int c = 0; c < 3; ++c) ASSERT_NEAR(img.at(x, y, c), expected[c], 1e-5f) << x << "," << y << " sort " << sort;
        ASSERT_EQ(img.at(x, y, 3), 0.0f);  // alpha
      }
  }
}

TEST(EscapedRays, BehindASurfaceTheSkyIsWhatTheBlackSphereDoesNotHide) {
  // A black sphere of radius 1 at distance 5 under a constant sky: a pixel
  // whose centre ray misses it by a margin wider than the filter sees the
  // sky; one deep inside its disk sees black and has alpha 1.  The sphere's
  // material reflects nothing, so every light reaching the film is escaped.
  Scene scene = load_test_scene(R"(
    Film "rgb" "integer xresolution" [32] "integer yresolution" [32]
    PixelFilter "box"
    LookAt 0 0 -5  0 0 0  0 1 0
    Camera "perspective" "float fov" [40]
    WorldBegin
    LightSource "infinite" "rgb L" [2 2 2]
    Material "diffuse" "rgb reflectance" [0 0 0]
    Shape "sphere" "float radius" [1]
  )");
  // The sphere's angular radius is asin(1/5); the image's half-width tan(20 deg).
  const float disk = std::tan(std::asin(0.2f)) / std::tan(glm::radians(20.0f)) * 16.0f;  // pixels
  for (bool sort : {false, true}) {
    ImageBuffer img = render_engine(scene, 4, sort);
    int sky = 0, sphere = 0;
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x) {
        const float r = std::hypot(float(x) + 0.5f - 16.0f, float(y) + 0.5f - 16.0f);
        if (r > disk + 1.5f) {
          ++sky;
          for (int c = 0; c < 3; ++c) ASSERT_NEAR(img.at(x, y, c), 2.0f, 1e-5f) << "sort " << sort;
          ASSERT_EQ(img.at(x, y, 3), 0.0f);
        } else if (r < disk - 1.5f) {
          ++sphere;
          for (int c = 0; c < 3; ++c) ASSERT_EQ(img.at(x, y, c), 0.0f) << "sort " << sort;
          ASSERT_EQ(img.at(x, y, 3), 1.0f);
        }
      }
    EXPECT_GT(sky, 400);
    EXPECT_GT(sphere, 100);
  }
}

// Floor, sky and a sphere of smoke behind an interface: every kind of traced ray.
Scene smoke_sphere_scene() {
  return load_test_scene(R"(
    Film "rgb" "integer xresolution" [24] "integer yresolution" [24]
    LookAt 0 1 -5  0 0 0  0 1 0
    Camera "perspective" "float fov" [40]
    WorldBegin
    LightSource "infinite" "rgb L" [1 1 1]
    AttributeBegin
      Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
      Shape "trianglemesh" "point3 P" [-4 -1 -4  4 -1 -4  4 -1 4  -4 -1 4] "integer indices" [0 2 1 0 3 2]
    AttributeEnd
    MakeNamedMedium "m" "string type" "homogeneous" "rgb sigma_a" [0.5 0.5 0.5] "rgb sigma_s" [2 2 2]
    MediumInterface "m" ""
    Material "interface"
    Shape "sphere" "float radius" [1]
  )");
}

// Sorting changes only the order in which paths are traced and shaded:
// every path draws the same numbers either way, so the images agree to the
// film's summation order.  The scene has every kind of traced ray: escapes
// into the sky, hits on a floor, and, inside an interface sphere of
// scattering smoke, paths that scatter or end in the medium and leave their
// batch there (which unsorted shading must pass by, and sorting drop).
TEST(ShadingOrder, SortedAndTracedOrdersGiveTheSameImage) {
  const Scene scene = smoke_sphere_scene();
  const ImageBuffer traced = render_engine(scene, 8, false, 8), sorted = render_engine(scene, 8, true, 8);
  double total = 0.0;
  for (int y = 0; y < 24; ++y)
    for (int x = 0; x < 24; ++x)
      for (int c = 0; c < 4; ++c) {
        const float a = traced.at(x, y, c), b = sorted.at(x, y, c);
        ASSERT_NEAR(a, b, 1e-5f * std::max(1.0f, std::abs(a))) << x << "," << y << " channel " << c;
        total += a;
      }
  EXPECT_GT(total, 100.0);  // not a black image agreeing with itself
}

// ---------------------------------------------------------------- lanes

struct LaneRender {
  ImageBuffer image;
  EngineStats stats;
  EngineSizes sizes;
  uint64_t stopped_at = 0;  // where the first render() call returned
  std::vector<double> progress;
};

// 8 spp at `threads` threads (one lane each) over a pool of 2048 paths, so
// that each lane claims camera samples many times.  Stopped as a time limit
// stops (paths in flight finish) once `stop_at` of the samples are claimed,
// then continued from where it stopped.
LaneRender render_in_lanes(const Scene& scene, int threads, double stop_at = 2.0) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
  RenderableScene rs(scene);
  Film film(scene.film.width, scene.film.height);
  StopRequest stop;
  EngineOptions opt;
  opt.max_depth = 8;
  opt.max_paths = 2048;
  opt.stop = &stop;
  WavefrontEngine engine(rs, film, opt);
  LaneRender r;
  const auto progress = [&](double f) {
    r.progress.push_back(f);
    if (f >= stop_at) stop.raise(StopReason::TimeLimit);
  };
  r.stopped_at = engine.render(0, 8, progress);
  stop.clear();
  engine.render(0, 8, {}, r.stopped_at);
  r.image = resolve_film(film);
  r.stats = engine.stats();
  r.sizes = engine.sizes();
  return r;
}

void expect_same_image(const ImageBuffer& a, const ImageBuffer& b) {
  ASSERT_EQ(a.data.size(), b.data.size());
  for (size_t i = 0; i < a.data.size(); ++i)
    ASSERT_NEAR(a.data[i], b.data[i], 1e-5f * std::max(1.0f, std::abs(a.data[i]))) << "value " << i;
}

// Each lane claims runs of camera samples from one counter: every sample is
// rendered once, by whichever lane, along the same path, so two lanes give
// one lane's image to the film's summation order, and the same rays.
TEST(Lanes, TwoLanesRenderOneLanesImageAndRays) {
  const Scene scene = smoke_sphere_scene();
  const LaneRender one = render_in_lanes(scene, 1), two = render_in_lanes(scene, 2);
  EXPECT_EQ(one.sizes.lanes, 1u);
  EXPECT_EQ(two.sizes.lanes, 2u);
  EXPECT_EQ(two.sizes.lane_paths(), 1024u);
  expect_same_image(one.image, two.image);
  EXPECT_EQ(two.stats.camera_rays, 24u * 24u * 8u);
  EXPECT_EQ(two.stats.total_rays(), one.stats.total_rays());
  EXPECT_EQ(two.stats.path_vertices, one.stats.path_vertices);
  EXPECT_LE(two.stats.peak_live_paths, 2048u);
  // Reported as the lanes claim, one call at a time: never backwards, and
  // ending at the whole iteration.
  ASSERT_GT(two.progress.size(), 4u);
  EXPECT_TRUE(std::is_sorted(two.progress.begin(), two.progress.end()));
  EXPECT_EQ(two.progress.back(), 1.0);
}

// A stop leaves the claimed samples one run from the start, all rendered:
// continuing from where render() returned completes the image exactly.
// (Whichever lane made the last claim: stopped at several points, the
// other lane makes it in some.)
TEST(Lanes, AStoppedIterationContinuesExactlyWhereTheLanesStopped) {
  const Scene scene = smoke_sphere_scene();
  const LaneRender whole = render_in_lanes(scene, 1);
  const uint64_t samples = 24 * 24 * 8;
  for (double at : {0.2, 0.35, 0.5, 0.65, 0.8}) {
    const LaneRender stopped = render_in_lanes(scene, 2, at);
    EXPECT_GE(double(stopped.stopped_at), at * double(samples));
    // Past the stop at most two runs are claimed (the one that crossed it,
    // and one the other lane may be taking), each at most a lane's 1024
    // paths: the stop is inside the iteration wherever that leaves room; a
    // later one may end it, as the lanes' timing falls.
    if (at * double(samples) + 2 * 1024 < double(samples)) {
      EXPECT_LT(stopped.stopped_at, samples);
    }
    EXPECT_LE(stopped.stopped_at, samples);
    expect_same_image(whole.image, stopped.image);
    EXPECT_EQ(stopped.stats.camera_rays, samples);
  }
}

}  // namespace
}  // namespace theia

namespace theia {
namespace {

// The power sampler, with counters: what a sampler that learns from
// shadow rays is told, per light.
class CountingLightSampler final : public LightSampler {
 public:
  CountingLightSampler(const LightSet& lights, bool learns) : power_(lights), learns_(learns) {}
  std::optional<SampledLight> sample(const LightSampleContext& ctx, float u) const override {
    auto s = power_.sample(ctx, u);
    if (s) s->region = 7;
    return s;
  }
  float pmf(const LightSampleContext& ctx, int light) const override { return power_.pmf(ctx, light); }
  const char* name() const override { return "counting"; }
  bool wants_feedback() const override { return learns_; }
  void record_shadow(const SampledLight& chosen, bool unoccluded) const override {
    if (chosen.region != 7) wrong_region.fetch_add(1);
    attempts[size_t(chosen.light)].fetch_add(1);
    if (unoccluded) successes[size_t(chosen.light)].fetch_add(1);
  }
  mutable std::atomic<uint64_t> attempts[2] = {0, 0}, successes[2] = {0, 0}, wrong_region{0};

 private:
  PowerLightSampler power_;
  bool learns_;
};

// A floor under a ceiling; light 0 between them, light 1 above the ceiling,
// where no shading point that can see it has a ray to it that is not blocked.
const char* kCeilingScene = R"(
  Film "rgb" "integer xresolution" [24] "integer yresolution" [24]
  Integrator "volpath" "integer maxdepth" [3]
  LookAt 0 0.8 0  0 0 0  0 0 1
  Camera "perspective" "float fov" [60]
  WorldBegin
  LightSource "point" "point3 from" [0 0.5 0] "rgb I" [1 1 1]
  LightSource "point" "point3 from" [0 2 0] "rgb I" [4 4 4]
  Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
  Shape "trianglemesh" "point3 P" [-1 0 -1  1 0 -1  1 0 1  -1 0 1] "integer indices" [0 1 2 0 2 3]
  Shape "trianglemesh" "point3 P" [-100 1 -100  100 1 -100  100 1 100  -100 1 100] "integer indices" [0 2 1 0 3 2]
)";

// Renders the scene with a counting sampler in place of the power sampler.
struct CountingRender {
  RenderableScene rs;
  const CountingLightSampler* sampler = nullptr;
  ImageBuffer image;

  CountingRender(const Scene& scene, bool learns) : rs(scene) {
    auto s = std::make_unique<CountingLightSampler>(rs.lights, learns);
    sampler = s.get();
    rs.light_sampler = std::move(s);
    Film film(scene.film.width, scene.film.height);
    EngineOptions opt;
    opt.max_depth = 3;
    WavefrontEngine(rs, film, opt).render(0, 8);
    image = resolve_film(film);
  }
};

TEST(ShadowRays, ALearningLightSamplerHearsEveryOutcomeWithItsOwnChoice) {
  Scene scene = test::load_test_scene(kCeilingScene);
  CountingRender learning(scene, true), plain(scene, false);
  const CountingLightSampler& s = *learning.sampler;
  EXPECT_EQ(s.wrong_region.load(), 0u);
  // Light 0 is in the room: every shadow ray to it arrives.  Light 1 is
  // above the ceiling: the floor's rays to it all hit the ceiling.
  EXPECT_GT(s.attempts[0].load(), 1000u);
  EXPECT_EQ(s.successes[0].load(), s.attempts[0].load());
  EXPECT_GT(s.attempts[1].load(), 1000u);
  EXPECT_EQ(s.successes[1].load(), 0u);
  // A sampler that does not learn hears nothing, and listening changes no pixel.
  EXPECT_EQ(plain.sampler->attempts[0].load() + plain.sampler->attempts[1].load(), 0u);
  ASSERT_EQ(learning.image.data.size(), plain.image.data.size());
  for (size_t i = 0; i < plain.image.data.size(); ++i)
    ASSERT_NEAR(learning.image.data[i], plain.image.data[i], 1e-5f * std::max(1.0f, std::abs(plain.image.data[i])));
}

}  // namespace
}  // namespace theia
