// The path-state pool, declared once as tables of fields (as Cycles does).
//
// The hot table generates one 64-byte record per path: what every stage reads.
// The cold tables hold per-feature state, one array per field and path slot,
// allocated only when the feature is on (a scene without curves has no curve
// skips, a render without media no medium stack).  Shading visits paths in hit
// order, which is random with respect to pool slots, so a record that fits in
// one cache line (one miss per path) beats a structure of arrays (one miss per
// field) on a CPU; the static_assert keeps it that way as fields are added.
#pragma once

#include "core/huge_pages.h"
#include "core/math.h"
#include "core/prefetch.h"
#include "scene/accel.h"
#include "scene/bsdf.h"
#include "wavefront/film.h"

#include <cstdint>
#include <vector>

namespace theia {

//   type       name            meaning
#define THEIA_PATH_STATE_FIELDS(F)                                                           \
  F(RGB, beta)                /* path throughput */                                           \
  F(vec3, prev_p)             /* the vertex the ray left (for light pdfs at emitter hits) */  \
  F(vec3, prev_ng)            /* its geometric normal */                                      \
  F(uint32_t, pixel)          /* y * width + x */                                             \
  F(uint32_t, sample)         /* sample index within the pixel */                             \
  F(uint32_t, vertex)         /* the path observer's handle (kNoVertex without observer) */   \
  F(float, filter_weight)     /* filter-importance-sampling weight of the camera sample */    \
  F(float, prev_pdf)          /* solid-angle pdf of the BSDF sample that made the ray */      \
  F(float, eta_scale)         /* product of eta^2 over refractions (pbrt-v4's etaScale, RR) */ \
  F(uint16_t, depth)          /* bounces so far: 0 for the camera ray */                      \
  F(uint8_t, flags)           /* PathFlags */                                                  \
  F(uint8_t, alpha_only)      /* consistent alpha: the camera ray only measures coverage */

enum PathFlags : uint8_t {
  kPathPrevSpecular = 1 << 0,    // the ray's direction came from a specular lobe
  kPathCausticReceiver = 1 << 1, // the primary hit was a caustic receiver (wavefront/caustics.h)
  kPathCausticCaster = 1 << 2,   // ... and the ray leaves the caster after it
  // Bits 3-5: the path's PathEvent (wavefront/film.h), the type of its first
  // scattering event (kEventEmission before it): every splat of the path,
  // and of its shadow rays, goes to that event's layer (--aov-events).
  kPathEventBits = 7 << 3,
};
inline constexpr int kPathEventShift = 3;
inline uint8_t path_event(uint8_t flags) { return uint8_t((flags & kPathEventBits) >> kPathEventShift); }
// The event bits of a path that scatters now with `event`: its first event's, once it has one.
inline uint8_t first_event_bits(uint8_t flags, uint8_t event) {
  return (flags & kPathEventBits) ? uint8_t(flags & kPathEventBits) : uint8_t(event << kPathEventShift);
}

struct alignas(64) PathState {
#define THEIA_DECLARE_FIELD(type, name) type name;
  THEIA_PATH_STATE_FIELDS(THEIA_DECLARE_FIELD)
#undef THEIA_DECLARE_FIELD
};
static_assert(sizeof(PathState) == 64, "a path's state should stay within one cache line");

// Cold per-feature state, indexed by path slot.
//   type       name          feature    meaning
#define THEIA_PATH_COLD_FIELDS(F)                                                                               \
  F(PrimRef, curve_skip, curves, "the curve segment the path's queued ray left (scene/accel.h: skips beside rays)") \
  F(double, roulette_correction, guiding, "product of guided pdf / BSDF pdf (seeds/000 ch. 1 eq. 18), in double") \
  F(float, pixel_estimate, adjoint_roulette, "the field's estimate of the path's pixel value (0: none yet)") \
  F(int32_t, medium, media, "the medium the path's queued ray travels in (Scene::media index, -1 vacuum)") \
  F(uint16_t, flight_depth, media, "depth + 1 of the last free flight that drew the stratified medium_flight") \
  F(float, roughness, roughening, "regularised roughness of the lobe that sampled the path's ray (0: camera ray)") \
  F(DeferredPdf, deferred_pdf, layered, "a layered sample's pdf inputs, where prev_pdf is kDeferredPdf (scene/bsdf.h)")

// Which features are on, so the cold tables know which fields to allocate.
struct PathFeatures {
  bool curves = false;
  bool guiding = false;  // with the roulette correction
  bool adjoint_roulette = false;
  bool media = false;    // Scene::has_media
  bool roughening = false;  // EngineOptions::roughening > 0
  bool layered = false;  // coated materials, and EngineOptions::defer_layered_pdf
};

// PathState::prev_pdf of a ray a layered BSDF sampled: its MIS pdf is in the
// path's deferred_pdf, computed only where an emitter's MIS weight needs it.
inline constexpr float kDeferredPdf = -1.0f;

struct PathStatePool {
  std::vector<PathState> paths;
  std::vector<uint32_t> free_slots;  // stack of unused slots
#define THEIA_DECLARE_COLD_FIELD(type, name, feature, doc) std::vector<type> name;
  THEIA_PATH_COLD_FIELDS(THEIA_DECLARE_COLD_FIELD)
#undef THEIA_DECLARE_COLD_FIELD
  bool has_cold = false;  // any of the tables: one test per hit where none is

