#include "radiance_recorder/recorder.h"

#include "core/hash.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace theia {

namespace {

// Indices move between a thread's cache and the global queue this many at a
// time, so the lock is taken once per this many allocations or frees.
constexpr size_t kFreeBatch = 256;

void atomic_add(RGB& target, const RGB& v) {
  for (int c = 0; c < 3; ++c) theia::atomic_add(target[c], v[c]);
}
RGB load(RGB& v) {
  RGB r;
  for (int c = 0; c < 3; ++c) r[c] = std::atomic_ref<float>(v[c]).load(std::memory_order_relaxed);
  return r;
}

// Octahedral unit-vector encoding, 16 bits per coordinate (~0.003 degrees):
// normals are for display and filtering, not for shading.
uint32_t encode_unit(vec3 n) {
  float l1 = std::abs(n.x) + std::abs(n.y) + std::abs(n.z);
  if (!(l1 > 0.0f)) return 0x7fff7fffu;
  vec2 e(n.x / l1, n.y / l1);
  if (n.z < 0.0f) e = vec2((1.0f - std::abs(e.y)) * (e.x >= 0.0f ? 1.0f : -1.0f),
                           (1.0f - std::abs(e.x)) * (e.y >= 0.0f ? 1.0f : -1.0f));
  auto q = [](float c) { return uint32_t(std::clamp(std::round((c * 0.5f + 0.5f) * 65535.0f), 0.0f, 65535.0f)); };
  return q(e.x) | (q(e.y) << 16);
}
vec3 decode_unit(uint32_t v) {
  vec2 e(float(v & 0xffffu) / 65535.0f * 2.0f - 1.0f, float(v >> 16) / 65535.0f * 2.0f - 1.0f);
  vec3 n(e.x, e.y, 1.0f - std::abs(e.x) - std::abs(e.y));
  if (n.z < 0.0f) {
    float x = n.x;
    n.x = (1.0f - std::abs(n.y)) * (x >= 0.0f ? 1.0f : -1.0f);
    n.y = (1.0f - std::abs(x)) * (n.y >= 0.0f ? 1.0f : -1.0f);
  }
  return glm::normalize(n);
}

// em / tp per channel; a channel the path cannot carry (tp = 0) carries nothing.
RGB divide(const RGB& em, const glm::dvec3& tp) {
  RGB r;
  for (int c = 0; c < 3; ++c) r[c] = tp[c] != 0.0 ? float(double(em[c]) / tp[c]) : 0.0f;
  return r;
}

bool is_special(PVIndex h) { return h == kPVNone || h == kPVSkipped || h == kPVDetached; }

}  // namespace

// 128 bytes: two cache lines.  Emissions are in film units (see
// core/path_observer.h) and are summed with float atomics; the throughput,
// the long product, is double.
struct RadianceRecorder::Vertex {
  glm::dvec3 tp;           // path throughput at the vertex (camera weight included)
  vec3 p;                  // origin of the vertex's ray
  vec3 wi;                 // its direction
  RGB em_indirect;         // from children and merged (unrecorded) descendants
  RGB em_direct;           // found by the vertex's own ray, MIS-weighted (as splatted)
  RGB em_direct_unweighted;// the same without the MIS weight (TrainingMode::All)
  RGB local;               // the scattering's own factor (N-th bounce debug buffer)
  uint32_t n_oct;          // shading normal, octahedral
  float pdf;
  float camera_weight;
  uint32_t pixel, sample;
  PVIndex parent;
  std::atomic<uint32_t> refs;
  uint16_t depth;
  uint8_t flags;
  uint8_t roughness;       // quantised to 1/255
};
struct RadianceRecorder::Block {
  static_assert(sizeof(Vertex) == 128, "keep a path vertex at two cache lines (the README says so)");
  Vertex v[kPVBlockSize];
};

struct RadianceRecorder::ThreadCache {
  std::vector<PVIndex> free;
  std::vector<TrainingSample> samples;
  uint64_t paths = 0, skipped_paths = 0, vertex_events = 0, recorded = 0, skipped_vertices = 0, merged = 0,
           dropped = 0;
};

double path_skip_rate(uint64_t paths, uint64_t vertices, double budget) {
  if (budget <= 0.0 || paths == 0 || vertices == 0) return 0.0;
  double keep = budget * double(paths) / double(vertices);
  return std::clamp(1.0 - keep, 0.0, 1.0);
}

size_t RadianceRecorder::vertex_bytes() { return sizeof(Vertex); }

