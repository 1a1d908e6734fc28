#include "cachepoints/cache_points.h"

#include "cachepoints/cache_point_build.h"
#include "cachepoints/local_sampler.h"

#include "core/log.h"
#include "core/stats.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>

namespace theia {

namespace {

// The weights of sampling's four groups (+-x, +-y, +-z, fluence; groups())
// under a unit normal: its absolute components over their sum, the bins of
// both sides of an axis alike; the fluence alone where there is no normal.
// The geometric normal's side is the mesh's winding, not the side the path
// arrived from (which the MIS pmf at an emitter hit cannot know), so the
// receiver is two-sided, as emitter_importance's.
std::array<float, 4> group_weights(const vec3& n) {
  std::array<float, 4> w{};
  const float sum = std::abs(n.x) + std::abs(n.y) + std::abs(n.z);
  if (!(sum > 0.0f)) {
    w[3] = 1.0f;
    return w;
  }
  for (int axis = 0; axis < 3; ++axis) w[size_t(axis)] = std::abs(n[axis]) / sum;
  return w;
}

// Eq. 5 and 6.
float visibility_weight(uint32_t attempts, uint32_t successes, float r_min) {
  const float r = float(successes + 1) / float(attempts + 1);
  return r <= r_min ? sqr(r / r_min) : 1.0f;
}

}  // namespace

// ---------------------------------------------------------------- the sampler

struct CachePointSampler::Impl {
  const LightSet& lights;
  const EmitterSet& set;
  CachePointParams prm;
  std::unique_ptr<PointTree> tree;  // null: the locally optimal fallback
  // Per point its entries: near ones [begin, mid), far ones [mid, begin of the next).
  std::vector<uint32_t> begin, mid;
  std::vector<uint32_t> entry_emitter;
  std::vector<float> entry_visibility;  // blurred W, 1 until learned
  std::unique_ptr<std::atomic<uint32_t>[]> attempts, successes;
  // The far entries' values in sampling's four groups (groups()), and per
  // group their cumulative sums times W, the CDFs sampling searches: point
  // c's F far entries hold 4 F floats of each from 4 far_begin[c], group by
  // group (far(c, g)).
  std::vector<uint32_t> far_begin;  // per point, into the far entries; size points + 1
  std::vector<float> far_value, far_cdf;
  Neighbours neighbours;
  // Costs and statistics for the log.
  double build_seconds = 0.0;
  size_t object_count = 0, pilot_count = 0, merged_points = 0, cull_evaluated = 0;

  Impl(const LightSet& l, const EmitterSet& s, const CachePointParams& p) : lights(l), set(s), prm(p) {}

  size_t points() const { return tree ? tree->points.size() : 0; }
  size_t entries() const { return entry_emitter.size(); }
  uint32_t far_count(uint32_t c) const { return far_begin[c + 1] - far_begin[c]; }
  // Group g of point c's far entries, in far_value or far_cdf.
  size_t far(uint32_t c, int g) const { return 4 * size_t(far_begin[c]) + size_t(g) * far_count(c); }

  void build(const Accel& accel);
  void store(std::vector<PointLists>&& lists);
  // far_cdf from far_value and the visibility, for points [first, last).
  void accumulate(size_t first, size_t last);
  // The entry of `emitter` at point c, or -1.
  int find_entry(uint32_t c, uint32_t emitter) const {
    auto search = [&](uint32_t a, uint32_t b) -> int {
      auto first = entry_emitter.begin() + a, last = entry_emitter.begin() + b;
      auto it = std::lower_bound(first, last, emitter);
      return it != last && *it == emitter ? int(it - entry_emitter.begin()) : -1;
    };
    int e = search(begin[c], mid[c]);
    return e >= 0 ? e : search(mid[c], begin[c + 1]);
  }
  float share(float total) const { return total > 0.0f && std::isfinite(total) ? prm.uniform_share : 1.0f; }

