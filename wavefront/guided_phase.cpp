#include "wavefront/guided_phase.h"

#include "scene/microfacet.h"

#include <algorithm>
#include <cmath>

namespace theia {

// Both candidates are weighed by target / (their equal mixture's density);
// one is picked by weight, and phase / pdf with pdf = target / mean(weights)
// is unbiased (eqs. 9-14 with f |cos| replaced by the phase function, which
// is positive everywhere: no candidate is lost below a surface).
std::optional<PhaseContinuation> sample_guided_phase_ris(const vec3& wo, float g, const DirectionalGuide& guide,
                                                         uint32_t region, float defensive, const GuidedDraw& u) {
  struct Candidate {
    vec3 wi{0.0f};
    float phase = 0.0f, guide_pdf = 0.0f, target = 0.0f, weight = 0.0f;
  };
  auto candidate = [&](const vec3& wi, float guide_pdf) {
    Candidate c{wi, henyey_greenstein(glm::dot(wo, wi), g), guide_pdf};
    const float mixture = guided_mis_pdf(c.phase, guide_pdf, kRISCandidateShare);
    c.target = c.phase * (defensive * kInv4Pi + (1.0f - defensive) * guide_pdf);
    c.weight = mixture > 0.0f && std::isfinite(c.target) ? c.target / mixture : 0.0f;
    return c;
  };
  float unused_pdf = 0.0f;
  const vec3 w_phase = sample_henyey_greenstein(wo, g, u.u_dir, &unused_pdf);
  const Candidate from_phase = candidate(w_phase, guide.pdf(region, w_phase));
  const GuideSample gs = guide.sample(region, u.u_guide);
  const Candidate from_guide = gs.pdf > 0.0f ? candidate(gs.wi, gs.pdf) : Candidate{};

  const float sum = from_phase.weight + from_guide.weight;
  if (!(sum > 0.0f) || !std::isfinite(sum)) return std::nullopt;
  const Candidate& pick = u.u_pick * sum < from_phase.weight ? from_phase : from_guide;
  PhaseContinuation c;
  c.wi = pick.wi;
  c.phase = pick.phase;
  c.pdf = pick.target / (kRISCandidateShare * sum);
  c.mis_pdf = guided_mis_pdf(pick.phase, pick.guide_pdf, kRISCandidateShare);
  c.roulette = double(c.pdf) / double(pick.phase);
  if (!(c.pdf > 0.0f) || !(pick.phase > 0.0f)) return std::nullopt;
  return c;
}

// The branch takes the direction's own first coordinate, rescaled (as at
// surfaces: each branch keeps a stratified share of the sampler's points).
std::optional<PhaseContinuation> sample_guided_phase_mis(const vec3& wo, float g, const DirectionalGuide& guide,
                                                         uint32_t region, float selection, const GuidedDraw& u) {
  vec2 ud = u.u_dir;
  PhaseContinuation c;
  float guide_pdf = 0.0f;
  if (ud.x < selection) {
    ud.x = std::min(ud.x / selection, kOneMinusEpsilon);
    const GuideSample gs = guide.sample(region, ud);
    if (!(gs.pdf > 0.0f)) return std::nullopt;  // a zero density at a quad's edge: cannot be weighted
    c.wi = gs.wi;
    guide_pdf = gs.pdf;
  } else {
    ud.x = std::min((ud.x - selection) / (1.0f - selection), kOneMinusEpsilon);
    float unused_pdf = 0.0f;
    c.wi = sample_henyey_greenstein(wo, g, ud, &unused_pdf);
    guide_pdf = guide.pdf(region, c.wi);
  }
  c.phase = henyey_greenstein(glm::dot(wo, c.wi), g);
  c.pdf = c.mis_pdf = guided_mis_pdf(c.phase, guide_pdf, selection);
  if (!(c.pdf > 0.0f) || !(c.phase > 0.0f)) return std::nullopt;
  c.roulette = double(c.pdf) / double(c.phase);
  return c;
}

}  // namespace theia