RadianceRecorder::RadianceRecorder(const RecorderOptions& options, TrainingSampleSink* sink)
    : opt_(options), sink_(sink), caches_(new tbb::enumerable_thread_specific<ThreadCache>()) {
  opt_.max_blocks = std::clamp<uint32_t>(opt_.max_blocks, 1, kPVMaxBlocks);
  opt_.vertex_skip_probability = std::clamp(opt_.vertex_skip_probability, 0.0f, 1.0f);
  blocks_ = std::make_unique<std::atomic<Block*>[]>(opt_.max_blocks);
  for (uint32_t b = 0; b < opt_.max_blocks; ++b) blocks_[b].store(nullptr, std::memory_order_relaxed);
  size_t pixels = size_t(std::max(opt_.width, 0)) * size_t(std::max(opt_.height, 0));
  if (opt_.debug) debug_primary_.assign(3 * pixels, 0.0f);
  if (opt_.debug_bounce >= 0) debug_bounce_.assign(3 * pixels, 0.0f);
}

RadianceRecorder::~RadianceRecorder() {
  for (uint32_t b = 0; b < block_count_.load(); ++b) delete blocks_[b].load();
  delete caches_;
}

RadianceRecorder::Vertex& RadianceRecorder::at(PVIndex i) const {
  return blocks_[i / kPVBlockSize].load(std::memory_order_acquire)->v[i % kPVBlockSize];
}

PVIndex RadianceRecorder::allocate(ThreadCache& tc) {
  if (tc.free.empty()) {
    std::lock_guard lock(free_mutex_);
    if (free_.size() >= kFreeBatch) {
      tc.free.assign(free_.end() - kFreeBatch, free_.end());
      free_.resize(free_.size() - kFreeBatch);
    } else if (!free_.empty()) {
      tc.free.swap(free_);
    } else {
      uint32_t b = block_count_.load(std::memory_order_relaxed);
      if (b >= opt_.max_blocks) return kPVSkipped;
      blocks_[b].store(new Block, std::memory_order_release);
      block_count_.store(b + 1, std::memory_order_release);
      // This thread keeps one batch; the rest of the block goes to the queue.
      for (uint32_t k = kPVBlockSize; k-- > 0;) {
        PVIndex i = b * kPVBlockSize + k;
        (k < kFreeBatch ? tc.free : free_).push_back(i);
      }
    }
  }
  PVIndex i = tc.free.back();
  tc.free.pop_back();
  uint64_t now = live_.fetch_add(1, std::memory_order_relaxed) + 1;
  uint64_t peak = peak_live_.load(std::memory_order_relaxed);
  while (now > peak && !peak_live_.compare_exchange_weak(peak, now, std::memory_order_relaxed)) {
  }
  return i;
}

void RadianceRecorder::release(ThreadCache& tc, PVIndex i) {
  live_.fetch_sub(1, std::memory_order_relaxed);
  tc.free.push_back(i);
  if (tc.free.size() >= 2 * kFreeBatch) {
    std::lock_guard lock(free_mutex_);
    free_.insert(free_.end(), tc.free.end() - kFreeBatch, tc.free.end());
    tc.free.resize(tc.free.size() - kFreeBatch);
  }
}

// ---------------------------------------------------------------- events

uint32_t RadianceRecorder::path_started(uint32_t pixel, uint32_t sample) {
  ThreadCache& tc = caches_->local();
  ++tc.paths;
  if (skip_rate_ > 0.0 && to_unit_float(uint32_t(hash(opt_.seed, pixel, sample, 0x5c1bu))) < skip_rate_) {
    ++tc.skipped_paths;
    return kPVSkipped;
  }
  return kPVNone;
}

