// What the tracing tests share (test_accel.cpp, test_spawn.cpp): a ray, a
// trace with its interaction, random directions and a tetrahedron.
#pragma once

#include "core/sampling.h"
#include "scene/accel.h"
#include "scene/shapes.h"

#include <array>
#include <random>

namespace theia::test {

inline TriangleMesh tetrahedron(const std::array<vec3, 4>& p) {
  TriangleMesh m;
  m.p.assign(p.begin(), p.end());
  m.indices = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  return m;
}
inline Ray make_ray(vec3 o, vec3 d) { return Ray{o, 0.0f, d, kInfinity}; }

struct Traced {
  Hit hit;
  SurfaceInteraction si;
};
inline Traced trace(const Scene& sc, const Accel& a, const Ray& r) {
  Traced t;
  t.hit = a.intersect1(r);
  if (t.hit.hit()) t.si = compute_interaction(sc, a, r, t.hit);
  return t;
}

inline vec3 random_direction(std::mt19937& rng) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  return sample_uniform_sphere(vec2(u(rng), u(rng)));
}

}  // namespace theia::test