  // What selection at a vertex weighs: the nearest point's near entries
  // estimated at the vertex (times W), and its far entries as a mixture over
  // the four groups, group g weighted by the normal's weight times its total.
  struct Weights {
    uint32_t c = 0;
    std::array<float, kMaxNear> near{};
    std::array<float, 4> normal{}, group{};
    float near_total = 0.0f, total = 0.0f;
  };
  Weights weights(const LightSampleContext& ctx) const {
    Weights w;
    w.c = tree->nearest(ctx.p);
    const uint32_t c = w.c;
    for (uint32_t k = begin[c]; k < mid[c]; ++k) {
      w.near[k - begin[c]] =
          emitter_importance(lights, set.emitters[entry_emitter[k]], ctx.p, ctx.ng) * entry_visibility[k];
      w.near_total += w.near[k - begin[c]];
    }
    w.normal = group_weights(ctx.ng);
    const uint32_t f = far_count(c);
    float far_total = 0.0f;
    for (int g = 0; g < 4; ++g) {
      if (w.normal[size_t(g)] > 0.0f && f > 0) w.group[size_t(g)] = w.normal[size_t(g)] * far_cdf[far(c, g) + f - 1];
      far_total += w.group[size_t(g)];
    }
    w.total = w.near_total + far_total;
    return w;
  }
  // Entry k's share of w.total: its near weight, or its far entry's width in each group's CDF.
  float entry_weight(const Weights& w, uint32_t k) const {
    const uint32_t c = w.c;
    if (k < mid[c]) return w.near[k - begin[c]];
    const uint32_t j = k - mid[c];
    float sum = 0.0f;
    for (int g = 0; g < 4; ++g) {
      if (!(w.normal[size_t(g)] > 0.0f)) continue;
      const float* cdf = &far_cdf[far(c, g)];
      sum += w.normal[size_t(g)] * (cdf[j] - (j > 0 ? cdf[j - 1] : 0.0f));
    }
    return sum;
  }
  // The probability of emitter e at w's point.
  float probability(const Weights& w, int e) const {
    const float s = share(w.total);
    float p = s / float(set.size());
    if (s < 1.0f) {
      const int k = find_entry(w.c, uint32_t(e));
      if (k >= 0) p += (1.0f - s) * entry_weight(w, uint32_t(k)) / w.total;
    }
    return p;
  }
  // The entry that t in [0, w.total) falls on: a near one by a walk, a far
  // one by its group, then a binary search in that group's CDF.  -1 if none.
  int choose_entry(const Weights& w, float t) const {
    const uint32_t c = w.c;
    if (t < w.near_total || !(w.total > w.near_total)) {  // (the far part may be empty: t rounded up to the total)
      int chosen = -1;
      for (uint32_t k = begin[c]; k < mid[c]; ++k) {
        const float x = w.near[k - begin[c]];
        if (x > 0.0f) chosen = int(k);
        if (t < x) break;
        t -= x;
      }
      return chosen;
    }
    t -= w.near_total;
    int g = -1;
    for (int h = 0; h < 4; ++h) {
      const float x = w.group[size_t(h)];
      if (x > 0.0f) g = h;
      if (t < x) break;
      t -= x;
    }
    if (g < 0) return -1;
    // Within the group, in units of its CDF; never past its last entry of positive width.
    const float* cdf = &far_cdf[far(c, g)];
    const uint32_t f = far_count(c);
    const float target = std::max(0.0f, t / w.normal[size_t(g)]);
    const uint32_t first = uint32_t(std::upper_bound(cdf, cdf + f, target) - cdf);
    const uint32_t last = uint32_t(std::lower_bound(cdf, cdf + f, cdf[f - 1]) - cdf);
    return int(mid[c] + std::min(first, last));
  }
  void fold_visibility();
};

CachePointSampler::CachePointSampler(const LightSet& lights, const Accel& accel, const CachePointParams& params)
    : emitters_(build_emitters(lights)), impl_(std::make_unique<Impl>(lights, emitters_, params)) {
  impl_->build(accel);
}

CachePointSampler::~CachePointSampler() = default;

void CachePointSampler::Impl::build(const Accel& accel) {
  const auto start = std::chrono::steady_clock::now();
  CachePointTables t = build_cache_points(lights, set, accel, prm);
  object_count = t.object_count;
  pilot_count = t.pilot_count;
  merged_points = t.merged_points;
  cull_evaluated = t.cull_evaluated;
  tree = std::move(t.tree);
  neighbours = std::move(t.neighbours);
  if (tree) store(std::move(t.lists));
  build_seconds = seconds_since(start);
}

void CachePointSampler::Impl::store(std::vector<PointLists>&& lists) {
  size_t total = 0, far_total = 0;
  for (const PointLists& l : lists) {
    total += l.near.size() + l.far.size();
    far_total += l.far.size();
  }
  entry_emitter.reserve(total);  // exactly: a growing table would briefly hold twice itself
  far_value.resize(4 * far_total);
  far_cdf.resize(4 * far_total);
  begin.reserve(lists.size() + 1);
  mid.reserve(lists.size());
  far_begin.reserve(lists.size() + 1);
  far_begin.push_back(0);
  for (PointLists& l : lists) {
    begin.push_back(uint32_t(entry_emitter.size()));
    entry_emitter.insert(entry_emitter.end(), l.near.begin(), l.near.end());
    mid.push_back(uint32_t(entry_emitter.size()));
    const size_t f = l.far.size();
    float* out = &far_value[4 * size_t(far_begin.back())];
    for (size_t j = 0; j < f; ++j) {
      entry_emitter.push_back(l.far[j].emitter);
      const std::array<float, 4> g = groups(l.far[j].value);
      for (size_t h = 0; h < 4; ++h) out[h * f + j] = g[h];
    }
    far_begin.push_back(far_begin.back() + uint32_t(f));
    l = PointLists{};  // copied: its memory can go
  }
  begin.push_back(uint32_t(entry_emitter.size()));
  entry_visibility.assign(entries(), 1.0f);
  attempts.reset(new std::atomic<uint32_t>[entries()]());
  successes.reset(new std::atomic<uint32_t>[entries()]());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, points()),
                    [&](const tbb::blocked_range<size_t>& r) { accumulate(r.begin(), r.end()); });
}

