#include "wavefront/caustics.h"

#include "core/hash.h"
#include "core/sampler.h"
#include "core/stats.h"
#include "scene/bsdf.h"
#include "scene/emission_side.h"
#include "scene/shape_bounds.h"
#include "scene/shapes.h"
#include "wavefront/caustic_first_ray.h"
#include "wavefront/sample_dims.h"

#include <tbb/parallel_for.h>

#include <chrono>

namespace theia {

namespace {

// Sample dimensions of a light path (its own seed keeps them apart from the camera paths').
constexpr uint32_t kDimPosition = 0, kDimDirection = 2, kDimBsdfDir = 4, kDimLight = 6, kDimPrim = 7, kDimLobe = 8;
constexpr size_t kGrain = 256;

// A light path on its way: throughput and the ray it travels.
struct LightPath {
  RGB beta{0.0f};
  Ray ray;
};

// Veach's correction for shading normals in light transport (thesis 5.3;
// pbrt-v3's CorrectShadingNormal): scattering importance-carrying light from
// wo (towards the light) into wi with a shading normal ns that is not the
// geometric ng.  1 where they agree.
float adjoint_shading_correction(const vec3& wo, const vec3& wi, const vec3& ns, const vec3& ng) {
  float den = std::abs(glm::dot(wo, ng)) * std::abs(glm::dot(wi, ns));
  if (!(den > 0.0f)) return 0.0f;
  return std::abs(glm::dot(wo, ns)) * std::abs(glm::dot(wi, ng)) / den;
}

// The materials bsdf_is_caustic_caster can accept.
bool caster_kind(MaterialKind k) {
  return k == MaterialKind::Conductor || k == MaterialKind::Dielectric || k == MaterialKind::ThinDielectric;
}

// The alpha make_bsdf gives a roughness slot that is a constant (or absent:
// 0), as its distribution() computes it; nullopt for any other texture.
std::optional<float> constant_alpha(const Scene& scene, int texture, bool remap) {
  float r = 0.0f;
  if (texture >= 0) {
    const Texture& t = scene.textures[size_t(texture)];
    if (t.kind != TextureKind::Constant) return std::nullopt;
    r = t.value.x;
  }
  if (remap) r = TrowbridgeReitz::roughness_to_alpha(r);
  return std::max(r, 0.0f);
}

// Whether material m can make a caster's BSDF: a caster kind, or a mix that
// may resolve to one, and not a conductor or dielectric whose constant
// roughness already makes every lobe too rough for bsdf_is_caustic_caster
// (veach-mis's "SuperRough" plate: its hits were set up only to be refused).
bool material_may_cast(const Scene& scene, int m, float max_roughness) {
  if (m < 0) return false;  // the default diffuse
  const Material& mat = scene.materials[size_t(m)];
  if (mat.kind == MaterialKind::Mix || mat.kind == MaterialKind::ThinDielectric) return true;
  if (mat.kind != MaterialKind::Conductor && mat.kind != MaterialKind::Dielectric) return false;
  const std::optional<float> u = constant_alpha(scene, mat.uroughness, mat.remap_roughness),
                             v = constant_alpha(scene, mat.vroughness, mat.remap_roughness);
  return !u || !v || std::max(*u, *v) <= max_roughness;
}

// Whether a hit on `shape` can be a caster (casting: per material,
// material_may_cast): most first hits are on other surfaces, not worth
// setting up.  An unknown shape goes on to compute_interaction, which reports it.
bool may_cast(const Scene& scene, const std::vector<uint8_t>& casting, int shape) {
  if (shape < 0) return true;
  const int m = scene.shapes[size_t(shape)].material;
  return m >= 0 && casting[size_t(m)];
}

// Boxes around the shapes may_cast accepts, for the light paths' first rays:
// most leave the light in directions where no caster is (veach-mis: 88% end
// at their first hit), and a ray that meets none of the boxes cannot have a
// caster as its first hit, so it need not be traced.  At most kMaxCasterBoxes
// (beyond that their union, one box); none when a caster is instanced or a
// curve (the pass then traces every ray, as without boxes).
constexpr size_t kMaxCasterBoxes = 8;

std::vector<Bounds3> find_caster_boxes(const Scene& scene, const std::vector<uint8_t>& casting) {
  std::vector<uint8_t> top_level(scene.shapes.size(), 0);
  for (int i : scene.top_level_shapes) top_level[size_t(i)] = 1;
  std::vector<Bounds3> boxes;
  for (size_t i = 0; i < scene.shapes.size(); ++i) {
    const Shape& s = scene.shapes[i];
    if (!may_cast(scene, casting, int(i))) continue;
    const std::optional<Bounds3> b = top_level[i] ? top_level_shape_bounds(scene, s) : std::nullopt;
    if (!b) return {};
    if (!b->empty()) boxes.push_back(*b);
  }
  if (boxes.size() > kMaxCasterBoxes) {
    Bounds3 all;
    for (const Bounds3& b : boxes) all = union_bounds(all, b);
    boxes.assign(1, all);
  }
  return boxes;
}

// A finished path's connection to the camera, waiting for its shadow ray.
struct Connection {
  vec2 raster{0.0f};
  RGB value{0.0f};  // per unit raster area, before the filter
  Ray shadow;
};

}  // namespace

namespace caustic_first_ray {

namespace {

// may_meet with the ray's reciprocal direction given, for a ray tested against many boxes.
bool may_meet_inv(const vec3& o, const vec3& inv, const Bounds3& b) {
  float t0 = 0.0f, t1 = kInfinity;
  for (int a = 0; a < 3; ++a) {
    float near = (b.min[a] - o[a]) * inv[a], far = (b.max[a] - o[a]) * inv[a];
    if (near > far) std::swap(near, far);
    far += 2.0f * gamma_bound(3) * std::abs(far);
    if (near > t0) t0 = near;
    if (far < t1) t1 = far;
    if (t0 > t1) return false;
  }
  return true;
}

}  // namespace

bool may_meet(const Ray& ray, const Bounds3& b) { return may_meet_inv(ray.o, 1.0f / ray.d, b); }

Ray emitted_ray(const LightLeSample& le) {
  return Ray{offset_ray_origin(le.p, le.p_error, le.n, le.w), 0.0f, le.w, kInfinity};
}

SphereEmitter sphere_emitter(const Scene& scene, int light, const std::vector<Bounds3>& boxes) {
  SphereEmitter e;
  const Light& l = scene.lights[size_t(light)];
  if (l.kind != LightKind::Area || l.shape < 0) return e;
  const Shape& s = scene.shapes[size_t(l.shape)];
  if (s.kind != ShapeKind::Sphere) return e;
  const SphereShape sp = make_sphere_shape(s.sphere);
  e.zmin = sp.zmin, e.zmax = sp.zmax, e.radius = sp.radius, e.phimax = sp.phimax;
  e.render_from_object = s.render_from_object.m;
  e.normal_matrix = glm::transpose(mat3(s.render_from_object.m_inv));
  e.flip = s.reverse_orientation != s.transform_swaps_handedness;
  e.two_sided = l.two_sided;
  const mat3 lin(s.render_from_object.m);
  e.size = float(sp.radius) * (glm::length(lin[0]) + glm::length(lin[1]) + glm::length(lin[2]));
  e.valid = sp.radius > 0.0 && std::isfinite(e.size);
  // Every point p of the sphere lies within `size` of its centre c (|M x| <=
  // sum |columns| for |x| <= 1), so |p|_1 <= |c|_1 + sqrt(3) size bounds the
  // origin's slack and |c - centre| + size + the half diagonal + that slack
  // the farthest the box is.  1% more covers these bounds' own rounding.
  const vec3 c = vec3(s.render_from_object.m * vec4(0.0f, 0.0f, 0.0f, 1.0f));
  const float origin_slack = kOriginSlack * (std::abs(c.x) + std::abs(c.y) + std::abs(c.z) + 2.75f * e.size);
  for (const Bounds3& b : boxes) {
    const vec3 centre = 0.5f * (b.min + b.max);
    const float farthest = glm::length(c - centre) + e.size + 0.5f * glm::length(b.max - b.min) + origin_slack;
    const float slack = 1.01f * (origin_slack + kDirectionSlack * farthest);
    e.grown.emplace_back(b.min - vec3(slack), b.max + vec3(slack));
    e.grown_union = union_bounds(e.grown_union, e.grown.back());
  }
  e.valid = e.valid && std::isfinite(e.grown_union.min.x + e.grown_union.min.y + e.grown_union.min.z) &&
            std::isfinite(e.grown_union.max.x + e.grown_union.max.y + e.grown_union.max.z);
  return e;
}

bool sphere_ray_may_meet(const SphereEmitter& e, vec2 u_pos, vec2 u_dir) {
  const double z = e.zmin + double(u_pos.x) * (e.zmax - e.zmin);
  const double ct = std::clamp(z / e.radius, -1.0, 1.0);
  const float st = float(std::sqrt(std::max(0.0, 1.0 - ct * ct)));
  const float phi = float(double(u_pos.y) * e.phimax);
  const vec3 n_obj(st * std::cos(phi), st * std::sin(phi), float(ct));
  const vec3 p = vec3(e.render_from_object * vec4(float(e.radius) * n_obj, 1.0f));
  vec3 n = glm::normalize(e.normal_matrix * n_obj);
  if (e.flip) n = -n;
  if (e.two_sided && emission_back_side(u_dir)) n = -n;
  if (!(std::abs(n.z) >= kMinFrameZ)) return true;
  const vec3 w = glm::normalize(Frame::from_z(n).from_local(sample_cosine_hemisphere(u_dir)));
  const vec3 inv = 1.0f / w;
  if (e.grown.size() > 1 && !may_meet_inv(p, inv, e.grown_union)) return false;
  for (const Bounds3& b : e.grown)
    if (may_meet_inv(p, inv, b)) return true;
  return false;
}

}  // namespace caustic_first_ray

using caustic_first_ray::SphereEmitter;

CausticTracer::CausticTracer(const Scene& scene, const Accel& accel, const LightSet& lights, const Camera& camera,
                             const Filter& filter, const CausticOptions& options)
    : scene_(scene), accel_(accel), lights_(lights), camera_(camera), filter_(filter), options_(options) {
  traced_.assign(scene.lights.size(), 0);
  std::vector<float> power;
  for (size_t l = 0; l < scene.lights.size(); ++l) {
    const Light& light = scene.lights[l];
    if (light.kind != LightKind::Area || light.is_virtual || light.shape < 0) continue;
    if (scene.shapes[size_t(light.shape)].alpha >= 0) continue;  // pbrt-v4's invisible lights and cut-outs
    float p = light_power(lights, int(l));
    if (!(p > 0.0f) || !std::isfinite(p)) continue;
    traced_[l] = 1;
    light_of_entry_.push_back(int(l));
    power.push_back(p);
  }
  bool has_caster = false, has_interface = false;
  casting_.assign(scene.materials.size(), 0);
  for (size_t m = 0; m < scene.materials.size(); ++m) {
    casting_[m] = material_may_cast(scene, int(m), options.caster_roughness);
    has_caster |= caster_kind(scene.materials[m].kind) && casting_[m];
    has_interface |= scene.materials[m].kind == MaterialKind::Interface;
  }
  if (!camera_supports_wi(camera)) inactive_reason_ = "the camera is not a pinhole perspective camera";
  else if (light_of_entry_.empty()) inactive_reason_ = "no area light without alpha";
  else if (!has_caster) inactive_reason_ = "no conductor or dielectric material smooth enough to cast";
  else if (has_interface) inactive_reason_ = "interface materials";
  else if (!scene.curves.empty()) inactive_reason_ = "curves";
  active_ = inactive_reason_.empty();
  if (active_) light_distribution_ = Distribution1D(power);
  else std::fill(traced_.begin(), traced_.end(), 0);
}

// What passes share: the scene's caster boxes and sphere estimates, made
// by the first pass and kept.
struct CausticTracer::Scratch {
  std::vector<Bounds3> caster_boxes;
  // Per traced light entry (light_of_entry_): its sphere's estimate, when it is one.
  std::vector<SphereEmitter> sphere_emitters;
};

// One pass: the light paths of an iteration's samples, each traced from its
// light to its splat by one thread, and splatted into the film as parts of
// their camera samples.  A light path is a few incoherent rays, mostly one
// (88% end at their first hit on veach-mis): traced where they are made,
// they need no buffers, and both threads stay busy where a batch's serial
// gathers and traces left one waiting.
struct CausticTracer::Pass {
  const CausticTracer& tracer;
  Film& film;
  const std::function<UVFootprint(const SurfaceInteraction&)>& footprint;
  const CausticSamples samples;
  const uint32_t seed;
  const size_t pixels;
  const uint64_t total;  // light paths: one per camera sample
  const int width, height;
  const vec2 radius;
  const float inv_integral;  // the filter's
  const std::vector<Bounds3>& caster_boxes;
  const std::vector<SphereEmitter>& sphere_emitters;

