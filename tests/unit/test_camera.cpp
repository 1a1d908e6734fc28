#include "core/log.h"
#include "core/sampling.h"
#include "scene/camera.h"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

using namespace theia;

namespace {

// pbrt-v4's LookAt: returns render_from_camera (the inverse of what LookAt puts in the CTM).
Transform look_at(vec3 pos, vec3 look, vec3 up) {
  vec3 dir = glm::normalize(look - pos);
  vec3 right = glm::normalize(glm::cross(glm::normalize(up), dir));
  vec3 new_up = glm::cross(dir, right);
  mat4 world_from_camera(vec4(right, 0), vec4(new_up, 0), vec4(dir, 0), vec4(pos, 1));
  return Transform(world_from_camera);
}

Camera pinhole(int w, int h, float fov, Transform render_from_camera = {}) {
  CameraParams c;
  c.fov = fov;
  c.render_from_camera = render_from_camera;
  FilmParams f;
  f.width = w;
  f.height = h;
  return make_camera(c, f);
}

// Direction of the pinhole ray through a raster point, in camera space.
vec3 camera_dir(const Camera& c, vec2 p) {
  return glm::normalize(c.render_from_camera.inverse().vector(generate_camera_ray(c, p, vec2(0.5f)).d));
}

float angle_deg(vec3 a, vec3 b) { return glm::degrees(safe_acos(glm::dot(glm::normalize(a), glm::normalize(b)))); }

}  // namespace

TEST(Camera, CentrePixelLooksAlongCameraZ) {
  Transform rt(glm::translate(mat4(1.0f), vec3(1, -2, 3)) * glm::rotate(mat4(1.0f), 0.7f, glm::normalize(vec3(1, 2, 3))));
  Camera c = pinhole(640, 480, 45.0f, rt);
  Ray r = generate_camera_ray(c, vec2(320.0f, 240.0f), vec2(0.5f));
  EXPECT_NEAR(glm::length(r.o - vec3(1, -2, 3)), 0.0f, 1e-5f);
  EXPECT_NEAR(glm::length(r.d - glm::normalize(rt.vector(vec3(0, 0, 1)))), 0.0f, 1e-5f);
  EXPECT_NEAR(glm::length(r.d), 1.0f, 1e-6f);
}

TEST(Camera, FovSpansTheShorterAxisForBothAspects) {
  const float fov = 60.0f, t = std::tan(radians(fov / 2));
  for (ivec2 res : {ivec2(400, 200), ivec2(200, 400), ivec2(300, 300)}) {
    Camera c = pinhole(res.x, res.y, fov);
    float aspect = float(res.x) / float(res.y);
    float half_x = glm::degrees(std::atan(t * std::max(aspect, 1.0f)));
    float half_y = glm::degrees(std::atan(t / std::min(aspect, 1.0f)));
    vec2 mid(res.x / 2.0f, res.y / 2.0f);
    EXPECT_NEAR(angle_deg(camera_dir(c, {0.0f, mid.y}), vec3(0, 0, 1)), half_x, 1e-3f);
    EXPECT_NEAR(angle_deg(camera_dir(c, {mid.x, 0.0f}), vec3(0, 0, 1)), half_y, 1e-3f);
    EXPECT_NEAR(std::min(half_x, half_y), fov / 2, 1e-3f);
    // Raster y runs down (camera +y is up); raster x runs along camera +x.
    EXPECT_GT(camera_dir(c, {mid.x, 0.0f}).y, 0.0f);
    EXPECT_GT(camera_dir(c, {float(res.x), mid.y}).x, 0.0f);
    // The top-left corner: screen (xmin, ymax) scaled by tan(fov / 2).
    vec3 corner = camera_dir(c, {0.0f, 0.0f});
    EXPECT_NEAR(corner.x / corner.z, -t * std::max(aspect, 1.0f), 1e-5f);
    EXPECT_NEAR(corner.y / corner.z, t / std::min(aspect, 1.0f), 1e-5f);
  }
}

