#include "guiding/vmm.h"

#include "core/bytes.h"
#include "core/hash.h"
#include "core/log.h"
#include "core/stats.h"
#include "guiding/sd_tree.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <iterator>
#include <limits>

namespace theia {

namespace {

constexpr float kMinKappa = 1e-3f;

bool finite3(const vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// log of the vMF normalisation kappa / (2 pi (1 - exp(-2 kappa))); expm1
// keeps it exact for small kappa, and exp(-2 kappa) vanishes for large.
double vmf_log_norm(double kappa) {
  if (kappa < kMinKappa) return std::log(double(kInv4Pi));
  return std::log(kappa) - std::log(2.0 * 3.14159265358979323846) - std::log(-std::expm1(-2.0 * kappa));
}

}  // namespace

float vmf_pdf(const vec3& mu, float kappa, const vec3& w) {
  if (kappa < kMinKappa) return kInv4Pi;
  const float c = std::min(glm::dot(mu, w), 1.0f);
  return float(std::exp(vmf_log_norm(kappa) + double(kappa) * (double(c) - 1.0)));
}

// Inverting the cdf of cos theta gives 1 - cos theta = -log(xi + (1 - xi)
// exp(-2 kappa)) / kappa, xi in (0, 1]; computing 1 - cos theta (not cos
// theta) keeps the sine exact for kappa in the thousands.
vec3 vmf_sample(const vec3& mu, float kappa, vec2 u) {
  double one_minus_cos;
  if (kappa < kMinKappa) {
    one_minus_cos = 2.0 * double(u.x);
  } else {
    const double xi = 1.0 - double(u.x);
    one_minus_cos = -std::log(xi + (1.0 - xi) * std::exp(-2.0 * double(kappa))) / double(kappa);
  }
  one_minus_cos = std::clamp(one_minus_cos, 0.0, 2.0);
  const double sin_theta = std::sqrt(std::max(0.0, one_minus_cos * (2.0 - one_minus_cos)));
  const double phi = 2.0 * 3.14159265358979323846 * double(u.y);
  const vec3 local(float(sin_theta * std::cos(phi)), float(sin_theta * std::sin(phi)), float(1.0 - one_minus_cos));
  return glm::normalize(Frame::from_z(mu).from_local(local));
}

float vmf_kappa_from_mean_cosine(float r) {
  r = std::clamp(r, 0.0f, 0.9999999f);
  return r * (3.0f - r * r) / (1.0f - r * r);
}

float vmf_mean_cosine(float kappa) {
  if (kappa < kMinKappa) return kappa / 3.0f;
  // coth(kappa) - 1 / kappa
  const double k = kappa;
  return float((1.0 + std::exp(-2.0 * k)) / -std::expm1(-2.0 * k) - 1.0 / k);
}

float vmf_norm(float kappa) { return float(std::exp(vmf_log_norm(kappa))); }

namespace {

std::array<float, kVMMLobes> norms(const VMMixture& m) {
  std::array<float, kVMMLobes> n{};
  for (int k = 0; k < kVMMLobes; ++k) n[size_t(k)] = vmf_norm(m.lobes[size_t(k)].kappa);
  return n;
}

}  // namespace

float vmm_pdf(const VMMixture& m, const std::array<float, kVMMLobes>& norm, const vec3& w) {
  float p = 0.0f;
  for (int k = 0; k < kVMMLobes; ++k) {
    const VMMLobe& l = m.lobes[size_t(k)];
    if (!(l.weight > 0.0f)) continue;
    const float kappa = l.kappa < kMinKappa ? 0.0f : l.kappa;
    p += l.weight * norm[size_t(k)] * std::exp(kappa * (std::min(glm::dot(l.mu, w), 1.0f) - 1.0f));
  }
  return p;
}

float vmm_pdf(const VMMixture& m, const vec3& w) { return vmm_pdf(m, norms(m), w); }

GuideSample vmm_sample(const VMMixture& m, vec2 u) { return vmm_sample(m, norms(m), u); }

GuideSample vmm_sample(const VMMixture& m, const std::array<float, kVMMLobes>& norm, vec2 u) {
  float total = 0.0f;
  for (const VMMLobe& l : m.lobes) total += l.weight;
  if (!(total > 0.0f)) return {};
  float at = u.x * total, begin = 0.0f;
  int k = 0;
  for (; k < kVMMLobes - 1; ++k) {
    if (at < begin + m.lobes[size_t(k)].weight) break;
    begin += m.lobes[size_t(k)].weight;
  }
  while (k > 0 && !(m.lobes[size_t(k)].weight > 0.0f)) --k;  // rounding past the last lobe with weight
  const VMMLobe& l = m.lobes[size_t(k)];
  u.x = std::clamp((at - begin) / l.weight, 0.0f, kOneMinusEpsilon);
  GuideSample s;
  s.wi = vmf_sample(l.mu, l.kappa, u);
  s.pdf = vmm_pdf(m, norm, s.wi) / total;
  return s;
}

VMMixture vmm_initial(float kappa) {
  VMMixture m;
  // A spherical Fibonacci set: even coverage for any lobe count.
  const float golden = kPi * (3.0f - std::sqrt(5.0f));
  for (int i = 0; i < kVMMLobes; ++i) {
    VMMLobe& l = m.lobes[size_t(i)];
    const float z = 1.0f - (2.0f * float(i) + 1.0f) / float(kVMMLobes);
    const float r = safe_sqrt(1.0f - z * z);
    const float phi = golden * float(i);
    l.mu = vec3(r * std::cos(phi), r * std::sin(phi), z);
    l.kappa = kappa;
    l.weight = 1.0f / float(kVMMLobes);
    l.inv_distance = 0.0f;
  }
  return m;
}

VMMSummary vmm_summary(const VMMixture& m) {
  VMMSummary s;
  double total = 0.0, weighted = 0.0;
  for (const VMMLobe& l : m.lobes) {
    total += double(l.weight), weighted += double(l.weight) * double(l.kappa);
    if (!(l.weight >= kVMMActiveWeight)) continue;
    s.kappa_min = s.active_lobes == 0 ? l.kappa : std::min(s.kappa_min, l.kappa);
    s.kappa_max = std::max(s.kappa_max, l.kappa);
    ++s.active_lobes;
  }
  s.kappa_mean = total > 0.0 ? float(weighted / total) : 0.0f;
  return s;
}

VMMixture vmm_at(const VMMixture& m, const vec3& pivot, const vec3& p) {
  VMMixture r = m;
  const vec3 shift = pivot - p;
  for (VMMLobe& l : r.lobes) {
    if (!(l.inv_distance > 0.0f)) continue;
    // (source - p) / distance = mu + (pivot - p) / distance.
    const vec3 v = l.mu + l.inv_distance * shift;
    const float len = glm::length(v);
    if (len > 1e-6f && std::isfinite(len)) l.mu = v / len;
  }
  return r;
}

namespace {

struct FitSample {
  vec3 dir;
  float weight;
  float inv_distance;
  bool known;  // the distance is known (inv_distance 0: at infinity)
};

void scale(VMMRegion& r, double s) {
  for (VMMLobeStats& st : r.stats) {
    st.weight *= s, st.direction *= s;
    st.inv_distance *= s, st.distance_weight *= s;
  }
  r.position_sum *= s;
  r.position_count *= s;
  r.weight_sum *= s;
}

}  // namespace

void vmm_fit(VMMRegion& region, std::span<const VMMSample> samples, const VMMOptions& o) {
  scale(region, o.decay);
  std::vector<FitSample> fit;
  fit.reserve(samples.size());
  for (const VMMSample& s : samples) {
    if (!finite3(s.p) || !finite3(s.wi) || !std::isfinite(s.radiance) || s.radiance < 0.0f || !(s.pdf > 0.0f) ||
        !std::isfinite(s.pdf))
      continue;
    region.position_sum += dvec3(s.p);
    region.position_count += 1.0;
  }
  if (!(region.position_count > 0.0)) return;
  const vec3 pivot = vec3(region.position_sum / region.position_count);
  if (region.fitted && o.parallax && pivot != region.pivot) {
    // The pivot moved: each lobe keeps its source, seen from the new pivot.
    region.mixture = vmm_at(region.mixture, region.pivot, pivot);
    for (int k = 0; k < kVMMLobes; ++k) {
      VMMLobeStats& st = region.stats[size_t(k)];
      st.direction = glm::length(st.direction) * dvec3(region.mixture.lobes[size_t(k)].mu);
    }
  }
  region.pivot = pivot;

  double weight_total = 0.0;
  for (const VMMSample& s : samples) {
    if (!finite3(s.p) || !finite3(s.wi) || !std::isfinite(s.radiance) || !(s.radiance > 0.0f) || !(s.pdf > 0.0f) ||
        !std::isfinite(s.pdf))
      continue;
    const float w = s.radiance / std::max(s.pdf, o.pdf_floor);
    if (!(w > 0.0f) || !std::isfinite(w)) continue;
    FitSample f{glm::normalize(s.wi), w, 0.0f, false};
    if (o.parallax && s.distance > 0.0f) {
      f.known = true;
      if (std::isfinite(s.distance)) {
        // Seen from the pivot: the direction to the sample's source, and its distance.
        const vec3 v = s.p + s.distance * f.dir - pivot;
        const float len = glm::length(v);
        if (len > 1e-6f * s.distance && std::isfinite(len)) f.dir = v / len, f.inv_distance = 1.0f / len;
        else f.inv_distance = 1.0f / s.distance;
      }
    }
    fit.push_back(f);
    weight_total += double(w);
  }
  if (fit.empty() || !(weight_total > 0.0) || !std::isfinite(weight_total)) return;
  // One unit per non-zero sample: iterations weigh by how many samples they
  // took, whatever their radiance level.
  const double normalise = double(fit.size()) / weight_total;

  const std::array<VMMLobeStats, kVMMLobes> prior = region.stats;
  std::array<VMMLobeStats, kVMMLobes> batch{};
  VMMixture& m = region.mixture;
  for (int it = 0; it < std::max(o.em_iterations, 1); ++it) {
    // E-step in log space: a direction far from every narrow lobe still
    // gets responsibilities.
    std::array<double, kVMMLobes> log_a{}, kappa{};
    std::array<dvec3, kVMMLobes> mu{};
    for (int k = 0; k < kVMMLobes; ++k) {
      const VMMLobe& l = m.lobes[size_t(k)];
      log_a[size_t(k)] = l.weight > 0.0f ? std::log(double(l.weight)) + vmf_log_norm(l.kappa)
                                         : -std::numeric_limits<double>::infinity();
      kappa[size_t(k)] = l.kappa < kMinKappa ? 0.0 : double(l.kappa);
      mu[size_t(k)] = dvec3(l.mu);
    }
    batch = {};
    for (const FitSample& f : fit) {
      std::array<double, kVMMLobes> lg{};
      double hi = -std::numeric_limits<double>::infinity();
      const dvec3 d(f.dir);
      for (int k = 0; k < kVMMLobes; ++k) {
        lg[size_t(k)] = log_a[size_t(k)] + kappa[size_t(k)] * (glm::dot(mu[size_t(k)], d) - 1.0);
        hi = std::max(hi, lg[size_t(k)]);
      }
      if (!std::isfinite(hi)) continue;
      double sum = 0.0;
      for (double& x : lg) sum += (x = std::exp(x - hi));
      const double w = double(f.weight) * normalise / sum;
      for (int k = 0; k < kVMMLobes; ++k) {
        const double g = w * lg[size_t(k)];
        VMMLobeStats& st = batch[size_t(k)];
        st.weight += g;
        st.direction += g * d;
        if (f.known) st.inv_distance += g * double(f.inv_distance), st.distance_weight += g;
      }
    }
    // M-step, MAP: a Dirichlet prior on the weights and a prior on each
    // lobe's mean cosine, so that a lobe a few samples support stays wide.
    double total = 0.0;
    std::array<VMMLobeStats, kVMMLobes> t{};
    for (int k = 0; k < kVMMLobes; ++k) {
      const VMMLobeStats &a = prior[size_t(k)], &b = batch[size_t(k)];
      t[size_t(k)] = {a.weight + b.weight, a.direction + b.direction, a.inv_distance + b.inv_distance,
                      a.distance_weight + b.distance_weight};
      total += t[size_t(k)].weight;
    }
    const double alpha = o.weight_prior;
    for (int k = 0; k < kVMMLobes; ++k) {
      const VMMLobeStats& st = t[size_t(k)];
      VMMLobe& l = m.lobes[size_t(k)];
      l.weight = float((st.weight + alpha) / (total + kVMMLobes * alpha));
      const double len = glm::length(st.direction);
      if (st.weight > 1e-9 * total && len > 0.0 && std::isfinite(len)) {
        l.mu = vec3(st.direction / len);
        const double r = std::min(len / st.weight, 1.0);
        const double beta = o.mean_cosine_strength;
        const double r_map = (r * st.weight + double(o.mean_cosine_prior) * beta) / (st.weight + beta);
        l.kappa = std::min(vmf_kappa_from_mean_cosine(float(r_map)), o.max_kappa);
      }
      l.inv_distance = st.distance_weight > 0.0 ? float(st.inv_distance / st.distance_weight) : 0.0f;
    }
  }
  for (int k = 0; k < kVMMLobes; ++k) {
    VMMLobeStats &st = region.stats[size_t(k)], &b = batch[size_t(k)];
    st.weight += b.weight, st.direction += b.direction;
    st.inv_distance += b.inv_distance, st.distance_weight += b.distance_weight;
  }
  region.weight_sum += double(fit.size());
  region.norm = norms(m);
  region.fitted = true;
}

// ---------------------------------------------------------------- the field

VMMField::VMMField(const SDTree& tree, const VMMOptions& options) : tree_(tree), options_(options) {
  regions_.resize(tree.leaf_count());
  boxes_ = tree.leaf_boxes();
}

void VMMField::add_samples(std::span<const VMMSample> samples) {
  pending_.insert(pending_.end(), samples.begin(), samples.end());
}

void VMMField::update() {
  ScopedTimer timer(fit_seconds_);
  // Follow the tree's splits: a split leaf keeps its index for one half and
  // the other halves are appended, so a leaf whose box changed was split and
  // a new leaf's parent is the old box holding its centre.
  const std::vector<Bounds3> boxes = tree_.leaf_boxes();
  std::vector<VMMRegion> old = regions_;
  regions_.resize(boxes.size());
  auto same = [](const Bounds3& a, const Bounds3& b) { return a.min == b.min && a.max == b.max; };
  for (size_t j = 0; j < boxes.size(); ++j) {
    if (j < old.size() && same(boxes[j], boxes_[j])) continue;
    size_t parent = j;
    if (j >= old.size()) {
      const vec3 c = boxes[j].centroid();
      for (size_t i = 0; i < boxes_.size(); ++i)
        if (boxes_[i].contains(c)) {
          parent = i;
          break;
        }
    }
    if (parent >= old.size()) continue;  // cannot happen: the old boxes tile the root
    regions_[j] = old[parent];
    scale(regions_[j], options_.split_decay);
  }
  boxes_ = boxes;

  // The iteration's samples grouped by leaf, each group in the given order.
  const size_t n = pending_.size();
  std::vector<uint32_t> leaf_of(n);
  tbb::parallel_for(size_t(0), n, [&](size_t i) {
    leaf_of[i] = finite3(pending_[i].p) ? tree_.leaf_index(pending_[i].p) : 0xffffffffu;
  });
  std::vector<size_t> first(regions_.size() + 1, 0);
  for (uint32_t l : leaf_of)
    if (l < regions_.size()) ++first[l + 1];
  for (size_t l = 0; l < regions_.size(); ++l) first[l + 1] += first[l];
  std::vector<VMMSample> grouped(first.back());
  {
    std::vector<size_t> at(first.begin(), first.end() - 1);
    for (size_t i = 0; i < n; ++i)
      if (leaf_of[i] < regions_.size()) grouped[at[leaf_of[i]]++] = pending_[i];
  }
  pending_ = {};  // nothing kept once training ends (the recorder may detach without telling)
  tbb::parallel_for(size_t(0), regions_.size(), [&](size_t l) {
    vmm_fit(regions_[l], std::span(grouped).subspan(first[l], first[l + 1] - first[l]), options_);
  });
  // Handles keep leaf index and cell below bit 31, so none is kNoGuideRegion.
  const int leaf_bits = std::bit_width(regions_.size());
  cell_bits_ = std::max(0, std::min(kVMMCellBits, (31 - leaf_bits) / 3));
}

uint32_t VMMField::region(const vec3& p) const {
  if (!finite3(p) || regions_.empty() || boxes_.size() != regions_.size()) return kNoGuideRegion;
  const uint32_t leaf = tree_.leaf_index(p);
  if (leaf >= regions_.size() || !regions_[leaf].fitted) return kNoGuideRegion;
  const int b = cell_bits_;
  const float cells = float(1u << b);
  const vec3 o = glm::clamp(boxes_[leaf].offset(p) * cells, vec3(0.0f), vec3(cells - 1.0f));
  const uint32_t cell = uint32_t(o.x) | uint32_t(o.y) << b | uint32_t(o.z) << (2 * b);
  return leaf << (3 * b) | cell;
}

VMMixture VMMField::mixture_at(uint32_t region) const {
  const uint32_t leaf = leaf_of(region);
  const VMMRegion& r = regions_[leaf];
  if (!options_.parallax) return r.mixture;
  const int b = cell_bits_;
  const uint32_t mask = (1u << b) - 1u;
  const vec3 q(float(region & mask), float((region >> b) & mask), float((region >> (2 * b)) & mask));
  const Bounds3& box = boxes_[leaf];
  const vec3 p = box.min + (q + 0.5f) / float(1u << b) * box.diagonal();
  return vmm_at(r.mixture, r.pivot, p);
}

GuideSample VMMField::sample(uint32_t region, vec2 u) const {
  if (region == kNoGuideRegion || leaf_of(region) >= regions_.size()) return {};
  return vmm_sample(mixture_at(region), regions_[leaf_of(region)].norm, u);
}

float VMMField::pdf(uint32_t region, const vec3& wi) const {
  if (region == kNoGuideRegion || leaf_of(region) >= regions_.size()) return 0.0f;
  return vmm_pdf(mixture_at(region), regions_[leaf_of(region)].norm, wi);
}

float VMMField::selection_probability(uint32_t region) const {
  return tree_.selection_probability(region == kNoGuideRegion ? region : leaf_of(region));
}

float VMMField::radiance_integral(uint32_t region) const {
  return region == kNoGuideRegion ? 0.0f : tree_.radiance_integral(leaf_of(region));
}

void VMMField::count_failed_draw(uint32_t region) const {
  if (region != kNoGuideRegion) tree_.count_failed_draw(leaf_of(region));
}

size_t VMMField::memory_bytes() const {
  return sizeof(*this) + regions_.capacity() * sizeof(VMMRegion) + boxes_.capacity() * sizeof(Bounds3) +
         pending_.capacity() * sizeof(VMMSample);
}

// ---------------------------------------------------------------- checkpoint

namespace {

constexpr char kVMMMagic[8] = {'T', 'H', 'E', 'I', 'A', 'V', 'M', 'M'};
constexpr uint32_t kVMMVersion = 1;
// What one region takes on disk (the reader refuses a count the input cannot hold).
constexpr size_t kRegionBytes = kVMMLobes * (sizeof(vec3) + 3 * sizeof(float)) +
                                kVMMLobes * (3 * sizeof(double) + sizeof(dvec3)) + sizeof(dvec3) +
                                2 * sizeof(double) + sizeof(vec3) + 1;

bool finite3d(const dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
bool non_negative(double v) { return v >= 0.0 && std::isfinite(v); }

void put_options(ByteWriter& w, const VMMOptions& o) {
  w.put(int32_t(o.em_iterations));
  w.put(o.weight_prior);
  w.put(o.mean_cosine_prior);
  w.put(o.mean_cosine_strength);
  w.put(o.max_kappa);
  w.put(o.decay);
  w.put(uint8_t(o.parallax));
  w.put(o.pdf_floor);
  w.put(o.split_decay);
}

// The options the bytes were written with, as put_options lays them out
// (compared whole: a field fitted with other options is not this render's).
std::vector<uint8_t> options_bytes(const VMMOptions& o) {
  ByteWriter w;
  put_options(w, o);
  return std::move(w.bytes);
}

}  // namespace

std::vector<uint8_t> VMMField::serialize() const {
  ByteWriter w;
  w.bytes.assign(std::begin(kVMMMagic), std::end(kVMMMagic));
  w.put(kVMMVersion);
  put_options(w, options_);
  w.put(int32_t(cell_bits_));
  w.put(uint64_t(regions_.size()));
  for (const VMMRegion& r : regions_) {
    for (const VMMLobe& l : r.mixture.lobes) w.put(l.mu), w.put(l.kappa), w.put(l.weight), w.put(l.inv_distance);
    for (const VMMLobeStats& st : r.stats)
      w.put(st.weight), w.put(st.direction), w.put(st.inv_distance), w.put(st.distance_weight);
    w.put(r.position_sum);
    w.put(r.position_count);
    w.put(r.pivot);
    w.put(r.weight_sum);
    w.put(uint8_t(r.fitted));
  }
  w.put(uint64_t(boxes_.size()));
  for (const Bounds3& b : boxes_) w.put(b.min), w.put(b.max);
  w.put_vector(pending_);
  w.put(hash_bytes(w.bytes.data(), w.bytes.size()));
  return std::move(w.bytes);
}

// Every value is checked against what update() can produce (finite, weights
// and concentrations in range, unit directions), so no input makes a lookup
// read out of bounds or return a non-finite density.
void VMMField::restore(std::span<const uint8_t> bytes, const std::string& what) {
  constexpr size_t kHeader = sizeof(kVMMMagic) + sizeof(uint32_t);
  if (bytes.size() < kHeader + sizeof(uint64_t))
    throw_error("{}: mixture field truncated: {} bytes, a header and checksum need {}", what, bytes.size(),
                kHeader + sizeof(uint64_t));
  if (std::memcmp(bytes.data(), kVMMMagic, sizeof(kVMMMagic)) != 0)
    throw_error("{}: mixture field corrupt: expected the magic \"THEIAVMM\"", what);
  uint32_t version;
  std::memcpy(&version, bytes.data() + sizeof(kVMMMagic), sizeof(version));
  if (version != kVMMVersion)
    throw_error("{}: mixture field has version {}, this build reads {}", what, version, kVMMVersion);
  const size_t body = bytes.size() - sizeof(uint64_t);
  uint64_t stored;
  std::memcpy(&stored, bytes.data() + body, sizeof(stored));
  if (stored != hash_bytes(bytes.data(), body))
    throw_error("{}: mixture field corrupt or truncated: checksum mismatch over {} bytes", what, body);

  ByteReader r(bytes.first(body), what + ": mixture field");
  r.pos = kHeader;
  const std::vector<uint8_t> options = options_bytes(options_);
  r.need(options.size());
  if (std::memcmp(r.data + r.pos, options.data(), options.size()) != 0)
    throw_error("{}: the mixture field was fitted with other options", what);
  r.pos += options.size();
  const int32_t cell_bits = r.get<int32_t>();
  const uint64_t count = r.get<uint64_t>();
  if (count != tree_.leaf_count())
    throw_error("{}: mixture field of {} regions for an SD-tree of {} leaves", what, count, tree_.leaf_count());
  r.need(count * kRegionBytes);
  if (cell_bits < 0 || cell_bits > kVMMCellBits || 3 * cell_bits + std::bit_width(count) > 31)
    throw_error("{}: mixture field corrupt: {} cell bits for {} regions", what, cell_bits, count);
  std::vector<VMMRegion> regions(count);
  for (size_t i = 0; i < count; ++i) {
    VMMRegion& g = regions[i];
    auto corrupt = [&](const char* part) { throw_error("{}: mixture field corrupt: region {} {}", what, i, part); };
    for (VMMLobe& l : g.mixture.lobes) {
      l.mu = r.get<vec3>();
      l.kappa = r.get<float>();
      l.weight = r.get<float>();
      l.inv_distance = r.get<float>();
      const float len = glm::length(l.mu);
      if (!finite3(l.mu) || !(std::abs(len - 1.0f) < 1e-3f)) corrupt("has a lobe direction that is not unit");
      if (!(l.kappa >= 0.0f && l.kappa <= options_.max_kappa)) corrupt("has a lobe concentration out of range");
      if (!(l.weight >= 0.0f && l.weight <= 1.0f)) corrupt("has a lobe weight out of [0, 1]");
      if (!non_negative(l.inv_distance)) corrupt("has a negative or non-finite inverse distance");
    }
    for (VMMLobeStats& st : g.stats) {
      st.weight = r.get<double>();
      st.direction = r.get<dvec3>();
      st.inv_distance = r.get<double>();
      st.distance_weight = r.get<double>();
      if (!non_negative(st.weight) || !finite3d(st.direction) || !non_negative(st.inv_distance) ||
          !non_negative(st.distance_weight))
        corrupt("has malformed lobe statistics");
    }
    g.position_sum = r.get<dvec3>();
    g.position_count = r.get<double>();
    g.pivot = r.get<vec3>();
    g.weight_sum = r.get<double>();
    const uint8_t fitted = r.get<uint8_t>();
    if (!finite3d(g.position_sum) || !non_negative(g.position_count) || !finite3(g.pivot) ||
        !non_negative(g.weight_sum) || fitted > 1)
      corrupt("has a malformed pivot or sample count");
    g.fitted = fitted != 0;
    double weights = 0.0;
    for (const VMMLobe& l : g.mixture.lobes) weights += double(l.weight);
    if (!(std::abs(weights - 1.0) < 1e-4)) corrupt("has lobe weights that do not sum to one");
    // Not stored: vmm_fit sets it from the kappas, which nothing else changes.
    g.norm = g.fitted ? norms(g.mixture) : std::array<float, kVMMLobes>{};
  }
  const uint64_t box_count = r.get<uint64_t>();
  if (box_count != count) throw_error("{}: mixture field corrupt: {} boxes for {} regions", what, box_count, count);
  r.need(box_count * sizeof(Bounds3));
  const std::vector<Bounds3> tree_boxes = tree_.leaf_boxes();
  std::vector<Bounds3> boxes(box_count);
  for (size_t i = 0; i < box_count; ++i) {
    boxes[i].min = r.get<vec3>();
    boxes[i].max = r.get<vec3>();
    if (boxes[i].min != tree_boxes[i].min || boxes[i].max != tree_boxes[i].max)
      throw_error("{}: mixture field region {}'s box is not the SD-tree's leaf {}'s", what, i, i);
  }
  std::vector<VMMSample> pending = r.get_vector<VMMSample>();
  if (r.pos != r.size) throw_error("{}: mixture field corrupt: {} unread bytes before the checksum", what, r.size - r.pos);
  regions_ = std::move(regions);
  boxes_ = std::move(boxes);
  pending_ = std::move(pending);
  cell_bits_ = cell_bits;
}

}  // namespace theia
