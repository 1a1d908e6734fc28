// The loop, the batches, and the stages around tracing: sort rays, trace
// closest hits, sort hits.  The other stages have their own files
// (engine_impl.h lists them).
#include "wavefront/engine_impl.h"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

#include <chrono>
#include <mutex>
#include <optional>
#include <stdexcept>

namespace theia {

namespace {

constexpr size_t kTraceGrain = 256;
constexpr size_t kShadeGrain = 64;
constexpr size_t kPrefetchDistance = 8;

// Shading order: (instance, geometry, primitive); misses last.
uint64_t hit_sort_key(const Hit& h) {
  return h.geom == kInvalidId ? ~uint64_t(0)
                              : (uint64_t(h.inst + 1) << 48) | (uint64_t(h.geom & 0xffff) << 32) | h.prim;
}

}  // namespace

EngineSizes engine_sizes(const EngineOptions& o, uint64_t pixels, int threads) {
  const uint64_t lanes = uint64_t(std::max(threads, 1));
  uint64_t paths = uint64_t(kUnsortedLanePaths) * lanes;
  if (o.sort) {
    // A pool of 2^19 paths keeps both cores of a production frame busy; a
    // small frame's whole iteration fits in far fewer.  Below 2^14 paths a
    // lane's batches are too small to sort: that floor, one per thread, wins
    // over both, and past 32 threads raises the ceiling with it.
    const uint64_t floor = (uint64_t(1) << 14) * lanes;
    paths = std::clamp<uint64_t>(pixels * 4, floor, std::max<uint64_t>(floor, uint64_t(1) << 19));
  }
  EngineSizes s;
  s.max_paths = o.max_paths > 0 ? o.max_paths : size_t(paths);
  s.lanes = std::clamp<size_t>(size_t(std::max(threads, 1)), 1, s.max_paths);
  s.batch_size = o.batch_size > 0 ? o.batch_size : default_batch_size(s.lane_paths(), o.sort);
  return s;
}

// Unsorted, 1024 rays, whatever the pool: a batch's rays were spawned by
// hits shaded close together (camera batches are in pixel order), so they
// start near each other and Embree traces them faster than a larger
// batch's, and what shading touches between two traces stays small.  Sorted,
// an eighth of the pool (continuation rays spread over six direction bins
// fill it), so that sorting has rays to order.
size_t default_batch_size(size_t paths, bool sort) {
  constexpr size_t kUnsortedBatch = 1024;
  return sort ? std::max<size_t>(paths / 8, kUnsortedBatch) : kUnsortedBatch;
}

static bool has_layered_material(const Scene& scene) {
  return std::any_of(scene.materials.begin(), scene.materials.end(), [](const Material& m) {
    return m.kind == MaterialKind::CoatedDiffuse || m.kind == MaterialKind::CoatedConductor;
  });
}

WavefrontEngine::Impl::Impl(const RenderableScene& rs, Film& f, const EngineOptions& o, const EngineHooks& h,
                            const EngineSizes& lane)
    : scene(rs.scene), accel(rs.accel), lights(rs.lights), light_sampler(*rs.light_sampler), camera(rs.camera),
      filter(rs.filter), film(f), opt(o), hooks(h), observer(h.observer), sizes(lane),
      pool(sizes.max_paths, PathFeatures{.curves = !rs.scene.curves.empty(),
                                         .guiding = h.guide != nullptr && o.guiding.roulette_correction,
                                         .adjoint_roulette = h.guide != nullptr && o.guiding.adjoint_roulette,
                                         .media = rs.scene.has_media(),
                                         .roughening = o.roughening > 0.0f,
                                         .layered = o.defer_layered_pdf && has_layered_material(rs.scene)}) {
  full_batch_size = sizes.batch_size;
  live_cap = pool.capacity();
  Bounds3 b = accel.bounds();
  if (b.min.x <= b.max.x) {
    bounds_min = b.min;
    bounds_inv_extent = 1.0f / glm::max(b.max - b.min, vec3(1e-30f));
  }
  material_footprint.resize(scene.materials.size());
  for (size_t m = 0; m < scene.materials.size(); ++m) material_footprint[m] = material_reads_footprint(scene, int(m));
  check_media_hooks();
  if (rs.scene.has_media()) sealed_media = theia::sealed_media(scene);
  light_sampler_learns = light_sampler.wants_feedback();
  light_sampler_primitives = light_sampler.chooses_primitives();
  footprint_scale = footprint_spp_scale(opt.footprint_spp);
}

// ---------------------------------------------------------------- the loop

// One iteration: the lanes render camera samples [first_camera, end) (or
// until stopped), the lead lane on the calling thread; then the caustic pass
// and the film's flush.
uint64_t WavefrontEngine::iterate(uint32_t s_begin, uint32_t s_end, const SampleRanges* ranges, uint64_t first_camera,
                                  const std::function<void(double)>& on_progress) {
  auto t0 = std::chrono::steady_clock::now();
  Impl& lead = *lanes_.front();
  lead.film.continue_in_thread_sums();
  std::atomic<uint64_t> claims{0};
  for (auto& lane : lanes_)
    lane->begin_iteration(s_begin, s_end, first_camera, ranges, lanes_.size() > 1 ? &claims : nullptr);
  claims = lead.next_camera;
  // Each lane reports as it claims camera samples, one lane at a time.
  std::mutex progress_lock;
  double reported = 0.0;
  const std::function<void(double)> report = [&](double fraction) {
    const std::lock_guard<std::mutex> hold(progress_lock);
    reported = std::max(reported, fraction);
    if (on_progress) on_progress(reported);
  };
  for (auto& lane : lanes_) lane->progress = &report;
  run_lanes();
  lead.next_camera = lead.cameras_claimed();
  for (auto& lane : lanes_) lane->camera_claims = nullptr, lane->ranges = nullptr, lane->progress = nullptr;
  lead.progress = &report;
  // The iteration's camera samples are all in: the caustic pass adds its
  // estimate for the same samples (an interrupted iteration runs it when resumed).
  if (lead.next_camera == lead.camera_end && !abandoned()) lead.trace_caustics();
  lead.film.flush();
  lead.report_progress();
  lead.progress = nullptr;
  end_iteration();
  stats_.render_seconds += seconds_since(t0);
  return lead.next_camera;
}

// Each lane on its own thread; the lead on the calling one.
void WavefrontEngine::run_lanes() {
  tbb::task_group others;
  for (size_t i = 1; i < lanes_.size(); ++i) others.run([lane = lanes_[i].get()] { lane->run(); });
  try {
    lanes_.front()->run();
  } catch (...) {
    others.wait();
    throw;
  }
  others.wait();
}

void WavefrontEngine::Impl::run() {
  auto loop = [this] {
    while (advance()) {
    }
  };
  if (arena)
    arena->execute(loop);
  else
    loop();
}

// The lanes' counts into the engine's: sums, but the phases' mean (the
// lanes ran at once) and the sum of each lane's peak; the captured rays in
// lane order.  The caustic pass runs after the lanes, on every thread, timed
// by the lead: its seconds are wall seconds already.
void WavefrontEngine::end_iteration() {
  const double share = 1.0 / double(lanes_.size());
  size_t live = 0, queued = 0, queued_shadows = 0;
  for (auto& lane : lanes_) {
    EngineStats& s = lane->stats;
    for (size_t p = 0; p < size_t(Phase::Count); ++p)
      stats_.phases[Phase(p)] += s.phases[Phase(p)] * (Phase(p) == Phase::Caustics ? 1.0 : share);
    stats_.camera_rays += s.camera_rays;
    stats_.continuation_rays += s.continuation_rays;
    stats_.shadow_rays += s.shadow_rays;
    stats_.paths += s.paths;
    stats_.path_vertices += s.path_vertices;
    stats_.batches += s.batches;
    stats_.shadow_batches += s.shadow_batches;
    live += s.peak_live_paths;
    queued += s.peak_queued_rays;
    queued_shadows += s.peak_queued_shadow_rays;
    s = EngineStats{};
  }
  stats_.peak_live_paths = std::max(stats_.peak_live_paths, live);
  stats_.peak_queued_rays = std::max(stats_.peak_queued_rays, queued);
  stats_.peak_queued_shadow_rays = std::max(stats_.peak_queued_shadow_rays, queued_shadows);
  // The lead captures into the caller's vectors itself.
  const EngineOptions& o = lanes_.front()->opt;
  auto append = [](std::vector<Ray>* to, std::vector<Ray>& from) {
    if (to) to->insert(to->end(), from.begin(), from.end());
    from.clear();
  };
  for (size_t i = 1; i < lanes_.size(); ++i) {
    append(o.capture_rays, lanes_[i]->captured_rays);
    append(o.capture_camera_rays, lanes_[i]->captured_camera_rays);
    append(o.capture_shadow_rays, lanes_[i]->captured_shadow_rays);
  }
}

void WavefrontEngine::Impl::begin_iteration(uint32_t s_begin, uint32_t s_end, uint64_t first_camera,
                                            const SampleRanges* sample_ranges, std::atomic<uint64_t>* claims) {
  ranges = sample_ranges;
  camera_claims = claims;
  sample_begin = s_begin;
  sample_count = s_end > s_begin ? s_end - s_begin : 0;
  // Per iteration: the caustic pass may have switched itself off after the last one.
  // Below depth 2 no camera path reaches a light through a caster, so there is nothing to hand over.
  caustics = hooks.caustics && hooks.caustics->active() && opt.throughput_reset_bounce < 0 && !ranges &&
                     opt.max_depth >= 2
                 ? hooks.caustics
                 : nullptr;
  camera_end = ranges ? ranges->total() : uint64_t(film.pixel_count()) * sample_count;
  next_camera = std::min(first_camera, camera_end);
  cap_live_paths();
  signal_seen.reset();
  abandoned = false;
}

// EngineHooks::observed_pool_share: batches sized for the paths that live
// (default_batch_size, as engine_sizes does for the pool), the refill at the same
// occupancy of them.  Unobserved, the pool's own sizes.  The floor is the
// engine's, shared by its lanes.
void WavefrontEngine::Impl::cap_live_paths() {
  const size_t min_live = (size_t(1) << 14) / lane_count;
  live_cap = pool.capacity();
  sizes.batch_size = full_batch_size;
  if (observer && hooks.observed_pool_share > 0.0f) {
    const size_t share = size_t(double(hooks.observed_pool_share) * double(pool.capacity()));
    live_cap = std::clamp(share, std::min(min_live, pool.capacity()), pool.capacity());
    if (opt.batch_size == 0 && live_cap < pool.capacity()) sizes.batch_size = default_batch_size(live_cap, opt.sort);
  }
  refill_below = size_t(opt.occupancy_threshold * float(live_cap));
}

// One turn of the loop: a batch (one bounce of at most batch_size rays), a
// refill of camera rays or a flush of shadow rays.  False once nothing is
// left, or when a signal's time for the paths in flight is up (checked every
// few milliseconds however long the paths are).
bool WavefrontEngine::Impl::advance() {
  if (out_of_time()) {
    abandon_paths_in_flight();
    return false;
  }
  if (pool.live() <= refill_below && can_generate()) generate_camera_rays_and_report();
  if (shadows.size() >= sizes.batch_size) trace_shadow_rays();
  if (!full.empty()) {
    Batch b = std::move(full.back());
    full.pop_back();
    process_and_recycle(b);
    return true;
  }
  if (can_generate()) {
    generate_camera_rays_and_report();
    return true;
  }
  // Nothing full and nothing left to generate: flush the fullest partial batch.
  Batch* fullest = nullptr;
  for (Batch& b : filling)
    if (b.size() > 0 && (!fullest || b.size() > fullest->size())) fullest = &b;
  if (fullest) {
    Batch b = std::move(*fullest);
    *fullest = take_spare();
    process_and_recycle(b);
    return true;
  }
  if (shadows.size() > 0) {
    trace_shadow_rays();
    return true;
  }
  return false;
}

// Once stopped, no camera ray is generated: the paths in flight finish,
// so exactly the pixel-samples [first_camera, cameras_claimed()) are
// complete (with lanes, once every lane has finished).
bool WavefrontEngine::Impl::can_generate() const {
  return cameras_claimed() < camera_end && pool.live() < live_cap && !(opt.stop && opt.stop->raised()) &&
         !(camera_deadline && std::chrono::steady_clock::now() >= *camera_deadline);
}

// A signal (not the time limit) bounds the time left to the paths in flight.
bool WavefrontEngine::Impl::out_of_time() {
  if (!opt.stop || opt.stop->reason() != StopReason::Signal) return false;
  if (!signal_seen) signal_seen = std::chrono::steady_clock::now();
  return seconds_since(*signal_seen) >= opt.abandon_after_seconds;
}

void WavefrontEngine::Impl::generate_camera_rays_and_report() {
  generate_camera_rays(live_cap - pool.live());
  report_progress();
}

void WavefrontEngine::Impl::report_progress() const {
  if (progress && *progress) (*progress)(camera_end ? double(cameras_claimed()) / double(camera_end) : 1.0);
}

// The camera samples this lane (or, with lanes, any lane) has taken on.
uint64_t WavefrontEngine::Impl::cameras_claimed() const {
  return camera_claims ? std::min(camera_claims->load(std::memory_order_relaxed), camera_end) : next_camera;
}

void WavefrontEngine::Impl::process_and_recycle(Batch& b) {
  process_batch(b);
  spare.push_back(std::move(b));
}

void WavefrontEngine::Impl::trace_caustics() {
  if (!caustics) return;
  ScopedTimer timer(stats.phases[Phase::Caustics]);
  caustics->trace(film, CausticSamples{opt.seed, sample_begin, sample_begin + sample_count, next_camera},
                  [this](const SurfaceInteraction& si) { return footprint(si); });
}

// One batch: its rays traced, their hits shaded, the rays they spawn queued.
void WavefrontEngine::Impl::process_batch(Batch& b) {
  queued_rays -= b.size();
  ++stats.batches;
  if (!b.camera) stats.continuation_rays += b.size();
  if (opt.sort && !b.camera) sort_rays(b);
  trace_closest(b);  // and, in media, each ray's medium interaction
  if (opt.sort)
    sort_hits(b);
  else
    set_aside_misses(b);
  shade_batch(b);
  merge_outputs();
}

// ---------------------------------------------------------------- batches

// Drops every path and queued ray: the engine is as before its first
// render() (the film keeps what was splatted, which the caller discards).
void WavefrontEngine::Impl::abandon_paths_in_flight() {
  abandoned = true;
  for (Batch& b : filling) queue_clear(b);
  for (Batch& b : full) spare.push_back(std::move(b));
  full.clear();
  queue_clear(shadows);
  queued_rays = 0;
  pool.free_slots.resize(pool.capacity());
  for (size_t i = 0; i < pool.capacity(); ++i) pool.free_slots[i] = uint32_t(pool.capacity() - 1 - i);
}

Batch WavefrontEngine::Impl::take_spare() {
  if (spare.empty()) return Batch{};
  Batch b = std::move(spare.back());
  spare.pop_back();
  queue_clear(b);
  b.camera = false;
  return b;
}

// One thread's rays of one direction bin into the bin's filling batch, in
// order, a full batch at a time.
void WavefrontEngine::Impl::enqueue(size_t bin, const RayQueue& q) {
  for (size_t i = 0; i < q.size();) {
    Batch& b = filling[bin];
    const size_t take = std::min(q.size() - i, sizes.batch_size > b.size() ? sizes.batch_size - b.size() : 0);
    queue_append(static_cast<RayQueue&>(b), q, i, i + take);
    i += take;
    if (b.size() >= sizes.batch_size) {
      full.push_back(std::move(b));
      b = take_spare();
    }
  }
  queued_rays += q.size();
}

// The threads' outputs into the queues, in a fixed order (the threads' own).
void WavefrontEngine::Impl::merge_outputs() {
  ScopedTimer timer(stats.phases[Phase::Queue]);
  for (ShadeOutput& out : outputs) {
    for (size_t bin = 0; bin < kDirectionBins; ++bin) enqueue(bin, out.rays[bin]);
    queue_append(shadows, out.shadows);
    pool.free_slots.insert(pool.free_slots.end(), out.freed.begin(), out.freed.end());
    stats.path_vertices += out.vertices;
    stats.continuation_rays += out.retraced;
    if (opt.capture_rays)
      opt.capture_rays->insert(opt.capture_rays->end(), out.retraced_rays.begin(), out.retraced_rays.end());
    for (RayQueue& q : out.rays) queue_clear(q);
    queue_clear(out.shadows);
    out.freed.clear();
    out.vertices = 0;
    out.retraced = 0;
    out.retraced_rays.clear();
  }
  stats.peak_queued_rays = std::max(stats.peak_queued_rays, queued_rays);
  stats.peak_queued_shadow_rays = std::max(stats.peak_queued_shadow_rays, shadows.size());
}

// ---------------------------------------------------------------- sort rays

uint64_t ray_sort_key(const Ray& r, const vec3& bounds_min, const vec3& bounds_inv_extent) {
  vec3 o = (r.o - bounds_min) * bounds_inv_extent;
  uint64_t m = morton3(o.x, o.y, o.z);
  // Direction: 4 bits per component (the bin already fixes the dominant axis);
  // cheap, and fine enough to group rays that will walk the same BVH nodes.
  vec3 d = glm::normalize(r.d);
  auto q = [](float c) { return uint64_t(std::clamp((c * 0.5f + 0.5f) * 16.0f, 0.0f, 15.0f)); };
  return (m << 12) | (q(d.x) << 8) | (q(d.y) << 4) | q(d.z);
}

void WavefrontEngine::Impl::sort_rays(Batch& b) {
  ScopedTimer timer(stats.phases[Phase::Sort]);
  sort_by_ray_key(b.rays, bounds_min, bounds_inv_extent, keys, scratch, order);
  queue_gather<RayQueue>(b, order, sorted);
}

void sort_by_ray_key(std::span<const Ray> rays, const vec3& bounds_min, const vec3& bounds_inv_extent,
                     std::vector<SortPair>& keys, std::vector<SortPair>& scratch, std::vector<uint32_t>& order) {
  const size_t n = rays.size();
  keys.resize(n);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i)
      keys[i] = SortPair{ray_sort_key(rays[i], bounds_min, bounds_inv_extent), uint32_t(i)};
  });
  radix_sort(keys, scratch, 42);
  order.resize(n);
  for (size_t i = 0; i < n; ++i) order[i] = keys[i].index;
}

