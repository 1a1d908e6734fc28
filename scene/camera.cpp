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

  // Along the diagonal, as pbrt-v4 searches: off-axis pixels subtend less angle.
  constexpr int kSteps = 512;
  float best_x = INFINITY, best_y = INFINITY;
  for (int i = 0; i < kSteps; ++i) {
    vec2 pf = float(i) / float(kSteps - 1) * c.resolution;
    vec3 p = c.p00 + pf.x * c.dx + pf.y * c.dy;
    Frame f = Frame::from_z(glm::normalize(p));
    vec3 dxf = glm::normalize(f.to_local(p + c.dx)) - vec3(0, 0, 1);
    vec3 dyf = glm::normalize(f.to_local(p + c.dy)) - vec3(0, 0, 1);
    if (glm::length(dxf) < best_x) best_x = glm::length(dxf), c.min_dir_dx = dxf;
    if (glm::length(dyf) < best_y) best_y = glm::length(dyf), c.min_dir_dy = dyf;
  }
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

namespace theia {

void approximate_dp_dxy(const Camera& c, const vec3& p, const vec3& n, float spp_scale, vec3& dpdx, vec3& dpdy) {
  dpdx = dpdy = vec3(0.0f);
  const Transform camera_from_render = c.render_from_camera.inverse();
  vec3 pc = camera_from_render.point(p);
  float z = glm::length(pc);
  if (!(z > 0.0f) || !std::isfinite(z)) return;
  // Turn the camera so p lies on +z; the differential rays leave the origin
  // along +z + min_dir_d* and meet the plane through p with normal n.
  Frame f = Frame::from_z(pc / z);
  vec3 nd = f.to_local(camera_from_render.normal(n));
  float d = nd.z * z;
  auto offset = [&](const vec3& dir_delta) {
    vec3 dir = vec3(0, 0, 1) + dir_delta;
    float denom = glm::dot(nd, dir);
    float t = d / denom;
    if (!std::isfinite(t) || denom == 0.0f) return vec3(0.0f);  // grazing: no usable footprint
    vec3 v = c.render_from_camera.vector(f.from_local(t * dir - vec3(0, 0, z)));
    return std::isfinite(v.x + v.y + v.z) ? spp_scale * v : vec3(0.0f);
  };
  dpdx = offset(c.min_dir_dx);
  dpdy = offset(c.min_dir_dy);
}

UVFootprint texture_footprint(const Camera& c, const SurfaceInteraction& si, float spp_scale) {
  vec3 dpdx, dpdy;
  approximate_dp_dxy(c, si.p, si.ng, spp_scale, dpdx, dpdy);
  // Normal equations of the 3x2 system [dpdu dpdv] (du, dv) = dp.
  float a00 = glm::dot(si.dpdu, si.dpdu), a01 = glm::dot(si.dpdu, si.dpdv), a11 = glm::dot(si.dpdv, si.dpdv);
  float inv_det = 1.0f / (a00 * a11 - a01 * a01);
  if (!std::isfinite(inv_det)) inv_det = 0.0f;
  float b0x = glm::dot(si.dpdu, dpdx), b1x = glm::dot(si.dpdv, dpdx);
  float b0y = glm::dot(si.dpdu, dpdy), b1y = glm::dot(si.dpdv, dpdy);
  auto sane = [](float v) { return std::isfinite(v) ? std::clamp(v, -1e8f, 1e8f) : 0.0f; };
  UVFootprint fp;
  fp.dudx = sane((a11 * b0x - a01 * b1x) * inv_det);
  fp.dvdx = sane((a00 * b1x - a01 * b0x) * inv_det);
  fp.dudy = sane((a11 * b0y - a01 * b1y) * inv_det);
  fp.dvdy = sane((a00 * b1y - a01 * b0y) * inv_det);
  return fp;
}

}  // namespace theia
