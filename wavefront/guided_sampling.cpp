#include "wavefront/guided_sampling.h"

#include <algorithm>
#include <cmath>

namespace theia {

// Eqs. 9-14: each candidate weighs t / p with the target
// t = lum(f) |cos| (a / 4pi + (1 - a) g) and p = (p_bsdf + g) / 2 its
// mixture density; one is picked by weight, and f |cos| / pdf with
// pdf = t / mean(weights) is unbiased.  A guide direction the BSDF does not
// scatter into has t = 0 and is never picked: the below-surface loss of
// one-sample MIS does not exist here.  (Guidable BSDFs have no delta lobe,
// so both candidates have densities.)
std::optional<Continuation> sample_guided_ris(const BSDF& bsdf, const vec3& wo, const vec3& ns,
                                              const DirectionalGuide& guide, uint32_t region, float defensive,
                                              const GuidedDraw& u) {
  struct Candidate {
    std::optional<BSDFSample> bs;
    float g = 0.0f;       // guide pdf
    float t = 0.0f;       // target
    float weight = 0.0f;  // t / mixture pdf
  };
  auto weigh = [&](Candidate& c) {
    if (!c.bs || !(c.bs->pdf > 0.0f) || !(c.g >= 0.0f)) return;
    const float p = guided_mis_pdf(c.bs->pdf, c.g, kRISCandidateShare);
    c.t = luminance(c.bs->f) * std::abs(glm::dot(c.bs->wi, ns)) * (defensive * kInv4Pi + (1.0f - defensive) * c.g);
    c.weight = p > 0.0f && std::isfinite(c.t) ? c.t / p : 0.0f;
  };
  Candidate from_bsdf, from_guide;
  from_bsdf.bs = bsdf_sample(bsdf, wo, u.u_lobe, u.u_dir);
  if (from_bsdf.bs) from_bsdf.g = guide.pdf(region, from_bsdf.bs->wi);
  weigh(from_bsdf);
  const GuideSample gs = guide.sample(region, u.u_guide);
  if (gs.pdf > 0.0f) {
    from_guide.bs = bsdf_event(bsdf, wo, gs.wi);
    from_guide.g = gs.pdf;
  }
  weigh(from_guide);
  if (!(from_guide.weight > 0.0f)) guide.count_failed_draw(region);

  const float sum = from_bsdf.weight + from_guide.weight;
  if (!(sum > 0.0f) || !std::isfinite(sum)) return std::nullopt;
  const Candidate& pick = u.u_pick * sum < from_bsdf.weight ? from_bsdf : from_guide;
  Continuation c;
  c.bs = *pick.bs;
  const float bsdf_pdf = c.bs.pdf;
  c.bs.pdf = pick.t / (kRISCandidateShare * sum);  // t / mean(weights) over the two
  c.mis_pdf = guided_mis_pdf(bsdf_pdf, pick.g, kRISCandidateShare);
  c.roulette = double(c.bs.pdf) / double(bsdf_pdf);
  c.guide_pdf = pick.g;
  c.bsdf_pdf = bsdf_pdf;
  return c;
}

// The branch takes the direction's own first coordinate (rescaled), not a
// dimension of its own: each branch then keeps a stratified share of the
// sampler's points instead of a random subset of them (Müller's
// practical-path-guiding chooses the same way).
std::optional<Continuation> sample_guided_mis(const BSDF& bsdf, const vec3& wo, const DirectionalGuide& guide,
                                              uint32_t region, float selection, const GuidedDraw& u) {
  vec2 ud = u.u_dir;
  std::optional<BSDFSample> bs;
  float guide_pdf = 0.0f;
  if (ud.x < selection) {
    ud.x = std::min(ud.x / selection, kOneMinusEpsilon);
    // A direction the guide reports a zero density for (rounding at a
    // quad's edge) cannot be weighted: the path ends, as for pdf 0.
    const GuideSample gs = guide.sample(region, ud);
    guide_pdf = gs.pdf;
    if (gs.pdf > 0.0f) bs = bsdf_event(bsdf, wo, gs.wi);
    if (!bs) guide.count_failed_draw(region);
  } else {
    ud.x = std::min((ud.x - selection) / (1.0f - selection), kOneMinusEpsilon);
    bs = bsdf_sample(bsdf, wo, u.u_lobe, ud);
    if (bs) guide_pdf = guide.pdf(region, bs->wi);
  }
  if (!bs) return std::nullopt;
  const float bsdf_pdf = bs->pdf;
  bs->pdf = guided_mis_pdf(bsdf_pdf, guide_pdf, selection);
  return Continuation{*bs, bs->pdf, bsdf_pdf > 0.0f ? double(bs->pdf) / double(bsdf_pdf) : 1.0, guide_pdf, bsdf_pdf};
}

}  // namespace theia
