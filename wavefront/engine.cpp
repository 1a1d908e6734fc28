#include "wavefront/engine.h"

#include "core/sampler.h"
#include "scene/bsdf.h"
#include "scene/mipmap.h"
#include "wavefront/path_state.h"
#include "wavefront/radix_sort.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <array>
#include <chrono>

namespace theia {

namespace {

// Sample dimensions: the camera uses 0..3; bounce d uses kBounceBase + 8 d onwards.
constexpr uint32_t kDimFilm = 0, kDimLens = 2, kBounceBase = 4, kDimsPerBounce = 8;
constexpr uint32_t kDimLightPoint = 0, kDimLightChoice = 2, kDimLightPrim = 3, kDimBsdfDir = 4, kDimBsdfLobe = 6,
                   kDimRoulette = 7;

constexpr size_t kTraceGrain = 256;
constexpr size_t kShadeGrain = 64;
constexpr size_t kPrefetchDistance = 8;

// A queued batch of rays, as a structure of arrays so tracing reads only rays.
struct Batch {
  std::vector<Ray> rays;
  std::vector<uint32_t> paths;  // path-pool slot of each ray
  bool camera = false;          // camera rays are coherent: traced with Embree's COHERENT flag
  size_t size() const { return rays.size(); }
  void clear() {
    rays.clear();
    paths.clear();
    camera = false;
  }
};

struct ShadowBatch {
  std::vector<Ray> rays;
  std::vector<PrimRef> skip;      // the curve segment each ray left (only when the scene has curves)
  std::vector<RGB> contribution;  // beta * f * L * w / pdf * filter weight: what reaches the film if unoccluded
  std::vector<float> mis_weight;  // the MIS weight inside the contribution (only when observed)
  std::vector<uint32_t> pixel;
  std::vector<uint32_t> sample;   // which half buffer of the film it belongs to
  std::vector<uint32_t> vertex;
  size_t size() const { return rays.size(); }
  void clear() {
    rays.clear();
    skip.clear();
    contribution.clear();
    mis_weight.clear();
    pixel.clear();
    sample.clear();
    vertex.clear();
  }
  void append(const ShadowBatch& o) {
    rays.insert(rays.end(), o.rays.begin(), o.rays.end());
    skip.insert(skip.end(), o.skip.begin(), o.skip.end());
    contribution.insert(contribution.end(), o.contribution.begin(), o.contribution.end());
    mis_weight.insert(mis_weight.end(), o.mis_weight.begin(), o.mis_weight.end());
    pixel.insert(pixel.end(), o.pixel.begin(), o.pixel.end());
    sample.insert(sample.end(), o.sample.begin(), o.sample.end());
    vertex.insert(vertex.end(), o.vertex.begin(), o.vertex.end());
  }
};

// What one thread's shading produced, merged into the queues after the stage.
struct ShadeOutput {
  Batch rays;
  ShadowBatch shadows;
  std::vector<uint32_t> freed;
  uint64_t vertices = 0;
};

int direction_bin(const vec3& d) {
  vec3 a = glm::abs(d);
  int axis = a.x >= a.y ? (a.x >= a.z ? 0 : 2) : (a.y >= a.z ? 1 : 2);
  return 2 * axis + (d[axis] < 0.0f ? 1 : 0);
}

}  // namespace

struct WavefrontEngine::Impl {
  const Scene& scene;
  const Accel& accel;
  const LightSet& lights;
  const LightSampler& light_sampler;
  const Camera& camera;
  const Filter& filter;
  Film& film;
  EngineOptions opt;
  PathObserver* observer;
  CausticTracer* caustics = nullptr;  // opt.caustics when active and usable in this engine

  PathStatePool pool;
  // Per path slot, the curve segment its queued ray left; allocated only
  // when the scene has curves (scene/accel.h: the skips beside rays).
  std::vector<PrimRef> path_skip;
  std::vector<PrimRef> batch_skips;  // path_skip gathered in a batch's ray order
  std::array<Batch, 6> filling;     // the batch being filled, per direction bin
  std::vector<Batch> full;          // filled batches, processed last-in first-out
  std::vector<Batch> spare;         // emptied batches, reused to keep allocations flat
  ShadowBatch shadows;
  size_t queued_rays = 0;

  std::vector<SortPair> keys, scratch;
  std::vector<Hit> hits;
  Batch sorted;                     // scratch batch for gathering in sorted order
  tbb::enumerable_thread_specific<ShadeOutput> outputs;

