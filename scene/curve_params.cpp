#include "scene/curve_params.h"

#include "scene/tokenizer.h"

#include <cmath>

namespace theia {

CubicBezier elevate_quadratic_bezier(const vec3& q0, const vec3& q1, const vec3& q2) {
  return {q0, q0 + (2.0f / 3.0f) * (q1 - q0), q2 + (2.0f / 3.0f) * (q1 - q2), q2};
}

CubicBezier cubic_bspline_to_bezier(const vec3& b0, const vec3& b1, const vec3& b2, const vec3& b3) {
  return {(b0 + 4.0f * b1 + b2) / 6.0f, (2.0f * b1 + b2) / 3.0f, (b1 + 2.0f * b2) / 3.0f, (b1 + 4.0f * b2 + b3) / 6.0f};
}

std::array<vec3, 3> quadratic_bspline_to_bezier(const vec3& b0, const vec3& b1, const vec3& b2) {
  return {0.5f * (b0 + b1), b1, 0.5f * (b1 + b2)};
}

vec3 bezier_point(const CubicBezier& cp, float u) {
  float s = 1.0f - u;
  return (s * s * s) * cp[0] + (3.0f * s * s * u) * cp[1] + (3.0f * s * u * u) * cp[2] + (u * u * u) * cp[3];
}

vec3 bezier_derivative(const CubicBezier& cp, float u) {
  float s = 1.0f - u;
  return 3.0f * ((s * s) * (cp[1] - cp[0]) + (2.0f * s * u) * (cp[2] - cp[1]) + (u * u) * (cp[3] - cp[2]));
}

CubicBezier curve_segment(const CurveSet& c, size_t k) {
  return {vec3(c.cp[4 * k]), vec3(c.cp[4 * k + 1]), vec3(c.cp[4 * k + 2]), vec3(c.cp[4 * k + 3])};
}

float curve_radius(const CurveSet& c, size_t k, float u) {
  float s = 1.0f - u;
  return (s * s * s) * c.cp[4 * k].w + (3.0f * s * s * u) * c.cp[4 * k + 1].w + (3.0f * s * u * u) * c.cp[4 * k + 2].w +
         (u * u * u) * c.cp[4 * k + 3].w;
}

namespace {

std::vector<vec3> read_vec3s(const Param* p) {
  std::vector<vec3> v;
  if (!p) return v;
  for (size_t i = 0; i + 2 < p->numbers.size(); i += 3)
    v.emplace_back(float(p->numbers[i]), float(p->numbers[i + 1]), float(p->numbers[i + 2]));
  return v;
}

float nonnegative_width(const ParamList& params, std::string_view name, float def) {
  const Param* p = params.find(name, ParamType::Float);
  if (!p || p->numbers.empty()) return def;
  float w = float(p->numbers[0]);
  if (!(w >= 0.0f)) throw_at(p->loc, "curve \"float {}\" is {}, expected a width >= 0", name, w);
  return w;
}

}  // namespace

CurveSet curves_from_params(const ParamList& params, const SourceLoc& loc, const Transform& ctm) {
  float width = nonnegative_width(params, "width", 1.0f);
  float width0 = nonnegative_width(params, "width0", width);
  float width1 = nonnegative_width(params, "width1", width);

  int degree = params.get_int("degree", 3);
  if (degree != 2 && degree != 3) throw_at(loc, "curve \"integer degree\" {}, expected 2 or 3", degree);
  std::string basis = params.get_string("basis", "bezier");
  if (basis != "bezier" && basis != "bspline")
    throw_at(loc, "curve \"string basis\" \"{}\", expected \"bezier\" or \"bspline\"", basis);
  std::string type = params.get_string("type", "flat");
  CurveSet c;
  if (type == "flat") c.type = CurveType::Flat;
  else if (type == "cylinder") c.type = CurveType::Cylinder;
  else if (type == "ribbon") c.type = CurveType::Ribbon;
  else throw_at(loc, "curve \"string type\" \"{}\", expected \"flat\", \"cylinder\" or \"ribbon\"", type);
  params.get_int("splitdepth", 3);  // pbrt-v4's refinement depth: Embree refines on its own

  const Param* P = params.find("P", ParamType::Point3);
  if (!P) throw_at(loc, "curve without \"point3 P\", expected control points");
  std::vector<vec3> cp = read_vec3s(P);
  const size_t d = size_t(degree);
  size_t segments = 0;
  if (basis == "bezier") {
    // Segments share their end points: degree + 1 points, then degree more per segment.
    if (cp.size() < d + 1 || (cp.size() - 1) % d != 0)
      throw_at(P->loc, "curve with {} control points, expected {} + n * {} for a degree {} bezier", cp.size(), d + 1, d,
               degree);
    segments = (cp.size() - 1) / d;
  } else {
    if (cp.size() < d + 1)
      throw_at(P->loc, "curve with {} control points, expected at least {} for a degree {} bspline", cp.size(), d + 1,
               degree);
    segments = cp.size() - d;
  }

  const Param* N = params.find("N", ParamType::Normal3);
  std::vector<vec3> n = read_vec3s(N);
  if (c.type == CurveType::Ribbon) {
    if (!N) throw_at(loc, "ribbon curve without \"normal N\", expected {} normals (one per segment end)", segments + 1);
    if (n.size() != segments + 1)
      throw_at(N->loc, "ribbon curve with {} normals, expected {} (one per segment end of {} segments)", n.size(),
               segments + 1, segments);
    for (const vec3& v : n)
      if (!(glm::dot(v, v) > 0.0f)) throw_at(N->loc, "ribbon curve with a zero normal, expected non-zero normals");
  } else if (N) {
    warn_at(N->loc, "curve normals are only used by \"ribbon\" curves; {} ignored", N->label());
  }

  // A width is a length: under the CTM it scales as lengths do on average.
  float width_scale = std::cbrt(std::abs(glm::determinant(mat3(ctm.m))));
  for (size_t seg = 0; seg < segments; ++seg) {
    CubicBezier b;
    if (basis == "bezier") {
      const vec3* q = &cp[seg * d];
      b = degree == 2 ? elevate_quadratic_bezier(q[0], q[1], q[2]) : CubicBezier{q[0], q[1], q[2], q[3]};
    } else if (degree == 2) {
      auto q = quadratic_bspline_to_bezier(cp[seg], cp[seg + 1], cp[seg + 2]);
      b = elevate_quadratic_bezier(q[0], q[1], q[2]);
    } else {
      b = cubic_bspline_to_bezier(cp[seg], cp[seg + 1], cp[seg + 2], cp[seg + 3]);
    }
    // pbrt-v4: the segment's end widths lerp width0 -> width1 over the shape,
    // linear within the segment; linear values have evenly spaced Bezier coefficients.
    float w0 = glm::mix(width0, width1, float(seg) / float(segments));
    float w1 = glm::mix(width0, width1, float(seg + 1) / float(segments));
    for (int i = 0; i < 4; ++i) {
      float r = 0.5f * width_scale * glm::mix(w0, w1, float(i) / 3.0f);
      c.cp.emplace_back(ctm.point(b[size_t(i)]), r);
    }
    if (c.type == CurveType::Ribbon) {
      vec3 n0 = glm::normalize(ctm.normal(n[seg])), n1 = glm::normalize(ctm.normal(n[seg + 1]));
      for (int i = 0; i < 4; ++i) c.n.push_back(glm::mix(n0, n1, float(i) / 3.0f));
    }
  }
  return c;
}

}  // namespace theia
