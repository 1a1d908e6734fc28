#include "scene/bxdfs.h"

#include "core/color.h"
#include "core/hash.h"
#include "core/sampling.h"
#include "scene/bxdf_kinds.h"
#include "scene/conductor_spectral.h"

#include <bit>

namespace theia {

RGB conductor_fresnel(float cos_i, const ConductorBxDF& b) {
  if (b.fresnel_table) return lookup_conductor_fresnel(b.fresnel_table, cos_i);
  return srgb_to_working(fresnel_complex(cos_i, b.eta, b.k));
}

// Diffuse, conductor and dielectric: scene/bxdf_kinds.h.
using namespace bxdf_kinds;

namespace {

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

}  // namespace

// The layered walk lives in its own file; it calls the typed entry points of scene/bxdf_kinds.h.
namespace layered {
RGB f(const CoatedDiffuseBxDF& b, vec3 wo, vec3 wi, TransportMode mode);
RGB f(const CoatedConductorBxDF& b, vec3 wo, vec3 wi, TransportMode mode);
float pdf(const CoatedDiffuseBxDF& b, vec3 wo, vec3 wi, TransportMode mode);
float pdf(const CoatedConductorBxDF& b, vec3 wo, vec3 wi, TransportMode mode);
std::optional<BxDFSample> sample(const CoatedDiffuseBxDF& b, vec3 wo, float uc, vec2 u, TransportMode mode);
std::optional<BxDFSample> sample(const CoatedConductorBxDF& b, vec3 wo, float uc, vec2 u, TransportMode mode);
}  // namespace layered

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

// Each kind's sample, returned as it is made: nothing on the way copies it
// (a copy of an optional sample was read back as one wide load of its
// narrow stores, which store forwarding cannot serve: 40% of bxdf_sample's
// time on the Cornell box).
[[gnu::always_inline]] inline std::optional<BxDFSample> sample_by_kind(const BxDF& b, const vec3& wo, float uc, vec2 u,
                                                                       TransportMode mode, uint8_t flags,
                                                                       const vec3* cosine) {
  switch (b.kind) {
    case BxDFKind::Diffuse: return sample_of(b.diffuse, wo, uc, u, mode, flags, cosine);
    case BxDFKind::Conductor: return sample_of(b.conductor, wo, uc, u, mode, flags);
    case BxDFKind::Dielectric: return sample_of(b.dielectric, wo, uc, u, mode, flags);
    case BxDFKind::ThinDielectric: return sample_of(b.thin, wo, uc, u, mode, flags);
    case BxDFKind::DiffuseTransmission: return sample_of(b.diffuse_transmission, wo, uc, u, mode, flags);
    case BxDFKind::CoatedDiffuse:
      if (flags & kSampleReflection) return layered::sample(b.coated_diffuse, wo, uc, u, mode);
      break;
    case BxDFKind::CoatedConductor:
      if (flags & kSampleReflection) return layered::sample(b.coated_conductor, wo, uc, u, mode);
      break;
    case BxDFKind::Hair:
      // pbrt-v4 ignores the sample flags; the fibre's lobes cannot be split by
      // hemisphere, so only a request for everything is served.
      if (flags == kSampleAll) {
        if (auto h = hair_sample(b.hair, wo, uc, u)) {
          BxDFSample s;
          s.f = h->f;
          s.wi = h->wi;
          s.pdf = h->pdf;
          s.flags = uint8_t(kBxDFGlossy | (same_hemisphere(wo, h->wi) ? kBxDFReflection : kBxDFTransmission));
          return s;
        }
      }
      break;
    case BxDFKind::None: break;
  }
  return std::nullopt;
}

std::optional<BxDFSample> bxdf_sample(const BxDF& b, const vec3& wo, float uc, vec2 u, TransportMode mode,
                                      uint8_t flags, const vec3* cosine) {
  std::optional<BxDFSample> s = sample_by_kind(b, wo, uc, u, mode, flags, cosine);
  if (!usable(s)) s.reset();
  return s;
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