uint32_t RadianceRecorder::vertex_created(uint32_t parent, const PathVertexInfo& info) {
  ThreadCache& tc = caches_->local();
  ++tc.vertex_events;
  if (parent == kPVSkipped) return kPVSkipped;
  const PVIndex real_parent = (parent == kPVNone || parent == kPVDetached) ? kPVNone : parent & ~kPVMergedBit;

  // Not recorded: the nearest recorded ancestor is continued in its place, so
  // what arrives along this ray still reaches it (as indirect light).
  auto merge = [&]() -> PVIndex {
    if (real_parent == kPVNone) return kPVDetached;
    at(real_parent).refs.fetch_add(1, std::memory_order_relaxed);
    return real_parent | kPVMergedBit;
  };
  if (opt_.vertex_skip_probability > 0.0f &&
      to_unit_float(uint32_t(hash(opt_.seed, info.pixel, info.sample, uint32_t(info.depth), uint32_t(info.is_nee),
                                  0x5eedu))) < opt_.vertex_skip_probability) {
    ++tc.skipped_vertices;
    return merge();
  }
  if (opt_.min_distance > 0.0f && real_parent != kPVNone &&
      glm::distance(at(real_parent).p, info.p) < opt_.min_distance) {
    ++tc.merged;
    return merge();
  }
  PVIndex i = allocate(tc);
  if (i == kPVSkipped) {  // storage cap reached
    ++tc.skipped_vertices;
    return merge();
  }
  ++tc.recorded;
  Vertex& v = at(i);
  v.tp = glm::dvec3(info.prefix) * glm::dvec3(info.local);
  v.p = info.p;
  v.wi = info.wi;
  v.em_indirect = v.em_direct = v.em_direct_unweighted = RGB(0.0f);
  v.local = info.local;
  v.n_oct = encode_unit(info.n);
  v.pdf = info.pdf;
  v.camera_weight = info.camera_weight;
  v.pixel = info.pixel;
  v.sample = info.sample;
  v.parent = real_parent;
  v.depth = uint16_t(std::clamp(info.depth, 0, 0xffff));
  v.flags = uint8_t((info.is_nee ? kVertexNEE : 0) | (info.in_medium ? kVertexInMedium : 0) |
                    ((info.lobe_flags & (1 << 4)) || info.delta_light ? kVertexDelta : 0) | ((info.lobe_flags & (1 << 3)) ? kVertexGlossy : 0));
  v.roughness = uint8_t(std::round(std::clamp(info.roughness, 0.0f, 1.0f) * 255.0f));
  // Publish the initialised vertex before anyone can reach it through the handle.
  v.refs.store(1, std::memory_order_release);
  if (real_parent != kPVNone) at(real_parent).refs.fetch_add(1, std::memory_order_relaxed);
  return i;
}

void RadianceRecorder::emission_added(uint32_t vertex, uint32_t pixel, const RGB& c, float mis_weight) {
  if (vertex == kPVSkipped || vertex == kPVDetached) return;
  if (vertex == kPVNone) {
    // Seen directly from the camera: part of the beauty, in no vertex.
    if (!debug_primary_.empty()) {
      if (!is_finite(c)) {
        ++caches_->local().dropped;
        return;
      }
      for (int k = 0; k < 3; ++k) atomic_add(debug_primary_[3 * size_t(pixel) + k], c[k]);
    }
    return;
  }
  Vertex& v = at(vertex & ~kPVMergedBit);
  if (vertex & kPVMergedBit) {
    atomic_add(v.em_indirect, c);
    return;
  }
  atomic_add(v.em_direct, c);
  if (mis_weight > 0.0f) atomic_add(v.em_direct_unweighted, c / mis_weight);
}

void RadianceRecorder::vertex_continued(uint32_t vertex) {
  if (is_special(vertex)) return;
  at(vertex & ~kPVMergedBit).refs.fetch_add(1, std::memory_order_relaxed);
}

void RadianceRecorder::vertex_done(uint32_t vertex) {
  if (is_special(vertex)) return;
  finish(caches_->local(), vertex & ~kPVMergedBit);
}

// Backpropagation (section 3.4.3), as a loop up the parent chain.
void RadianceRecorder::finish(ThreadCache& tc, PVIndex i) {
  while (true) {
    Vertex& v = at(i);
    // acq_rel: the thread that takes the count to zero sees every emission
    // added (relaxed) before the other threads' decrements.
    if (v.refs.fetch_sub(1, std::memory_order_acq_rel) != 1) return;
    record(tc, v);
    RGB total = load(v.em_indirect) + load(v.em_direct);
    PVIndex parent = v.parent;
    release(tc, i);
    if (parent == kPVNone) return;
    if (is_finite(total)) atomic_add(at(parent).em_indirect, total);
    i = parent;
  }
}

void RadianceRecorder::record(ThreadCache& tc, Vertex& v) {
  const RGB indirect = load(v.em_indirect), direct = load(v.em_direct);
  const RGB total = indirect + direct;
  const double keep = (1.0 - skip_rate_) * (1.0 - double(opt_.vertex_skip_probability));
  const float debug_weight = keep > 0.0 ? float(1.0 / keep) : 0.0f;

  if (!debug_primary_.empty() && v.depth == 0) {
    RGB d = total * debug_weight;
    if (is_finite(d))
      for (int k = 0; k < 3; ++k) atomic_add(debug_primary_[3 * size_t(v.pixel) + k], d[k]);
    else
      ++tc.dropped;
  }
  if (!debug_bounce_.empty() && int(v.depth) == opt_.debug_bounce) {
    // Incident radiance x local response, without the prefix throughput.
    RGB d = divide(total, v.tp) * v.local * (v.camera_weight * debug_weight);
    if (is_finite(d))
      for (int k = 0; k < 3; ++k) atomic_add(debug_bounce_[3 * size_t(v.pixel) + k], d[k]);
    else
      ++tc.dropped;
  }
  if (!sink_) return;

  RGB radiance = divide(indirect, v.tp);
  if (opt_.mode == TrainingMode::IndirectPlusMISDirect) radiance += divide(direct, v.tp);
  if (opt_.mode == TrainingMode::All) radiance += divide(load(v.em_direct_unweighted), v.tp);
  if (!is_finite(radiance)) {
    ++tc.dropped;
    return;
  }
  TrainingSample s;
  s.p = v.p;
  s.wi = v.wi;
  s.n = decode_unit(v.n_oct);
  s.radiance = radiance;
  s.pdf = v.pdf;
  s.roughness = float(v.roughness) / 255.0f;
  s.pixel = v.pixel;
  s.sample = v.sample;
  s.depth = v.depth;
  s.flags = v.flags;
  tc.samples.push_back(s);
}

