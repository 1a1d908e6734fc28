// pbrt-v4's perspective camera (thin lens) as plain precomputed data.
//
// Camera space is pbrt's: +z forward, +y up, raster x grows with camera +x.
// Raster space has (0, 0) at the top-left corner of the image and y pointing
// down; pixel (x, y) covers [x, x + 1) x [y, y + 1).
#pragma once

#include "core/math.h"
#include "scene/accel.h"
#include "scene/scene.h"

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
};

// Throws Error for an impossible resolution, fov, lens or screen window.
Camera make_camera(const CameraParams& camera, const FilmParams& film);

// The ray through continuous raster point p_film, in render space, with a unit
// direction and [0, inf) extent.  u_lens picks the point on the lens (ignored
// for a pinhole).
Ray generate_camera_ray(const Camera& camera, vec2 p_film, vec2 u_lens);

}  // namespace theia
