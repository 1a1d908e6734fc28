// Directly seen caustics, traced from the lights: paths light -> caster ->
// receiver -> camera (L S D E in Heckbert's notation, one caster), where the
// caster is a near-mirror or a glass and the receiver is diffuse.  A small
// light's reflection in a near-mirror, landing on a diffuse wall, is found by
// a camera path only when the wall's diffuse bounce happens to hit the one
// spot of the mirror that sees the light (veach-mis: about once in 3000
// samples, at about 3000 times the pixel's value).  From the light, every
// path that hits the mirror finds it.
//
// The two tracers split path space rather than weighting each other by MIS:
// the engine's camera paths leave out exactly the paths this pass traces (a
// receiver at the primary hit, a caster at the next, then one of this pass's
// lights, reached by NEE or by hitting it), so every path is counted once
// and the sum stays unbiased.  Which paths those are depends only on the
// BSDFs at the two hits (scene/bsdf.h bsdf_is_caustic_caster / _receiver).
#pragma once

#include "core/sampling.h"
#include "scene/accel.h"
#include "scene/camera.h"
#include "scene/filter.h"
#include "scene/lights.h"
#include "wavefront/film.h"

#include <string>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

namespace theia {

struct CausticOptions {
  // Casters: conductors and dielectrics whose every lobe is at most this rough.
  float caster_roughness = 0.1f;
  uint32_t seed = 0;
  // Whether the pass may switch itself off (kCausticDecisionPaths).  A split
  // frame's part cannot see the passes before its samples, so it keeps the
  // pass on: every part then traces the same light paths (farm/README.md).
  bool may_switch_off = true;
};

// The options a render sets (flags --caustics-NAME; see app/options.h);
// the seed is the render's.
template <class V>
void declare_options(V& v, CausticOptions& o) {
  v.image("caster_roughness", o.caster_roughness, "Caustic casters: conductors and dielectrics no rougher than this");
}

struct CausticStats {
  uint64_t paths = 0, caster_hits = 0, receiver_hits = 0, splats = 0;
  uint64_t dropped = 0;  // light paths ended by a non-finite throughput or value (never splatted)
  double seconds = 0.0;
  int switched_off_after = -1;  // passes run before it switched itself off; -1: on
};

// The pass switches itself off (camera paths take every path back from the
// next iteration on) once it has traced kCausticDecisionPaths light paths
// of which fewer than kCausticMinSplatRate reached the camera: casters whose
// caustics the camera does not see (veach-ajar: 6e-5, +25% time for nothing).
inline constexpr uint64_t kCausticDecisionPaths = 100'000;
inline constexpr double kCausticMinSplatRate = 1e-3;

// The camera samples a pass adds to: samples [sample_begin, sample_end) of
// every pixel, numbered as the engine numbers them (g = pixel * n + sample -
// sample_begin, n = sample_end - sample_begin), of which g < rendered are in.
struct CausticSamples {
  uint32_t camera_seed = 0;  // the camera rays' seed (their filter weights)
  uint32_t sample_begin = 0, sample_end = 0;
  uint64_t rendered = 0;
};

class CausticTracer {
 public:
  CausticTracer(const Scene& scene, const Accel& accel, const LightSet& lights, const Camera& camera,
                const Filter& filter, const CausticOptions& options);
  ~CausticTracer();

  // Whether there is anything to trace: a pinhole perspective camera, an
  // area light the pass can emit from, a material that can be a caster, and
  // nothing the two tracers would see differently (interface materials,
  // curves), and the pass has not switched itself off.  When false the
  // engine neither splits path space nor calls trace().  Read once per
  // iteration: each iteration is one unbiased estimate either way.
  bool active() const { return active_ && stats_.switched_off_after < 0; }
  // Area lights without alpha textures and not virtual: the lights whose
  // caustics this pass owns.
  bool traces_light(int light) const { return light >= 0 && size_t(light) < traced_.size() && traced_[size_t(light)]; }
  float caster_roughness() const { return options_.caster_roughness; }
  // Why the pass is off (for the log), empty when active.
  const std::string& inactive_reason() const { return inactive_reason_; }

  // One light path per camera sample of `samples`: sample index s of the
  // frame has one light path per pixel (keyed by seed, index, s).  Where a
  // light path of sample s lands, its splat into pixel p is part of camera
  // sample (p, s): weighted by that sample's filter weight
  // (camera_filter_sample) and added to the film as the sample's own value
  // is, and only if the sample was rendered.  So the film's sums over any set
  // of samples hold exactly their caustics: a frame split into sample ranges
  // anywhere (farm/) merges to the whole render, and a stopped iteration keeps
  // its rendered samples' share.  Deterministic per (seed, samples).
  // `footprint` is the engine's texture footprint at a hit, so that both
  // tracers make the same BSDF there (and agree on casters and receivers).
  void trace(Film& film, const CausticSamples& samples,
             const std::function<UVFootprint(const SurfaceInteraction&)>& footprint);

  const CausticStats& stats() const { return stats_; }
  // Resuming: the counters the switch-off decision reads.
  void restore_stats(const CausticStats& stats, int passes) {
    stats_ = stats;
    passes_ = passes;
  }
  int passes() const { return passes_; }

 private:
  struct Pass;  // one call of trace(): its light paths
  // What passes share: the scene's caster boxes and sphere estimates, made
  // by the first pass and kept.
  struct Scratch;
  std::unique_ptr<Scratch> scratch_;
  const Scene& scene_;
  const Accel& accel_;
  const LightSet& lights_;
  const Camera& camera_;
  const Filter& filter_;
  CausticOptions options_;
  bool active_ = false;
  std::string inactive_reason_;
  std::vector<uint8_t> traced_;  // per scene light
  std::vector<uint8_t> casting_;  // per material: may make a caster (material_may_cast in caustics.cpp)
  std::vector<int> light_of_entry_;
  Distribution1D light_distribution_;  // over the traced lights, by power
  CausticStats stats_;
  int passes_ = 0;
};

}  // namespace theia
