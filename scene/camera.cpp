#include "scene/camera.h"

#include "core/log.h"
#include "core/sampling.h"

#include <array>

namespace theia {

namespace {

const char* kind_name(CameraKind k) {
  return k == CameraKind::Perspective ? "perspective" : k == CameraKind::Orthographic ? "orthographic" : "spherical";
}

// pbrt-v4's WrapEqualAreaSquare: a point just off the square (a filter
// offset past the image edge) continues on the sphere across that edge.
vec2 wrap_equal_area_square(vec2 uv) {
  if (uv.x < 0.0f) {
    uv = vec2(-uv.x, 1.0f - uv.y);
  } else if (uv.x > 1.0f) {
    uv = vec2(2.0f - uv.x, 1.0f - uv.y);
  }
  if (uv.y < 0.0f) {
    uv = vec2(1.0f - uv.x, -uv.y);
  } else if (uv.y > 1.0f) {
    uv = vec2(1.0f - uv.x, 2.0f - uv.y);
  }
  return uv;
}

// The screen window and the raster -> camera map of the two projective cameras.
void setup_projective(Camera& c, const CameraParams& params) {
  float* sw = c.screen_window;
  if (params.has_screen_window) {
    for (int i = 0; i < 4; ++i) sw[i] = params.screen_window[i];
    if (!(sw[0] < sw[1] && sw[2] < sw[3]))
      throw_error("{} camera: \"screenwindow\" needs xmin < xmax and ymin < ymax, got [{} {} {} {}]",
                  kind_name(c.kind), sw[0], sw[1], sw[2], sw[3]);
  } else {
    // pbrt-v4: the shorter image axis spans [-1, 1], so fov applies to it.
    float aspect = c.resolution.x / c.resolution.y;
    if (aspect > 1.0f) {
      sw[0] = -aspect, sw[1] = aspect, sw[2] = -1.0f, sw[3] = 1.0f;
    } else {
      sw[0] = -1.0f, sw[1] = 1.0f, sw[2] = -1.0f / aspect, sw[3] = 1.0f / aspect;
    }
  }
  // Screen (sx, sy) is camera (x, y) / (z * tan(fov / 2)) for perspective and
  // camera (x, y) itself for orthographic (pbrt-v4's Orthographic(0, 1));
  // raster y runs from the window's top (ymax) downwards.
  float t = c.kind == CameraKind::Perspective ? std::tan(radians(params.fov) * 0.5f) : 1.0f;
  float z = c.kind == CameraKind::Perspective ? 1.0f : 0.0f;
  c.p00 = vec3(sw[0] * t, sw[3] * t, z);
  c.dx = vec3((sw[1] - sw[0]) * t / c.resolution.x, 0.0f, 0.0f);
  c.dy = vec3(0.0f, -(sw[3] - sw[2]) * t / c.resolution.y, 0.0f);
}

void find_minimum_differentials(Camera& c) {
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
}

}  // namespace

Camera make_camera(const CameraParams& params, const FilmParams& film) {
  if (film.width <= 0 || film.height <= 0)
    throw_error("film: resolution must be positive, got {}x{}", film.width, film.height);
  Camera c;
  c.kind = params.kind;
  c.mapping = params.mapping;
  c.render_from_camera = params.render_from_camera;
  c.resolution = vec2(float(film.width), float(film.height));
  if (c.kind == CameraKind::Spherical) return c;

  const char* name = kind_name(c.kind);
  if (c.kind == CameraKind::Perspective && !(params.fov > 0.0f && params.fov < 180.0f))
    throw_error("perspective camera: \"fov\" must be in (0, 180) degrees, got {}", params.fov);
  if (!(params.lens_radius >= 0.0f && std::isfinite(params.lens_radius)))
    throw_error("{} camera: \"lensradius\" must be non-negative, got {}", name, params.lens_radius);
  if (params.lens_radius > 0.0f && !(params.focal_distance > 0.0f && std::isfinite(params.focal_distance)))
    throw_error("{} camera: \"focaldistance\" must be positive, got {}", name, params.focal_distance);
  c.lens_radius = params.lens_radius;
  c.focal_distance = params.focal_distance;
  setup_projective(c, params);
  if (c.kind == CameraKind::Perspective) find_minimum_differentials(c);
  return c;
}

vec3 spherical_camera_direction(const Camera& c, vec2 p_film) {
  vec2 uv = p_film / c.resolution;
  vec3 d = c.mapping == SphericalMapping::Equirectangular ? equirect_to_sphere(uv)
                                                          : equal_area_square_to_sphere(wrap_equal_area_square(uv));
  return {d.x, d.z, d.y};
}

vec2 spherical_camera_raster(const Camera& c, const vec3& dir) {
  vec3 d(dir.x, dir.z, dir.y);
  vec2 uv = c.mapping == SphericalMapping::Equirectangular ? sphere_to_equirect(d) : equal_area_sphere_to_square(d);
  return uv * c.resolution;
}

bool camera_supports_wi(const Camera& c) {
  if (c.kind != CameraKind::Perspective || c.lens_radius > 0.0f) return false;
  mat3 m(c.render_from_camera.m);
  mat3 g = glm::transpose(m) * m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (std::abs(g[i][j] - (i == j ? 1.0f : 0.0f)) > 1e-4f) return false;
  return true;
}

std::optional<CameraWiSample> camera_wi(const Camera& c, const vec3& p) {
  vec3 p_camera = c.render_from_camera.inverse().point(p);
  float d2 = glm::dot(p_camera, p_camera);
  if (!(p_camera.z > 0.0f) || !(d2 > 0.0f) || !std::isfinite(d2)) return std::nullopt;
  float d = std::sqrt(d2);
  float cos_theta = p_camera.z / d;
  vec3 q = p_camera / p_camera.z;  // on the z = 1 plane, where cameraFromRaster puts the film
  CameraWiSample s;
  s.raster = vec2((q.x - c.p00.x) / c.dx.x, (q.y - c.p00.y) / c.dy.y);
  s.p_lens = c.render_from_camera.point(vec3(0.0f));
  s.wi = (s.p_lens - p) / d;
  s.distance = d;
  float film_area = std::abs(c.dx.x * c.resolution.x * c.dy.y * c.resolution.y);
  s.importance = 1.0f / (film_area * cos_theta * cos_theta * cos_theta * d2);
  if (!std::isfinite(s.importance) || !std::isfinite(s.raster.x) || !std::isfinite(s.raster.y)) return std::nullopt;
  return s;
}

namespace {

// Both forms of the camera ray (generate_camera_ray and its span form)
// compute these two, so that they give the same bits.  Every multiply-add
// is written out (mul_add): left to the compiler, the one-ray and the
// vector form fused different pairs (a third of a turned camera's rays
// differed).  The pairs fused are the ones GCC chose for the one-ray code
// before, so that images stay the same bit for bit.
[[gnu::always_inline]] inline vec3 camera_plane_point(const Camera& c, vec2 p) {
  auto axis = [&](int i) { return mul_add(p.y, c.dy[i], mul_add(p.x, c.dx[i], c.p00[i])); };
  return {axis(0), axis(1), axis(2)};
}
[[gnu::always_inline]] inline vec3 render_direction(const Camera& c, const vec3& d) {
  const mat4& m = c.render_from_camera.m;
  const float x = mul_add(m[2][0], d.z, mul_add(m[1][0], d.y, m[0][0] * d.x));
  const float y = mul_add(m[2][1], d.z, mul_add(m[1][1], d.y, m[0][1] * d.x));
  const float z = mul_add(m[2][2], d.z, mul_add(m[0][2], d.x, m[1][2] * d.y));
  const float inv_length = 1.0f / std::sqrt(mul_add(z, z, mul_add(y, y, x * x)));
  return {x * inv_length, y * inv_length, z * inv_length};
}

}  // namespace

Ray generate_camera_ray(const Camera& c, vec2 p_film, vec2 u_lens) {
  vec3 o(0.0f), d;
  if (c.kind == CameraKind::Spherical) {
    d = spherical_camera_direction(c, p_film);
  } else {
    vec3 p_camera = camera_plane_point(c, p_film);
    bool ortho = c.kind == CameraKind::Orthographic;
    o = ortho ? p_camera : vec3(0.0f);
    d = ortho ? vec3(0, 0, 1) : p_camera;  // perspective: p_camera is on z = 1
    if (c.lens_radius > 0.0f) {
      // Every ray through this film point meets the pinhole ray on the plane
      // of focus.  As pbrt-v4, the orthographic lens is centred on the camera
      // origin, not on the film point.
      vec3 p_focus = o + d * c.focal_distance;
      o = vec3(c.lens_radius * sample_uniform_disk_concentric(u_lens), 0.0f);
      d = p_focus - o;
    }
  }
  Ray ray;
  ray.o = c.render_from_camera.point(o);
  ray.d = render_direction(c, d);
  return ray;
}

void generate_camera_rays(const Camera& c, std::span<const vec2> p_film, std::span<const vec2> u_lens,
                          std::span<Ray> out) {
  if (c.kind != CameraKind::Perspective || c.lens_radius > 0.0f) {
    for (size_t i = 0; i < p_film.size(); ++i) out[i] = generate_camera_ray(c, p_film[i], u_lens[i]);
    return;
  }
  // A pinhole: one origin, and directions through the z = 1 plane.  The
  // directions are computed a block at a time, in structure-of-arrays form
  // so that the loop vectorizes.
  const vec3 o = c.render_from_camera.point(vec3(0.0f));
  constexpr size_t kBlock = 64;
  for (size_t first = 0; first < p_film.size(); first += kBlock) {
    const size_t m = std::min(kBlock, p_film.size() - first);
    std::array<float, kBlock> dx, dy, dz;
    for (size_t i = 0; i < m; ++i) {
      const vec3 d = render_direction(c, camera_plane_point(c, p_film[first + i]));
      dx[i] = d.x, dy[i] = d.y, dz[i] = d.z;
    }
    for (size_t i = 0; i < m; ++i) {
      Ray& ray = out[first + i];
      ray = Ray{};
      ray.o = o;
      ray.d = vec3(dx[i], dy[i], dz[i]);
    }
  }
}

}  // namespace theia

