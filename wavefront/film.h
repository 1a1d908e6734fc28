// The film: per-pixel sums that many threads splat into at once.
//
// Every sample contributes weight * value to its own pixel (filter importance
// sampling: no sample touches a neighbour), so a pixel is sum(w L) / sum(w).
// A value that is NaN, infinite or beyond kMaxSampleValue is dropped and
// counted, never stored: below that bound 1e8 samples of one pixel still sum
// to a finite float, so no Inf can reach a buffer through its sums either.
// Weights are negative in the negative lobes of Mitchell and Lanczos filters
// and are summed as they are, as pbrt-v4's RGBFilm does: nothing clamps them.
#pragma once

#include "core/image.h"
#include "core/math.h"

#include <atomic>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace theia {

// An extra RGB layer of per-pixel sums (interleaved RGB), resolved like the
// beauty (divided by the pixel's weight) as channels NAME.R NAME.G NAME.B:
// how other subsystems (the recorder's debug buffers) reach the EXR.
struct FilmLayer {
  std::string name;
  std::vector<float> rgb;
};

inline constexpr float kMaxSampleValue = 1e30f;

// The class of a camera path by its first scattering event (--aov-events):
// light seen directly (or through pass-through surfaces and virtual lights)
// is `emission`; otherwise the type of the first surface event as BSDF
// sampling labels it (event_of_lobe in engine_impl.h), or `volume` for a real
// scattering in a medium.  Every splat carries its path's class, so the layers sum to
// the beauty.
enum PathEvent : uint8_t { kEventEmission, kEventDiffuse, kEventGlossy, kEventSpecular, kEventVolume, kEventCount };
inline constexpr const char* kEventLayerNames[kEventCount] = {"emission", "diffuse", "glossy", "specular", "volume"};
inline std::vector<std::string> event_layer_names() { return {std::begin(kEventLayerNames), std::end(kEventLayerNames)}; }
// Logs that `exr_path` has the event layers beside the beauty.
void log_event_layers(const std::string& exr_path);

// False for NaN, infinities and components beyond +-kMaxSampleValue.
inline bool is_storable(const RGB& v) {
  return std::abs(v.x) <= kMaxSampleValue && std::abs(v.y) <= kMaxSampleValue && std::abs(v.z) <= kMaxSampleValue;
}

struct Film {
  int width = 0, height = 0;
  // Planar float sums, one entry per pixel each.
  std::vector<float> r, g, b;      // sum of w * L
  std::vector<float> weight;       // sum of w
  std::vector<float> alpha;        // sum of w where the camera ray hit geometry (alpha samples only)
  std::vector<float> alpha_weight; // sum of w over the samples that count for alpha
  std::vector<float> albedo[3];    // first-hit AOVs, sums of w * value
  std::vector<float> normal[3];
  std::vector<float> depth;
  // The same sums over odd-numbered samples only: with the full sums they give
  // two independent half estimates of each pixel, whose difference estimates
  // its variance (adaptive sampling, inverse-variance combination).
  std::vector<float> r_odd, g_odd, b_odd, weight_odd;
  std::atomic<uint64_t> dropped{0};  // non-finite or too large contributions discarded
  std::vector<FilmLayer> layers;     // extra layers, after the AOVs
  // --aov-events: sums of w * L per path class (PathEvent), planar RGB;
  // empty unless enabled, and then planes after the kPlaneCount fixed ones.
  std::vector<float> events[kEventCount][3];

  Film(int w, int h, bool aov_events = false);
  size_t pixel_count() const { return size_t(width) * size_t(height); }
  size_t memory_bytes() const {
    return (pixel_count() * plane_count() + thread_sums_.size()) * sizeof(float) + lock_count();
  }
  bool aov_events() const { return !events[0][0].empty(); }

  // Every per-pixel plane, named, in a fixed order: for clearing, summing
  // iterations and checkpoints.  The first kPlaneCount are always there,
  // the event planes (plane_name) only with aov_events().
  static constexpr size_t kPlaneCount = 17;
  static constexpr size_t kEventPlaneCount = 3 * kEventCount;
  static const char* const kPlaneNames[kPlaneCount];
  size_t plane_count() const { return kPlaneCount + (aov_events() ? kEventPlaneCount : 0); }
  static std::string plane_name(size_t i);  // kPlaneNames, then "diffuse.R" ... for the event planes
  std::vector<float>* plane(size_t i);
  const std::vector<float>* plane(size_t i) const { return const_cast<Film*>(this)->plane(i); }
  void clear();
  // this += o, plane by plane (o must have the same size).
  void add(const Film& o);

