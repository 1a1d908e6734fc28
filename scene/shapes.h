// Shapes as geometry: the quadric intersection routines Embree calls back
// into, surface interactions rebuilt from hits, robust ray spawning
// (pbrt-v4's error bounds), and sampling points on shapes for area lights.
#pragma once

#include "core/math.h"
#include "core/prefetch.h"
#include "core/sampling.h"
#include "scene/accel.h"
#include "scene/scene.h"

#include <optional>
#include <vector>

namespace theia {

// pbrt-v4's gamma(n): bound on the relative error of n chained float operations.
inline constexpr float gamma_bound(int n) {
  constexpr float e = 0x1p-24f;
  return (float(n) * e) / (1.0f - float(n) * e);
}
inline constexpr float kShadowEpsilon = 1e-4f;

// ---------------------------------------------------------------- quadrics in object space

// pbrt-v4's derived sphere/disk parameters (angles in radians, z range clamped).
struct SphereShape {
  double radius, zmin, zmax, theta_zmin, theta_zmax, phimax;
};
struct DiskShape {
  double height, radius, inner_radius, phimax;
};
struct CylinderShape {
  double radius, zmin, zmax, phimax;
};
SphereShape make_sphere_shape(const SphereParams& p);
DiskShape make_disk_shape(const DiskParams& p);
CylinderShape make_cylinder_shape(const CylinderParams& p);

struct QuadricHit {
  double t;
  float u, v;  // what Hit::u, Hit::v store for the shape kind
};
// Closest intersection with t in (tmin, tmax), both sphere roots considered.
// Double precision so that rays spawned off the surface never re-hit it.
// `surface` false: the caller needs only t, so where no cut (z range, phimax)
// can reject the root, u and v are left 0 (no atan2 / acos); the same roots
// are accepted either way.
bool intersect_sphere(const SphereShape& s, const glm::dvec3& o, const glm::dvec3& d, double tmin, double tmax,
                      QuadricHit* hit, bool surface = true);
bool intersect_disk(const DiskShape& s, const glm::dvec3& o, const glm::dvec3& d, double tmin, double tmax,
                    QuadricHit* hit);
// Both roots considered; the caps are open (pbrt-v4), so a ray can enter at
// one end and hit the inside.  `surface` as for spheres (the full turn: no phi).
bool intersect_cylinder(const CylinderShape& s, const glm::dvec3& o, const glm::dvec3& d, double tmin, double tmax,
                        QuadricHit* hit, bool surface = true);
// pbrt-v4's (u, v) of a hit from QuadricHit's u, v: (phi / phimax, the
// fraction of the theta range) on spheres, (phi / phimax, (radius - r) /
// (radius - inner radius)) on disks, (phi / phimax, (z - zmin) / (zmax -
// zmin)) on cylinders.
vec2 sphere_uv(const SphereShape& s, double phi, double theta);
vec2 disk_uv(const DiskShape& s, double x, double y);
vec2 cylinder_uv(const CylinderShape& s, double phi, double z);

// ---------------------------------------------------------------- interactions

struct SurfaceInteraction {
  vec3 p{0.0f};
  vec3 p_error{0.0f};  // conservative absolute error bound of p
  vec3 ng{0.0f};       // geometric normal, unit, pbrt-v4 orientation
  vec3 ns{0.0f};       // shading normal, unit, same hemisphere as ng
  vec2 uv{0.0f};
  vec3 dpdu{0.0f}, dpdv{0.0f};
  // pbrt-v4's derivatives of the normal (the shape's own, never flipped): the displaced
  // surface p + d n of a bump map turns with them.  0 on planes, disks and curves.
  vec3 dndu{0.0f}, dndv{0.0f};
  vec3 wo{0.0f};  // -ray.d, unit
  float t = 0.0f;
  int shape = -1, material = -1, area_light = -1, instance = -1;
  int prim = -1;  // triangle meshes: the triangle (per-triangle emission and sampling pdf)
  // Curves: the segment hit, which rays spawned here ignore near their origin
  // (the skips beside rays, scene/accel.h).  Unset (kInvalidId) on every other shape.
  PrimRef skip;
};

// Area of triangle `tri`, in double from its stored (float) corners.
double triangle_area(const TriangleMesh& m, size_t tri);

// The (u, v) of triangle `tri`'s corners: the mesh's, or pbrt-v4's default (0,0) (1,0) (1,1).
void triangle_uvs(const TriangleMesh& m, size_t tri, vec2 uv[3]);
// One corner's: `vertex` the mesh vertex at corner 0, 1 or 2.
inline vec2 corner_uv(const TriangleMesh& m, uint32_t vertex, int corner) {
  if (m.uv.empty()) return vec2(corner == 0 ? 0.0f : 1.0f, corner == 2 ? 1.0f : 0.0f);
  return m.uv[vertex];
}

SurfaceInteraction compute_interaction(const Scene& scene, const Accel& accel, const Ray& ray, const Hit& hit);
// Shading visits a batch's hits in traced order (or, sorted, in (geometry,
// primitive) order), and on a mesh larger than the cache neighbouring hits
// land on distant triangles: compute_interaction then waits on the
// triangle's indices and again on its vertices.  Ask for them ahead, the
// indices first and, once they have arrived, the vertices they name.
// No-ops for other shapes and misses.  Worth it only where the meshes
// outgrow the cache (triangle_mesh_bytes): below that they fetch nothing.
// A top-level mesh's arrays are found by geometry id in a table made once,
// not through the shape and mesh tables at every hit (a dozen loads and two
// calls, which were a twentieth of the shade stage).
class TrianglePrefetcher {
 public:
  TrianglePrefetcher(const Scene& scene, const Accel& accel);
  void indices(const Hit& hit) const {
    if (hit.inst != kInvalidId) return indices(instanced(hit), hit.prim);
    if (hit.geom < top_.size()) indices(top_[hit.geom], hit.prim);
  }
  void vertices(const Hit& hit) const {
    if (hit.inst != kInvalidId) return vertices(instanced(hit), hit.prim);
    if (hit.geom < top_.size()) vertices(top_[hit.geom], hit.prim);
  }

