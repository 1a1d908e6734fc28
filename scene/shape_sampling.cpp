// Area-light sampling of shapes (ShapeSampling, scene/shapes.h): points by
// area and by solid angle, with their pdfs, as pbrt-v4 samples each shape.
#include "scene/shapes.h"

#include "core/log.h"
#include "scene/shape_geometry.h"
#include "scene/surface_crossing.h"

#include <cmath>

namespace theia {

using glm::dmat3;
using glm::dmat4;
using glm::dvec3;
using glm::dvec4;
using namespace shape_geometry;

namespace {

// Area scale of the linear map at a point with object-space unit normal n (Nanson).
double area_jacobian(const ShapeSampling::Entry& e, const dvec3& n) { return e.det * glm::length(e.normal_matrix * n); }

// A linear map that is a rotation times a uniform scale s (s2 = s^2) keeps
// quadrics' areas in closed form.
bool is_similarity(const dmat3& lin, double* s2_out) {
  dmat3 g = glm::transpose(lin) * lin;
  double s2 = (g[0][0] + g[1][1] + g[2][2]) / 3.0;
  *s2_out = s2;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (std::abs(g[i][j] - (i == j ? s2 : 0.0)) > 1e-5 * s2) return false;
  return true;
}

// 1 - cos(theta_max) of the cone subtended by a sphere, with pbrt-v4's
// small-angle expansion where the direct form loses all precision.
float cone_one_minus_cos(float sin2_theta_max) {
  if (sin2_theta_max < 0.00068523f) return sin2_theta_max / 2.0f;
  return 1.0f - safe_sqrt(1.0f - sin2_theta_max);
}

std::optional<ShapeSample> to_solid_angle(ShapeSample ss, float pdf_area, const ShapeSampleContext& ref) {
  vec3 d = ss.p - ref.p;
  float d2 = glm::dot(d, d);
  if (d2 == 0.0f) return std::nullopt;
  float cos = std::abs(glm::dot(ss.n, d / std::sqrt(d2)));
  if (cos == 0.0f) return std::nullopt;
  ss.pdf = pdf_area * d2 / cos;
  if (!std::isfinite(ss.pdf) || ss.pdf <= 0.0f) return std::nullopt;
  return ss;
}

std::optional<ShapeSample> with_pdf(ShapeSample ss, float pdf_area) {
  ss.pdf = pdf_area;
  if (!std::isfinite(ss.pdf) || ss.pdf <= 0.0f) return std::nullopt;
  return ss;
}

ShapeSample from_quadric(const ShapeSampling::Entry& e, const LocalGeom& g) {
  ShapeSample ss;
  ss.p = vec3(dvec3(e.render_from_object * dvec4(g.p, 1.0)));
  ss.p_error = vec3(transform_error(e.render_from_object, g.p, g.p_error));
  ss.n = vec3(glm::normalize(e.normal_matrix * g.n));
  if (e.flip) ss.n = -ss.n;
  ss.uv = g.uv;
  return ss;
}

}  // namespace

ShapeSampling::ShapeSampling(const Scene& scene, const std::vector<std::vector<float>>& triangle_weight)
    : entry_of_shape_(scene.shapes.size(), -1) {
  for (const ObjectPrototype& proto : scene.prototypes)
    for (int s : proto.shapes)
      if (scene.shapes[size_t(s)].area_light >= 0)
        log_warning("{}:{}: area lights inside object instances are not supported; the shape will not be sampled",
                    scene.shapes[size_t(s)].loc.file, scene.shapes[size_t(s)].loc.line);

  for (int index : scene.top_level_shapes) {
    const Shape& s = scene.shapes[size_t(index)];
    if (s.area_light < 0) continue;
    Entry e;
    e.kind = s.kind;
    e.flip = s.reverse_orientation != s.transform_swaps_handedness;
    if (s.kind == ShapeKind::TriangleMesh) {
      e.mesh = &scene.meshes[size_t(s.mesh)];
      e.unit_normals.resize(e.mesh->triangle_count());
      for (size_t t = 0; t < e.unit_normals.size(); ++t) e.unit_normals[t] = triangle_unit_normal(*e.mesh, t);
      std::vector<float> areas(e.mesh->triangle_count());
      double total = 0.0;
      for (size_t t = 0; t < areas.size(); ++t) {
        areas[t] = float(triangle_area(*e.mesh, t));
        total += double(areas[t]);
      }
      e.area = float(total);
      const std::vector<float>* w = size_t(index) < triangle_weight.size() ? &triangle_weight[size_t(index)] : nullptr;
      if (w && !w->empty()) {
        if (w->size() != areas.size())
          throw_error("{}:{}: {} triangle weights for {} triangles", s.loc.file, s.loc.line, w->size(), areas.size());
        std::vector<float> f(areas.size());
        for (size_t t = 0; t < f.size(); ++t) f[t] = areas[t] * std::max((*w)[t], 0.0f);
        e.triangles = Distribution1D(f);
        // The exact density of what sample() does: the pmf it picks a
        // triangle with, spread uniformly over that triangle.
        e.triangle_pdf.resize(areas.size());
        for (size_t t = 0; t < areas.size(); ++t)
          e.triangle_pdf[t] = areas[t] > 0.0f ? e.triangles.discrete_pmf(int(t)) / areas[t] : 0.0f;
      } else {
        e.triangles = Distribution1D(areas);
      }
    } else {
      e.render_from_object = dmat4(s.render_from_object.m);
      e.object_from_render = glm::inverse(e.render_from_object);
      dmat3 lin(e.render_from_object);
      e.normal_matrix = glm::transpose(glm::inverse(lin));
      e.det = std::abs(glm::determinant(lin));
      if (s.kind == ShapeKind::Sphere) {
        e.sphere = make_sphere_shape(s.sphere);
        const SphereShape& sp = e.sphere;
        e.object_area = sp.phimax * sp.radius * (sp.zmax - sp.zmin);
        // A similarity keeps the sphere a sphere: closed-form area, cone sampling.
        double s2;
        if (is_similarity(lin, &s2)) {
          e.area = float(e.object_area * s2);
          e.cone = is_full_sphere(sp);
          e.center = vec3(dvec3(e.render_from_object[3]));
          e.render_radius = float(std::sqrt(s2) * sp.radius);
        } else {
          // Midpoint rule over the (z, phi) parameterisation, in which the
          // sphere's area element is uniform.
          constexpr int kZ = 512, kPhi = 512;
          double sum = 0.0;
          for (int iz = 0; iz < kZ; ++iz) {
            double z = sp.zmin + (sp.zmax - sp.zmin) * (iz + 0.5) / kZ;
            double rxy = std::sqrt(std::max(0.0, sp.radius * sp.radius - z * z));
            for (int ip = 0; ip < kPhi; ++ip) {
              double phi = sp.phimax * (ip + 0.5) / kPhi;
              sum += area_jacobian(e, dvec3(rxy * std::cos(phi), rxy * std::sin(phi), z) / sp.radius);
            }
          }
          e.area = float(e.object_area * sum / (double(kZ) * kPhi));
        }
      } else if (s.kind == ShapeKind::Cylinder) {
        e.cylinder = make_cylinder_shape(s.cylinder);
        const CylinderShape& cy = e.cylinder;
        e.object_area = cy.phimax * cy.radius * (cy.zmax - cy.zmin);
        // The area element scales with phi only (the normal does not depend on
        // z): the midpoint rule over phi, exact under a similarity.
        double s2;
        if (is_similarity(lin, &s2)) {
          e.area = float(e.object_area * s2);
        } else {
          constexpr int kPhi = 4096;
          double sum = 0.0;
          for (int ip = 0; ip < kPhi; ++ip) {
            double phi = cy.phimax * (ip + 0.5) / kPhi;
            sum += area_jacobian(e, dvec3(std::cos(phi), std::sin(phi), 0.0));
          }
          e.area = float(e.object_area * sum / kPhi);
        }
      } else {
        e.disk = make_disk_shape(s.disk);
        const DiskShape& dk = e.disk;
        e.object_area = 0.5 * dk.phimax * (dk.radius * dk.radius - dk.inner_radius * dk.inner_radius);
        e.area = float(e.object_area * area_jacobian(e, dvec3(0.0, 0.0, 1.0)));
      }
    }
    if (!(e.area > 0.0f))
      log_warning("{}:{}: emissive shape has zero area and will not emit", s.loc.file, s.loc.line);
    entry_of_shape_[size_t(index)] = int(entries_.size());
    entries_.push_back(std::move(e));
  }
}

float ShapeSampling::area(int shape) const {
  if (shape < 0 || size_t(shape) >= entry_of_shape_.size() || entry_of_shape_[size_t(shape)] < 0) return 0.0f;
  return entries_[size_t(entry_of_shape_[size_t(shape)])].area;
}

// Uniform on one triangle the caller chose.
static float given_triangle_pdf(const TriangleMesh& m, size_t t) {
  double a = triangle_area(m, t);
  return a > 0.0 ? float(1.0 / a) : 0.0f;
}

float ShapeSampling::area_pdf(const Entry& e, const vec3& p, int prim) const {
  if (!e.triangle_pdf.empty())
    return prim >= 0 && size_t(prim) < e.triangle_pdf.size() ? e.triangle_pdf[size_t(prim)] : 0.0f;
  if (e.kind == ShapeKind::Sphere) {
    dvec3 n = glm::normalize(dvec3(e.object_from_render * dvec4(dvec3(p), 1.0)));
    return float(1.0 / (e.object_area * area_jacobian(e, n)));
  }
  if (e.kind == ShapeKind::Cylinder) {
    dvec3 q = dvec3(e.object_from_render * dvec4(dvec3(p), 1.0));
    double rxy = std::sqrt(q.x * q.x + q.y * q.y);
    if (!(rxy > 0.0)) return 0.0f;
    return float(1.0 / (e.object_area * area_jacobian(e, dvec3(q.x / rxy, q.y / rxy, 0.0))));
  }
  return 1.0f / e.area;
}

std::optional<ShapeSample> ShapeSampling::sample(int shape, const ShapeSampleContext& ref, vec2 u, float u_prim,
                                                 int triangle, bool want_uv) const {
  if (shape < 0 || size_t(shape) >= entry_of_shape_.size() || entry_of_shape_[size_t(shape)] < 0) return std::nullopt;
  const Entry& e = entries_[size_t(entry_of_shape_[size_t(shape)])];
  if (!(e.area > 0.0f)) return std::nullopt;
  if (e.kind == ShapeKind::Sphere) {
    const SphereShape& sp = e.sphere;
    vec3 to_center = e.center - ref.p;
    float dc2 = glm::dot(to_center, to_center);
    if (e.cone && dc2 > sqr(e.render_radius)) {
      // pbrt-v4: uniform over the cone of directions the sphere subtends,
      // mapped straight to the visible surface point.
      float dc = std::sqrt(dc2);
      float sin_theta_max = e.render_radius / dc;
      float sin2_theta_max = sqr(sin_theta_max);
      float one_minus_cos_max = cone_one_minus_cos(sin2_theta_max);
      float cos_theta = 1.0f - u.x * one_minus_cos_max;
      float sin2_theta = 1.0f - sqr(cos_theta);
      if (sin2_theta_max < 0.00068523f) {
        sin2_theta = sin2_theta_max * u.x;
        cos_theta = std::sqrt(1.0f - sin2_theta);
      }
      float cos_alpha = sin2_theta / sin_theta_max + cos_theta * safe_sqrt(1.0f - sin2_theta / sin2_theta_max);
      float sin_alpha = safe_sqrt(1.0f - sqr(cos_alpha));
      const vec2 cs = cos_sin_turn(u.y);
      vec3 w(sin_alpha * cs.x, sin_alpha * cs.y, cos_alpha);
      Frame frame = Frame::from_z(to_center / dc);
      vec3 n_out = glm::normalize(frame.from_local(-w));
      ShapeSample ss;
      ss.p = e.center + e.render_radius * n_out;
      ss.p_error = gamma_bound(5) * glm::abs(ss.p);
      ss.n = e.flip ? -n_out : n_out;
      if (want_uv) {
        dvec3 p_obj = dvec3(e.object_from_render * dvec4(dvec3(ss.p), 1.0));
        double theta = std::acos(std::clamp(p_obj.z / sp.radius, -1.0, 1.0));
        ss.uv = sphere_uv(sp, phi_of(p_obj.x, p_obj.y), theta);  // what sphere_local gives, without its frame
      }
      ss.pdf = 1.0f / (2.0f * kPi * one_minus_cos_max);
      if (!std::isfinite(ss.pdf)) return std::nullopt;
      return ss;
    }
  }
  auto ss = sample_area(shape, u, u_prim, triangle);
  if (!ss) return std::nullopt;
  return to_solid_angle(*ss, ss->pdf, ref);
}

std::optional<ShapeSample> ShapeSampling::sample_area(int shape, vec2 u, float u_prim, int triangle) const {
  if (shape < 0 || size_t(shape) >= entry_of_shape_.size() || entry_of_shape_[size_t(shape)] < 0) return std::nullopt;
  const Entry& e = entries_[size_t(entry_of_shape_[size_t(shape)])];
  if (!(e.area > 0.0f)) return std::nullopt;

  if (e.kind == ShapeKind::TriangleMesh) {
    const TriangleMesh& m = *e.mesh;
    const bool given = triangle >= 0;
    if (given && size_t(triangle) >= m.triangle_count()) return std::nullopt;
    size_t t = given ? size_t(triangle) : size_t(e.triangles.sample_discrete(u_prim));
    vec2 b = sample_uniform_triangle(u);
    float b0 = b.x, b1 = b.y, b2 = 1.0f - b.x - b.y;
    const vec3 &p0 = m.p[m.indices[3 * t]], &p1 = m.p[m.indices[3 * t + 1]], &p2 = m.p[m.indices[3 * t + 2]];
    ShapeSample ss;
    ss.p = b0 * p0 + b1 * p1 + b2 * p2;
    ss.p_error = gamma_bound(6) * (glm::abs(b0 * p0) + glm::abs(b1 * p1) + glm::abs(b2 * p2));
    ss.n = triangle_normal(m, e.unit_normals[t], e.flip, t, b0, b1, b2, nullptr);
    vec2 uv[3];
    triangle_uvs(m, t, uv);
    ss.uv = b0 * uv[0] + b1 * uv[1] + b2 * uv[2];
    ss.prim = int(t);
    if (given) return with_pdf(ss, given_triangle_pdf(m, t));
    return with_pdf(ss, area_pdf(e, ss.p, ss.prim));
  }

  if (e.kind == ShapeKind::Sphere) {
    const SphereShape& sp = e.sphere;
    // Uniform in (z, phi) is uniform in area on the (partial) object-space sphere.
    double z = sp.zmin + double(u.x) * (sp.zmax - sp.zmin);
    double phi = double(u.y) * sp.phimax;
    double theta = std::acos(std::clamp(z / sp.radius, -1.0, 1.0));
    LocalGeom g = sphere_local(sp, phi, theta);
    ShapeSample ss = from_quadric(e, g);
    return with_pdf(ss, area_pdf(e, ss.p, -1));
  }

  if (e.kind == ShapeKind::Cylinder) {
    // pbrt-v4: uniform in (z, phi), which is uniform in object-space area.
    const CylinderShape& cy = e.cylinder;
    double z = cy.zmin + double(u.x) * (cy.zmax - cy.zmin);
    double phi = double(u.y) * cy.phimax;
    ShapeSample ss = from_quadric(e, cylinder_local(cy, phi, z));
    return with_pdf(ss, area_pdf(e, ss.p, -1));
  }

  const DiskShape& dk = e.disk;
  double x, y;
  if (dk.inner_radius == 0.0 && dk.phimax >= 2.0 * kPiD) {
    vec2 pd = sample_uniform_disk_concentric(u);
    x = double(pd.x) * dk.radius;
    y = double(pd.y) * dk.radius;
  } else {
    // Partial disks: uniform over the annulus sector, so that the area pdf stays exact.
    double ri2 = dk.inner_radius * dk.inner_radius;
    double r = std::sqrt(ri2 + double(u.x) * (dk.radius * dk.radius - ri2));
    double phi = double(u.y) * dk.phimax;
    x = r * std::cos(phi);
    y = r * std::sin(phi);
  }
  return with_pdf(from_quadric(e, disk_local(dk, x, y)), 1.0f / e.area);
}

float ShapeSampling::pdf(int shape, const ShapeSampleContext& ref, const vec3& wi,
                         const SurfaceInteraction& light_hit, bool given_triangle) const {
  if (shape < 0 || size_t(shape) >= entry_of_shape_.size() || entry_of_shape_[size_t(shape)] < 0) return 0.0f;
  const Entry& e = entries_[size_t(entry_of_shape_[size_t(shape)])];
  if (!(e.area > 0.0f)) return 0.0f;
  if (e.kind == ShapeKind::Sphere && e.cone) {
    vec3 to_center = e.center - ref.p;
    float dc2 = glm::dot(to_center, to_center);
    if (dc2 > sqr(e.render_radius)) {
      float one_minus_cos_max = cone_one_minus_cos(sqr(e.render_radius) / dc2);
      float pdf = 1.0f / (2.0f * kPi * one_minus_cos_max);
      return std::isfinite(pdf) ? pdf : 0.0f;
    }
  }
  // The conversion uses the direction to the light point exactly as sample()
  // computes it, so that both agree to the bit at grazing angles too; wi only
  // has to point that way.
  vec3 d = light_hit.p - ref.p;
  float d2 = glm::dot(d, d);
  if (d2 == 0.0f || glm::dot(wi, d) <= 0.0f) return 0.0f;
  float cos = std::abs(glm::dot(light_hit.ng, d / std::sqrt(d2)));
  if (cos == 0.0f) return 0.0f;
  const bool given = given_triangle && e.kind == ShapeKind::TriangleMesh;
  if (given && (light_hit.prim < 0 || size_t(light_hit.prim) >= e.mesh->triangle_count())) return 0.0f;
  float area_density = given ? given_triangle_pdf(*e.mesh, size_t(light_hit.prim))
                             : area_pdf(e, light_hit.p, light_hit.prim);
  float pdf = area_density * d2 / cos;
  return std::isfinite(pdf) ? pdf : 0.0f;
}

float pbrt_quadric_area(const Shape& s) {
  if (s.kind == ShapeKind::Sphere) {
    double r = s.sphere.radius;
    double zmin = std::clamp(double(std::min(s.sphere.zmin, s.sphere.zmax)), -r, r);
    double zmax = std::clamp(double(std::max(s.sphere.zmin, s.sphere.zmax)), -r, r);
    return float(radians(std::clamp(s.sphere.phimax, 0.0f, 360.0f)) * r * (zmax - zmin));
  }
  if (s.kind == ShapeKind::Cylinder) {
    double dz = std::abs(double(s.cylinder.zmax) - double(s.cylinder.zmin));
    return float(radians(std::clamp(s.cylinder.phimax, 0.0f, 360.0f)) * double(s.cylinder.radius) * dz);
  }
  return float(0.5 * radians(std::clamp(s.disk.phimax, 0.0f, 360.0f)) *
               (double(s.disk.radius) * s.disk.radius - double(s.disk.innerradius) * s.disk.innerradius));
}

}  // namespace theia
