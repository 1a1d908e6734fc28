#include "scene/camera.h"
#include "scene/mipmap.h"
#include "scene/texture.h"

#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace theia;

namespace {

// w x h grey checkerboard of 1-texel checks: 0 and 1.
Image checker(int w, int h) {
  return test::make_image(w, h, 1, [](int x, int y) { return RGB(float((x + y) % 2)); });
}

// RGB texels with no structure a box filter could preserve by accident.
Image noise_image(int w, int h) {
  Image img;
  img.width = w;
  img.height = h;
  img.channels = 3;
  for (int i = 0; i < w * h * 3; ++i) img.pixels.push_back(float((i * 7919) % 101) / 100.0f);
  return img;
}

float max_abs(const RGB& v) { return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}); }

std::vector<double> channel_means(const Image& img) {
  std::vector<double> m(size_t(img.channels), 0.0);
  for (size_t i = 0; i < img.pixels.size(); ++i) m[i % size_t(img.channels)] += img.pixels[i];
  for (double& v : m) v /= double(img.width) * double(img.height);
  return m;
}

TEST(MipMap, EvenCheckerLevelsAreItsMeanExactly) {
  Image img = checker(8, 8);
  build_mip_pyramid(img);
  ASSERT_EQ(img.mip.size(), 3u);  // 4x4, 2x2, 1x1
  for (const Image& l : img.mip) {
    EXPECT_EQ(l.width, l.height);
    for (float v : l.pixels) EXPECT_EQ(v, 0.5f);
  }
  EXPECT_EQ(img.mip.back().width, 1);
}

TEST(MipMap, OddSizesKeepTheMeanAtEveryLevel) {
  for (auto [w, h] : {std::pair{7, 5}, std::pair{1, 9}, std::pair{13, 2}}) {
    Image img = noise_image(w, h);
    build_mip_pyramid(img);
    std::vector<double> mean = channel_means(img);
    int pw = w, ph = h;
    for (const Image& l : img.mip) {
      EXPECT_EQ(l.width, std::max(1, (pw + 1) / 2));
      EXPECT_EQ(l.height, std::max(1, (ph + 1) / 2));
      pw = l.width, ph = l.height;
      std::vector<double> lm = channel_means(l);
      for (size_t c = 0; c < mean.size(); ++c) EXPECT_NEAR(lm[c], mean[c], 1e-5) << w << "x" << h;
    }
    EXPECT_EQ(pw * ph, 1);
  }
}

TEST(MipMap, OneTexelFootprintIsBilinearLevelZero) {
  Image img = noise_image(16, 16);
  build_mip_pyramid(img);
  const float texel = 1.0f / 16.0f;
  for (vec2 st : {vec2(0.3f, 0.7f), vec2(0.01f, 0.99f), vec2(0.51f, 0.24f)})
    for (float f : {1.0f, 0.5f, 0.0f}) {
      // Filter width 2 max|d| = one texel (or less).
      RGB a = image_lookup_trilinear(img, st, {0.5f * f * texel, 0.0f}, {0.0f, 0.3f * f * texel}, WrapMode::Repeat);
      RGB b = image_lookup_bilinear(img, st, WrapMode::Repeat);
      EXPECT_EQ(a, b);
    }
}

TEST(MipMap, FootprintCoveringTheImageIsItsMean) {
  Image img = noise_image(12, 9);
  build_mip_pyramid(img);
  std::vector<double> mean = channel_means(img);
  for (WrapMode wrap : {WrapMode::Repeat, WrapMode::Black, WrapMode::Clamp}) {
    RGB v = image_lookup_trilinear(img, vec2(0.2f, 0.6f), {0.6f, 0.0f}, {0.0f, 0.1f}, wrap);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(v[c], mean[size_t(c)], 1e-5);
  }
}

TEST(MipMap, TrilinearIsContinuousInTheFootprint) {
  Image img = noise_image(32, 32);
  build_mip_pyramid(img);
  const vec2 st(0.37f, 0.61f);
  // Sweep the width across every level boundary in fine steps: no jumps.
  float worst = 0.0f;
  RGB prev = image_lookup_trilinear(img, st, {0.0f, 0.0f}, {0.0f, 0.0f}, WrapMode::Repeat);
  for (int i = 1; i <= 4000; ++i) {
    float width = std::exp2(-7.0f + 8.0f * float(i) / 4000.0f);  // 1/4 texel to 8 images
    RGB v = image_lookup_trilinear(img, st, {0.5f * width, 0.0f}, {0.0f, 0.5f * width}, WrapMode::Repeat);
    worst = std::max(worst, max_abs(v - prev));
    prev = v;
  }
  // A jump of a whole level would be ~0.1-0.5 here; steps of 1/500 of a level change little.
  EXPECT_LT(worst, 0.01f);
  // And both sides of a boundary (level 2 = 4 texels wide) agree.
  float w = 4.0f / 32.0f;
  RGB below = image_lookup_trilinear(img, st, {0.5f * w * 0.9999f, 0}, {0, 0}, WrapMode::Repeat);
  RGB above = image_lookup_trilinear(img, st, {0.5f * w * 1.0001f, 0}, {0, 0}, WrapMode::Repeat);
  EXPECT_LT(max_abs(below - above), 1e-3f);
}