// ---------------------------------------------------------------- iterations

void RadianceRecorder::update_skip_rate() { skip_rate_ = path_skip_rate(last_paths_, last_events_, opt_.vertex_budget); }

void RadianceRecorder::begin_iteration() {
  run_peak_live_ = std::max(run_peak_live_, peak_live_.load());
  peak_live_.store(live_.load());
  RecorderStats s = stats();
  iteration_begin_paths_ = s.paths;
  iteration_begin_events_ = s.vertex_events;
}

void RadianceRecorder::end_iteration() {
  RecorderStats s = stats();
  last_paths_ = s.paths - iteration_begin_paths_ + carried_paths_;
  last_events_ = s.vertex_events - iteration_begin_events_ + carried_events_;
  carried_paths_ = carried_events_ = 0;
  iteration_begin_paths_ = s.paths;  // nothing is in progress until the next begin
  iteration_begin_events_ = s.vertex_events;
  if (live_.load() != 0)
    throw std::logic_error("radiance recorder: " + std::to_string(live_.load()) +
                           " path vertices still allocated at the end of an iteration (an event was lost)");
  size_t count = 0;
  for (ThreadCache& tc : *caches_) count += tc.samples.size();
  peak_sample_bytes_ = std::max<uint64_t>(peak_sample_bytes_, count * sizeof(TrainingSample));
  if (!sink_) return;
  std::vector<TrainingSample> all;
  all.reserve(count);
  for (ThreadCache& tc : *caches_) {
    all.insert(all.end(), tc.samples.begin(), tc.samples.end());
    tc.samples.clear();
  }
  // Deterministic order whatever the threads did.
  std::sort(all.begin(), all.end(), [](const TrainingSample& a, const TrainingSample& b) {
    if (a.pixel != b.pixel) return a.pixel < b.pixel;
    if (a.sample != b.sample) return a.sample < b.sample;
    if (a.depth != b.depth) return a.depth < b.depth;
    return a.flags < b.flags;
  });
  sink_->consume(all);
}

RadianceRecorder::ResumeState RadianceRecorder::resume_state() const {
  if (live_.load() != 0)
    throw std::logic_error("radiance recorder: checkpoint requested with path vertices still allocated");
  ResumeState st;
  st.skip_rate = skip_rate_;
  RecorderStats s = stats();
  st.iteration_paths = s.paths - iteration_begin_paths_ + carried_paths_;
  st.iteration_events = s.vertex_events - iteration_begin_events_ + carried_events_;
  for (const ThreadCache& tc : *caches_) st.samples.insert(st.samples.end(), tc.samples.begin(), tc.samples.end());
  return st;
}

void RadianceRecorder::restore(const ResumeState& st) {
  skip_rate_ = st.skip_rate;
  carried_paths_ = st.iteration_paths;
  carried_events_ = st.iteration_events;
  for (ThreadCache& tc : *caches_) tc.samples.clear();
  caches_->local().samples = st.samples;
}

RecorderStats RadianceRecorder::stats() const {
  RecorderStats s;
  for (const ThreadCache& tc : *caches_) {
    s.paths += tc.paths;
    s.skipped_paths += tc.skipped_paths;
    s.vertex_events += tc.vertex_events;
    s.recorded += tc.recorded;
    s.skipped_vertices += tc.skipped_vertices;
    s.merged_vertices += tc.merged;
    s.dropped += tc.dropped;
  }
  s.iteration_peak_live_vertices = peak_live_.load();
  s.peak_live_vertices = std::max(run_peak_live_, s.iteration_peak_live_vertices);
  s.peak_blocks = block_count_.load();
  s.peak_sample_bytes = peak_sample_bytes_;
  s.path_skip_rate = skip_rate_;
  s.average_path_length = last_paths_ ? double(last_events_) / double(last_paths_) : 0.0;
  return s;
}

size_t RadianceRecorder::peak_bytes() const {
  return size_t(block_count_.load()) * sizeof(Block) + size_t(peak_sample_bytes_);
}

}  // namespace theia
