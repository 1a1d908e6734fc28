#include "scene/camera.h"

#include "core/log.h"
#include "core/sampling.h"

namespace theia {

Camera make_camera(const CameraParams& params, const FilmParams& film) {
  if (film.width <= 0 || film.height <= 0)
    throw_error("film: resolution must be positive, got {}x{}", film.width, film.height);
  if (!(params.fov > 0.0f && params.fov < 180.0f))
    throw_error("perspective camera: \"fov\" must be in (0, 180) degrees, got {}", params.fov);
  if (!(params.lens_radius >= 0.0f && std::isfinite(params.lens_radius)))
    throw_error("perspective camera: \"lensradius\" must be non-negative, got {}", params.lens_radius);
  if (params.lens_radius > 0.0f && !(params.focal_distance > 0.0f && std::isfinite(params.focal_distance)))
    throw_error("perspective camera: \"focaldistance\" must be positive, got {}", params.focal_distance);

  Camera c;
  c.render_from_camera = params.render_from_camera;
  c.resolution = vec2(float(film.width), float(film.height));
  c.lens_radius = params.lens_radius;
  c.focal_distance = params.focal_distance;

  float* sw = c.screen_window;
  if (params.has_screen_window) {
    for (int i = 0; i < 4; ++i) sw[i] = params.screen_window[i];
    if (!(sw[0] < sw[1] && sw[2] < sw[3]))
      throw_error("perspective camera: \"screenwindow\" needs xmin < xmax and ymin < ymax, got [{} {} {} {}]",
                  sw[0], sw[1], sw[2], sw[3]);
  } else {
    // pbrt-v4: the shorter image axis spans [-1, 1], so fov applies to it.
    float aspect = c.resolution.x / c.resolution.y;
    if (aspect > 1.0f) {
      sw[0] = -aspect, sw[1] = aspect, sw[2] = -1.0f, sw[3] = 1.0f;
    } else {
      sw[0] = -1.0f, sw[1] = 1.0f, sw[2] = -1.0f / aspect, sw[3] = 1.0f / aspect;
    }
  }

  // Screen (sx, sy) is camera (x, y) / (z * tan(fov / 2)); raster y runs from
  // the window's top (ymax) downwards.
  float t = std::tan(radians(params.fov) * 0.5f);
  c.p00 = vec3(sw[0] * t, sw[3] * t, 1.0f);
  c.dx = vec3((sw[1] - sw[0]) * t / c.resolution.x, 0.0f, 0.0f);
  c.dy = vec3(0.0f, -(sw[3] - sw[2]) * t / c.resolution.y, 0.0f);
  return c;
}

Ray generate_camera_ray(const Camera& c, vec2 p_film, vec2 u_lens) {
  vec3 p_camera = c.p00 + p_film.x * c.dx + p_film.y * c.dy;  // on z = 1
  vec3 o(0.0f), d = p_camera;
  if (c.lens_radius > 0.0f) {
    // Every ray through this film point meets the pinhole ray on the plane of focus.
    vec3 p_focus = p_camera * c.focal_distance;
    vec2 p_lens = c.lens_radius * sample_uniform_disk_concentric(u_lens);
    o = vec3(p_lens, 0.0f);
    d = p_focus - o;
  }
  Ray ray;
  ray.o = c.render_from_camera.point(o);
  ray.d = glm::normalize(c.render_from_camera.vector(d));
  return ray;
}

}  // namespace theia
