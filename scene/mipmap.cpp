#include "scene/mipmap.h"

#include "scene/texture.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace theia {

namespace {

// Output texel i of a reduction from n to m texels covers input [i n/m, (i+1) n/m).
// n/m <= 2, so at most three input texels overlap it.
struct BoxTap {
  int first = 0, count = 0;
  float w[3] = {0, 0, 0};
};

std::vector<BoxTap> box_taps(int n, int m) {
  std::vector<BoxTap> taps(static_cast<size_t>(m));
  for (int i = 0; i < m; ++i) {
    double a = double(i) * n / m, b = double(i + 1) * n / m;
    BoxTap& t = taps[size_t(i)];
    t.first = int(std::floor(a));
    int last = std::min(n, int(std::ceil(b)));
    for (int j = t.first; j < last && t.count < 3; ++j)
      t.w[t.count++] = float((std::min(b, double(j + 1)) - std::max(a, double(j))) / (b - a));
  }
  return taps;
}

// One level down: separable, x then y.
Image reduce(const Image& src) {
  const int w = src.width, h = src.height, nc = src.channels;
  const int mw = std::max(1, (w + 1) / 2), mh = std::max(1, (h + 1) / 2);
  const std::vector<BoxTap> tx = box_taps(w, mw), ty = box_taps(h, mh);
  std::vector<float> rows(size_t(mw) * size_t(h) * size_t(nc));
  tbb::parallel_for(0, h, [&](int y) {
    for (int x = 0; x < mw; ++x) {
      const BoxTap& t = tx[size_t(x)];
      for (int c = 0; c < nc; ++c) {
        float v = 0.0f;
        for (int k = 0; k < t.count; ++k)
          v += t.w[k] * src.pixels[(size_t(y) * size_t(w) + size_t(t.first + k)) * size_t(nc) + size_t(c)];
        rows[(size_t(y) * size_t(mw) + size_t(x)) * size_t(nc) + size_t(c)] = v;
      }
    }
  });
  Image dst;
  dst.is_color = src.is_color;
  dst.width = mw;
  dst.height = mh;
  dst.channels = nc;
  dst.pixels.resize(size_t(mw) * size_t(mh) * size_t(nc));
  tbb::parallel_for(0, mh, [&](int y) {
    const BoxTap& t = ty[size_t(y)];
    for (int x = 0; x < mw; ++x)
      for (int c = 0; c < nc; ++c) {
        float v = 0.0f;
        for (int k = 0; k < t.count; ++k)
          v += t.w[k] * rows[(size_t(t.first + k) * size_t(mw) + size_t(x)) * size_t(nc) + size_t(c)];
        dst.pixels[(size_t(y) * size_t(mw) + size_t(x)) * size_t(nc) + size_t(c)] = v;
      }
  });
  return dst;
}

inline const Image& level(const Image& image, int l) { return l == 0 ? image : image.mip[size_t(l - 1)]; }

// The 1x1 level: the image's mean, whatever the wrap mode.
inline RGB mip_mean(const Image& image) { return image_texel(image.mip.back(), {0, 0}, WrapMode::Clamp); }

// pbrt-v4's EWA weights: the Gaussian exp(-2 r^2) less its value at r = 1, so
// that it falls to zero at the ellipse's edge, tabulated over r^2 in [0, 1].
constexpr int kEWATableSize = 128;
struct EWAWeights {
  float w[kEWATableSize];
  EWAWeights() {
    for (int i = 0; i < kEWATableSize; ++i)
      w[i] = float(std::exp(-2.0 * i / (kEWATableSize - 1)) - std::exp(-2.0));
  }
};
const EWAWeights kEWAWeights;

// Keeps a raster coordinate finite and within int range before it becomes
// texel indices (the wrap mode makes far-off values alike anyway).
inline float sane_raster(float x) { return std::isfinite(x) ? std::clamp(x, -1e8f, 1e8f) : 0.0f; }

// pbrt-v4's MIPMap::EWA in one level; st and the axes in texture units.
RGB ewa_level(const Image& image, int l, vec2 st, vec2 dst0, vec2 dst1, WrapMode wrap) {
  if (l >= int(image.mip.size())) return mip_mean(image);
  const Image& img = level(image, l);
  const vec2 res(float(img.width), float(img.height));
  // Raster space of the level: pixel centres at integers, rows top to bottom,
  // so t and its derivatives change sign.
  const vec2 c(sane_raster(st.x * res.x - 0.5f), sane_raster((1.0f - st.y) * res.y - 0.5f));
  const vec2 d0(dst0.x * res.x, -dst0.y * res.y), d1(dst1.x * res.x, -dst1.y * res.y);
  // The implicit ellipse A x^2 + B x y + C y^2 < 1 spanned by d0 and d1,
  // widened by a one-texel disk (its matrix is D D^T + I) so that even a tiny
  // ellipse covers the nearest texel centre.
  float A = d0.y * d0.y + d1.y * d1.y + 1.0f;
  float B = -2.0f * (d0.x * d0.y + d1.x * d1.y);
  float C = d0.x * d0.x + d1.x * d1.x + 1.0f;
  const float inv_f = 1.0f / (A * C - 0.25f * B * B);
  A *= inv_f, B *= inv_f, C *= inv_f;
  // Its bounding box.
  const float det = 4.0f * A * C - B * B, inv_det = 1.0f / det;
  const float us = std::sqrt(std::max(0.0f, det * C)), vs = std::sqrt(std::max(0.0f, det * A));
  const int s0 = int(std::ceil(c.x - 2.0f * inv_det * us)), s1 = int(std::floor(c.x + 2.0f * inv_det * us));
  const int t0 = int(std::ceil(c.y - 2.0f * inv_det * vs)), t1 = int(std::floor(c.y + 2.0f * inv_det * vs));
  RGB sum(0.0f);
  float sum_w = 0.0f;
  for (int it = t0; it <= t1; ++it) {
    const float tt = float(it) - c.y;
    for (int is = s0; is <= s1; ++is) {
      const float ss = float(is) - c.x;
      const float r2 = A * ss * ss + B * ss * tt + C * tt * tt;
      if (r2 >= 1.0f) continue;
      const float w = kEWAWeights.w[std::min(int(r2 * kEWATableSize), kEWATableSize - 1)];
      sum += w * image_texel(img, {is, it}, wrap);
      sum_w += w;
    }
  }
  // The centre texel is always inside (r2 < 1 there after the widening), so
  // sum_w > 0; guard anyway rather than divide by zero.
  return sum_w > 0.0f ? sum / sum_w : image_lookup_bilinear(img, st, wrap);
}

}  // namespace

