// Light evaluation and sampling for the light kinds of scene/scene.h: area,
// point, spot, distant, infinite (constant or an environment image), and
// pbrt-v4's image-modulated point lights, goniometric and projection.
//
// Sampling is split the way pbrt-v4 splits it: a LightSampler
// (cachepoints/light_sampler.h) chooses a light, then sample_li() chooses a
// point on it.  Pdfs returned here are per unit solid angle at the reference
// point and do not include the light-choice probability.
#pragma once

#include "core/distribution2d.h"
#include "scene/accel.h"
#include "scene/scene.h"
#include "scene/shapes.h"

#include <optional>

namespace theia {

struct LightSampleContext {
  vec3 p{0.0f};
  vec3 p_error{0.0f};
  vec3 ng{0.0f};  // zero for points not on a surface
  vec3 ns{0.0f};
};

struct LightLiSample {
  RGB L{0.0f};          // radiance arriving from the light (no visibility)
  vec3 wi{0.0f};        // unit direction towards the light
  // Solid angle; for delta lights 1 and `is_delta` set.  An invisible area
  // light (constant alpha 0) keeps its pdf and sets `is_delta`: no MIS weight.
  float pdf = 0.0f;
  vec3 p_light{0.0f};   // point on the light (for infinite lights: far away along wi)
  vec3 p_light_error{0.0f};
  vec3 n_light{0.0f};
  bool is_delta = false;
  bool is_infinite = false;
};

// An infinite light's environment image with its sampling tables.  Square
// images are pbrt-v4's equal-area octahedral maps; images twice as wide as
// tall are latitude-longitude maps (pbrt-v3's convention, see
// core/sampling.h).  Radiance is the nearest texel (as pbrt-v4 looks it up),
// so the piecewise-constant tables match it exactly.
struct EnvironmentMap {
  const Image* image = nullptr;
  bool equal_area = true;
  RGB scale{1.0f};                // Light::L, with "illuminance" applied
  // Per texel: mean of the channels, times sin(theta) for lat-long maps.
  Distribution2D distribution;
  // The same minus its mean, clamped at zero (pbrt-v4's "compensated"
  // distribution): with MIS, the BSDF samples the dim directions well
  // enough, so light samples go where the map is brighter than average.
  Distribution2D compensated;
  float luminance_integral = 0.0f;  // integral of luminance(scale * texel) over the sphere
};

// A one-sided planar area light's plane: n its emitting side (unit), offset
// = dot(n, any point on it); the light is planar and one-sided when
// `planar`.  A point counts as behind it only below the plane by more than
// margin + margin_per_distance * |p - center|: the margins bound how far a
// vertex lies off the plane, how far a triangle's own normal (which decides
// emission) tilts from n, and rounding.
struct EmitterPlane {
  bool planar = false;
  vec3 n{0.0f};
  float offset = 0.0f;
  vec3 center{0.0f};
  float margin = 0.0f;
  float margin_per_distance = 0.0f;
};

// Everything light sampling needs that is built once per scene.
struct LightSet {
  const Scene* scene = nullptr;
  ShapeSampling shapes;
  vec3 scene_center{0.0f};
  float scene_radius = 0.0f;
  std::vector<int> infinite_lights;  // indices into Scene::lights (those seen by escaped rays)
  std::vector<EnvironmentMap> environments;
  std::vector<int> environment_of_light;  // per light: index into environments, or -1
  // Per light (area, goniometric, projection; 1 for the others): the factor
  // on L (* triangle_scale) * texel that is known only with the pixels,
  // 1 / k_e for an image with "power" (times "power" for the point-like two).
  std::vector<float> image_scale;
  // Per light (goniometric, projection): the emitted luminous power, for light_power.
  std::vector<double> image_power;
  // Per light (area lights): the emitted luminance integrated over the shape's
  // area, for light_power (luminance(L) * area for a uniform emitter).
  std::vector<double> area_luminance;
  // Per light: the plane of a one-sided area light that lies in one plane
  // and faces one way (a quad, a panel), for light_faces_away.
  std::vector<EmitterPlane> emitter_planes;

