// Materials evaluated at a hit: a BSDF is plain data made per shading point,
// and free functions evaluate, sample and give the pdf of it.
//
// A BSDF is a small set of lobes.  Sampling reports which lobe produced the
// direction, its kind (diffuse / glossy / specular, reflection / transmission)
// and its roughness: path guiding needs these to decide where to guide, to
// label scattering events and to roughen.
#pragma once

#include "scene/accel.h"
#include "scene/bxdf_kinds.h"
#include "scene/bxdfs.h"
#include "scene/scene.h"
#include "scene/shapes.h"
#include "scene/texture.h"

#include <algorithm>
#include <optional>

namespace theia {

// The same bits as BxDFFlags.
enum LobeFlags : uint8_t {
  kLobeReflection = kBxDFReflection,
  kLobeTransmission = kBxDFTransmission,
  kLobeDiffuse = kBxDFDiffuse,
  kLobeGlossy = kBxDFGlossy,
  kLobeSpecular = kBxDFSpecular,
};

inline constexpr int kMaxLobes = 4;

struct BxDFLobe {
  uint8_t flags = 0;
  float roughness = 1.0f;  // 1 for diffuse, 0 for specular, alpha for microfacet lobes
  RGB albedo{0.0f};        // reflectance/tint of the lobe (for AOVs and lobe selection)
};

// Lobes of each BxDF kind: diffuse, conductor and the coated kinds have one
// (reflection); dielectric, thindielectric and diffusetransmission two
// (0 reflection, 1 transmission).  lobe_count == 0 is the "interface"
// material: no surface, the ray passes through.
struct BSDF {
  Frame shading;           // shading frame: n = shading normal (bump/normal mapped), s along dpdu
  vec3 ng{0.0f};           // geometric normal
  MaterialKind kind = MaterialKind::Diffuse;  // the material chosen (a mix resolves to one of its parts)
  BxDF bxdf;
  int lobe_count = 0;
  uint8_t flags = 0;  // bxdf_flags(bxdf), kept with the lobes (set_lobes)
  BxDFLobe lobes[kMaxLobes];
};

struct BSDFSample {
  RGB f{0.0f};        // BSDF value (without the cosine)
  vec3 wi{0.0f};      // world space, unit
  float pdf = 0.0f;   // solid angle (for specular lobes: the discrete probability)
  int lobe = -1;
  uint8_t flags = 0;  // flags of the lobe that produced wi
  float roughness = 1.0f;
  float eta = 1.0f;   // relative index crossed by a refraction (pbrt-v4's etaScale uses its square)
  // A layered sample whose bsdf_pdf was left to deferred_pdf (bsdf_sample's
  // `defer`): pdf is the walk's own, only proportional to the density.
  bool pdf_deferred = false;
  bool is_specular() const { return (flags & kLobeSpecular) != 0; }
  bool is_transmission() const { return (flags & kLobeTransmission) != 0; }
};

// Evaluates the material's textures at si, resolves mix materials (by a
// hash of the hit, as pbrt-v4 does) and applies bump or normal mapping.
// `fp` is the texture filter footprint (scene/camera.h texture_footprint);
// zero filters nothing (level-0 lookups).
BSDF make_bsdf(const Scene& scene, const SurfaceInteraction& si, const UVFootprint& fp = {});
// Whether make_bsdf reads `fp` at hits on material `material` (-1: the
// default diffuse): a texture that filters with it, through mix materials
// too, or a bump map (its offsets).  Where not, any footprint gives the same
// BSDF, so the engine computes none.
bool material_reads_footprint(const Scene& scene, int material, int depth = 0);
// True for the "interface" material: the engine continues the ray unchanged.
inline bool bsdf_is_passthrough(const BSDF& bsdf) { return bsdf.lobe_count == 0; }

// f(wo, wi) summed over the non-specular lobes; wo and wi are world-space unit vectors.
// `mode` Importance for paths traced from the lights (the adjoint BSDF).
RGB bsdf_f(const BSDF& bsdf, const vec3& wo, const vec3& wi, TransportMode mode = TransportMode::Radiance);
// A BSDF of one BxDF in a given frame, its lobes filled in as make_bsdf
// fills them (for code that builds BSDFs without a scene: tests).
BSDF bsdf_from(const BxDF& bxdf, const Frame& shading, const vec3& ng);
// Solid-angle pdf that bsdf_sample() produces wi (non-specular lobes only).
float bsdf_pdf(const BSDF& bsdf, const vec3& wo, const vec3& wi);
// What the bsdf_pdf of a layered sample needs later: what the layered pdf
// reads of the BxDF (the coat, the base and the walk count: scene/layered.cpp
// walk_pdf) and the two local directions.  For a cold per-path table of a
// pool's size: 88 bytes where the whole BxDF made it 128 (material-testball:
// 7.3 MB of fresh pages instead of 10.6 MB).
struct DeferredPdf {
  // Left uninitialised, so that a pool's table of them (megabytes) is not
  // written, nor its pages faulted in, before a layered sample uses a slot.
  DeferredPdf() {}
  // b is a layered kind (the only ones whose pdf is deferred).
  DeferredPdf(const BxDF& b, const vec3& o, const vec3& i, TransportMode m);
  union {
    DiffuseBxDF diffuse;      // kind CoatedDiffuse
    ConductorBxDF conductor;  // kind CoatedConductor
  };
  union {
    DielectricBxDF top;
  };
  vec3 wo, wi;
  int n_samples;
  BxDFKind kind;
  TransportMode mode;
};
static_assert(std::is_trivially_copyable_v<DeferredPdf> && sizeof(DeferredPdf) == 88);
// bsdf_pdf of the sample `d` was made for, bit for bit.
float deferred_pdf(const DeferredPdf& d);
// For the stochastic layered BxDFs a non-specular sample reports bsdf_pdf()
// as its pdf (what MIS needs) and f rescaled so that f / pdf is the random
// walk's own weight, as pbrt-v4's pdfIsProportional handling amounts to.
// With `defer`, such a sample keeps the walk's own f and pdf (the same ratio)
// and leaves in *defer what deferred_pdf needs for bsdf_pdf (pdf_deferred):
// the pdf costs a second walk, and only MIS at an emitter the ray finds reads it.
// `cosine`: as bxdf_sample's.
inline std::optional<BSDFSample> bsdf_sample(const BSDF& bsdf, const vec3& wo, float u_lobe, vec2 u,
                                             TransportMode mode = TransportMode::Radiance,
                                             DeferredPdf* defer = nullptr, const vec3* cosine = nullptr);
// bsdf_sample of every kind but diffuse (which bsdf_sample makes inline),
// from the local `wo` (shading frame, wo.z != 0).
std::optional<BSDFSample> any_bsdf_sample(const BSDF& bsdf, const vec3& wo, float u_lobe, vec2 u, TransportMode mode,
                                          DeferredPdf* defer, const vec3* cosine);

// Which lobe (see BSDF) a pair of local directions belongs to.
inline int lobe_of(const BSDF& bsdf, const vec3& wo, const vec3& wi) {
  return (bsdf.lobe_count == 2 && !same_hemisphere(wo, wi)) ? 1 : 0;
}
// bsdf_sample's last step: the BxDF's sample `bs` (at local wo, of value f
// and density pdf) in world space, with its lobe; nullopt where it carries
// nothing.
inline std::optional<BSDFSample> world_sample(const BSDF& bsdf, const vec3& wo, const BxDFSample& bs, const RGB& f,
                                              float pdf, bool pdf_deferred) {
  BSDFSample s;
  s.f = f;
  s.pdf = pdf;
  s.pdf_deferred = pdf_deferred;
  s.wi = bsdf.shading.from_local(bs.wi);
  s.lobe = lobe_of(bsdf, wo, bs.wi);
  s.flags = bs.flags;
  s.roughness = bsdf.lobes[s.lobe].roughness;
  s.eta = bs.eta;
  if (!is_finite(s.f) || !(s.pdf > 0.0f) || is_black(s.f)) return std::nullopt;
  return s;
}
// Inline for the commonest BSDF, a diffuse one: called out of line, with
// its sample passed back through memory twice, it took a seventh of the
// shading stage on the bench scene.
inline std::optional<BSDFSample> bsdf_sample(const BSDF& bsdf, const vec3& wo_world, float u_lobe, vec2 u,
                                             TransportMode mode, DeferredPdf* defer, const vec3* cosine) {
  const vec3 wo = bsdf.shading.to_local(wo_world);
  if (wo.z == 0.0f || bsdf.lobe_count == 0) return std::nullopt;
  if (bsdf.bxdf.kind != BxDFKind::Diffuse) return any_bsdf_sample(bsdf, wo, u_lobe, u, mode, defer, cosine);
  const std::optional<BxDFSample> bs = bxdf_kinds::sample_of(bsdf.bxdf.diffuse, wo, u_lobe, u, mode, kSampleAll, cosine);
  if (!bs) return std::nullopt;
  return world_sample(bsdf, wo, *bs, bs->f, bs->pdf, false);
}
// The scattering event of a direction chosen elsewhere (by a path-guiding
// distribution): f, bsdf_pdf, and the lobe the direction belongs to with its
// flags, roughness and eta, as bsdf_sample would report them.  nullopt where
// f is zero.  Not for the layered kinds (their f is a stochastic estimate).
std::optional<BSDFSample> bsdf_event(const BSDF& bsdf, const vec3& wo, const vec3& wi);
// True where a guide may share sampling with the BSDF (seeds/000 ch. 1
// section 3): no delta lobe (a delta has no density to mix), an exact pdf
// (not the layered kinds), lobes split by hemisphere (not hair), and some
// lobe rougher than `min_roughness`, since
// directions a guide proposes rarely matter to a near-specular lobe.
bool bsdf_is_guidable(const BSDF& bsdf, float min_roughness);
// The two ends of a directly seen caustic (wavefront/caustics.h): a caster
// is a conductor or dielectric whose every lobe is at most `max_roughness`
// rough (a near-mirror, a glass); a receiver's every lobe is diffuse.  Both
// depend on the BSDF alone, so that camera paths and light paths agree on
// which paths are caustics.
bool bsdf_is_caustic_caster(const BSDF& bsdf, float max_roughness);
bool bsdf_is_caustic_receiver(const BSDF& bsdf);
// Joint pdf of choosing `lobe` and sampling wi (the lobes' pdfs sum to
// bsdf_pdf), for guiding's per-lobe decisions.
float bsdf_lobe_pdf(const BSDF& bsdf, int lobe, const vec3& wo, const vec3& wi);
// The kind bit (kLobeGlossy or kLobeDiffuse) bsdf_sample reports for a
// direction that no delta lobe made: what labels a direction chosen by light
// sampling or a guide (seeds/000 ch. 1 section 6).  No BSDF has two
// non-delta lobes of different kinds that share a direction: the
// reflection/transmission pairs are one kind split by hemisphere, and the
// layered kinds' walk reports every non-delta exit as glossy (pbrt-v4), so
// the label is a function of the BSDF and eq. 24's stochastic choice
// between lobes never has two kinds to choose from.
inline uint8_t bsdf_nondelta_kind(const BSDF& bsdf) { return (bsdf.flags & kLobeGlossy) ? kLobeGlossy : kLobeDiffuse; }
// Path-space regularisation (OPSR, simplified as in seeds/000 ch. 1 section
// 7, eq. 25): the roughness a lobe of roughness `alpha` has at a vertex whose
// incoming direction was sampled by a lobe of regularised roughness `prev`,
// with strength `gamma` in [0, 1].  Roughness is the Trowbridge-Reitz alpha
// (diffuse 1, specular 0).  Alphas beyond 1 (pbrt-v4 lets roughness exceed
// 1) are left as they are: eq. 25 would make them smoother.
inline float regularized_roughness(float alpha, float gamma, float prev) {
  const float g = gamma * prev;
  if (!(alpha < 1.0f) || !(g > 0.0f)) return alpha;
  // max: the float product must not round a hair below alpha.
  return std::max(alpha, 1.0f - (1.0f - std::max(alpha, 0.0f)) * (1.0f - g));
}
// Roughens every microfacet and specular interface of the BSDF per eq. 25
// and refreshes its lobes, so that evaluation, sampling, pdfs and NEE all see
// the one roughened BSDF: a delta lobe whose alpha rises past the smooth
// threshold (1e-3) becomes a rough microfacet lobe.  The layered kinds
// roughen their coat and a conductor base (their walk uses those BxDFs).
// The thin dielectric (pbrt-v4 has no rough one) and hair (its beta_m is a
// longitudinal width, not an alpha) are left unchanged.
void bsdf_roughen(BSDF& bsdf, float gamma, float prev);
// The regularised roughness a sampled direction hands to the next vertex:
// that of the lobe that sampled it (not the BSDF's average), 0 for a delta
// lobe, clamped to [0, 1].  A direction chosen by a guide takes the lobe
// bsdf_event assigns it, which is eq. 24's stochastic choice: no BSDF has two
// lobes whose densities share a direction (lobes split by hemisphere), so
// that choice is certain.
inline float sampled_roughness(const BSDFSample& s) {
  return s.is_specular() ? 0.0f : std::clamp(s.roughness, 0.0f, 1.0f);
}
// Directional albedo estimate for the albedo AOV (reflectance of the material).
inline RGB bsdf_albedo(const BSDF& bsdf) {
  RGB a(0.0f);
  for (int i = 0; i < bsdf.lobe_count; ++i) a += bsdf.lobes[i].albedo;
  return a;
}
// True when every lobe is specular: no light sampling at this vertex.
inline bool bsdf_is_specular(const BSDF& bsdf) {
  return bsdf.lobe_count > 0 && !(bsdf.flags & (kLobeDiffuse | kLobeGlossy));
}

}  // namespace theia