  vec3 bounds_min{0.0f}, bounds_inv_extent{1.0f};
  EngineStats stats;
  // Texture footprints cost a transform per hit: only when a texture filters
  // (MIP-mapped images, pbrt-v4's box-filtered 2D checkerboard) or a material
  // is bump mapped.
  bool uses_footprint = false;
  float footprint_scale = 1.0f;

  uint64_t next_camera = 0, camera_end = 0;
  uint32_t sample_begin = 0, sample_count = 0;
  const SampleRanges* ranges = nullptr;  // per-pixel samples instead of [sample_begin, + sample_count)

  Impl(const Scene& s, const Accel& a, const LightSet& l, const LightSampler& ls, const Camera& c, const Filter& f,
       Film& fi, const EngineOptions& o, PathObserver* obs)
      : scene(s), accel(a), lights(l), light_sampler(ls), camera(c), filter(f), film(fi), opt(o), observer(obs),
        pool(std::max<size_t>(o.max_paths, 1)) {
    if (!s.curves.empty()) path_skip.resize(std::max<size_t>(o.max_paths, 1));
    Bounds3 b = accel.bounds();
    if (b.min.x <= b.max.x) {
      bounds_min = b.min;
      vec3 ext = glm::max(b.max - b.min, vec3(1e-30f));
      bounds_inv_extent = 1.0f / ext;
    }
    opt.batch_size = std::max<size_t>(opt.batch_size, 1);
    for (const Texture& t : scene.textures)
      uses_footprint |= (t.kind == TextureKind::ImageMap && filter_uses_mipmap(t.filter)) ||
                        (t.kind == TextureKind::Checkerboard && t.mapping_kind != TextureMappingKind::Point3D);
    // Bump mapping takes its finite-difference offsets from the footprint too.
    for (const Material& m : scene.materials) uses_footprint |= m.displacement >= 0;
    footprint_scale = footprint_spp_scale(opt.footprint_spp);
  }

  UVFootprint footprint(const SurfaceInteraction& si) const {
    return uses_footprint ? texture_footprint(camera, si, footprint_scale) : UVFootprint{};
  }

  bool counts_for_alpha(uint32_t sample) const { return opt.alpha_spp == 0 || sample < opt.alpha_spp; }

  float sample1(uint32_t pixel, uint32_t sample, uint32_t dim) const {
    return sample_1d(SamplerKey{opt.seed, pixel, sample}, dim);
  }
  vec2 sample2(uint32_t pixel, uint32_t sample, uint32_t dim) const {
    return sample_2d(SamplerKey{opt.seed, pixel, sample}, dim);
  }

  Batch take_spare() {
    if (spare.empty()) return Batch{};
    Batch b = std::move(spare.back());
    spare.pop_back();
    b.clear();
    return b;
  }

  void enqueue(const Ray& ray, uint32_t path) {
    Batch& b = filling[direction_bin(ray.d)];
    b.rays.push_back(ray);
    b.paths.push_back(path);
    ++queued_rays;
    if (b.size() >= opt.batch_size) {
      full.push_back(std::move(b));
      b = take_spare();
    }
  }

  // ---------------------------------------------------------------- generate

