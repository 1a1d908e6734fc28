// Light evaluation and sampling for the light kinds of scene/scene.h.
//
// Sampling is split the way pbrt-v4 splits it: a LightSampler
// (cachepoints/light_sampler.h) chooses a light, then sample_li() chooses a
// point on it.  Pdfs returned here are per unit solid angle at the reference
// point and do not include the light-choice probability.
#pragma once

#include "scene/accel.h"
#include "scene/scene.h"
#include "scene/shapes.h"

#include <optional>

namespace theia {

struct LightSampleContext {
  vec3 p{0.0f};
  vec3 p_error{0.0f};
  vec3 ng{0.0f};  // zero for points not on a surface
  vec3 ns{0.0f};
};

struct LightLiSample {
  RGB L{0.0f};          // radiance arriving from the light (no visibility)
  vec3 wi{0.0f};        // unit direction towards the light
  float pdf = 0.0f;     // solid angle; for delta lights 1 and `is_delta` set
  vec3 p_light{0.0f};   // point on the light (for infinite lights: far away along wi)
  vec3 p_light_error{0.0f};
  vec3 n_light{0.0f};
  bool is_delta = false;
  bool is_infinite = false;
};

// Everything light sampling needs that is built once per scene.
struct LightSet {
  const Scene* scene = nullptr;
  ShapeSampling shapes;
  vec3 scene_center{0.0f};
  float scene_radius = 0.0f;
  std::vector<int> infinite_lights;  // indices into Scene::lights

  LightSet(const Scene& scene, const Accel& accel);
};

std::optional<LightLiSample> sample_li(const LightSet& lights, int light, const LightSampleContext& ctx, vec2 u,
                                       float u_prim);
// Solid-angle pdf that sample_li() on `light` produces the point `hit` seen along wi (area lights).
float area_light_pdf(const LightSet& lights, int light, const LightSampleContext& ctx, const vec3& wi,
                     const SurfaceInteraction& hit);
// Solid-angle pdf that sample_li() on infinite `light` produces direction wi.
float infinite_light_pdf(const LightSet& lights, int light, const vec3& wi);

// Radiance an area light emits from `hit` towards `w` (one- or two-sided).
RGB area_light_L(const Light& light, const SurfaceInteraction& hit, const vec3& w);
// Radiance arriving along an escaped ray from one infinite light.
RGB infinite_light_Le(const LightSet& lights, int light, const vec3& dir);

// Total emitted power (for power-proportional light selection), as luminance.
float light_power(const LightSet& lights, int light);

}  // namespace theia
