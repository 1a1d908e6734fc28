// End-to-end renders of the light kinds against closed forms: a furnace under
// a constant environment image equals the constant-L furnace; spot and
// distant lights on a diffuse plane; an alpha cut-out casts no shadow where
// alpha is zero; area-light emission images seen directly, and a diffuse
// plane under pbrt-v4's per-triangle "power"; projection and goniometric
// lights on a diffuse plane.
#include "render_helpers.h"
#include "core/sampling.h"
#include "scene/camera.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

using namespace theia;
using namespace theia::test;

namespace {

// Replaces light 0's constant L by an in-memory w x h image of that value.
void make_environment_image(Scene& scene, int w, int h) {
  Light& l = scene.lights[0];
  Image img;
  img.width = w;
  img.height = h;
  img.channels = 3;
  for (int i = 0; i < w * h; ++i) img.pixels.insert(img.pixels.end(), {l.L.x, l.L.y, l.L.z});
  scene.images.push_back(std::move(img));
  l.image = int(scene.images.size()) - 1;
  l.L = RGB(1.0f);
}

const char* kFurnace = R"(
    Film "rgb" "integer xresolution" [24] "integer yresolution" [24]
    LookAt 0 0 -5  0 0 0  0 1 0
    Camera "perspective" "float fov" [30]
    WorldBegin
    AttributeBegin
    Rotate 30 1 1 0
    LightSource "infinite" "rgb L" [0.7 0.8 0.9]
    AttributeEnd
    Material "diffuse" "rgb reflectance" [1 1 1]
    Shape "sphere" "float radius" [1]
  )";

}  // namespace

// A diffuse sphere of albedo 1 under a constant environment image: every
// path ends in the environment, so every pixel equals the constant, whichever
// parameterisation the image uses.
TEST(EnvironmentFurnace, ConstantImageEqualsConstantL) {
  Scene constant = load_test_scene(kFurnace);
  RGB ref = image_mean(render_scene(constant, quick_config(32)).image);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(ref[c], 0.7f + 0.1f * float(c), 0.005f);
  for (ivec2 size : {ivec2(16, 16), ivec2(32, 16)}) {
    Scene scene = load_test_scene(kFurnace);
    make_environment_image(scene, size.x, size.y);
    RenderResult r = render_scene(scene, quick_config(32));
    RGB mean = image_mean(r.image);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], ref[c], 0.005f) << size.x << "x" << size.y << " channel " << c;
    // One pixel at 32 spp: MIS of light and BSDF samples leaves ~4% noise.
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(pixel_channel(r.image, 12, 12, c), ref[c], 0.1f);
    EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
  }
}

// Spot light straight above a diffuse plane: L = rho / pi * I * cos / d^2
// inside the inner cone (the camera sees only that part).
TEST(Analytic, DiffusePlaneUnderSpotLight) {
  const float rho = 0.5f, I = 6.0f, h = 2.0f;
  Scene scene = load_test_scene(R"(
    Film "rgb" "integer xresolution" [32] "integer yresolution" [32]
    PixelFilter "box" "float xradius" [0.5] "float yradius" [0.5]
    LookAt 0 5 0  0 0 0  0 0 1
    Camera "perspective" "float fov" [20]
    WorldBegin
    LightSource "spot" "rgb I" [6 6 6] "point3 from" [0 2 0] "point3 to" [0 0 0]
      "float coneangle" 60 "float conedeltaangle" 5
    Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
    Shape "trianglemesh" "point3 P" [-10 0 -10  10 0 -10  10 0 10  -10 0 10]
      "integer indices" [0 1 2 0 2 3]
  )");
  RenderResult r = render_scene(scene, quick_config(16));
  Camera cam = make_camera(scene.camera, scene.film);
  double worst = 0.0;
  for (int y = 2; y < 32; y += 3)
    for (int x = 2; x < 32; x += 3) {
      vec3 p = pixel_on_plane(cam, x, y);
      vec3 to_light = vec3(0.0f, h, 0.0f) - p;
      float d2 = glm::dot(to_light, to_light);
      float expected = rho / kPi * I * (h / std::sqrt(d2)) / d2;
      worst = std::max(worst, double(std::abs(pixel_channel(r.image, x, y, 1) - expected) / expected));
    }
  EXPECT_LT(worst, 0.01);
}

