// Whether a ray goes on through a surface (shape_crossing), and the part of
// a surface hit it needs to go on (crossing_interaction): the point, its
// error bound, the normals and the shape, by compute_interaction's own
// formulas (triangle_point, triangle_normal), without the uv, the
// derivatives and the tangents that only shading reads.
#pragma once

#include "scene/shapes.h"

namespace theia {

// compute_interaction's p, p_error, ng, ns, wo, t, prim, shape, material,
// area_light and instance (the rest left at their defaults) for a top-level
// triangle mesh; for any other shape all of compute_interaction.
SurfaceInteraction crossing_interaction(const Scene& scene, const Accel& accel, const Ray& ray, const Hit& hit);

// What a shape does to a ray crossing it, where the shape alone decides it: a
// holdout or a surface with a BSDF blocks, an interface or a virtual light
// passes; a mix material is resolved at the hit (its choice hashes the point).
// Shadow rays through media ask it at every hit; a path's ray asks it only
// for a shape that is no light (a virtual light adds its emission first).
enum class ShapeCrossing { Blocks, Passes, AtHit };

inline ShapeCrossing shape_crossing(const Scene& scene, int shape) {
  const Shape& s = scene.shapes[size_t(shape)];
  if (s.holdout) return ShapeCrossing::Blocks;
  if (s.area_light >= 0 && scene.lights[size_t(s.area_light)].is_virtual) return ShapeCrossing::Passes;
  if (s.material < 0) return ShapeCrossing::Blocks;  // the default diffuse
  switch (scene.materials[size_t(s.material)].kind) {
    case MaterialKind::Interface: return ShapeCrossing::Passes;
    case MaterialKind::Mix: return ShapeCrossing::AtHit;
    default: return ShapeCrossing::Blocks;
  }
}

}  // namespace theia
