// The engine's stages on closed forms: the escaped-ray stage alone (a scene
// of infinite lights and nothing else), and the escaped-ray stage behind the
// surface stage (a sphere that hides part of the sky).
#include "render_helpers.h"
#include "wavefront/engine.h"

#include <gtest/gtest.h>

namespace theia {
namespace {

using test::load_test_scene;

ImageBuffer render_engine(const Scene& scene, int spp) {
  RenderableScene rs(scene);
  Film film(scene.film.width, scene.film.height);
  EngineOptions opt;
  opt.max_depth = 5;
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
  ImageBuffer img = render_engine(scene, 4);
  // The two radiances, 0.5 0.75 1.25 in linear sRGB: the same in the output.
  const float expected[3] = {0.5f, 0.75f, 1.25f};
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(img.at(x, y, c), expected[c], 1e-5f) << x << "," << y;
      ASSERT_EQ(img.at(x, y, 3), 0.0f);  // alpha
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
  ImageBuffer img = render_engine(scene, 4);
  // The sphere's angular radius is asin(1/5); the image's half-width tan(20 deg).
  const float disk = std::tan(std::asin(0.2f)) / std::tan(glm::radians(20.0f)) * 16.0f;  // pixels
  int sky = 0, sphere = 0;
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 32; ++x) {
      const float r = std::hypot(float(x) + 0.5f - 16.0f, float(y) + 0.5f - 16.0f);
      if (r > disk + 1.5f) {
        ++sky;
        for (int c = 0; c < 3; ++c) ASSERT_NEAR(img.at(x, y, c), 2.0f, 1e-5f);
        ASSERT_EQ(img.at(x, y, 3), 0.0f);
      } else if (r < disk - 1.5f) {
        ++sphere;
        for (int c = 0; c < 3; ++c) ASSERT_EQ(img.at(x, y, c), 0.0f);
        ASSERT_EQ(img.at(x, y, 3), 1.0f);
      }
    }
  EXPECT_GT(sky, 400);
  EXPECT_GT(sphere, 100);
}

}  // namespace
}  // namespace theia
