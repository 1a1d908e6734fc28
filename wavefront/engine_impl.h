// The engine's state and its stages, shared by the stage files of wavefront/
// (private to the folder: nothing outside includes it).
//
//   engine.cpp        the loop, batches, sorting, tracing closest hits
//   camera_rays.cpp   generate camera rays
//   escaped_rays.cpp  rays that left the scene: infinite lights
//   surface.cpp       shade surface hits (emission, pass-through, NEE, continuation, roulette)
//   shadow_rays.cpp   trace shadow rays and splat the unoccluded ones
//   media.cpp         medium interactions (free flight, in-medium vertices) and
//                     shadow-ray transmittance; only in scenes with media
#pragma once

#include "core/radix_sort.h"
#include "core/sampler.h"
#include "scene/bsdf.h"
#include "scene/media.h"
#include "wavefront/engine.h"
#include "wavefront/guided_phase.h"
#include "wavefront/guided_sampling.h"
#include "wavefront/path_state.h"
#include "wavefront/queues.h"
#include "wavefront/sample_dims.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <array>
#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <optional>

namespace theia {

struct PixelSample;  // camera_samples.h

// A batch of rays of one direction bin; camera rays are coherent (traced in
// Embree's ray packets).
struct Batch : RayQueue {
  bool camera = false;
};

// Continuation rays are batched by the axis and sign of their direction's
// largest component: rays of one bin walk the BVH alike.  Without branches:
// scattered directions make each comparison a coin flip.
inline constexpr size_t kDirectionBins = 6;
inline int direction_bin(const vec3& d) {
  const vec3 a = glm::abs(d);
  const bool x = (a.x >= a.y) & (a.x >= a.z), y = !(a.x >= a.y) & (a.y >= a.z);  // else z
  const bool negative = (x & (d.x < 0.0f)) | (y & (d.y < 0.0f)) | (!x & !y & (d.z < 0.0f));
  return 2 * (2 - 2 * int(x) - int(y)) + int(negative);
}

// Triangle data larger than a core's L2 cache (2 MiB on the EPYC this was
// measured on): beyond it shading waits on memory for neighbouring hits
// (scene/shapes.h TrianglePrefetcher).
inline constexpr size_t kPrefetchTrianglesAbove = size_t(2) << 20;

// What one thread's shading produced, merged into the queues after the stage.
struct ShadeOutput {
  // Continuation rays, already in their direction bins: the serial merge
  // after each batch (the other thread waits on it) is then a bulk copy per
  // bin, not a pass over every ray.
  std::array<RayQueue, kDirectionBins> rays;
  ShadowQueue shadows;
  std::vector<uint32_t> freed;
  uint64_t vertices = 0;
  // Rays the medium stage traced itself past an interface (continuation
  // rays that never enter a batch), and with EngineOptions::capture_rays the
  // rays themselves, so that the ray counts and the capture include them.
  uint64_t retraced = 0;
  std::vector<Ray> retraced_rays;
};

// A surface hit's continuation numbers, drawn a chunk of hits ahead
// (draw_continuations): bsdf_dir, bsdf_lobe and roulette (sample_dims.h),
// and bsdf_dir's cosine-weighted direction, which a diffuse BSDF takes
// (made ahead too: its division, polynomial and square root were on each
// hit's chain of dependent steps).
struct ContinuationDraw {
  vec4 u{0.0f};
  vec3 cosine{0.0f};  // sample_cosine_hemisphere(vec2(u))
};

// One surface vertex while it is shaded: what its steps share.
struct ShadingPoint {
  PathState& ps;
  uint32_t slot;
  const SurfaceInteraction& si;
  BSDF bsdf;
  const ContinuationDraw& draw;  // the continuation's numbers, drawn ahead
  vec3 ns{0.0f};                 // bump- or normal-mapped shading normal
  RGB beta{0.0f};                // throughput before this vertex (reset to 1 at the throughput-reset bounce)
  BounceDims dims{};
  uint8_t caustic_flags = 0;  // kPathCausticReceiver / kPathCausticCaster at this vertex
  bool guidable = false;      // bsdf_is_guidable: the engine guides here when it has a guide
  uint32_t guide_region = kNoGuideRegion;  // != kNoGuideRegion: the vertex is guided
  float guide_fraction = 0.0f;             // one-sample MIS: the guide's selection probability
  bool guided() const { return guide_region != kNoGuideRegion; }
};

// The PathEvent of a surface event from its lobe flags (BSDFSample::flags).
inline uint8_t event_of_lobe(uint8_t lobe_flags) {
  if (lobe_flags & kLobeSpecular) return kEventSpecular;
  return (lobe_flags & kLobeGlossy) ? kEventGlossy : kEventDiffuse;
}

// What a vertex, at a surface or in a medium, tells the observer about
// itself: the path's fields, the throughput `beta` before it, its direction.
inline PathVertexInfo path_vertex_info(const PathState& ps, const vec3& p, const RGB& beta, const vec3& wi,
                                       const RGB& local, float pdf) {
  PathVertexInfo info;
  info.p = p;
  info.wi = wi;
  info.prefix = ps.filter_weight * beta;
  info.local = local;
  info.pdf = pdf;
  info.camera_weight = ps.filter_weight;
  info.pixel = ps.pixel;
  info.sample = ps.sample;
  info.depth = int(ps.depth);
  return info;
}

// One medium scattering vertex while it is handled (media.cpp).
struct MediumVertex {
  PathState& ps;
  SurfaceInteraction si;  // the point and wo only: no surface
  float g = 0.0f;         // the medium's Henyey-Greenstein asymmetry
  BounceDims dims{};
  vec4 u_continuation{0.0f};  // as a surface vertex's: the phase sample's direction and roulette
  RGB beta{0.0f};         // throughput at the vertex (reset to 1 at the throughput-reset bounce)
  uint32_t guide_region = kNoGuideRegion;  // != kNoGuideRegion: the vertex is guided
  float guide_fraction = 0.0f;             // one-sample MIS: the guide's selection probability
  bool guided() const { return guide_region != kNoGuideRegion; }
};

// The ray-sorting key: origin Morton code, then a coarse direction.
uint64_t ray_sort_key(const Ray& r, const vec3& bounds_min, const vec3& bounds_inv_extent);
// `order` = the permutation that sorts `rays` by ray_sort_key (radix sort).
void sort_by_ray_key(std::span<const Ray> rays, const vec3& bounds_min, const vec3& bounds_inv_extent,
                     std::vector<SortPair>& keys, std::vector<SortPair>& scratch, std::vector<uint32_t>& order);

struct WavefrontEngine::Impl {
  const Scene& scene;
  const Accel& accel;
  const LightSet& lights;
  const LightSampler& light_sampler;
  const Camera& camera;
  const Filter& filter;
  Film& film;
  EngineOptions opt;
  EngineHooks hooks;
  PathObserver* observer;             // hooks.observer
  bool light_sampler_primitives = false;  // light_sampler.chooses_primitives(): emitter hits name their triangle
  bool light_sampler_learns = false;  // light_sampler.wants_feedback(): shadow rays carry its choice
  // NEE's light_choice pair decides nothing (sample_dims.h light_choice_fixed): not drawn.
  bool light_choice_fixed =
      theia::light_choice_fixed(scene, light_sampler.wants_feedback(), light_sampler.chooses_primitives());
  // The scene's one light, or -1: every sampler would choose it, so NEE can
  // ask whether it faces away before drawing or choosing anything.
  int sole_light = scene.lights.size() == 1 ? 0 : -1;
  // Shading fetches each hit's triangle ahead (scene/shapes.h) only where
  // the meshes outgrow the cache.
  bool prefetch_triangles = triangle_mesh_bytes(scene) > kPrefetchTrianglesAbove;
  TrianglePrefetcher triangles{scene, accel};
  CausticTracer* caustics = nullptr;  // hooks.caustics when active and usable in this iteration
  std::vector<uint8_t> sealed_media;  // scene/media.h sealed_media: NEE from their vertices is always blocked