  // A range of paths' events, added to the pass's once.
  struct Counts {
    uint64_t caster_hits = 0, receiver_hits = 0, splats = 0, dropped = 0;
  };
  std::atomic<uint64_t> caster_hits{0}, receiver_hits{0}, splats{0}, dropped{0};

  Pass(const CausticTracer& t, const Scratch& sc, Film& f, const CausticSamples& s,
       const std::function<UVFootprint(const SurfaceInteraction&)>& fp)
      : tracer(t), film(f), footprint(fp), samples(s), seed(uint32_t(hash(t.options_.seed, 0xca057u))),
        pixels(f.pixel_count()), total(uint64_t(pixels) * uint64_t(s.sample_end - s.sample_begin)), width(f.width),
        height(f.height), radius(filter_radius(t.filter_)), inv_integral(1.0f / filter_integral(t.filter_)),
        caster_boxes(sc.caster_boxes), sphere_emitters(sc.sphere_emitters) {}

  static std::vector<SphereEmitter> find_sphere_emitters(const CausticTracer& t, const std::vector<Bounds3>& boxes) {
    std::vector<SphereEmitter> e;
    for (int light : t.light_of_entry_) e.push_back(caustic_first_ray::sphere_emitter(t.scene_, light, boxes));
    return e;
  }
  // Whether a light path's first ray may meet a caster (caster_boxes).
  bool may_reach_caster(const Ray& ray) const {
    if (caster_boxes.empty()) return true;
    for (const Bounds3& b : caster_boxes)
      if (caustic_first_ray::may_meet(ray, b)) return true;
    return false;
  }
  SamplerKey key(uint64_t path) const {
    return SamplerKey{seed, uint32_t(path % pixels), samples.sample_begin + uint32_t(path / pixels)};
  }
  // Whether camera sample (pixel, sample) of this pass was rendered.
  bool rendered(size_t pixel, uint32_t sample) const {
    const uint64_t n = samples.sample_end - samples.sample_begin;
    return uint64_t(pixel) * n + (sample - samples.sample_begin) < samples.rendered;
  }
  // A path that may go on: its throughput is finite and not black (a
  // non-finite one is counted).
  static bool keep(const RGB& v, Counts& c) {
    if (!is_finite(v)) ++c.dropped;
    return is_finite(v) && !is_black(v);
  }
  // The surface a path's ray hit, if it is one the pass shades (no holdout).
  std::optional<std::pair<SurfaceInteraction, BSDF>> surface(const Ray& ray, const Hit& hit) const {
    SurfaceInteraction si = compute_interaction(tracer.scene_, tracer.accel_, ray, hit);
    if (si.shape >= 0 && tracer.scene_.shapes[size_t(si.shape)].holdout) return std::nullopt;
    BSDF bsdf = make_bsdf(tracer.scene_, si, footprint(si));
    return std::pair{si, bsdf};
  }

