// End-to-end convergence: the engine's estimator against closed forms.
#include "render_helpers.h"
#include "scene/camera.h"

#include <gtest/gtest.h>

using namespace theia;
using namespace theia::test;

// A diffuse sphere of albedo 1 inside a constant environment of radiance 1:
// every path ends in the environment with throughput 1, so every pixel is 1.
TEST(WhiteFurnace, DiffuseSphereOfAlbedoOneRendersToOne) {
  Scene scene = load_test_scene(furnace_sphere_scene(32, 30.0f, 1.0f));
  RenderResult r = render_scene(scene, quick_config(64));
  RGB mean = image_mean(r.image);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], 1.0f, 0.005f) << "channel " << c;
  // The sphere covers the centre; a pixel there must be 1 within noise too.
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(pixel_channel(r.image, 16, 16, c), 1.0f, 0.05f);
  // ... and the centre pixel saw the sphere (alpha 1), a corner did not.
  EXPECT_FLOAT_EQ(pixel_channel(r.image, 16, 16, 3), 1.0f);
  EXPECT_FLOAT_EQ(pixel_channel(r.image, 0, 0, 3), 0.0f);
  EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
}

// The same furnace with albedo 0.5: single-sphere, convex, so radiance at the
// sphere is 0.5 * 1 (one bounce, then the environment): pixels inside read 0.5.
TEST(WhiteFurnace, GreySphereReflectsHalf) {
  Scene scene = load_test_scene(furnace_sphere_scene(16, 10.0f, 0.5f));
  RenderResult r = render_scene(scene, quick_config(256));
  RGB mean = image_mean(r.image);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], 0.5f, 0.005f);
}

// A diffuse plane under a point light: L = rho / pi * I * cos(theta) / d^2 at
// every visible point, with no indirect light (nothing else in the scene).
TEST(Analytic, DiffusePlaneUnderPointLight) {
  const float rho = 0.8f, I = 10.0f, h = 2.0f;
  Scene scene = load_test_scene(R"(
    Film "rgb" "integer xresolution" [64] "integer yresolution" [64]
    PixelFilter "box" "float xradius" [0.5] "float yradius" [0.5]
    LookAt 0 4 0  0 0 0  0 0 1
    Camera "perspective" "float fov" [40]
    WorldBegin
    LightSource "point" "rgb I" [10 10 10] "point3 from" [0.5 2 0.25]
    Material "diffuse" "rgb reflectance" [0.8 0.8 0.8]
    Shape "trianglemesh" "point3 P" [-10 0 -10  10 0 -10  10 0 10  -10 0 10]
      "integer indices" [0 1 2 0 2 3]
  )");
  RenderResult r = render_scene(scene, quick_config(16));
  // Intersect each pixel's central camera ray with the plane y = 0 and compare.
  Camera cam = make_camera(scene.camera, scene.film);
  int checked = 0;
  double worst = 0.0;
  for (int y = 4; y < 60; y += 5)
    for (int x = 4; x < 60; x += 5) {
      vec3 p = pixel_on_plane(cam, x, y);
      vec3 to_light = vec3(0.5f, h, 0.25f) - p;
      float d2 = glm::dot(to_light, to_light);
      float cos_theta = to_light.y / std::sqrt(d2);
      float expected = rho / kPi * I * cos_theta / d2;
      float got = pixel_channel(r.image, x, y, 1);
      worst = std::max(worst, double(std::abs(got - expected) / expected));
      ++checked;
    }
  EXPECT_GT(checked, 100);
  // The pixel footprint averages a smooth function: agreement to well under 1%.
  EXPECT_LT(worst, 0.01);
}
