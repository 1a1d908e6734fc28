#include "scene/bxdfs.h"

#include "core/color.h"
#include "core/hash.h"
#include "core/sampling.h"
#include "scene/conductor_spectral.h"

#include <bit>

namespace theia {

RGB conductor_fresnel(float cos_i, const ConductorBxDF& b) {
  if (b.fresnel_table) return lookup_conductor_fresnel(b.fresnel_table, cos_i);
  return srgb_to_working(fresnel_complex(cos_i, b.eta, b.k));
}

namespace {

// ---------------------------------------------------------------- diffuse

RGB f_of(const DiffuseBxDF& b, const vec3& wo, const vec3& wi, TransportMode) {
  return same_hemisphere(wo, wi) ? b.r * kInvPi : RGB(0.0f);
}
float pdf_of(const DiffuseBxDF&, const vec3& wo, const vec3& wi, TransportMode, uint8_t flags) {
  if (!(flags & kSampleReflection) || !same_hemisphere(wo, wi)) return 0.0f;
  return cosine_hemisphere_pdf(std::abs(wi.z));
}
std::optional<BxDFSample> sample_of(const DiffuseBxDF& b, const vec3& wo, float, vec2 u, TransportMode,
                                    uint8_t flags) {
  if (!(flags & kSampleReflection)) return std::nullopt;
  vec3 wi = sample_cosine_hemisphere(u);
  if (wo.z < 0.0f) wi.z = -wi.z;
  BxDFSample s;
  s.f = b.r * kInvPi;
  s.wi = wi;
  s.pdf = cosine_hemisphere_pdf(std::abs(wi.z));
  s.flags = kBxDFReflection | kBxDFDiffuse;
  return s;
}
uint8_t flags_of(const DiffuseBxDF& b) { return is_black(b.r) ? 0 : (kBxDFReflection | kBxDFDiffuse); }

// ---------------------------------------------------------------- conductor

RGB f_of(const ConductorBxDF& b, const vec3& wo, const vec3& wi, TransportMode) {
  if (!same_hemisphere(wo, wi) || b.distrib.effectively_smooth()) return RGB(0.0f);
  float cos_o = std::abs(wo.z), cos_i = std::abs(wi.z);
  if (cos_i == 0.0f || cos_o == 0.0f) return RGB(0.0f);
  vec3 wm = wi + wo;
  if (glm::dot(wm, wm) == 0.0f) return RGB(0.0f);
  wm = glm::normalize(wm);
  RGB F = conductor_fresnel(std::abs(glm::dot(wo, wm)), b);
  return b.distrib.D(wm) * F * b.distrib.G(wo, wi) / (4.0f * cos_i * cos_o);
}
float pdf_of(const ConductorBxDF& b, const vec3& wo, const vec3& wi, TransportMode, uint8_t flags) {
  if (!(flags & kSampleReflection) || !same_hemisphere(wo, wi) || b.distrib.effectively_smooth()) return 0.0f;
  vec3 wm = wo + wi;
  if (glm::dot(wm, wm) == 0.0f) return 0.0f;
  wm = face_forward(glm::normalize(wm), vec3(0, 0, 1));
  return b.distrib.pdf(wo, wm) / (4.0f * std::abs(glm::dot(wo, wm)));
}
std::optional<BxDFSample> sample_of(const ConductorBxDF& b, const vec3& wo, float, vec2 u, TransportMode,
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
uint8_t flags_of(const ConductorBxDF& b) {
  return kBxDFReflection | (b.distrib.effectively_smooth() ? kBxDFSpecular : kBxDFGlossy);
}

// ---------------------------------------------------------------- dielectric

uint8_t flags_of(const DielectricBxDF& b) {
  uint8_t f = b.eta == 1.0f ? kBxDFTransmission : (kBxDFReflection | kBxDFTransmission);
  return f | (b.distrib.effectively_smooth() ? kBxDFSpecular : kBxDFGlossy);
}

// The microfacet normal of a (wo, wi) pair and the relative index crossed;
// false for pairs the rough dielectric cannot produce.
bool dielectric_half_vector(const DielectricBxDF& b, const vec3& wo, const vec3& wi, vec3* wm, float* etap,
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

RGB f_of(const DielectricBxDF& b, const vec3& wo, const vec3& wi, TransportMode mode) {
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

float pdf_of(const DielectricBxDF& b, const vec3& wo, const vec3& wi, TransportMode, uint8_t flags) {
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

std::optional<BxDFSample> sample_of(const DielectricBxDF& b, const vec3& wo, float uc, vec2 u, TransportMode mode,
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

// ---------------------------------------------------------------- thin dielectric

std::optional<BxDFSample> sample_of(const ThinDielectricBxDF& b, const vec3& wo, float uc, vec2, TransportMode,
                                    uint8_t flags) {
  float R = fresnel_dielectric(std::abs(wo.z), b.eta), T = 1.0f - R;
  // Sum of the geometric series of inter-reflections inside the slab.
  if (R < 1.0f) {
    R += sqr(T) * R / (1.0f - sqr(R));
    T = 1.0f - R;
  }
  float pr = (flags & kSampleReflection) ? R : 0.0f, pt = (flags & kSampleTransmission) ? T : 0.0f;
  if (pr == 0.0f && pt == 0.0f) return std::nullopt;
  BxDFSample s;
  if (uc < pr / (pr + pt)) {
    s.wi = vec3(-wo.x, -wo.y, wo.z);
    s.f = RGB(R / std::abs(s.wi.z));
    s.pdf = pr / (pr + pt);
    s.flags = kBxDFReflection | kBxDFSpecular;
  } else {
    s.wi = -wo;
    s.f = RGB(T / std::abs(s.wi.z));
    s.pdf = pt / (pr + pt);
    s.flags = kBxDFTransmission | kBxDFSpecular;
  }
  if (s.wi.z == 0.0f) return std::nullopt;
  return s;
}

// ---------------------------------------------------------------- diffuse transmission

RGB f_of(const DiffuseTransmissionBxDF& b, const vec3& wo, const vec3& wi, TransportMode) {
  return (same_hemisphere(wo, wi) ? b.r : b.t) * kInvPi;
}
float pdf_of(const DiffuseTransmissionBxDF& b, const vec3& wo, const vec3& wi, TransportMode, uint8_t flags) {
  float pr = (flags & kSampleReflection) ? max_component(b.r) : 0.0f;
  float pt = (flags & kSampleTransmission) ? max_component(b.t) : 0.0f;
  if (pr == 0.0f && pt == 0.0f) return 0.0f;
  float p = cosine_hemisphere_pdf(std::abs(wi.z));
  return same_hemisphere(wo, wi) ? pr / (pr + pt) * p : pt / (pr + pt) * p;
}
std::optional<BxDFSample> sample_of(const DiffuseTransmissionBxDF& b, const vec3& wo, float uc, vec2 u,
                                    TransportMode, uint8_t flags) {
  float pr = (flags & kSampleReflection) ? max_component(b.r) : 0.0f;
  float pt = (flags & kSampleTransmission) ? max_component(b.t) : 0.0f;
  if (pr == 0.0f && pt == 0.0f) return std::nullopt;
  BxDFSample s;
  s.wi = sample_cosine_hemisphere(u);
  bool refl = uc < pr / (pr + pt);
  if ((wo.z < 0.0f) == refl) s.wi.z = -s.wi.z;
  s.f = (refl ? b.r : b.t) * kInvPi;
  s.pdf = cosine_hemisphere_pdf(std::abs(s.wi.z)) * (refl ? pr : pt) / (pr + pt);
  s.flags = (refl ? kBxDFReflection : kBxDFTransmission) | kBxDFDiffuse;
  return s;
}

// A sample the path can use: the same test for every entry point.
std::optional<BxDFSample> usable_or_none(const std::optional<BxDFSample>& s) {
  if (!s || s->pdf == 0.0f || is_black(s->f) || s->wi.z == 0.0f || !is_finite(s->f) || !std::isfinite(s->pdf))
    return std::nullopt;
  return s;
}

}  // namespace

// The layered walk lives in its own file; it calls the typed entry points below.
namespace layered {
RGB f(const CoatedDiffuseBxDF& b, vec3 wo, vec3 wi, TransportMode mode);
RGB f(const CoatedConductorBxDF& b, vec3 wo, vec3 wi, TransportMode mode);
float pdf(const CoatedDiffuseBxDF& b, vec3 wo, vec3 wi, TransportMode mode);
float pdf(const CoatedConductorBxDF& b, vec3 wo, vec3 wi, TransportMode mode);
std::optional<BxDFSample> sample(const CoatedDiffuseBxDF& b, vec3 wo, float uc, vec2 u, TransportMode mode);
std::optional<BxDFSample> sample(const CoatedConductorBxDF& b, vec3 wo, float uc, vec2 u, TransportMode mode);
}  // namespace layered

RGB bxdf_f(const DielectricBxDF& b, const vec3& wo, const vec3& wi, TransportMode mode) { return f_of(b, wo, wi, mode); }
float bxdf_pdf(const DielectricBxDF& b, const vec3& wo, const vec3& wi, TransportMode mode, uint8_t flags) {
  return pdf_of(b, wo, wi, mode, flags);
}
std::optional<BxDFSample> bxdf_sample(const DielectricBxDF& b, const vec3& wo, float uc, vec2 u, TransportMode mode,
                                      uint8_t flags) {
  return usable_or_none(sample_of(b, wo, uc, u, mode, flags));
}
RGB bxdf_f(const DiffuseBxDF& b, const vec3& wo, const vec3& wi, TransportMode mode) { return f_of(b, wo, wi, mode); }
float bxdf_pdf(const DiffuseBxDF& b, const vec3& wo, const vec3& wi, TransportMode mode, uint8_t flags) {
  return pdf_of(b, wo, wi, mode, flags);
}
std::optional<BxDFSample> bxdf_sample(const DiffuseBxDF& b, const vec3& wo, float uc, vec2 u, TransportMode mode,
                                      uint8_t flags) {
  return usable_or_none(sample_of(b, wo, uc, u, mode, flags));
}
RGB bxdf_f(const ConductorBxDF& b, const vec3& wo, const vec3& wi, TransportMode mode) { return f_of(b, wo, wi, mode); }
float bxdf_pdf(const ConductorBxDF& b, const vec3& wo, const vec3& wi, TransportMode mode, uint8_t flags) {
  return pdf_of(b, wo, wi, mode, flags);
}
std::optional<BxDFSample> bxdf_sample(const ConductorBxDF& b, const vec3& wo, float uc, vec2 u, TransportMode mode,
                                      uint8_t flags) {
  return usable_or_none(sample_of(b, wo, uc, u, mode, flags));
}
uint8_t bxdf_flags(const DielectricBxDF& b) { return flags_of(b); }
uint8_t bxdf_flags(const DiffuseBxDF& b) { return flags_of(b); }
uint8_t bxdf_flags(const ConductorBxDF& b) { return flags_of(b); }

// Dispatch on the kind.
RGB bxdf_f(const BxDF& b, const vec3& wo, const vec3& wi, TransportMode mode) {
  switch (b.kind) {
    case BxDFKind::Diffuse: return f_of(b.diffuse, wo, wi, mode);
    case BxDFKind::Conductor: return f_of(b.conductor, wo, wi, mode);
    case BxDFKind::Dielectric: return f_of(b.dielectric, wo, wi, mode);
    case BxDFKind::DiffuseTransmission: return f_of(b.diffuse_transmission, wo, wi, mode);
    case BxDFKind::CoatedDiffuse: return layered::f(b.coated_diffuse, wo, wi, mode);
    case BxDFKind::CoatedConductor: return layered::f(b.coated_conductor, wo, wi, mode);
    case BxDFKind::Hair: return hair_f(b.hair, wo, wi);
    case BxDFKind::ThinDielectric:
    case BxDFKind::None: break;
  }
  return RGB(0.0f);
}

float bxdf_pdf(const BxDF& b, const vec3& wo, const vec3& wi, TransportMode mode, uint8_t flags) {
  switch (b.kind) {
    case BxDFKind::Diffuse: return pdf_of(b.diffuse, wo, wi, mode, flags);
    case BxDFKind::Conductor: return pdf_of(b.conductor, wo, wi, mode, flags);
    case BxDFKind::Dielectric: return pdf_of(b.dielectric, wo, wi, mode, flags);
    case BxDFKind::DiffuseTransmission: return pdf_of(b.diffuse_transmission, wo, wi, mode, flags);
    case BxDFKind::CoatedDiffuse: return (flags & kSampleReflection) ? layered::pdf(b.coated_diffuse, wo, wi, mode) : 0.0f;
    case BxDFKind::CoatedConductor:
      return (flags & kSampleReflection) ? layered::pdf(b.coated_conductor, wo, wi, mode) : 0.0f;
    case BxDFKind::Hair: return flags == kSampleAll ? hair_pdf(b.hair, wo, wi) : 0.0f;
    case BxDFKind::ThinDielectric:
    case BxDFKind::None: break;
  }
  return 0.0f;
}

std::optional<BxDFSample> bxdf_sample(const BxDF& b, const vec3& wo, float uc, vec2 u, TransportMode mode,
                                      uint8_t flags) {
  std::optional<BxDFSample> s;
  switch (b.kind) {
    case BxDFKind::Diffuse: s = sample_of(b.diffuse, wo, uc, u, mode, flags); break;
    case BxDFKind::Conductor: s = sample_of(b.conductor, wo, uc, u, mode, flags); break;
    case BxDFKind::Dielectric: s = sample_of(b.dielectric, wo, uc, u, mode, flags); break;
    case BxDFKind::ThinDielectric: s = sample_of(b.thin, wo, uc, u, mode, flags); break;
    case BxDFKind::DiffuseTransmission: s = sample_of(b.diffuse_transmission, wo, uc, u, mode, flags); break;
    case BxDFKind::CoatedDiffuse:
      if (flags & kSampleReflection) s = layered::sample(b.coated_diffuse, wo, uc, u, mode);
      break;
    case BxDFKind::CoatedConductor:
      if (flags & kSampleReflection) s = layered::sample(b.coated_conductor, wo, uc, u, mode);
      break;
    case BxDFKind::Hair:
      // pbrt-v4 ignores the sample flags; the fibre's lobes cannot be split by
      // hemisphere, so only a request for everything is served.
      if (flags == kSampleAll) {
        if (auto h = hair_sample(b.hair, wo, uc, u)) {
          s = BxDFSample{};
          s->f = h->f;
          s->wi = h->wi;
          s->pdf = h->pdf;
          s->flags = uint8_t(kBxDFGlossy | (same_hemisphere(wo, h->wi) ? kBxDFReflection : kBxDFTransmission));
        }
      }
      break;
    case BxDFKind::None: break;
  }
  return usable_or_none(s);
}

uint8_t bxdf_flags(const BxDF& b) {
  switch (b.kind) {
    case BxDFKind::Diffuse: return flags_of(b.diffuse);
    case BxDFKind::Conductor: return flags_of(b.conductor);
    case BxDFKind::Dielectric: return flags_of(b.dielectric);
    case BxDFKind::ThinDielectric: return kBxDFReflection | kBxDFTransmission | kBxDFSpecular;
    case BxDFKind::DiffuseTransmission:
      return (is_black(b.diffuse_transmission.r) ? 0 : kBxDFReflection | kBxDFDiffuse) |
             (is_black(b.diffuse_transmission.t) ? 0 : kBxDFTransmission | kBxDFDiffuse);
    case BxDFKind::CoatedDiffuse: return kBxDFReflection | kBxDFDiffuse | kBxDFGlossy |
                                         (b.coated_diffuse.top.distrib.effectively_smooth() ? kBxDFSpecular : 0);
    case BxDFKind::CoatedConductor: {
      const CoatedConductorBxDF& c = b.coated_conductor;
      uint8_t f = kBxDFReflection | kBxDFGlossy;
      if (c.top.distrib.effectively_smooth() && c.base.distrib.effectively_smooth()) f = kBxDFReflection | kBxDFSpecular;
      else if (c.top.distrib.effectively_smooth()) f |= kBxDFSpecular;
      return f;
    }
    case BxDFKind::Hair: return kBxDFReflection | kBxDFTransmission | kBxDFGlossy;
    case BxDFKind::None: break;
  }
  return 0;
}

}  // namespace theia
