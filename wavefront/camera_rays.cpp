// Stage: generate camera rays, in pixel-sample order, into fresh path slots.
#include "wavefront/camera_samples.h"
#include "wavefront/engine_impl.h"

namespace theia {

namespace {

constexpr size_t kSlotPrefetchDistance = 8;
constexpr uint64_t kMinCameraClaim = 1024;

}  // namespace

// A camera path's state at its first vertex; the cold tables of the
// features that are on start afresh too.
void WavefrontEngine::Impl::start_path(uint32_t slot, uint32_t pixel, uint32_t sample, bool alpha_only,
                                       float filter_weight, const vec3& origin) {
  PathState& ps = pool[slot];
  ps.beta = RGB(1.0f);
  ps.prev_p = origin;
  ps.prev_ng = vec3(0.0f);
  ps.pixel = pixel;
  ps.sample = sample;
  ps.vertex = observer ? observer->path_started(pixel, sample) : kNoVertex;
  ps.filter_weight = filter_weight;
  ps.prev_pdf = 0.0f;
  ps.eta_scale = 1.0f;
  ps.depth = 0;
  ps.flags = kPathPrevSpecular;
  ps.alpha_only = alpha_only ? 1 : 0;
  if (!pool.has_cold) return;
  if (!pool.curve_skip.empty()) pool.curve_skip[slot] = PrimRef{};
  if (!pool.roulette_correction.empty()) pool.roulette_correction[slot] = 1.0;
  if (!pool.pixel_estimate.empty()) pool.pixel_estimate[slot] = 0.0f;
  if (!pool.medium.empty()) pool.medium[slot] = scene.camera_medium, pool.flight_depth[slot] = 0;
  if (!pool.roughness.empty()) pool.roughness[slot] = 0.0f;
}

// The rays of a block of camera samples, from their film offsets (and lens
// draws), several at a time (generate_camera_rays).
void WavefrontEngine::Impl::camera_rays(std::span<const PixelSample> samples, std::span<const FilterSample> film_draws,
                                        std::span<Ray> rays) const {
  std::array<vec2, kFilmBlock> p_film, u_lens;
  const uint32_t width = uint32_t(film.width);
  // A pixel's samples are consecutive: its centre is found once, not by a
  // division per sample.
  uint32_t pixel = ~0u;
  vec2 centre(0.0f);
  for (size_t i = 0; i < samples.size(); ++i) {
    const PixelSample& s = samples[i];
    if (s.pixel != pixel) pixel = s.pixel, centre = vec2(float(pixel % width) + 0.5f, float(pixel / width) + 0.5f);
    const vec2 offset = film_draws[i].p;
    p_film[i] = centre + offset;
    // A pinhole reads no lens sample: the Sobol pair costs as much as the rest of the ray.
    const SamplerKey key{opt.seed, s.pixel, s.sample};
    u_lens[i] = camera.lens_radius > 0.0f ? sample_2d(key, CameraDims::lens) : vec2(0.5f);
  }
  theia::generate_camera_rays(camera, std::span<const vec2>(p_film.data(), samples.size()),
                              std::span<const vec2>(u_lens.data(), samples.size()), rays);
}

// Camera sample s's filter weights added to the film and its path started in
// `slot`; `fs`: its film offset and weight (camera_filter_sample).
void WavefrontEngine::Impl::start_camera_path(uint32_t slot, const PixelSample& s, const FilterSample& fs,
                                              const vec3& origin) {
  film.add_weights(s.pixel, s.sample, fs.weight, !s.alpha_only, counts_for_alpha(s.sample));
  start_path(slot, s.pixel, s.sample, s.alpha_only, fs.weight, origin);
}

// The next run of camera samples for this lane: at most `count` (fewer as
// the iteration's end nears, so that the lanes finish together); sets
// `count` to the run's length, 0 when none is left.
uint64_t WavefrontEngine::Impl::claim_camera_samples(size_t& count) {
  count = std::min(count, pool.free_slots.size());
  if (!camera_claims) {
    count = size_t(std::min<uint64_t>(count, camera_end - next_camera));
    return next_camera;
  }
  const uint64_t left = camera_end - cameras_claimed();
  count = size_t(std::min<uint64_t>(count, std::max<uint64_t>(left / (2 * lane_count), kMinCameraClaim)));
  const uint64_t first = camera_claims->fetch_add(count, std::memory_order_relaxed);
  count = first < camera_end ? size_t(std::min<uint64_t>(count, camera_end - first)) : 0;
  return first;
}

void WavefrontEngine::Impl::generate_camera_rays(size_t count) {
  ScopedTimer timer(stats.phases[Phase::Generate]);
  const uint64_t first = claim_camera_samples(count);
  if (count == 0) return;
  std::vector<uint32_t> slots(pool.free_slots.end() - count, pool.free_slots.end());
  pool.free_slots.resize(pool.free_slots.size() - count);

  // Camera rays stay in pixel order rather than entering the direction bins:
  // neighbouring pixels' rays are coherent already, and a batch of them is
  // traced in Embree's ray packets (Accel::intersect).  They are written
  // straight into their batches, pushed last first so that the first pixels
  // are traced first.
  const size_t batch = sizes.batch_size, n_batches = (count + batch - 1) / batch;
  const size_t first_batch = full.size();
  for (size_t k = n_batches; k-- > 0;) {
    Batch b = take_spare();
    b.camera = true;
    const size_t lo = k * batch, hi = std::min(count, lo + batch);
    b.rays.resize(hi - lo);
    b.paths.assign(slots.begin() + lo, slots.begin() + hi);
    full.push_back(std::move(b));
  }
  stage_loop(count, 1024, [&](const tbb::blocked_range<size_t>& r) {
    start_camera_paths(first, r.begin(), r.end(), slots, first_batch);
  });
  next_camera = first + count;
  stats.camera_rays += count;
  stats.paths += count;
  queued_rays += count;

  stats.peak_live_paths = std::max(stats.peak_live_paths, pool.live());
}

// Samples [begin, end) of a run of camera samples (the run's first is
// camera sample `first`, its path slots `slots`), a block at a time: their
// paths started, and their rays written into the run's camera batches
// (full[first_batch] on, pushed last first).
void WavefrontEngine::Impl::start_camera_paths(uint64_t first, size_t begin, size_t end,
                                               std::span<const uint32_t> slots, size_t first_batch) {
  const size_t batch = sizes.batch_size, n_batches = (slots.size() + batch - 1) / batch;
  CameraSampleWalk walk(first + begin, ranges, sample_begin, sample_count);
  CameraFilmDraws draw_film(filter, opt.seed, walk->pixel);
  std::array<PixelSample, kFilmBlock> samples;
  std::array<FilterSample, kFilmBlock> film_draws;
  std::array<Ray, kFilmBlock> rays;
  for (size_t i = begin; i < end; i += kFilmBlock) {
    const size_t m = std::min(kFilmBlock, end - i);
    draw_film(walk, std::span(samples.data(), m), std::span(film_draws.data(), m));
    camera_rays(std::span(samples.data(), m), std::span(film_draws.data(), m), std::span(rays.data(), m));
    for (size_t b = 0; b < m; ++b) {
      // The free slots' path records, and their cold tables that start_path
      // resets, were last written by whichever thread ended their paths:
      // fetch them a few samples ahead (the cold tables, left to wait, were
      // most of this loop's time at two threads on smoke-grid).
      if (i + b + kSlotPrefetchDistance < end) {
        __builtin_prefetch(&pool[slots[i + b + kSlotPrefetchDistance]], 1);
        pool.prefetch_cold(slots[i + b + kSlotPrefetchDistance]);
      }
      start_camera_path(slots[i + b], samples[b], film_draws[b], rays[b].o);
    }
    // Sample g's ray is ray g % batch of batch g / batch (from the run's first batch).
    for (size_t b = 0; b < m;) {
      const size_t g = i + b, k = g / batch, j = g % batch, n = std::min(m - b, batch - j);
      Batch& to = full[first_batch + n_batches - 1 - k];
      std::copy_n(rays.begin() + ptrdiff_t(b), n, to.rays.begin() + ptrdiff_t(j));
      b += n;
    }
  }
}

}  // namespace theia
