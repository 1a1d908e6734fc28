#include "core/log.h"
#include "core/sampling.h"
#include "core/sampler.h"
#include "scene/camera.h"
#include "tests/unit/chi2.h"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <cstring>
#include <span>
#include <vector>

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

FilmParams film_of(int w, int h) {
  FilmParams f;
  f.width = w;
  f.height = h;
  return f;
}

Camera pinhole(int w, int h, float fov, Transform render_from_camera = {}) {
  CameraParams c;
  c.fov = fov;
  c.render_from_camera = render_from_camera;
  return make_camera(c, film_of(w, h));
}

// A thin-lens camera at (1, 2, 3) looking at the origin, z up.
CameraParams thin_lens(CameraKind kind, float lens_radius, float focal_distance) {
  CameraParams p;
  p.kind = kind;
  p.fov = 50.0f;
  p.lens_radius = lens_radius;
  p.focal_distance = focal_distance;
  p.render_from_camera = look_at(vec3(1, 2, 3), vec3(0, 0, 0), vec3(0, 0, 1));
  return p;
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
  CameraParams p = thin_lens(CameraKind::Perspective, 0.25f, 7.0f);
  Camera c = make_camera(p, film_of(200, 100));
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

// ---------------------------------------------------------------- orthographic

namespace {

Camera orthographic(int w, int h, Transform render_from_camera = {}, const float* window = nullptr) {
  CameraParams p;
  p.kind = CameraKind::Orthographic;
  p.fov = 0.0f;  // not an orthographic parameter: must not be checked
  p.render_from_camera = render_from_camera;
  if (window) {
    p.has_screen_window = true;
    std::copy(window, window + 4, p.screen_window);
  }
  return make_camera(p, film_of(w, h));
}

Camera spherical(int w, int h, SphericalMapping mapping, Transform render_from_camera = {}) {
  CameraParams p;
  p.kind = CameraKind::Spherical;
  p.mapping = mapping;
  p.render_from_camera = render_from_camera;
  return make_camera(p, film_of(w, h));
}

}  // namespace

TEST(Camera, OrthographicPixelCentresMapToTheScreenWindow) {
  Transform rt(glm::translate(mat4(1.0f), vec3(1, -2, 3)) * glm::rotate(mat4(1.0f), 0.7f, glm::normalize(vec3(1, 2, 3))));
  const float sw[4] = {-0.5f, 1.5f, -1.0f, 0.25f};
  Camera c = orthographic(40, 20, rt, sw);
  const vec3 forward = rt.vector(vec3(0, 0, 1));
  for (int y = 0; y < 20; y += 3)
    for (int x = 0; x < 40; x += 7) {
      Ray r = generate_camera_ray(c, vec2(x + 0.5f, y + 0.5f), vec2(0.5f));
      vec3 o = rt.inverse().point(r.o);
      // Raster x runs from xmin to xmax, raster y from ymax down to ymin.
      EXPECT_NEAR(o.x, sw[0] + (x + 0.5f) / 40.0f * (sw[1] - sw[0]), 1e-5f);
      EXPECT_NEAR(o.y, sw[3] - (y + 0.5f) / 20.0f * (sw[3] - sw[2]), 1e-5f);
      EXPECT_NEAR(o.z, 0.0f, 1e-5f);
      EXPECT_NEAR(glm::length(r.d - forward), 0.0f, 1e-6f);
    }
  // Without a window the shorter axis spans [-1, 1], as for perspective.
  Camera wide = orthographic(400, 200);
  EXPECT_NEAR(generate_camera_ray(wide, vec2(0.0f, 0.0f), vec2(0.5f)).o.x, -2.0f, 1e-6f);
  EXPECT_NEAR(generate_camera_ray(wide, vec2(0.0f, 0.0f), vec2(0.5f)).o.y, 1.0f, 1e-6f);
  EXPECT_NEAR(generate_camera_ray(wide, vec2(400.0f, 200.0f), vec2(0.5f)).o.x, 2.0f, 1e-6f);
  Camera tall = orthographic(100, 400);
  EXPECT_NEAR(generate_camera_ray(tall, vec2(100.0f, 0.0f), vec2(0.5f)).o.y, 4.0f, 1e-6f);
  const float bad[4] = {1.0f, -1.0f, -1.0f, 1.0f};
  EXPECT_THROW(orthographic(10, 10, {}, bad), Error);
}

TEST(Camera, ThinLensOrthographicFocuses) {
  CameraParams p = thin_lens(CameraKind::Orthographic, 0.3f, 5.0f);
  Camera c = make_camera(p, film_of(64, 32));
  Camera pin = make_camera(thin_lens(CameraKind::Orthographic, 0.0f, 5.0f), film_of(64, 32));
  const Transform camera_from_render = p.render_from_camera.inverse();
  for (vec2 film : {vec2(32, 16), vec2(3.5f, 30.25f), vec2(63, 1)}) {
    // The pinhole ray leaves the film point along +z; every lens ray meets it
    // at the plane of focus.
    vec3 o = camera_from_render.point(generate_camera_ray(pin, film, vec2(0.5f)).o);
    vec3 focus = o + vec3(0, 0, p.focal_distance);
    float max_spread = 0.0f;
    for (int i = 0; i < 64; ++i) {
      vec2 u((i % 8 + 0.5f) / 8.0f, (i / 8 + 0.5f) / 8.0f);
      Ray r = generate_camera_ray(c, film, u);
      vec3 ro = camera_from_render.point(r.o), rd = camera_from_render.vector(r.d);
      EXPECT_NEAR(ro.z, 0.0f, 1e-5f);
      EXPECT_LE(glm::length(vec2(ro)), p.lens_radius * 1.0001f);  // pbrt-v4: the lens is centred on the camera origin
      max_spread = std::max(max_spread, glm::length(vec2(ro)));
      vec3 at_focus = ro + rd * ((focus.z - ro.z) / rd.z);
      EXPECT_NEAR(glm::length(at_focus - focus), 0.0f, 1e-4f) << film.x << " " << film.y << " " << i;
    }
    EXPECT_GT(max_spread, 0.25f);
  }
}

// ---------------------------------------------------------------- spherical

// pbrt-v4's SphericalCamera::GenerateRay, equirectangular: theta = pi v,
// phi = 2 pi u, (sin theta cos phi, sin theta sin phi, cos theta) with y and z swapped.
TEST(Camera, SphericalEquirectangularIsPbrtsMapping) {
  Transform rt(glm::rotate(mat4(1.0f), 1.1f, glm::normalize(vec3(-1, 2, 0.5f))));
  const int W = 48, H = 24;
  Camera c = spherical(W, H, SphericalMapping::Equirectangular, rt);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      vec2 pf(x + 0.5f, y + 0.5f);
      double theta = kPi * pf.y / H, phi = 2.0 * kPi * pf.x / W;
      vec3 want(float(std::sin(theta) * std::cos(phi)), float(std::cos(theta)), float(std::sin(theta) * std::sin(phi)));
      Ray r = generate_camera_ray(c, pf, vec2(0.3f, 0.9f));
      EXPECT_NEAR(glm::length(r.o), 0.0f, 1e-6f);
      ASSERT_NEAR(glm::length(rt.inverse().vector(r.d) - want), 0.0f, 2e-6f) << x << " " << y;
      // And back: the direction's raster point is the pixel centre.
      vec2 back = spherical_camera_raster(c, want);
      EXPECT_NEAR(back.x, pf.x, 2e-4f * W);
      EXPECT_NEAR(back.y, pf.y, 2e-4f * H);
    }
  // Across the image's side edge phi wraps around; past the top, theta goes over the pole.
  EXPECT_NEAR(glm::length(spherical_camera_direction(c, vec2(-0.5f, 7.0f)) -
                          spherical_camera_direction(c, vec2(W - 0.5f, 7.0f))), 0.0f, 1e-5f);
}

