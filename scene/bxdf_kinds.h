// The BxDF kinds the layered walk (scene/layered.cpp) builds its coat and base
// from, defined inline so that the walk's many calls to them compile with
// their sample flags known and without a call or an optional copied per
// interface event (the walk's events are most of a coated material's cost).
// Everything else reaches them through scene/bxdfs.h's dispatch on the kind.
#pragma once

#include "core/sampling.h"
#include "scene/bxdfs.h"

#include <type_traits>

namespace theia {

namespace bxdf_kinds {

// ---------------------------------------------------------------- diffuse

inline RGB f_of(const DiffuseBxDF& b, const vec3& wo, const vec3& wi, TransportMode) {
  return same_hemisphere(wo, wi) ? b.r * kInvPi : RGB(0.0f);
}
inline float pdf_of(const DiffuseBxDF&, const vec3& wo, const vec3& wi, TransportMode, uint8_t flags) {
  if (!(flags & kSampleReflection) || !same_hemisphere(wo, wi)) return 0.0f;
  return cosine_hemisphere_pdf(std::abs(wi.z));
}
// `cosine`: sample_cosine_hemisphere(u), where the caller made it ahead.
inline std::optional<BxDFSample> sample_of(const DiffuseBxDF& b, const vec3& wo, float, vec2 u, TransportMode,
                                    uint8_t flags, const vec3* cosine = nullptr) {
  if (!(flags & kSampleReflection)) return std::nullopt;
  vec3 wi = cosine ? *cosine : sample_cosine_hemisphere(u);
  if (wo.z < 0.0f) wi.z = -wi.z;
  BxDFSample s;
  s.f = b.r * kInvPi;
  s.wi = wi;
  s.pdf = cosine_hemisphere_pdf(std::abs(wi.z));
  s.flags = kBxDFReflection | kBxDFDiffuse;
  return s;
}
inline uint8_t flags_of(const DiffuseBxDF& b) { return is_black(b.r) ? 0 : (kBxDFReflection | kBxDFDiffuse); }

// ---------------------------------------------------------------- conductor

inline RGB f_of(const ConductorBxDF& b, const vec3& wo, const vec3& wi, TransportMode) {
  if (!same_hemisphere(wo, wi) || b.distrib.effectively_smooth()) return RGB(0.0f);
  float cos_o = std::abs(wo.z), cos_i = std::abs(wi.z);
  if (cos_i == 0.0f || cos_o == 0.0f) return RGB(0.0f);
  vec3 wm = wi + wo;
  if (glm::dot(wm, wm) == 0.0f) return RGB(0.0f);
  wm = glm::normalize(wm);
  RGB F = conductor_fresnel(std::abs(glm::dot(wo, wm)), b);
  return b.distrib.D(wm) * F * b.distrib.G(wo, wi) / (4.0f * cos_i * cos_o);
}
inline float pdf_of(const ConductorBxDF& b, const vec3& wo, const vec3& wi, TransportMode, uint8_t flags) {
  if (!(flags & kSampleReflection) || !same_hemisphere(wo, wi) || b.distrib.effectively_smooth()) return 0.0f;
  vec3 wm = wo + wi;
  if (glm::dot(wm, wm) == 0.0f) return 0.0f;
  wm = face_forward(glm::normalize(wm), vec3(0, 0, 1));
  return b.distrib.pdf(wo, wm) / (4.0f * std::abs(glm::dot(wo, wm)));
}
inline std::optional<BxDFSample> sample_of(const ConductorBxDF& b, const vec3& wo, float, vec2 u, TransportMode,
                                    uint8_t flags) {
  if (!(flags & kSampleReflection)) return std::nullopt;
  BxDFSample s;
  if (b.distrib.effectively_smooth()) {
    s.wi = vec3(-wo.x, -wo.y, wo.z);
    float c = std::abs(s.wi.z);
    if (c == 0.0f) return std::nullopt;
    s.f = conductor_fresnel(c, b) / c;
    s.pdf = 1.0f;
    s.flags = kBxDFReflection | kBxDFSpecular;
    return s;
  }
  if (wo.z == 0.0f) return std::nullopt;
  vec3 wm = b.distrib.sample_wm(wo, u);
  vec3 wi = reflect(wo, wm);
  if (!same_hemisphere(wo, wi)) return std::nullopt;
  float cos_o = std::abs(wo.z), cos_i = std::abs(wi.z);
  if (cos_i == 0.0f || cos_o == 0.0f) return std::nullopt;
  s.wi = wi;
  const float d_wm = b.distrib.D(wm), lambda_o = b.distrib.lambda(wo);
  s.pdf = b.distrib.pdf(wo, wm, d_wm, lambda_o) / (4.0f * std::abs(glm::dot(wo, wm)));
  RGB F = conductor_fresnel(std::abs(glm::dot(wo, wm)), b);
  s.f = d_wm * F * b.distrib.G(lambda_o, wi) / (4.0f * cos_i * cos_o);
  s.flags = kBxDFReflection | kBxDFGlossy;
  return s;
}
inline uint8_t flags_of(const ConductorBxDF& b) {
  return kBxDFReflection | (b.distrib.effectively_smooth() ? kBxDFSpecular : kBxDFGlossy);
}

// ---------------------------------------------------------------- dielectric

inline uint8_t flags_of(const DielectricBxDF& b) {
  uint8_t f = b.eta == 1.0f ? kBxDFTransmission : (kBxDFReflection | kBxDFTransmission);
  return f | (b.distrib.effectively_smooth() ? kBxDFSpecular : kBxDFGlossy);
}

// The microfacet normal of a (wo, wi) pair and the relative index crossed;
// false for pairs the rough dielectric cannot produce.
inline bool dielectric_half_vector(const DielectricBxDF& b, const vec3& wo, const vec3& wi, vec3* wm, float* etap,
                            bool* reflect_pair) {
  float cos_o = wo.z, cos_i = wi.z;
  *reflect_pair = cos_i * cos_o > 0.0f;
  *etap = 1.0f;
  if (!*reflect_pair) *etap = cos_o > 0.0f ? b.eta : 1.0f / b.eta;
  vec3 m = wi * *etap + wo;
  if (cos_i == 0.0f || cos_o == 0.0f || glm::dot(m, m) == 0.0f) return false;
  m = face_forward(glm::normalize(m), vec3(0, 0, 1));
  // Back-facing microfacets scatter nothing.
  if (glm::dot(m, wi) * cos_i < 0.0f || glm::dot(m, wo) * cos_o < 0.0f) return false;
  *wm = m;
  return true;
}

inline RGB f_of(const DielectricBxDF& b, const vec3& wo, const vec3& wi, TransportMode mode) {
  if (b.eta == 1.0f || b.distrib.effectively_smooth()) return RGB(0.0f);
  vec3 wm;
  float etap;
  bool refl;
  if (!dielectric_half_vector(b, wo, wi, &wm, &etap, &refl)) return RGB(0.0f);
  float F = fresnel_dielectric(glm::dot(wo, wm), b.eta);
  if (refl) return RGB(b.distrib.D(wm) * b.distrib.G(wo, wi) * F / std::abs(4.0f * wi.z * wo.z));
  float denom = sqr(glm::dot(wi, wm) + glm::dot(wo, wm) / etap) * wi.z * wo.z;
  float ft = b.distrib.D(wm) * (1.0f - F) * b.distrib.G(wo, wi) *
             std::abs(glm::dot(wi, wm) * glm::dot(wo, wm) / denom);
  if (mode == TransportMode::Radiance) ft /= sqr(etap);
  return RGB(ft);
}

inline float pdf_of(const DielectricBxDF& b, const vec3& wo, const vec3& wi, TransportMode, uint8_t flags) {
  if (b.eta == 1.0f || b.distrib.effectively_smooth()) return 0.0f;
  vec3 wm;
  float etap;
  bool refl;
  if (!dielectric_half_vector(b, wo, wi, &wm, &etap, &refl)) return 0.0f;
  float R = fresnel_dielectric(glm::dot(wo, wm), b.eta), T = 1.0f - R;
  float pr = (flags & kSampleReflection) ? R : 0.0f, pt = (flags & kSampleTransmission) ? T : 0.0f;
  if (pr == 0.0f && pt == 0.0f) return 0.0f;
  if (refl) return b.distrib.pdf(wo, wm) / (4.0f * std::abs(glm::dot(wo, wm))) * pr / (pr + pt);
  float denom = sqr(glm::dot(wi, wm) + glm::dot(wo, wm) / etap);
  return b.distrib.pdf(wo, wm) * std::abs(glm::dot(wi, wm)) / denom * pt / (pr + pt);
}

inline std::optional<BxDFSample> sample_of(const DielectricBxDF& b, const vec3& wo, float uc, vec2 u, TransportMode mode,
                                    uint8_t flags) {
  BxDFSample s;
  if (b.eta == 1.0f || b.distrib.effectively_smooth()) {
    float R = fresnel_dielectric(wo.z, b.eta), T = 1.0f - R;
    float pr = (flags & kSampleReflection) ? R : 0.0f, pt = (flags & kSampleTransmission) ? T : 0.0f;
    if (pr == 0.0f && pt == 0.0f) return std::nullopt;
    if (uc < pr / (pr + pt)) {
      s.wi = vec3(-wo.x, -wo.y, wo.z);
      s.f = RGB(R / std::abs(s.wi.z));
      s.pdf = pr / (pr + pt);
      s.flags = kBxDFReflection | kBxDFSpecular;
      return s;
    }
    if (!refract(wo, vec3(0, 0, 1), b.eta, &s.eta, &s.wi) || s.wi.z == 0.0f) return std::nullopt;
    float ft = T / std::abs(s.wi.z);
    if (mode == TransportMode::Radiance) ft /= sqr(s.eta);
    s.f = RGB(ft);
    s.pdf = pt / (pr + pt);
    s.flags = kBxDFTransmission | kBxDFSpecular;
    return s;
  }
  if (wo.z == 0.0f) return std::nullopt;
  vec3 wm = b.distrib.sample_wm(wo, u);
  float R = fresnel_dielectric(glm::dot(wo, wm), b.eta), T = 1.0f - R;
  float pr = (flags & kSampleReflection) ? R : 0.0f, pt = (flags & kSampleTransmission) ? T : 0.0f;
  if (pr == 0.0f && pt == 0.0f) return std::nullopt;
  if (uc < pr / (pr + pt)) {
    s.wi = reflect(wo, wm);
    if (!same_hemisphere(wo, s.wi)) return std::nullopt;
    const float d_wm = b.distrib.D(wm), lambda_o = b.distrib.lambda(wo);
    s.pdf = b.distrib.pdf(wo, wm, d_wm, lambda_o) / (4.0f * std::abs(glm::dot(wo, wm))) * pr / (pr + pt);
    s.f = RGB(d_wm * b.distrib.G(lambda_o, s.wi) * R / (4.0f * s.wi.z * wo.z));
    s.flags = kBxDFReflection | kBxDFGlossy;
    return s;
  }
  if (!refract(wo, wm, b.eta, &s.eta, &s.wi) || same_hemisphere(wo, s.wi) || s.wi.z == 0.0f) return std::nullopt;
  const float d_wm = b.distrib.D(wm), lambda_o = b.distrib.lambda(wo);
  float denom = sqr(glm::dot(s.wi, wm) + glm::dot(wo, wm) / s.eta);
  s.pdf = b.distrib.pdf(wo, wm, d_wm, lambda_o) * std::abs(glm::dot(s.wi, wm)) / denom * pt / (pr + pt);
  float ft = T * d_wm * b.distrib.G(lambda_o, s.wi) *
             std::abs(glm::dot(s.wi, wm) * glm::dot(wo, wm) / (s.wi.z * wo.z * denom));
  if (mode == TransportMode::Radiance) ft /= sqr(s.eta);
  s.f = RGB(ft);
  s.flags = kBxDFTransmission | kBxDFGlossy;
  return s;
}

// A sample the path can use: the same test for every entry point.
inline bool usable(const std::optional<BxDFSample>& s) {
  return s && s->pdf != 0.0f && !is_black(s->f) && s->wi.z != 0.0f && is_finite(s->f) && std::isfinite(s->pdf);
}
inline std::optional<BxDFSample> usable_or_none(const std::optional<BxDFSample>& s) {
  if (!usable(s)) return std::nullopt;
  return s;
}

// A direction sampled from one half of a dielectric (flags: reflection or
// transmission alone) and its weight f |cos| / pdf, for a walk that needs
// no more.  With visible normals D cancels, and so does most of the pdf:
// the weight is F G(wo, wi) / G1(wo) by reflection, (1 - F) G / G1 (over
// eta^2 for radiance) through, where f and pdf apart cost five divisions
// more.  The same directions and refusals as bxdf_sample's (and for a
// smooth interface, its very sample), but one: at a grazing wi whose f or
// pdf alone would overflow, the weight (G -> 0 there) is finite and kept.
struct DirectionWeight {
  vec3 wi;
  RGB weight;
};
inline std::optional<DirectionWeight> sample_one_half(const DielectricBxDF& b, const vec3& wo, vec2 u, TransportMode mode,
                                                      uint8_t half) {
  if (b.eta == 1.0f || b.distrib.effectively_smooth()) {
    auto s = usable_or_none(sample_of(b, wo, 0.5f, u, mode, half));
    if (!s) return std::nullopt;
    return DirectionWeight{s->wi, s->f * std::abs(s->wi.z) / s->pdf};
  }
  if (wo.z == 0.0f) return std::nullopt;
  const vec3 wm = b.distrib.sample_wm(wo, u);
  // D(wm) is zero there (TrowbridgeReitz::D): f and pdf would be.
  if (sqr(sqr(wm.z)) < 1e-16f) return std::nullopt;
  const float R = fresnel_dielectric(glm::dot(wo, wm), b.eta);
  DirectionWeight d;
  float F;
  if (half & kSampleReflection) {
    F = R;
    d.wi = reflect(wo, wm);
    if (!same_hemisphere(wo, d.wi)) return std::nullopt;
  } else {
    F = 1.0f - R;
    float etap;
    if (!refract(wo, wm, b.eta, &etap, &d.wi) || same_hemisphere(wo, d.wi)) return std::nullopt;
    if (mode == TransportMode::Radiance) F /= sqr(etap);
  }
  if (F == 0.0f || d.wi.z == 0.0f) return std::nullopt;
  const float lambda_o = b.distrib.lambda(wo);
  d.weight = RGB(F * (1.0f + lambda_o) * b.distrib.G(lambda_o, d.wi));
  if (!is_finite(d.weight) || is_black(d.weight)) return std::nullopt;
  return d;
}

}  // namespace bxdf_kinds

// The same for one known kind, without the dispatch.  bxdf_sample rejects
// unusable samples exactly as the generic one does.
template <typename B>
concept WalkKind = std::is_same_v<B, DielectricBxDF> || std::is_same_v<B, DiffuseBxDF> || std::is_same_v<B, ConductorBxDF>;

template <WalkKind B>
inline RGB bxdf_f(const B& b, const vec3& wo, const vec3& wi, TransportMode mode) {
  return bxdf_kinds::f_of(b, wo, wi, mode);
}
template <WalkKind B>
inline float bxdf_pdf(const B& b, const vec3& wo, const vec3& wi, TransportMode mode, uint8_t flags) {
  return bxdf_kinds::pdf_of(b, wo, wi, mode, flags);
}
template <WalkKind B>
inline std::optional<BxDFSample> bxdf_sample(const B& b, const vec3& wo, float uc, vec2 u, TransportMode mode,
                                             uint8_t flags) {
  return bxdf_kinds::usable_or_none(bxdf_kinds::sample_of(b, wo, uc, u, mode, flags));
}
template <WalkKind B>
inline uint8_t bxdf_flags(const B& b) {
  return bxdf_kinds::flags_of(b);
}

}  // namespace theia