TEST(MipMap, BuiltOnlyForTrilinearTexturesAndCounted) {
  Scene s;
  s.images = {checker(16, 16), checker(16, 16)};
  Texture a, b;
  a.kind = b.kind = TextureKind::ImageMap;
  a.image = 0, a.filter = TextureFilter::Trilinear;
  b.image = 1, b.filter = TextureFilter::Bilinear;
  s.textures = {a, b};
  build_mipmaps(s);
  EXPECT_EQ(s.images[0].mip.size(), 4u);
  EXPECT_TRUE(s.images[1].mip.empty());
  // 8x8 + 4x4 + 2x2 + 1x1 floats.
  EXPECT_EQ(mip_memory_bytes(s), (64u + 16u + 4u + 1u) * sizeof(float));
  EXPECT_EQ(texture_memory_bytes(s), mip_memory_bytes(s) + 2u * 256u * sizeof(float));
}

TEST(TextureFootprint, SppScaleIsPbrts) {
  EXPECT_FLOAT_EQ(footprint_spp_scale(1), 1.0f);
  EXPECT_FLOAT_EQ(footprint_spp_scale(16), 0.25f);
  EXPECT_FLOAT_EQ(footprint_spp_scale(4096), 0.125f);
}

// A plane facing a narrow pinhole camera at distance D: one pixel spans
// D * (pixel width on the z = 1 plane), so dp/dx and dp/dy are that long,
// along the camera's x and y; with dpdu = (2, 0, 0), dpdv = (0, 3, 0) the uv
// derivatives are those lengths over 2 and 3.
TEST(TextureFootprint, PlaneFacingTheCameraGivesThePixelFootprint) {
  CameraParams cp;
  cp.fov = 1.0f;
  FilmParams fp;
  fp.width = 64;
  fp.height = 64;
  Camera cam = make_camera(cp, fp);
  const float D = 7.0f, pixel = 2.0f * std::tan(radians(0.5f)) / 64.0f;
  vec3 dpdx, dpdy;
  for (vec3 p : {vec3(0, 0, D), vec3(0.03f, -0.02f, D)}) {
    approximate_dp_dxy(cam, p, vec3(0, 0, -1), 0.5f, dpdx, dpdy);
    EXPECT_NEAR(glm::length(dpdx), 0.5f * D * pixel, 1e-3f * D * pixel);
    EXPECT_NEAR(glm::length(dpdy), 0.5f * D * pixel, 1e-3f * D * pixel);
    EXPECT_NEAR(dpdx.z, 0.0f, 1e-6f);
    EXPECT_NEAR(glm::dot(dpdx, dpdy), 0.0f, 1e-3f * glm::dot(dpdx, dpdx));
  }
  SurfaceInteraction si;
  si.p = vec3(0, 0, D);
  si.ng = vec3(0, 0, -1);
  si.dpdu = vec3(2, 0, 0);
  si.dpdv = vec3(0, 3, 0);
  UVFootprint f = texture_footprint(cam, si, 1.0f);
  float du = std::max(std::abs(f.dudx), std::abs(f.dudy)), dv = std::max(std::abs(f.dvdx), std::abs(f.dvdy));
  EXPECT_NEAR(du, D * pixel / 2.0f, 1e-3f * D * pixel);
  EXPECT_NEAR(dv, D * pixel / 3.0f, 1e-3f * D * pixel);
  EXPECT_NEAR(std::min(std::abs(f.dudx), std::abs(f.dudy)), 0.0f, 1e-3f * D * pixel);
  // Tilting the plane 60 degrees about x stretches the y footprint by 1/cos.
  si.ng = glm::normalize(vec3(0, std::sin(radians(60.0f)), -std::cos(radians(60.0f))));
  approximate_dp_dxy(cam, si.p, si.ng, 1.0f, dpdx, dpdy);
  float longer = std::max(glm::length(dpdx), glm::length(dpdy)), shorter = std::min(glm::length(dpdx), glm::length(dpdy));
  EXPECT_NEAR(shorter, D * pixel, 2e-3f * D * pixel);
  EXPECT_NEAR(longer, 2.0f * D * pixel, 4e-3f * D * pixel);
  // Degenerate dpdu/dpdv: no footprint rather than NaN.
  si.dpdu = si.dpdv = vec3(0.0f);
  UVFootprint z = texture_footprint(cam, si, 1.0f);
  EXPECT_EQ(z.dudx, 0.0f);
  EXPECT_EQ(z.dvdy, 0.0f);
}

}  // namespace
