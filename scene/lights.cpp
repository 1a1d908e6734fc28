#include "scene/lights.h"

#include "core/hash.h"
#include "core/log.h"
#include "core/sampling.h"
#include "scene/emission_side.h"
#include "scene/surface_crossing.h"
#include "scene/texture.h"
#include "scene/tokenizer.h"

#include <numeric>

namespace theia {

namespace {

// pbrt-v4's Image::LookupNearest: uv in [0,1]^2 with (0, 0) the top-left
// corner, clamped; negative values clamped to zero.
RGB nearest_texel(const Image& img, vec2 uv) {
  if (img.pixels.empty() || img.width <= 0 || img.height <= 0) return RGB(0.0f);
  ivec2 p(std::clamp(int(uv.x * float(img.width)), 0, img.width - 1),
          std::clamp(int(uv.y * float(img.height)), 0, img.height - 1));
  return glm::max(texel_value(img, p), RGB(0.0f));
}

RGB environment_texel(const EnvironmentMap& env, vec2 uv) { return nearest_texel(*env.image, uv); }

// A goniometric texel: pbrt-v4 keeps one channel, the mean of R, G and B
// (a grey image's value).
float goniometric_texel(const Image& img, vec2 uv) {
  RGB c = nearest_texel(img, uv);
  return (c.x + c.y + c.z) / 3.0f;
}

// pbrt-v4's ProjectionLight frustum: Perspective(fov) maps a light-space
// direction w to the screen point w.xy / (w.z tan(fov / 2)), and the screen
// is [-aspect, aspect] x [-1, 1] (or [-1, 1] x [-1/aspect, 1/aspect] for a
// tall image), so fov spans the image's shorter axis.
struct ProjectionFrustum {
  vec2 screen_max{1.0f};
  float tan_half_fov = 1.0f;
  float area = 4.0f;  // pbrt-v4's A: the screen's area on the plane z = 1
};

ProjectionFrustum projection_frustum(const Light& light, const Image& img) {
  ProjectionFrustum f;
  float aspect = float(img.width) / float(img.height);
  f.screen_max = aspect > 1.0f ? vec2(aspect, 1.0f) : vec2(1.0f, 1.0f / aspect);
  f.tan_half_fov = std::tan(radians(light.fov) / 2.0f);
  f.area = 4.0f * sqr(f.tan_half_fov) * (aspect > 1.0f ? aspect : 1.0f / aspect);
  return f;
}

constexpr float kProjectionHither = 1e-3f;  // pbrt-v4's: directions this close to the screen's plane see nothing

// The texel a unit light-space direction projects to; black outside the frustum.
RGB projection_texel(const ProjectionFrustum& f, const Image& img, const vec3& w) {
  if (w.z < kProjectionHither) return RGB(0.0f);
  vec2 ps = vec2(w.x, w.y) / (w.z * f.tan_half_fov);
  if (std::abs(ps.x) > f.screen_max.x || std::abs(ps.y) > f.screen_max.y) return RGB(0.0f);
  return nearest_texel(img, (ps + f.screen_max) / (2.0f * f.screen_max));
}

// The direction through the centre of screen texel (x, y), light space, unit.
vec3 projection_direction(const ProjectionFrustum& f, const Image& img, int x, int y) {
  vec2 uv((float(x) + 0.5f) / float(img.width), (float(y) + 0.5f) / float(img.height));
  vec2 ps = (2.0f * uv - 1.0f) * f.screen_max * f.tan_half_fov;
  return glm::normalize(vec3(ps, 1.0f));
}

// Solid angle of texel (x, y) and its centre direction, light space.
float texel_solid_angle(const EnvironmentMap& env, int y) {
  const Image& img = *env.image;
  float n = float(img.width) * float(img.height);
  if (env.equal_area) return 4.0f * kPi / n;
  float theta = kPi * (float(y) + 0.5f) / float(img.height);
  return 2.0f * kPi * kPi * std::sin(theta) / n;
}

EnvironmentMap make_environment(const Light& light, const Image& img) {
  EnvironmentMap env;
  env.image = &img;
  if (img.pixels.empty() || img.width <= 0 || img.height <= 0)
    throw_error("{}:{}: environment image \"{}\" was not loaded", light.loc.file, light.loc.line, img.filename);
  if (img.width == img.height)
    env.equal_area = true;
  else if (img.width == 2 * img.height)
    env.equal_area = false;
  else
    throw_error("{}:{}: environment image \"{}\" is {}x{}, expected a square equal-area map or a 2:1 "
                "latitude-longitude map",
                light.loc.file, light.loc.line, img.filename, img.width, img.height);
  for (float v : img.pixels)
    if (!std::isfinite(v))
      throw_error("{}:{}: environment image \"{}\" has non-finite pixels", light.loc.file, light.loc.line,
                  img.filename);

  const int w = img.width, h = img.height;
  std::vector<float> d(size_t(w) * size_t(h));
  // "illuminance" as pbrt-v4 computes it for equal-area maps: the sum of
  // luminance * cos(theta) over upper-hemisphere texels times 2 pi / texels,
  // which is half the true upper-hemisphere illuminance.  Lat-long maps use
  // the same definition (half the true integral) so both give one scale.
  double illum = 0.0, integral = 0.0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      vec2 uv((float(x) + 0.5f) / float(w), (float(y) + 0.5f) / float(h));
      RGB c = image_texel(img, {x, y}, WrapMode::Clamp);
      vec3 dir = environment_direction(env, uv);
      float sin_theta = env.equal_area ? 1.0f : std::sin(kPi * uv.y);
      d[size_t(y) * size_t(w) + size_t(x)] = (c.x + c.y + c.z) / 3.0f * sin_theta;
      float lum = luminance(glm::max(c, RGB(0.0f)));
      float dw = texel_solid_angle(env, y);
      integral += double(lum * dw);
      if (dir.z > 0.0f) illum += double(lum * dir.z * dw);
    }
  illum *= 0.5;
  env.scale = light.L;
  if (light.illuminance > 0.0f) {
    if (!(illum > 0.0))
      throw_error("{}:{}: \"illuminance\" given for an environment image that is black above the horizon",
                  light.loc.file, light.loc.line);
    env.scale *= float(double(light.illuminance) / illum);
  }
  env.luminance_integral = float(integral) * luminance(env.scale);
  env.distribution = Distribution2D(d, w, h);
  double mean = std::accumulate(d.begin(), d.end(), 0.0) / double(d.size());
  bool any = false;
  for (float& v : d) {
    v = std::max(0.0f, float(double(v) - mean));
    any = any || v > 0.0f;
  }
  if (!any) std::fill(d.begin(), d.end(), 1.0f);
  env.compensated = Distribution2D(d, w, h);
  return env;
}

// pbrt-v4's SmoothStep: 0 below a, 1 above b, Hermite between.
float smooth_step(float a, float b, float x) {
  if (a == b) return x < a ? 0.0f : 1.0f;
  float t = std::clamp((x - a) / (b - a), 0.0f, 1.0f);
  return t * t * (3.0f - 2.0f * t);
}

vec3 to_light(const Light& light, const vec3& w) {
  return glm::normalize(mat3(light.render_from_light.m_inv) * w);
}

// An area light's image at the surface's uv, as pbrt-v4 looks it up: v
// flipped, Image::Bilerp with clamping, negative values clamped to zero.
RGB area_texel(const Image& img, vec2 uv) {
  return glm::max(image_bilerp(img, vec2(uv.x, 1.0f - uv.y), WrapMode::Clamp), RGB(0.0f));
}

// Radiance of area light `light_index` at triangle `prim` (-1 for quadrics), uv, before the side test.
RGB area_radiance(const LightSet& lights, int light_index, int prim, vec2 uv) {
  const Light& light = lights.scene->lights[size_t(light_index)];
  RGB L = light.L * lights.image_scale[size_t(light_index)];
  if (!light.triangle_scale.empty())
    L *= prim >= 0 && size_t(prim) < light.triangle_scale.size() ? light.triangle_scale[size_t(prim)] : 0.0f;
  if (light.image >= 0) L *= area_texel(lights.scene->images[size_t(light.image)], uv);
  return L;
}

// Mean luminance of an area light's image over mesh triangle t: a stratified
// grid of points on the triangle, 16 or more per texel it covers (16 x 16
// to 64 x 64).  Only the triangle choice and light_power use it, and the pdf
// is whatever the choice does, so an estimate costs variance, not bias.
double triangle_image_luminance(const Image& img, const TriangleMesh& m, size_t t) {
  vec2 uv[3];
  triangle_uvs(m, t, uv);
  vec2 e1 = uv[1] - uv[0], e2 = uv[2] - uv[0];
  double texels = 0.5 * std::abs(double(e1.x) * e2.y - double(e1.y) * e2.x) * img.width * img.height;
  int n = std::clamp(int(std::ceil(4.0 * std::sqrt(texels))), 16, 64);
  double sum = 0.0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      vec2 b = sample_uniform_triangle(vec2((float(i) + 0.5f) / float(n), (float(j) + 0.5f) / float(n)));
      sum += double(luminance(area_texel(img, b.x * uv[0] + b.y * uv[1] + (1.0f - b.x - b.y) * uv[2])));
    }
  return sum / double(n * n);
}