void build_mip_pyramid(Image& image) {
  image.mip.clear();
  if (image.pixels.empty() || image.width <= 0 || image.height <= 0) return;
  const Image* prev = &image;
  std::vector<Image> levels;
  while (prev->width > 1 || prev->height > 1) {
    levels.push_back(reduce(*prev));
    prev = &levels.back();
  }
  image.mip = std::move(levels);
}

void build_mipmaps(Scene& scene) {
  std::vector<char> needed(scene.images.size(), 0);
  for (const Texture& t : scene.textures)
    if (t.kind == TextureKind::ImageMap && filter_uses_mipmap(t.filter) && t.image >= 0)
      needed[size_t(t.image)] = 1;
  tbb::parallel_for(size_t(0), scene.images.size(), [&](size_t i) {
    if (needed[i]) build_mip_pyramid(scene.images[i]);
  });
}

size_t mip_memory_bytes(const Scene& scene) {
  size_t n = 0;
  for (const Image& image : scene.images)
    for (const Image& l : image.mip) n += l.pixels.size() * sizeof(float);
  return n;
}

size_t texture_memory_bytes(const Scene& scene) {
  size_t n = mip_memory_bytes(scene);
  for (const Image& image : scene.images) n += image.pixels.size() * sizeof(float);
  return n;
}

RGB image_lookup_trilinear(const Image& image, vec2 st, vec2 dst0, vec2 dst1, WrapMode wrap) {
  if (image.mip.empty() || image.pixels.empty()) return image_lookup_bilinear(image, st, wrap);
  const int n_levels = int(image.mip.size()) + 1;
  float width = 2.0f * std::max({std::abs(dst0.x), std::abs(dst0.y), std::abs(dst1.x), std::abs(dst1.y)});
  // pbrt-v4's level: its level 0 is resampled up to 2^(n_levels - 1) texels, so
  // a footprint as wide as the image reaches the 1x1 mean whatever the size.
  float lvl = float(n_levels - 1) + std::log2(std::max(width, 1e-8f));
  // (Also catches NaN: no footprint is level 0.)
  if (!(lvl > 0.0f)) return image_lookup_bilinear(image, st, wrap);
  if (lvl >= float(n_levels - 1)) return mip_mean(image);
  // pbrt-v4 returns level 0 for every level below 1, which jumps at level 1;
  // lerping from level 0 keeps the filter continuous in the footprint.
  int i = int(std::floor(lvl));
  float delta = lvl - float(i);
  RGB a = image_lookup_bilinear(level(image, i), st, wrap), b = image_lookup_bilinear(level(image, i + 1), st, wrap);
  return (1.0f - delta) * a + delta * b;
}

RGB image_lookup_ewa(const Image& image, vec2 st, vec2 dst0, vec2 dst1, WrapMode wrap, float max_anisotropy) {
  if (image.mip.empty() || image.pixels.empty()) return image_lookup_bilinear(image, st, wrap);
  // The ellipse's axes: dst0 the longer.
  if (glm::dot(dst0, dst0) < glm::dot(dst1, dst1)) std::swap(dst0, dst1);
  const float longer = glm::length(dst0);
  float shorter = glm::length(dst1);
  // (NaN anywhere: no usable footprint, level 0.)
  if (!(longer >= 0.0f) || !(shorter >= 0.0f)) return image_lookup_bilinear(image, st, wrap);
  // A ratio below 1 would make the minor axis the longer one.
  max_anisotropy = std::max(max_anisotropy, 1.0f);
  if (shorter * max_anisotropy < longer && shorter > 0.0f) {
    // Grow the minor axis rather than shrink the major one: blur, not alias,
    // and the level (from the minor axis) keeps the loop over texels short.
    const float scale = longer / (shorter * max_anisotropy);
    dst1 *= scale;
    shorter *= scale;
  }
  if (shorter == 0.0f) return image_lookup_bilinear(image, st, wrap);
  const int n_levels = int(image.mip.size()) + 1;
  const float lod = std::max(0.0f, float(n_levels - 1) + std::log2(shorter));
  // (Also an infinite footprint.)
  if (!(lod < float(n_levels - 1))) return mip_mean(image);
  const int i = int(std::floor(lod));
  const float delta = lod - float(i);
  RGB a = ewa_level(image, i, st, dst0, dst1, wrap);
  if (delta == 0.0f) return a;
  return (1.0f - delta) * a + delta * ewa_level(image, i + 1, st, dst0, dst1, wrap);
}

}  // namespace theia
