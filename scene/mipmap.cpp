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
    if (t.kind == TextureKind::ImageMap && t.filter == TextureFilter::Trilinear && t.image >= 0)
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
  if (lvl >= float(n_levels - 1)) return image_texel(level(image, n_levels - 1), {0, 0}, WrapMode::Clamp);
  // pbrt-v4 returns level 0 for every level below 1, which jumps at level 1;
  // lerping from level 0 keeps the filter continuous in the footprint.
  int i = int(std::floor(lvl));
  float delta = lvl - float(i);
  RGB a = image_lookup_bilinear(level(image, i), st, wrap), b = image_lookup_bilinear(level(image, i + 1), st, wrap);
  return (1.0f - delta) * a + delta * b;
}

}  // namespace theia