// Equal-area: pbrt-v4 wraps the raster point onto the square, applies
// EqualAreaSquareToSphere and swaps y and z: the image centre looks along
// camera +y, the corners along -y, the mid-edges along -z, +x, +z, -x.
TEST(Camera, SphericalEqualAreaIsPbrtsMapping) {
  const int W = 40, H = 40;
  Camera c = spherical(W, H, SphericalMapping::EqualArea);
  auto dir = [&](float u, float v) { return spherical_camera_direction(c, vec2(u * W, v * H)); };
  EXPECT_NEAR(glm::length(dir(0.5f, 0.5f) - vec3(0, 1, 0)), 0.0f, 1e-6f);
  for (vec2 corner : {vec2(0, 0), vec2(1, 0), vec2(0, 1), vec2(1, 1)})
    EXPECT_NEAR(glm::length(dir(corner.x, corner.y) - vec3(0, -1, 0)), 0.0f, 1e-6f);
  EXPECT_NEAR(glm::length(dir(0.5f, 0.0f) - vec3(0, 0, -1)), 0.0f, 1e-6f);
  EXPECT_NEAR(glm::length(dir(1.0f, 0.5f) - vec3(1, 0, 0)), 0.0f, 1e-6f);
  EXPECT_NEAR(glm::length(dir(0.5f, 1.0f) - vec3(0, 0, 1)), 0.0f, 1e-6f);
  EXPECT_NEAR(glm::length(dir(0.0f, 0.5f) - vec3(-1, 0, 0)), 0.0f, 1e-6f);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      vec2 pf(x + 0.5f, y + 0.5f);
      vec3 s = equal_area_square_to_sphere(pf / vec2(W, H));
      vec3 d = generate_camera_ray(c, pf, vec2(0.5f)).d;
      ASSERT_NEAR(glm::length(d - vec3(s.x, s.z, s.y)), 0.0f, 1e-6f) << x << " " << y;
      vec2 back = spherical_camera_raster(c, d);
      EXPECT_NEAR(glm::length(back - pf), 0.0f, 2e-3f) << x << " " << y;
    }
  // A filter offset past an edge continues across it on the sphere (pbrt-v4's
  // WrapEqualAreaSquare): just outside the left edge is just inside it, mirrored.
  EXPECT_NEAR(glm::length(dir(-0.01f, 0.3f) - dir(0.01f, 0.7f)), 0.0f, 1e-5f);
  EXPECT_NEAR(glm::length(dir(0.3f, 1.01f) - dir(0.7f, 0.99f)), 0.0f, 1e-5f);
}

