// Guided directional sampling at a medium vertex (seeds/000 ch. 1 section
// 2.1, ch. 2 section 5.4): the guide's distribution over the full sphere
// combined with Henyey-Greenstein phase sampling, by RIS or one-sample MIS
// as at surfaces (guided_sampling.h).  Free functions of the phase function,
// the guide and the vertex's random numbers, tested against their densities
// without an engine.
#pragma once

#include "core/directional_guide.h"
#include "wavefront/guided_sampling.h"

#include <optional>

namespace theia {

// The scattered direction at a guided medium vertex.
struct PhaseContinuation {
  vec3 wi{0.0f};
  float phase = 0.0f;     // the phase function's value at wi
  float pdf = 0.0f;       // the density phase / pdf is weighted with
  float mis_pdf = 0.0f;   // what MIS against light sampling uses
  double roulette = 1.0;  // pdf / phase-sampling pdf: the roulette correction (eq. 17)
};

// RIS over a phase-function and a guide candidate, target
// phase x (a / 4pi + (1 - a) guide) (`defensive` = a).
std::optional<PhaseContinuation> sample_guided_phase_ris(const vec3& wo, float g, const DirectionalGuide& guide,
                                                         uint32_t region, float defensive, const GuidedDraw& u);
// One-sample MIS: the guide with probability `selection`, else the phase function.
std::optional<PhaseContinuation> sample_guided_phase_mis(const vec3& wo, float g, const DirectionalGuide& guide,
                                                         uint32_t region, float selection, const GuidedDraw& u);

}  // namespace theia
