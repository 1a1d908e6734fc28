// Light selection as the wavefront engine sees it: which light a shading
// point samples for next-event estimation, with what probability, and what
// the shadow ray then found.
//
// The interface lives in core/ (like DirectionalGuide and PathObserver) so
// the engine calls it without knowing how a sampler decides; the baseline
// samplers (uniform, power) and cache points implement it in cachepoints/.
//
// Learning from visibility: a sampler that learns (cache points' online
// visibility) returns true from wants_feedback(), and the engine reports
// every traced shadow ray's outcome to record_shadow(), with the
// SampledLight that sample() returned for it.  The engine asks
// wants_feedback() once, when it is built: the shadow rays of a sampler
// that learns nothing carry no choice and report nothing, so it pays nothing.
// Between iterations (no ray in flight) the scheduler calls update(), where
// the sampler folds what it counted into the distributions the next
// iteration samples; sample() and pmf() never see a
// distribution change mid-iteration, so the image stays a pure function of
// (seed, pixel, sample index).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace theia {

// The shading point a light is chosen for (position, normals); defined with
// the lights in scene/lights.h.  The interface takes it by reference only.
struct LightSampleContext;

struct SampledLight {
  int light = -1;
  float pmf = 0.0f;
  // The sampler's own name for where it chose (a cache point), handed back
  // with the shadow ray's outcome so that it need not find it again.
  uint32_t region = 0;
  // The triangle of an emissive mesh, for a sampler that treats each
  // triangle as a light (pbrt-v4's semantics; chooses_primitives()); -1: the
  // light's own sampling (sample_li) chooses where on it.
  int primitive = -1;
};

class LightSampler {
 public:
  virtual ~LightSampler() = default;
  virtual std::optional<SampledLight> sample(const LightSampleContext& ctx, float u) const = 0;
  // Probability that sample(ctx, .) returns `light`.
  virtual float pmf(const LightSampleContext& ctx, int light) const = 0;
  virtual const char* name() const = 0;

  // True when sample() names triangles of emissive meshes (SampledLight::primitive).
  // The engine asks once, when it is built; then the MIS weight of an emitter
  // hit asks pmf_primitive() with the triangle hit, and the light's pdf is
  // that triangle's alone.
  virtual bool chooses_primitives() const { return false; }
  // Probability that sample(ctx, .) returns (light, primitive); primitive is
  // ignored for a light that is not a triangle mesh.
  virtual float pmf_primitive(const LightSampleContext& ctx, int light, int /*primitive*/) const {
    return pmf(ctx, light);
  }

  // True when the sampler learns from shadow-ray outcomes (record_shadow).
  virtual bool wants_feedback() const { return false; }
  // A shadow ray towards `chosen` (what sample() returned) was traced:
  // `unoccluded` says whether it reached the light.  Called concurrently from
  // the engine's worker threads while other threads call sample() and pmf();
  // hence const: a learning sampler counts into mutable atomics (or
  // per-thread tables) and changes no distribution until update().
  virtual void record_shadow(const SampledLight& /*chosen*/, bool /*unoccluded*/) const {}
  // Between iterations, no ray in flight: fold the counts into the
  // distributions.  The samplers that learn nothing do nothing.
  virtual void update() {}

  // What a resumed render needs to sample as this one would (what update()
  // learned); empty for a sampler that learns nothing.  restore() throws
  // theia::Error for bytes it cannot read.
  virtual std::vector<uint8_t> save_state() const { return {}; }
  virtual void restore(const std::vector<uint8_t>& /*state*/) {}
  // Its costs and statistics for the log: (name, value) pairs.
  virtual std::vector<std::pair<std::string, double>> statistics() const { return {}; }
};

}  // namespace theia