// A distant light at 45 degrees on a diffuse plane: L = rho / pi * E cos(45).
TEST(Analytic, DiffusePlaneUnderDistantLight) {
  Scene scene = load_test_scene(R"(
    Film "rgb" "integer xresolution" [16] "integer yresolution" [16]
    LookAt 0 5 0  0 0 0  0 0 1
    Camera "perspective" "float fov" [20]
    WorldBegin
    LightSource "distant" "rgb L" [3 3 3] "point3 from" [1 1 0] "point3 to" [0 0 0]
    Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
    Shape "trianglemesh" "point3 P" [-10 0 -10  10 0 -10  10 0 10  -10 0 10]
      "integer indices" [0 1 2 0 2 3]
  )");
  RenderResult r = render_scene(scene, quick_config(4));
  const float expected = 0.5f / kPi * 3.0f * std::sqrt(0.5f);
  for (int y = 0; y < 16; y += 5)
    for (int x = 0; x < 16; x += 5) EXPECT_NEAR(pixel_channel(r.image, x, y, 0), expected, 1e-3f * expected);
}

// A checkerboard-alpha quad between a distant light and a plane: the camera
// sees the plane through the cells where alpha is zero, and the plane is lit
// exactly where its shadow ray crosses such a cell.
TEST(AlphaCutout, ShadowRaysPassWhereAlphaIsZero) {
  Scene scene = load_test_scene(R"(
    Film "rgb" "integer xresolution" [32] "integer yresolution" [32]
    PixelFilter "box" "float xradius" [0.5] "float yradius" [0.5]
    LookAt 0 5 0  0 0 0  0 0 1
    Camera "perspective" "float fov" [20]
    WorldBegin
    LightSource "distant" "rgb L" [3 3 3] "point3 from" [0.7 1 0.3] "point3 to" [0 0 0]
    Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
    Shape "trianglemesh" "point3 P" [-10 0 -10  10 0 -10  10 0 10  -10 0 10]
      "integer indices" [0 1 2 0 2 3]
    Texture "checks" "float" "checkerboard" "float uscale" 4 "float vscale" 4 "float tex1" 1 "float tex2" 0
    Material "diffuse" "rgb reflectance" [0 0 0]
    Shape "trianglemesh" "point3 P" [-2 0.5 -2  2 0.5 -2  2 0.5 2  -2 0.5 2] "point2 uv" [0 0 1 0 1 1 0 1]
      "integer indices" [0 1 2 0 2 3] "texture alpha" "checks"
  )");
  RenderResult r = render_scene(scene, quick_config(4));
  Camera cam = make_camera(scene.camera, scene.film);
  const vec3 wl = glm::normalize(vec3(0.7f, 1.0f, 0.3f));
  const float lit = 0.5f / kPi * 3.0f * wl.y;
  int n_lit = 0, n_dark = 0;
  for (int y = 1; y < 32; y += 2)
    for (int x = 1; x < 32; x += 2) {
      // Where the central camera ray crosses the cut-out (y = 0.5) and the plane (y = 0).
      vec3 q = pixel_on_plane(cam, x, y, 0.5f), p = pixel_on_plane(cam, x, y);
      auto cell = [](vec3 v) {
        vec2 uv((v.x + 2.0f) / 4.0f, (v.z + 2.0f) / 4.0f);
        vec2 f = glm::fract(uv * 4.0f);
        bool near_edge = glm::any(glm::lessThan(glm::min(f, 1.0f - f), vec2(0.15f)));
        return near_edge ? -1 : (int(std::floor(4 * uv.x)) + int(std::floor(4 * uv.y))) % 2;
      };
      vec3 s = p + (0.5f / wl.y) * wl;  // where the shadow ray crosses the cut-out
      int cq = cell(q), cp = cell(s);
      if (cq < 0 || cp < 0) continue;
      float v = pixel_channel(r.image, x, y, 0);
      if (cq == 0) {
        EXPECT_NEAR(v, 0.0f, 1e-6f) << x << " " << y;  // the black, opaque part of the cut-out
      } else if (cp == 0) {
        EXPECT_NEAR(v, 0.0f, 1e-6f) << x << " " << y;  // seen through a hole, in the shadow of a solid cell
        ++n_dark;
      } else {
        EXPECT_NEAR(v, lit, 1e-3f * lit) << x << " " << y;  // through a hole, lit through the hole above
        ++n_lit;
      }
    }
  EXPECT_GT(n_lit, 5);
  EXPECT_GT(n_dark, 5);
}

