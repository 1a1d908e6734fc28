// Guided directional sampling at one vertex (seeds/000 ch. 1 section 3): the
// two ways a guide and a BSDF share the choice of the next direction.  Free
// functions of the BSDF, the guide and the vertex's random numbers, so that
// tests can check them against their densities without an engine.
#pragma once

#include "core/directional_guide.h"
#include "scene/bsdf.h"

#include <optional>

namespace theia {

// The continuation direction and what the path keeps of its drawing.
struct Continuation {
  BSDFSample bs;          // bs.pdf: the density f |cos| / pdf is weighted with
  float mis_pdf = 0.0f;   // what MIS against light sampling uses (RIS: the candidates' mixture)
  double roulette = 1.0;  // this vertex's roulette correction: bs.pdf / BSDF pdf (eq. 17)
  float guide_pdf = 0.0f; // the guide's density at the direction (adjoint-driven roulette)
  float bsdf_pdf = 0.0f;  // the BSDF's own density at the direction
};

// The vertex's random numbers for its direction.
struct GuidedDraw {
  float u_lobe = 0.0f;  // the BSDF's lobe choice
  vec2 u_dir{0.0f};     // the BSDF's direction (MIS: and the branch, from u_dir.x)
  vec2 u_guide{0.0f};   // RIS: the guide candidate
  float u_pick = 0.0f;  // RIS: which candidate
};

// RIS draws one candidate from each: their mixture is half and half (eq. 9).
inline constexpr float kRISCandidateShare = 0.5f;

// RIS over two candidates, one from the BSDF and one from the guide.
// `defensive` is the uniform share a of the target's radiance estimate.
std::optional<Continuation> sample_guided_ris(const BSDF& bsdf, const vec3& wo, const vec3& ns,
                                              const DirectionalGuide& guide, uint32_t region, float defensive,
                                              const GuidedDraw& u);
// One-sample MIS: the guide with probability `selection`, else the BSDF.
std::optional<Continuation> sample_guided_mis(const BSDF& bsdf, const vec3& wo, const DirectionalGuide& guide,
                                              uint32_t region, float selection, const GuidedDraw& u);
// The density MIS against light sampling takes for a direction of a guided
// vertex: the mixture (RIS: its two candidates' equal mixture, which stands
// in for the resampled pdf that no direction has outside its candidate set,
// section 3.3.1).
inline float guided_mis_pdf(float bsdf_pdf, float guide_pdf, float selection) {
  return selection * guide_pdf + (1.0f - selection) * bsdf_pdf;
}

}  // namespace theia
