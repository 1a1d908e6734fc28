#include "radiance_recorder/recorder.h"

#include "core/hash.h"
#include "core/huge_pages.h"
#include "core/log.h"
#include "core/stats.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <glm/gtc/packing.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <tuple>

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

// A guided vertex's BSDF and guide densities over its drawing density, as
// two halves: ratios bounded by 1 / (the smaller share of the mixture), and
// what they train (the selection probability's gradient) is noisy far beyond
// 11 bits.
uint32_t pack_ratios(float bsdf_ratio, float guide_ratio) {
  auto finite = [](float r) { return std::isfinite(r) && r > 0.0f ? std::min(r, 65504.0f) : 0.0f; };
  return glm::packHalf2x16(vec2(finite(bsdf_ratio), finite(guide_ratio)));
}

// em / tp per channel; a channel the path cannot carry (tp = 0) carries nothing.
RGB divide(const RGB& em, const glm::dvec3& tp) {
  RGB r;
  for (int c = 0; c < 3; ++c) r[c] = tp[c] != 0.0 ? float(double(em[c]) / tp[c]) : 0.0f;
  return r;
}

bool is_special(PVIndex h) { return h == kPVNone || h == kPVSkipped || h == kPVDetached; }

// A vertex flag the recorder keeps for itself (never in a sample): the vertex makes one.
constexpr uint8_t kVertexTrains = 1 << 7;

int bits_for(uint64_t max_value) { return max_value ? 64 - std::countl_zero(max_value) : 0; }

}  // namespace

// 128 bytes, two cache lines, aligned: the first holds what the events touch
// (a child's reference on its parent, emission, backpropagation), the second
// what is written once and read when the sample is recorded.  Emissions are
// in film units (see core/path_observer.h); the throughput, the long
// product, is double.  Only em_indirect is summed by several threads (the
// children finish anywhere), so only it takes float atomics; the vertex's own
// ray adds its direct emission one event after the other.
struct alignas(64) RadianceRecorder::Vertex {
  std::atomic<uint32_t> refs;
  PVIndex parent;
  RGB em_indirect;         // from children and merged (unrecorded) descendants
  RGB em_direct;           // found by the vertex's own ray, MIS-weighted (as splatted)
  RGB em_direct_unweighted;// the same without the MIS weight (TrainingMode::All only)
  uint16_t depth;
  uint8_t flags;
  uint8_t roughness;       // quantised to 1/255
  uint32_t pixel, sample;
  float pdf;
  float camera_weight;
  // second line
  glm::dvec3 tp;           // path throughput at the vertex (camera weight included)
  vec3 p;                  // origin of the vertex's ray
  vec3 wi;                 // its direction
  RGB local;               // the scattering's own factor (N-th bounce debug buffer)
  uint32_t mixture_ratios; // pack_ratios(bsdf_ratio, guide_ratio)
};
struct RadianceRecorder::Block {
  static_assert(sizeof(Vertex) == 128, "keep a path vertex at two cache lines (the README says so)");
  static_assert(offsetof(Vertex, tp) == 64, "the event fields fill the first cache line");
  Vertex v[kPVBlockSize];
};

struct RadianceRecorder::ThreadCache {
  std::vector<PVIndex> free;
  std::vector<TrainingSample> samples;
  int64_t live = 0;        // allocations minus frees not yet added to live_
  int64_t peak = 0;        // the most live vertices this thread saw in this iteration
  static constexpr uint32_t kHints = 4;
  uint32_t hinted[kHints] = {kPVNone, kPVNone, kPVNone, kPVNone};  // the last prefetch() hints
  uint32_t next_hint = 0;
  uint64_t paths = 0, skipped_paths = 0, vertex_events = 0, recorded = 0, skipped_vertices = 0, merged = 0,
           untrainable = 0, untrainable_merged = 0, dropped = 0;
};

namespace {

// Live-count changes reach the shared counter this many at a time.
constexpr int64_t kLiveBatch = 32;

std::atomic<uint64_t> next_recorder_id{1};

}  // namespace