// Every direction is seen by exactly one raster point: directions -> raster
// -> directions is the identity, and uniformly distributed directions land
// on the image with the mapping's density (uniform for equal-area,
// pi/2 sin(pi v) for equirectangular), which a chi-square test checks.
TEST(Camera, SphericalCamerasCoverEveryDirectionOnce) {
  for (SphericalMapping m : {SphericalMapping::EqualArea, SphericalMapping::Equirectangular}) {
    Camera c = spherical(64, 32, m);
    for (uint32_t i = 0; i < 20000; ++i) {
      vec3 d = sample_uniform_sphere(sample_2d({11, 0, i}, 0));
      vec2 r = spherical_camera_raster(c, d);
      ASSERT_TRUE(r.x >= 0.0f && r.x <= 64.0f && r.y >= 0.0f && r.y <= 32.0f);
      ASSERT_NEAR(glm::length(spherical_camera_direction(c, r) - d), 0.0f, 2e-4f) << int(m) << " " << i;
    }
    auto sample = [&](vec2 u, float) { return std::optional(spherical_camera_raster(c, sample_uniform_sphere(u)) / vec2(64, 32)); };
    auto pdf = [&](vec2 p) { return m == SphericalMapping::EqualArea ? 1.0 : kPi / 2.0 * std::sin(kPi * double(p.y)); };
    Chi2Result r = chi2_test(m == SphericalMapping::EqualArea ? "equal-area" : "equirectangular", sample, pdf, 400'000,
                             32, 16, 0.01, 2);
    EXPECT_TRUE(r.passed) << r.report;
  }
}

// ---------------------------------------------------------------- footprints

// An orthographic pixel is the same patch of a plane wherever the plane is:
// dp/dx and dp/dy are the pixel's width and height on a plane facing the
// camera at any distance and offset, and stretch by 1/cos on a tilted one.
TEST(Camera, OrthographicFootprintIsConstantPerPixel) {
  Transform rt = look_at(vec3(0, 0, -10), vec3(0, 0, 0), vec3(0, 1, 0));
  const float sw[4] = {-2.0f, 2.0f, -1.0f, 1.0f};
  Camera c = orthographic(80, 40, rt, sw);
  const float pixel = 4.0f / 80.0f;
  const vec3 n_facing = rt.vector(vec3(0, 0, -1));
  const vec3 n_tilted = rt.vector(glm::normalize(vec3(0, std::sin(radians(60.0f)), -std::cos(radians(60.0f)))));
  for (vec3 pc : {vec3(0, 0, 3), vec3(1.7f, -0.8f, 20), vec3(-1.9f, 0.9f, 0.5f)}) {
    vec3 p = rt.point(pc), dpdx, dpdy;
    approximate_dp_dxy(c, p, n_facing, 0.5f, dpdx, dpdy);
    EXPECT_NEAR(glm::length(dpdx - 0.5f * pixel * rt.vector(vec3(1, 0, 0))), 0.0f, 1e-5f);
    EXPECT_NEAR(glm::length(dpdy + 0.5f * pixel * rt.vector(vec3(0, 1, 0))), 0.0f, 1e-5f);  // raster y runs down
    approximate_dp_dxy(c, p, n_tilted, 1.0f, dpdx, dpdy);
    EXPECT_NEAR(glm::length(dpdx), pixel, 1e-5f);
    EXPECT_NEAR(glm::length(dpdy), 2.0f * pixel, 2e-5f);
  }
  // Edge-on: no footprint rather than infinity.
  vec3 dpdx, dpdy;
  approximate_dp_dxy(c, rt.point(vec3(0, 0, 3)), rt.vector(vec3(0, 1, 0)), 1.0f, dpdx, dpdy);
  EXPECT_EQ(dpdy, vec3(0.0f));
}