// ---------------------------------------------------------------- trace closest

// In scenes with media each traced ray's medium interaction follows at
// once, in the same loop, on the core whose cache holds its ray and hit:
// its hit is then final, and the shading keys (when hits are sorted) are
// made there too.  Each stage boundary saved is a wait of one thread on the
// other per batch.
void WavefrontEngine::Impl::trace_closest(Batch& b) {
  const size_t n = b.size();
  if (std::vector<Ray>* to = b.camera && opt.capture_camera_rays ? opt.capture_camera_rays : opt.capture_rays)
    to->insert(to->end(), b.rays.begin(), b.rays.end());
  hits.resize(n);
  if (opt.sort) keys.resize(n);
  batch_skips.clear();
  if (!pool.curve_skip.empty())
    for (uint32_t slot : b.paths) batch_skips.push_back(pool.curve_skip[slot]);
  const bool media = !pool.medium.empty();
  if (media) blocked.assign(n, 0);
  ScopedTimer timer(stats.phases[Phase::Trace]);
  stage_loop(n, kTraceGrain, [&](const tbb::blocked_range<size_t>& r) {
    std::span<const PrimRef> skips;
    if (!batch_skips.empty()) skips = std::span<const PrimRef>(batch_skips.data() + r.begin(), r.size());
    accel.intersect(std::span<const Ray>(b.rays.data() + r.begin(), r.size()),
                    std::span<Hit>(hits.data() + r.begin(), r.size()), b.camera, skips);
    if (media) handle_medium_interactions(b, r.begin(), r.end(), outputs.local());
    if (opt.sort)
      for (size_t i = r.begin(); i < r.end(); ++i) keys[i] = SortPair{hit_sort_key(hits[i]), uint32_t(i)};
  });
}

