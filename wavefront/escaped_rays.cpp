// Stage: rays that left the scene see the infinite lights, MIS-weighted
// against light sampling, and their paths end.
#include "wavefront/engine_impl.h"

namespace theia {

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

// What handle_escaped does with a miss beyond ending its path: nothing
// without infinite lights to see it or an observer to tell (and, in media, a
// path's ray may have left its batch without reaching its hit).
bool WavefrontEngine::Impl::misses_only_end_paths() const {
  return lights.infinite_lights.empty() && !observer && pool.medium.empty();
}

void WavefrontEngine::Impl::handle_escaped_ray(const Ray& ray, uint32_t slot, ShadeOutput& out) {
  if (observer)
    handle_escaped<true>(ray, slot, out);
  else
    handle_escaped<false>(ray, slot, out);
}

}  // namespace theia
