// How a shading point chooses which light to sample for next-event estimation.
//
// The wavefront sees only this interface.  The baseline samplers (uniform and
// power-proportional) live here; cache points, which learn a per-region
// distribution with visibility, will implement the same interface.
#pragma once

#include "core/sampling.h"
#include "scene/lights.h"

#include <memory>
#include <optional>
#include <string>

namespace theia {

struct SampledLight {
  int light = -1;
  float pmf = 0.0f;
};

class LightSampler {
 public:
  virtual ~LightSampler() = default;
  virtual std::optional<SampledLight> sample(const LightSampleContext& ctx, float u) const = 0;
  // Probability that sample(ctx, .) returns `light`.
  virtual float pmf(const LightSampleContext& ctx, int light) const = 0;
  virtual const char* name() const = 0;
};

class UniformLightSampler final : public LightSampler {
 public:
  explicit UniformLightSampler(int light_count) : count_(light_count) {}
  std::optional<SampledLight> sample(const LightSampleContext&, float u) const override;
  float pmf(const LightSampleContext&, int light) const override;
  const char* name() const override { return "uniform"; }

 private:
  int count_;
};

class PowerLightSampler final : public LightSampler {
 public:
  explicit PowerLightSampler(const LightSet& lights);
  std::optional<SampledLight> sample(const LightSampleContext&, float u) const override;
  float pmf(const LightSampleContext&, int light) const override;
  const char* name() const override { return "power"; }

 private:
  Distribution1D distribution_;
};

// "uniform" or "power"; throws theia::Error for anything else.
std::unique_ptr<LightSampler> make_light_sampler(const std::string& name, const LightSet& lights);

}  // namespace theia
