#include "wavefront/film.h"

#include "core/color.h"
#include "core/log.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <thread>

namespace theia {

const char* const Film::kPlaneNames[Film::kPlaneCount] = {
    "R",    "G",    "B",    "weight", "alpha", "albedo.R", "albedo.G", "albedo.B", "N.X",
    "N.Y",  "N.Z",  "depth", "odd.R", "odd.G", "odd.B",    "odd.weight", "alpha_weight"};

void log_event_layers(const std::string& exr_path) {
  std::string names;
  for (const char* n : kEventLayerNames) names += (names.empty() ? "" : ", ") + std::string(n);
  log_info("{}: --aov-events layers {} (.R .G .B) beside the beauty", exr_path, names);
}

std::string Film::plane_name(size_t i) {
  if (i < kPlaneCount) return kPlaneNames[i];
  i -= kPlaneCount;
  return std::string(kEventLayerNames[i / 3]) + "." + "RGB"[i % 3];
}

std::vector<float>* Film::plane(size_t i) {
  std::vector<float>* all[kPlaneCount] = {&r,         &g,         &b,         &weight,    &alpha,     &albedo[0],
                                              &albedo[1], &albedo[2], &normal[0], &normal[1], &normal[2], &depth,
                                              &r_odd,     &g_odd,     &b_odd,     &weight_odd, &alpha_weight};
  if (i < kPlaneCount) return all[i];
  i -= kPlaneCount;
  return i < kEventPlaneCount ? &events[i / 3][i % 3] : nullptr;
}

Film::Film(int w, int h, bool aov_events) : width(w), height(h) {
  locks_ = std::make_unique<std::atomic<uint8_t>[]>(lock_count());
  // The event planes exist (are non-empty) exactly when enabled.
  if (aov_events)
    for (auto& e : events)
      for (auto& c : e) c.resize(pixel_count());
  clear();
}

void Film::clear() {
  for (size_t i = 0; i < plane_count(); ++i) plane(i)->assign(pixel_count(), 0.0f);
  std::fill(thread_sums_.begin(), thread_sums_.end(), 0.0f);
  dropped = 0;
}

namespace {

// A small number per OS thread, given on its first splat: the per-thread sums
// it adds into.  Stable for the thread's life, which a TBB slot index is not
// (a worker may leave the arena and come back in another slot).
std::atomic<size_t> g_next_thread_number{0};

size_t thread_number() {
  thread_local const size_t n = g_next_thread_number.fetch_add(1, std::memory_order_relaxed);
  return n;
}

}  // namespace

void Film::use_thread_sums(int threads) {
  flush();
  // The threads a render has numbered before (a process's earlier renders,
  // other subsystems' threads) take numbers too: room for a few more.
  const size_t count = size_t(std::max(threads, 1)) + 2;
  const size_t bytes = count * pixel_count() * kPlaneCount * sizeof(float);
  // With --aov-events the layers must sum to the beauty to float precision:
  // both keep the atomics, so that they are summed alike.
  thread_sum_count_ = bytes <= kMaxThreadSumBytes && !aov_events() ? count : 0;
  thread_sums_.assign(thread_sum_count_ * pixel_count() * kPlaneCount, 0.0f);
}

float* Film::thread_sum(uint32_t pixel) {
  const size_t t = thread_number();
  return t < thread_sum_count_ ? &thread_sums_[(t * pixel_count() + pixel) * kPlaneCount] : nullptr;
}

void Film::continue_in_thread_sums() {
  float* mine = thread_sums_.empty() ? nullptr : thread_sum(0);
  if (!mine) return;
  for (size_t i = 0; i < kPlaneCount; ++i) {
    float* p = plane(i)->data();
    for (size_t px = 0; px < pixel_count(); ++px) {
      mine[px * kPlaneCount + i] += p[px];
      p[px] = 0.0f;
    }
  }
}

void Film::flush() {
  if (thread_sums_.empty()) return;
  float* planes[kPlaneCount];
  for (size_t i = 0; i < kPlaneCount; ++i) planes[i] = plane(i)->data();
  const size_t n = pixel_count();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1024), [&](const tbb::blocked_range<size_t>& range) {
    for (size_t t = 0; t < thread_sum_count_; ++t)
      for (size_t px = range.begin(); px < range.end(); ++px) {
        float* s = &thread_sums_[(t * n + px) * kPlaneCount];
        for (size_t i = 0; i < kPlaneCount; ++i) {
          planes[i][px] += s[i];
          s[i] = 0.0f;
        }
      }
  });
}

