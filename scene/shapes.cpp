#include "scene/shapes.h"
#include "scene/surface_crossing.h"

#include "core/log.h"
#include "scene/curve_params.h"
#include "scene/shape_geometry.h"
#include "scene/shape_bounds.h"

#include <cmath>

namespace theia {

using glm::dmat3;
using glm::dmat4;
using glm::dvec3;
using glm::dvec4;
using namespace shape_geometry;


// ---------------------------------------------------------------- quadrics in object space

SphereShape make_sphere_shape(const SphereParams& p) {
  double r = p.radius;
  double z0 = std::min(p.zmin, p.zmax), z1 = std::max(p.zmin, p.zmax);
  SphereShape s;
  s.radius = r;
  s.zmin = std::clamp(z0, -r, r);
  s.zmax = std::clamp(z1, -r, r);
  s.theta_zmin = std::acos(std::clamp(z0 / r, -1.0, 1.0));
  s.theta_zmax = std::acos(std::clamp(z1 / r, -1.0, 1.0));
  s.phimax = std::clamp(double(p.phimax), 0.0, 360.0) * (kPiD / 180.0);
  return s;
}

DiskShape make_disk_shape(const DiskParams& p) {
  return {p.height, p.radius, p.innerradius, std::clamp(double(p.phimax), 0.0, 360.0) * (kPiD / 180.0)};
}

CylinderShape make_cylinder_shape(const CylinderParams& p) {
  return {p.radius, std::min(p.zmin, p.zmax), std::max(p.zmin, p.zmax),
          std::clamp(double(p.phimax), 0.0, 360.0) * (kPiD / 180.0)};
}

// The roots of a t^2 + b t + c for a quadric of radius r, with pbrt-v4's
// discriminant 4a (r^2 - vlen^2), vlen the ray's closest approach to the
// centre (sphere) or axis (cylinder): no cancellation for distant origins.
static bool quadric_roots(double a, double b, double c, double r, double vlen, double* t0, double* t1) {
  double discrim = 4.0 * a * (r + vlen) * (r - vlen);
  if (discrim < 0.0) return false;
  double root = std::sqrt(discrim);
  double q = b < 0.0 ? -0.5 * (b - root) : -0.5 * (b + root);
  *t0 = q / a;
  *t1 = q != 0.0 ? c / q : *t0;
  if (*t0 > *t1) std::swap(*t0, *t1);
  return true;
}

bool intersect_sphere(const SphereShape& s, const dvec3& o, const dvec3& d, double tmin, double tmax,
                      QuadricHit* hit, bool surface) {
  double r = s.radius;
  double a = glm::dot(d, d);
  if (a == 0.0) return false;
  double b = 2.0 * glm::dot(d, o);
  double olen = glm::length(o);
  double c = (olen - r) * (olen + r);
  double t0, t1;
  if (!quadric_roots(a, b, c, r, glm::length(o - (b / (2.0 * a)) * d), &t0, &t1)) return false;
  if (t0 >= tmax || t1 <= tmin) return false;
  for (double t : {t0, t1}) {
    if (t <= tmin) continue;
    if (t >= tmax) break;
    if (!surface && is_full_sphere(s)) {
      *hit = {t, 0.0f, 0.0f};
      return true;
    }
    dvec3 p = o + t * d;
    p *= r / glm::length(p);
    if (p.x == 0.0 && p.y == 0.0) p.x = 1e-5 * r;
    double phi = phi_of(p.x, p.y);
    if ((s.zmin > -r && p.z < s.zmin) || (s.zmax < r && p.z > s.zmax) || phi > s.phimax) continue;
    *hit = {t, float(phi), float(std::acos(std::clamp(p.z / r, -1.0, 1.0)))};
    return true;
  }
  return false;
}

bool intersect_disk(const DiskShape& s, const dvec3& o, const dvec3& d, double tmin, double tmax, QuadricHit* hit) {
  if (d.z == 0.0) return false;
  double t = (s.height - o.z) / d.z;
  if (t <= tmin || t >= tmax) return false;
  double x = o.x + t * d.x, y = o.y + t * d.y;
  double dist2 = x * x + y * y;
  if (dist2 > s.radius * s.radius || dist2 < s.inner_radius * s.inner_radius) return false;
  if (s.phimax < 2.0 * kPiD && phi_of(x, y) > s.phimax) return false;
  *hit = {t, float(x), float(y)};
  return true;
}

bool intersect_cylinder(const CylinderShape& s, const dvec3& o, const dvec3& d, double tmin, double tmax,
                        QuadricHit* hit, bool surface) {
  double r = s.radius;
  double a = d.x * d.x + d.y * d.y;
  if (a == 0.0) return false;  // along the axis: never meets the side
  double b = 2.0 * (d.x * o.x + d.y * o.y);
  double c = o.x * o.x + o.y * o.y - r * r;
  double f = b / (2.0 * a);
  double t0, t1;
  if (!quadric_roots(a, b, c, r, std::hypot(o.x - f * d.x, o.y - f * d.y), &t0, &t1)) return false;
  if (t0 >= tmax || t1 <= tmin) return false;
  for (double t : {t0, t1}) {
    if (t <= tmin) continue;
    if (t >= tmax) break;
    dvec3 p = o + t * d;
    if (p.z < s.zmin || p.z > s.zmax) continue;
    if (!surface && is_full_turn(s.phimax)) {
      *hit = {t, 0.0f, 0.0f};
      return true;
    }
    double rxy = std::sqrt(p.x * p.x + p.y * p.y);
    if (rxy > 0.0) p.x *= r / rxy, p.y *= r / rxy;
    double phi = phi_of(p.x, p.y);
    if (phi > s.phimax) continue;
    *hit = {t, float(phi), float(p.z)};
    return true;
  }
  return false;
}

vec2 sphere_uv(const SphereShape& s, double phi, double theta) {
  double dtheta = s.theta_zmax - s.theta_zmin;
  return vec2(float(s.phimax > 0.0 ? phi / s.phimax : 0.0), float(dtheta != 0.0 ? (theta - s.theta_zmin) / dtheta : 0.0));
}

vec2 disk_uv(const DiskShape& s, double x, double y) {
  double dr = s.radius - s.inner_radius;
  return vec2(float(s.phimax > 0.0 ? phi_of(x, y) / s.phimax : 0.0),
              float(dr != 0.0 ? (s.radius - std::sqrt(x * x + y * y)) / dr : 0.0));
}

vec2 cylinder_uv(const CylinderShape& s, double phi, double z) {
  double dz = s.zmax - s.zmin;
  return vec2(float(s.phimax > 0.0 ? phi / s.phimax : 0.0), float(dz != 0.0 ? (z - s.zmin) / dz : 0.0));
}

// ---------------------------------------------------------------- local geometry

double triangle_area(const TriangleMesh& m, size_t tri) {
  dvec3 p0(m.p[m.indices[3 * tri]]), p1(m.p[m.indices[3 * tri + 1]]), p2(m.p[m.indices[3 * tri + 2]]);
  return 0.5 * glm::length(glm::cross(p1 - p0, p2 - p0));
}

Bounds3 quadric_object_bounds(const Shape& s) {
  if (s.kind == ShapeKind::Sphere) {
    SphereShape sp = make_sphere_shape(s.sphere);
    return Bounds3(vec3(-sp.radius, -sp.radius, sp.zmin), vec3(sp.radius, sp.radius, sp.zmax));
  }
  if (s.kind == ShapeKind::Cylinder) {
    CylinderShape cy = make_cylinder_shape(s.cylinder);
    return Bounds3(vec3(-cy.radius, -cy.radius, cy.zmin), vec3(cy.radius, cy.radius, cy.zmax));
  }
  DiskShape dk = make_disk_shape(s.disk);
  return Bounds3(vec3(-dk.radius, -dk.radius, dk.height), vec3(dk.radius, dk.radius, dk.height));
}

Bounds3 padded_bounds(Bounds3 b) {
  vec3 pad = 1e-5f * glm::max(glm::abs(b.min), glm::abs(b.max)) + vec3(1e-30f);
  b.min -= pad;
  b.max += pad;
  return b;
}

Bounds3 transform_bounds(const glm::dmat4& m, const Bounds3& b) {
  Bounds3 r;
  for (int c = 0; c < 8; ++c) {
    glm::dvec3 p((c & 1) ? b.max.x : b.min.x, (c & 2) ? b.max.y : b.min.y, (c & 4) ? b.max.z : b.min.z);
    r = union_bounds(r, vec3(glm::dvec3(m * glm::dvec4(p, 1.0))));
  }
  return padded_bounds(r);
}

std::optional<Bounds3> top_level_shape_bounds(const Scene& scene, const Shape& s) {
  if (s.kind == ShapeKind::Curve) return std::nullopt;
  if (s.kind != ShapeKind::TriangleMesh)
    return transform_bounds(glm::dmat4(s.render_from_object.m), quadric_object_bounds(s));
  Bounds3 b;
  for (const vec3& p : scene.meshes[size_t(s.mesh)].p) b = union_bounds(b, p);
  return b.empty() ? b : padded_bounds(b);
}

void triangle_uvs(const TriangleMesh& m, size_t tri, vec2 uv[3]) {
  for (int k = 0; k < 3; ++k) uv[k] = corner_uv(m, m.indices[3 * tri + size_t(k)], k);
}

namespace {

vec3 face_forward(const vec3& v, const vec3& ref) { return glm::dot(v, ref) < 0.0f ? -v : v; }

// Triangle tri's geometric normal oriented as pbrt-v4 orients it (from its
// unit normal as wound, triangle_unit_normal); writes the shading normal
// (interpolated N, or the geometric normal) to *ns.
vec3 orient_triangle_normal(const TriangleMesh& m, vec3 ng, bool flip, size_t tri, float b0, float b1, float b2,
                            vec3* ns) {
  if (flip) ng = -ng;
  vec3 n = ng;
  if (!m.n.empty()) {
    const uint32_t i0 = m.indices[3 * tri], i1 = m.indices[3 * tri + 1], i2 = m.indices[3 * tri + 2];
    vec3 interp = b0 * m.n[i0] + b1 * m.n[i1] + b2 * m.n[i2];
    if (glm::dot(interp, interp) > 0.0f) {
      n = glm::normalize(interp);
      ng = face_forward(ng, n);
    }
  }
  if (ns) *ns = n;
  return ng;
}


void coordinate_system(const vec3& n, vec3* a, vec3* b) {
  Frame f = Frame::from_z(n);
  *a = f.s;
  *b = f.t;
}

// pbrt-v4's dndu, dndv of a triangle's interpolated vertex normals: the normals'
// differences over the uv differences (any orthogonal pair when the uvs are degenerate).
void triangle_normal_derivatives(const TriangleMesh& m, size_t tri, vec2 duv02, vec2 duv12, vec3* dndu, vec3* dndv) {
  uint32_t i0 = m.indices[3 * tri], i1 = m.indices[3 * tri + 1], i2 = m.indices[3 * tri + 2];
  vec3 dn1 = m.n[i0] - m.n[i2], dn2 = m.n[i1] - m.n[i2];
  float det = duv02.x * duv12.y - duv02.y * duv12.x;
  if (std::abs(det) >= 1e-9f) {
    *dndu = (duv12.y * dn1 - duv02.y * dn2) / det;
    *dndv = (duv02.x * dn2 - duv12.x * dn1) / det;
    return;
  }
  vec3 dn = glm::cross(m.n[i2] - m.n[i0], m.n[i1] - m.n[i0]);
  if (glm::dot(dn, dn) > 0.0f) coordinate_system(glm::normalize(dn), dndu, dndv);
}

// A triangle hit's point and error bound: where both the full interaction
// and a crossing (surface_crossing.h) start.
[[gnu::always_inline]] inline void triangle_point(const TriangleMesh& m, size_t tri, float b0, float b1, float b2,
                                                  vec3& p, vec3& p_error) {
  uint32_t i0 = m.indices[3 * tri], i1 = m.indices[3 * tri + 1], i2 = m.indices[3 * tri + 2];
  const vec3 &p0 = m.p[i0], &p1 = m.p[i1], &p2 = m.p[i2];
  p = b0 * p0 + b1 * p1 + b2 * p2;
  p_error = gamma_bound(7) * (glm::abs(b0 * p0) + glm::abs(b1 * p1) + glm::abs(b2 * p2));
}

// `normal_derivatives`: whether dndu and dndv are wanted (only a bump map reads them).
SurfaceInteraction triangle_interaction(const TriangleMesh& m, const Shape& s, size_t tri, float b1, float b2,
                                        bool normal_derivatives) {
  float b0 = 1.0f - b1 - b2;
  uint32_t i0 = m.indices[3 * tri], i1 = m.indices[3 * tri + 1], i2 = m.indices[3 * tri + 2];
  const vec3 &p0 = m.p[i0], &p1 = m.p[i1], &p2 = m.p[i2];
  SurfaceInteraction si;
  triangle_point(m, tri, b0, b1, b2, si.p, si.p_error);
  // Corner by corner, not through triangle_uvs' array: GCC kept the array on
  // the stack, stored each corner as one 8-byte integer and read two back as
  // one vector, which store forwarding cannot serve (a third of this
  // function's time on the Cornell box).
  const vec2 uv0 = corner_uv(m, i0, 0), uv1 = corner_uv(m, i1, 1), uv2 = corner_uv(m, i2, 2);
  si.uv = b0 * uv0 + b1 * uv1 + b2 * uv2;
  vec2 duv02 = uv0 - uv2, duv12 = uv1 - uv2;
  vec3 dp02 = p0 - p2, dp12 = p1 - p2;
  float det = duv02.x * duv12.y - duv02.y * duv12.x;
  bool degenerate = std::abs(det) < 1e-9f;
  if (!degenerate) {
    float inv = 1.0f / det;
    si.dpdu = (duv12.y * dp02 - duv02.y * dp12) * inv;
    si.dpdv = (duv02.x * dp12 - duv12.x * dp02) * inv;
  }
  si.ng = triangle_normal(m, s.reverse_orientation != s.transform_swaps_handedness, tri, b0, b1, b2, &si.ns);
  if (degenerate || glm::dot(glm::cross(si.dpdu, si.dpdv), glm::cross(si.dpdu, si.dpdv)) == 0.0f)
    coordinate_system(si.ng, &si.dpdu, &si.dpdv);
  if (normal_derivatives && !m.n.empty()) triangle_normal_derivatives(m, tri, duv02, duv12, &si.dndu, &si.dndv);
  return si;
}

// Object-space quadric geometry carried to the shape's parent space.
SurfaceInteraction quadric_interaction(const Shape& s, const LocalGeom& g) {
  dmat4 m(s.render_from_object.m);
  dmat3 nm = glm::transpose(glm::inverse(dmat3(m)));
  SurfaceInteraction si;
  si.p = vec3(dvec3(m * dvec4(g.p, 1.0)));
  si.p_error = vec3(transform_error(m, g.p, g.p_error));
  si.ng = vec3(glm::normalize(nm * g.n));
  if (s.reverse_orientation != s.transform_swaps_handedness) si.ng = -si.ng;
  si.ns = si.ng;
  si.uv = g.uv;
  si.dpdu = vec3(dmat3(m) * g.dpdu);
  si.dpdv = vec3(dmat3(m) * g.dpdv);
  // Carried as normals, as pbrt-v4 carries them, over the length the transform gives the unit
  // normal: exact for similarities, where pbrt-v4's dndu is off by the inverse of the scale.
  const double n_scale = glm::length(nm * g.n);
  si.dndu = vec3(nm * g.dndu / n_scale);
  si.dndv = vec3(nm * g.dndv / n_scale);
  return si;
}

// Embree's curve hits carry only (t, u, v): p comes from the ray, the frame
// from the segment at u.  o, d in the curve's space.  Embree's own Ng is not
// kept (it is the tangent on flat curves, and Hit stays small).
SurfaceInteraction curve_interaction(const CurveSet& c, const Shape& s, const vec3& o, const vec3& d, const Hit& hit) {
  size_t k = std::min<size_t>(hit.prim, c.segment_count() - 1);
  float u = std::clamp(hit.u, 0.0f, 1.0f);
  CubicBezier b = curve_segment(c, k);
  vec3 p = o + hit.t * d;
  // Embree's u is approximate (on tubes the centre point at u was measured up
  // to 75% of the radius off): Newton steps to the centre-line point closest
  // to p, whose tangent is perpendicular to p - centre.
  for (int it = 0; it < 4; ++it) {
    vec3 e = bezier_point(b, u) - p, d1 = bezier_derivative(b, u);
    vec3 d2 = 6.0f * ((1.0f - u) * (b[2] - 2.0f * b[1] + b[0]) + u * (b[3] - 2.0f * b[2] + b[1]));
    float f1 = glm::dot(d1, d1) + glm::dot(e, d2);
    if (!(f1 > 0.0f)) break;
    u = std::clamp(u - glm::dot(e, d1) / f1, 0.0f, 1.0f);
  }
  vec3 center = bezier_point(b, u);
  vec3 dpdu = bezier_derivative(b, u);
  // Coincident end control points leave a zero derivative at the end itself.
  if (!(glm::dot(dpdu, dpdu) > 0.0f)) dpdu = b[3] - b[0];
  if (!(glm::dot(dpdu, dpdu) > 0.0f)) dpdu = vec3(1.0f, 0.0f, 0.0f);
  vec3 T = glm::normalize(dpdu);
  auto across = [&](vec3 v) { return v - glm::dot(v, T) * T; };
  SurfaceInteraction si;
  si.p = p;
  float r = curve_radius(c, k, u);
  vec3 n(0.0f);
  if (c.type == CurveType::Flat) {
    n = across(-d);  // the ribbon faces the ray
  } else if (c.type == CurveType::Cylinder) {
    // A sweep of circles: radial, tilted back where the radius changes along the curve.
    vec3 radial = across(si.p - center);
    if (glm::dot(radial, radial) > 0.0f) {
      float s1 = 1.0f - u;
      const vec4* q = &c.cp[4 * k];
      float dr = 3.0f * (s1 * s1 * (q[1].w - q[0].w) + 2.0f * s1 * u * (q[2].w - q[1].w) + u * u * (q[3].w - q[2].w));
      n = glm::normalize(radial) - (dr / glm::length(dpdu)) * T;
    }
  } else {
    float s1 = 1.0f - u;
    const vec3* q = &c.n[4 * k];
    n = across(s1 * s1 * s1 * q[0] + 3.0f * s1 * s1 * u * q[1] + 3.0f * s1 * u * u * q[2] + u * u * u * q[3]);
  }
  if (!(glm::dot(n, n) > 0.0f) || !std::isfinite(glm::dot(n, n))) n = Frame::from_z(T).s;
  n = glm::normalize(n);
  if (c.type != CurveType::Flat && s.reverse_orientation != s.transform_swaps_handedness) n = -n;
  // Float p = o + t d, plus what Embree's iterative solve leaves of t: a few
  // ulps of the curve's coordinates (measured in tests/unit/test_curves.cpp).
  si.p_error = gamma_bound(3) * (glm::abs(o) + glm::abs(hit.t * d)) +
               gamma_bound(64) * (glm::abs(center) + vec3(r));
  si.ng = si.ns = n;
  si.uv = vec2(hit.u, hit.v);
  // On a tapered tube n leans back along T: keep dpdu in the tangent plane.
  si.dpdu = dpdu - glm::dot(dpdu, n) * n;
  si.dpdv = glm::normalize(glm::cross(n, T)) * (2.0f * r);
  return si;
}

}  // namespace

vec3 shape_geometry::triangle_normal(const TriangleMesh& m, bool flip, size_t tri, float b0, float b1, float b2,
                                      vec3* ns) {
  return orient_triangle_normal(m, triangle_unit_normal(m, tri), flip, tri, b0, b1, b2, ns);
}

vec3 shape_geometry::triangle_normal(const TriangleMesh& m, const vec3& unit_normal, bool flip, size_t tri, float b0,
                                      float b1, float b2, vec3* ns) {
  return orient_triangle_normal(m, unit_normal, flip, tri, b0, b1, b2, ns);
}

namespace {

// The interaction on the hit's own shape, before any instance transform.
// Each kind's is returned as it is made, so that it is built in
// compute_interaction's result: assigned from a temporary, the copy read
// back the temporary's narrow stores as wide loads, which store forwarding
// cannot serve (a third of compute_interaction's time on the Cornell box).
[[gnu::always_inline]] inline SurfaceInteraction shape_interaction(const Scene& scene, const Accel& accel,
                                                                   const Ray& ray, const Hit& hit, const Shape& s) {
  if (s.kind == ShapeKind::TriangleMesh) {
    // A bump map (bsdf.cpp's shading_frame) is the only reader of dndu and
    // dndv: a shape whose material has none, and cannot pick one by a mix,
    // leaves them 0.
    const Material* mat = s.material >= 0 ? &scene.materials[size_t(s.material)] : nullptr;
    const bool bump = !mat || mat->displacement >= 0 || mat->kind == MaterialKind::Mix;
    return triangle_interaction(scene.meshes[size_t(s.mesh)], s, hit.prim, hit.u, hit.v, bump);
  }
  if (s.kind == ShapeKind::Sphere || s.kind == ShapeKind::Cylinder) {
    const vec2 uv = std::isnan(hit.u) ? accel.quadric_uv(ray, hit) : vec2(hit.u, hit.v);
    return quadric_interaction(s, s.kind == ShapeKind::Sphere ? sphere_local(make_sphere_shape(s.sphere), uv.x, uv.y)
                                                              : cylinder_local(make_cylinder_shape(s.cylinder), uv.x, uv.y));
  }
  if (s.kind == ShapeKind::Curve) {
    vec3 o = ray.o, d = ray.d;
    if (int inst = accel.instance_index(hit); inst >= 0) {
      // Embree found the hit with the ray in instance space, where t is the same.
      const dmat4& inv = accel.instance_from_render(inst);
      o = vec3(dvec3(inv * dvec4(dvec3(ray.o), 1.0)));
      d = vec3(dmat3(inv) * dvec3(ray.d));
    }
    return curve_interaction(scene.curves[size_t(s.curves)], s, o, d, hit);
  }
  return quadric_interaction(s, disk_local(make_disk_shape(s.disk), hit.u, hit.v));
}

}  // namespace

SurfaceInteraction compute_interaction(const Scene& scene, const Accel& accel, const Ray& ray, const Hit& hit) {
  int shape = accel.shape_index(hit);
  if (shape < 0) throw_error("compute_interaction: hit names no shape (geometry {})", hit.geom);
  const Shape& s = scene.shapes[size_t(shape)];
  SurfaceInteraction si = shape_interaction(scene, accel, ray, hit, s);
  if (s.kind == ShapeKind::TriangleMesh || s.kind == ShapeKind::Curve) si.prim = int(hit.prim);
  if (s.kind == ShapeKind::Curve) si.skip = PrimRef{hit.inst, hit.geom, hit.prim};
  int inst = accel.instance_index(hit);
  if (inst >= 0) {
    const Transform& t = scene.instances[size_t(inst)].render_from_instance;
    const dmat4& m = accel.render_from_instance(inst);
    dvec3 p_inst(si.p), e_inst(si.p_error);
    dvec3 p = dvec3(m * dvec4(p_inst, 1.0));
    // Embree carries rays into instance space with its own float inverse;
    // widen the bound by that mapping's error so spawned rays clear the surface.
    dvec3 e_back = transform_error(accel.instance_from_render(inst), p, dvec3(0.0));
    si.p = vec3(p);
    si.p_error = vec3(transform_error(m, p_inst, e_inst + e_back));
    const float n_scale = glm::length(t.normal(si.ns));  // as for quadrics: exact for similarities
    si.ng = glm::normalize(t.normal(si.ng));
    si.ns = face_forward(glm::normalize(t.normal(si.ns)), si.ng);
    si.dpdu = t.vector(si.dpdu);
    si.dpdv = t.vector(si.dpdv);
    si.dndu = t.normal(si.dndu) / n_scale;
    si.dndv = t.normal(si.dndv) / n_scale;
  }
  si.wo = -glm::normalize(ray.d);
  si.t = hit.t;
  si.shape = shape;
  si.material = s.material;
  si.area_light = s.area_light;
  si.instance = inst;
  return si;
}

namespace {
// The mesh behind a triangle hit, or nullptr.
const TriangleMesh* hit_mesh(const Scene& scene, const Accel& accel, const Hit& hit) {
  const int shape = accel.shape_index(hit);
  if (shape < 0) return nullptr;
  const Shape& s = scene.shapes[size_t(shape)];
  return s.kind == ShapeKind::TriangleMesh ? &scene.meshes[size_t(s.mesh)] : nullptr;
}
}  // namespace

TrianglePrefetcher::Arrays TrianglePrefetcher::arrays_of(const TriangleMesh* m) {
  if (!m || m->indices.empty()) return {};
  return {m->indices.data(), m->p.data(), m->n.empty() ? nullptr : m->n.data(), m->uv.empty() ? nullptr : m->uv.data()};
}

TrianglePrefetcher::TrianglePrefetcher(const Scene& scene, const Accel& accel) : scene_(scene), accel_(accel) {
  top_.resize(accel.top_geometry_count());
  for (size_t g = 0; g < top_.size(); ++g) {
    Hit h;
    h.geom = uint32_t(g);
    top_[g] = arrays_of(hit_mesh(scene, accel, h));
  }
}

TrianglePrefetcher::Arrays TrianglePrefetcher::instanced(const Hit& hit) const {
  return arrays_of(hit_mesh(scene_, accel_, hit));
}

size_t triangle_mesh_bytes(const Scene& scene) {
  size_t bytes = 0;
  for (const TriangleMesh& m : scene.meshes)
    bytes += m.indices.size() * sizeof(uint32_t) + m.p.size() * sizeof(vec3) + m.n.size() * sizeof(vec3) +
             m.uv.size() * sizeof(vec2);
  return bytes;
}

// Out of line, so that every caller (and the accel's table of them) gets the
// same rounding.
[[gnu::noinline]] vec3 triangle_unit_normal(const TriangleMesh& m, size_t tri) {
  const uint32_t i0 = m.indices[3 * tri], i1 = m.indices[3 * tri + 1], i2 = m.indices[3 * tri + 2];
  const vec3 &p0 = m.p[i0], &p1 = m.p[i1], &p2 = m.p[i2];
  vec3 c = glm::cross(p0 - p2, p1 - p2);
  if (glm::dot(c, c) == 0.0f) c = vec3(glm::cross(dvec3(p0 - p2), dvec3(p1 - p2)));
  return glm::normalize(c);
}

SurfaceCrossing surface_crossing(const Scene& scene, const Accel& accel, const Ray& ray, const Hit& hit, int shape) {
  if (shape < 0 || scene.shapes[size_t(shape)].kind != ShapeKind::TriangleMesh || accel.instance_index(hit) >= 0)
    return surface_crossing(compute_interaction(scene, accel, ray, hit));
  const Shape& s = scene.shapes[size_t(shape)];
  SurfaceCrossing c;
  const TriangleMesh& m = scene.meshes[size_t(s.mesh)];
  const float b0 = 1.0f - hit.u - hit.v;
  triangle_point(m, hit.prim, b0, hit.u, hit.v, c.p, c.p_error);
  // A surface rays pass through has its unit normals at hand (a crossing
  // was ~2% of smoke-grid's CPU in the normalisation's square root and division).
  const vec3* unit = accel.passing_unit_normals(shape);
  const vec3 ng = unit ? unit[hit.prim] : triangle_unit_normal(m, hit.prim);
  c.ng = orient_triangle_normal(m, ng, s.reverse_orientation != s.transform_swaps_handedness, hit.prim, b0, hit.u,
                                hit.v, nullptr);
  c.shape = shape;
  return c;
}

vec3 offset_ray_origin(const vec3& p, const vec3& p_error, const vec3& ng, const vec3& w) {
  // To w's side by a sign, not a branch: a batch's hits alternate between
  // surfaces whose normals face their rays and surfaces whose normals do not.
  const float d = glm::dot(glm::abs(ng), p_error) * (glm::dot(w, ng) < 0.0f ? -1.0f : 1.0f);
  const vec3 offset = d * ng;
  vec3 po = p + offset;
  // Round away from p so that the offset survives the addition's rounding.
  for (int i = 0; i < 3; ++i) po[i] = next_float_toward(po[i], offset[i]);
  return po;
}

// A point whose error bound is zero along the normal (a coordinate that is
// exactly 0 on an axis-aligned plane through the origin) gets no offset, and
// Embree, unlike pbrt-v4's own tests, accepts a hit at t == 0; a tmin just
// above zero rejects exactly that hit and nothing else.
constexpr float kSpawnTMin = std::numeric_limits<float>::min();

namespace {

// The spawns from a surface point with error bound p_error and normal ng.
template <class Surface>
Ray spawn_from(const Surface& si, const vec3& d) {
  return Ray{offset_ray_origin(si.p, si.p_error, si.ng, d), kSpawnTMin, d, kInfinity};
}

template <class Surface>
Ray spawn_from_to(const Surface& si, const vec3& p_to, const vec3& p_to_error, const vec3& n_to) {
  vec3 pf = offset_ray_origin(si.p, si.p_error, si.ng, p_to - si.p);
  vec3 pt = offset_ray_origin(p_to, p_to_error, n_to, pf - p_to);
  return Ray{pf, kSpawnTMin, pt - pf, 1.0f - kShadowEpsilon};
}

}  // namespace

Ray spawn_ray(const SurfaceInteraction& si, const vec3& d) { return spawn_from(si, d); }
Ray spawn_ray(const SurfaceCrossing& c, const vec3& d) { return spawn_from(c, d); }

Ray spawn_ray_to(const SurfaceInteraction& si, const vec3& p_to, const vec3& p_to_error, const vec3& n_to) {
  return spawn_from_to(si, p_to, p_to_error, n_to);
}
Ray spawn_ray_to(const SurfaceCrossing& c, const vec3& p_to, const vec3& p_to_error, const vec3& n_to) {
  return spawn_from_to(c, p_to, p_to_error, n_to);
}

}  // namespace theia
