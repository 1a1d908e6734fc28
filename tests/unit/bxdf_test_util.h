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
  BxDF b;
  b.kind = BxDFKind::Conductor;
  b.conductor.distrib = {ax, ay};
  b.conductor.eta = eta;
  b.conductor.k = k;
  return b;
}
// A conductor whose Fresnel term is 1 to float precision (k >> 1).
inline BxDF perfect_mirror(float alpha) { return conductor(alpha, alpha, RGB(1.0f), RGB(1e4f)); }
inline BxDF dielectric(float alpha, float eta) {
  BxDF b;
  b.kind = BxDFKind::Dielectric;
  b.dielectric.distrib = {alpha, alpha};
  b.dielectric.eta = eta;
  return b;
}
inline BxDF diffuse(RGB r) {
  BxDF b;
  b.kind = BxDFKind::Diffuse;
  b.diffuse.r = r;
  return b;
}
inline BxDF diffuse_transmission(RGB r, RGB t) {
  BxDF b;
  b.kind = BxDFKind::DiffuseTransmission;
  b.diffuse_transmission = {r, t};
  return b;
}
inline BxDF coated_diffuse(float alpha, RGB r, RGB albedo = RGB(0.0f)) {
  BxDF b;
  b.kind = BxDFKind::CoatedDiffuse;
  b.dielectric.distrib = {alpha, alpha};
  b.dielectric.eta = 1.5f;
  b.diffuse.r = r;
  b.layer.albedo = albedo;
  return b;
}
inline BxDF coated_conductor(float coat_alpha, float base_alpha) {
  BxDF b = conductor(base_alpha, base_alpha);
  b.kind = BxDFKind::CoatedConductor;
  b.conductor.eta /= 1.5f;
  b.conductor.k /= 1.5f;
  b.dielectric.distrib = {coat_alpha, coat_alpha};
  b.dielectric.eta = 1.5f;
  return b;
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

}  // namespace theia::test