  // A camera sample's filter weight: to the colour weights unless `colour`
  // is false (a coverage-only sample), to the alpha weight if `alpha`; one
  // lookup of the thread's sums (or one lock) for both.
  void add_weights(uint32_t pixel, uint32_t sample, float w, bool colour, bool alpha);
  void add_weight(uint32_t pixel, uint32_t sample, float w) { add_weights(pixel, sample, w, true, false); }
  void add_alpha_weight(uint32_t pixel, float w) { add_weights(pixel, 0, w, false, true); }
  // `event`: the path's PathEvent, kept only with aov_events().
  void splat(uint32_t pixel, uint32_t sample, const RGB& weighted_L, uint8_t event);
  void splat_first_hit(uint32_t pixel, float w, bool hit, const RGB& albedo, const vec3& n, float depth);

  // Per-thread sums: up to `threads` threads each add into their own copy of
  // the fixed planes, without atomics (an uncontended atomic float add is a
  // compare-exchange loop, and a splat made up to eight); flush() adds the
  // copies into the planes and must run before the planes are read.  Off
  // when the copies would exceed kMaxThreadSumBytes (a production frame:
  // 141 MB a thread at 1080p), with aov_events() (the event layers must sum
  // to the beauty), and for threads beyond `threads`: those add into the
  // planes themselves, under a spin lock per kPixelsPerLock pixels: one
  // locked instruction a splat, where atomic adds took one a value.  Lanes
  // splat runs of whole pixels far apart, so the locks are hardly ever
  // contended.
  static constexpr size_t kMaxThreadSumBytes = size_t(32) << 20;
  static constexpr size_t kPixelsPerLock = 32;
  void use_thread_sums(int threads);
  void flush();
  // Moves the planes' sums into the calling thread's own, so that its adds
  // continue one running sum: a resumed iteration's restored film then ends
  // in the same bits as an uninterrupted one on one thread.
  void continue_in_thread_sums();

 private:
  std::vector<float> thread_sums_;  // [thread][pixel][plane]: kPlaneCount floats a pixel
  size_t thread_sum_count_ = 0;
  float* thread_sum(uint32_t pixel);
  std::unique_ptr<std::atomic<uint8_t>[]> locks_;  // 1: held; one per kPixelsPerLock pixels
  size_t lock_count() const { return (pixel_count() + kPixelsPerLock - 1) / kPixelsPerLock; }
  class PixelLock;
};

// sum / weight, or 0 where that is not a finite number: a pixel whose
// (signed) weights sum to zero stays black, as in pbrt-v4, and one whose sum
// is so small that the quotient overflows does too.
inline float resolve_sum(float sum, float weight) {
  float v = weight != 0.0f ? sum / weight : 0.0f;
  return std::isfinite(v) ? v : 0.0f;
}

// Appends each layer (per-pixel sums of w * value, working space) to `image`
// as NAME.R/G/B in linear sRGB, divided by the per-pixel weight sums.
void append_film_layers(ImageBuffer& image, const std::vector<FilmLayer>& layers, const std::vector<float>& weight);

// The film's sums as an image: channel PREFIX + kPlaneNames[i] for every
// plane (float32 EXR keeps them exactly), so that films rendered apart (a
// frame's sample ranges) can be written, read and added.
ImageBuffer film_sums_image(const Film& film, const std::string& prefix);
// Whether film_sums_image(film, prefix) made `image` from a film with aov_events().
bool sums_have_aov_events(const ImageBuffer& image, const std::string& prefix);
// film += the planes of `image` named PREFIX + plane_name(i); throws
// theia::Error naming `what` and the channel when one is missing, the size
// differs, or one of them has the --aov-events planes and the other not.
void add_film_sums(Film& film, const ImageBuffer& image, const std::string& prefix, const std::string& what);

// Resolve to an image with channels R G B A albedo.R albedo.G albedo.B N.X N.Y N.Z depth.Z,
// then EVENT.R EVENT.G EVENT.B per path class with aov_events() (divided by the
// beauty's weight, so they sum to R G B), then LAYER.R LAYER.G LAYER.B for
// each extra layer.
ImageBuffer resolve_film(const Film& film);

}  // namespace theia