// An emitting quad whose "filename" is a 2 x 1 image (left and right texels)
// seen straight on: where the bilinear lookup is flat (u < 1/4, u > 3/4),
// every pixel is "scale" times its texel, at any sample count.
TEST(AreaLightImage, PixelsSeeingTheEmitterEqualItsTexels) {
  test::TempDir tmp;
  const RGB texel[2] = {RGB(0.9f, 0.2f, 0.1f), RGB(0.1f, 0.3f, 1.5f)};
  ImageBuffer two(2, 1, {"R", "G", "B"});
  for (int x = 0; x < 2; ++x)
    for (int c = 0; c < 3; ++c) two.at(x, 0, c) = texel[x][c];
  write_exr(tmp.file("two.exr"), two);
  Scene scene = parse_scene_string(R"(
    Film "rgb" "integer xresolution" [32] "integer yresolution" [16]
    PixelFilter "box" "float xradius" [0.5] "float yradius" [0.5]
    LookAt 0 0 5  0 0 0  0 1 0
    Camera "perspective" "float fov" [20]
    WorldBegin
    AreaLightSource "diffuse" "string filename" "two.exr" "float scale" 2
    Shape "trianglemesh" "point3 P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] "point2 uv" [0 0 1 0 1 1 0 1]
      "integer indices" [0 1 2 0 2 3]
  )", tmp.file("t.pbrt"), tmp.path.string());
  load_images(scene);
  RenderResult r = render_scene(scene, quick_config(4));
  Camera cam = make_camera(scene.camera, scene.film);
  int checked[2] = {0, 0};
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 32; ++x) {
      Ray ray = generate_camera_ray(cam, vec2(float(x) + 0.5f, float(y) + 0.5f), vec2(0.5f));
      vec3 p = ray.o - (ray.o.z / ray.d.z) * ray.d;  // on the quad's plane, z = 0
      vec2 uv((p.x + 1.0f) / 2.0f, (p.y + 1.0f) / 2.0f);
      // A pixel is about 0.06 in uv: keep whole pixels inside the flat parts of the quad.
      if (uv.y < 0.1f || uv.y > 0.9f) continue;
      int side = uv.x > 0.06f && uv.x < 0.19f ? 0 : uv.x > 0.81f && uv.x < 0.94f ? 1 : -1;
      if (side < 0) continue;
      RGB got = pixel_rgb(r.image, x, y), want = 2.0f * texel[side];
      EXPECT_NEAR(glm::length(got - want), 0.0f, 1e-4f * glm::length(want)) << x << " " << y;
      ++checked[side];
    }
  EXPECT_GE(checked[0], 8);
  EXPECT_GE(checked[1], 8);
}

