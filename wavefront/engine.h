// The sorted-deferred (wavefront) path tracer, as Hyperion does it.
//
// Each thread runs a wavefront of its own (a lane): its pool, batches and
// queues, every stage on its own core, camera samples claimed from a counter
// the lanes share.  Within a lane, paths live in a fixed-capacity pool.
// Camera rays are generated in pixel-sample order whenever occupancy falls
// below a threshold; every ray is queued into one of six batches binned by
// its dominant direction; the most recently filled batch is processed next:
// traced (with sorting on, its rays sorted first by origin Morton code, then
// direction, and its hits by geometry and primitive) and shaded.  Shading
// splats emission and queues continuation and shadow rays; a shadow ray
// carries its pixel and its unoccluded, MIS-weighted contribution, so nothing
// ever waits for a later wave.
#pragma once

#include "cachepoints/light_sampler.h"
#include "core/directional_guide.h"
#include "core/stop.h"
#include "core/stats.h"
#include "wavefront/caustics.h"
#include "scene/accel.h"
#include "scene/camera.h"
#include "scene/filter.h"
#include "scene/lights.h"
#include "wavefront/film.h"
#include "wavefront/observer.h"

#include <atomic>
#include <cstdint>
#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace theia {

struct EngineOptions {
  int max_depth = 5;
  uint32_t seed = 0;
  // Rays per batch and path-state pool capacity; 0: sized from the frame
  // and the thread count (engine_sizes), which is what a render wants unless
  // it measures otherwise.
  size_t batch_size = 0;
  size_t max_paths = 0;
  float occupancy_threshold = 0.5f;       // refill the pool below this fraction
  bool sort = false;                      // sort rays and hits (off: queue order; README, Performance)
  int rr_min_depth = 1;                   // Russian roulette from this depth on (pbrt-v4: depth > 1)
  // >= 0: render the "throughput reset at bounce N" image the recorder's
  // N-th bounce debug buffer is compared with (only light arriving at
  // vertices of depth >= N, throughput 1 at hit N).
  int throughput_reset_bounce = -1;
  // When raised (a SIGTERM handler, a time limit), render() generates no
  // more camera rays, finishes the paths in flight and returns early.
  const StopRequest* stop = nullptr;
  // A signal is a farm taking the machine back within seconds: paths still
  // in flight this long after it was seen are abandoned (abandoned() is then
  // true and the iteration's film is incomplete: the scheduler keeps the last
  // checkpoint, which the resume continues from).  A time limit waits for them.
  double abandon_after_seconds = 2.0;
  // Consistent alpha: only samples with index below alpha_spp count for alpha
  // (and the first-hit AOVs), so alpha has the same samples in every render
  // pass whatever adaptive sampling does with colour.  0: every sample counts.
  uint32_t alpha_spp = 0;
  // Samples per pixel of the whole render: sets pbrt-v4's texture-footprint
  // scale max(1/8, 1/sqrt(spp)) for trilinear imagemaps (scene/camera.h).
  int footprint_spp = 1;
  // Path-space regularisation strength gamma in [0, 1] (seeds/000 ch. 1
  // eq. 25, scene/bsdf.h bsdf_roughen): 0 is off and costs nothing.
  float roughening = 0.0f;
  // A layered BSDF sample's MIS pdf (a second random walk) is computed only
  // where an emitter the ray finds needs it (PathState::prev_pdf, kDeferredPdf).
  // Tests turn it off to compare with the eager pdf; the image is the same but
  // for the rounding of f / pdf.
  bool defer_layered_pdf = true;
  // Path guiding (EngineHooks::guide): how guided vertices sample.
  GuidedSampling guiding;
  // Benchmarks only: when set, every traced ray is appended here in the order
  // it was traced (the medium stage's re-traces past interfaces after their
  // batch), so the raw Embree rate can be measured on the same rays.  With
  // capture_camera_rays set too, camera batches go there instead, so that
  // they can be traced as the engine traces them (in packets).
  std::vector<Ray>* capture_rays = nullptr;
  std::vector<Ray>* capture_camera_rays = nullptr;
  std::vector<Ray>* capture_shadow_rays = nullptr;
};

// What the engine calls that is not the scene: each hook is an interface in
// core/ (or the caustic pass of this folder), null when its feature is off,
// and a feature that is off costs nothing.
struct EngineHooks {
  // Path events (the radiance recorder); without one, shading is compiled
  // without the calls.
  PathObserver* observer = nullptr;
  // Path guiding: at vertices whose BSDF is guidable, directions come from
  // guide and BSDF together, as EngineOptions::guiding says.
  const DirectionalGuide* guide = nullptr;
  // Directly seen caustics traced from the lights (wavefront/caustics.h):
  // when active, camera paths leave those paths to it, and each completed
  // render() call runs its pass for the same samples.  Not with per-pixel
  // sample ranges (adaptive sampling) or the throughput-reset image.
  CausticTracer* caustics = nullptr;
  // > 0: while an observer is attached, at most this share of the pool's
  // paths live at once (not fewer than 2^14): the recorder's vertices of
  // fewer paths in flight stay in cache (guiding's training iterations).
  float observed_pool_share = 0.0f;
};

// The pool and batch sizes a render uses: `options`' where set, otherwise
// sized from the thread count (sorted, from the frame's samples per iteration
// too, so that a small image does not hold a production frame's queues).
struct EngineSizes {
  size_t max_paths = 0;   // all lanes' paths
  size_t batch_size = 0;  // rays per batch of one lane
  size_t lanes = 1;       // wavefronts, one per thread, of max_paths / lanes paths each
  size_t lane_paths() const { return max_paths / lanes; }
};
EngineSizes engine_sizes(const EngineOptions& options, uint64_t pixels, int threads);
// An unsorted lane's paths at any frame size: enough to keep its six
// direction bins' batches of 1024 rays full, few enough that their records
// stay in the core's cache (a sorted lane's pool grows with the frame).
inline constexpr size_t kUnsortedLanePaths = size_t(1) << 13;
// Rays per batch where the options leave it to the engine, for a lane of
// `paths` live paths (engine_sizes).
size_t default_batch_size(size_t paths, bool sort);