void CachePointSampler::Impl::accumulate(size_t first, size_t last) {
  for (size_t c = first; c < last; ++c) {
    const uint32_t f = far_count(uint32_t(c));
    const float* w = &entry_visibility[mid[c]];
    for (int g = 0; g < 4; ++g) {
      const float* v = &far_value[far(uint32_t(c), g)];
      float* cdf = &far_cdf[far(uint32_t(c), g)];
      float sum = 0.0f;
      for (uint32_t j = 0; j < f; ++j) {
        sum += v[j] * w[j];
        cdf[j] = sum;
      }
    }
  }
}

std::optional<SampledLight> CachePointSampler::sample(const LightSampleContext& ctx, float u) const {
  const Impl& m = *impl_;
  const size_t n = emitters_.size();
  if (n == 0) return std::nullopt;
  auto result = [&](int e, float pmf, uint32_t region) -> std::optional<SampledLight> {
    if (e < 0 || !(pmf > 0.0f)) return std::nullopt;
    const Emitter& em = emitters_.emitters[size_t(e)];
    return SampledLight{em.light, pmf, region, em.primitive};
  };
  if (!m.tree) {
    const LocalChoice c = sample_locally_optimal(m.lights, emitters_, ctx, u, m.prm.uniform_share);
    return result(c.emitter, c.pmf, 0);
  }
  const Impl::Weights w = m.weights(ctx);
  const float share = m.share(w.total);
  int e = -1;
  if (u < share) {
    e = std::min(int(u / share * float(n)), int(n) - 1);
  } else {
    const int k = m.choose_entry(w, (u - share) / (1.0f - share) * w.total);
    if (k >= 0) e = int(m.entry_emitter[size_t(k)]);
  }
  if (e < 0) return std::nullopt;
  return result(e, m.probability(w, e), w.c);
}

float CachePointSampler::pmf_primitive(const LightSampleContext& ctx, int light, int primitive) const {
  const Impl& m = *impl_;
  const int e = emitters_.find(light, primitive);
  if (e < 0) return 0.0f;
  if (!m.tree) return pmf_locally_optimal(m.lights, emitters_, ctx, e, m.prm.uniform_share);
  return m.probability(m.weights(ctx), e);
}