TrainingMode parse_training_mode(const std::string& name) {
  if (name == "mis-direct") return TrainingMode::IndirectPlusMISDirect;
  if (name == "all") return TrainingMode::All;
  if (name == "indirect") return TrainingMode::IndirectOnly;
  throw_error("--recorder-training {}: expected mis-direct, all or indirect", name);
}

double path_skip_rate(uint64_t paths, uint64_t vertices, double budget) {
  if (budget <= 0.0 || paths == 0 || vertices == 0) return 0.0;
  double keep = budget * double(paths) / double(vertices);
  return std::clamp(1.0 - keep, 0.0, 1.0);
}

size_t RadianceRecorder::vertex_bytes() { return sizeof(Vertex); }

RadianceRecorder::RadianceRecorder(const RecorderOptions& options, TrainingSampleSink* sink)
    : opt_(options), mode_(parse_training_mode(options.training)), sink_(sink), caches_(new tbb::enumerable_thread_specific<ThreadCache>()),
      id_(next_recorder_id.fetch_add(1, std::memory_order_relaxed)) {
  opt_.max_blocks = std::clamp<uint32_t>(opt_.max_blocks, 1, kPVMaxBlocks);
  opt_.vertex_skip_probability = std::clamp(opt_.vertex_skip_probability, 0.0f, 1.0f);
  opt_.medium_skip_probability = std::clamp(opt_.medium_skip_probability, 0.0f, 1.0f);
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

// Every event needs its thread's cache.  The TBB table hashes the thread id
// on each lookup; events come by the million, so each thread keeps a pointer
// to its cache of the recorder it served last (named by id_, which no later
// recorder reuses, unlike an address).
RadianceRecorder::ThreadCache& RadianceRecorder::cache() const {
  thread_local struct {
    uint64_t id = 0;
    ThreadCache* tc = nullptr;
  } last;
  if (last.id != id_) {
    last.tc = &caches_->local();
    last.id = id_;
  }
  return *last.tc;
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
  // The next allocation takes the next index: have its line ready to be written.
  if (!tc.free.empty()) __builtin_prefetch(&at(tc.free.back()), 1);
  ++tc.live;
  // The shared count is read here and written once a batch: what this thread
  // sees is exact up to the other threads' unflushed batches.
  tc.peak = std::max(tc.peak, live_.load(std::memory_order_relaxed) + tc.live);
  if (tc.live >= kLiveBatch) flush_live(tc);
  return i;
}

void RadianceRecorder::flush_live(ThreadCache& tc) {
  live_.fetch_add(tc.live, std::memory_order_relaxed);
  tc.live = 0;
}

uint64_t RadianceRecorder::iteration_peak_live() const {
  int64_t peak = peak_live_;
  for (const ThreadCache& tc : *caches_) peak = std::max(peak, tc.peak);
  return uint64_t(peak);
}

uint64_t RadianceRecorder::live_vertices() const {
  int64_t live = live_.load(std::memory_order_relaxed);
  for (const ThreadCache& tc : *caches_) live += tc.live;
  return uint64_t(live);
}

void RadianceRecorder::release(ThreadCache& tc, PVIndex i) {
  if (--tc.live <= -kLiveBatch) flush_live(tc);
  tc.free.push_back(i);
  if (tc.free.size() >= 2 * kFreeBatch) {
    std::lock_guard lock(free_mutex_);
    free_.insert(free_.end(), tc.free.end() - kFreeBatch, tc.free.end());
    tc.free.resize(tc.free.size() - kFreeBatch);
  }
}

// ---------------------------------------------------------------- events

uint32_t RadianceRecorder::path_started(uint32_t pixel, uint32_t sample) {
  ThreadCache& tc = cache();
  ++tc.paths;
  if (skip_rate_ > 0.0 && to_unit_float(uint32_t(hash(opt_.seed, pixel, sample, 0x5c1bu))) < skip_rate_) {
    ++tc.skipped_paths;
    return kPVSkipped;
  }
  return kPVNone;
}

// A sample the guiding field can learn from: a direction with a density,
// from a BSDF the engine guides (NEE rays per the options).  Without a sink
// nothing trains; vertices are then kept only for the debug buffers.
bool RadianceRecorder::trainable(const PathVertexInfo& info) const {
  const bool delta = (info.lobe_flags & (1 << 4)) || info.delta_light;  // scene/bsdf.h kLobeSpecular
  return sink_ && !delta && info.guidable && (!info.is_nee || sink_->wants_nee_samples());
}

double RadianceRecorder::keep_probability(bool in_medium) const {
  const double keep = 1.0 - double(opt_.vertex_skip_probability);
  return in_medium ? keep * (1.0 - double(opt_.medium_skip_probability)) : keep;
}

// Stochastic vertex skipping: a pure function of the vertex (pixel, sample,
// depth, kind), so whatever the thread count the same vertices are skipped.
bool RadianceRecorder::skipped(const PathVertexInfo& info) const {
  const double skip = 1.0 - keep_probability(info.in_medium);
  return skip > 0.0 && to_unit_float(uint32_t(hash(opt_.seed, info.pixel, info.sample, uint32_t(info.depth),
                                                    uint32_t(info.is_nee), 0x5eedu))) < skip;
}

// The debug buffers splat the vertices of these depths.
bool RadianceRecorder::debug_records(int depth) const {
  return (!debug_primary_.empty() && depth == 0) || (!debug_bounce_.empty() && depth == opt_.debug_bounce);
}

uint32_t RadianceRecorder::vertex_created(uint32_t parent, const PathVertexInfo& info) {
  ThreadCache& tc = cache();
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
  // A vertex that cannot train makes no sample.  An NEE vertex has no
  // children, so merging it gives its parent exactly the sum it would have
  // had (its emission instead of its total, the same number); a scattering
  // vertex is still allocated, since merging its subtree into the parent
  // would change the order, hence the rounding, of the parent's sum.  The
  // debug buffers keep the vertices they splat.
  const bool trains = trainable(info);
  if (!trains) {
    ++tc.untrainable;
    if (info.is_nee && !debug_records(info.depth)) {
      ++tc.untrainable_merged;
      return merge();
    }
  }
  if (skipped(info)) {
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
  v.mixture_ratios = pack_ratios(info.bsdf_ratio, info.guide_ratio);
  v.pdf = info.pdf;
  v.camera_weight = info.camera_weight;
  v.pixel = info.pixel;
  v.sample = info.sample;
  // Atomic only for prefetch(), which may read a stale vertex's parent.
  std::atomic_ref<PVIndex>(v.parent).store(real_parent, std::memory_order_relaxed);
  v.depth = uint16_t(std::clamp(info.depth, 0, 0xffff));
  v.flags = uint8_t((info.is_nee ? kVertexNEE : 0) | (info.in_medium ? kVertexInMedium : 0) |
                    ((info.lobe_flags & (1 << 4)) || info.delta_light ? kVertexDelta : 0) |
                    ((info.lobe_flags & (1 << 3)) ? kVertexGlossy : 0) | (trains ? kVertexTrains : 0));
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
        ++cache().dropped;
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
  v.em_direct += c;
  if (mode_ == TrainingMode::All && mis_weight > 0.0f) v.em_direct_unweighted += c / mis_weight;
}

void RadianceRecorder::vertex_continued(uint32_t vertex) {
  if (is_special(vertex)) return;
  at(vertex & ~kPVMergedBit).refs.fetch_add(1, std::memory_order_relaxed);
}

void RadianceRecorder::vertex_done(uint32_t vertex) {
  if (is_special(vertex)) return;
  finish(cache(), vertex & ~kPVMergedBit);
}

// The vertex's lines now; its parent's (where backpropagation adds its
// light) a few hints later, when the vertex's line has arrived and names it.
void RadianceRecorder::prefetch(uint32_t vertex) const {
  ThreadCache& tc = cache();
  const uint32_t earlier = tc.hinted[tc.next_hint];
  tc.hinted[tc.next_hint] = vertex;
  tc.next_hint = (tc.next_hint + 1) % ThreadCache::kHints;
  if (!is_special(vertex)) {
    const char* v = reinterpret_cast<const char*>(&at(vertex & ~kPVMergedBit));
    __builtin_prefetch(v, 1);
    __builtin_prefetch(v + 64, 1);
  }
  if (is_special(earlier) || (earlier & kPVMergedBit)) return;
  // A vertex hinted but since freed reads a stale parent: the hint is only a hint.
  const PVIndex parent = std::atomic_ref<PVIndex>(at(earlier).parent).load(std::memory_order_relaxed);
  if (!is_special(parent)) __builtin_prefetch(&at(parent), 1);
}

// Backpropagation (section 3.4.3), as a loop up the parent chain.
void RadianceRecorder::finish(ThreadCache& tc, PVIndex i) {
  while (true) {
    Vertex& v = at(i);
    // acq_rel: the thread that takes the count to zero sees every emission
    // added (relaxed) before the other threads' decrements.
    if (v.refs.fetch_sub(1, std::memory_order_acq_rel) != 1) return;
    record(tc, v);
    RGB total = load(v.em_indirect) + v.em_direct;
    PVIndex parent = v.parent;
    release(tc, i);
    if (parent == kPVNone) return;
    if (is_finite(total)) atomic_add(at(parent).em_indirect, total);
    i = parent;
  }
}

void RadianceRecorder::record(ThreadCache& tc, Vertex& v) {
  const RGB indirect = load(v.em_indirect), direct = v.em_direct;
  const RGB total = indirect + direct;
  // A splat stands for the vertices skipped in its place.
  const double keep = (1.0 - skip_rate_) * keep_probability((v.flags & kVertexInMedium) != 0);
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
  if (!(v.flags & kVertexTrains)) return;

  RGB radiance = divide(indirect, v.tp);
  if (mode_ == TrainingMode::IndirectPlusMISDirect) radiance += divide(direct, v.tp);
  if (mode_ == TrainingMode::All) radiance += divide(v.em_direct_unweighted, v.tp);
  if (!is_finite(radiance)) {
    ++tc.dropped;
    return;
  }
  TrainingSample s;
  s.p = v.p;
  s.wi = v.wi;
  s.radiance = radiance;
  s.pdf = v.pdf;
  s.roughness = float(v.roughness) / 255.0f;
  s.scattering_weight = luminance(v.local);
  const vec2 ratios = glm::unpackHalf2x16(v.mixture_ratios);
  s.bsdf_ratio = ratios.x;
  s.guide_ratio = ratios.y;
  s.pixel = v.pixel;
  s.sample = v.sample;
  s.depth = v.depth;
  s.flags = uint8_t(v.flags & ~kVertexTrains);
  grow_huge_for_one_more(tc.samples);
  tc.samples.push_back(s);
}

// ---------------------------------------------------------------- iterations

void RadianceRecorder::update_skip_rate() { skip_rate_ = path_skip_rate(last_paths_, last_events_, opt_.vertex_budget); }

void RadianceRecorder::begin_iteration() {
  for (ThreadCache& tc : *caches_) flush_live(tc);
  run_peak_live_ = std::max(run_peak_live_, iteration_peak_live());
  peak_live_ = live_.load();
  for (ThreadCache& tc : *caches_) tc.peak = 0;
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
  for (ThreadCache& tc : *caches_) flush_live(tc);
  if (live_.load() != 0)
    throw std::logic_error("radiance recorder: " + std::to_string(live_.load()) +
                           " path vertices still allocated at the end of an iteration (an event was lost)");
  size_t count = 0;
  for (ThreadCache& tc : *caches_) count += tc.samples.size();
  // The samples, their sorted copy and the sort's keys, at the sort's peak.
  peak_sample_bytes_ =
      std::max<uint64_t>(peak_sample_bytes_, count * (2 * sizeof(TrainingSample) + 2 * sizeof(SortPair)));
  if (!sink_) return;
  std::span<const TrainingSample> sorted;
  {
    ScopedTimer timer(sort_seconds_);
    sorted = sorted_samples();
  }
  samples_ += sorted.size();
  ScopedTimer timer(consume_seconds_);
  sink_->consume(sorted);
}

// Deterministic order whatever the threads did: (pixel, sample, depth,
// flags) packed into one key with as many bits as this iteration's largest
// values need (28 on a 128 x 128 frame at 64 spp), radix-sorted with the
// record's position, then the records gathered in that order.  The keys are
// unique (one vertex per pixel, sample, depth and kind), so the order is too.
std::span<const TrainingSample> RadianceRecorder::sorted_samples() {
  std::vector<const std::vector<TrainingSample>*> parts;
  std::vector<size_t> offset{0};
  for (ThreadCache& tc : *caches_) {
    if (tc.samples.empty()) continue;
    parts.push_back(&tc.samples);
    offset.push_back(offset.back() + tc.samples.size());
  }
  const size_t n = offset.back();
  if (n == 0) {  // nothing recorded (training is over): give the kept arrays back
    keys_ = {}, scratch_ = {}, sorted_ = {};
    return {};
  }
  auto sample_at = [&](size_t index) -> const TrainingSample& {
    size_t p = size_t(std::upper_bound(offset.begin(), offset.end(), index) - offset.begin()) - 1;
    return (*parts[p])[index - offset[p]];
  };
  // Each thread's part scanned on its own (maxima: the same whatever the split).
  std::vector<std::array<uint32_t, 4>> part_max(parts.size(), {0, 0, 0, 0});
  tbb::parallel_for(size_t(0), parts.size(), [&](size_t p) {
    std::array<uint32_t, 4>& m = part_max[p];
    for (const TrainingSample& s : *parts[p]) {
      m[0] = std::max(m[0], s.pixel);
      m[1] = std::max(m[1], s.sample);
      m[2] = std::max<uint32_t>(m[2], s.depth);
      m[3] = std::max<uint32_t>(m[3], s.flags);
    }
  });
  uint32_t max_pixel = 0, max_sample = 0, max_depth = 0, max_flags = 0;
  for (const std::array<uint32_t, 4>& m : part_max) {
    max_pixel = std::max(max_pixel, m[0]);
    max_sample = std::max(max_sample, m[1]);
    max_depth = std::max(max_depth, m[2]);
    max_flags = std::max(max_flags, m[3]);
  }
  const int flag_bits = bits_for(max_flags), depth_bits = bits_for(max_depth), sample_bits = bits_for(max_sample);
  const int key_bits = bits_for(max_pixel) + sample_bits + depth_bits + flag_bits;

  std::vector<SortPair>& keys = keys_;
  reserve_huge(keys, n);
  reserve_huge(scratch_, n);  // radix_sort resizes it to n
  if (keys.size() != n) keys.resize(n);
  if (key_bits <= 64) {
    tbb::parallel_for(size_t(0), parts.size(), [&](size_t p) {
      const std::vector<TrainingSample>& part = *parts[p];
      for (size_t i = 0; i < part.size(); ++i) {
        const TrainingSample& s = part[i];
        uint64_t key = (((uint64_t(s.pixel) << sample_bits | s.sample) << depth_bits | s.depth) << flag_bits) | s.flags;
        keys[offset[p] + i] = {key, uint32_t(offset[p] + i)};
      }
    });
    radix_sort(keys, scratch_, key_bits);
  } else {  // too many bits to pack: compare the fields
    for (size_t i = 0; i < n; ++i) keys[i] = {0, uint32_t(i)};
    std::sort(keys.begin(), keys.end(), [&](const SortPair& a, const SortPair& b) {
      const TrainingSample &x = sample_at(a.index), &y = sample_at(b.index);
      return std::tie(x.pixel, x.sample, x.depth, x.flags) < std::tie(y.pixel, y.sample, y.depth, y.flags);
    });
  }
  reserve_huge(sorted_, n);
  if (sorted_.size() < n) sorted_.resize(n);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, size_t(1) << 14), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) sorted_[i] = sample_at(keys[i].index);
  });
  for (ThreadCache& tc : *caches_) tc.samples.clear();
  return std::span<const TrainingSample>(sorted_).first(n);
}

RadianceRecorder::ResumeState RadianceRecorder::resume_state() const {
  if (live_vertices() != 0)
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
    s.untrainable += tc.untrainable;
    s.untrainable_merged += tc.untrainable_merged;
    s.dropped += tc.dropped;
  }
  s.samples = samples_;
  s.sort_seconds = sort_seconds_;
  s.consume_seconds = consume_seconds_;
  s.iteration_peak_live_vertices = iteration_peak_live();
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