// ---------------------------------------------------------------- sort hits

// Shading in (instance, geometry, primitive) order makes neighbouring work
// share meshes, materials and textures.  Misses sort last and leave the
// list for the escaped-ray stage.
void WavefrontEngine::Impl::sort_hits(const Batch& b) {
  ScopedTimer timer(stats.phases[Phase::Sort]);
  // Misses leave first, in order, so that the sort sees only hits: their
  // keys share high bits, whose passes the radix sort then skips.  (In
  // place: std::stable_partition takes a temporary buffer per batch.)
  // Paths that left the batch in a medium leave the list.
  const bool media = !pool.medium.empty();
  queue_clear(escaped);
  size_t kept = 0;
  for (size_t k = 0; k < keys.size(); ++k) {
    const SortPair p = keys[k];
    if (media && blocked[p.index]) continue;
    if (p.key != ~uint64_t(0)) {
      keys[kept++] = p;
    } else {
      escaped.rays.push_back(b.rays[p.index]);
      escaped.paths.push_back(b.paths[p.index]);
    }
  }
  keys.resize(kept);
  radix_sort(keys, scratch, 64);
}

// ---------------------------------------------------------------- shade

// Unsorted: the hits' indices go to `keys` in the order they were traced,
// so that shading's loop sees only hits, as it does sorted.  A miss's path
// ends here where that is all a miss does (misses_only_end_paths); else the
// miss goes to `escaped`, shaded first, as sorted batches' are.  Paths that
// left the batch in a medium leave the list.  Each ray's index is written
// to both lists and counted in one: whether it hit is a coin flip, which a
// branch would mispredict half the time.
void WavefrontEngine::Impl::set_aside_misses(const Batch& b) {
  const size_t n = b.size();
  const bool media = !pool.medium.empty();
  keys.resize(n);
  missed.resize(n);
  size_t kept = 0, n_missed = 0;
  for (size_t i = 0; i < n; ++i) {
    const bool stays = !media || !blocked[i], hit = hits[i].geom != kInvalidId;
    keys[kept] = SortPair{0, uint32_t(i)};
    missed[n_missed] = uint32_t(i);
    kept += stays & hit;
    n_missed += stays & !hit;
  }
  keys.resize(kept);
  missed.resize(n_missed);
  queue_clear(escaped);
  if (misses_only_end_paths()) {
    std::vector<uint32_t>& freed = outputs.local().freed;
    for (uint32_t i : missed) freed.push_back(b.paths[i]);
    return;
  }
  for (uint32_t i : missed) escaped.rays.push_back(b.rays[i]), escaped.paths.push_back(b.paths[i]);
}

