// pbrt-v4's "curve" shape: its parameters read into a CurveSet (scene.h), and
// the cubic Bezier algebra both the parser and the hit code need.
//
// Every segment is stored as a cubic Bezier, as pbrt-v4's CreateCurves makes
// it: degree 2 is elevated exactly, uniform b-splines are converted to their
// Bezier control points.  Embree then traces one curve type for all of them.
#pragma once

#include "core/math.h"
#include "scene/params.h"
#include "scene/scene.h"

#include <array>

namespace theia {

using CubicBezier = std::array<vec3, 4>;

CubicBezier elevate_quadratic_bezier(const vec3& q0, const vec3& q1, const vec3& q2);
// Uniform (cardinal) b-spline segments to the Bezier control points of the same curve.
CubicBezier cubic_bspline_to_bezier(const vec3& b0, const vec3& b1, const vec3& b2, const vec3& b3);
std::array<vec3, 3> quadratic_bspline_to_bezier(const vec3& b0, const vec3& b1, const vec3& b2);

vec3 bezier_point(const CubicBezier& cp, float u);
vec3 bezier_derivative(const CubicBezier& cp, float u);

// Segment k of a CurveSet: its control points (positions only) and radii.
CubicBezier curve_segment(const CurveSet& c, size_t k);
float curve_radius(const CurveSet& c, size_t k, float u);

// "point3 P", "string basis" (bezier | bspline), "integer degree" (2 | 3),
// "string type" (flat | cylinder | ribbon), "float width" / "width0" /
// "width1" (full width, linear along the whole shape), "normal N" (ribbon:
// one per segment end) and "integer splitdepth" (read, unused: Embree refines
// itself).  Positions and normals are baked with `ctm`; widths scale by the
// cube root of its determinant (exact for similarities).  Malformed input
// throws file:line:col errors.
CurveSet curves_from_params(const ParamList& params, const SourceLoc& loc, const Transform& ctm);

}  // namespace theia
