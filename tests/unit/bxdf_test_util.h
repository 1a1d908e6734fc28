// BxDF constructors and estimators shared by the BxDF tests.
#pragma once

#include "core/sampling.h"
#include "scene/bxdfs.h"

#include <random>

namespace theia::test {

inline vec3 dir_at(float theta, float phi = 0.3f) {
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

inline BxDF conductor(float ax, float ay, RGB eta = RGB(0.2f, 0.9f, 1.1f), RGB k = RGB(3.9f, 2.4f, 2.2f)) {
  return ConductorBxDF{{ax, ay}, eta, k};
}
// A conductor whose Fresnel term is 1 to float precision (k >> 1).
inline BxDF perfect_mirror(float alpha) { return conductor(alpha, alpha, RGB(1.0f), RGB(1e4f)); }
inline BxDF dielectric(float alpha, float eta) { return DielectricBxDF{{alpha, alpha}, eta}; }
inline BxDF diffuse(RGB r) { return DiffuseBxDF{r}; }
inline BxDF diffuse_transmission(RGB r, RGB t) { return DiffuseTransmissionBxDF{r, t}; }
inline BxDF coated_diffuse(float alpha, RGB r, RGB albedo = RGB(0.0f)) {
  LayerParams layer;
  layer.albedo = albedo;
  return CoatedDiffuseBxDF{DielectricBxDF{{alpha, alpha}, 1.5f}, DiffuseBxDF{r}, layer};
}
// pbrt-v4's coatedconductor divides the conductor's eta and k by the coat's.
inline BxDF coated_conductor(float coat_alpha, float base_alpha, float eta = 1.5f) {
  ConductorBxDF base = conductor(base_alpha, base_alpha).conductor;
  base.eta /= eta;
  base.k /= eta;
  return CoatedConductorBxDF{DielectricBxDF{{coat_alpha, coat_alpha}, eta}, base, LayerParams{}};
}
// The coat and the medium of either layered kind.
inline DielectricBxDF& coat_of(BxDF& b) {
  return b.kind == BxDFKind::CoatedDiffuse ? b.coated_diffuse.top : b.coated_conductor.top;
}
inline const DielectricBxDF& coat_of(const BxDF& b) {
  return b.kind == BxDFKind::CoatedDiffuse ? b.coated_diffuse.top : b.coated_conductor.top;
}
inline LayerParams& layer_of(BxDF& b) {
  return b.kind == BxDFKind::CoatedDiffuse ? b.coated_diffuse.layer : b.coated_conductor.layer;
}

// Monte Carlo albedo from the BxDF's own samples: mean and standard error of
// f |cos| / pdf (the largest over the channels).
struct Estimate {
  RGB mean{0.0f};
  float stderr_max = 0.0f;
};
inline Estimate albedo_by_sampling(const BxDF& b, const vec3& wo, int n, TransportMode mode, uint64_t seed = 1) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u01(0.0f, 0.99999994f);
  glm::dvec3 sum(0.0), sum2(0.0);
  for (int i = 0; i < n; ++i) {
    auto s = bxdf_sample(b, wo, u01(rng), vec2(u01(rng), u01(rng)), mode);
    if (!s) continue;
    glm::dvec3 w = glm::dvec3(s->f * std::abs(s->wi.z) / s->pdf);
    sum += w;
    sum2 += w * w;
  }
  Estimate e;
  glm::dvec3 mean = sum / double(n), var = sum2 / double(n) - mean * mean;
  e.mean = RGB(mean);
  e.stderr_max = float(std::sqrt(std::max({var.x, var.y, var.z, 0.0}) / n));
  return e;
}

// Directional albedo of a Trowbridge-Reitz reflector with F = 1, by a dense
// deterministic quadrature written independently of scene/microfacet.h (double
// precision, isotropic): over microfacet normals wm, with wi = reflect(wo, wm)
// and d wi = 4 |wo.wm| d wm,
//   E(wo) = integral D(wm) G(wo, wi) |wo.wm| / cos(theta_o) d wm   (wi above).
// theta_m is parameterised by u in (0, 1) with tan(theta_m) = alpha sqrt(u / (1 - u)),
// which puts the midpoint nodes where D is large for any alpha.
inline double ggx_albedo_quadrature(double alpha, double theta_o, int n) {
  const double pi = 3.14159265358979323846, a2 = alpha * alpha;
  const double so = std::sin(theta_o), co = std::cos(theta_o);
  auto lambda = [&](double cos_t) { return (std::sqrt(1.0 + a2 * (1.0 - cos_t * cos_t) / (cos_t * cos_t)) - 1.0) / 2.0; };
  double sum = 0.0;
  for (int i = 0; i < n; ++i) {
    double u = (i + 0.5) / n, t = alpha * std::sqrt(u / (1.0 - u));
    double theta = std::atan(t), ct = std::cos(theta), st = std::sin(theta);
    double dtheta_du = alpha / (2.0 * std::sqrt(u) * std::pow(1.0 - u, 1.5)) / (1.0 + t * t);
    double D = a2 / (pi * std::pow(ct, 4) * sqr(a2 + t * t));
    for (int j = 0; j < n; ++j) {
      double phi = 2.0 * pi * (j + 0.5) / n;
      double o_dot_m = so * st * std::cos(phi) + co * ct;  // wo = (sin, 0, cos)
      double wi_z = 2.0 * o_dot_m * ct - co;
      if (o_dot_m <= 0.0 || wi_z <= 0.0) continue;
      double G = 1.0 / (1.0 + lambda(co) + lambda(wi_z));
      sum += D * G * o_dot_m / co * st * dtheta_du / n * (2.0 * pi / n);
    }
  }
  return sum;
}

}  // namespace theia::test
