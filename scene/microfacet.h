// Scattering building blocks in a local shading frame (z = normal): the
// Trowbridge-Reitz (GGX) microfacet distribution with visible-normal sampling,
// Fresnel terms, refraction and the Henyey-Greenstein phase function.
// Semantics follow pbrt-v4 (Pharr, Jakob, Humphreys, 4th ed., ch. 9 and 11):
// directions point away from the surface, eta is the ratio of the inside to
// the outside index, and alpha < 1e-3 counts as a perfectly smooth surface.
#pragma once

#include "core/math.h"

#include <complex>

namespace theia {

inline bool same_hemisphere(const vec3& a, const vec3& b) { return a.z * b.z > 0.0f; }
inline vec3 reflect(const vec3& wo, const vec3& n) { return -wo + 2.0f * glm::dot(wo, n) * n; }
inline vec3 face_forward(const vec3& v, const vec3& ref) { return glm::dot(v, ref) < 0.0f ? -v : v; }

// Refraction of wi through the interface with normal n (either side) and
// relative index eta; false on total internal reflection.  *etap receives
// the relative index actually crossed (eta or 1/eta).
inline bool refract(const vec3& wi, vec3 n, float eta, float* etap, vec3* wt) {
  float cos_i = glm::dot(n, wi);
  if (cos_i < 0.0f) {
    eta = 1.0f / eta;
    cos_i = -cos_i;
    n = -n;
  }
  float sin2_i = std::max(0.0f, 1.0f - cos_i * cos_i);
  float sin2_t = sin2_i / (eta * eta);
  if (sin2_t >= 1.0f) return false;
  float cos_t = safe_sqrt(1.0f - sin2_t);
  *wt = -wi / eta + (cos_i / eta - cos_t) * n;
  *etap = eta;
  return true;
}

// Unpolarised Fresnel reflectance of a dielectric; cos_i < 0 means from inside.
inline float fresnel_dielectric(float cos_i, float eta) {
  cos_i = std::clamp(cos_i, -1.0f, 1.0f);
  if (cos_i < 0.0f) {
    eta = 1.0f / eta;
    cos_i = -cos_i;
  }
  float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
  if (sin2_t >= 1.0f) return 1.0f;
  float cos_t = safe_sqrt(1.0f - sin2_t);
  float r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
  float r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
  return 0.5f * (r_parl * r_parl + r_perp * r_perp);
}

// Fresnel reflectance of a conductor with complex index eta + i k.
inline float fresnel_complex(float cos_i, float eta, float k) {
  using C = std::complex<float>;
  cos_i = std::clamp(cos_i, 0.0f, 1.0f);
  C e(eta, k);
  float sin2_i = 1.0f - cos_i * cos_i;
  C sin2_t = sin2_i / (e * e);
  C cos_t = std::sqrt(C(1.0f) - sin2_t);
  C r_parl = (e * cos_i - cos_t) / (e * cos_i + cos_t);
  C r_perp = (cos_i - e * cos_t) / (cos_i + e * cos_t);
  return 0.5f * (std::norm(r_parl) + std::norm(r_perp));
}
inline RGB fresnel_complex(float cos_i, const RGB& eta, const RGB& k) {
  return {fresnel_complex(cos_i, eta.x, k.x), fresnel_complex(cos_i, eta.y, k.y), fresnel_complex(cos_i, eta.z, k.z)};
}

// ---------------------------------------------------------------- Trowbridge-Reitz

struct TrowbridgeReitz {
  float alpha_x = 0.0f, alpha_y = 0.0f;

  // pbrt-v4's "remaproughness": user roughness to alpha.
  static float roughness_to_alpha(float roughness) { return std::sqrt(std::max(roughness, 0.0f)); }
  bool effectively_smooth() const { return std::max(alpha_x, alpha_y) < 1e-3f; }
  float roughness() const { return std::max(alpha_x, alpha_y); }

