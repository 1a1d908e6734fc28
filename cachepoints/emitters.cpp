#include "cachepoints/emitters.h"

#include "scene/shapes.h"

#include <algorithm>
#include <cmath>

namespace theia {

namespace {

// Per unit area, the mean of a light's emitted luminance (images and per-triangle "power" included).
float mean_radiance(const LightSet& lights, int light) {
  const Light& l = lights.scene->lights[size_t(light)];
  float area = lights.shapes.area(l.shape);
  return area > 0.0f ? float(lights.area_luminance[size_t(light)] / double(area)) : 0.0f;
}

void add_mesh_triangles(const LightSet& lights, int light, EmitterSet& set) {
  const Light& l = lights.scene->lights[size_t(light)];
  const Shape& s = lights.scene->shapes[size_t(l.shape)];
  const TriangleMesh& m = lights.scene->meshes[size_t(s.mesh)];
  const float mean = mean_radiance(lights, light);
  for (size_t t = 0; t < m.triangle_count(); ++t) {
    Emitter e;
    e.light = light;
    e.primitive = int(t);
    e.two_sided = l.two_sided;
    const vec3 &p0 = m.p[m.indices[3 * t]], &p1 = m.p[m.indices[3 * t + 1]], &p2 = m.p[m.indices[3 * t + 2]];
    e.center = (p0 + p1 + p2) / 3.0f;
    e.radius = std::sqrt(std::max({glm::dot(p0 - e.center, p0 - e.center), glm::dot(p1 - e.center, p1 - e.center),
                                   glm::dot(p2 - e.center, p2 - e.center)}));
    e.area = float(triangle_area(m, t));
    // The emitting side as sampling sees it (orientation flags included).
    if (auto ss = lights.shapes.sample_area(l.shape, vec2(1.0f / 3.0f), 0.0f, int(t))) e.normal = ss->n;
    e.radiance = l.triangle_scale.empty() ? mean : luminance(l.L) * l.triangle_scale[t];
    set.emitters.push_back(e);
  }
}

// A sphere, disk or cylinder: one emitter, its centre and radius from a few area samples.
Emitter whole_shape(const LightSet& lights, int light) {
  const Light& l = lights.scene->lights[size_t(light)];
  Emitter e;
  e.light = light;
  e.two_sided = true;  // curved: some part faces almost every way
  e.area = lights.shapes.area(l.shape);
  e.radiance = mean_radiance(lights, light);
  constexpr int kSamples = 8;
  std::vector<vec3> pts;
  for (int i = 0; i < kSamples; ++i)
    for (int j = 0; j < kSamples; ++j)
      if (auto ss = lights.shapes.sample_area(l.shape, vec2((i + 0.5f) / kSamples, (j + 0.5f) / kSamples), 0.5f))
        pts.push_back(ss->p);
  for (const vec3& p : pts) e.center += p / float(pts.size());
  for (const vec3& p : pts) e.radius = std::max(e.radius, glm::length(p - e.center));
  return e;
}

Emitter light_emitter(const LightSet& lights, int light) {
  const Light& l = lights.scene->lights[size_t(light)];
  Emitter e;
  e.light = light;
  switch (l.kind) {
    case LightKind::Area:
      return whole_shape(lights, light);
    case LightKind::Infinite:
      e.kind = EmitterKind::Infinite;
      // light_power() is the luminance integral times the disk pi r^2; per steradian:
      e.radiance = light_power(lights, light) / (kPi * sqr(lights.scene_radius) * 4.0f * kPi);
      return e;
    case LightKind::Distant:
      e.kind = EmitterKind::Distant;
      e.radiance = luminance(l.L);
      e.direction = l.direction;
      return e;
    default:
      e.kind = EmitterKind::PointLike;
      e.center = l.position;
      return e;
  }
}

// cos(max(theta - alpha, 0)) for cos theta = c and an emitter of angular radius alpha.
float cos_bound(float c, float sin_a, float cos_a) {
  if (c >= cos_a) return 1.0f;
  return std::max(0.0f, c * cos_a + std::sqrt(std::max(0.0f, 1.0f - c * c)) * sin_a);
}

// What a finite emitter sends towards p, per unit receiver cosine (intensity / d^2), and
// where from: the unit direction w from p towards it and its angular radius.
struct Incoming {
  float value = 0.0f;
  vec3 w{0.0f, 0.0f, 1.0f};
  float sin_a = 0.0f, cos_a = 1.0f;
};

Incoming incoming(const LightSet& lights, const Emitter& e, const vec3& p) {
  Incoming in;
  const vec3 d = e.center - p;
  const float d2 = glm::dot(d, d);
  const float dist = std::sqrt(d2);
  if (dist > 0.0f) in.w = d / dist;
  in.sin_a = dist > e.radius ? e.radius / dist : 1.0f;
  in.cos_a = std::sqrt(std::max(0.0f, 1.0f - in.sin_a * in.sin_a));
  if (e.kind == EmitterKind::PointLike) {
    if (!(d2 > 0.0f)) return in;
    in.value = luminance(light_intensity(lights, e.light, -in.w)) / d2;
    return in;
  }
  float cos_e = 1.0f;
  if (glm::dot(e.normal, e.normal) > 0.0f) {
    const float c = glm::dot(e.normal, -in.w);
    cos_e = cos_bound(e.two_sided ? std::abs(c) : c, in.sin_a, in.cos_a);
  }
  // Closer than its own size the inverse square overestimates: clamp at its radius.
  in.value = e.radiance * e.area * cos_e / std::max(d2, sqr(e.radius));
  return in;
}

// An area light on a triangle mesh: one emitter per triangle.
bool per_triangle(const LightSet& lights, const Light& l) {
  return l.kind == LightKind::Area && l.shape >= 0 &&
         lights.scene->shapes[size_t(l.shape)].kind == ShapeKind::TriangleMesh && lights.shapes.area(l.shape) > 0.0f;
}

}  // namespace

size_t emitter_count(const LightSet& lights) {
  size_t n = 0;
  for (const Light& l : lights.scene->lights)
    n += per_triangle(lights, l) ? lights.scene->meshes[size_t(lights.scene->shapes[size_t(l.shape)].mesh)].triangle_count()
                                 : 1;
  return n;
}

EmitterSet build_emitters(const LightSet& lights) {
  EmitterSet set;
  const Scene& scene = *lights.scene;
  set.first.resize(scene.lights.size());
  set.count.resize(scene.lights.size());
  for (size_t i = 0; i < scene.lights.size(); ++i) {
    const Light& l = scene.lights[i];
    set.first[i] = int(set.emitters.size());
    if (per_triangle(lights, l))
      add_mesh_triangles(lights, int(i), set);
    else
      set.emitters.push_back(light_emitter(lights, int(i)));
    set.count[i] = int(set.emitters.size()) - set.first[i];
  }
  return set;
}

float emitter_importance(const LightSet& lights, const Emitter& e, const vec3& p, const vec3& n) {
  const bool surface = glm::dot(n, n) > 0.0f;
  if (e.kind == EmitterKind::Infinite) return e.radiance * (surface ? kPi : 4.0f * kPi);
  if (e.kind == EmitterKind::Distant) return e.radiance * (surface ? std::abs(glm::dot(n, e.direction)) : 1.0f);
  Incoming in = incoming(lights, e, p);
  if (!surface || in.value == 0.0f) return in.value;
  return in.value * cos_bound(std::abs(glm::dot(n, in.w)), in.sin_a, in.cos_a);
}

SensorValues emitter_sensors(const LightSet& lights, const Emitter& e, const vec3& p) {
  SensorValues s{};
  if (e.kind == EmitterKind::Infinite) {
    s.fill(e.radiance * kPi);
    s[kFluenceBin] = e.radiance * 4.0f * kPi;
    return s;
  }
  const bool distant = e.kind == EmitterKind::Distant;
  Incoming in;
  if (distant) {
    in.value = e.radiance;
    in.w = e.direction;
  } else {
    in = incoming(lights, e, p);
  }
  s[kFluenceBin] = in.value;
  if (in.value == 0.0f) return s;
  for (int axis = 0; axis < 3; ++axis) {
    s[size_t(2 * axis)] = in.value * cos_bound(in.w[axis], in.sin_a, in.cos_a);
    s[size_t(2 * axis + 1)] = in.value * cos_bound(-in.w[axis], in.sin_a, in.cos_a);
  }
  return s;
}

}  // namespace theia
