// Warps from the unit square to the domains a renderer samples, with their
// pdfs, and tabulated 1D distributions.  Every warp here has a chi-square test
// against its pdf in tests/unit/test_sampling.cpp.
#pragma once

#include "core/math.h"

#include <span>
#include <vector>

namespace theia {

// ---------------------------------------------------------------- warps

inline vec2 sample_uniform_disk_concentric(vec2 u) {
  vec2 o = 2.0f * u - vec2(1.0f);
  if (o.x == 0.0f && o.y == 0.0f) return vec2(0.0f);
  // The angle is (pi / 4) (o.y / o.x) where |o.x| is the larger, else pi / 2
  // less (pi / 4) (o.x / o.y): an octant's cos and sin, swapped for the
  // second.  Selects, not branches: the choice is a coin flip.
  const bool x_major = std::abs(o.x) > std::abs(o.y);
  const float r = x_major ? o.x : o.y, minor = x_major ? o.y : o.x;
  const vec2 cs = cos_sin_octant((kPi / 4.0f) * (minor / r));
  return r * vec2(x_major ? cs.x : cs.y, x_major ? cs.y : cs.x);
}

inline vec3 sample_cosine_hemisphere(vec2 u) {
  vec2 d = sample_uniform_disk_concentric(u);
  float z = safe_sqrt(1.0f - d.x * d.x - d.y * d.y);
  return {d.x, d.y, z};
}
// sample_cosine_hemisphere(vec2(u[i])) for every i, bit for bit, several
// lanes at a time (the loop vectorizes): the wavefront makes a chunk of
// hits' diffuse directions at once, off each hit's chain of dependent steps.
inline void sample_cosine_hemisphere(std::span<const vec4> u, std::span<vec3> out) {
  for (size_t i = 0; i < u.size(); ++i) out[i] = sample_cosine_hemisphere(vec2(u[i]));
}
inline float cosine_hemisphere_pdf(float cos_theta) { return std::max(cos_theta, 0.0f) * kInvPi; }

inline vec3 sample_uniform_sphere(vec2 u) {
  float z = 1.0f - 2.0f * u.x;
  float r = safe_sqrt(1.0f - z * z);
  const vec2 cs = cos_sin_turn(u.y);
  return {r * cs.x, r * cs.y, z};
}
inline constexpr float uniform_sphere_pdf() { return kInv4Pi; }

inline vec3 sample_uniform_hemisphere(vec2 u) {
  float z = u.x;
  float r = safe_sqrt(1.0f - z * z);
  const vec2 cs = cos_sin_turn(u.y);
  return {r * cs.x, r * cs.y, z};
}
inline constexpr float uniform_hemisphere_pdf() { return kInv2Pi; }

// Uniform over the cone of directions within acos(cos_theta_max) of +z.
inline vec3 sample_uniform_cone(vec2 u, float cos_theta_max) {
  float cos_theta = (1.0f - u.x) + u.x * cos_theta_max;
  float sin_theta = safe_sqrt(1.0f - cos_theta * cos_theta);
  const vec2 cs = cos_sin_turn(u.y);
  return {cs.x * sin_theta, cs.y * sin_theta, cos_theta};
}
inline float uniform_cone_pdf(float cos_theta_max) { return 1.0f / (2.0f * kPi * (1.0f - cos_theta_max)); }

// Barycentrics (b0, b1) uniform over a triangle (Heitz 2019: low distortion).
inline vec2 sample_uniform_triangle(vec2 u) {
  float b0, b1;
  if (u.x < u.y) {
    b0 = u.x / 2.0f;
    b1 = u.y - b0;
  } else {
    b1 = u.y / 2.0f;
    b0 = u.x - b1;
  }
  return {b0, b1};
}

// Tent on [-r, r] (the triangle filter's shape).
// Selects, not branches: which half u falls in is a coin flip (every camera
// ray draws two).
inline float sample_tent(float u, float r) {
  const bool left = u < 0.5f;
  const float s = r * safe_sqrt(left ? u * 2.0f : 1.0f - (u - 0.5f) * 2.0f);
  return left ? -r + s : r - s;
}
inline float tent_pdf(float x, float r) { return std::abs(x) >= r ? 0.0f : (1.0f / r - std::abs(x) / (r * r)); }

// ---------------------------------------------------------------- sphere parameterisations

// Clarberg's equal-area octahedral map of the unit square onto the unit
// sphere (pbrt-v4's EqualAreaSquareToSphere): equal areas of the square map to
// equal solid angles, so a pixel of a square environment map covers
// 4 pi / (width * height) steradians wherever it is.  The centre of the
// square is +z, its corners -z; the inner diamond |2u-1| + |2v-1| <= 1 is the
// upper hemisphere.
inline vec3 equal_area_square_to_sphere(vec2 p) {
  float u = 2.0f * p.x - 1.0f, v = 2.0f * p.y - 1.0f;
  float up = std::abs(u), vp = std::abs(v);
  float signed_distance = 1.0f - (up + vp);  // > 0 inside the diamond (upper hemisphere)
  float r = 1.0f - std::abs(signed_distance);
  // phi = (pi / 4) turns_8 within the quadrant, turns_8 in [0, 2].
  float turns_8 = r == 0.0f ? 1.0f : (vp - up) / r + 1.0f;
  const vec2 cs = cos_sin_turn(turns_8 * 0.125f);
  float z = std::copysign(1.0f - r * r, signed_distance);
  float s = r * safe_sqrt(2.0f - r * r);
  return {std::copysign(cs.x, u) * s, std::copysign(cs.y, v) * s, z};
}

// The square's point for a unit vector d, from r = sqrt(1 - |d.z|) and phi,
// the angle within d's quadrant as a fraction of pi / 2.
inline vec2 equal_area_square_from_quadrant(const vec3& d, float r, float phi) {
  float v = phi * r, u = r - v;
  if (d.z < 0.0f) {
    float t = u;
    u = 1.0f - v;
    v = 1.0f - t;
  }
  u = std::copysign(u, d.x);
  v = std::copysign(v, d.y);
  return {std::clamp(0.5f * (u + 1.0f), 0.0f, 1.0f), std::clamp(0.5f * (v + 1.0f), 0.0f, 1.0f)};
}

// The inverse of equal_area_square_to_sphere for a unit vector.
inline vec2 equal_area_sphere_to_square(const vec3& d) {
  float x = std::abs(d.x), y = std::abs(d.y), z = std::abs(d.z);
  float r = safe_sqrt(1.0f - z);
  float phi = (x == 0.0f && y == 0.0f) ? 0.0f : std::atan2(y, x) * (2.0f / kPi);
  return equal_area_square_from_quadrant(d, r, phi);
}

// The same with the angle from a polynomial (Clarberg, "Fast Equal-Area
// Mapping of the (Hemi)Sphere using SIMD", JGT 2008: a minimax fit of
// atan(b) 2 / pi on [0, 1], within 4.1e-6 of it, so (u, v) moves by at most
// 2.1e-6) in place of atan2f, ~130 of the ~345 instructions of an
// environment lookup, which every escaped ray and every MIS weight of a BSDF
// sample against the map makes.  pbrt-v4's environment lookups use the same
// polynomial.  Not an exact inverse: where a round trip matters, the above.
inline vec2 equal_area_sphere_to_square_fast(const vec3& d) {
  const float x = std::abs(d.x), y = std::abs(d.y), z = std::abs(d.z);
  const float r = safe_sqrt(1.0f - z);
  const float a = std::max(x, y);
  const float b = a == 0.0f ? 0.0f : std::min(x, y) / a;
  float phi = 0.406758566246788489601959989e-5f +
              b * (0.636226545274016134946890922156f +
                   b * (0.61572017898280213493197203466e-2f +
                        b * (-0.247333733281268944196501420480f +
                             b * (0.881770664775316294736387951347e-1f +
                                  b * (0.419038818029165735901852432784e-1f +
                                       b * -0.251390972343483509333252996350e-1f)))));
  if (x < y) phi = 1.0f - phi;
  return equal_area_square_from_quadrant(d, r, phi);
}

// Latitude-longitude (equirectangular) map, pbrt-v3's convention: u = phi /
// 2 pi with phi measured from +x towards +y, v = theta / pi from +z (row 0 of
// the image is the +z pole).  Its Jacobian is d(omega) = 2 pi^2 sin(theta) du dv.
inline vec3 equirect_to_sphere(vec2 p) {
  float phi = 2.0f * kPi * p.x, theta = kPi * p.y;
  float st = std::sin(theta);
  return {st * std::cos(phi), st * std::sin(phi), std::cos(theta)};
}
inline vec2 sphere_to_equirect(const vec3& d) {
  float phi = std::atan2(d.y, d.x);
  if (phi < 0.0f) phi += 2.0f * kPi;
  float theta = std::acos(std::clamp(d.z, -1.0f, 1.0f));
  return {std::clamp(phi * kInv2Pi, 0.0f, 1.0f), std::clamp(theta * kInvPi, 0.0f, 1.0f)};
}

// ---------------------------------------------------------------- MIS

inline float power_heuristic(float nf, float f_pdf, float ng, float g_pdf) {
  float f = nf * f_pdf, g = ng * g_pdf;
  if (std::isinf(f)) return 1.0f;
  if (f == 0.0f && g == 0.0f) return 0.0f;
  // In ratio form: f * f overflows above ~1e19 and underflows below ~1e-19,
  // which gave weights of 1 + 1 or 0 / 0.
  if (f >= g) {
    float r = g / f;
    return 1.0f / (1.0f + r * r);
  }
  float r = f / g;
  return (r * r) / (1.0f + r * r);
}

// ---------------------------------------------------------------- tabulated distributions

// Piecewise-constant distribution over [0, 1) from non-negative weights.
// Zero total weight falls back to uniform, so sampling never divides by zero.
struct Distribution1D {
  std::vector<float> func;  // |f| per cell
  std::vector<float> cdf;   // size n + 1, cdf[n] == 1
  float integral = 0.0f;    // integral of func over [0, 1)
  // Guide table (the cutpoint method), from 16 cells: for each of min(n, kGuideBuckets)
  // equal slices of u, the first and last cell a u in it can fall in, so a
  // lookup searches those few cells instead of the whole cdf (same cell).
  std::vector<uint32_t> guide;  // pairs: first, last
  static constexpr size_t kGuideBuckets = 64;

  Distribution1D() = default;
  explicit Distribution1D(std::span<const float> f);

  size_t size() const { return func.size(); }
  // Returns x in [0, 1); writes the density at x and the cell index.
  float sample_continuous(float u, float* pdf, int* offset = nullptr) const;
  // Returns a cell index with probability func[i] / sum(func).
  int sample_discrete(float u, float* pmf = nullptr, float* u_remapped = nullptr) const;
  float discrete_pmf(int i) const;
  // Largest i with cdf[i] <= u, clamped to a valid cell.
  int find_interval(float u) const;
};

}  // namespace theia