  EngineSizes sizes;  // the pool's and batches' (engine_sizes)
  PathStatePool pool;
  std::array<Batch, kDirectionBins> filling;  // the batch being filled, per direction bin
  std::vector<Batch> full;                    // filled batches, processed last-in first-out
  std::vector<Batch> spare;                   // emptied batches, reused to keep allocations flat
  ShadowQueue shadows;
  size_t queued_rays = 0;

  // Scratch reused from batch to batch.
  std::vector<SortPair> keys, scratch;
  std::vector<uint32_t> order;
  std::vector<uint32_t> missed;  // set_aside_misses: the batch indices of the misses
  std::vector<Hit> hits;
  std::vector<PrimRef> batch_skips;  // the curve skips gathered in a batch's ray order
  // Per shadow ray while trace_shadow_rays runs; in scenes with media, per
  // ray of the batch from the trace loop (the path left the batch in a
  // medium) to shading.  Shadow rays are never traced within a batch.
  std::vector<uint8_t> blocked;
  Batch sorted;
  ShadowQueue shadows_sorted;
  EscapedQueue escaped;
  tbb::enumerable_thread_specific<ShadeOutput> outputs;

  vec3 bounds_min{0.0f}, bounds_inv_extent{1.0f};
  EngineStats stats;
  // Texture footprints cost a transform per hit: only when a texture filters
  // (MIP-mapped images, pbrt-v4's box-filtered 2D checkerboard) or a material
  // is bump mapped.
  // Per material: whether its BSDF reads the texture footprint (scene/bsdf.h);
  // only hits on those pay for one (2-3% of a render's instructions).
  std::vector<uint8_t> material_footprint;
  float footprint_scale = 1.0f;

