// The Radiance Recorder (Hyperion, "Path Guiding Surfaces and Volumes",
// section 3): turns the wavefront's feed-forward path events into one
// incident-radiance training sample per recorded path vertex.
//
// A vertex lives until every ray descending from it has finished (reference
// count); then its accumulated emission, divided by its throughput, is its
// incident radiance, and the emission is handed to its parent
// (backpropagation).  Memory is bounded by path skipping (a per-iteration rate
// from a per-path vertex budget), stochastic vertex skipping and a minimum
// parent-child distance.  Debug buffers re-splat the primary-hit (and N-th
// bounce) samples so they can be compared with the beauty pass.
#pragma once

#include "core/path_observer.h"
#include "core/radix_sort.h"

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

namespace theia {

// ---------------------------------------------------------------- handles

using PVIndex = uint32_t;
inline constexpr uint32_t kPVBlockSize = 4096;
inline constexpr PVIndex kPVNone = kNoVertex;      // the camera: no vertex to record
inline constexpr PVIndex kPVSkipped = 0xfffffffeu; // a skipped path: never allocates, never has children
// A vertex that was not recorded (vertex skipping) whose parent is the camera:
// its emission has no recorded ancestor, but its children are recorded.
inline constexpr PVIndex kPVDetached = 0xfffffffdu;
// Set on a handle that names an ancestor continued in place of an unrecorded
// child: what arrives through it is indirect light for that ancestor.
inline constexpr PVIndex kPVMergedBit = 0x80000000u;
inline constexpr uint32_t kPVMaxBlocks = (kPVMergedBit / kPVBlockSize);

// ---------------------------------------------------------------- samples

enum VertexFlags : uint8_t {
  kVertexNEE = 1 << 0,      // created for an NEE ray
  kVertexInMedium = 1 << 1, // created inside a medium
  kVertexDelta = 1 << 2,    // a direction without a density: a delta (specular) lobe or an NEE ray to a delta light
  kVertexGlossy = 1 << 3,   // sampled from a glossy lobe
};

// What a training sample's radiance holds (seeds/000 ch. 1 section 5).
enum class TrainingMode {
  All,                  // direct (unweighted) + indirect: the full incident-radiance estimate
  IndirectOnly,         // what arrives through later scattering only
  IndirectPlusMISDirect // indirect + MIS-weighted direct (Ruppert et al. 2020; course notes ch. 1 eq. 23)
};

// "mis-direct" | "all" | "indirect"; throws theia::Error naming the flag otherwise.
TrainingMode parse_training_mode(const std::string& name);

struct TrainingSample {
  vec3 p{0.0f};
  vec3 wi{0.0f};        // direction of the vertex's ray (incident radiance arrives from it)
  RGB radiance{0.0f};   // incident radiance along wi, per the mode
  float pdf = 0.0f;
  // luminance(f |cos| / pdf) of the scattering, and the BSDF's and the guide's
  // densities of wi over the density it was drawn with (both 0 unless the
  // direction came from a guide-and-BSDF mixture): what learning the
  // selection probability needs (PathVertexInfo::bsdf_ratio).
  float scattering_weight = 0.0f;
  float bsdf_ratio = 0.0f, guide_ratio = 0.0f;
  float roughness = 1.0f;
  uint32_t pixel = 0, sample = 0;
  uint16_t depth = 0;
  uint8_t flags = 0;    // VertexFlags
};

// Where samples go: guiding implements this.  consume() is called from the
// thread that calls end_iteration(), once, with the iteration's samples
// sorted by (pixel, sample, depth, flags), an order that does not depend on
// the thread count, so that training is deterministic.  Only samples that can
// train are handed over: none for a direction without a density (kVertexDelta)
// or from a BSDF the engine does not guide (PathVertexInfo::guidable).
class TrainingSampleSink {
 public:
  virtual ~TrainingSampleSink() = default;
  virtual void consume(std::span<const TrainingSample> samples) = 0;
  // Whether NEE rays' vertices are samples to it.  When not, they are not
  // recorded (their light still reaches the parent), as for every vertex
  // that cannot train.
  virtual bool wants_nee_samples() const { return true; }
};

// The sorted samples cut at fixed offsets (the same chunks whatever the
// thread count), for a sink that trains in parallel: chunk c of
// training_chunks(n) is [c * kTrainingChunk, min(n, (c + 1) * kTrainingChunk)).
// Reducing per-chunk results in chunk order keeps training deterministic.
inline constexpr size_t kTrainingChunk = size_t(1) << 14;
inline size_t training_chunks(size_t samples) { return (samples + kTrainingChunk - 1) / kTrainingChunk; }
inline std::span<const TrainingSample> training_chunk(std::span<const TrainingSample> samples, size_t c) {
  const size_t begin = std::min(samples.size(), c * kTrainingChunk);
  return samples.subspan(begin, std::min(kTrainingChunk, samples.size() - begin));
}

// Counts and keeps every sample (tests).
class StoringSampleSink final : public TrainingSampleSink {
 public:
  void consume(std::span<const TrainingSample> s) override { samples.insert(samples.end(), s.begin(), s.end()); }
  std::vector<TrainingSample> samples;
};

// ---------------------------------------------------------------- options and stats

struct RecorderOptions {
  // What a sample's radiance holds (TrainingMode): "mis-direct" (eq. 23,
  // the default), "all" (eq. 21) or "indirect" (eq. 22).
  std::string training = "mis-direct";
  float vertex_budget = 4.0f;          // target recorded vertices per path; <= 0: no path skipping
  float vertex_skip_probability = 0.0f;// stochastic vertex skipping
  // In-medium vertices are skipped with this probability as well (seeds/000
  // ch. 2 section 5.1.3): a dense medium makes far more of them than surfaces
  // do, and skipping them lets a path record deep in the medium within its budget.
  float medium_skip_probability = 0.0f;
  float min_distance = 0.0f;           // closer to its parent than this: the parent is continued instead
  uint32_t seed = 0;
  // Debug buffers (section 4.1); width * height pixels, RGB sums.
  int width = 0, height = 0;
  bool debug = false;                  // the primary-hit buffer (equals the beauty)
  int debug_bounce = -1;               // >= 0: also the N-th bounce buffer
  uint32_t max_blocks = 1u << 16;      // hard cap on storage: 2^16 blocks = 268M vertices
};

// The options a render sets, each once (flags --recorder-NAME; see
// app/options.h for what image / output mean); the others are set by the
// renderer (seed, film size) or keep their defaults.
template <class V>
void declare_options(V& v, RecorderOptions& o) {
  v.image("training", o.training,
          "What training samples hold: mis-direct (indirect + MIS-weighted direct, eq. 23), all (eq. 21) or "
          "indirect (eq. 22)");
  v.image("vertex_budget", o.vertex_budget, "Recorded vertices per path (path skipping); 0: off");
  v.image("vertex_skip_probability", o.vertex_skip_probability, "Probability of skipping a path vertex, in [0, 1)");
  v.image("medium_skip_probability", o.medium_skip_probability,
          "Probability of skipping an in-medium vertex (besides vertex_skip_probability), in [0, 1)");
  v.image("min_distance", o.min_distance, "Closer than this to its parent, a vertex is merged into the parent");
  v.image("debug", o.debug, "Write the recorder's primary-hit debug layer 'recorder' (equals the beauty)");
  v.image("debug_bounce", o.debug_bounce,
          "Also write layer 'recorder_bounceN' (compare with --throughput-reset-bounce N; default: none)");
}

struct RecorderStats {
  uint64_t paths = 0, skipped_paths = 0;
  uint64_t vertex_events = 0;          // vertex_created calls (the unskipped path length)
  uint64_t recorded = 0;               // vertices allocated (= samples produced)
  uint64_t skipped_vertices = 0, merged_vertices = 0;
  uint64_t untrainable = 0;            // vertices that cannot train (delta, unguided BSDF): no sample
  uint64_t untrainable_merged = 0;     // ... of which not even allocated (merged into the parent)
  uint64_t samples = 0;                // training samples handed to the sink
  uint64_t dropped = 0;                // non-finite samples or debug splats
  uint64_t peak_live_vertices = 0;           // over the whole run
  uint64_t iteration_peak_live_vertices = 0; // in the current (or last) iteration
  uint64_t peak_blocks = 0;
  uint64_t peak_sample_bytes = 0;
  double path_skip_rate = 0.0;         // of the current (last begun) iteration
  double average_path_length = 0.0;    // vertex events per path in the last finished iteration
  // end_iteration(), over the run: sorting the samples, and the sink's consume().
  double sort_seconds = 0.0, consume_seconds = 0.0;
};

// Path skip rate for an iteration given the previous one (section 3.4.4):
// keep budget * paths of the vertices; 8 paths x 8 vertices, budget 4 -> 0.5.
double path_skip_rate(uint64_t paths, uint64_t vertices, double budget);

// ---------------------------------------------------------------- the recorder

class RadianceRecorder final : public PathObserver {
 public:
  explicit RadianceRecorder(const RecorderOptions& options, TrainingSampleSink* sink = nullptr);
  ~RadianceRecorder() override;
  RadianceRecorder(const RadianceRecorder&) = delete;
  RadianceRecorder& operator=(const RadianceRecorder&) = delete;