// Two facing-down emitters of areas 1 and 0.25 in one mesh with "power" phi,
// outside the view, above a diffuse plane.  pbrt-v4 gives each triangle the
// power, so triangle i has radiance phi / (pi A_i) and the plane shows
// rho / pi * sum_i L_i * integral over T_i of cos cos / r^2 = 1 / r^4 (both
// cosines are h / r, h = 1), integrated here by a fine midpoint rule.
TEST(AreaLightPower, DiffusePlaneUnderUnequalTrianglesMatchesPerTrianglePower) {
  const float rho = 0.5f, phi = 10.0f;
  Scene scene = load_test_scene(R"(
    Film "rgb" "integer xresolution" [24] "integer yresolution" [24]
    PixelFilter "box" "float xradius" [0.5] "float yradius" [0.5]
    LookAt 0 6 0  0 0 0  0 0 1
    Camera "perspective" "float fov" [30]
    WorldBegin
    AttributeBegin
    Material "diffuse" "rgb reflectance" [0 0 0]
    AreaLightSource "diffuse" "float power" 10
    Shape "trianglemesh" "point3 P" [2 1 -0.5  3 1 -0.5  2 1 1.5   -2.5 1 -0.5  -2 1 -0.5  -2 1 0.5]
      "integer indices" [0 1 2 3 4 5]
    AttributeEnd
    Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
    Shape "trianglemesh" "point3 P" [-10 0 -10  10 0 -10  10 0 10  -10 0 10]
      "integer indices" [0 1 2 0 2 3]
  )");
  const vec3 tri[2][3] = {{vec3(2, 1, -0.5f), vec3(3, 1, -0.5f), vec3(2, 1, 1.5f)},
                          {vec3(-2.5f, 1, -0.5f), vec3(-2, 1, -0.5f), vec3(-2, 1, 0.5f)}};
  const float area[2] = {1.0f, 0.25f};
  auto predicted = [&](const vec3& p) {
    double e = 0.0;
    const int n = 48;
    for (int t = 0; t < 2; ++t) {
      double sum = 0.0;
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
          vec2 b = sample_uniform_triangle(vec2((float(i) + 0.5f) / n, (float(j) + 0.5f) / n));
          vec3 q = b.x * tri[t][0] + b.y * tri[t][1] + (1.0f - b.x - b.y) * tri[t][2];
          sum += 1.0 / sqr(double(glm::dot(q - p, q - p)));
        }
      e += double(phi / (kPi * area[t])) * sum / double(n * n) * area[t];
    }
    return rho / kPi * e;
  };
  RenderResult r = render_scene(scene, quick_config(64));
  Camera cam = make_camera(scene.camera, scene.film);
  // Sums over columns near each emitter and between them: each resolves the
  // triangles' radiances (the mean-area radiance would be 1.6x too bright on
  // the large triangle's side, 0.4x on the small one's); one pixel at 64 spp
  // is noisy to ~10%, a sum over 150 to ~1%.
  expect_region_sums_match(
      r.image, cam, 3, [](vec3 p) { return p.x > 0.8f ? 0 : p.x < -0.8f ? 1 : 2; }, predicted, 0.01,
      {"large", "small", "middle"});
  EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
}

// A projection light of a 2 x 2 colour image pointing down from (0, 2, 0)
// with the CTM's +y (the image's top) along render +z: the plane shows the
// four texels in their quadrants, L = rho / pi * scale * texel * cos / d^2,
// and nothing outside the 30 degree frustum (|x|, |z| > 2 tan 15).
TEST(Analytic, DiffusePlaneUnderProjectionLightShowsTheImageQuadrants) {
  test::TempDir tmp;
  // Row 0 is the image's top: red, green / blue, yellow.
  const RGB texel[2][2] = {{RGB(0.9f, 0.1f, 0.1f), RGB(0.1f, 0.8f, 0.2f)},
                           {RGB(0.1f, 0.2f, 0.9f), RGB(0.8f, 0.7f, 0.1f)}};
  ImageBuffer quad(2, 2, {"R", "G", "B"});
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 2; ++x)
      for (int c = 0; c < 3; ++c) quad.at(x, y, c) = texel[y][x][c];
  write_exr(tmp.file("quad.exr"), quad);
  Scene scene = parse_scene_string(R"(
    Film "rgb" "integer xresolution" [32] "integer yresolution" [32]
    PixelFilter "box" "float xradius" [0.5] "float yradius" [0.5]
    LookAt 0 5 0  0 0 0  0 0 1
    Camera "perspective" "float fov" [20]
    WorldBegin
    AttributeBegin
    Translate 0 2 0
    Rotate 90 1 0 0
    LightSource "projection" "string filename" "quad.exr" "float fov" 30 "float scale" 3
    AttributeEnd
    Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
    Shape "trianglemesh" "point3 P" [-10 0 -10  10 0 -10  10 0 10  -10 0 10]
      "integer indices" [0 1 2 0 2 3]
  )", tmp.file("t.pbrt"), tmp.path.string());
  load_images(scene);
  RenderResult r = render_scene(scene, quick_config(4));
  Camera cam = make_camera(scene.camera, scene.film);
  const float edge = 2.0f * std::tan(radians(15.0f)), margin = 0.06f;  // a pixel is 0.055 wide on the plane
  int checked[2][2] = {{0, 0}, {0, 0}}, dark = 0;
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 32; ++x) {
      vec3 p = pixel_on_plane(cam, x, y);
      float ax = std::abs(p.x), az = std::abs(p.z);
      if (std::abs(ax - edge) < margin || std::abs(az - edge) < margin || ax < margin || az < margin) continue;
      RGB got = pixel_rgb(r.image, x, y);
      if (ax > edge || az > edge) {
        EXPECT_EQ(got, RGB(0.0f)) << x << " " << y;
        ++dark;
        continue;
      }
      int tx = p.x > 0.0f ? 1 : 0, ty = p.z > 0.0f ? 0 : 1;  // +z is the image's top
      vec3 d = vec3(0, 2, 0) - p;
      float d2 = glm::dot(d, d);
      RGB want = 0.5f / kPi * 3.0f * texel[ty][tx] * (2.0f / std::sqrt(d2)) / d2;
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], want[c], 0.01f * want[c]) << x << " " << y << " channel " << c;
      ++checked[ty][tx];
    }
  for (int q = 0; q < 4; ++q) EXPECT_GE(checked[q / 2][q % 2], 8) << "quadrant " << q;
  EXPECT_GE(dark, 100);
  EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
}