// A spherical camera's pixel is a fixed solid angle (equal-area: 4 pi / (W H)
// everywhere) or angle (equirectangular: 2 pi / W sin(theta) by pi / H): on a
// sphere of radius R around the camera, dp/dx and dp/dy span R^2 times that.
TEST(Camera, SphericalFootprintIsThePixelsAngle) {
  const float R = 3.0f;
  Transform rt(glm::translate(mat4(1.0f), vec3(2, -1, 0.5f)));
  Camera ea = spherical(64, 64, SphericalMapping::EqualArea, rt);
  // Raster points 0.07 pixel or more off the map's fold lines (x, y = 32 and
  // the diagonals through the mid-edges), where its derivative jumps.
  for (vec2 pf : {vec2(10.3f, 20.6f), vec2(40.3f, 5.6f), vec2(50.3f, 50.6f), vec2(31.3f, 33.6f), vec2(2.3f, 60.6f)}) {
    vec3 w = spherical_camera_direction(ea, pf), dpdx, dpdy;
    approximate_dp_dxy(ea, rt.point(R * w), rt.vector(-w), 1.0f, dpdx, dpdy);
    float area = glm::length(glm::cross(dpdx, dpdy));
    EXPECT_NEAR(area, R * R * 4.0f * kPi / (64.0f * 64.0f), 2e-3f * R * R * 4.0f * kPi / (64.0f * 64.0f))
        << pf.x << " " << pf.y;
  }
  Camera er = spherical(96, 48, SphericalMapping::Equirectangular, rt);
  for (vec2 pf : {vec2(10.5f, 24.0f), vec2(70.25f, 24.0f), vec2(33.5f, 8.5f), vec2(90.5f, 40.5f)}) {
    vec3 w = spherical_camera_direction(er, pf), dpdx, dpdy;
    approximate_dp_dxy(er, rt.point(R * w), rt.vector(-w), 0.5f, dpdx, dpdy);
    float sin_theta = std::sin(kPi * pf.y / 48.0f);
    EXPECT_NEAR(glm::length(dpdx), 0.5f * R * 2.0f * kPi / 96.0f * sin_theta, 2e-3f * R * 2.0f * kPi / 96.0f);
    EXPECT_NEAR(glm::length(dpdy), 0.5f * R * kPi / 48.0f, 2e-3f * R * kPi / 48.0f);
    EXPECT_NEAR(glm::dot(dpdx, dpdy), 0.0f, 1e-3f * glm::length(dpdx) * glm::length(dpdy) + 1e-7f);
  }
}

// The camera stage makes a block of rays at once (a pinhole's in vector
// lanes) and the caustic pass and tests one at a time: every camera kind's
// rays must be the same bit for bit, for points across the film and off its
// edges (a filter radius outside), in blocks of any length.
TEST(Camera, ABlockOfRaysIsEachRayBitForBit) {
  const Transform turned = look_at(vec3(1, 2, 3), vec3(0, 0, 0), vec3(0, 0, 1));
  std::vector<Camera> cameras{pinhole(160, 120, 40.0f, turned), pinhole(64, 200, 75.0f),
                              make_camera(thin_lens(CameraKind::Perspective, 0.25f, 7.0f), film_of(200, 100)),
                              make_camera(thin_lens(CameraKind::Orthographic, 0.0f, 1e6f), film_of(90, 50))};
  CameraParams spherical;
  spherical.kind = CameraKind::Spherical;
  cameras.push_back(make_camera(spherical, film_of(64, 32)));
  std::vector<vec2> p_film, u_lens;
  for (uint32_t i = 0; i < 100000; ++i) {
    const vec2 u = sample_2d({9, i / 256, i % 256}, 0), v = sample_2d({9, i / 256, i % 256}, 2);
    p_film.push_back(vec2(-1.5f, -1.5f) + u * vec2(203.0f, 203.0f));
    u_lens.push_back(v);
  }
  for (size_t c = 0; c < cameras.size(); ++c) {
    std::vector<Ray> block(p_film.size());
    for (size_t first = 0, len = 1; first < p_film.size(); first += len, len = len % 67 + 1) {
      const size_t m = std::min(len, p_film.size() - first);
      generate_camera_rays(cameras[c], std::span<const vec2>(p_film).subspan(first, m),
                           std::span<const vec2>(u_lens).subspan(first, m), std::span<Ray>(block).subspan(first, m));
    }
    size_t differ = 0;
    for (size_t i = 0; i < p_film.size(); ++i) {
      const Ray one = generate_camera_ray(cameras[c], p_film[i], u_lens[i]);
      differ += std::memcmp(&one, &block[i], sizeof(Ray)) != 0;
    }
    EXPECT_EQ(differ, 0u) << "camera " << c << ", " << p_film.size() << " rays";
  }
}