  // The steps of one light path; each returns what the next takes, or
  // nothing where the path ends.
  std::optional<LightPath> leave_light(const SamplerKey& k, Counts& c) const;
  std::optional<LightPath> the_caster(const SamplerKey& k, const LightPath& path, const Hit& hit, Counts& c) const;
  std::optional<Connection> the_receiver(const LightPath& path, const Hit& hit, Counts& c) const;
  void splat(uint32_t sample, const Connection& connection, Counts& c) const;

  void trace_path(uint64_t path, Counts& c) const {
    const SamplerKey k = key(path);
    const std::optional<LightPath> emitted = leave_light(k, c);
    if (!emitted) return;
    const std::optional<LightPath> scattered = the_caster(k, *emitted, tracer.accel_.intersect1(emitted->ray), c);
    if (!scattered) return;
    const std::optional<Connection> seen = the_receiver(*scattered, tracer.accel_.intersect1(scattered->ray), c);
    if (seen && !tracer.accel_.occluded1(seen->shadow)) splat(k.sample, *seen, c);
  }
  void trace_all() {
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, total, kGrain), [&](const tbb::blocked_range<uint64_t>& r) {
      Counts c;
      for (uint64_t path = r.begin(); path != r.end(); ++path) trace_path(path, c);
      caster_hits.fetch_add(c.caster_hits, std::memory_order_relaxed);
      receiver_hits.fetch_add(c.receiver_hits, std::memory_order_relaxed);
      splats.fetch_add(c.splats, std::memory_order_relaxed);
      dropped.fetch_add(c.dropped, std::memory_order_relaxed);
    });
  }
};