// The batch's escaped rays and surface hits in one parallel loop: a stage
// boundary fewer per batch (each costs both threads a wait).  The escaped
// rays first, then the hits in `keys` order (sort_hits' or
// set_aside_misses').  Each chunk of hits has its continuations' numbers
// drawn before it is shaded.
void WavefrontEngine::Impl::shade_batch(const Batch& b) {
  ScopedTimer timer(stats.phases[Phase::Shade]);
  const size_t n_escaped = escaped.size(), n = n_escaped + keys.size();
  stage_loop(n, kShadeGrain, [&](const tbb::blocked_range<size_t>& r) {
    ShadeOutput& out = outputs.local();
    std::array<ContinuationDraw, kDrawChunk> draws;
    for (size_t chunk = r.begin(); chunk < r.end(); chunk += kDrawChunk) {
      const size_t end = std::min(chunk + kDrawChunk, r.end());
      draw_continuations(b, chunk, end, n_escaped, draws);
      for (size_t k = chunk; k < end; ++k) {
        if (k >= n_escaped) {
          shade_traced_ray(b, k - n_escaped, draws[k - chunk], out);
          continue;
        }
        // In the batch's sort order their path records are scattered: fetch a few ahead.
        if (k + kPrefetchDistance < n_escaped) __builtin_prefetch(&pool[escaped.paths[k + kPrefetchDistance]]);
        handle_escaped_ray(escaped.rays[k], escaped.paths[k], out);
      }
    }
  });
}