// Per-pixel samples of one iteration (adaptive sampling).  Pixel p renders
// samples [begin[p], begin[p] + offset[p+1] - offset[p]); those at or past
// colour_end[p] are alpha-only rays: they measure coverage and nothing else.
struct SampleRanges {
  std::vector<uint32_t> begin;
  std::vector<uint32_t> colour_end;
  std::vector<uint64_t> offset;  // pixel_count + 1 prefix sums of the per-pixel counts
  uint64_t total() const { return offset.empty() ? 0 : offset.back(); }
};

enum class Phase { Generate, Sort, Trace, TraceShadow, Shade, Queue, Caustics, Count };
inline constexpr const char* kPhaseNames[] = {"generate", "sort", "trace", "trace_shadow", "shade", "queue", "caustics"};

struct EngineStats {
  PhaseTimes<Phase, size_t(Phase::Count)> phases;
  uint64_t camera_rays = 0, continuation_rays = 0, shadow_rays = 0;
  uint64_t paths = 0;
  uint64_t path_vertices = 0;   // surface hits over all paths (average path length = vertices / paths)
  uint64_t batches = 0, shadow_batches = 0;
  size_t peak_live_paths = 0;
  size_t peak_queued_rays = 0;
  size_t peak_queued_shadow_rays = 0;
  double render_seconds = 0.0;
  uint64_t total_rays() const { return camera_rays + continuation_rays + shadow_rays; }
};

// Everything the engine needs that is derived once from a Scene: the Embree
// scene, light sampling, camera and filter.  The Scene must outlive it.
struct RenderableScene {
  const Scene& scene;

 private:
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();

 public:
  // Members are built in this order, so accel_seconds times the Embree build alone.
  Accel accel;
  double accel_seconds = seconds_since(start_);
  LightSet lights;
  std::unique_ptr<LightSampler> light_sampler;
  Camera camera;
  Filter filter;

  // light_sampler: uniform, power, bvh, cachepoints, local or auto (make_light_sampler; throws theia::Error otherwise).
  explicit RenderableScene(const Scene& scene, const std::string& light_sampler = "power");
};

class WavefrontEngine {
 public:
  WavefrontEngine(const RenderableScene& rs, Film& film, const EngineOptions& options, const EngineHooks& hooks = {});
  ~WavefrontEngine();
  WavefrontEngine(const WavefrontEngine&) = delete;
  WavefrontEngine& operator=(const WavefrontEngine&) = delete;

  // Renders samples [sample_begin, sample_end) of every pixel and returns
  // when no ray is in flight (one scheduler iteration).  `progress` is called
  // with the fraction of camera samples generated, which never decreases,
  // from the lanes' threads (the calling thread's among them), one call at a time.
  //
  // Camera samples are numbered in pixel-sample order, g = pixel * n + (sample
  // - sample_begin) with n = sample_end - sample_begin; the call renders
  // g in [first_camera_sample, end) and returns how far it got: the end, or
  // less if options.stop was raised.  A stopped iteration is continued
  // exactly by calling again with that value as first_camera_sample.
  uint64_t render(uint32_t sample_begin, uint32_t sample_end, const std::function<void(double)>& progress = {},
                  uint64_t first_camera_sample = 0);
  // The same with a sample range per pixel, numbered g = offset[pixel] + (sample - begin[pixel]).
  uint64_t render(const SampleRanges& ranges, const std::function<void(double)>& progress = {},
                  uint64_t first_camera_sample = 0);
  // The last render() was stopped and its samples are kept as they are (a
  // time limit ends the render there): the caustic pass adds its estimate for
  // that iteration's samples, as a finished iteration's does.  Its splats are
  // parts of camera samples, so only the samples rendered get theirs.
  void finish_stopped_iteration();
  // Between render() calls: no camera sample is generated from `at` on (none:
  // no such time), and render() returns as if stopped.  A time limit sets it
  // short of the limit by the tail that follows the camera samples.
  void stop_camera_samples_at(std::optional<std::chrono::steady_clock::time_point> at);
  // The last render() abandoned paths in flight after a signal (see
  // EngineOptions::abandon_after_seconds): its film and its samples are not
  // a consistent state to keep.
  bool abandoned() const;
  // Between render() calls only: the hooks the next iterations call (a
  // feature that turns itself off, as guiding that does not pay, drops its
  // own, and the engine then shades without them).
  void set_hooks(const EngineHooks& hooks);
  const EngineHooks& hooks() const;

  // The lanes' counts summed; phase seconds are per lane (the lanes run at
  // once, so a phase's mean over them is its share of the wall time).
  const EngineStats& stats() const;
  // The pool and batch sizes in use (engine_sizes of the options).
  EngineSizes sizes() const;
  // Memory the engine holds for paths and queues at their peak.
  size_t memory_bytes() const;

 private:
  struct Impl;  // one lane: a wavefront with its own pool, batches and queues
  uint64_t iterate(uint32_t sample_begin, uint32_t sample_end, const SampleRanges* ranges,
                   uint64_t first_camera_sample, const std::function<void(double)>& progress);
  void run_lanes();
  void end_iteration();

  EngineSizes sizes_;
  std::vector<std::unique_ptr<Impl>> lanes_;  // the first (the lead) runs on the calling thread
  EngineStats stats_;
};

}  // namespace theia
