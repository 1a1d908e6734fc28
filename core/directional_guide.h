// Path guiding as the wavefront engine sees it: a directional distribution
// per region of space, learned from earlier iterations, that the engine
// combines with BSDF sampling (resampling or one-sample MIS, seeds/000 ch. 1
// sections 3.2 and 3.3).
//
// The interface lives in core/ (like PathObserver) so that guiding/, which
// may use only core, implements it and the engine calls it without knowing
// what an SD-tree is.  A region is looked up once per vertex; sample() and
// pdf() then take it, so a vertex pays one spatial descent however many
// directions it asks about (its own sample, the NEE ray's MIS weight).
#pragma once

#include "core/math.h"

#include <cstdint>

namespace theia {

inline constexpr uint32_t kNoGuideRegion = 0xffffffffu;

// How a guided vertex draws its direction.
enum class GuideMixing : uint8_t {
  // RIS (seeds/000 ch. 1 section 3.3): one BSDF and one guide candidate,
  // resampled by f |cos| (a / 4pi + (1 - a) g).  The product target never
  // picks a direction the BSDF does not scatter into.
  Resampled,
  // One-sample MIS (section 3.2): the guide with its selection probability,
  // else the BSDF; the choice taken from the direction's own first coordinate.
  OneSampleMIS,
};

// What the engine needs to know about guided sampling (the guide itself aside).
struct GuidedSampling {
  GuideMixing mixing = GuideMixing::Resampled;
  float min_roughness = 0.05f;  // guide only where a lobe is rougher (bsdf_is_guidable)
  float defensive = 0.5f;       // RIS: the uniform share a of the target's radiance estimate
  // One-sample MIS: the guide's share of directions at most this.  Where the
  // guide takes a share s, a direction it missed is weighted by at most
  // f / ((1 - s) p_bsdf): a learned share of 0.92 makes such a path 12x a
  // BSDF sample's weight, a firefly on a diffuse wall.  1: no cap.
  float selection_max = 1.0f;
  // Russian roulette on the throughput as BSDF sampling would have made it
  // (section 4.1.1): guiding's high pdfs towards light do not cut paths short.
  bool roulette_correction = true;
  // Adjoint-driven roulette (section 4.2): a guided continuation survives
  // with its expected contribution (throughput x the field's radiance from
  // its direction) against the path's pixel estimate (its first vertex's
  // outgoing radiance from the field), not with its throughput.
  bool adjoint_roulette = false;
  // Adjoint-driven roulette's least survival probability: the estimates are
  // coarse, and a survivor's weight grows by up to 1 / floor at each guided
  // vertex, so a low floor turns the field's mistakes into fireflies.
  float roulette_floor = 0.5f;
};

struct GuideSample {
  vec3 wi{0.0f};     // world space, unit
  float pdf = 0.0f;  // solid angle
};

class DirectionalGuide {
 public:
  virtual ~DirectionalGuide() = default;
  // The region whose distribution applies at p, or kNoGuideRegion where the
  // field has learned nothing (the engine then samples the BSDF alone).
  virtual uint32_t region(const vec3& p) const = 0;
  // A direction drawn from the region's distribution, u in [0,1)^2.
  virtual GuideSample sample(uint32_t region, vec2 u) const = 0;
  // Solid-angle density of sample() producing wi (world space, unit).
  virtual float pdf(uint32_t region, const vec3& wi) const = 0;
  // Probability of drawing from the guide rather than the BSDF in this region.
  virtual float selection_probability(uint32_t region) const = 0;
  // The region's incident radiance integrated over the sphere (luminance);
  // pdf(region, w) times this estimates the radiance arriving from w, which
  // is what adjoint-driven roulette weighs a path's continuation by.
  virtual float radiance_integral(uint32_t region) const = 0;
  // Statistics (the field viewer's): a direction drawn from the region's
  // distribution that the BSDF does not scatter into, so it was wasted.
  // Called from any thread, only when it happens.
  virtual void count_failed_draw(uint32_t /*region*/) const {}
};

}  // namespace theia