  bool abandoned = false;  // the last render() dropped paths in flight (EngineOptions::abandon_after_seconds)
  void abandon_paths_in_flight();
  uint64_t next_camera = 0, camera_end = 0;
  // With more than one lane: the next camera sample no lane has claimed
  // (generate_camera_rays claims a run of them), shared by all.
  std::atomic<uint64_t>* camera_claims = nullptr;
  size_t lane_count = 1;
  // With more than one lane: a one-thread arena, so that the stages'
  // parallel loops run on the lane's own thread, in order, and never take
  // (or hand over) another lane's work.
  std::unique_ptr<tbb::task_arena> arena;
  // Threads a stage's loop may use: 1 with more than one lane (or one
  // thread); all of them for a render's only lane on more threads (one
  // with fewer paths than threads).
  int stage_threads = 1;
  // A stage's loop over [0, n), `body` taking tbb::blocked_range chunks of
  // about `grain`: tbb::parallel_for where the lane has threads to spare,
  // else one call over the whole range, in the order a one-thread
  // parallel_for takes the chunks, without its task set-up at every batch
  // (about 1% of the bench scene's CPU at 1024-ray batches).
  template <class Body>
  void stage_loop(size_t n, size_t grain, Body&& body) const {
    if (stage_threads > 1)
      tbb::parallel_for(tbb::blocked_range<size_t>(0, n, grain), body);
    else if (n > 0)
      body(tbb::blocked_range<size_t>(0, n, grain));
  }
  // A lane's own for EngineOptions::capture_rays and its kin.
  std::vector<Ray> captured_rays, captured_camera_rays, captured_shadow_rays;
  uint32_t sample_begin = 0, sample_count = 0;
  const SampleRanges* ranges = nullptr;  // per-pixel samples instead of [sample_begin, + sample_count)
  const std::function<void(double)>* progress = nullptr;  // render()'s (behind the lanes' lock), while it runs
  size_t refill_below = 0;  // camera rays refill the pool below this many live paths
  size_t live_cap = 0;      // at most this many live paths (the pool, or less while observed)
  size_t full_batch_size = 0;  // sizes.batch_size for the whole pool (sizes' is for live_cap)
  std::optional<std::chrono::steady_clock::time_point> signal_seen;
  std::optional<std::chrono::steady_clock::time_point> camera_deadline;  // stop_camera_samples_at

  Impl(const RenderableScene& rs, Film& film, const EngineOptions& options, const EngineHooks& hooks,
       const EngineSizes& lane);

