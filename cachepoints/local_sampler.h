// The locally optimal light sampler (`--light-sampler local`): at each vertex
// every emitter's unoccluded estimate (emitter_importance), a choice in
// proportion to it.  The quality ceiling of a sampler that knows no
// visibility, for small test scenes: sample() and pmf() each cost one
// evaluation per emitter at every vertex.  Cache points fall back to the same
// choice where they have too few points.
//
// A small uniform share over all emitters keeps every emitter possible: the
// estimate is conservative in angle but zero behind a one-sided emitter and
// for a black one, and the estimator must stay unbiased wherever it errs.
#pragma once

#include "cachepoints/emitters.h"
#include "core/light_sampler.h"

#include <optional>

namespace theia {

// From this many emitters `--light-sampler local` warns: each vertex then
// evaluates more emitters than cache points would list there (the cache
// points' `auto` threshold, where selection cost starts to matter).
inline constexpr size_t kLocalWarnEmitters = 1024;

// The choice among `set` at ctx: emitter e with probability
// share / n + (1 - share) importance(e) / total, where total is the sum of
// the importances; all uniform where that sum is zero or not finite.
struct LocalChoice {
  int emitter = -1;
  float pmf = 0.0f;
};
LocalChoice sample_locally_optimal(const LightSet& lights, const EmitterSet& set, const LightSampleContext& ctx,
                                   float u, float uniform_share);
float pmf_locally_optimal(const LightSet& lights, const EmitterSet& set, const LightSampleContext& ctx, int emitter,
                          float uniform_share);

class LocalLightSampler final : public LightSampler {
 public:
  LocalLightSampler(const LightSet& lights, float uniform_share);
  std::optional<SampledLight> sample(const LightSampleContext& ctx, float u) const override;
  float pmf(const LightSampleContext& ctx, int light) const override { return pmf_primitive(ctx, light, -1); }
  float pmf_primitive(const LightSampleContext& ctx, int light, int primitive) const override;
  const char* name() const override { return "local"; }
  bool chooses_primitives() const override { return true; }
  std::vector<std::pair<std::string, double>> statistics() const override;

  const EmitterSet& emitters() const { return emitters_; }

 private:
  const LightSet& lights_;
  EmitterSet emitters_;
  float uniform_share_;
};

}  // namespace theia
