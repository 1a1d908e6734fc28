// The baseline light samplers, uniform and power-proportional, and the
// --light-sampler choice among them and cache points (cache_points.h).  The
// interface the wavefront calls is core/light_sampler.h (included here so
// that code naming this header keeps working).
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

// "auto": cache points from this many emitters on (a mesh light's triangles
// each count), the light BVH from kAutoBvhEmitters, else power-proportional
// selection (cachepoints/README.md has the measurements behind both).
inline constexpr size_t kAutoCachePointEmitters = 1024;
inline constexpr size_t kAutoBvhEmitters = 8;

bool light_sampler_name_known(const std::string& name);
// "uniform", "power", "bvh" (cachepoints/light_bvh.h), "cachepoints" (cachepoints/cache_points.h; power for a
// scene of one emitter, where there is nothing to choose), "local"
// (cachepoints/local_sampler.h; never chosen by "auto": it costs every emitter
// at every vertex) or "auto"; throws theia::Error for anything else.
std::unique_ptr<LightSampler> make_light_sampler(const std::string& name, const LightSet& lights, const Accel& accel);

}  // namespace theia