// pbrt-v4's k_e for an area light image: the mean over pixels of their luminance.
double image_mean_luminance(const Light& light, const Image& img) {
  if (img.pixels.empty() || img.width <= 0 || img.height <= 0)
    throw_error("{}:{}: area light image \"{}\" was not loaded", light.loc.file, light.loc.line, img.filename);
  if (img.channels < 3)
    throw_error("{}:{}: area light image \"{}\" has {} channel(s), expected an RGB image (as pbrt-v4)",
                light.loc.file, light.loc.line, img.filename, img.channels);
  double sum = 0.0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) sum += double(luminance(image_texel(img, {x, y}, WrapMode::Clamp)));
  return sum / (double(img.width) * double(img.height));
}

// k_e of a goniometric or projection light: the luminous power it emits for
// L of luminance 1, as pbrt-v4 sums it over the texels (exact for the equal-area map,
// pbrt-v4's midpoint rule over the texels' cos^3 Jacobian for the frustum).
// Throws for images these lights cannot use.
double point_image_power(const Light& light, const Image& img) {
  const char* kind = light.kind == LightKind::Goniometric ? "goniometric" : "projection";
  if (img.pixels.empty() || img.width <= 0 || img.height <= 0)
    throw_at(light.loc, "{} light image \"{}\" was not loaded, expected its pixels", kind, img.filename);
  double sum = 0.0;
  if (light.kind == LightKind::Goniometric) {
    if (img.width != img.height)
      throw_at(light.loc,
               "goniometric light image \"{}\" is {}x{}, expected a square (equal-area) map as pbrt-v4 does",
               img.filename, img.width, img.height);
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x)
        sum += double(goniometric_texel(img, vec2((float(x) + 0.5f) / float(img.width),
                                                  (float(y) + 0.5f) / float(img.height))));
    return 4.0 * kPi * sum / (double(img.width) * double(img.height));
  }
  if (img.channels < 3)
    throw_at(light.loc, "projection light image \"{}\" has {} channel(s), expected an RGB image (as pbrt-v4)",
             img.filename, img.channels);
  ProjectionFrustum f = projection_frustum(light, img);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      float cos_theta = projection_direction(f, img, x, y).z;
      sum += double(luminance(glm::max(image_texel(img, {x, y}, WrapMode::Clamp), RGB(0.0f)))) *
             double(cos_theta * cos_theta * cos_theta);
    }
  return double(f.area) * sum / (double(img.width) * double(img.height));
}