// The continuation's numbers (sample_dims.h) of every surface hit among
// shading's rays [begin, end), and their cosine-weighted directions, into
// draws[k - begin].  Drawn a chunk at a time, in vector lanes, they are off
// each hit's chain of dependent steps: drawn in the middle of it, their
// hashing held the chain up.  The draws read the
// chunk's path records first, so the next chunk's are fetched here (the hits
// scatter them, sorted by (geometry, primitive) or not).
void WavefrontEngine::Impl::draw_continuations(const Batch& b, size_t begin, size_t end, size_t n_escaped,
                                               std::span<ContinuationDraw> draws) const {
  std::array<SamplerKey, kDrawChunk> key{};
  std::array<uint32_t, kDrawChunk> first{};
  const size_t n = n_escaped + keys.size();
  for (size_t k = begin; k < end; ++k) {
    if (const size_t next = k + kDrawChunk; next >= n_escaped && next < n)
      __builtin_prefetch(&pool[b.paths[hit_index(next - n_escaped)]]);
    if (k < n_escaped) continue;
    const uint32_t i = hit_index(k - n_escaped);
    const PathState& ps = pool[b.paths[i]];
    key[k - begin] = sampler_key(ps);
    first[k - begin] = bounce_dims(ps.depth).bsdf_dir;
  }
  const size_t count = end - begin;
  std::array<vec4, kDrawChunk> u;
  std::array<vec3, kDrawChunk> cosine;
  sample_4d(std::span(key).first(count), std::span(first).first(count), std::span(u).first(count));
  sample_cosine_hemisphere(std::span<const vec4>(u).first(count), std::span(cosine).first(count));
  for (size_t k = 0; k < count; ++k) draws[k] = {u[k], cosine[k]};
}

