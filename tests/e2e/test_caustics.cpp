// Directly seen caustics traced from the lights (wavefront/caustics.h): the
// light-traced estimate plus the camera paths that leave those paths out
// must converge to what path tracing alone converges to.
#include "core/metrics.h"
#include "render_helpers.h"
#include "scene/camera.h"

#include <gtest/gtest.h>

using namespace theia;
using namespace theia::test;

namespace {

const std::string kMirrorRoom = mirror_room_scene(32, 24, 0.1f);

RenderResult render(const Scene& scene, int spp, bool caustics, uint32_t seed = 0, int threads = 0) {
  RenderConfig c = quick_config(spp);
  c.caustics.enabled = caustics;
  c.seed = seed;
  c.threads = threads;
  return render_scene(scene, c);
}

// Mean of the green channel over the top (far floor) or bottom (near floor) half.
double half_mean(const ImageBuffer& img, bool bottom) {
  int y0 = bottom ? img.height / 2 : 0;
  double s = 0.0;
  for (int y = y0; y < y0 + img.height / 2; ++y)
    for (int x = 0; x < img.width; ++x) s += pixel_channel(img, x, y, 1);
  return s / (img.width * img.height / 2);
}

}  // namespace

TEST(Caustics, LightTracedCausticsConvergeToThePathTracedImage) {
  Scene scene = load_test_scene(kMirrorRoom);
  RenderResult pt = render(scene, 4096, false);
  RenderResult ca = render(scene, 256, true);
  ASSERT_TRUE(ca.log["caustics"]["traced"].get<bool>());
  EXPECT_EQ(ca.log["caustics"]["switched_off_after_passes"].get<int>(), -1);
  EXPECT_GT(ca.log["caustics"]["splats"].get<uint64_t>(), 10000u);
  RGB mp = image_mean(pt.image), mc = image_mean(ca.image);
  std::printf("mirror room: path traced 4096 spp (%.4f %.4f %.4f), with caustics 256 spp (%.4f %.4f %.4f)\n", mp.x,
              mp.y, mp.z, mc.x, mc.y, mc.z);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mc[c] / mp[c], 1.0, 0.01) << "channel " << c;
  // Where the light lands, not only how much.  The near floor sees the
  // ceiling at steep angles where the path traced reference itself is
  // noisy (+-1.5% between seeds at 4096 spp), hence its wider tolerance.
  EXPECT_NEAR(half_mean(ca.image, false) / half_mean(pt.image, false), 1.0, 0.01);
  EXPECT_NEAR(half_mean(ca.image, true) / half_mean(pt.image, true), 1.0, 0.04);
  EXPECT_EQ(ca.log["dropped_samples"].get<uint64_t>(), 0u);
  EXPECT_EQ(ca.log["caustics"]["dropped"].get<uint64_t>(), 0u);
}

// A light path's splat into a pixel counts as part of that pixel's camera
// sample of the same index, weighted by that sample's filter weight: under
// Mitchell's filter some weights are negative, and the estimate must still
// converge to the path tracer's image.
TEST(Caustics, SplatsTakeTheirCameraSamplesFilterWeightsNegativeLobesIncluded) {
  Scene scene = load_test_scene("PixelFilter \"mitchell\"\n" + kMirrorRoom);
  RenderResult pt = render(scene, 4096, false);
  RenderResult ca = render(scene, 256, true);
  ASSERT_GT(ca.log["caustics"]["splats"].get<uint64_t>(), 10000u);
  RGB mp = image_mean(pt.image), mc = image_mean(ca.image);
  std::printf("mirror room, Mitchell: path traced 4096 spp (%.4f %.4f %.4f), with caustics 256 spp (%.4f %.4f %.4f)\n",
              mp.x, mp.y, mp.z, mc.x, mc.y, mc.z);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mc[c] / mp[c], 1.0, 0.01) << "channel " << c;
  EXPECT_NEAR(half_mean(ca.image, false) / half_mean(pt.image, false), 1.0, 0.01);
  EXPECT_NEAR(half_mean(ca.image, true) / half_mean(pt.image, true), 1.0, 0.04);
}

// Splats add atomically in any order; the light paths themselves are a
// function of (seed, pixel, sample).
TEST(Caustics, ImageIndependentOfThreadCount) {
  Scene scene = load_test_scene(kMirrorRoom);
  RenderResult a = render(scene, 16, true, 0, 1), b = render(scene, 16, true, 0, 2);
  EXPECT_LT(max_relative_difference(a.image, b.image), 1e-4);
}