  // D and lambda in Cartesian form (Heitz 2014, "Understanding the
  // masking-shadowing function", eqs. 85 and 86), equal for unit vectors to
  // pbrt-v4's form in tan(theta), cos(phi) and sin(phi), which costs two
  // square roots and five divisions more per call; the layered BxDFs' random
  // walks call them several times per bounce.
  float D(const vec3& wm) const {
    const float ax2 = sqr(alpha_x), ay2 = sqr(alpha_y), z2 = sqr(wm.z);
    if (sqr(z2) < 1e-16f) return 0.0f;
    // (x^2 / ax^2 + y^2 / ay^2 + z^2) ax^2 ay^2
    const float s = sqr(wm.x) * ay2 + sqr(wm.y) * ax2 + z2 * (ax2 * ay2);
    return ax2 * ay2 * alpha_x * alpha_y / (kPi * sqr(s));
  }
  float lambda(const vec3& w) const {
    const float z2 = sqr(w.z);
    if (z2 == 0.0f) return 0.0f;
    // alpha(phi)^2 tan^2(theta)
    const float a2t2 = (sqr(w.x) * sqr(alpha_x) + sqr(w.y) * sqr(alpha_y)) / z2;
    return (std::sqrt(1.0f + a2t2) - 1.0f) * 0.5f;
  }
  float G1(const vec3& w) const { return 1.0f / (1.0f + lambda(w)); }
  float G(const vec3& wo, const vec3& wi) const { return G(lambda(wo), wi); }
  // Distribution of normals visible from w, and the density sample_wm draws them with.
  float D(const vec3& w, const vec3& wm) const { return pdf(w, wm, D(wm), lambda(w)); }
  float pdf(const vec3& w, const vec3& wm) const { return D(w, wm); }
  // The same from D(wm) and lambda(w) already at hand: a sampled normal needs
  // both its pdf and f, and each of D and lambda costs square roots and divisions.
  float pdf(const vec3& w, const vec3& wm, float d_wm, float lambda_w) const {
    return 1.0f / (1.0f + lambda_w) / std::abs(w.z) * d_wm * std::abs(glm::dot(w, wm));
  }
  float G(float lambda_wo, const vec3& wi) const { return 1.0f / (1.0f + lambda_wo + lambda(wi)); }

  // Visible-normal sampling (Heitz 2018), as pbrt-v4 does it.
  vec3 sample_wm(const vec3& w, vec2 u) const {
    vec3 wh = glm::normalize(vec3(alpha_x * w.x, alpha_y * w.y, w.z));
    if (wh.z < 0.0f) wh = -wh;
    vec3 t1 = wh.z < 0.99999f ? glm::normalize(glm::cross(vec3(0, 0, 1), wh)) : vec3(1, 0, 0);
    vec3 t2 = glm::cross(wh, t1);
    vec2 p = std::sqrt(u.x) * cos_sin_turn(u.y);
    float h = std::sqrt(1.0f - p.x * p.x);
    float s = (1.0f + wh.z) * 0.5f;
    p.y = (1.0f - s) * h + s * p.y;
    float pz = safe_sqrt(1.0f - glm::dot(p, p));
    vec3 nh = p.x * t1 + p.y * t2 + pz * wh;
    return glm::normalize(vec3(alpha_x * nh.x, alpha_y * nh.y, std::max(1e-6f, nh.z)));
  }
};

// ---------------------------------------------------------------- Henyey-Greenstein

// pbrt-v4 convention: cos_theta = dot(wo, wi) with both pointing away, so
// g > 0 (forward scattering) peaks at wi = -wo.
inline float henyey_greenstein(float cos_theta, float g) {
  float denom = 1.0f + g * g + 2.0f * g * cos_theta;
  return kInv4Pi * (1.0f - g * g) / (denom * safe_sqrt(denom));
}
inline vec3 sample_henyey_greenstein(const vec3& wo, float g, vec2 u, float* pdf) {
  float cos_theta;
  if (std::abs(g) < 1e-3f) cos_theta = 1.0f - 2.0f * u.x;
  else cos_theta = -1.0f / (2.0f * g) * (1.0f + g * g - sqr((1.0f - g * g) / (1.0f + g - 2.0f * g * u.x)));
  cos_theta = std::clamp(cos_theta, -1.0f, 1.0f);
  float sin_theta = safe_sqrt(1.0f - cos_theta * cos_theta);
  const vec2 cs = cos_sin_turn(u.y);
  Frame f = Frame::from_z(wo);
  *pdf = henyey_greenstein(cos_theta, g);
  return f.from_local(vec3(sin_theta * cs.x, sin_theta * cs.y, cos_theta));
}

}  // namespace theia