  // ---- the loop and its stages
  void begin_iteration(uint32_t s_begin, uint32_t s_end, uint64_t first_camera, const SampleRanges* ranges,
                       std::atomic<uint64_t>* claims);
  void run();      // the lane's loop, in its arena: until the iteration is done
  bool advance();  // one turn of the loop; false once the iteration is done
  uint64_t cameras_claimed() const;
  bool can_generate() const;
  bool out_of_time();
  void generate_camera_rays_and_report();
  void report_progress() const;
  void process_and_recycle(Batch& b);
  void process_batch(Batch& b);
  void trace_caustics();                    // the caustic pass over this iteration's samples
  void generate_camera_rays(size_t count);  // camera_rays.cpp
  uint64_t claim_camera_samples(size_t& count);
  void camera_rays(std::span<const PixelSample> samples, std::span<const FilterSample> film_draws,
                   std::span<Ray> rays) const;
  void start_camera_path(uint32_t slot, const PixelSample& s, const FilterSample& fs, const vec3& origin);
  void start_camera_paths(uint64_t first, size_t begin, size_t end, std::span<const uint32_t> slots,
                          size_t first_batch);
  void cap_live_paths();                    // live_cap, sizes.batch_size and refill_below for an iteration
  void start_path(uint32_t slot, uint32_t pixel, uint32_t sample, bool alpha_only, float filter_weight,
                  const vec3& origin);
  void sort_rays(Batch& b);
  void trace_closest(Batch& b);
  void sort_hits(const Batch& b);           // with sorting: shading order into `keys`, misses into `escaped`
  void set_aside_misses(const Batch& b);    // without: the same in trace order
  void shade_batch(const Batch& b);         // escaped rays and surface hits
  // The batch index of the k-th hit to shade (sort_hits' or set_aside_misses' order).
  uint32_t hit_index(size_t k) const { return keys[k].index; }
  bool misses_only_end_paths() const;  // escaped_rays.cpp: handle_escaped does nothing else
  void prefetch_for_shading(const Batch& b, size_t k);
  void handle_escaped_ray(const Ray& ray, uint32_t slot, ShadeOutput& out);  // escaped_rays.cpp
  // Shading draws its hits' continuation numbers this many at a time (the
  // vector lanes of sample_4d's span form).
  static constexpr size_t kDrawChunk = 16;
  void draw_continuations(const Batch& b, size_t begin, size_t end, size_t n_escaped,
                          std::span<ContinuationDraw> draws) const;
  void shade_traced_ray(const Batch& b, size_t k, const ContinuationDraw& draw, ShadeOutput& out);
  void merge_outputs();
  void check_media_hooks() const;
  void trace_shadow_rays();                 // shadow_rays.cpp
  // ---- media (media.cpp): only called when the pool has the medium table
  // Rays [begin, end) of a batch just traced: free flight; scattered and
  // absorbed paths leave the batch (blocked[i] = 1).
  void handle_medium_interactions(Batch& b, size_t begin, size_t end, ShadeOutput& out);
  void end_path(uint32_t slot, ShadeOutput& out);  // finish_path, observed if there is an observer
  bool interact_in_medium(const Ray& ray, const Hit& hit, uint32_t slot, ShadeOutput& out);
  bool track_through_interfaces(Ray& ray, Hit& hit, uint32_t slot, ShadeOutput& out);
  // Whether a path's ray goes on through the surface it hit as it was: an
  // "interface" by its own material (not a mix's choice), neither a light nor
  // a holdout, in a scene with media, for a path that is not alpha-only:
  // then the shape's index, else -1.
  int passing_shape(const Hit& hit, const PathState& ps) const;
  void scatter_in_medium(const Ray& ray, const FreeFlight& ff, uint32_t slot, int medium, ShadeOutput& out);
  void sample_direct_light_in_medium(const MediumVertex& v, int medium, ShadeOutput& out);
  std::optional<PhaseContinuation> sample_phase_continuation(const MediumVertex& v) const;
  float phase_mis_pdf(const MediumVertex& v, const vec3& wi) const;
  void attenuate_shadow_rays_in_media();      // transmittance through every segment, across interfaces
  RGB shadow_transmittance(Ray ray, int medium, PrimRef skip, uint64_t key) const;