// Leave a light: a point by area, a cosine-weighted direction.
std::optional<LightPath> CausticTracer::Pass::leave_light(const SamplerKey& k, Counts& c) const {
  float pmf = 0.0f;
  int entry = tracer.light_distribution_.sample_discrete(sample_1d(k, kDimLight), &pmf);
  int light = tracer.light_of_entry_[size_t(entry)];
  const vec2 u_pos = sample_2d(k, kDimPosition), u_dir = sample_2d(k, kDimDirection);
  // A sphere light's ray that surely misses every caster box is not made at all.
  const SphereEmitter& se = sphere_emitters[size_t(entry)];
  if (se.valid && !caster_boxes.empty() && !caustic_first_ray::sphere_ray_may_meet(se, u_pos, u_dir))
    return std::nullopt;
  auto le = sample_le(tracer.lights_, light, u_pos, sample_1d(k, kDimPrim), u_dir);
  if (!le || !(pmf > 0.0f)) return std::nullopt;
  RGB beta = le->L * (std::abs(glm::dot(le->n, le->w)) / (pmf * le->pdf_pos * le->pdf_dir));
  if (!keep(beta, c)) return std::nullopt;
  const Ray ray = caustic_first_ray::emitted_ray(*le);
  // The path would end at its first hit in the_caster: not traced at all.
  if (!may_reach_caster(ray)) return std::nullopt;
  return LightPath{beta, ray};
}