// The plane of a one-sided area light on a triangle mesh whose triangles,
// oriented as sample_li orients them (shape_geometry::triangle_normal), all
// face within a small angle of one normal; not planar otherwise.
EmitterPlane emitter_plane(const Scene& s, const Light& l) {
  EmitterPlane e;
  if (l.kind != LightKind::Area || l.two_sided || l.shape < 0) return e;
  const Shape& shape = s.shapes[size_t(l.shape)];
  if (shape.kind != ShapeKind::TriangleMesh) return e;
  const TriangleMesh& m = s.meshes[size_t(shape.mesh)];
  const bool flip = shape.reverse_orientation != shape.transform_swaps_handedness;
  // The largest triangle's normal is the plane's (the best conditioned).
  size_t largest = 0;
  double largest_area = -1.0;
  for (size_t t = 0; t < m.triangle_count(); ++t)
    if (double a = triangle_area(m, t); a > largest_area) largest = t, largest_area = a;
  if (!(largest_area > 0.0)) return e;
  const vec3 n = (flip ? -1.0f : 1.0f) * triangle_unit_normal(m, largest);
  // Interpolated vertex normals decide which way a triangle faces; all on
  // the plane's side keep every triangle facing as its geometric normal.
  for (const vec3& vn : m.n)
    if (!(glm::dot(vn, n) > 0.0f)) return e;
  Bounds3 b;
  for (uint32_t i : m.indices) b = union_bounds(b, m.p[i]);
  e.center = 0.5f * (b.min + b.max);
  e.n = n;
  e.offset = glm::dot(n, e.center);
  float tilt = 0.0f, deviation = 0.0f;
  for (size_t t = 0; t < m.triangle_count(); ++t) {
    if (!(triangle_area(m, t) > 0.0)) continue;  // sample_li never draws it
    const vec3 nt = (flip ? -1.0f : 1.0f) * triangle_unit_normal(m, t);
    if (!(glm::dot(nt, n) > 0.999f)) return EmitterPlane{};
    tilt = std::max(tilt, glm::length(nt - n));
  }
  for (uint32_t i : m.indices) deviation = std::max(deviation, std::abs(glm::dot(n, m.p[i]) - e.offset));
  // From a point p at distance d from the centre, a point q on the light is
  // at most d + radius away; q's triangle faces away from p when p is below
  // q's plane by more than deviation + tilt |p - q|.  1e-5 of the distances
  // covers the rounding of q, p - q and the dot products.
  const float radius = 0.5f * glm::length(b.max - b.min);
  const float per_distance = tilt + 2e-5f;
  e.margin = deviation + per_distance * radius + 1e-5f * glm::length(e.center);
  e.margin_per_distance = per_distance;
  e.planar = std::isfinite(e.offset) && std::isfinite(e.margin) && std::isfinite(e.margin_per_distance);
  return e;
}

}  // namespace