  template <bool kObserve>
  void handle_escaped(const Ray& ray, uint32_t slot, ShadeOutput& out);
  // ---- the surface stage's steps (surface.cpp)
  template <bool kObserve>
  void shade_surface(const Ray& ray, const Hit& hit, uint32_t slot, const ContinuationDraw& draw, ShadeOutput& out);
  template <bool kObserve>
  [[gnu::always_inline]] inline bool add_surface_emission(uint32_t slot, const Ray& ray, const SurfaceInteraction& si,
                                                          ShadeOutput& out);
  template <bool kObserve>
  void prepare_vertex(ShadingPoint& v) const;
  // Whether a vertex draws a light sample: not on a specular lobe, not
  // before the throughput-reset bounce, and not where the sole light faces
  // away.  Asked before sample_direct_light's call, which is the costlier
  // part where most vertices stop here.
  bool draws_light_sample(const ShadingPoint& v) const {
    return !bsdf_is_specular(v.bsdf) && int(v.ps.depth) >= opt.throughput_reset_bounce &&
           !(sole_light >= 0 && light_faces_away(lights, sole_light, v.si.p));
  }
  template <bool kObserve>
  void sample_direct_light(ShadingPoint& v, ShadeOutput& out);  // where draws_light_sample(v)
  std::optional<Continuation> sample_continuation(const ShadingPoint& v, DeferredPdf* defer) const;
  template <bool kObserve>
  [[gnu::always_inline]] inline void continue_path(ShadingPoint& v, const Continuation& c, ShadeOutput& out);
  // Russian roulette on the throughput (times eta_scale), as pbrt-v4 does it;
  // a survivor's throughput and local factor carry the compensation.  A
  // guided path's throughput is first corrected to what BSDF sampling would
  // have made it (`correction`, seeds/000 ch. 1 eq. 19).  `survival`: the
  // probability the path had of surviving.  Inline: every continuation
  // takes it, between the pdf's division and the spawn.
  bool survives_roulette(const PathState& ps, float u_roulette, RGB& beta, RGB& local, float eta_scale,
                         double correction, float adjoint, float& survival) const {
    if (int(ps.depth) + 1 <= opt.rr_min_depth) return true;
    const float rr = adjoint >= 0.0f ? adjoint : float(double(max_component(beta * eta_scale)) * correction);
    if (rr >= 1.0f) return true;
    const float q = std::max(0.0f, 1.0f - rr);
    if (u_roulette < q) return false;
    survival = 1.0f - q;
    beta /= survival;
    local /= survival;
    return true;
  }
  float adjoint_survival(const ShadingPoint& v, const Continuation& c, const RGB& beta);
  void report_vertex(ShadingPoint& v, const Continuation& c, const RGB& local, float survival);
  float scattering_pdf(const ShadingPoint& v, const vec3& wi) const;
  // The guide's share of a guided vertex's mixture, as MIS weights see it.
  float mis_guide_share(const ShadingPoint& v) const {
    return opt.guiding.mixing == GuideMixing::Resampled ? kRISCandidateShare : v.guide_fraction;
  }
  // One-sample MIS: the guide's share of directions in a region, capped.
  float guide_share(uint32_t region) const {
    return std::min(hooks.guide->selection_probability(region), opt.guiding.selection_max);
  }
  uint8_t caustic_flags(const PathState& ps, const BSDF& bsdf) const;

  // ---- shared by the stages
  // Emission found by a BSDF-sampled ray: MIS against light sampling (the
  // light pdf only computed when the previous bounce was not specular),
  // splatted and reported.
  template <bool kObserve, class LightPdf>
  void add_emission(const PathState& ps, int light, const RGB& Le, LightPdf&& light_pdf, int primitive = -1);
  // Light that the caustic pass counts (wavefront/caustics.h): from a light
  // it traces, after a receiver and a caster.
  bool left_to_caustic_pass(uint8_t path_flags, int light) const {
    return caustics && (path_flags & kPathCausticCaster) && caustics->traces_light(light);
  }
  template <bool kObserve>
  void finish_path(uint32_t slot, ShadeOutput& out) {
    if constexpr (kObserve) observer->vertex_done(pool[slot].vertex);
    out.freed.push_back(slot);
  }
  // Queues the path's next ray, leaving the surface `si` (an interaction or a crossing).
  template <class Surface>
  void queue_ray(uint32_t slot, const Surface& si, const Ray& ray, ShadeOutput& out) {
    RayQueue& q = out.rays[size_t(direction_bin(ray.d))];
    q.rays.push_back(ray);
    q.paths.push_back(slot);
    if (!pool.curve_skip.empty()) pool.curve_skip[slot] = si.skip;
    if (!pool.medium.empty()) pool.medium[slot] = medium_after(scene, si.shape, si.ng, ray.d, pool.medium[slot]);
  }
  // Queues a shadow ray with the fields every NEE vertex fills (the
  // observer's are the caller's).  `event`: the path's PathEvent, its first
  // scattering event's if this vertex is that event.
  void queue_shadow(ShadeOutput& out, const Ray& ray, const RGB& contribution, const PathState& ps,
                    const SampledLight& chosen, const PrimRef& skip, int medium, uint8_t event) const {
    ShadowQueue& q = out.shadows;
    q.rays.push_back(ray);
    q.contribution.push_back(contribution);
    q.pixel.push_back(ps.pixel);
    q.sample.push_back(ps.sample);
    if (!pool.curve_skip.empty()) q.skip.push_back(skip);
    if (light_sampler_learns) q.chosen.push_back(chosen);
    if (!pool.medium.empty()) q.medium.push_back(medium);
    if (film.aov_events()) q.event.push_back(event);
    if (defers_nee_mis()) q.deferred_mis.emplace_back();
  }
  // Guided NEE weighs its MIS weight only once the shadow ray is known to be
  // unoccluded (DeferredNeeMIS); not where the observer records the weight
  // with the vertex, nor in scenes with media (their shadow rays splat in the
  // medium stage).
  bool defers_nee_mis() const { return hooks.guide != nullptr && observer == nullptr && pool.medium.empty(); }
  void apply_deferred_nee_mis();  // on `shadows`, after `blocked` is known
  void enqueue(size_t bin, const RayQueue& q);
  Batch take_spare();

