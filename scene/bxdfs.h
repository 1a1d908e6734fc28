// pbrt-v4's BxDFs in a local shading frame (z = shading normal, directions
// pointing away from the surface), as plain data plus free functions that
// switch on the kind: no virtual calls, nothing allocated.  scene/bsdf.h wraps
// them with the shading frame and the lobe description guiding needs.
//
// Conventions (pbrt-v4's): f excludes the cosine; a specular sample has a
// discrete probability as its pdf and f carries the 1/|cos| that cancels the
// cosine; f and pdf never include specular lobes.  Refraction in Radiance
// mode scales by 1/eta^2.  Layered BxDFs (coateddiffuse, coatedconductor) are
// stochastic: f and pdf are unbiased estimates from a random walk seeded by a
// hash of the directions, and a sample's pdf is only proportional to its
// density (pdf_is_proportional), so MIS must use bxdf_pdf instead.
#pragma once

#include "scene/hair.h"
#include "scene/microfacet.h"

#include <optional>
#include <type_traits>

namespace theia {

enum class TransportMode : uint8_t { Radiance, Importance };
inline TransportMode operator!(TransportMode m) {
  return m == TransportMode::Radiance ? TransportMode::Importance : TransportMode::Radiance;
}

// Which halves a sampling routine may use (pbrt-v4's BxDFReflTransFlags).
enum SampleFlags : uint8_t { kSampleReflection = 1, kSampleTransmission = 2, kSampleAll = 3 };

enum BxDFFlags : uint8_t {
  kBxDFReflection = 1 << 0,
  kBxDFTransmission = 1 << 1,
  kBxDFDiffuse = 1 << 2,
  kBxDFGlossy = 1 << 3,
  kBxDFSpecular = 1 << 4,
};

enum class BxDFKind : uint8_t {
  None,  // no scattering (the "interface" material)
  Diffuse,
  Conductor,
  Dielectric,
  ThinDielectric,
  DiffuseTransmission,
  CoatedDiffuse,    // dielectric interface over a diffuse base
  CoatedConductor,  // dielectric interface over a conductor base
  Hair,             // pbrt-v4's HairBxDF (scene/hair.h): x along the fibre
};

struct DiffuseBxDF {
  RGB r{0.0f};
};
struct ConductorBxDF {
  TrowbridgeReitz distrib;
  RGB eta{1.0f}, k{0.0f};
  // Material::conductor_fresnel when it has one (scene/conductor_spectral.h):
  // the spectral reflectance over cos theta replaces the per-band Fresnel of eta and k.
  const RGB* fresnel_table = nullptr;
};

// A conductor's Fresnel reflectance, in the working colour space.  eta and k
// are optical constants per band, not colours, so they stay in the linear-sRGB
// bands the scene (or the named spectrum) gives them; the reflectance they
// produce is a colour and joins the working space.  Converting eta and k
// instead would saturate metals beyond what their spectra reflect.  With a
// table (spectral eta and k) the table is the reflectance.
RGB conductor_fresnel(float cos_i, const ConductorBxDF& b);
struct DielectricBxDF {
  TrowbridgeReitz distrib;
  float eta = 1.5f;
};
struct ThinDielectricBxDF {
  float eta = 1.5f;
};
struct DiffuseTransmissionBxDF {
  RGB r{0.0f}, t{0.0f};
};
// The medium between a layered BxDF's interfaces (pbrt-v4's LayeredBxDF).
struct LayerParams {
  float thickness = 0.01f;
  float g = 0.0f;
  RGB albedo{0.0f};
  int max_depth = 10;
  int n_samples = 1;
};

// The layered kinds: a dielectric coat (`top`) over an opaque base.
struct CoatedDiffuseBxDF {
  DielectricBxDF top;
  DiffuseBxDF base;
  LayerParams layer;
};
struct CoatedConductorBxDF {
  DielectricBxDF top;
  ConductorBxDF base;
  LayerParams layer;
};

// One BxDF as a tagged union: `kind` names the one member that is live.
// Built from the variant it holds (`BxDF b = DielectricBxDF{...}`), so the
// tag and the member cannot disagree; a BSDF is made per shading point, and
// this keeps it as small as its largest variant (the coated conductor) rather than the sum.
struct BxDF {
  BxDFKind kind = BxDFKind::None;
  union {
    DiffuseBxDF diffuse;
    ConductorBxDF conductor;
    DielectricBxDF dielectric;
    ThinDielectricBxDF thin;
    DiffuseTransmissionBxDF diffuse_transmission;
    CoatedDiffuseBxDF coated_diffuse;
    CoatedConductorBxDF coated_conductor;
    HairBxDF hair;
  };
  BxDF() : diffuse{} {}
  BxDF(const DiffuseBxDF& b) : kind(BxDFKind::Diffuse), diffuse(b) {}
  BxDF(const ConductorBxDF& b) : kind(BxDFKind::Conductor), conductor(b) {}
  BxDF(const DielectricBxDF& b) : kind(BxDFKind::Dielectric), dielectric(b) {}
  BxDF(const ThinDielectricBxDF& b) : kind(BxDFKind::ThinDielectric), thin(b) {}
  BxDF(const DiffuseTransmissionBxDF& b) : kind(BxDFKind::DiffuseTransmission), diffuse_transmission(b) {}
  BxDF(const CoatedDiffuseBxDF& b) : kind(BxDFKind::CoatedDiffuse), coated_diffuse(b) {}
  BxDF(const CoatedConductorBxDF& b) : kind(BxDFKind::CoatedConductor), coated_conductor(b) {}
  BxDF(const HairBxDF& b) : kind(BxDFKind::Hair), hair(b) {}
};
static_assert(std::is_trivially_copyable_v<BxDF>);

struct BxDFSample {
  RGB f{0.0f};
  vec3 wi{0.0f};
  float pdf = 0.0f;
  uint8_t flags = 0;   // BxDFFlags of the scattering event
  float eta = 1.0f;    // relative index crossed (transmission), for Russian roulette's eta scale
  bool pdf_is_proportional = false;
  bool is_specular() const { return (flags & kBxDFSpecular) != 0; }
  bool is_transmission() const { return (flags & kBxDFTransmission) != 0; }
  bool is_reflection() const { return (flags & kBxDFReflection) != 0; }
};

uint8_t bxdf_flags(const BxDF& b);
RGB bxdf_f(const BxDF& b, const vec3& wo, const vec3& wi, TransportMode mode = TransportMode::Radiance);
float bxdf_pdf(const BxDF& b, const vec3& wo, const vec3& wi, TransportMode mode = TransportMode::Radiance,
               uint8_t sample_flags = kSampleAll);
// `cosine`: sample_cosine_hemisphere(u), where the caller made it ahead (a
// diffuse BxDF then takes its direction instead of making it).
std::optional<BxDFSample> bxdf_sample(const BxDF& b, const vec3& wo, float uc, vec2 u,
                                      TransportMode mode = TransportMode::Radiance,
                                      uint8_t sample_flags = kSampleAll, const vec3* cosine = nullptr);

// The typed overloads for diffuse, conductor and dielectric BxDFs, which the
// layered walk calls for its coat and base: scene/bxdf_kinds.h.

}  // namespace theia
