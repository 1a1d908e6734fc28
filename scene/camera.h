// pbrt-v4's perspective and orthographic cameras (thin lens) and its
// spherical camera, as plain precomputed data.
//
// Camera space is pbrt's: +z forward, +y up, raster x grows with camera +x.
// Raster space has (0, 0) at the top-left corner of the image and y pointing
// down; pixel (x, y) covers [x, x + 1) x [y, y + 1).  The spherical camera
// maps raster / resolution to a direction (equal-area square or
// equirectangular) with pbrt-v4's swap of y and z: camera +y is the pole.
#pragma once

#include "core/math.h"
#include "scene/accel.h"
#include "scene/scene.h"
#include "scene/shapes.h"
#include "scene/texture.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <span>

namespace theia {

struct Camera {
  CameraKind kind = CameraKind::Perspective;
  SphericalMapping mapping = SphericalMapping::EqualArea;
  Transform render_from_camera;
  vec2 resolution{0.0f};
  // Perspective and orthographic: raster point (x, y) maps to the
  // camera-space point p00 + x * dx + y * dy (pbrt-v4's cameraFromRaster, with
  // the projection folded in), on the z = 1 plane for perspective, on z = 0
  // for orthographic, whose rays leave it along +z.
  vec3 p00{0.0f}, dx{0.0f}, dy{0.0f};
  float screen_window[4] = {0, 0, 0, 0};  // xmin xmax ymin ymax actually used
  float lens_radius = 0.0f;
  float focal_distance = 1e6f;
  // Perspective: pbrt-v4's FindMinimumDifferentials, the smallest change of
  // the unit ray direction from one pixel to the next (x and y), over the
  // image diagonal, in the ray's own Frame::from_z.  Rays through the lens
  // centre share one origin, so the position differentials pbrt-v4 also keeps
  // are zero here.  Orthographic: the position differentials are dx and dy
  // and the direction ones zero (as pbrt-v4).  Spherical: differentials are
  // taken at each point instead (see approximate_dp_dxy).
  vec3 min_dir_dx{0.0f}, min_dir_dy{0.0f};
};

// Throws Error for an impossible resolution, fov, lens or screen window (the
// spherical camera uses none of the last three).
Camera make_camera(const CameraParams& camera, const FilmParams& film);

// The ray through continuous raster point p_film, in render space, with a unit
// direction and [0, inf) extent.  u_lens picks the point on the lens (ignored
// for a pinhole and the spherical camera).  p_film may lie a filter radius
// outside the image.
Ray generate_camera_ray(const Camera& camera, vec2 p_film, vec2 u_lens);
// out[i] = generate_camera_ray(camera, p_film[i], u_lens[i]) for every i, bit
// for bit; a pinhole perspective camera's (which reads no u_lens: it may be
// empty) several rays at a time in vector lanes.
void generate_camera_rays(const Camera& camera, std::span<const vec2> p_film, std::span<const vec2> u_lens,
                          std::span<Ray> out);

// The camera seen from a render-space point (pbrt-v4's Camera::SampleWi), for
// light paths that end on it.  Pinhole perspective cameras with a rigid
// render_from_camera only (camera_supports_wi).  raster: where the point
// lands (may lie outside the image); wi: unit direction from p to the
// pinhole; importance: pbrt-v4's We / pdf = 1 / (A cos^3 theta d^2), A the
// film's area on the z = 1 plane, so that radiance L leaving p along wi
// contributes L * importance per unit raster area (pbrt-v4's splat scale).
struct CameraWiSample {
  vec2 raster{0.0f};
  vec3 p_lens{0.0f};
  vec3 wi{0.0f};
  float distance = 0.0f;
  float importance = 0.0f;
};
bool camera_supports_wi(const Camera& camera);
std::optional<CameraWiSample> camera_wi(const Camera& camera, const vec3& p);

// Spherical camera: the camera-space unit direction of raster point p_film,
// and back (the raster point of a camera-space direction, within the image).
vec3 spherical_camera_direction(const Camera& camera, vec2 p_film);
vec2 spherical_camera_raster(const Camera& camera, const vec3& dir);

// pbrt-v4's sppScale: footprints shrink with more samples per pixel, which
// average over the pixel anyway.
inline float footprint_spp_scale(int spp) { return std::max(0.125f, 1.0f / std::sqrt(float(std::max(spp, 1)))); }

// pbrt-v4's Camera::Approximate_dp_dxy: dp/dx and dp/dy at p (surface normal
// n) as if the camera's minimum differential rays, turned to pass through p,
// met the tangent plane there; scaled by spp_scale.  Used at every depth, as
// pbrt-v4's wavefront integrator does, since no ray carries differentials.
// Orthographic: the rays one pixel over stay parallel to +z, so a plane's
// footprint is the same at every pixel (pbrt-v4 turns them towards p as if
// they left the camera origin).  Spherical: the differentials of the pixel
// that sees p, so the footprint is that pixel's solid angle at p's distance
// (pbrt-v4's minimum over the diagonal is ~0 at an equirectangular pole).
void approximate_dp_dxy(const Camera& camera, const vec3& p, const vec3& n, float spp_scale, vec3& dpdx, vec3& dpdy);

// The (u, v) derivatives from those: least squares of dp = dpdu du + dpdv dv
// (pbrt-v4's SurfaceInteraction::ComputeDifferentials); 0 where degenerate.
UVFootprint texture_footprint(const Camera& camera, const SurfaceInteraction& si, float spp_scale);

}  // namespace theia