  UVFootprint footprint(const SurfaceInteraction& si) const {
    return si.material >= 0 && material_footprint[size_t(si.material)] ? texture_footprint(camera, si, footprint_scale)
                                                                         : UVFootprint{};
  }
  bool counts_for_alpha(uint32_t sample) const { return opt.alpha_spp == 0 || sample < opt.alpha_spp; }
  // The throughput-reset image (recorder debug, bounce N): only light
  // arriving at vertices of depth >= N reaches the film.  Emission found at
  // hit d arrives at the vertex of depth d-1.
  bool splats_emission(uint32_t depth) const {
    return opt.throughput_reset_bounce < 0 || int(depth) > opt.throughput_reset_bounce;
  }
  float light_choice_pmf(const LightSampleContext& ctx, int light, int primitive) const {
    return primitive < 0 ? light_sampler.pmf(ctx, light) : light_sampler.pmf_primitive(ctx, light, primitive);
  }
  // The MIS pdf of the BSDF sample that made the path's ray (kDeferredPdf:
  // computed now from the path's deferred_pdf, bit for bit what eager
  // sampling would have stored).
  float prev_mis_pdf(const PathState& ps) const {
    if (ps.prev_pdf != kDeferredPdf) return ps.prev_pdf;
    return deferred_pdf(pool.deferred_pdf[size_t(&ps - pool.paths.data())]);
  }
  static LightSampleContext previous_vertex(const PathState& ps) {
    return LightSampleContext{ps.prev_p, vec3(0.0f), ps.prev_ng, ps.prev_ng};
  }
  SamplerKey sampler_key(const PathState& ps) const { return SamplerKey{opt.seed, ps.pixel, ps.sample}; }
  float sample1(const PathState& ps, uint32_t dim) const { return sample_1d(sampler_key(ps), dim); }
  // Always inlined, as sample_2d is (core/sampler.h): GCC outlined it once
  // sample_direct_light drew the light_choice pair with it.
  [[gnu::always_inline]] vec2 sample2(const PathState& ps, uint32_t dim) const {
    return sample_2d(sampler_key(ps), dim);
  }
  size_t memory_bytes() const;
};

template <bool kObserve, class LightPdf>
void WavefrontEngine::Impl::add_emission(const PathState& ps, int light, const RGB& Le, LightPdf&& light_pdf,
                                         int primitive) {
  float w = 1.0f;
  if (!(ps.flags & kPathPrevSpecular))
    w = power_heuristic(1, prev_mis_pdf(ps), 1, light_choice_pmf(previous_vertex(ps), light, primitive) * light_pdf());
  RGB contribution = ps.filter_weight * ps.beta * w * Le;
  if (splats_emission(ps.depth)) film.splat(ps.pixel, ps.sample, contribution, path_event(ps.flags));
  if constexpr (kObserve) observer->emission_added(ps.vertex, ps.pixel, contribution, w);
}

}  // namespace theia