vec3 environment_direction(const EnvironmentMap& env, vec2 uv) {
  return env.equal_area ? equal_area_square_to_sphere(uv) : equirect_to_sphere(uv);
}

vec2 environment_uv(const EnvironmentMap& env, const vec3& w_light) {
  return env.equal_area ? equal_area_sphere_to_square_fast(w_light) : sphere_to_equirect(w_light);
}

float environment_pdf(const EnvironmentMap& env, const vec3& w_light, bool compensated) {
  vec2 uv = environment_uv(env, w_light);
  float pdf_uv = (compensated ? env.compensated : env.distribution).pdf(uv);
  if (env.equal_area) return pdf_uv * kInv4Pi;
  float sin_theta = std::sin(kPi * uv.y);
  return sin_theta > 0.0f ? pdf_uv / (2.0f * kPi * kPi * sin_theta) : 0.0f;
}

LightSet::LightSet(const Scene& s, const Accel& accel) : scene(&s) {
  // Goniometric and projection lights: k_e and "power".  Area lights: the
  // image normalisation, the triangles' emission per unit area (their choice
  // by power) and the integral of it over the shape.
  image_scale.assign(s.lights.size(), 1.0f);
  image_power.assign(s.lights.size(), 0.0);
  area_luminance.assign(s.lights.size(), 0.0);
  std::vector<std::vector<float>> triangle_weight(s.shapes.size());
  std::vector<double> pixel_mean(s.lights.size(), 1.0), weighted_area(s.lights.size(), -1.0);
  for (size_t i = 0; i < s.lights.size(); ++i) {
    const Light& l = s.lights[i];
    if (l.kind == LightKind::Goniometric || l.kind == LightKind::Projection) {
      if (l.image < 0) throw_at(l.loc, "light without an image, expected \"string filename\"");
      const Image& img = s.images.at(size_t(l.image));
      double k_e = point_image_power(l, img);
      if (l.power > 0.0f) {
        if (!(k_e > 0.0))
          throw_at(l.loc, "\"power\" given for a light whose image \"{}\" is black, expected some light",
                   img.filename);
        // pbrt-v4 multiplies: "scale" and the luminance of "I" still apply on top of "power".
        image_scale[i] = float(double(l.power) / k_e);
      }
      image_power[i] = double(luminance(l.L)) * double(image_scale[i]) * k_e;
      continue;
    }
    if (l.kind != LightKind::Area || l.shape < 0) continue;
    const Image* img = l.image >= 0 ? &s.images.at(size_t(l.image)) : nullptr;
    if (img) {
      pixel_mean[i] = image_mean_luminance(l, *img);
      if (l.power > 0.0f) {
        if (!(pixel_mean[i] > 0.0))
          throw_error("{}:{}: \"power\" given for an area light whose image \"{}\" is black", l.loc.file,
                      l.loc.line, img->filename);
        image_scale[i] = float(1.0 / pixel_mean[i]);
      }
    }
    const Shape& shape = s.shapes[size_t(l.shape)];
    if (shape.kind != ShapeKind::TriangleMesh || (l.triangle_scale.empty() && !img)) continue;
    const TriangleMesh& m = s.meshes[size_t(shape.mesh)];
    std::vector<float>& w = triangle_weight[size_t(l.shape)];
    w.assign(m.triangle_count(), 1.0f);
    double sum = 0.0;
    for (size_t t = 0; t < w.size(); ++t) {
      if (!l.triangle_scale.empty()) w[t] = l.triangle_scale[t];
      if (img) w[t] *= float(triangle_image_luminance(*img, m, t));
      sum += double(float(triangle_area(m, t))) * double(w[t]);
    }
    weighted_area[i] = sum;
  }
  shapes = ShapeSampling(s, triangle_weight);
  for (size_t i = 0; i < s.lights.size(); ++i) {
    const Light& l = s.lights[i];
    if (l.kind != LightKind::Area) continue;
    double integral = weighted_area[i] >= 0.0 ? weighted_area[i] : double(shapes.area(l.shape)) * pixel_mean[i];
    // L is grey whenever there is an image, so luminance factors out of the texel.
    area_luminance[i] = integral * double(luminance(l.L * image_scale[i]));
  }

  for (const Light& l : s.lights) emitter_planes.push_back(emitter_plane(s, l));

  Bounds3 b = accel.bounds();
  if (b.min.x <= b.max.x) {
    scene_center = 0.5f * (b.min + b.max);
    scene_radius = 0.5f * glm::length(b.max - b.min);
  }
  environment_of_light.assign(s.lights.size(), -1);
  for (size_t i = 0; i < s.lights.size(); ++i) {
    const Light& l = s.lights[i];
    if (l.kind != LightKind::Infinite) continue;
    infinite_lights.push_back(int(i));
    if (l.image >= 0) {
      environment_of_light[i] = int(environments.size());
      environments.push_back(make_environment(l, s.images.at(size_t(l.image))));
    }
  }
}

