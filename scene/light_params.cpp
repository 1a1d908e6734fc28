#include "scene/light_params.h"

#include "scene/shapes.h"

namespace theia {

Light make_area_light(const Scene& scene, const AreaLightParams& a, const Shape& s, int shape_index) {
  Light l;
  l.kind = LightKind::Area;
  l.L = a.L;
  l.image = a.image;
  l.power = a.power;
  l.two_sided = a.two_sided;
  l.is_virtual = a.is_virtual;
  l.shape = shape_index;
  l.loc = s.loc;
  if (!(a.power > 0.0f)) return l;
  const float k = kPi * (a.two_sided ? 2.0f : 1.0f);
  // A shape or triangle without area is never hit nor sampled; 0 keeps phi / 0 out of the tables.
  auto per_area = [&](float area) { return area > 0.0f ? a.power / (k * area) : 0.0f; };
  if (s.kind != ShapeKind::TriangleMesh) {
    l.L *= per_area(pbrt_quadric_area(s));
    return l;
  }
  const TriangleMesh& m = scene.meshes[size_t(s.mesh)];
  l.triangle_scale.resize(m.triangle_count());
  bool uniform = true;
  for (size_t t = 0; t < l.triangle_scale.size(); ++t) {
    // pbrt-v4's Triangle::Area(), in float from the render-space corners.
    l.triangle_scale[t] = per_area(float(triangle_area(m, t)));
    uniform = uniform && l.triangle_scale[t] == l.triangle_scale[0];
  }
  if (uniform && !l.triangle_scale.empty()) {
    l.L *= l.triangle_scale[0];
    l.triangle_scale.clear();
  }
  return l;
}

}  // namespace theia
