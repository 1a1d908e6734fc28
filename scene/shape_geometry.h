// What hit setup (shapes.cpp) and area sampling (shape_sampling.cpp) share:
// quadric points in object space as pbrt-v4 sets them up (derivatives and
// error bounds, inline, so that each caller gets the code it had when both
// were one file: the same rounding, the images bit for bit) and triangles'
// oriented normals.  Internal to scene/.
#pragma once

#include "core/math.h"
#include "scene/shapes.h"

#include <cmath>

namespace theia::shape_geometry {

using glm::dmat4;
using glm::dvec3;

inline constexpr double kPiD = 3.14159265358979323846;

// phi_of's largest value is 2 pi as a double (atan2 of a negative angle
// plus 2 pi rounds to at most that), so phimax >= 2 pi never cuts.
inline bool is_full_turn(double phimax) { return phimax >= 2.0 * kPiD; }

inline bool is_full_sphere(const SphereShape& s) {
  return s.zmin <= -s.radius && s.zmax >= s.radius && is_full_turn(s.phimax);
}

inline double phi_of(double x, double y) {
  double phi = std::atan2(y, x);
  return phi < 0.0 ? phi + 2.0 * kPiD : phi;
}

// A quadric point in object space with pbrt-v4's derivatives and error.
struct LocalGeom {
  dvec3 p, p_error, n, dpdu, dpdv;
  dvec3 dndu{0.0}, dndv{0.0};
  vec2 uv;
};

inline LocalGeom sphere_local(const SphereShape& s, double phi, double theta) {
  double r = s.radius;
  double st = std::sin(theta), ct = std::cos(theta);
  LocalGeom g;
  g.p = dvec3(r * st * std::cos(phi), r * st * std::sin(phi), r * ct);
  if (g.p.x == 0.0 && g.p.y == 0.0) g.p.x = 1e-5 * r;
  g.p_error = double(gamma_bound(5)) * glm::abs(g.p);
  g.n = g.p / r;
  double dtheta = s.theta_zmax - s.theta_zmin;
  g.uv = sphere_uv(s, phi, theta);
  g.dpdu = dvec3(-s.phimax * g.p.y, s.phimax * g.p.x, 0.0);
  g.dpdv = dtheta * dvec3(g.p.z * std::cos(phi), g.p.z * std::sin(phi), -r * st);
  // n = p / r: what pbrt-v4's Weingarten equations give on a sphere.
  g.dndu = g.dpdu / r;
  g.dndv = g.dpdv / r;
  return g;
}

inline LocalGeom disk_local(const DiskShape& s, double x, double y) {
  LocalGeom g;
  g.p = dvec3(x, y, s.height);
  g.p_error = dvec3(0.0);
  g.n = dvec3(0.0, 0.0, 1.0);
  double r_hit = std::sqrt(x * x + y * y);
  double dr = s.radius - s.inner_radius;
  g.uv = disk_uv(s, x, y);
  g.dpdu = dvec3(-s.phimax * y, s.phimax * x, 0.0);
  g.dpdv = r_hit > 0.0 ? dvec3(x, y, 0.0) * (-dr / r_hit) : dvec3(0.0);
  return g;
}

// pbrt-v4's cylinder: dpdu x dpdv is the outward normal.
inline LocalGeom cylinder_local(const CylinderShape& s, double phi, double z) {
  LocalGeom g;
  g.p = dvec3(s.radius * std::cos(phi), s.radius * std::sin(phi), z);
  g.p_error = double(gamma_bound(3)) * glm::abs(dvec3(g.p.x, g.p.y, 0.0));
  g.n = dvec3(std::cos(phi), std::sin(phi), 0.0);
  g.uv = cylinder_uv(s, phi, z);
  g.dpdu = dvec3(-s.phimax * g.p.y, s.phimax * g.p.x, 0.0);
  g.dpdv = dvec3(0.0, 0.0, s.zmax - s.zmin);
  g.dndu = g.dpdu / s.radius;  // n = (x, y, 0) / r
  return g;
}

// pbrt-v4 Transform::operator()(Point3fi): bound on the error of m * p when p
// itself is off by up to e.
inline dvec3 transform_error(const dmat4& m, const dvec3& p, const dvec3& e) {
  const double g3 = gamma_bound(3);
  dvec3 err;
  for (int i = 0; i < 3; ++i) {
    double abs_sum = std::abs(m[0][i] * p.x) + std::abs(m[1][i] * p.y) + std::abs(m[2][i] * p.z) + std::abs(m[3][i]);
    double e_sum = std::abs(m[0][i]) * e.x + std::abs(m[1][i]) * e.y + std::abs(m[2][i]) * e.z;
    err[i] = g3 * abs_sum + (1.0 + g3) * e_sum;
  }
  return err;
}

// Triangle tri's geometric normal oriented as pbrt-v4 orients it (flip: the
// shape's reverse orientation differs from its transform's handedness);
// writes the shading normal (interpolated N, or the geometric normal) to
// *ns when given.  shapes.cpp.
vec3 triangle_normal(const TriangleMesh& m, bool flip, size_t tri, float b0, float b1, float b2, vec3* ns);
// The same from the triangle's unit normal as wound (triangle_unit_normal),
// for a caller that keeps those at hand.
vec3 triangle_normal(const TriangleMesh& m, const vec3& unit_normal, bool flip, size_t tri, float b0, float b1,
                     float b2, vec3* ns);

}  // namespace theia::shape_geometry