 private:
  struct Arrays {
    const uint32_t* indices = nullptr;  // nullptr: not a triangle mesh (or a miss)
    const vec3 *p = nullptr, *n = nullptr;
    const vec2* uv = nullptr;
  };
  static void indices(const Arrays& a, uint32_t prim) {
    if (a.indices) prefetch_line(a.indices + 3 * size_t(prim));
  }
  static void vertices(const Arrays& a, uint32_t prim) {
    if (!a.indices) return;
    const uint32_t* v = a.indices + 3 * size_t(prim);
    for (int c = 0; c < 3; ++c) {
      prefetch_line(a.p + v[c]);
      if (a.n) prefetch_line(a.n + v[c]);
      if (a.uv) prefetch_line(a.uv + v[c]);
    }
  }
  Arrays instanced(const Hit& hit) const;  // through the shape and mesh tables
  static Arrays arrays_of(const TriangleMesh* m);  // none for nullptr (another shape, a miss)
  const Scene& scene_;
  const Accel& accel_;
  std::vector<Arrays> top_;  // by top-level geometry id
};
// Bytes of every triangle mesh's indices, positions, normals and uvs: what
// compute_interaction reads from.
size_t triangle_mesh_bytes(const Scene& scene);

// pbrt-v4 OffsetRayOrigin: p pushed along ng past its error box, to w's side.
vec3 offset_ray_origin(const vec3& p, const vec3& p_error, const vec3& ng, const vec3& w);
Ray spawn_ray(const SurfaceInteraction& si, const vec3& d);
// Shadow ray from si to p_to, both ends offset; d = end - start (not unit), tmax = 1 - kShadowEpsilon.
Ray spawn_ray_to(const SurfaceInteraction& si, const vec3& p_to, const vec3& p_to_error, const vec3& n_to);

// ---------------------------------------------------------------- sampling for area lights

struct ShapeSample {
  vec3 p{0.0f};
  vec3 p_error{0.0f};
  vec3 n{0.0f};  // oriented as compute_interaction's ng at p
  vec2 uv{0.0f};
  int prim = -1;     // triangle meshes: the triangle chosen
  float pdf = 0.0f;  // w.r.t. solid angle at the reference point
};
struct ShapeSampleContext {
  vec3 p{0.0f};
  vec3 n{0.0f};  // zero for points in media
};

class ShapeSampling {
 public:
  ShapeSampling() = default;
  // Tables only for top-level shapes with area_light >= 0.  A mesh's
  // triangles are chosen with probability proportional to area times
  // triangle_weight[shape][i] (the light's emitted luminance per unit area on
  // triangle i, so that triangles are chosen by power), or to area alone
  // where that vector is missing or empty.
  explicit ShapeSampling(const Scene& scene, const std::vector<std::vector<float>>& triangle_weight = {});

