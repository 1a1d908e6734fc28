#include "cachepoints/local_sampler.h"

#include <algorithm>
#include <cmath>

namespace theia {

namespace {

float total_importance(const LightSet& lights, const EmitterSet& set, const LightSampleContext& ctx) {
  float total = 0.0f;
  for (const Emitter& e : set.emitters) total += emitter_importance(lights, e, ctx.p, ctx.ng);
  return total;
}

float share_for(float total, float uniform_share) {
  return total > 0.0f && std::isfinite(total) ? uniform_share : 1.0f;
}

// One formula for sample() and pmf(), so that the two agree to the bit.
float probability(float importance, float total, float share, size_t n) {
  float p = share / float(n);
  if (share < 1.0f) p += (1.0f - share) * importance / total;
  return p;
}

}  // namespace

LocalChoice sample_locally_optimal(const LightSet& lights, const EmitterSet& set, const LightSampleContext& ctx,
                                   float u, float uniform_share) {
  const size_t n = set.size();
  if (n == 0) return {};
  const float total = total_importance(lights, set, ctx);
  const float share = share_for(total, uniform_share);
  int e = -1;
  if (u < share) {
    e = std::min(int(u / share * float(n)), int(n) - 1);
  } else {
    // Never past the last emitter of positive importance (t may round up to the total).
    float t = (u - share) / (1.0f - share) * total;
    for (size_t i = 0; i < n; ++i) {
      const float w = emitter_importance(lights, set.emitters[i], ctx.p, ctx.ng);
      if (w > 0.0f) e = int(i);
      if (t < w) break;
      t -= w;
    }
  }
  if (e < 0) return {};
  const float w = emitter_importance(lights, set.emitters[size_t(e)], ctx.p, ctx.ng);
  return {e, probability(w, total, share, n)};
}

float pmf_locally_optimal(const LightSet& lights, const EmitterSet& set, const LightSampleContext& ctx, int emitter,
                          float uniform_share) {
  if (emitter < 0 || size_t(emitter) >= set.size()) return 0.0f;
  const float total = total_importance(lights, set, ctx);
  const float w = emitter_importance(lights, set.emitters[size_t(emitter)], ctx.p, ctx.ng);
  return probability(w, total, share_for(total, uniform_share), set.size());
}

LocalLightSampler::LocalLightSampler(const LightSet& lights, float uniform_share)
    : lights_(lights), emitters_(build_emitters(lights)), uniform_share_(uniform_share) {}

std::optional<SampledLight> LocalLightSampler::sample(const LightSampleContext& ctx, float u) const {
  const LocalChoice c = sample_locally_optimal(lights_, emitters_, ctx, u, uniform_share_);
  if (c.emitter < 0 || !(c.pmf > 0.0f)) return std::nullopt;
  const Emitter& e = emitters_.emitters[size_t(c.emitter)];
  return SampledLight{e.light, c.pmf, 0, e.primitive};
}

float LocalLightSampler::pmf_primitive(const LightSampleContext& ctx, int light, int primitive) const {
  return pmf_locally_optimal(lights_, emitters_, ctx, emitters_.find(light, primitive), uniform_share_);
}

std::vector<std::pair<std::string, double>> LocalLightSampler::statistics() const {
  return {{"emitters", double(emitters_.size())}, {"uniform_share", double(uniform_share_)}};
}

}  // namespace theia
