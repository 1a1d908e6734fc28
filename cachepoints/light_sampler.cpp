#include "cachepoints/light_sampler.h"

#include "cachepoints/cache_points.h"
#include "cachepoints/light_bvh.h"
#include "cachepoints/local_sampler.h"
#include "core/log.h"

namespace theia {

std::optional<SampledLight> UniformLightSampler::sample(const LightSampleContext&, float u) const {
  if (count_ == 0) return std::nullopt;
  int i = std::min(int(u * float(count_)), count_ - 1);
  return SampledLight{i, 1.0f / float(count_)};
}

float UniformLightSampler::pmf(const LightSampleContext&, int light) const {
  return count_ > 0 && light >= 0 && light < count_ ? 1.0f / float(count_) : 0.0f;
}

PowerLightSampler::PowerLightSampler(const LightSet& lights) {
  std::vector<float> power(lights.scene->lights.size());
  for (size_t i = 0; i < power.size(); ++i) power[i] = light_power(lights, int(i));
  distribution_ = Distribution1D(power);
}

std::optional<SampledLight> PowerLightSampler::sample(const LightSampleContext&, float u) const {
  if (distribution_.size() == 0) return std::nullopt;
  float pmf;
  int i = distribution_.sample_discrete(u, &pmf);
  if (pmf == 0.0f) return std::nullopt;
  return SampledLight{i, pmf};
}

float PowerLightSampler::pmf(const LightSampleContext&, int light) const {
  return light >= 0 && size_t(light) < distribution_.size() ? distribution_.discrete_pmf(light) : 0.0f;
}

bool light_sampler_name_known(const std::string& name) {
  return name == "uniform" || name == "power" || name == "bvh" || name == "cachepoints" || name == "local" ||
         name == "auto";
}

std::unique_ptr<LightSampler> make_light_sampler(const std::string& name, const LightSet& lights, const Accel& accel) {
  if (!light_sampler_name_known(name))
    throw_error("unknown light sampler '{}', expected uniform, power, bvh, cachepoints, local or auto", name);
  if (name == "uniform") return std::make_unique<UniformLightSampler>(int(lights.scene->lights.size()));
  if (name == "bvh") return std::make_unique<LightBvhSampler>(lights);
  const size_t emitters = emitter_count(lights);
  if (name == "local") {
    if (emitters >= kLocalWarnEmitters)
      log_warning("--light-sampler local evaluates all {} emitters at every vertex, twice with MIS: meant for small test "
                  "scenes; cachepoints or bvh choose among this many far faster",
                  emitters);
    return std::make_unique<LocalLightSampler>(lights, CachePointParams{}.uniform_share);
  }
  const bool cache_points = name == "cachepoints" ? emitters > 1 : name == "auto" && emitters >= kAutoCachePointEmitters;
  if (cache_points) return std::make_unique<CachePointSampler>(lights, accel);
  if (name == "auto" && emitters >= kAutoBvhEmitters) return std::make_unique<LightBvhSampler>(lights);
  if (name == "cachepoints") log_info("--light-sampler cachepoints: one light, nothing to choose; power-proportional");
  return std::make_unique<PowerLightSampler>(lights);
}

}  // namespace theia
