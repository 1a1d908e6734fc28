// The part of a surface hit a ray needs to go on through the surface (a
// shadow ray crossing an "interface" in a scene with media): the point, its
// error bound, the normals and the shape, by compute_interaction's own
// formulas (triangle_point, triangle_normal), without the uv, the derivatives
// and the tangents that only shading reads.
#pragma once

#include "scene/shapes.h"

namespace theia {

// compute_interaction's p, p_error, ng, ns, wo, t, prim, shape, material,
// area_light and instance (the rest left at their defaults) for a top-level
// triangle mesh; for any other shape all of compute_interaction.
SurfaceInteraction crossing_interaction(const Scene& scene, const Accel& accel, const Ray& ray, const Hit& hit);

}  // namespace theia
