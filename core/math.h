// Vector math on GLM, plus the few renderer-specific helpers every module needs.
#pragma once

#include <glm/glm.hpp>
#include <glm/gtc/matrix_inverse.hpp>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>

namespace theia {

using glm::dvec3;
using glm::ivec2;
using glm::mat3;
using glm::mat4;
using glm::uvec2;
using glm::vec2;
using glm::vec3;
using glm::vec4;

// Linear RGB radiance / reflectance in the renderer's working colour space
// (linear Rec.2020, D65: see core/color.h for why, and for the conversions).
using RGB = glm::vec3;

inline constexpr float kPi = 3.14159265358979323846f;
inline constexpr float kInvPi = 0.31830988618379067154f;
inline constexpr float kInv2Pi = 0.15915494309189533577f;
inline constexpr float kInv4Pi = 0.07957747154594766788f;
inline constexpr float kInfinity = std::numeric_limits<float>::infinity();
inline constexpr float kOneMinusEpsilon = 0x1.fffffep-1f;

inline float sqr(float x) { return x * x; }

// a * b + c with one rounding where the target has FMA instructions, two
// where it has none.  GCC fuses such sums where it can, but which of a sum's
// products it fuses may differ between a function and the same arithmetic
// in a vectorized loop; code that must give the same bits both ways writes
// its fusions out with this.  (Without FMA, std::fma would be a slow library
// call, and GCC fuses nothing either.)
inline float mul_add(float a, float b, float c) {
#if defined(__FMA__)
  return std::fma(a, b, c);
#else
  return a * b + c;
#endif
}

// cos and sin of an angle within pi / 4 of zero, by their Taylor polynomials
// (within 2e-9 of the exact values there; float rounding adds an ulp or
// two).  The sampling warps turn every random angle through these: libm's
// sincosf call was 3% of a render, the polynomials are a few FMAs inline.
inline vec2 cos_sin_octant(float a) {
  const float a2 = a * a;
  const float s = a * (1.0f + a2 * (-1.0f / 6.0f + a2 * (1.0f / 120.0f + a2 * (-1.0f / 5040.0f + a2 * (1.0f / 362880.0f)))));
  const float c = 1.0f + a2 * (-0.5f + a2 * (1.0f / 24.0f + a2 * (-1.0f / 720.0f + a2 * (1.0f / 40320.0f +
                                                                                        a2 * (-1.0f / 3628800.0f)))));
  return {c, s};
}

// cos and sin of 2 pi u, for |u| < 2^20 (a sample's turn, u in [0, 1)): the
// nearest quarter turn exactly, the rest by the octant polynomials.  No
// branch: a random angle's quadrant would mispredict three times in four.
inline vec2 cos_sin_turn(float u) {
  const float x = 4.0f * u;
  const long k = std::lrint(x);  // one conversion instruction (math errno is off)
  const vec2 cs = cos_sin_octant((x - float(k)) * (kPi / 2.0f));
  // The quadrant turns (cos, sin) by arithmetic (exact: weights 0 and 1, signs +-1).
  const float odd = float(k & 1), sign = 1.0f - float(k & 2);
  const float even = 1.0f - odd;
  return sign * vec2(even * cs.x - odd * cs.y, even * cs.y + odd * cs.x);
}
inline float safe_sqrt(float x) { return std::sqrt(std::max(0.0f, x)); }
inline float safe_acos(float x) { return std::acos(std::clamp(x, -1.0f, 1.0f)); }
inline float radians(float deg) { return deg * (kPi / 180.0f); }

// std::nextafter(v, +-infinity) without the libm call (a shading point makes
// up to three per ray origin): the neighbouring float by its bit pattern.
// Equal to nextafter for every input, -0, infinities and NaN included
// (tests/unit/test_math.cpp).
inline float next_float_up(float v) {
  if (std::isinf(v) && v > 0.0f) return v;
  if (v == 0.0f) v = 0.0f;  // -0 steps up like +0
  uint32_t bits = std::bit_cast<uint32_t>(v);
  bits = v >= 0.0f ? bits + 1 : bits - 1;
  return std::isnan(v) ? v : std::bit_cast<float>(bits);
}
inline float next_float_down(float v) {
  if (std::isinf(v) && v < 0.0f) return v;
  if (v == 0.0f) v = -0.0f;  // +0 steps down like -0
  uint32_t bits = std::bit_cast<uint32_t>(v);
  bits = v > 0.0f ? bits - 1 : bits + 1;
  return std::isnan(v) ? v : std::bit_cast<float>(bits);
}
// next_float_up(v) where `side` > 0, next_float_down(v) where it is < 0, v
// itself where it is 0 or NaN: without branches, for ray origins pushed off
// a surface, whose offsets' signs are a coin flip per component (branches on
// them were mispredicted about half the time).
inline float next_float_toward(float v, float side) {
  const uint32_t bits = std::bit_cast<uint32_t>(v);
  const bool up = side > 0.0f, down = side < 0.0f, negative = (bits >> 31) != 0;
  const bool outward = up != negative;  // the step moves away from zero
  const uint32_t stepped = (bits & 0x7fffffffu) == 0 ? (up ? 1u : 0x80000001u) : bits + (outward ? 1u : ~0u);
  const bool keep = !(up || down) || std::isnan(v) || (std::isinf(v) && outward);
  return keep ? v : std::bit_cast<float>(stepped);
}

// Y of a working-space (Rec.2020) colour.
inline float luminance(const RGB& c) { return 0.2627002f * c.x + 0.6779981f * c.y + 0.0593017f * c.z; }
inline float max_component(const RGB& c) { return std::max(c.x, std::max(c.y, c.z)); }
inline bool is_black(const RGB& c) { return c.x == 0.0f && c.y == 0.0f && c.z == 0.0f; }
inline bool is_finite(const RGB& c) {
  return std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z);
}