// The caster: scatter with the adjoint BSDF.
std::optional<LightPath> CausticTracer::Pass::the_caster(const SamplerKey& k, const LightPath& path, const Hit& h,
                                                         Counts& c) const {
  if (!h.hit() || !may_cast(tracer.scene_, tracer.casting_, tracer.accel_.shape_index(h))) return std::nullopt;
  auto hit = surface(path.ray, h);
  if (!hit || !bsdf_is_caustic_caster(hit->second, tracer.options_.caster_roughness)) return std::nullopt;
  const auto& [si, bsdf] = *hit;
  ++c.caster_hits;
  auto bs = bsdf_sample(bsdf, si.wo, sample_1d(k, kDimLobe), sample_2d(k, kDimBsdfDir), TransportMode::Importance);
  if (!bs || !(bs->pdf > 0.0f)) return std::nullopt;
  RGB beta = path.beta * bs->f * (std::abs(glm::dot(bs->wi, bsdf.shading.n)) / bs->pdf) *
             adjoint_shading_correction(si.wo, bs->wi, bsdf.shading.n, si.ng);
  if (!keep(beta, c)) return std::nullopt;
  return LightPath{beta, spawn_ray(si, bs->wi)};
}

// The receiver, connected to the camera.
std::optional<Connection> CausticTracer::Pass::the_receiver(const LightPath& path, const Hit& h, Counts& c) const {
  if (!h.hit()) return std::nullopt;
  auto hit = surface(path.ray, h);
  if (!hit || !bsdf_is_caustic_receiver(hit->second)) return std::nullopt;
  const auto& [si, bsdf] = *hit;
  ++c.receiver_hits;
  auto cw = camera_wi(tracer.camera_, si.p);
  if (!cw) return std::nullopt;
  if (cw->raster.x < -radius.x || cw->raster.y < -radius.y || cw->raster.x > float(width) + radius.x ||
      cw->raster.y > float(height) + radius.y)
    return std::nullopt;
  RGB f = bsdf_f(bsdf, si.wo, cw->wi, TransportMode::Importance);
  RGB value = path.beta * f *
              (std::abs(glm::dot(cw->wi, bsdf.shading.n)) * cw->importance *
               adjoint_shading_correction(si.wo, cw->wi, bsdf.shading.n, si.ng));
  if (!keep(value, c)) return std::nullopt;
  return Connection{cw->raster, value, spawn_ray_to(si, cw->p_lens, vec3(0.0f), vec3(0.0f))};
}