  // `triangle` >= 0 on a mesh: that triangle, chosen by the caller (a light
  // sampler that treats each triangle as a light, as pbrt-v4 does); the pdf
  // is then the triangle's alone (per unit area 1 / its area), u_prim unused.
  // `want_uv` false: the caller reads no uv (a light without an image or an
  // alpha texture), so a sphere's cone sample leaves it 0 instead of paying
  // an acos, an atan2 and a double transform for it.
  std::optional<ShapeSample> sample(int shape, const ShapeSampleContext& ref, vec2 u, float u_prim,
                                    int triangle = -1, bool want_uv = true) const;
  // A point by area (what sample() does where it does not sample a cone), pdf per unit area.
  std::optional<ShapeSample> sample_area(int shape, vec2 u, float u_prim, int triangle = -1) const;
  // Solid-angle density with which sample() returns light_hit's point in
  // direction wi; `given_triangle`: as sample() with light_hit.prim chosen by the caller.
  float pdf(int shape, const ShapeSampleContext& ref, const vec3& wi, const SurfaceInteraction& light_hit,
            bool given_triangle = false) const;
  float area(int shape) const;

  // One sampleable shape (public only so that the .cpp's helpers can see it).
  struct Entry {
    ShapeKind kind = ShapeKind::TriangleMesh;
    const TriangleMesh* mesh = nullptr;
    bool flip = false;  // reverse_orientation XOR transform_swaps_handedness
    float area = 0.0f;
    Distribution1D triangles;  // mesh: proportional to triangle area (times its weight)
    std::vector<float> triangle_pdf;  // weighted mesh: area density on each triangle (pmf / area)
    // mesh: each triangle's unit normal as wound (triangle_unit_normal), made
    // once: every light sample needs one, and its square root and division
    // were a visible share of next-event estimation.
    std::vector<vec3> unit_normals;
    SphereShape sphere{};
    DiskShape disk{};
    CylinderShape cylinder{};
    glm::dmat4 render_from_object{1.0}, object_from_render{1.0};
    glm::dmat3 normal_matrix{1.0};  // inverse transpose of the linear part
    double det = 1.0;               // |det| of the linear part
    double object_area = 0.0;       // quadrics: area before the transform
    bool cone = false;              // full sphere under a similarity: cone sampling from outside
    vec3 center{0.0f};
    float render_radius = 0.0f;
  };

 private:
  float area_pdf(const Entry& e, const vec3& p, int prim) const;
  std::vector<Entry> entries_;
  std::vector<int> entry_of_shape_;
};

// The area pbrt-v4's DiffuseAreaLight divides "power" by for a quadric: its
// object-space area, as pbrt-v4's Sphere::Area(), Disk::Area() and Cylinder::Area() return
// (meshes are one light per triangle: triangle_area).
float pbrt_quadric_area(const Shape& shape);

}  // namespace theia