// Orthonormal basis around a unit vector (Duff et al. 2017, branchless).
struct Frame {
  vec3 s, t, n;

  static Frame from_z(const vec3& n) {
    float sign = std::copysign(1.0f, n.z);
    float a = -1.0f / (sign + n.z);
    float b = n.x * n.y * a;
    return {vec3(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x), vec3(b, sign + n.y * n.y * a, -n.y), n};
  }
  vec3 to_local(const vec3& v) const { return {glm::dot(v, s), glm::dot(v, t), glm::dot(v, n)}; }
  vec3 from_local(const vec3& v) const { return s * v.x + t * v.y + n * v.z; }
};

// Affine transform with its inverse kept alongside, as pbrt-v4 does, so that
// normals and inverse mappings never need a fresh matrix inversion.
struct Transform {
  mat4 m{1.0f};
  mat4 m_inv{1.0f};

  Transform() = default;
  explicit Transform(const mat4& mat) : m(mat), m_inv(glm::inverse(mat)) {}
  Transform(const mat4& mat, const mat4& inv) : m(mat), m_inv(inv) {}

  vec3 point(const vec3& p) const {
    vec4 r = m * vec4(p, 1.0f);
    return r.w == 1.0f ? vec3(r) : vec3(r) / r.w;
  }
  vec3 vector(const vec3& v) const { return mat3(m) * v; }
  // Normals transform by the inverse transpose.
  vec3 normal(const vec3& n) const { return glm::transpose(mat3(m_inv)) * n; }
  Transform inverse() const { return {m_inv, m}; }
  bool swaps_handedness() const { return glm::determinant(mat3(m)) < 0.0f; }
  bool is_identity() const { return m == mat4(1.0f); }
  friend Transform operator*(const Transform& a, const Transform& b) { return {a.m * b.m, b.m_inv * a.m_inv}; }
};

// Lock-free accumulation into buffers that many threads splat into.
inline void atomic_add(float& target, float v) { std::atomic_ref<float>(target).fetch_add(v, std::memory_order_relaxed); }

}  // namespace theia