// A goniometric light with a constant white image is a point light: every
// pixel of the point light's analytic test (tests/e2e/test_estimators.cpp),
// L = rho / pi * I * cos / d^2, with the light placed and turned by the CTM;
// and the same render as that point light's.
TEST(Analytic, DiffusePlaneUnderConstantGoniometricLight) {
  test::TempDir tmp;
  write_exr(tmp.file("white.exr"), ImageBuffer(16, 16, {"R", "G", "B"}, 1.0f));
  const float rho = 0.8f, I = 10.0f;
  const vec3 light(0.5f, 2.0f, 0.25f);
  auto render = [&](const std::string& light_source) {
    Scene scene = parse_scene_string(R"(
      Film "rgb" "integer xresolution" [64] "integer yresolution" [64]
      PixelFilter "box" "float xradius" [0.5] "float yradius" [0.5]
      LookAt 0 4 0  0 0 0  0 0 1
      Camera "perspective" "float fov" [40]
      WorldBegin
      Material "diffuse" "rgb reflectance" [0.8 0.8 0.8]
      Shape "trianglemesh" "point3 P" [-10 0 -10  10 0 -10  10 0 10  -10 0 10] "integer indices" [0 1 2 0 2 3]
    )" + light_source, tmp.file("t.pbrt"), tmp.path.string());
    load_images(scene);
    return std::make_pair(render_scene(scene, quick_config(16)).image, make_camera(scene.camera, scene.film));
  };
  auto [gonio, cam] = render(R"(Translate 0.5 2 0.25
    Rotate 35 1 0 1
    LightSource "goniometric" "rgb I" [10 10 10] "string filename" "white.exr")");
  ImageBuffer predicted(gonio.width, gonio.height, {"R", "G", "B"});
  for (int y = 0; y < gonio.height; ++y)
    for (int x = 0; x < gonio.width; ++x) {
      vec3 d = light - pixel_on_plane(cam, x, y);
      float d2 = glm::dot(d, d);
      for (int c = 0; c < 3; ++c) predicted.at(x, y, c) = rho / kPi * I * (d.y / std::sqrt(d2)) / d2;
    }
  // The pixel footprint averages a smooth function: agreement to well under 1%.
  EXPECT_LT(max_relative_difference(gonio, predicted), 0.01);
  ImageBuffer point = render(R"(LightSource "point" "rgb I" [10 10 10] "point3 from" [0.5 2 0.25])").first;
  EXPECT_LT(max_relative_difference(gonio, point), 1e-5);
}
