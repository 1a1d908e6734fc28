// Path events, for whoever wants to know what happened along a path after the
// wavefront has forgotten it (the radiance recorder).
//
// A path carries one opaque 32-bit handle, the observer's name for the path's
// current vertex; shadow rays carry their own.  The engine never interprets
// handles.  With no observer attached the engine's shading code is compiled
// without any of these calls (see wavefront/engine.cpp), so it costs nothing.
#pragma once

#include "core/math.h"

#include <cstdint>

namespace theia {

inline constexpr uint32_t kNoVertex = 0xffffffffu;

struct PathVertexInfo {
  vec3 p{0.0f};
  vec3 n{0.0f};          // shading normal
  vec3 wi{0.0f};         // direction of the ray leaving the vertex
  RGB throughput{0.0f};  // path throughput up to (and including) the scattering at this vertex
  float pdf = 0.0f;      // solid-angle pdf of wi (light-sampling pdf for NEE rays)
  uint32_t pixel = 0;
  uint32_t sample = 0;
  int depth = 0;
  uint8_t lobe_flags = 0;
  float roughness = 1.0f;
  bool is_nee = false;
};

class PathObserver {
 public:
  virtual ~PathObserver() = default;
  // A camera ray leaves the camera.  Returns the handle the path carries.
  virtual uint32_t path_started(uint32_t pixel, uint32_t sample) = 0;
  // A ray is scattered (or an NEE ray sent) from a surface vertex, child of `parent`.
  virtual uint32_t vertex_created(uint32_t parent, const PathVertexInfo& v) = 0;
  // Radiance (already MIS-weighted, in units of radiance arriving at `vertex`) was found.
  virtual void emission_added(uint32_t vertex, const RGB& L) = 0;
  // The ray of `vertex` went on past something that does not end it (a virtual light).
  virtual void vertex_continued(uint32_t vertex) = 0;
  // Nothing more will arrive at `vertex` from its own ray.
  virtual void vertex_done(uint32_t vertex) = 0;
};

}  // namespace theia