std::optional<LightLiSample> sample_li(const LightSet& lights, int light_index, const LightSampleContext& ctx,
                                       vec2 u, float u_prim, bool allow_incomplete_pdf, int primitive) {
  const Light& light = lights.scene->lights[light_index];
  // Far enough along wi to be outside the scene from any point in it.
  auto far_point = [&](const vec3& wi) {
    return ctx.p + wi * (2.0f * lights.scene_radius + glm::length(ctx.p - lights.scene_center) + 1.0f);
  };
  switch (light.kind) {
    case LightKind::Area: {
      const Shape& shape = lights.scene->shapes[size_t(light.shape)];
      // The uv is read only by an image's lookup and an alpha test.
      const bool want_uv = light.image >= 0 || shape.alpha >= 0;
      auto ss = lights.shapes.sample(light.shape, ShapeSampleContext{ctx.p, ctx.ng}, u, u_prim, primitive, want_uv);
      if (!ss || ss->pdf == 0.0f) return std::nullopt;
      vec3 d = ss->p - ctx.p;
      float dist2 = glm::dot(d, d);
      if (dist2 == 0.0f) return std::nullopt;
      vec3 wi = d / std::sqrt(dist2);
      if (!light.two_sided && glm::dot(ss->n, -wi) <= 0.0f) return std::nullopt;
      // pbrt-v4's invisible area light: a constant alpha of 0 hides the
      // shape from every ray but not its emission, and since rays never find
      // it, light samples take no MIS weight (pbrt-v4 makes it DeltaPosition).
      bool invisible = shape.alpha >= 0 && lights.scene->textures[size_t(shape.alpha)].kind == TextureKind::Constant &&
                       lights.scene->textures[size_t(shape.alpha)].value.x <= 0.0f;
      if (!invisible && area_light_alpha_masked(*lights.scene, light.shape, ss->p, ss->uv)) return std::nullopt;
      RGB L = area_radiance(lights, light_index, ss->prim, ss->uv);
      if (is_black(L)) return std::nullopt;
      return LightLiSample{L, wi, ss->pdf, ss->p, ss->p_error, ss->n, invisible, false};
    }
    case LightKind::Point:
    case LightKind::Spot:
    case LightKind::Goniometric:
    case LightKind::Projection: {
      vec3 d = light.position - ctx.p;
      float dist2 = glm::dot(d, d);
      if (dist2 == 0.0f) return std::nullopt;
      vec3 wi = d / std::sqrt(dist2);
      RGB I = light_intensity(lights, light_index, -wi);
      if (is_black(I)) return std::nullopt;
      return LightLiSample{I / dist2, wi, 1.0f, light.position, vec3(0.0f), vec3(0.0f), true, false};
    }
    case LightKind::Distant: {
      vec3 wi = light.direction;
      return LightLiSample{light.L, wi, 1.0f, far_point(wi), vec3(0.0f), -wi, true, true};
    }
    case LightKind::Infinite: {
      int e = lights.environment_of_light[size_t(light_index)];
      if (e < 0) {
        vec3 wi = sample_uniform_sphere(u);
        return LightLiSample{light.L, wi, uniform_sphere_pdf(), far_point(wi), vec3(0.0f), -wi, false, true};
      }
      const EnvironmentMap& env = lights.environments[size_t(e)];
      float pdf_uv = 0.0f;
      vec2 uv = (allow_incomplete_pdf ? env.compensated : env.distribution).sample_continuous(u, &pdf_uv);
      if (pdf_uv == 0.0f) return std::nullopt;
      vec3 w_light = environment_direction(env, uv);
      float pdf;
      if (env.equal_area) {
        pdf = pdf_uv * kInv4Pi;
      } else {
        float sin_theta = std::sin(kPi * uv.y);
        if (sin_theta <= 0.0f) return std::nullopt;
        pdf = pdf_uv / (2.0f * kPi * kPi * sin_theta);
      }
      vec3 wi = glm::normalize(light.render_from_light.vector(w_light));
      RGB L = env.scale * environment_texel(env, uv);
      if (is_black(L)) return std::nullopt;
      return LightLiSample{L, wi, pdf, far_point(wi), vec3(0.0f), -wi, false, true};
    }
  }
  return std::nullopt;
}