  // Every table is advised for huge pages before it is first written
  // (core/huge_pages.h): a pool is megabytes (material-testball: 5 MiB hot,
  // 10 MiB of layered pdfs), which 4 KiB faults filled at ~2% of the CPU.
  PathStatePool(size_t capacity, const PathFeatures& features) {
    reserve_huge(paths, capacity);
    paths.resize(capacity);
    free_slots.resize(capacity);
    // Hand out low slots first so a small render touches little memory.
    for (size_t i = 0; i < capacity; ++i) free_slots[i] = uint32_t(capacity - 1 - i);
#define THEIA_ALLOCATE_COLD_FIELD(type, name, feature, doc) \
  if (features.feature) {                                   \
    reserve_huge(name, capacity);                           \
    name.resize(capacity);                                  \
    has_cold = true;                                        \
  }
    THEIA_PATH_COLD_FIELDS(THEIA_ALLOCATE_COLD_FIELD)
#undef THEIA_ALLOCATE_COLD_FIELD
  }

  // Fetches a slot's cold fields of the features that are on: shading visits
  // paths in hit order, so each table costs a cache miss per vertex unless
  // it is asked for a few hits ahead, as the hot record is.
  void prefetch_cold(uint32_t slot) const {
    if (!has_cold) return;
#define THEIA_PREFETCH_COLD_FIELD(type, name, feature, doc) \
  if (!name.empty()) prefetch_line(&name[slot]);
    THEIA_PATH_COLD_FIELDS(THEIA_PREFETCH_COLD_FIELD)
#undef THEIA_PREFETCH_COLD_FIELD
  }

  PathState& operator[](uint32_t slot) { return paths[slot]; }
  const PathState& operator[](uint32_t slot) const { return paths[slot]; }
  size_t capacity() const { return paths.size(); }
  size_t live() const { return capacity() - free_slots.size(); }
  size_t memory_bytes() const {
    size_t bytes = paths.capacity() * sizeof(PathState) + free_slots.capacity() * sizeof(uint32_t);
#define THEIA_COLD_FIELD_BYTES(type, name, feature, doc) bytes += name.capacity() * sizeof(type);
    THEIA_PATH_COLD_FIELDS(THEIA_COLD_FIELD_BYTES)
#undef THEIA_COLD_FIELD_BYTES
    return bytes;
  }
};

}  // namespace theia
