// The traceable scene: every shape of a theia::Scene turned into Embree
// geometry (curves into Embree's native Bezier curves), object prototypes
// into instanced sub-scenes.
//
// The Accel shares the Scene's vertex and index arrays, so the Scene must
// outlive it and stay unmodified.  Embree headers stay out of this header.
#pragma once

#include "core/bounds.h"
#include "core/math.h"
#include "scene/scene.h"

#include <cstdint>
#include <limits>
#include <memory>
#include <span>

namespace theia {

inline constexpr uint32_t kInvalidId = 0xffffffffu;  // == RTC_INVALID_GEOMETRY_ID

// An Embree primitive: (top-level instance, geometry, primitive), as in Hit.
struct PrimRef {
  uint32_t inst = kInvalidId, geom = kInvalidId, prim = kInvalidId;
};

struct Ray {
  vec3 o;
  float tmin = 0;
  vec3 d;
  float tmax = kInfinity;
};
// A ray spawned from a curve skips the segment it left (SurfaceInteraction::skip,
// passed beside the rays to intersect/occluded): hits on it within
// kCurveSkipWidths of its width of the origin are ignored, since a thin
// curve's hit point is too imprecise (and a flat curve turns to face every
// ray) for an origin offset to clear it.  Only curve geometry reads it, and
// the skips travel beside the rays, not in them, so scenes without curves keep
// 32-byte rays and pass none.
inline constexpr float kCurveSkipWidths = 2.0f;

// Flat curves are Embree's chains of ray-facing quads, at most 16 per segment:
// on a segment whose max |c''| is at most 8 kFlatCurveSag width 16^2 (= 512
// widths: a curvature radius above ~width / 5 on a unit-length segment) the
// ribbon lies within kFlatCurveSag * width of the Bezier curve; beyond, within
// max|c''| / (8 * 16^2).  See scene/README.md.
inline constexpr float kFlatCurveSag = 0.25f;
inline constexpr float kFlatCurveMaxRate = 16.0f;

// What tracing returns; geom == kInvalidId means a miss.  geom/prim name the
// Embree geometry and primitive in the scene that was hit (the prototype's
// scene for instanced hits), inst the top-level instance geometry.
//   triangles: (u, v) are Embree's barycentrics: p = (1-u-v) p0 + u p1 + v p2
//   spheres:   (u, v) = object-space (phi, theta)
//   disks:     (u, v) = object-space (x, y)
//   cylinders: (u, v) = object-space (phi, z)
//   curves:    (u, v) = Embree's: u along segment `prim` (0..1), v across
//              (-1..1 flat, 0..1 ribbon, 0 on round "cylinder" curves)
struct Hit {
  float t = kInfinity;
  float u = 0, v = 0;
  uint32_t geom = kInvalidId, prim = 0, inst = kInvalidId;
  bool hit() const { return geom != kInvalidId; }
};
// Hit::u of a quadric hit whose (u, v) were left for Accel::quadric_uv.
inline constexpr float kQuadricUVPending = std::numeric_limits<float>::quiet_NaN();

class Accel {
 public:
  explicit Accel(const Scene& scene);
  ~Accel();
  Accel(const Accel&) = delete;
  Accel& operator=(const Accel&) = delete;

  // Closest hits.  Single-threaded over the span; safe to call concurrently.
  // `coherent`: neighbouring rays share origin and direction closely (a
  // camera batch), and are traced in Embree's widest native packets.  The
  // hits are those of one by one, bit for bit, except on curves (to rounding:
  // Embree's packet curve intersector rounds differently), and never depend
  // on which rays share a packet.
  // `skips`: empty, or the curve segment each ray left (parallel to rays).
  // `surface` false: the caller needs only t and what was hit, not (u, v):
  // spheres and cylinders whose cuts cannot reject a root then leave u, v at
  // 0 (no atan2 / acos).  The hits are the same either way.
  void intersect(std::span<const Ray> rays, std::span<Hit> hits, bool coherent,
                 std::span<const PrimRef> skips = {}, bool surface = true) const;
  // Any hit in [tmin, tmax]: blocked[i] = 1 if ray i is occluded.
  void occluded(std::span<const Ray> rays, std::span<uint8_t> blocked, std::span<const PrimRef> skips = {}) const;
  // Convenience for tests and one-off queries.
  Hit intersect1(const Ray& ray, const PrimRef& skip = {}, bool surface = true) const;
  bool occluded1(const Ray& ray, const PrimRef& skip = {}) const;
  // A shadow ray's trace through media (Accel::intersect_passing): `stop` is
  // the closest hit on anything but a passing surface (a triangle mesh or
  // curve that shape_crossing says passes: an interface or a virtual light,
  // no holdout; quadrics are always stops, they run no filters), a miss if
  // none; `first_pass` the nearest passing hit met, `passes` how many were
  // met.  The closest of the two is intersect1's hit.  Passing hits beyond
  // `stop` may be in the count; when `stop` misses, every passing hit in
  // [tmin, tmax] is.
  struct PassingTrace {
    Hit stop, first_pass;
    uint32_t passes = 0;
    const Hit& closest() const { return first_pass.t < stop.t ? first_pass : stop; }
  };
  PassingTrace intersect_passing(const Ray& ray, const PrimRef& skip = {}, bool surface = true) const;

  // A top-level sphere's or cylinder's hit carries u = kQuadricUVPending:
  // its (u, v), found again from the ray that hit (compute_interaction asks).
  vec2 quadric_uv(const Ray& ray, const Hit& hit) const;
  int shape_index(const Hit& hit) const;     // index into Scene::shapes, -1 on a miss
  size_t top_geometry_count() const;         // top-level geometry ids are below this
  // A triangle mesh that rays pass through (an interface: intersect_passing's
  // shapes): its triangles' unit normals (scene/surface_crossing.h
  // triangle_unit_normal), computed once; nullptr for any other shape.
  const vec3* passing_unit_normals(int shape) const;
  int instance_index(const Hit& hit) const;  // index into Scene::instances, or -1
  // Scene instance i's render_from_instance and its inverse, in double, as
  // hit points are carried back to render space (computed once, not per hit).
  const glm::dmat4& render_from_instance(int i) const;
  const glm::dmat4& instance_from_render(int i) const;
  Bounds3 bounds() const;                    // render-space bounds of all geometry
  size_t memory_bytes() const;               // what the built scene keeps allocated (Embree + tables)

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace theia