// The k-th surface hit to shade, batch index hit_index(k).
void WavefrontEngine::Impl::shade_traced_ray(const Batch& b, size_t k, const ContinuationDraw& draw, ShadeOutput& out) {
  prefetch_for_shading(b, k);
  const uint32_t i = hit_index(k);
  if (observer)
    shade_surface<true>(b.rays[i], hits[i], b.paths[i], draw, out);
  else
    shade_surface<false>(b.rays[i], hits[i], b.paths[i], draw, out);
}

// What shading hit k (in shading order: hit_index) reads besides its path
// record (draw_continuations fetches those), a few hits ahead: its ray, its
// path's cold fields, and on meshes larger than the cache its triangle.
void WavefrontEngine::Impl::prefetch_for_shading(const Batch& b, size_t k) {
  const size_t n = keys.size();
  if (prefetch_triangles && k + 2 * kPrefetchDistance < n)
    triangles.indices(hits[hit_index(k + 2 * kPrefetchDistance)]);
  if (k + kPrefetchDistance < n) {
    const uint32_t j = hit_index(k + kPrefetchDistance);
    __builtin_prefetch(&b.rays[j]);
    if (prefetch_triangles)
      triangles.vertices(hits[j]);
    else
      __builtin_prefetch(&hits[j]);
    pool.prefetch_cold(b.paths[j]);
  }
  // The path record (fetched a chunk ahead) names the observer's vertex: fetch that too.
  if (observer && k + kPrefetchDistance / 2 < n)
    observer->prefetch(pool[b.paths[hit_index(k + kPrefetchDistance / 2)]].vertex);
}