  void generate_camera_rays(size_t count) {
    ScopedTimer timer(stats.phases[Phase::Generate]);
    count = std::min<uint64_t>({count, camera_end - next_camera, pool.free_slots.size()});
    if (count == 0) return;
    std::vector<uint32_t> slots(pool.free_slots.end() - count, pool.free_slots.end());
    pool.free_slots.resize(pool.free_slots.size() - count);

    Batch all = take_spare();
    all.camera = true;
    all.rays.resize(count);
    all.paths = slots;
    const uint64_t first = next_camera;
    const int width = film.width;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 1024), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i < r.end(); ++i) {
        uint64_t g = first + i;
        uint32_t pixel, sample;
        bool alpha_only = false;
        if (ranges) {
          auto it = std::upper_bound(ranges->offset.begin(), ranges->offset.end(), g);
          pixel = uint32_t(it - ranges->offset.begin()) - 1;
          sample = ranges->begin[pixel] + uint32_t(g - ranges->offset[pixel]);
          alpha_only = sample >= ranges->colour_end[pixel];
        } else {
          pixel = uint32_t(g / sample_count);
          sample = sample_begin + uint32_t(g % sample_count);
        }
        int x = int(pixel % uint32_t(width)), y = int(pixel / uint32_t(width));
        FilterSample fs = sample_filter(filter, sample2(pixel, sample, kDimFilm));
        vec2 p_film(float(x) + 0.5f + fs.p.x, float(y) + 0.5f + fs.p.y);
        auto cam = generate_camera_ray(camera, p_film, sample2(pixel, sample, kDimLens));
        Ray ray;
        ray.o = cam.o;
        ray.d = cam.d;
        if (!alpha_only) film.add_weight(pixel, sample, fs.weight);
        if (counts_for_alpha(sample)) film.add_alpha_weight(pixel, fs.weight);
        PathState& ps = pool[slots[i]];
        ps.beta = RGB(1.0f);
        ps.prev_p = ray.o;
        ps.prev_ng = vec3(0.0f);
        ps.pixel = pixel;
        ps.sample = sample;
        ps.vertex = observer ? observer->path_started(pixel, sample) : kNoVertex;
        ps.filter_weight = fs.weight;
        ps.prev_pdf = 0.0f;
        ps.depth = 0;
        ps.flags = kPathPrevSpecular;
        ps.alpha_only = alpha_only ? 1 : 0;
        ps.eta_scale = 1.0f;
        if (!path_skip.empty()) path_skip[slots[i]] = PrimRef{};
        all.rays[i] = ray;
      }
    });
    next_camera += count;
    stats.camera_rays += count;
    stats.paths += count;
    queued_rays += count;

    // Split into batches; push the last first so the first pixels are traced first.
    size_t n_batches = (count + opt.batch_size - 1) / opt.batch_size;
    for (size_t k = n_batches; k-- > 0;) {
      size_t lo = k * opt.batch_size, hi = std::min(count, lo + opt.batch_size);
      Batch b = take_spare();
      b.camera = true;
      b.rays.assign(all.rays.begin() + lo, all.rays.begin() + hi);
      b.paths.assign(all.paths.begin() + lo, all.paths.begin() + hi);
      full.push_back(std::move(b));
    }
    spare.push_back(std::move(all));
    stats.peak_live_paths = std::max(stats.peak_live_paths, pool.live());
  }

  // ---------------------------------------------------------------- sort

  uint64_t ray_sort_key(const Ray& r) const {
    vec3 o = (r.o - bounds_min) * bounds_inv_extent;
    uint64_t m = morton3(o.x, o.y, o.z);
    // Direction: 4 bits per component (the bin already fixes the dominant axis);
    // cheap, and fine enough to group rays that will walk the same BVH nodes.
    vec3 d = glm::normalize(r.d);
    auto q = [](float c) { return uint64_t(std::clamp((c * 0.5f + 0.5f) * 16.0f, 0.0f, 15.0f)); };
    return (m << 12) | (q(d.x) << 8) | (q(d.y) << 4) | q(d.z);
  }

  void sort_batch(Batch& b) {
    ScopedTimer timer(stats.phases[Phase::Sort]);
    const size_t n = b.size();
    keys.resize(n);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i < r.end(); ++i) keys[i] = SortPair{ray_sort_key(b.rays[i]), uint32_t(i)};
    });
    radix_sort(keys, scratch, 42);
    sorted.clear();
    sorted.camera = b.camera;
    sorted.rays.resize(n);
    sorted.paths.resize(n);
    for (size_t i = 0; i < n; ++i) {
      sorted.rays[i] = b.rays[keys[i].index];
      sorted.paths[i] = b.paths[keys[i].index];
    }
    std::swap(sorted, b);
  }

  // ---------------------------------------------------------------- trace + shade

  void process_batch(Batch& b) {
    const size_t n = b.size();
    queued_rays -= n;
    ++stats.batches;
    if (!b.camera) stats.continuation_rays += n;
    if (opt.sort && !b.camera) sort_batch(b);

    if (opt.capture_rays) opt.capture_rays->insert(opt.capture_rays->end(), b.rays.begin(), b.rays.end());
    hits.resize(n);
    batch_skips.clear();
    if (!path_skip.empty())
      for (uint32_t slot : b.paths) batch_skips.push_back(path_skip[slot]);
    {
      ScopedTimer timer(stats.phases[Phase::Trace]);
      tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kTraceGrain), [&](const tbb::blocked_range<size_t>& r) {
        std::span<const PrimRef> skips;
        if (!batch_skips.empty()) skips = std::span<const PrimRef>(batch_skips.data() + r.begin(), r.size());
        accel.intersect(std::span<const Ray>(b.rays.data() + r.begin(), r.size()),
                        std::span<Hit>(hits.data() + r.begin(), r.size()), b.camera, skips);
      });
    }

    // Shade in (geometry, primitive) order so that neighbouring work shares
    // meshes, materials and textures; misses sort last.
    keys.resize(n);
    {
      ScopedTimer timer(stats.phases[Phase::Sort]);
      for (size_t i = 0; i < n; ++i) {
        const Hit& h = hits[i];
        uint64_t key = h.geom == kInvalidId
                           ? ~uint64_t(0)
                           : (uint64_t(h.inst + 1) << 48) | (uint64_t(h.geom & 0xffff) << 32) | h.prim;
        keys[i] = SortPair{key, uint32_t(i)};
      }
      if (opt.sort) radix_sort(keys, scratch, 64);
    }

    {
      ScopedTimer timer(stats.phases[Phase::Shade]);
      tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kShadeGrain), [&](const tbb::blocked_range<size_t>& r) {
        ShadeOutput& out = outputs.local();
        for (size_t k = r.begin(); k < r.end(); ++k) {
          // Hits arrive in (geometry, primitive) order, which scatters their
          // rays and path records: fetch a few iterations ahead.
          if (k + kPrefetchDistance < n) {
            uint32_t j = keys[k + kPrefetchDistance].index;
            __builtin_prefetch(&b.rays[j]);
            __builtin_prefetch(&hits[j]);
            __builtin_prefetch(&pool[b.paths[j]]);
          }
          uint32_t i = keys[k].index;
          if (observer)
            shade<true>(b.rays[i], hits[i], b.paths[i], out);
          else
            shade<false>(b.rays[i], hits[i], b.paths[i], out);
        }
      });
    }
    merge_outputs();
  }

  void merge_outputs() {
    ScopedTimer timer(stats.phases[Phase::Queue]);
    for (ShadeOutput& out : outputs) {
      for (size_t i = 0; i < out.rays.size(); ++i) enqueue(out.rays.rays[i], out.rays.paths[i]);
      shadows.append(out.shadows);
      pool.free_slots.insert(pool.free_slots.end(), out.freed.begin(), out.freed.end());
      stats.path_vertices += out.vertices;
      out.rays.clear();
      out.shadows.clear();
      out.freed.clear();
      out.vertices = 0;
    }
    stats.peak_queued_rays = std::max(stats.peak_queued_rays, queued_rays);
    stats.peak_queued_shadow_rays = std::max(stats.peak_queued_shadow_rays, shadows.size());
  }

  template <bool kObserve>
  void finish_path(uint32_t slot, ShadeOutput& out) {
    if constexpr (kObserve) observer->vertex_done(pool[slot].vertex);
    out.freed.push_back(slot);
  }

  template <bool kObserve>
  void shade(const Ray& ray, const Hit& hit, uint32_t slot, ShadeOutput& out) {
    PathState& ps = pool[slot];
    const uint32_t pixel = ps.pixel, sample = ps.sample, depth = ps.depth;
    const float fw = ps.filter_weight;
    RGB beta = ps.beta;
    const bool prev_specular = (ps.flags & kPathPrevSpecular) != 0;
    // Emission after a receiver and a caster, from a light the caustic pass
    // traces, is that pass's to count (wavefront/caustics.h).
    const bool caustic_suffix = (ps.flags & kPathCausticCaster) != 0;
    LightSampleContext prev_ctx{ps.prev_p, vec3(0.0f), ps.prev_ng, ps.prev_ng};
    // Throughput-reset image (recorder debug, bounce N): only light arriving
    // at vertices of depth >= N reaches the film, with the throughput set to
    // 1 at hit N.  Emission found at hit d arrives at the vertex of depth d-1.
    const int reset_depth = opt.throughput_reset_bounce;
    const bool splat_emission = reset_depth < 0 || int(depth) > reset_depth;

    // Escaped: infinite lights, MIS-weighted against light sampling.
    if (hit.geom == kInvalidId && ps.alpha_only) {
      finish_path<kObserve>(slot, out);
      return;
    }
    if (hit.geom == kInvalidId) {
      vec3 d = glm::normalize(ray.d);
      for (int l : lights.infinite_lights) {
        RGB Le = infinite_light_Le(lights, l, d);
        if (is_black(Le)) continue;
        float w = 1.0f;
        if (!prev_specular) {
          float light_pdf = light_sampler.pmf(prev_ctx, l) * infinite_light_pdf(lights, l, d);
          w = power_heuristic(1, ps.prev_pdf, 1, light_pdf);
        }
        RGB contribution = fw * beta * w * Le;
        if (splat_emission) film.splat(pixel, sample, contribution);
        if constexpr (kObserve) observer->emission_added(ps.vertex, pixel, contribution, w);
      }
      finish_path<kObserve>(slot, out);
      return;
    }

    SurfaceInteraction si = compute_interaction(scene, accel, ray, hit);
    const vec3 wo = si.wo;
    // A holdout matte blocks the ray and adds neither colour nor alpha.
    if (si.shape >= 0 && scene.shapes[size_t(si.shape)].holdout) {
      finish_path<kObserve>(slot, out);
      return;
    }
    if (ps.alpha_only) {
      film.splat_first_hit(pixel, fw, true, bsdf_albedo(make_bsdf(scene, si, footprint(si))), si.ns, si.t);
      finish_path<kObserve>(slot, out);
      return;
    }

    // Emission found by the BSDF-sampled ray.
    if (si.area_light >= 0 && !(caustic_suffix && caustics->traces_light(si.area_light))) {
      const Light& light = scene.lights[si.area_light];
      RGB Le = area_light_L(lights, si.area_light, si, wo);
      if (!is_black(Le)) {
        float w = 1.0f;
        if (!prev_specular) {
          float light_pdf = light_sampler.pmf(prev_ctx, si.area_light) *
                            area_light_pdf(lights, si.area_light, prev_ctx, glm::normalize(ray.d), si);
          w = power_heuristic(1, ps.prev_pdf, 1, light_pdf);
        }
        RGB contribution = fw * beta * w * Le;
        if (splat_emission) film.splat(pixel, sample, contribution);
        if constexpr (kObserve) observer->emission_added(ps.vertex, pixel, contribution, w);
      }
      // A virtual light emits but does not block: the same ray goes on from
      // the far side (re-traced; shadow rays skip it with an Embree filter).
      if (light.is_virtual) {
        if constexpr (kObserve) {
          observer->vertex_continued(ps.vertex);
          observer->vertex_done(ps.vertex);
        }
        out.rays.rays.push_back(spawn_ray(si, ray.d));
        out.rays.paths.push_back(slot);
        if (!path_skip.empty()) path_skip[slot] = si.skip;
        return;
      }
    }
    ++out.vertices;

    BSDF bsdf = make_bsdf(scene, si, footprint(si));
    // An "interface" surface: continue the ray as it was, without a bounce.
    if (bsdf_is_passthrough(bsdf)) {
      out.rays.rays.push_back(spawn_ray(si, -wo));
      out.rays.paths.push_back(slot);
      if (!path_skip.empty()) path_skip[slot] = si.skip;
      return;
    }
    const vec3 ns = bsdf.shading.n;  // bump- or normal-mapped
    if (depth == 0 && counts_for_alpha(sample)) film.splat_first_hit(pixel, fw, true, bsdf_albedo(bsdf), ns, si.t);

    if (int(depth) >= opt.max_depth) {
      finish_path<kObserve>(slot, out);
      return;
    }

    const uint32_t dim = kBounceBase + kDimsPerBounce * depth;
    if (int(depth) == reset_depth) beta = RGB(1.0f);

    // Directly seen caustics: a receiver at the primary hit and a caster
    // right after it hand the caster's light from the traced lights to the
    // caustic pass, by NEE here and by emission at the next hit.
    uint8_t caustic_flags = 0;
    if (caustics) {
      if (depth == 0 && bsdf_is_caustic_receiver(bsdf)) caustic_flags = kPathCausticReceiver;
      else if (depth == 1 && (ps.flags & kPathCausticReceiver) &&
               bsdf_is_caustic_caster(bsdf, caustics->caster_roughness()))
        caustic_flags = kPathCausticCaster;
    }

    // The guide's region, where this vertex samples directions from the
    // mixture of guide and BSDF; every pdf MIS needs at this vertex is then
    // the mixture's.
    const uint32_t region =
        opt.guide && bsdf_is_guidable(bsdf, opt.guiding_min_roughness) ? opt.guide->region(si.p) : kNoGuideRegion;
    const float guide_fraction = region != kNoGuideRegion ? opt.guide->selection_probability(region) : 0.0f;
    auto scattering_pdf = [&](const vec3& wi) {
      float p = bsdf_pdf(bsdf, wo, wi);
      if (guide_fraction > 0.0f) p = guide_fraction * opt.guide->pdf(region, wi) + (1.0f - guide_fraction) * p;
      return p;
    };

    // Next-event estimation: queue a shadow ray carrying its unoccluded contribution.
    if (!bsdf_is_specular(bsdf) && int(depth) >= reset_depth) {
      LightSampleContext ctx{si.p, si.p_error, si.ng, ns};
      if (auto sl = light_sampler.sample(ctx, sample1(pixel, sample, dim + kDimLightChoice))) {
        auto ls = caustic_flags == kPathCausticCaster && caustics->traces_light(sl->light)
                      ? std::nullopt
                      : sample_li(lights, sl->light, ctx, sample2(pixel, sample, dim + kDimLightPoint),
                                  sample1(pixel, sample, dim + kDimLightPrim));
        // pdf guard: the product of selection and sampling pdfs can underflow
        // to 0 (a light of 1e-3 beside one of 1e9); such a sample is dropped, never divided by.
        const float light_pdf = ls ? sl->pmf * ls->pdf : 0.0f;
        if (ls && light_pdf > 0.0f && std::isfinite(light_pdf)) {
          RGB f = bsdf_f(bsdf, wo, ls->wi) * std::abs(glm::dot(ls->wi, ns));
          if (!is_black(f)) {
            float w = ls->is_delta ? 1.0f : power_heuristic(1, light_pdf, 1, scattering_pdf(ls->wi));
            RGB radiance = ls->L * (w / light_pdf);
            RGB contribution = fw * beta * f * radiance;
            if (is_finite(contribution) && !is_black(contribution)) {
              ShadowBatch& sb = out.shadows;
              sb.rays.push_back(spawn_ray_to(si, ls->p_light, ls->p_light_error, ls->n_light));
              if (!path_skip.empty()) sb.skip.push_back(si.skip);
              sb.contribution.push_back(contribution);
              sb.pixel.push_back(pixel);
              sb.sample.push_back(sample);
              uint32_t v = kNoVertex;
              if constexpr (kObserve) {
                sb.mis_weight.push_back(w);
                PathVertexInfo info;
                info.p = si.p;
                info.n = ns;
                info.wi = ls->wi;
                info.prefix = fw * beta;
                info.local = f / light_pdf;
                info.pdf = light_pdf;
                info.camera_weight = fw;
                info.pixel = pixel;
                info.sample = sample;
                info.depth = int(depth);
                info.is_nee = true;
                info.delta_light = ls->is_delta;
                v = observer->vertex_created(ps.vertex, info);
              }
              sb.vertex.push_back(v);
            }
          }
        }
      }
    }

    // Continue the path by sampling the BSDF, or the guide's mixture with it.
    // The mixture splits the lobe-choice dimension, so that an unguided
    // render draws exactly the numbers it drew before guiding existed.
    const float u_lobe = sample1(pixel, sample, dim + kDimBsdfLobe);
    const vec2 u_dir = sample2(pixel, sample, dim + kDimBsdfDir);
    std::optional<BSDFSample> bs;
    if (guide_fraction <= 0.0f) {
      bs = bsdf_sample(bsdf, wo, u_lobe, u_dir);
    } else {
      float guide_pdf = 0.0f;
      if (u_lobe < guide_fraction) {
        // A direction the guide reports a zero density for (rounding at a
        // quad's edge) cannot be weighted: the path ends, as for pdf 0 below.
        GuideSample gs = opt.guide->sample(region, u_dir);
        guide_pdf = gs.pdf;
        if (gs.pdf > 0.0f) bs = bsdf_event(bsdf, wo, gs.wi);
      } else {
        bs = bsdf_sample(bsdf, wo, std::min((u_lobe - guide_fraction) / (1.0f - guide_fraction), kOneMinusEpsilon), u_dir);
        if (bs) guide_pdf = opt.guide->pdf(region, bs->wi);
      }
      if (bs) bs->pdf = guide_fraction * guide_pdf + (1.0f - guide_fraction) * bs->pdf;
    }
    // pdf guard: a direction with pdf 0 (or NaN) ends the path instead of dividing by it.
    if (!bs || !(bs->pdf > 0.0f)) {
      finish_path<kObserve>(slot, out);
      return;
    }
    [[maybe_unused]] const RGB beta_in = beta;
    RGB local = bs->f * (std::abs(glm::dot(bs->wi, ns)) / bs->pdf);
    beta *= local;
    // Radiance refracted into a denser medium is scaled by 1/eta^2; roulette
    // undoes that scale so that it does not kill paths inside glass.
    float eta_scale = ps.eta_scale;
    if (bs->is_transmission()) eta_scale *= sqr(bs->eta);
    uint32_t next_depth = depth + 1;
    // Russian roulette on the throughput, as pbrt-v4 does it.
    if (int(next_depth) > opt.rr_min_depth) {
      float rr = max_component(beta * eta_scale);
      if (rr < 1.0f) {
        float q = std::max(0.0f, 1.0f - rr);
        if (sample1(pixel, sample, dim + kDimRoulette) < q) {
          finish_path<kObserve>(slot, out);
          return;
        }
        beta /= 1.0f - q;
        local /= 1.0f - q;
      }
    }
    if (!is_finite(beta) || is_black(beta)) {
      finish_path<kObserve>(slot, out);
      return;
    }
    if constexpr (kObserve) {
      PathVertexInfo info;
      info.p = si.p;
      info.n = ns;
      info.wi = bs->wi;
      info.prefix = fw * beta_in;
      info.local = local;
      info.pdf = bs->pdf;
      info.camera_weight = fw;
      info.pixel = pixel;
      info.sample = sample;
      info.depth = int(depth);
      info.lobe_flags = bs->flags;
      info.roughness = bs->roughness;
      uint32_t child = observer->vertex_created(ps.vertex, info);
      observer->vertex_done(ps.vertex);
      ps.vertex = child;
    }
    ps.beta = beta;
    ps.depth = uint16_t(next_depth);
    ps.prev_pdf = bs->pdf;
    ps.eta_scale = eta_scale;
    ps.flags = uint8_t((bs->is_specular() ? kPathPrevSpecular : 0) | caustic_flags);
    ps.prev_p = si.p;
    ps.prev_ng = si.ng;
    out.rays.rays.push_back(spawn_ray(si, bs->wi));
    out.rays.paths.push_back(slot);
    if (!path_skip.empty()) path_skip[slot] = si.skip;
  }

  // ---------------------------------------------------------------- shadow rays

  void trace_shadows() {
    const size_t n = shadows.size();
    if (n == 0) return;
    ++stats.shadow_batches;
    stats.shadow_rays += n;
    ShadowBatch& s = shadows;
    std::vector<uint32_t> order;
    if (opt.sort) {
      ScopedTimer timer(stats.phases[Phase::Sort]);
      keys.resize(n);
      tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end(); ++i) keys[i] = SortPair{ray_sort_key(s.rays[i]), uint32_t(i)};
      });
      radix_sort(keys, scratch, 42);
      std::vector<Ray> rays(n);
      for (size_t i = 0; i < n; ++i) rays[i] = s.rays[keys[i].index];
      s.rays.swap(rays);
      if (!s.skip.empty()) {
        std::vector<PrimRef> skip(n);
        for (size_t i = 0; i < n; ++i) skip[i] = s.skip[keys[i].index];
        s.skip.swap(skip);
      }
      order.resize(n);
      for (size_t i = 0; i < n; ++i) order[i] = keys[i].index;
    }
    if (opt.capture_shadow_rays)
      opt.capture_shadow_rays->insert(opt.capture_shadow_rays->end(), s.rays.begin(), s.rays.end());
    std::vector<uint8_t> blocked(n);
    {
      ScopedTimer timer(stats.phases[Phase::TraceShadow]);
      tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kTraceGrain), [&](const tbb::blocked_range<size_t>& r) {
        std::span<const PrimRef> skips;
        if (!s.skip.empty()) skips = std::span<const PrimRef>(s.skip.data() + r.begin(), r.size());
        accel.occluded(std::span<const Ray>(s.rays.data() + r.begin(), r.size()),
                       std::span<uint8_t>(blocked.data() + r.begin(), r.size()), skips);
      });
    }
    {
      ScopedTimer timer(stats.phases[Phase::Shade]);
      tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1024), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t k = r.begin(); k < r.end(); ++k) {
          size_t i = order.empty() ? k : order[k];
          if (!blocked[k]) film.splat(s.pixel[i], s.sample[i], s.contribution[i]);
          if (observer) {
            // An occluded NEE ray still finishes its vertex: a zero sample.
            if (!blocked[k]) observer->emission_added(s.vertex[i], s.pixel[i], s.contribution[i], s.mis_weight[i]);
            observer->vertex_done(s.vertex[i]);
          }
        }
      });
    }
    s.clear();
  }

  // ---------------------------------------------------------------- the loop

  uint64_t render(uint32_t s_begin, uint32_t s_end, uint64_t first_camera, const std::function<void(double)>& progress) {
    auto t0 = std::chrono::steady_clock::now();
    sample_begin = s_begin;
    sample_count = s_end > s_begin ? s_end - s_begin : 0;
    // Per iteration: the caustic pass may have switched itself off after the last one.
    // Below depth 2 no camera path reaches a light through a caster, so there is nothing to hand over.
    caustics = opt.caustics && opt.caustics->active() && opt.throughput_reset_bounce < 0 && !ranges && opt.max_depth >= 2
                   ? opt.caustics
                   : nullptr;
    camera_end = ranges ? ranges->total() : uint64_t(film.pixel_count()) * sample_count;
    next_camera = std::min(first_camera, camera_end);
    // Once stopped, no camera ray is generated: the paths in flight finish,
    // so exactly the pixel-samples [first_camera, next_camera) are complete.
    auto stopped = [&] { return opt.stop && opt.stop->load(std::memory_order_relaxed); };
    const size_t capacity = pool.capacity();
    const size_t refill_below = size_t(opt.occupancy_threshold * float(capacity));

    auto report = [&] {
      if (progress) progress(camera_end ? double(next_camera) / double(camera_end) : 1.0);
    };
    while (true) {
      if (pool.live() <= refill_below && next_camera < camera_end && !stopped()) {
        generate_camera_rays(capacity - pool.live());
        report();
      }
      if (shadows.size() >= opt.batch_size) trace_shadows();
      if (!full.empty()) {
        Batch b = std::move(full.back());
        full.pop_back();
        process_batch(b);
        spare.push_back(std::move(b));
        continue;
      }
      if (next_camera < camera_end && !pool.free_slots.empty() && !stopped()) {
        generate_camera_rays(capacity - pool.live());
        report();
        continue;
      }
      // Nothing full and nothing left to generate: flush the fullest partial batch.
      Batch* fullest = nullptr;
      for (Batch& b : filling)
        if (b.size() > 0 && (!fullest || b.size() > fullest->size())) fullest = &b;
      if (fullest) {
        Batch b = std::move(*fullest);
        *fullest = take_spare();
        process_batch(b);
        spare.push_back(std::move(b));
        continue;
      }
      if (shadows.size() > 0) {
        trace_shadows();
        continue;
      }
      break;
    }
    // The iteration's camera samples are all in: the caustic pass adds its
    // estimate for the same samples (an interrupted iteration runs it when resumed).
    if (caustics && next_camera == camera_end) {
      ScopedTimer timer(stats.phases[Phase::Caustics]);
      caustics->trace(film, sample_begin, sample_begin + sample_count,
                      [this](const SurfaceInteraction& si) { return footprint(si); });
    }
    report();
    stats.render_seconds += seconds_since(t0);
    return next_camera;
  }

  size_t memory_bytes() const {
    size_t ray_bytes = sizeof(Ray) + sizeof(uint32_t);
    size_t shadow_bytes = sizeof(Ray) + sizeof(RGB) + 2 * sizeof(uint32_t) + (observer ? sizeof(float) : 0);
    return pool.memory_bytes() + stats.peak_queued_rays * ray_bytes +
           stats.peak_queued_shadow_rays * shadow_bytes;
  }
};

