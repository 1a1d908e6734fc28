// Texture evaluation (scene/texture.h): pbrt-v4's mappings and textures, on
// the hot shading path, so it allocates nothing, takes no locks and makes no
// virtual calls (a switch on TextureKind).
#include "core/color.h"
#include "scene/mipmap.h"
#include "scene/noise.h"
#include "scene/texture.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <iterator>
#include <type_traits>

namespace theia {

// ---------------------------------------------------------------- mappings

TexCoord2D map_texture_2d(const Texture& tex, const TextureEvalContext& ctx) {
  const UVMapping& m = tex.mapping;
  switch (tex.mapping_kind) {
    case TextureMappingKind::UV:
    case TextureMappingKind::Point3D:  // not a 2D mapping: only reached by misuse
      return {{m.su * ctx.uv.x + m.du, m.sv * ctx.uv.y + m.dv},
              {m.su * ctx.fp.dudx, m.sv * ctx.fp.dvdx},
              {m.su * ctx.fp.dudy, m.sv * ctx.fp.dvdy}};
    case TextureMappingKind::Spherical: {
      vec3 pt = tex.texture_from_render.point(ctx.p);
      float len = glm::length(pt);
      // The centre itself has no direction; pbrt-v4 would return NaN there.
      vec3 d = len > 0.0f && std::isfinite(len) ? pt / len : vec3(0, 0, 1);
      float theta = std::acos(std::clamp(d.z, -1.0f, 1.0f));
      float phi = std::atan2(d.y, d.x);
      if (phi < 0.0f) phi += 2.0f * kPi;
      return {{theta * kInvPi, phi * kInv2Pi}};
    }
    case TextureMappingKind::Cylindrical: {
      vec3 pt = tex.texture_from_render.point(ctx.p);
      return {{(kPi + std::atan2(pt.y, pt.x)) * kInv2Pi, pt.z}};
    }
    case TextureMappingKind::Planar: {
      vec3 pt = tex.texture_from_render.point(ctx.p);
      return {{m.du + glm::dot(pt, tex.planar_s), m.dv + glm::dot(pt, tex.planar_t)}};
    }
  }
  return {ctx.uv};
}

bool texture_reads_footprint(const Scene& scene, int texture, int depth) {
  if (texture < 0) return false;
  if (depth > 16) return true;
  const Texture& t = scene.textures[size_t(texture)];
  if ((t.kind == TextureKind::ImageMap && filter_uses_mipmap(t.filter)) ||
      (t.kind == TextureKind::Checkerboard && t.mapping_kind != TextureMappingKind::Point3D))
    return true;
  return texture_reads_footprint(scene, t.tex1, depth + 1) || texture_reads_footprint(scene, t.tex2, depth + 1) ||
         texture_reads_footprint(scene, t.amount, depth + 1);
}

// ---------------------------------------------------------------- pattern functions

namespace {

// +1 on even unit intervals, -1 on odd ones.  fmod keeps the parity defined
// for any float, negative or huge.
inline float square_wave(float x) { return std::fmod(std::floor(x), 2.0f) == 0.0f ? 1.0f : -1.0f; }

// A second antiderivative of the square wave (pbrt-v4's d(x)): its derivative
// is the triangle wave 1 - 2|y|, whose derivative is the square wave.
inline float square_wave_integral2(float x) {
  float y = x / 2 - std::floor(x / 2) - 0.5f;
  return x / 2 + y * (1 - 2 * std::abs(y));
}

// The square wave filtered by a triangle of half-width r: the second
// difference of its second antiderivative over r^2, as pbrt-v4.
inline float filtered_square_wave(float x, float r) {
  if (std::floor(x - r) == std::floor(x + r)) return square_wave(x);
  float v = (square_wave_integral2(x + r) - 2 * square_wave_integral2(x) + square_wave_integral2(x - r)) / (r * r);
  return std::isfinite(v) ? std::clamp(v, -1.0f, 1.0f) : square_wave(x);
}

// pbrt-v4's EvaluateCubicBezier over four control points.
inline RGB cubic_bezier(const RGB* c, float u) {
  auto lerp3 = [u](const RGB& a, const RGB& b) { return (1 - u) * a + u * b; };
  RGB c01 = lerp3(c[0], c[1]), c12 = lerp3(c[1], c[2]), c23 = lerp3(c[2], c[3]);
  return lerp3(lerp3(c01, c12), lerp3(c12, c23));
}

// The control points of pbrt-v4's marble spline: greys and one dark blue vein (sRGB).
const RGB kMarbleColors[] = {{.58f, .58f, .6f}, {.58f, .58f, .6f}, {.58f, .58f, .6f},
                             {.5f, .5f, .5f},   {.6f, .59f, .58f}, {.58f, .58f, .6f},
                             {.58f, .58f, .6f}, {.2f, .2f, .33f},  {.58f, .58f, .6f}};

// pbrt-v4's marble: a sine of height perturbed by fbm, through the spline
// (converted to the working space).
RGB marble(const Texture& tex, const TextureEvalContext& ctx) {
  vec3 p = tex.marble_scale * tex.texture_from_render.point(ctx.p);
  float m = p.y + tex.variation * fbm(p, vec3(0.0f), vec3(0.0f), tex.roughness, tex.octaves);
  float t = 0.5f + 0.5f * std::sin(m);
  constexpr int kSegments = int(std::size(kMarbleColors)) - 3;
  if (!std::isfinite(t)) t = 0.5f;  // sin of a huge p.y
  int first = std::clamp(int(std::floor(t * kSegments)), 0, kSegments - 1);
  return srgb_to_working(1.5f * cubic_bezier(kMarbleColors + first, t * kSegments - float(first)));
}

}  // namespace

float checkerboard_weight(const Texture& tex, const TextureEvalContext& ctx) {
  if (tex.mapping_kind == TextureMappingKind::Point3D) {
    // pbrt-v4 filters over the footprint's extent along each axis; theia has
    // no dp/dx, dp/dy, so the 3D checkerboard is unfiltered.
    vec3 p = tex.texture_from_render.point(ctx.p);
    return 0.5f - 0.5f * square_wave(p.x) * square_wave(p.y) * square_wave(p.z);
  }
  TexCoord2D c = map_texture_2d(tex, ctx);
  // A triangle filter 1.5 times the larger derivative wide, as pbrt-v4.
  float ds = 1.5f * std::max(std::abs(c.dst0.x), std::abs(c.dst1.x));
  float dt = 1.5f * std::max(std::abs(c.dst0.y), std::abs(c.dst1.y));
  return 0.5f - 0.5f * filtered_square_wave(c.st.x, ds) * filtered_square_wave(c.st.y, dt);
}

bool inside_polka_dot(vec2 st) {
  float s_cell = std::floor(st.x + 0.5f), t_cell = std::floor(st.y + 0.5f);
  if (!(perlin_noise(s_cell + 0.5f, t_cell + 0.5f) > 0.0f)) return false;
  constexpr float kRadius = 0.35f, kMaxShift = 0.5f - kRadius;
  float s_centre = s_cell + kMaxShift * perlin_noise(s_cell + 1.5f, t_cell + 2.8f);
  float t_centre = t_cell + kMaxShift * perlin_noise(s_cell + 4.5f, t_cell + 9.8f);
  vec2 d = st - vec2(s_centre, t_centre);
  return glm::dot(d, d) < kRadius * kRadius;
}

// ---------------------------------------------------------------- evaluation

namespace {

template <typename T>
T first(const RGB& c) {
  if constexpr (std::is_same_v<T, float>)
    return c.x;
  else
    return c;
}

template <typename T>
T eval(const Scene& scene, int index, const TextureEvalContext& ctx);

// A child slot: the texture if present, pbrt-v4's default constant otherwise.
template <typename T>
inline T eval_child(const Scene& scene, int index, float fallback, const TextureEvalContext& ctx) {
  return index < 0 ? T(fallback) : eval<T>(scene, index, ctx);
}

template <typename T>
T image_map(const Scene& scene, const Texture& tex, const TextureEvalContext& ctx) {
  if (tex.image < 0) return T(0.0f);
  TexCoord2D c = map_texture_2d(tex, ctx);
  const Image& img = scene.images[size_t(tex.image)];
  RGB v;
  switch (tex.filter) {
    case TextureFilter::Point: v = image_lookup_nearest(img, c.st, tex.wrap); break;
    case TextureFilter::Bilinear: v = image_lookup_bilinear(img, c.st, tex.wrap); break;
    case TextureFilter::Trilinear: v = image_lookup_trilinear(img, c.st, c.dst0, c.dst1, tex.wrap); break;
    case TextureFilter::EWA: v = image_lookup_ewa(img, c.st, c.dst0, c.dst1, tex.wrap, tex.max_anisotropy); break;
  }
  T s = tex.scale * first<T>(v);
  if constexpr (std::is_same_v<T, float>) {
    return tex.invert ? std::max(0.0f, 1.0f - s) : s;
  } else {
    // pbrt-v4 clamps spectrum imagemaps at zero whether inverted or not.
    return glm::max(tex.invert ? RGB(1.0f) - s : s, RGB(0.0f));
  }
}

template <typename T>
T eval(const Scene& scene, int index, const TextureEvalContext& ctx) {
  assert(index >= 0 && size_t(index) < scene.textures.size());
  const Texture& tex = scene.textures[size_t(index)];
  switch (tex.kind) {
    case TextureKind::Constant:
      return first<T>(tex.value);
    case TextureKind::ImageMap:
      return image_map<T>(scene, tex, ctx);
    case TextureKind::Checkerboard: {
      float w = checkerboard_weight(tex, ctx);
      T t1 = w != 1.0f ? eval_child<T>(scene, tex.tex1, 1.0f, ctx) : T(0.0f);
      T t2 = w != 0.0f ? eval_child<T>(scene, tex.tex2, 0.0f, ctx) : T(0.0f);
      return (1.0f - w) * t1 + w * t2;
    }
    case TextureKind::Scale: {
      float s = eval_child<float>(scene, tex.tex2, 1.0f, ctx);
      if (s == 0.0f) return T(0.0f);  // skip the (possibly costly) other branch
      return eval_child<T>(scene, tex.tex1, 1.0f, ctx) * s;
    }
    case TextureKind::Mix: {
      float a = eval_child<float>(scene, tex.amount, 0.5f, ctx);
      T t1 = a != 1.0f ? eval_child<T>(scene, tex.tex1, 0.0f, ctx) : T(0.0f);
      T t2 = a != 0.0f ? eval_child<T>(scene, tex.tex2, 1.0f, ctx) : T(0.0f);
      return (1.0f - a) * t1 + a * t2;
    }
    case TextureKind::DirectionMix: {
      // tex1 where the normal is along dir, tex2 where it is perpendicular.
      float a = std::min(std::abs(glm::dot(ctx.n, tex.dir)), 1.0f);
      T t1 = a != 0.0f ? eval_child<T>(scene, tex.tex1, 0.0f, ctx) : T(0.0f);
      T t2 = a != 1.0f ? eval_child<T>(scene, tex.tex2, 1.0f, ctx) : T(0.0f);
      return a * t1 + (1.0f - a) * t2;
    }
    case TextureKind::Bilerp: {
      // Not clamped to the unit square: outside it the corners extrapolate, as in pbrt-v4.
      vec2 st = map_texture_2d(tex, ctx).st;
      const RGB* v = tex.corners;  // v00, v01, v10, v11
      RGB r = (1 - st.x) * (1 - st.y) * v[0] + st.x * (1 - st.y) * v[2] + (1 - st.x) * st.y * v[1] +
              st.x * st.y * v[3];
      return first<T>(r);
    }
    case TextureKind::Dots:
      return inside_polka_dot(map_texture_2d(tex, ctx).st) ? eval_child<T>(scene, tex.tex1, 0.0f, ctx)
                                                           : eval_child<T>(scene, tex.tex2, 1.0f, ctx);
    case TextureKind::FBm:
      return T(fbm(tex.texture_from_render.point(ctx.p), vec3(0.0f), vec3(0.0f), tex.roughness, tex.octaves));
    case TextureKind::Wrinkled:
      return T(turbulence(tex.texture_from_render.point(ctx.p), vec3(0.0f), vec3(0.0f), tex.roughness, tex.octaves));
    case TextureKind::Windy: {
      vec3 p = tex.texture_from_render.point(ctx.p);
      float wind = fbm(0.1f * p, vec3(0.0f), vec3(0.0f), 0.5f, 3);
      float wave = fbm(p, vec3(0.0f), vec3(0.0f), 0.5f, 6);
      return T(std::abs(wind) * wave);
    }
    case TextureKind::Marble:
      return first<T>(marble(tex, ctx));
  }
  return T(0.0f);
}

}  // namespace

RGB eval_texture(const Scene& scene, int texture, const TextureEvalContext& ctx) {
  return eval<RGB>(scene, texture, ctx);
}

float eval_float_texture(const Scene& scene, int texture, const TextureEvalContext& ctx) {
  return eval<float>(scene, texture, ctx);
}

}  // namespace theia
