// The caustic pass's test of a light path's first ray against the caster
// boxes, and its float estimate of a sphere light's first ray
// (wavefront/caustics.cpp).  In a header of their own so that the guard test
// (tests/unit/test_caustic_first_ray.cpp) can hold the estimate to its
// promise: every ray it drops is one the exact test would drop too.
#pragma once

#include "core/math.h"
#include "scene/lights.h"
#include "scene/scene.h"

#include <vector>

namespace theia::caustic_first_ray {

// Whether the ray may meet box b at t >= 0: a slab test that only a sure
// miss fails (a NaN from a ray in a slab's plane keeps the box; the far
// distance is widened by pbrt-v4's gamma(3) bound).
bool may_meet(const Ray& ray, const Bounds3& b);

// The exact first ray of a light path leaving a light with sample le.
Ray emitted_ray(const LightLeSample& le);

// A sphere light's emitted rays, estimated in float before sample_le computes
// them exactly (in double, with the point's error bounds, its pdf and its
// radiance): a light path whose first ray surely meets no caster box is
// dropped from the estimate alone.  The estimate repeats sample_le's steps
// (ShapeSampling::sample_area's uniform (z, phi) point, its normal through the
// normal matrix, the side of a two-sided light, the cosine-weighted direction
// in Frame::from_z) from the same numbers, so it lies within float rounding of
// the exact ray: within kOriginSlack (relative to the point's size) of its
// origin, the offset included, and kDirectionSlack of its unit direction.
// A box grown by the origin's slack plus the direction's slack times the
// farthest the box can be is then met by the estimate wherever the exact ray
// meets the box, so the exact test (may_meet, itself widened by a few ulps
// only) drops every path the estimate drops: the image stays bit for bit.
// The slacks are ~100 times the float rounding they cover.  Where the frame's
// branch (the sign of n.z) could differ between the two, nothing is dropped.
// The boxes are grown once per light, by the most any point of the sphere
// needs (its distance to the box and its size bounded over the sphere: at
// most a sphere's size more than a point on it needs, and the sphere is
// small beside the distances where a box's slack matters), and a ray that
// misses their union misses them all.
struct SphereEmitter {
  bool valid = false;
  double zmin = 0.0, zmax = 0.0, radius = 1.0, phimax = 0.0;
  mat4 render_from_object{1.0f};
  mat3 normal_matrix{1.0f};
  bool flip = false, two_sided = false;
  float size = 0.0f;  // the transformed radius bound, for the origin's slack
  std::vector<Bounds3> grown;  // the caster boxes, grown by the slacks
  Bounds3 grown_union;
};
constexpr float kOriginSlack = 1e-4f, kDirectionSlack = 1e-3f, kMinFrameZ = 1e-3f;

// Light `light`'s estimate against `boxes`; not valid unless it is an area
// light on a sphere.
SphereEmitter sphere_emitter(const Scene& scene, int light, const std::vector<Bounds3>& boxes);

// Whether the ray sample_le would make from (u_pos, u_dir) may meet one of
// the boxes (see SphereEmitter); true wherever the estimate is unsure.
bool sphere_ray_may_meet(const SphereEmitter& e, vec2 u_pos, vec2 u_dir);

}  // namespace theia::caustic_first_ray