RenderableScene::RenderableScene(const Scene& s, const std::string& sampler_name)
    : scene(s),
      accel(s),
      lights(s, accel),
      light_sampler(make_light_sampler(sampler_name, lights)),
      camera(make_camera(s.camera, s.film)),
      filter(make_filter(s.filter)) {}

WavefrontEngine::WavefrontEngine(const Scene& scene, const Accel& accel, const LightSet& lights,
                                 const LightSampler& light_sampler, const Camera& camera, const Filter& filter,
                                 Film& film, const EngineOptions& options, PathObserver* observer)
    : impl_(new Impl(scene, accel, lights, light_sampler, camera, filter, film, options, observer)) {}

WavefrontEngine::~WavefrontEngine() { delete impl_; }

uint64_t WavefrontEngine::render(uint32_t sample_begin, uint32_t sample_end, const std::function<void(double)>& progress,
                                 uint64_t first_camera_sample) {
  impl_->ranges = nullptr;
  return impl_->render(sample_begin, sample_end, first_camera_sample, progress);
}

uint64_t WavefrontEngine::render(const SampleRanges& ranges, const std::function<void(double)>& progress,
                                 uint64_t first_camera_sample) {
  impl_->ranges = &ranges;
  uint64_t done = impl_->render(0, 0, first_camera_sample, progress);
  impl_->ranges = nullptr;
  return done;
}

const EngineStats& WavefrontEngine::stats() const { return impl_->stats; }
size_t WavefrontEngine::memory_bytes() const { return impl_->memory_bytes(); }

}  // namespace theia
