// Stage: trace the queued shadow rays and splat the contribution of every
// unoccluded one (it was computed when the ray was queued).
#include "wavefront/engine_impl.h"

namespace theia {

// Shadow rays are visited in ray order, their vertices live wherever the
// observer put them: hint it this many rays ahead.
constexpr size_t kObserverPrefetch = 8;

void WavefrontEngine::Impl::trace_shadow_rays() {
  const size_t n = shadows.size();
  if (n == 0) return;
  ++stats.shadow_batches;
  stats.shadow_rays += n;
  ShadowQueue& s = shadows;
  if (opt.sort) {
    ScopedTimer timer(stats.phases[Phase::Sort]);
    sort_by_ray_key(s.rays, bounds_min, bounds_inv_extent, keys, scratch, order);
    queue_gather(s, order, shadows_sorted);
  }
  if (opt.capture_shadow_rays)
    opt.capture_shadow_rays->insert(opt.capture_shadow_rays->end(), s.rays.begin(), s.rays.end());
  blocked.assign(n, 0);
  if (!s.medium.empty()) {
    attenuate_shadow_rays_in_media();
  } else {
    ScopedTimer timer(stats.phases[Phase::TraceShadow]);
    stage_loop(n, 256, [&](const tbb::blocked_range<size_t>& r) {
      std::span<const PrimRef> skips;
      if (!s.skip.empty()) skips = std::span<const PrimRef>(s.skip.data() + r.begin(), r.size());
      accel.occluded(std::span<const Ray>(s.rays.data() + r.begin(), r.size()),
                     std::span<uint8_t>(blocked.data() + r.begin(), r.size()), skips);
    });
  }
  {
    ScopedTimer timer(stats.phases[Phase::Shade]);
    apply_deferred_nee_mis();
    stage_loop(n, 1024, [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i < r.end(); ++i) {
        if (observer && i + kObserverPrefetch < n) observer->prefetch(s.vertex[i + kObserverPrefetch]);
        if (!blocked[i]) film.splat(s.pixel[i], s.sample[i], s.contribution[i], s.event.empty() ? 0 : s.event[i]);
        if (!s.chosen.empty()) light_sampler.record_shadow(s.chosen[i], !blocked[i]);
        if (observer) {
          // An occluded NEE ray still finishes its vertex: a zero sample.
          if (!blocked[i]) observer->emission_added(s.vertex[i], s.pixel[i], s.contribution[i], s.mis_weight[i]);
          observer->vertex_done(s.vertex[i]);
        }
      }
    });
  }
  queue_clear(s);
}

}  // namespace theia