void CachePointSampler::record_shadow(const SampledLight& chosen, bool unoccluded) const {
  const Impl& m = *impl_;
  if (!m.tree || chosen.region >= m.points()) return;
  const int e = emitters_.find(chosen.light, chosen.primitive);
  if (e < 0) return;
  const int k = m.find_entry(chosen.region, uint32_t(e));
  if (k < 0) return;
  m.attempts[size_t(k)].fetch_add(1, std::memory_order_relaxed);
  if (unoccluded) m.successes[size_t(k)].fetch_add(1, std::memory_order_relaxed);
}

// Section 3.2.2: each entry's W blurred with the neighbours that list the
// same emitter (normalised over those, so an unlisted neighbour does not
// count as an occluder).  A pure function of the counts.  Only entries whose
// emitter has W < 1 at the point or a neighbour can differ from 1 (a sum of
// weights times 1 over the same sum is exactly 1), so only those are blurred.
void CachePointSampler::Impl::fold_visibility() {
  std::vector<float> w(entries());
  std::vector<std::vector<uint32_t>> lowered(points());
  tbb::parallel_for(size_t(0), points(), [&](size_t c) {
    for (uint32_t k = begin[c]; k < begin[c + 1]; ++k) {
      w[k] = visibility_weight(attempts[k].load(std::memory_order_relaxed),
                               successes[k].load(std::memory_order_relaxed), prm.r_min);
      if (w[k] < 1.0f) lowered[c].push_back(k);
    }
  });
  auto blurred = [&](uint32_t c, uint32_t k) {
    float sum = 0.0f, norm = 0.0f;
    for (uint32_t j = neighbours.begin[c]; j < neighbours.begin[c + 1]; ++j) {
      const uint32_t q = neighbours.index[j];
      const int kq = q == c ? int(k) : find_entry(q, entry_emitter[k]);
      if (kq < 0) continue;
      sum += neighbours.weight[j] * w[size_t(kq)];
      norm += neighbours.weight[j];
    }
    return norm > 0.0f ? sum / norm : 1.0f;
  };
  tbb::parallel_for(size_t(0), points(), [&](size_t c) {
    std::fill(entry_visibility.begin() + begin[c], entry_visibility.begin() + begin[c + 1], 1.0f);
    for (uint32_t j = neighbours.begin[c]; j < neighbours.begin[c + 1]; ++j) {
      const uint32_t q = neighbours.index[j];
      for (uint32_t kq : lowered[q]) {
        const int k = q == c ? int(kq) : find_entry(uint32_t(c), entry_emitter[kq]);
        if (k >= 0) entry_visibility[size_t(k)] = blurred(uint32_t(c), uint32_t(k));
      }
    }
  });
  tbb::parallel_for(tbb::blocked_range<size_t>(0, points()),
                    [&](const tbb::blocked_range<size_t>& r) { accumulate(r.begin(), r.end()); });
}

void CachePointSampler::update() {
  if (impl_->tree) impl_->fold_visibility();
}

// The counts and the visibility in effect (everything else is rebuilt from
// the scene): a checkpoint can fall inside an iteration, whose rest must
// sample with the weights of its start.  Layout: the entry count, then
// attempts and successes (uint32) and the weights (float), little-endian.
std::vector<uint8_t> CachePointSampler::save_state() const {
  const Impl& m = *impl_;
  const uint64_t n = m.entries();
  std::vector<uint8_t> bytes(sizeof(n) + 3 * n * sizeof(uint32_t));
  std::memcpy(bytes.data(), &n, sizeof(n));
  uint8_t* out = bytes.data() + sizeof(n);
  for (size_t k = 0; k < n; ++k) {
    const uint32_t a = m.attempts[k].load(), s = m.successes[k].load();
    std::memcpy(out + k * sizeof(uint32_t), &a, sizeof(a));
    std::memcpy(out + (n + k) * sizeof(uint32_t), &s, sizeof(s));
  }
  std::memcpy(out + 2 * n * sizeof(uint32_t), m.entry_visibility.data(), n * sizeof(float));
  return bytes;
}

