#include "scene/light_params.h"

#include "scene/shapes.h"

#include <algorithm>

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
  if (m.patch_start.empty()) {
    // pbrt-v4's Triangle::Area(), in float from the render-space corners.
    for (size_t t = 0; t < l.triangle_scale.size(); ++t) l.triangle_scale[t] = per_area(float(triangle_area(m, t)));
  } else {
    // A bilinear patch is one pbrt-v4 light: its triangles share the patch's
    // radiance.  The tessellation's area stands in for BilinearPatch::Area()
    // (exact for planar patches; pbrt-v4 approximates curved ones too).
    for (size_t k = 0; k + 1 < m.patch_start.size(); ++k) {
      double area = 0.0;
      for (uint32_t t = m.patch_start[k]; t < m.patch_start[k + 1]; ++t) area += triangle_area(m, t);
      std::fill(l.triangle_scale.begin() + m.patch_start[k], l.triangle_scale.begin() + m.patch_start[k + 1],
                per_area(float(area)));
    }
  }
  bool uniform = true;
  for (float f : l.triangle_scale) uniform = uniform && f == l.triangle_scale[0];
  if (uniform && !l.triangle_scale.empty()) {
    l.L *= l.triangle_scale[0];
    l.triangle_scale.clear();
  }
  return l;
}

}  // namespace theia
