#include "scene/lights.h"

#include "core/log.h"
#include "core/sampling.h"

namespace theia {

LightSet::LightSet(const Scene& s, const Accel& accel) : scene(&s), shapes(s) {
  Bounds3 b = accel.bounds();
  if (b.min.x <= b.max.x) {
    scene_center = 0.5f * (b.min + b.max);
    scene_radius = 0.5f * glm::length(b.max - b.min);
  }
  for (size_t i = 0; i < s.lights.size(); ++i) {
    const Light& l = s.lights[i];
    if (l.kind == LightKind::Infinite) {
      infinite_lights.push_back(int(i));
      if (l.image >= 0)
        log_warning("{}:{}: environment images are not supported yet: the infinite light uses constant L",
                    l.loc.file, l.loc.line);
    }
  }
}

std::optional<LightLiSample> sample_li(const LightSet& lights, int light_index, const LightSampleContext& ctx,
                                       vec2 u, float u_prim) {
  const Light& light = lights.scene->lights[light_index];
  switch (light.kind) {
    case LightKind::Area: {
      auto ss = lights.shapes.sample(light.shape, ShapeSampleContext{ctx.p, ctx.ng}, u, u_prim);
      if (!ss || ss->pdf == 0.0f) return std::nullopt;
      vec3 d = ss->p - ctx.p;
      float dist2 = glm::dot(d, d);
      if (dist2 == 0.0f) return std::nullopt;
      vec3 wi = d / std::sqrt(dist2);
      RGB L = light.two_sided || glm::dot(ss->n, -wi) > 0.0f ? light.L : RGB(0.0f);
      if (is_black(L)) return std::nullopt;
      return LightLiSample{L, wi, ss->pdf, ss->p, ss->p_error, ss->n, false, false};
    }
    case LightKind::Point: {
      vec3 d = light.position - ctx.p;
      float dist2 = glm::dot(d, d);
      if (dist2 == 0.0f) return std::nullopt;
      vec3 wi = d / std::sqrt(dist2);
      return LightLiSample{light.L / dist2, wi, 1.0f, light.position, vec3(0.0f), vec3(0.0f), true, false};
    }
    case LightKind::Infinite: {
      vec3 wi = sample_uniform_sphere(u);
      float far = 2.0f * lights.scene_radius + glm::length(ctx.p - lights.scene_center) + 1.0f;
      return LightLiSample{light.L, wi, uniform_sphere_pdf(), ctx.p + wi * far, vec3(0.0f), -wi, false, true};
    }
  }
  return std::nullopt;
}

float area_light_pdf(const LightSet& lights, int light_index, const LightSampleContext& ctx, const vec3& wi,
                     const SurfaceInteraction& hit) {
  const Light& light = lights.scene->lights[light_index];
  return lights.shapes.pdf(light.shape, ShapeSampleContext{ctx.p, ctx.ng}, wi, hit);
}

float infinite_light_pdf(const LightSet&, int, const vec3&) { return uniform_sphere_pdf(); }

RGB area_light_L(const Light& light, const SurfaceInteraction& hit, const vec3& w) {
  if (!light.two_sided && glm::dot(hit.ng, w) <= 0.0f) return RGB(0.0f);
  return light.L;
}

RGB infinite_light_Le(const LightSet& lights, int light_index, const vec3&) {
  return lights.scene->lights[light_index].L;
}

float light_power(const LightSet& lights, int light_index) {
  const Light& light = lights.scene->lights[light_index];
  float y = luminance(light.L);
  switch (light.kind) {
    case LightKind::Area:
      return kPi * (light.two_sided ? 2.0f : 1.0f) * lights.shapes.area(light.shape) * y;
    case LightKind::Point:
      return 4.0f * kPi * y;
    case LightKind::Infinite:
      return kPi * sqr(lights.scene_radius) * 4.0f * kPi * y;
  }
  return 0.0f;
}

}  // namespace theia
