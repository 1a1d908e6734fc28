// Stage: rays that left the scene see the infinite lights, MIS-weighted
// against light sampling, and their paths end.
#include "wavefront/engine_impl.h"

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

// Escaped ray i of the batch (shade_batch's loop runs them first).
void WavefrontEngine::Impl::handle_escaped_ray(size_t i, ShadeOutput& out) {
  // The escaped rays keep their batch's sort order, which scatters the path
  // records: fetch a few ahead (the first load of each was most of this
  // stage's cycles).
  if (i + kEscapedPrefetchDistance < escaped.size())
    __builtin_prefetch(&pool[escaped.paths[i + kEscapedPrefetchDistance]]);
  if (observer)
    handle_escaped<true>(escaped.rays[i], escaped.paths[i], out);
  else
    handle_escaped<false>(escaped.rays[i], escaped.paths[i], out);
}

}  // namespace theia