void CachePointSampler::restore(const std::vector<uint8_t>& state) {
  Impl& m = *impl_;
  uint64_t n = 0;
  if (state.size() >= sizeof(n)) std::memcpy(&n, state.data(), sizeof(n));
  if (state.size() < sizeof(n) || n != m.entries() || state.size() != sizeof(n) + 3 * n * sizeof(uint32_t))
    throw_error("checkpoint section 'light-sampler': {} bytes do not hold the {} visibility entries of these cache points",
                state.size(), m.entries());
  const uint8_t* in = state.data() + sizeof(n);
  for (size_t k = 0; k < n; ++k) {
    uint32_t a, s;
    std::memcpy(&a, in + k * sizeof(uint32_t), sizeof(a));
    std::memcpy(&s, in + (n + k) * sizeof(uint32_t), sizeof(s));
    m.attempts[k].store(a);
    m.successes[k].store(s);
  }
  std::memcpy(m.entry_visibility.data(), in + 2 * n * sizeof(uint32_t), n * sizeof(float));
  m.accumulate(0, m.points());
}

std::vector<std::pair<std::string, double>> CachePointSampler::statistics() const {
  const Impl& m = *impl_;
  const double points = double(m.points());
  double near = 0.0, tries = 0.0, hits = 0.0, lowered = 0.0;
  for (size_t c = 0; c < m.points(); ++c) near += double(m.mid[c] - m.begin[c]);
  for (size_t k = 0; k < m.entries(); ++k) {
    tries += double(m.attempts[k].load());
    hits += double(m.successes[k].load());
    lowered += m.entry_visibility[k] < 1.0f ? 1.0 : 0.0;
  }
  const double bytes = double(m.entries() * (sizeof(uint32_t) * 3 + sizeof(float)) +
                              (m.far_value.size() + m.far_cdf.size()) * sizeof(float) +
                              m.points() * (sizeof(vec3) + 3 * sizeof(uint32_t)) +
                              m.neighbours.index.size() * (sizeof(uint32_t) + sizeof(float)) +
                              emitters_.size() * sizeof(Emitter));
  // The built tables' checksum (48 bits, exact in a double): equal builds, equal checksums.
  uint64_t sum = 1469598103934665603ull;
  auto mix = [&](const void* data, size_t words) {  // FNV-1a over 32-bit words
    for (size_t i = 0; i < words; ++i) {
      uint32_t w;
      std::memcpy(&w, static_cast<const uint8_t*>(data) + 4 * i, 4);
      sum = (sum ^ w) * 1099511628211ull;
    }
  };
  mix(m.begin.data(), m.begin.size());
  mix(m.mid.data(), m.mid.size());
  mix(m.entry_emitter.data(), m.entry_emitter.size());
  mix(m.far_value.data(), m.far_value.size());
  return {{"build_seconds", m.build_seconds},
          {"tables_checksum", double(sum >> 16)},
          {"emitters", double(emitters_.size())},
          {"candidates_in_objects", double(m.object_count)},
          {"candidates_on_pilot_paths", double(m.pilot_count)},
          {"points_after_merge", double(m.merged_points)},
          {"points", points},
          {"locally_optimal", m.tree ? 0.0 : 1.0},
          {"mean_near_lights", points > 0 ? near / points : 0.0},
          {"mean_far_lights", points > 0 ? (double(m.entries()) - near) / points : 0.0},
          {"mean_emitters_evaluated", m.tree ? double(m.cull_evaluated) / double(m.merged_points) : 0.0},
          {"memory_bytes", bytes},
          {"shadow_attempts", tries},
          {"shadow_successes", hits},
          {"entries_down_weighted", lowered}};
}

size_t CachePointSampler::point_count() const { return impl_->points(); }

float CachePointSampler::visibility(const vec3& p, int emitter) const {
  const Impl& m = *impl_;
  if (!m.tree || emitter < 0) return 1.0f;
  const int k = m.find_entry(m.tree->nearest(p), uint32_t(emitter));
  return k >= 0 ? m.entry_visibility[size_t(k)] : 1.0f;
}

std::vector<uint32_t> CachePointSampler::listed(size_t point) const {
  const Impl& m = *impl_;
  if (point >= m.points()) return {};
  return {m.entry_emitter.begin() + m.begin[point], m.entry_emitter.begin() + m.begin[point + 1]};
}

}  // namespace theia
