#include "wavefront/film.h"

#include "core/color.h"

namespace theia {

static void atomic_add(float& target, float v) { std::atomic_ref<float>(target).fetch_add(v, std::memory_order_relaxed); }

Film::Film(int w, int h) : width(w), height(h) {
  size_t n = pixel_count();
  for (auto* v : {&r, &g, &b, &weight, &alpha, &depth}) v->assign(n, 0.0f);
  for (int c = 0; c < 3; ++c) {
    albedo[c].assign(n, 0.0f);
    normal[c].assign(n, 0.0f);
  }
}

void Film::add_weight(uint32_t pixel, float w) { atomic_add(weight[pixel], w); }

void Film::splat(uint32_t pixel, const RGB& L) {
  if (!is_finite(L)) {
    dropped.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  atomic_add(r[pixel], L.x);
  atomic_add(g[pixel], L.y);
  atomic_add(b[pixel], L.z);
}

void Film::splat_first_hit(uint32_t pixel, float w, bool hit, const RGB& a, const vec3& n, float d) {
  if (!hit) return;
  if (!is_finite(a) || !is_finite(n) || !std::isfinite(d)) {
    dropped.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  atomic_add(alpha[pixel], w);
  for (int c = 0; c < 3; ++c) {
    atomic_add(albedo[c][pixel], w * a[c]);
    atomic_add(normal[c][pixel], w * n[c]);
  }
  atomic_add(depth[pixel], w * d);
}

ImageBuffer resolve_film(const Film& film) {
  ImageBuffer img;
  img.width = film.width;
  img.height = film.height;
  img.channels = {"R", "G", "B", "A", "albedo.R", "albedo.G", "albedo.B", "N.X", "N.Y", "N.Z", "depth.Z"};
  const size_t first_layer = img.channels.size();
  for (const FilmLayer& l : film.layers)
    for (const char* c : {".R", ".G", ".B"}) img.channels.push_back(l.name + c);
  const size_t nc = img.channels.size();
  img.data.assign(film.pixel_count() * nc, 0.0f);
  for (size_t i = 0; i < film.pixel_count(); ++i) {
    float w = film.weight[i];
    if (w == 0.0f) continue;
    float inv = 1.0f / w;
    float* px = &img.data[i * nc];
    RGB c = working_to_srgb(RGB(film.r[i], film.g[i], film.b[i]) * inv);
    px[0] = c.x;
    px[1] = c.y;
    px[2] = c.z;
    px[3] = film.alpha[i] * inv;
    // AOVs average over the samples that hit something, so edges do not fade to zero.
    float a = film.alpha[i];
    if (a > 0.0f) {
      RGB albedo = working_to_srgb(RGB(film.albedo[0][i], film.albedo[1][i], film.albedo[2][i]) / a);
      for (int c = 0; c < 3; ++c) {
        px[4 + c] = albedo[c];
        px[7 + c] = film.normal[c][i] / a;
      }
      px[10] = film.depth[i] / a;
    }
    for (size_t l = 0; l < film.layers.size(); ++l) {
      const std::vector<float>& rgb = film.layers[l].rgb;
      if (rgb.size() != 3 * film.pixel_count()) continue;
      RGB v = working_to_srgb(RGB(rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]) * inv);
      for (int c = 0; c < 3; ++c) px[first_layer + 3 * l + c] = v[c];
    }
  }
  return img;
}

}  // namespace theia
