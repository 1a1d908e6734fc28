// Stage: rays that left the scene see the infinite lights, MIS-weighted
// against light sampling, and their paths end.
#include "wavefront/engine_impl.h"

#include <tbb/parallel_for.h>

namespace theia {

namespace {

// How many rays ahead the stage fetches their path records.
constexpr size_t kEscapedPrefetchDistance = 8;

}  // namespace

template <bool kObserve>
void WavefrontEngine::Impl::handle_escaped(const Ray& ray, uint32_t slot, ShadeOutput& out) {
  const PathState& ps = pool[slot];
  if (!ps.alpha_only) {
    const vec3 d = glm::normalize(ray.d);
    for (int l : lights.infinite_lights) {
      RGB Le = infinite_light_Le(lights, l, d);
      if (!is_black(Le)) add_emission<kObserve>(ps, l, Le, [&] { return infinite_light_pdf(lights, l, d); });
    }
  }
  finish_path<kObserve>(slot, out);
}

void WavefrontEngine::Impl::handle_escaped_rays() {
  const size_t n = escaped.size();
  if (n == 0) return;
  ScopedTimer timer(stats.phases[Phase::Shade]);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 256), [&](const tbb::blocked_range<size_t>& r) {
    ShadeOutput& out = outputs.local();
    for (size_t i = r.begin(); i < r.end(); ++i) {
      // The escaped rays keep their batch's sort order, which scatters the
      // path records: fetch a few ahead (the first load of each was most
      // of this stage's cycles).
      if (i + kEscapedPrefetchDistance < n) __builtin_prefetch(&pool[escaped.paths[i + kEscapedPrefetchDistance]]);
      if (observer)
        handle_escaped<true>(escaped.rays[i], escaped.paths[i], out);
      else
        handle_escaped<false>(escaped.rays[i], escaped.paths[i], out);
    }
  });
}

}  // namespace theia