float area_light_pdf(const LightSet& lights, int light_index, const LightSampleContext& ctx, const vec3& wi,
                     const SurfaceInteraction& hit, bool given_primitive) {
  const Light& light = lights.scene->lights[light_index];
  return lights.shapes.pdf(light.shape, ShapeSampleContext{ctx.p, ctx.ng}, wi, hit, given_primitive);
}

float infinite_light_pdf(const LightSet& lights, int light_index, const vec3& wi, bool allow_incomplete_pdf) {
  int e = lights.environment_of_light[size_t(light_index)];
  if (e < 0) return uniform_sphere_pdf();
  const Light& light = lights.scene->lights[light_index];
  return environment_pdf(lights.environments[size_t(e)], to_light(light, wi), allow_incomplete_pdf);
}

RGB light_intensity(const LightSet& lights, int light_index, const vec3& w) {
  const Light& light = lights.scene->lights[size_t(light_index)];
  switch (light.kind) {
    case LightKind::Point:
      return light.L;
    case LightKind::Spot:
      return light.L * smooth_step(light.cos_falloff_end, light.cos_falloff_start, glm::dot(w, light.direction));
    case LightKind::Goniometric: {
      const Image& img = lights.scene->images[size_t(light.image)];
      float y = goniometric_texel(img, equal_area_sphere_to_square(to_light(light, w)));
      return light.L * (lights.image_scale[size_t(light_index)] * y);
    }
    case LightKind::Projection: {
      const Image& img = lights.scene->images[size_t(light.image)];
      RGB texel = projection_texel(projection_frustum(light, img), img, to_light(light, w));
      return light.L * lights.image_scale[size_t(light_index)] * texel;
    }
    default:
      return RGB(0.0f);
  }
}

