// The path-state pool, declared once as a table of fields (as Cycles does):
// the table generates a structure of arrays, so each wavefront stage touches
// only the fields it reads, and adding a field is one line.
#pragma once

#include "core/math.h"

#include <cstdint>
#include <vector>

namespace theia {

//   type       name            meaning
#define THEIA_PATH_STATE_FIELDS(F)                                                           \
  F(uint32_t, pixel)          /* y * width + x */                                             \
  F(uint32_t, sample)         /* sample index within the pixel */                             \
  F(uint32_t, depth)          /* bounces so far: 0 for the camera ray */                      \
  F(RGB, beta)                /* path throughput */                                           \
  F(float, filter_weight)     /* filter-importance-sampling weight of the camera sample */    \
  F(float, prev_pdf)          /* solid-angle pdf of the BSDF sample that made the ray */      \
  F(uint8_t, prev_specular)   /* that sample came from a specular lobe */                     \
  F(vec3, prev_p)             /* the vertex the ray left (for light pdfs at emitter hits) */  \
  F(vec3, prev_ng)                                                                            \
  F(uint32_t, vertex)         /* the path observer's handle (kNoVertex without observer) */

struct PathStatePool {
#define THEIA_DECLARE_FIELD(type, name) std::vector<type> name;
  THEIA_PATH_STATE_FIELDS(THEIA_DECLARE_FIELD)
#undef THEIA_DECLARE_FIELD

  std::vector<uint32_t> free_slots;  // stack of unused slots

  explicit PathStatePool(size_t capacity) {
#define THEIA_RESIZE_FIELD(type, name) name.resize(capacity);
    THEIA_PATH_STATE_FIELDS(THEIA_RESIZE_FIELD)
#undef THEIA_RESIZE_FIELD
    free_slots.resize(capacity);
    // Hand out low slots first so a small render touches little memory.
    for (size_t i = 0; i < capacity; ++i) free_slots[i] = uint32_t(capacity - 1 - i);
  }

  size_t capacity() const { return pixel.size(); }
  size_t live() const { return capacity() - free_slots.size(); }

  static constexpr size_t bytes_per_path() {
    size_t b = 0;
#define THEIA_FIELD_BYTES(type, name) b += sizeof(type);
    THEIA_PATH_STATE_FIELDS(THEIA_FIELD_BYTES)
#undef THEIA_FIELD_BYTES
    return b + sizeof(uint32_t);
  }
  size_t memory_bytes() const { return capacity() * bytes_per_path(); }
};

}  // namespace theia