  // Around each engine render() call (no ray may be in flight at either).
  // begin sets this iteration's path skip rate from the last one; end hands
  // the samples to the sink and checks that nothing is left allocated.
  void begin_iteration();
  void end_iteration();
  // Between iterations (the scheduler's recorder-skip-rate slot): the next
  // iteration's path skip rate from this one's average path length and the budget.
  void update_skip_rate();

  uint32_t path_started(uint32_t pixel, uint32_t sample) override;
  uint32_t vertex_created(uint32_t parent, const PathVertexInfo& v) override;
  void emission_added(uint32_t vertex, uint32_t pixel, const RGB& contribution, float mis_weight) override;
  void vertex_continued(uint32_t vertex) override;
  void vertex_done(uint32_t vertex) override;
  void prefetch(uint32_t vertex) const override;

  // Resuming (checkpoint/).  The engine finishes every path before a
  // checkpoint, so no vertex is live then; what the iteration in progress has
  // recorded and counted is carried over, so that a resumed render trains
  // on the same samples and sets the same skip rate as an uninterrupted one.
  struct ResumeState {
    double skip_rate = 0.0;
    uint64_t iteration_paths = 0, iteration_events = 0;
    std::vector<TrainingSample> samples;
  };
  ResumeState resume_state() const;
  void restore(const ResumeState& state);

