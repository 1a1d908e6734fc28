// Whether a ray goes on through a surface (shape_crossing), and the part of
// a surface hit it needs to go on (surface_crossing): the point, its error
// bound, the geometric normal, the shape and the curve segment to skip, by
// compute_interaction's own formulas (triangle_point, triangle_normal),
// without the uv, the derivatives, the tangents and the shading normal that
// only shading reads.
#pragma once

#include "scene/shapes.h"

namespace theia {

struct SurfaceCrossing {
  vec3 p{0.0f}, p_error{0.0f}, ng{0.0f};
  int shape = -1;
  PrimRef skip;
};

// compute_interaction's p, p_error, ng, shape and skip for a hit on `shape`
// (accel.shape_index(hit), which the caller has looked up already): for a
// top-level triangle mesh computed alone, for any other shape taken from
// compute_interaction.
SurfaceCrossing surface_crossing(const Scene& scene, const Accel& accel, const Ray& ray, const Hit& hit, int shape);
inline SurfaceCrossing surface_crossing(const SurfaceInteraction& si) {
  return {si.p, si.p_error, si.ng, si.shape, si.skip};
}
// Triangle tri's unit geometric normal as wound (before pbrt-v4's
// orientation): what surface_crossing and compute_interaction start from,
// and what Accel::passing_unit_normals holds.
vec3 triangle_unit_normal(const TriangleMesh& m, size_t tri);
// spawn_ray and spawn_ray_to leaving a crossing.
Ray spawn_ray(const SurfaceCrossing& c, const vec3& d);
Ray spawn_ray_to(const SurfaceCrossing& c, const vec3& p_to, const vec3& p_to_error, const vec3& n_to);

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