void Film::add(const Film& o) {
  if (o.plane_count() != plane_count()) throw_error("adding films with and without --aov-events layers");
  for (size_t i = 0; i < plane_count(); ++i) {
    std::vector<float>* p = plane(i);
    const std::vector<float>& q = *o.plane(i);
    for (size_t k = 0; k < p->size(); ++k) (*p)[k] += q[k];
  }
  dropped += o.dropped.load();
}

namespace {

// The planes' order in a pixel's per-thread sums (Film::plane).
enum : size_t { kR, kG, kB, kWeight, kAlpha, kAlbedo, kNormal = kAlbedo + 3, kDepth = kNormal + 3, kOddR, kOddG, kOddB,
                kOddWeight, kAlphaWeight };
static_assert(kAlphaWeight + 1 == Film::kPlaneCount);

}  // namespace

// Held for a splat's adds into the planes (Film::kPixelsPerLock).  A waiter
// that keeps finding it held yields: with more threads than cores (a wrong
// --threads) the holder may have been preempted inside its few adds.
class Film::PixelLock {
 public:
  PixelLock(const Film& film, uint32_t pixel) : lock_(film.locks_[pixel / kPixelsPerLock]) {
    for (int spins = 0; lock_.exchange(1, std::memory_order_acquire);)
      while (lock_.load(std::memory_order_relaxed))
        if (spins < kSpinsBeforeYield) ++spins, pause();
        else std::this_thread::yield();
  }
  ~PixelLock() { lock_.store(0, std::memory_order_release); }
  PixelLock(const PixelLock&) = delete;
  PixelLock& operator=(const PixelLock&) = delete;

 private:
  static constexpr int kSpinsBeforeYield = 64;
  static void pause() {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
  }
  std::atomic<uint8_t>& lock_;
};

void Film::add_weights(uint32_t pixel, uint32_t sample, float w, bool colour, bool alpha) {
  if (!colour && !alpha) return;
  if (float* s = thread_sum(pixel)) {
    if (colour) s[kWeight] += w;
    if (colour && (sample & 1)) s[kOddWeight] += w;
    if (alpha) s[kAlphaWeight] += w;
    return;
  }
  PixelLock lock(*this, pixel);
  if (colour) weight[pixel] += w;
  if (colour && (sample & 1)) weight_odd[pixel] += w;
  if (alpha) alpha_weight[pixel] += w;
}