// Splat through the pixel filter, as pbrt-v4's film adds splats, each pixel's
// share weighted as a part of that pixel's camera sample of the same index.
void CausticTracer::Pass::splat(uint32_t sample, const Connection& cn, Counts& c) const {
  ++c.splats;
  int x0 = std::max(0, int(std::ceil(cn.raster.x - 0.5f - radius.x)));
  int x1 = std::min(width - 1, int(std::floor(cn.raster.x - 0.5f + radius.x)));
  int y0 = std::max(0, int(std::ceil(cn.raster.y - 0.5f - radius.y)));
  int y1 = std::min(height - 1, int(std::floor(cn.raster.y - 0.5f + radius.y)));
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) {
      float h = filter_eval(tracer.filter_, cn.raster - vec2(float(x) + 0.5f, float(y) + 0.5f));
      const size_t pixel = size_t(y) * size_t(width) + size_t(x);
      if (h == 0.0f || !rendered(pixel, sample)) continue;
      const float w = camera_filter_sample(tracer.filter_, samples.camera_seed, uint32_t(pixel), sample).weight;
      // A directly seen caustic's camera path scatters first at its diffuse receiver.
      film.splat(uint32_t(pixel), sample, cn.value * (h * w * inv_integral), kEventDiffuse);
    }
}

CausticTracer::~CausticTracer() = default;

void CausticTracer::trace(Film& film, const CausticSamples& samples,
                          const std::function<UVFootprint(const SurfaceInteraction&)>& footprint) {
  // A time limit may stop an iteration before its first camera sample: nothing to splat into.
  if (!active_ || samples.sample_end <= samples.sample_begin || samples.rendered == 0) return;
  auto t0 = std::chrono::steady_clock::now();
  if (!scratch_) {
    scratch_ = std::make_unique<Scratch>();
    scratch_->caster_boxes = find_caster_boxes(scene_, casting_);
    scratch_->sphere_emitters = Pass::find_sphere_emitters(*this, scratch_->caster_boxes);
  }
  Pass pass(*this, *scratch_, film, samples, footprint);
  pass.trace_all();
  stats_.paths += pass.total;
  stats_.caster_hits += pass.caster_hits.load();
  stats_.receiver_hits += pass.receiver_hits.load();
  stats_.splats += pass.splats.load();
  stats_.dropped += pass.dropped.load();
  stats_.seconds += seconds_since(t0);
  ++passes_;
  if (options_.may_switch_off && stats_.paths >= kCausticDecisionPaths &&
      double(stats_.splats) < kCausticMinSplatRate * double(stats_.paths))
    stats_.switched_off_after = passes_;
}

}  // namespace theia