RGB area_light_L(const LightSet& lights, int light_index, const SurfaceInteraction& hit, const vec3& w) {
  const Light& light = lights.scene->lights[size_t(light_index)];
  if (!light.two_sided && glm::dot(hit.ng, w) <= 0.0f) return RGB(0.0f);
  return area_radiance(lights, light_index, hit.prim, hit.uv);
}

std::optional<LightLeSample> sample_le(const LightSet& lights, int light_index, vec2 u_pos, float u_prim,
                                       vec2 u_dir) {
  const Light& light = lights.scene->lights[size_t(light_index)];
  if (light.kind != LightKind::Area) return std::nullopt;
  auto ss = lights.shapes.sample_area(light.shape, u_pos, u_prim);
  if (!ss || area_light_alpha_masked(*lights.scene, light.shape, ss->p, ss->uv)) return std::nullopt;
  LightLeSample ls;
  ls.L = area_radiance(lights, light_index, ss->prim, ss->uv);
  if (is_black(ls.L)) return std::nullopt;
  ls.p = ss->p;
  ls.p_error = ss->p_error;
  ls.n = ss->n;
  ls.pdf_pos = ss->pdf;
  vec3 n = ss->n;
  if (light.two_sided && emission_back_side(u_dir)) n = -n;
  vec3 w_local = sample_cosine_hemisphere(u_dir);
  ls.pdf_dir = cosine_hemisphere_pdf(w_local.z) * (light.two_sided ? 0.5f : 1.0f);
  if (!(ls.pdf_dir > 0.0f)) return std::nullopt;
  ls.w = glm::normalize(Frame::from_z(n).from_local(w_local));
  return ls;
}

bool area_light_alpha_masked(const Scene& scene, int shape, const vec3& p, vec2 uv) {
  int alpha = scene.shapes[size_t(shape)].alpha;
  if (alpha < 0) return false;
  float a = eval_float_texture(scene, alpha, TextureEvalContext{uv, p, {}});
  if (a >= 1.0f) return false;
  if (a <= 0.0f) return true;
  return to_unit_float(uint32_t(hash_bytes(&p, sizeof(p)) >> 32)) > a;
}

RGB infinite_light_Le(const LightSet& lights, int light_index, const vec3& dir) {
  const Light& light = lights.scene->lights[light_index];
  int e = lights.environment_of_light[size_t(light_index)];
  if (e < 0) return light.L;
  const EnvironmentMap& env = lights.environments[size_t(e)];
  return env.scale * environment_texel(env, environment_uv(env, to_light(light, dir)));
}

float light_power(const LightSet& lights, int light_index) {
  const Light& light = lights.scene->lights[light_index];
  float y = luminance(light.L);
  float disk = kPi * sqr(lights.scene_radius);  // what a directional emitter illuminates
  switch (light.kind) {
    case LightKind::Area:
      return float(kPi * (light.two_sided ? 2.0 : 1.0) * lights.area_luminance[size_t(light_index)]);
    case LightKind::Point:
      return 4.0f * kPi * y;
    case LightKind::Spot:
      return 2.0f * kPi * y *
             ((1.0f - light.cos_falloff_start) + (light.cos_falloff_start - light.cos_falloff_end) / 2.0f);
    case LightKind::Distant:
      return disk * y;
    case LightKind::Goniometric:
    case LightKind::Projection:
      return float(lights.image_power[size_t(light_index)]);
    case LightKind::Infinite: {
      int e = lights.environment_of_light[size_t(light_index)];
      return disk * (e < 0 ? 4.0f * kPi * y : lights.environments[size_t(e)].luminance_integral);
    }
  }
  return 0.0f;
}

}  // namespace theia