void Film::splat(uint32_t pixel, uint32_t sample, const RGB& L, uint8_t event) {
  if (!is_storable(L)) {
    dropped.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  if (float* s = thread_sum(pixel)) {
    s[kR] += L.x;
    s[kG] += L.y;
    s[kB] += L.z;
    if (sample & 1) {
      s[kOddR] += L.x;
      s[kOddG] += L.y;
      s[kOddB] += L.z;
    }
    return;
  }
  PixelLock lock(*this, pixel);  // (with aov_events() there are no per-thread sums)
  if (aov_events()) {
    std::vector<float>(&e)[3] = events[event < kEventCount ? event : uint8_t(kEventEmission)];
    for (int c = 0; c < 3; ++c) e[c][pixel] += L[c];
  }
  r[pixel] += L.x;
  g[pixel] += L.y;
  b[pixel] += L.z;
  if (sample & 1) {
    r_odd[pixel] += L.x;
    g_odd[pixel] += L.y;
    b_odd[pixel] += L.z;
  }
}

void Film::splat_first_hit(uint32_t pixel, float w, bool hit, const RGB& a, const vec3& n, float d) {
  if (!hit) return;
  if (!is_finite(a) || !is_finite(n) || !std::isfinite(d)) {
    dropped.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  if (float* s = thread_sum(pixel)) {
    s[kAlpha] += w;
    for (size_t c = 0; c < 3; ++c) {
      s[kAlbedo + c] += w * a[int(c)];
      s[kNormal + c] += w * n[int(c)];
    }
    s[kDepth] += w * d;
    return;
  }
  PixelLock lock(*this, pixel);
  alpha[pixel] += w;
  for (int c = 0; c < 3; ++c) {
    albedo[c][pixel] += w * a[c];
    normal[c][pixel] += w * n[c];
  }
  depth[pixel] += w * d;
}

void append_film_layers(ImageBuffer& img, const std::vector<FilmLayer>& layers, const std::vector<float>& weight) {
  const size_t n = size_t(img.width) * size_t(img.height);
  const size_t old_nc = img.channels.size();
  for (const FilmLayer& l : layers)
    for (const char* c : {".R", ".G", ".B"}) img.channels.push_back(l.name + c);
  const size_t nc = img.channels.size();
  std::vector<float> data(n * nc, 0.0f);
  for (size_t i = 0; i < n; ++i) {
    std::copy_n(&img.data[i * old_nc], old_nc, &data[i * nc]);
    if (weight[i] == 0.0f) continue;
    for (size_t l = 0; l < layers.size(); ++l) {
      const std::vector<float>& rgb = layers[l].rgb;
      if (rgb.size() != 3 * n) continue;
      RGB v = working_to_srgb(RGB(resolve_sum(rgb[3 * i], weight[i]), resolve_sum(rgb[3 * i + 1], weight[i]),
                                  resolve_sum(rgb[3 * i + 2], weight[i])));
      for (int c = 0; c < 3; ++c) data[i * nc + old_nc + 3 * l + size_t(c)] = v[c];
    }
  }
  img.data.swap(data);
}

// The event planes as layers (interleaved RGB), resolved like the beauty.
static std::vector<FilmLayer> event_layers(const Film& film) {
  std::vector<FilmLayer> out(kEventCount);
  for (size_t e = 0; e < kEventCount; ++e) {
    out[e].name = kEventLayerNames[e];
    out[e].rgb.resize(3 * film.pixel_count());
    for (size_t i = 0; i < film.pixel_count(); ++i)
      for (size_t c = 0; c < 3; ++c) out[e].rgb[3 * i + c] = film.events[e][c][i];
  }
  return out;
}

ImageBuffer resolve_film(const Film& film) {
  ImageBuffer img;
  img.width = film.width;
  img.height = film.height;
  img.channels = {"R", "G", "B", "A", "albedo.R", "albedo.G", "albedo.B", "N.X", "N.Y", "N.Z", "depth.Z"};
  const size_t nc = img.channels.size();
  img.data.assign(film.pixel_count() * nc, 0.0f);
  for (size_t i = 0; i < film.pixel_count(); ++i) {
    float* px = &img.data[i * nc];
    // Alpha has its own sample count (consistent alpha): its own denominator.
    px[3] = resolve_sum(film.alpha[i], film.alpha_weight[i]);
    float w = film.weight[i];
    if (w == 0.0f) continue;
    RGB c = working_to_srgb(RGB(resolve_sum(film.r[i], w), resolve_sum(film.g[i], w), resolve_sum(film.b[i], w)));
    px[0] = c.x;
    px[1] = c.y;
    px[2] = c.z;
    // AOVs average over the samples that hit something, so edges do not fade
    // to zero.  Signed weights can cancel here too.
    float a = film.alpha[i];
    if (a != 0.0f) {
      RGB albedo = working_to_srgb(RGB(resolve_sum(film.albedo[0][i], a), resolve_sum(film.albedo[1][i], a),
                                       resolve_sum(film.albedo[2][i], a)));
      for (int c = 0; c < 3; ++c) {
        px[4 + c] = albedo[c];
        px[7 + c] = resolve_sum(film.normal[c][i], a);
      }
      px[10] = resolve_sum(film.depth[i], a);
    }
  }
  if (film.aov_events()) append_film_layers(img, event_layers(film), film.weight);
  if (!film.layers.empty()) append_film_layers(img, film.layers, film.weight);
  return img;
}

ImageBuffer film_sums_image(const Film& film, const std::string& prefix) {
  const size_t np = film.plane_count();
  std::vector<std::string> names;
  for (size_t p = 0; p < np; ++p) names.push_back(prefix + Film::plane_name(p));
  ImageBuffer img(film.width, film.height, std::move(names));
  for (size_t p = 0; p < np; ++p) {
    const std::vector<float>& v = *film.plane(p);
    for (size_t i = 0; i < v.size(); ++i) img.data[i * np + p] = v[i];
  }
  return img;
}

bool sums_have_aov_events(const ImageBuffer& image, const std::string& prefix) {
  return image.channel_index(prefix + Film::plane_name(Film::kPlaneCount)) >= 0;
}

void add_film_sums(Film& film, const ImageBuffer& image, const std::string& prefix, const std::string& what) {
  if (image.width != film.width || image.height != film.height)
    throw_error("{}: the image is {}x{}, expected {}x{}", what, image.width, image.height, film.width, film.height);
  const size_t nc = image.channels.size();
  if (sums_have_aov_events(image, prefix) != film.aov_events())
    throw_error("{}: the sums {} --aov-events layers, the film {}", what,
                film.aov_events() ? "lack the" : "have", film.aov_events() ? "has them" : "has none");
  for (size_t p = 0; p < film.plane_count(); ++p) {
    const int c = image.channel_index(prefix + Film::plane_name(p));
    if (c < 0) throw_error("{}: no channel {}{} (not a film's sums)", what, prefix, Film::plane_name(p));
    std::vector<float>& v = *film.plane(p);
    for (size_t i = 0; i < v.size(); ++i) v[i] += image.data[i * nc + size_t(c)];
  }
}

}  // namespace theia
