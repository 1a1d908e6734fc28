// Scenes built shape by shape for the geometry tests (test_accel.cpp,
// test_shapes.cpp): transforms and the Shape records the parser would make.
#pragma once

#include "scene/scene.h"

#include <glm/gtc/matrix_transform.hpp>

namespace theia::test {

inline Transform translate(vec3 t) { return Transform(glm::translate(mat4(1.0f), t)); }
inline Transform scale(vec3 s) { return Transform(glm::scale(mat4(1.0f), s)); }
inline Transform rotate(float deg, vec3 axis) { return Transform(glm::rotate(mat4(1.0f), radians(deg), axis)); }

// Appends `s` (to the top level unless `top` is false); its index.
inline int add_shape(Scene& sc, Shape s, bool top = true) {
  int index = int(sc.shapes.size());
  sc.shapes.push_back(std::move(s));
  if (top) sc.top_level_shapes.push_back(index);
  return index;
}
// A quadric placed by `t`, handedness taken from the transform as the parser does.
inline Shape quadric_shape(ShapeKind kind, const Transform& t, bool reverse) {
  Shape s;
  s.kind = kind;
  s.render_from_object = t;
  s.transform_swaps_handedness = t.swaps_handedness();
  s.reverse_orientation = reverse;
  return s;
}
inline int add_sphere(Scene& sc, SphereParams p, Transform t = {}, bool reverse = false, bool top = true) {
  Shape s = quadric_shape(ShapeKind::Sphere, t, reverse);
  s.sphere = p;
  return add_shape(sc, s, top);
}
inline int add_disk(Scene& sc, DiskParams p, Transform t = {}, bool reverse = false, bool top = true) {
  Shape s = quadric_shape(ShapeKind::Disk, t, reverse);
  s.disk = p;
  return add_shape(sc, s, top);
}
inline int add_cylinder(Scene& sc, CylinderParams p, Transform t = {}, bool reverse = false, bool top = true) {
  Shape s = quadric_shape(ShapeKind::Cylinder, t, reverse);
  s.cylinder = p;
  return add_shape(sc, s, top);
}
// `m` in render space (the parser bakes the transform into the vertices).
inline int add_mesh(Scene& sc, TriangleMesh m, bool reverse = false, bool swaps = false, bool top = true) {
  Shape s;
  s.kind = ShapeKind::TriangleMesh;
  s.mesh = int(sc.meshes.size());
  sc.meshes.push_back(std::move(m));
  s.reverse_orientation = reverse;
  s.transform_swaps_handedness = swaps;
  return add_shape(sc, s, top);
}
// Makes shape `index` an area light of radiance 1; returns `index`.
inline int make_emissive(Scene& sc, int index) {
  Light l;
  l.shape = index;
  l.L = RGB(1.0f);
  sc.shapes[size_t(index)].area_light = int(sc.lights.size());
  sc.lights.push_back(l);
  return index;
}

}  // namespace theia::test
