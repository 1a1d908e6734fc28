// Boxes around shapes, for the accel's quadrics and the caustic pass's casters.
#pragma once

#include "core/bounds.h"
#include "scene/scene.h"

#include <optional>

namespace theia {

// A quadric's object-space box (a sphere's z range, a disk's plane).
Bounds3 quadric_object_bounds(const Shape& s);
// Box b padded so that float rounding can never clip a hit on what it bounds.
Bounds3 padded_bounds(Bounds3 b);
// The padded box of b's corners carried by m.
Bounds3 transform_bounds(const glm::dmat4& m, const Bounds3& b);
// A top-level triangle mesh's or quadric's padded render-space box (meshes
// are baked to render space); nullopt for a curve.
std::optional<Bounds3> top_level_shape_bounds(const Scene& scene, const Shape& s);

}  // namespace theia