namespace theia {

namespace {

// Where the line o + t d meets the plane through p with normal n, minus p;
// zero when it runs (nearly) parallel to the plane.
vec3 offset_on_plane(const vec3& o, const vec3& d, const vec3& p, const vec3& n) {
  float denom = glm::dot(n, d);
  float t = glm::dot(n, p - o) / denom;
  if (denom == 0.0f || !std::isfinite(t)) return vec3(0.0f);
  vec3 v = o + t * d - p;
  return std::isfinite(v.x + v.y + v.z) ? v : vec3(0.0f);
}

}  // namespace

void approximate_dp_dxy(const Camera& c, const vec3& p, const vec3& n, float spp_scale, vec3& dpdx, vec3& dpdy) {
  dpdx = dpdy = vec3(0.0f);
  const Transform camera_from_render = c.render_from_camera.inverse();
  vec3 pc = camera_from_render.point(p), nc = camera_from_render.normal(n);
  vec3 ox(0.0f), oy(0.0f), dx, dy;  // the two differential rays, in camera space
  if (c.kind == CameraKind::Orthographic) {
    ox = pc + c.dx, oy = pc + c.dy;
    dx = dy = vec3(0, 0, 1);
  } else {
    float z = glm::length(pc);
    if (!(z > 0.0f) || !std::isfinite(z)) return;
    vec3 w = pc / z;
    if (c.kind == CameraKind::Perspective) {
      // Turn the camera so p lies on +z; the differential rays leave the
      // origin along +z + min_dir_d*.
      Frame f = Frame::from_z(w);
      dx = f.from_local(vec3(0, 0, 1) + c.min_dir_dx);
      dy = f.from_local(vec3(0, 0, 1) + c.min_dir_dy);
    } else {
      // pbrt-v4's GenerateRayDifferential at the raster point that sees p,
      // 0.05 pixel either side (pbrt-v4 steps one way, whose error shows on
      // the curved maps), scaled to one pixel.
      constexpr float kEps = 0.05f;
      vec2 r = spherical_camera_raster(c, w);
      auto derivative = [&](vec2 step) {
        return (spherical_camera_direction(c, r + step) - spherical_camera_direction(c, r - step)) / (2.0f * kEps);
      };
      dx = w + derivative(vec2(kEps, 0.0f));
      dy = w + derivative(vec2(0.0f, kEps));
    }
  }
  dpdx = spp_scale * c.render_from_camera.vector(offset_on_plane(ox, dx, pc, nc));
  dpdy = spp_scale * c.render_from_camera.vector(offset_on_plane(oy, dy, pc, nc));
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