// Without a caster or with an unsupported camera the pass stays off and the
// image is the path tracer's, sample for sample.
TEST(Caustics, InactiveWithoutACasterAndTheImageIsUnchanged) {
  Scene scene = load_test_scene(mirror_room_scene(32, 24, 0.5f));
  RenderConfig c = quick_config(8);
  c.caustics.enabled = true;
  c.caustics.caster_roughness = 0.1f;
  RenderResult on = render_scene(scene, c), off = render(scene, 8, false);
  EXPECT_EQ(on.log["caustics"]["splats"].get<uint64_t>(), 0u);
  EXPECT_LT(max_relative_difference(on.image, off.image), 1e-6);
  // With a maximum depth of 1 no camera path reaches the light through the
  // ceiling, so the light tracer must not add those paths either.
  Scene shallow = load_test_scene(mirror_room_scene(32, 24, 0.1f));
  RenderConfig d1 = quick_config(8);
  d1.max_depth = 1;
  RenderResult a = render_scene(shallow, d1);
  d1.caustics.enabled = false;
  RenderResult b = render_scene(shallow, d1);
  EXPECT_FALSE(a.log["caustics"]["traced"].get<bool>());
  EXPECT_LT(max_relative_difference(a.image, b.image), 1e-6);
}

// The pinhole's importance, checked against the camera's own rays: a point
// on a camera ray maps back to the ray's raster point and direction.
TEST(CameraImportance, RasterAndDirectionRoundTrip) {
  Scene scene = load_test_scene(kMirrorRoom);
  Camera cam = make_camera(scene.camera, scene.film);
  ASSERT_TRUE(camera_supports_wi(cam));
  for (vec2 p : {vec2(0.5f, 0.5f), vec2(16.0f, 12.0f), vec2(31.7f, 3.2f), vec2(2.0f, 23.9f)}) {
    Ray r = generate_camera_ray(cam, p, vec2(0.5f));
    vec3 d = glm::normalize(r.d);
    auto cw = camera_wi(cam, r.o + 7.0f * d);
    ASSERT_TRUE(cw);
    EXPECT_NEAR(cw->raster.x, p.x, 1e-3f);
    EXPECT_NEAR(cw->raster.y, p.y, 1e-3f);
    EXPECT_NEAR(glm::dot(cw->wi, -d), 1.0f, 1e-5f);
    EXPECT_NEAR(cw->distance, 7.0f, 1e-4f);
  }
  EXPECT_FALSE(camera_wi(cam, cam.render_from_camera.point(vec3(0, 0, -1))));  // behind the camera
}

// Casters and lights but no receiver in view: the pass finds nothing, so it
// switches itself off once it has traced enough paths to say so, and the
// image is the path tracer's.
TEST(Caustics, SwitchesItselfOffWhenTheCameraSeesNoCaustic) {
  std::string text = mirror_room_scene(64, 64, 0.1f);
  text.replace(text.find("LookAt 0 5 -9  0 0 0"), 20, "LookAt 0 1 -9  0 1 -20");  // facing away, at the sky
  Scene scene = load_test_scene(text);
  RenderResult on = render(scene, 64, true), off = render(scene, 64, false);
  // Regular schedule 16 16 32: 4096 x 32 = 131k paths after the second pass.
  EXPECT_EQ(on.log["caustics"]["switched_off_after_passes"].get<int>(), 2);
  EXPECT_EQ(on.log["caustics"]["splats"].get<uint64_t>(), 0u);
  EXPECT_LT(max_relative_difference(on.image, off.image), 1e-5);
}

// Shading normals that are not the geometric ones (a floor whose vertex
// normals lean 20 degrees towards the camera): light paths need Veach's adjoint correction at
// the caster and the receiver to agree with camera paths.
TEST(Caustics, ShadingNormalsGetTheAdjointCorrection) {
  std::string text = mirror_room_scene(32, 24, 0.1f);
  const std::string floor = "Shape \"trianglemesh\" \"point3 P\" [-8 0 -8  8 0 -8  8 0 8  -8 0 8]";
  text.replace(text.find(floor), floor.size(), floor + " \"normal N\" [0 0.94 -0.342  0 0.94 -0.342  0 0.94 -0.342  0 0.94 -0.342]");
  Scene scene = load_test_scene(text);
  RenderResult pt = render(scene, 4096, false), ca = render(scene, 256, true);
  RGB mp = image_mean(pt.image), mc = image_mean(ca.image);
  std::printf("leaning shading normals: path traced %.4f, with caustics %.4f\n", mp.y, mc.y);
  EXPECT_NEAR(mc.y / mp.y, 1.0, 0.01);
  EXPECT_NEAR(half_mean(ca.image, false) / half_mean(pt.image, false), 1.0, 0.015);
}