  RecorderStats stats() const;
  uint64_t live_vertices() const;      // exact when no event is in progress
  size_t peak_bytes() const;           // vertex blocks at their peak + buffered samples at theirs
  static size_t vertex_bytes();
  // Debug sums (RGB per pixel, in film units: divide by the film's weight).
  const std::vector<float>& debug_primary() const { return debug_primary_; }
  const std::vector<float>& debug_bounce() const { return debug_bounce_; }
  const RecorderOptions& options() const { return opt_; }

 private:
  struct Vertex;
  struct Block;
  struct ThreadCache;

  ThreadCache& cache() const;
  Vertex& at(PVIndex i) const;
  bool trainable(const PathVertexInfo& info) const;
  bool skipped(const PathVertexInfo& info) const;
  double keep_probability(bool in_medium) const;  // of a vertex, given the path was not skipped
  bool debug_records(int depth) const;
  PVIndex allocate(ThreadCache& tc);
  void release(ThreadCache& tc, PVIndex i);
  void flush_live(ThreadCache& tc);
  uint64_t iteration_peak_live() const;
  void finish(ThreadCache& tc, PVIndex i);      // drop one reference; backpropagate at zero
  void record(ThreadCache& tc, Vertex& v);
  // Every thread's samples, sorted (into sorted_, valid until the next call); the threads' emptied.
  std::span<const TrainingSample> sorted_samples();

  RecorderOptions opt_;
  TrainingMode mode_;
  TrainingSampleSink* sink_;
  std::unique_ptr<std::atomic<Block*>[]> blocks_;
  std::atomic<uint32_t> block_count_{0};
  std::mutex free_mutex_;                       // guards free_ and block creation
  std::vector<PVIndex> free_;                   // global free queue, refilled in batches
  tbb::enumerable_thread_specific<ThreadCache>* caches_;
  const uint64_t id_;                           // names this recorder to the threads' cache() shortcut
  // Threads add their allocations here in batches (ThreadCache::live), so the
  // count is exact between iterations and the peak (ThreadCache::peak) within
  // a batch per thread.
  std::atomic<int64_t> live_{0};
  int64_t peak_live_ = 0;                       // live at the iteration's start
  uint64_t run_peak_live_ = 0;
  uint64_t peak_sample_bytes_ = 0;
  double skip_rate_ = 0.0;
  uint64_t last_paths_ = 0, last_events_ = 0;                    // the previous iteration's
  uint64_t iteration_begin_paths_ = 0, iteration_begin_events_ = 0;
  uint64_t carried_paths_ = 0, carried_events_ = 0;              // restored from a checkpoint
  std::vector<float> debug_primary_, debug_bounce_;
  double sort_seconds_ = 0.0, consume_seconds_ = 0.0;
  uint64_t samples_ = 0;
  // The sort's arrays, kept across iterations: an iteration of a million
  // samples would otherwise allocate and zero ~90 MB on one thread.
  std::vector<SortPair> keys_, scratch_;
  std::vector<TrainingSample> sorted_;
};

}  // namespace theia