size_t WavefrontEngine::Impl::memory_bytes() const {
  size_t bytes = pool.memory_bytes() + queue_bytes(shadows) + queue_bytes(shadows_sorted) + queue_bytes(escaped) +
                 queue_bytes(sorted) + (keys.capacity() + scratch.capacity()) * sizeof(SortPair) +
                 (order.capacity() + missed.capacity()) * sizeof(uint32_t) + hits.capacity() * sizeof(Hit);
  for (const Batch& b : filling) bytes += queue_bytes(b);
  for (const Batch& b : full) bytes += queue_bytes(b);
  for (const Batch& b : spare) bytes += queue_bytes(b);
  for (const ShadeOutput& out : outputs) {
    bytes += queue_bytes(out.shadows);
    for (const RayQueue& q : out.rays) bytes += queue_bytes(q);
  }
  return bytes;
}

// ---------------------------------------------------------------- the public face

RenderableScene::RenderableScene(const Scene& s, const std::string& sampler_name)
    : scene(s),
      accel(s),
      lights(s, accel),
      light_sampler(make_light_sampler(sampler_name, lights, accel)),
      camera(make_camera(s.camera, s.film)),
      filter(make_filter(s.filter)) {}

WavefrontEngine::WavefrontEngine(const RenderableScene& rs, Film& film, const EngineOptions& options,
                                 const EngineHooks& hooks) {
  const int threads = int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
  sizes_ = engine_sizes(options, uint64_t(film.pixel_count()), threads);
  const EngineSizes lane{sizes_.lane_paths(), sizes_.batch_size, 1};
  for (size_t i = 0; i < sizes_.lanes; ++i) {
    lanes_.push_back(std::make_unique<Impl>(rs, film, options, hooks, lane));
    Impl& l = *lanes_.back();
    l.lane_count = sizes_.lanes;
    if (sizes_.lanes > 1) l.arena = std::make_unique<tbb::task_arena>(1);
    l.stage_threads = sizes_.lanes > 1 ? 1 : threads;
    if (i == 0) continue;
    if (options.capture_rays) l.opt.capture_rays = &l.captured_rays;
    if (options.capture_camera_rays) l.opt.capture_camera_rays = &l.captured_camera_rays;
    if (options.capture_shadow_rays) l.opt.capture_shadow_rays = &l.captured_shadow_rays;
  }
  film.use_thread_sums(threads);
}

