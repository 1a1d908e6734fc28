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

// ---------------------------------------------------------------- EWA

// Largest minus smallest lookup over `n` points along a line through the
// image: how much of a pattern's contrast a filter lets through.
template <typename Lookup>
float contrast_along(vec2 from, vec2 to, int n, Lookup lookup) {
  float lo = kInfinity, hi = -kInfinity;
  for (int i = 0; i < n; ++i) {
    float v = lookup(from + (to - from) * (float(i) + 0.5f) / float(n)).x;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  return hi - lo;
}

// Grey stripes 4 texels wide, alternating 0 and 1 down the image: constant
// along s, varying along t.
Image stripes_along_t(int w, int h) {
  return test::make_image(w, h, 1, [](int, int y) { return RGB(float((y / 4) % 2)); });
}

TEST(MipMapEWA, ConstantImageGivesExactlyTheConstant) {
  // Powers of two: every weighted sum and lerp of them is exact.
  for (float c : {1.0f, 0.25f}) {
    Image img = test::make_image(16, 16, 1, [c](int, int) { return RGB(c); });
    build_mip_pyramid(img);
    for (WrapMode wrap : {WrapMode::Repeat, WrapMode::Clamp})
      for (vec2 st : {vec2(0.3f, 0.7f), vec2(0.0f, 1.0f), vec2(0.97f, 0.02f)})
        // (Not r = 0: that is bilinear, whose weights round.)
        for (float r : {0.01f, 0.07f, 0.3f, 2.0f}) {
          EXPECT_EQ(image_lookup_ewa(img, st, {r, 0.3f * r}, {-0.1f * r, 0.2f * r}, wrap, 8.0f), RGB(c));
          EXPECT_EQ(image_lookup_ewa(img, st, {r, 0.0f}, {0.0f, 0.01f * r}, wrap, 8.0f), RGB(c));
        }
  }
  // Any other constant, odd size: exact up to float rounding.
  Image img = test::make_image(13, 7, 3, [](int, int) { return RGB(0.37f, 0.8f, 0.01f); });
  build_mip_pyramid(img);
  for (float r : {0.02f, 0.1f, 0.5f}) {
    RGB v = image_lookup_ewa(img, vec2(0.41f, 0.66f), {r, r}, {0.5f * r, -0.3f * r}, WrapMode::Repeat, 8.0f);
    EXPECT_FLOAT_EQ(v.x, 0.37f);
    EXPECT_FLOAT_EQ(v.y, 0.8f);
    EXPECT_FLOAT_EQ(v.z, 0.01f);
  }
}

TEST(MipMapEWA, ZeroFootprintIsBilinearLevelZero) {
  Image img = noise_image(16, 12);
  build_mip_pyramid(img);
  for (vec2 st : {vec2(0.3f, 0.7f), vec2(0.01f, 0.99f), vec2(0.51f, 0.24f)})
    for (WrapMode wrap : {WrapMode::Repeat, WrapMode::Black}) {
      RGB b = image_lookup_bilinear(img, st, wrap);
      EXPECT_EQ(image_lookup_ewa(img, st, {0, 0}, {0, 0}, wrap, 8.0f), b);
      // A degenerate ellipse (one axis zero) too, as in pbrt-v4.
      EXPECT_EQ(image_lookup_ewa(img, st, {0.2f, 0.1f}, {0, 0}, wrap, 8.0f), b);
      EXPECT_EQ(image_lookup_ewa(img, st, {NAN, 0.1f}, {0, 0.1f}, wrap, 8.0f), b);
    }
}

// The isotropic footprint radius, in texels, at which a lookup has lost half
// of the contrast of stripes `period` texels apart (64 if it never does).
template <typename Lookup>
float half_contrast_footprint(int period, Lookup lookup) {
  Image img = test::make_image(64, 64, 1, [period](int, int y) { return RGB(float((y / (period / 2)) % 2)); });
  build_mip_pyramid(img);
  const float texel = 1.0f / 64.0f;
  for (int k = -16; k <= 48; ++k) {
    const float r = std::exp2(float(k) / 8.0f);
    const vec2 d0(r * texel, 0.0f), d1(0.0f, r * texel);
    float c = contrast_along({0.3f, 0.2f}, {0.3f, 0.2f + 2.0f * float(period) * texel}, 128,
                             [&](vec2 st) { return lookup(img, st, d0, d1); });
    if (c < 0.5f) return r;
  }
  return 64.0f;
}

TEST(MipMapEWA, IsotropicFootprintBlursAboutAsMuchAsTrilinear) {
  for (int period : {8, 16}) {
    float ewa = half_contrast_footprint(period, [](const Image& img, vec2 st, vec2 d0, vec2 d1) {
      return image_lookup_ewa(img, st, d0, d1, WrapMode::Repeat, 8.0f);
    });
    float tri = half_contrast_footprint(period, [](const Image& img, vec2 st, vec2 d0, vec2 d1) {
      return image_lookup_trilinear(img, st, d0, d1, WrapMode::Repeat);
    });
    // A footprint comparable to the stripes blurs them (unfiltered bilinear
    // never would: 64 here), and the two filters agree within a factor 1.5 on
    // where.  (pbrt-v4's EWA picks its level from the radius, trilinear from
    // the diameter, so EWA is the sharper of the two.)
    EXPECT_GT(ewa, 0.2f * float(period)) << period;
    EXPECT_LT(ewa, 1.0f * float(period)) << period;
    EXPECT_GE(ewa / tri, 1.0f / 1.5f) << period;
    EXPECT_LE(ewa / tri, 1.5f) << period;
  }
}

TEST(MipMapEWA, AnisotropicFootprintKeepsStripesAlongItsLongAxisSharp) {
  Image img = stripes_along_t(64, 64);
  build_mip_pyramid(img);
  const float texel = 1.0f / 64.0f;
  // Long along s (8 texels, the anisotropy limit), short along t (1 texel),
  // as a floor seen at a grazing angle.
  const vec2 d0(8.0f * texel, 0.0f), d1(0.0f, texel);
  const vec2 from(0.3f, 0.2f), to(0.3f, 0.2f + 16 * texel);
  float ewa = contrast_along(from, to, 64, [&](vec2 st) { return image_lookup_ewa(img, st, d0, d1, WrapMode::Repeat, 8.0f); });
  float tri = contrast_along(from, to, 64, [&](vec2 st) { return image_lookup_trilinear(img, st, d0, d1, WrapMode::Repeat); });
  EXPECT_GT(ewa, 0.8f);  // the stripes survive...
  EXPECT_LT(tri, 0.1f);  // ... where trilinear's isotropic filter averages them away
  // Past the anisotropy limit the minor axis grows: 64:1 clamped to 8:1 is
  // the 8 x 8 texel footprint, which blurs the stripes like an isotropic one.
  const vec2 e0(64.0f * texel, 0.0f);
  float clamped = contrast_along(from, to, 64, [&](vec2 st) { return image_lookup_ewa(img, st, e0, d1, WrapMode::Repeat, 8.0f); });
  float iso = contrast_along(from, to, 64, [&](vec2 st) {
    return image_lookup_ewa(img, st, e0, {0.0f, 8.0f * texel}, WrapMode::Repeat, 8.0f);
  });
  EXPECT_NEAR(clamped, iso, 1e-5f);
  EXPECT_LT(clamped, 0.5f * ewa);
  // A higher limit keeps them again.
  float loose = contrast_along(from, to, 64, [&](vec2 st) { return image_lookup_ewa(img, st, e0, d1, WrapMode::Repeat, 64.0f); });
  EXPECT_GT(loose, 0.8f);
}

// The ellipse lies along the footprint's long axis in texture space, with t
// pointing up the image: a sheared footprint along st (1, 1) runs along
// stripes that are constant along it, and across stripes along (1, -1).
TEST(MipMapEWA, ShearedFootprintFollowsTheDiagonal) {
  // Stripes constant along raster (1, -1), i.e. along st (1, 1).
  Image img = test::make_image(64, 64, 1, [](int x, int y) { return RGB(float(((x + y) / 4) % 2)); });
  build_mip_pyramid(img);
  const float texel = 1.0f / 64.0f;
  const vec2 along(5.0f * texel, 5.0f * texel), across(0.7f * texel, -0.7f * texel);
  const vec2 from(0.3f, 0.3f), to(0.3f + 16 * texel, 0.3f - 16 * texel);  // across the stripes
  float sharp = contrast_along(from, to, 64, [&](vec2 st) { return image_lookup_ewa(img, st, along, across, WrapMode::Repeat, 8.0f); });
  float blurred = contrast_along(from, to, 64, [&](vec2 st) {
    return image_lookup_ewa(img, st, vec2(along.x, -along.y), vec2(across.x, -across.y), WrapMode::Repeat, 8.0f);
  });
  EXPECT_GT(sharp, 0.7f);
  EXPECT_LT(blurred, 0.5f * sharp);
}

TEST(MipMapEWA, LargeFootprintIsTheImageMean) {
  Image img = noise_image(12, 9);
  build_mip_pyramid(img);
  std::vector<double> mean = channel_means(img);
  for (WrapMode wrap : {WrapMode::Repeat, WrapMode::Black, WrapMode::Clamp})
    for (vec2 d1 : {vec2(0.0f, 1.0f), vec2(0.9f, 0.9f), vec2(0.0f, INFINITY)}) {
      RGB v = image_lookup_ewa(img, vec2(0.2f, 0.6f), {2.0f, 0.0f}, d1, wrap, 8.0f);
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(v[c], mean[size_t(c)], 1e-5);
    }
}

TEST(MipMapEWA, WrapModesDecideWhatLiesPastTheBorder) {
  // Column 0 bright, the last column half as bright, the rest dark: at the
  // left edge, clamp repeats column 0, repeat brings the last column round
  // and black brings nothing.
  Image img = test::make_image(16, 16, 1, [](int x, int) { return RGB(x == 0 ? 1.0f : x == 15 ? 0.5f : 0.0f); });
  build_mip_pyramid(img);
  const vec2 d0(1.5f / 16.0f, 0.0f), d1(0.0f, 1.5f / 16.0f);
  auto at = [&](vec2 st, WrapMode wrap) { return image_lookup_ewa(img, st, d0, d1, wrap, 8.0f).x; };
  const vec2 edge(0.0f, 0.5f);
  float clamp = at(edge, WrapMode::Clamp), repeat = at(edge, WrapMode::Repeat), black = at(edge, WrapMode::Black);
  EXPECT_GT(clamp, repeat + 0.05f);
  EXPECT_GT(repeat, black + 0.05f);
  EXPECT_GT(black, 0.0f);
  // Repeat is periodic; away from the border the modes agree.
  EXPECT_NEAR(at(edge + vec2(1.0f, 0.0f), WrapMode::Repeat), repeat, 1e-5f);
  EXPECT_NEAR(at(edge + vec2(-3.0f, 2.0f), WrapMode::Repeat), repeat, 1e-5f);
  const vec2 inside(0.5f, 0.5f);
  EXPECT_EQ(at(inside, WrapMode::Clamp), at(inside, WrapMode::Black));
  EXPECT_EQ(at(inside, WrapMode::Repeat), at(inside, WrapMode::Black));
}

TEST(MipMapEWA, PyramidsAreBuiltForEWATextures) {
  Scene s;
  s.images = {checker(16, 16)};
  Texture t;
  t.kind = TextureKind::ImageMap;
  t.image = 0, t.filter = TextureFilter::EWA;
  s.textures = {t};
  build_mipmaps(s);
  EXPECT_EQ(s.images[0].mip.size(), 4u);
  EXPECT_EQ(mip_memory_bytes(s), (64u + 16u + 4u + 1u) * sizeof(float));
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
