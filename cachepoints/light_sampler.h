// The baseline light samplers: uniform and power-proportional.  The
// interface the wavefront calls is core/light_sampler.h (included here so
// that code naming this header keeps working); cache points, which learn a
// per-region distribution with visibility, will implement it beside these.
#pragma once

#include "core/light_sampler.h"
#include "core/sampling.h"
#include "scene/lights.h"

#include <memory>
#include <optional>
#include <string>

namespace theia {

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
