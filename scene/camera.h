// pbrt-v4's perspective camera (thin lens) as plain precomputed data.
//
// Camera space is pbrt's: +z forward, +y up, raster x grows with camera +x.
// Raster space has (0, 0) at the top-left corner of the image and y pointing
// down; pixel (x, y) covers [x, x + 1) x [y, y + 1).
#pragma once

#include "core/math.h"
#include "scene/accel.h"
#include "scene/scene.h"
#include "scene/shapes.h"
#include "scene/texture.h"

#include <algorithm>
#include <cmath>

namespace theia {

struct Camera {
  Transform render_from_camera;
  vec2 resolution{0.0f};
  // Raster point (x, y) maps to the camera-space point p00 + x * dx + y * dy
  // on the z = 1 plane (pbrt-v4's cameraFromRaster, with the projection folded in).
  vec3 p00{0.0f}, dx{0.0f}, dy{0.0f};
  float screen_window[4] = {0, 0, 0, 0};  // xmin xmax ymin ymax actually used
  float lens_radius = 0.0f;
  float focal_distance = 1e6f;
  // pbrt-v4's FindMinimumDifferentials: the smallest change of the unit ray
  // direction from one pixel to the next (x and y), over the image diagonal,
  // in the ray's own Frame::from_z.  Rays through the lens centre share one
  // origin, so the position differentials pbrt-v4 also keeps are zero here.
  vec3 min_dir_dx{0.0f}, min_dir_dy{0.0f};
};

// Throws Error for an impossible resolution, fov, lens or screen window.
Camera make_camera(const CameraParams& camera, const FilmParams& film);

// The ray through continuous raster point p_film, in render space, with a unit
// direction and [0, inf) extent.  u_lens picks the point on the lens (ignored
// for a pinhole).
Ray generate_camera_ray(const Camera& camera, vec2 p_film, vec2 u_lens);

// pbrt-v4's sppScale: footprints shrink with more samples per pixel, which
// average over the pixel anyway.
inline float footprint_spp_scale(int spp) { return std::max(0.125f, 1.0f / std::sqrt(float(std::max(spp, 1)))); }

// pbrt-v4's Camera::Approximate_dp_dxy: dp/dx and dp/dy at p (surface normal
// n) as if the camera's minimum differential rays, turned to pass through p,
// met the tangent plane there; scaled by spp_scale.  Used at every depth, as
// pbrt-v4's wavefront integrator does, since no ray carries differentials.
void approximate_dp_dxy(const Camera& camera, const vec3& p, const vec3& n, float spp_scale, vec3& dpdx, vec3& dpdy);

// The (u, v) derivatives from those: least squares of dp = dpdu du + dpdv dv
// (pbrt-v4's SurfaceInteraction::ComputeDifferentials); 0 where degenerate.
UVFootprint texture_footprint(const Camera& camera, const SurfaceInteraction& si, float spp_scale);

}  // namespace theia