  // Images must be loaded (scene/texture.h's load_images); throws
  // theia::Error for an environment image that is neither square nor 2:1 or
  // has non-finite pixels, for an area or projection light image that is not
  // RGB, a goniometric image that is not square, and an image that "power"
  // cannot normalise (black).
  LightSet(const Scene& scene, const Accel& accel);
};

// The map's parameterisation both ways.
vec3 environment_direction(const EnvironmentMap& env, vec2 uv);  // light space, unit
vec2 environment_uv(const EnvironmentMap& env, const vec3& w_light);
// Directional density of sampling the map's uv table (per unit solid angle in light space).
float environment_pdf(const EnvironmentMap& env, const vec3& w_light, bool compensated);

// `allow_incomplete_pdf`: environment maps sample their compensated
// distribution, as pbrt-v4's path tracer asks; the engine's MIS weights use
// the matching infinite_light_pdf(..., true).
// `primitive` >= 0 (an area light on a triangle mesh): that triangle,
// chosen by a light sampler that treats each triangle as a light (pbrt-v4's
// semantics, SampledLight::primitive); the pdf is then that triangle's alone.
std::optional<LightLiSample> sample_li(const LightSet& lights, int light, const LightSampleContext& ctx, vec2 u,
                                       float u_prim, bool allow_incomplete_pdf = true, int primitive = -1);
// True when p lies behind one-sided planar area light `light`: every point
// sample_li() could draw on it faces away from p and would be refused.
// Next-event estimation asks this before it spends a light sample.  Margins
// cover rounding: a point within them of the plane is never called behind.
inline bool light_faces_away(const LightSet& lights, int light, const vec3& p) {
  const EmitterPlane& e = lights.emitter_planes[size_t(light)];
  if (!e.planar) return false;
  const float height = glm::dot(e.n, p) - e.offset;
  return height < 0.0f && height < -(e.margin + e.margin_per_distance * glm::length(p - e.center));
}
// Solid-angle pdf that sample_li() on `light` produces the point `hit` seen
// along wi (area lights); `given_primitive`: sample_li() was given hit.prim.
float area_light_pdf(const LightSet& lights, int light, const LightSampleContext& ctx, const vec3& wi,
                     const SurfaceInteraction& hit, bool given_primitive = false);
// Solid-angle pdf that sample_li() on infinite `light` produces direction wi.
float infinite_light_pdf(const LightSet& lights, int light, const vec3& wi, bool allow_incomplete_pdf = true);

// Radiant intensity a point-like light (point, spot, goniometric,
// projection) emits along the unit render-space direction w leaving it;
// black for the other kinds.  Goniometric: L times the nearest texel's mean
// of R, G, B at the equal-area position of w in light space.  Projection: L
// times the nearest texel where w crosses the frustum's screen, black behind
// pbrt-v4's hither plane (light-space z < 1e-3) and outside the screen.
RGB light_intensity(const LightSet& lights, int light, const vec3& w);

// Radiance area light `light` emits from `hit` towards `w`: one- or
// two-sided, its triangle's factor, its image at hit.uv.  No alpha test: a
// hit found by a ray has passed the accel's stochastic alpha test already
// (pbrt-v4 tests alpha again here, which makes the emission rays find a^2 L
// while light sampling finds a L; theia tests once on each strategy).
RGB area_light_L(const LightSet& lights, int light, const SurfaceInteraction& hit, const vec3& w);
// pbrt-v4's DiffuseAreaLight::AlphaMasked for a sampled point on `shape`:
// masked where alpha <= 0, never where alpha >= 1, else where a hash of p exceeds alpha.
bool area_light_alpha_masked(const Scene& scene, int shape, const vec3& p, vec2 uv);
// Radiance arriving along an escaped ray from one infinite light.
RGB infinite_light_Le(const LightSet& lights, int light, const vec3& dir);

// A ray leaving an area light (pbrt-v4's Light::SampleLe): a point by area
// (triangles by power, as for light sampling) and a cosine-weighted
// direction on its emitting side (either side, each half the time, when
// two-sided).  L is what leaves along the ray; the pdfs are per unit area and
// per unit solid angle.  nullopt for other lights, and where the point is
// alpha-masked or emits nothing.
struct LightLeSample {
  RGB L{0.0f};
  vec3 p{0.0f}, p_error{0.0f}, n{0.0f};  // n: the shape's oriented normal at p
  vec3 w{0.0f};
  float pdf_pos = 0.0f, pdf_dir = 0.0f;
};
std::optional<LightLeSample> sample_le(const LightSet& lights, int light, vec2 u_pos, float u_prim, vec2 u_dir);

// Total emitted power (for power-proportional light selection), as luminance.
float light_power(const LightSet& lights, int light);

}  // namespace theia