WavefrontEngine::~WavefrontEngine() = default;

uint64_t WavefrontEngine::render(uint32_t sample_begin, uint32_t sample_end, const std::function<void(double)>& progress,
                                 uint64_t first_camera_sample) {
  return iterate(sample_begin, sample_end, nullptr, first_camera_sample, progress);
}

uint64_t WavefrontEngine::render(const SampleRanges& ranges, const std::function<void(double)>& progress,
                                 uint64_t first_camera_sample) {
  return iterate(0, 0, &ranges, first_camera_sample, progress);
}

void WavefrontEngine::set_hooks(const EngineHooks& hooks) {
  for (auto& lane : lanes_) {
    lane->hooks = hooks;
    lane->observer = hooks.observer;
    lane->check_media_hooks();
  }
}

// The caustic pass's light paths do not track media: the caller switches it off.
void WavefrontEngine::Impl::check_media_hooks() const {
  if (!pool.medium.empty() && hooks.caustics)
    throw std::invalid_argument("a scene with participating media renders without the caustic pass");
}

const EngineHooks& WavefrontEngine::hooks() const { return lanes_.front()->hooks; }

bool WavefrontEngine::abandoned() const {
  return std::any_of(lanes_.begin(), lanes_.end(), [](const auto& lane) { return lane->abandoned; });
}

void WavefrontEngine::finish_stopped_iteration() {
  auto t0 = std::chrono::steady_clock::now();
  Impl& lead = *lanes_.front();
  lead.film.continue_in_thread_sums();
  lead.trace_caustics();
  lead.film.flush();
  end_iteration();
  stats_.render_seconds += seconds_since(t0);
}

void WavefrontEngine::stop_camera_samples_at(std::optional<std::chrono::steady_clock::time_point> at) {
  for (auto& lane : lanes_) lane->camera_deadline = at;
}

const EngineStats& WavefrontEngine::stats() const { return stats_; }
// The batch size of a lane while observed may be capped (cap_live_paths).
EngineSizes WavefrontEngine::sizes() const { return {sizes_.max_paths, lanes_.front()->sizes.batch_size, sizes_.lanes}; }

size_t WavefrontEngine::memory_bytes() const {
  size_t bytes = 0;
  for (const auto& lane : lanes_) bytes += lane->memory_bytes();
  return bytes;
}

}  // namespace theia