TEST(Camera, LookAtCameraLooksAtItsTarget) {
  vec3 pos(3, 4, -5), target(-1, 0.5f, 2), up(0, 1, 0);
  Camera c = pinhole(320, 240, 40.0f, look_at(pos, target, up));
  Ray centre = generate_camera_ray(c, vec2(160.0f, 120.0f), vec2(0.5f));
  EXPECT_NEAR(glm::length(centre.o - pos), 0.0f, 1e-5f);
  EXPECT_NEAR(glm::length(centre.d - glm::normalize(target - pos)), 0.0f, 1e-5f);
  // The top of the image is towards "up".
  Ray top = generate_camera_ray(c, vec2(160.0f, 0.0f), vec2(0.5f));
  EXPECT_GT(glm::dot(top.d - centre.d, up), 0.0f);
}

TEST(Camera, ScreenWindowMapsTheImageCorners) {
  CameraParams p;
  p.fov = 90.0f;  // tan(45) = 1: camera x/z and y/z equal screen coordinates
  p.has_screen_window = true;
  float sw[4] = {-0.5f, 1.5f, -1.0f, 0.25f};
  std::copy(sw, sw + 4, p.screen_window);
  FilmParams f;
  f.width = 100;
  f.height = 50;
  Camera c = make_camera(p, f);
  vec3 tl = camera_dir(c, {0.0f, 0.0f}), br = camera_dir(c, {100.0f, 50.0f});
  EXPECT_NEAR(tl.x / tl.z, -0.5f, 1e-5f);
  EXPECT_NEAR(tl.y / tl.z, 0.25f, 1e-5f);
  EXPECT_NEAR(br.x / br.z, 1.5f, 1e-5f);
  EXPECT_NEAR(br.y / br.z, -1.0f, 1e-5f);
  std::swap(p.screen_window[0], p.screen_window[1]);
  EXPECT_THROW(make_camera(p, f), Error);
}

TEST(Camera, ThinLensRaysConvergeOnThePlaneOfFocus) {
  CameraParams p;
  p.fov = 50.0f;
  p.lens_radius = 0.25f;
  p.focal_distance = 7.0f;
  p.render_from_camera = look_at(vec3(1, 2, 3), vec3(0, 0, 0), vec3(0, 0, 1));
  FilmParams f;
  f.width = 200;
  f.height = 100;
  Camera c = make_camera(p, f);
  Camera pin = c;
  pin.lens_radius = 0.0f;
  for (vec2 film : {vec2(100, 50), vec2(13.5f, 80.25f), vec2(199, 1)}) {
    Ray chief = generate_camera_ray(pin, film, vec2(0.5f));
    // The pinhole ray meets the plane of focus (camera z = focal distance) here.
    vec3 focus = chief.o + chief.d * (p.focal_distance / glm::dot(chief.d, glm::normalize(p.render_from_camera.vector(vec3(0, 0, 1)))));
    float max_spread = 0.0f;
    for (int i = 0; i < 64; ++i) {
      vec2 u((i % 8 + 0.5f) / 8.0f, (i / 8 + 0.5f) / 8.0f);
      Ray r = generate_camera_ray(c, film, u);
      EXPECT_NEAR(glm::length(r.d), 1.0f, 1e-5f);
      vec3 lens = p.render_from_camera.inverse().point(r.o);
      EXPECT_NEAR(lens.z, 0.0f, 1e-5f);
      EXPECT_LE(glm::length(vec2(lens)), p.lens_radius * 1.0001f);
      max_spread = std::max(max_spread, glm::length(vec2(lens)));
      // Distance from the focus point to the ray's line.
      vec3 to_focus = focus - r.o;
      float miss = glm::length(to_focus - r.d * glm::dot(to_focus, r.d));
      EXPECT_LT(miss, 1e-4f * glm::length(to_focus)) << film.x << " " << film.y << " " << i;
    }
    EXPECT_GT(max_spread, 0.2f);  // the rays really leave from across the lens
  }
}

TEST(Camera, RejectsImpossibleParameters) {
  CameraParams p;
  FilmParams f;
  p.fov = 0.0f;
  EXPECT_THROW(make_camera(p, f), Error);
  p.fov = 180.0f;
  EXPECT_THROW(make_camera(p, f), Error);
  p.fov = 45.0f;
  f.height = 0;
  EXPECT_THROW(make_camera(p, f), Error);
  f.height = 10;
  p.lens_radius = -1.0f;
  EXPECT_THROW(make_camera(p, f), Error);
  p.lens_radius = 0.1f;
  p.focal_distance = 0.0f;
  EXPECT_THROW(make_camera(p, f), Error);
}
