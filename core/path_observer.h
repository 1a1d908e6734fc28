// Path events, for whoever wants to know what happened along a path after the
// wavefront has forgotten it (the radiance recorder).
//
// The interface lives in core/ (not wavefront/) so that the recorder, which
// may use only core, implements it without depending on the engine; the
// engine calls it.  A path carries one opaque 32-bit handle, the observer's
// name for the path's current vertex; shadow rays carry their own.  The engine
// never interprets handles.  With no observer attached the engine's shading
// code is compiled without any of these calls, so it costs nothing.
//
// Units: every emission is reported as the engine's film contribution
// (camera weight x path throughput x MIS weight x Le), so that an observer can
// add it to any vertex of the path and divide by that vertex's throughput.
#pragma once

#include "core/math.h"

#include <cstdint>

namespace theia {

inline constexpr uint32_t kNoVertex = 0xffffffffu;

struct PathVertexInfo {
  vec3 p{0.0f};
  vec3 n{0.0f};          // shading normal
  vec3 wi{0.0f};         // direction of the ray leaving the vertex
  // Throughput from the camera up to the hit (camera sample weight included),
  // before the scattering at this vertex; the vertex's path throughput is
  // prefix * local (its product is kept in double by the recorder).
  RGB prefix{0.0f};
  // The scattering's own factor: f |cos| / pdf (with the Russian-roulette
  // compensation) for a BSDF sample, f |cos| / light pdf for an NEE ray.
  RGB local{0.0f};
  // Density of wi being reported: the solid-angle sampling pdf times the
  // Russian-roulette survival probability (light-sampling pdf for NEE rays).
  float pdf = 0.0f;
  float camera_weight = 1.0f;  // the camera sample's filter weight (part of prefix)
  uint32_t pixel = 0;
  uint32_t sample = 0;
  int depth = 0;         // which hit the vertex leaves from: 0 = the primary hit
  uint8_t lobe_flags = 0;  // scene/bsdf.h LobeFlags of the sampled lobe (0 for NEE)
  float roughness = 1.0f;
  bool is_nee = false;
  bool delta_light = false;  // an NEE ray to a point-like light: its direction has no density
  bool in_medium = false;
  // The engine guides directions at this BSDF (bsdf_is_guidable); a sample
  // from one it never guides trains nothing, so the recorder does not make one.
  bool guidable = true;
  // A direction drawn from a one-sample-MIS mixture of guide and BSDF: the
  // BSDF's and the guide's densities of wi over the mixture's (0 otherwise).
  // The guide learns its selection probability from them.
  float bsdf_ratio = 0.0f, guide_ratio = 0.0f;
};

class PathObserver {
 public:
  virtual ~PathObserver() = default;
  // A camera ray leaves the camera.  Returns the handle the path carries.
  virtual uint32_t path_started(uint32_t pixel, uint32_t sample) = 0;
  // A ray is scattered (or an NEE ray sent) from a surface vertex, child of `parent`.
  virtual uint32_t vertex_created(uint32_t parent, const PathVertexInfo& v) = 0;
  // The ray of `vertex` found emission: `contribution` is what the engine
  // splatted to the film for it, `mis_weight` the MIS weight it includes.
  // `pixel` names the film pixel (the handle may name the camera).
  virtual void emission_added(uint32_t vertex, uint32_t pixel, const RGB& contribution, float mis_weight) = 0;
  // The ray of `vertex` went on past something that does not end it (a virtual light).
  virtual void vertex_continued(uint32_t vertex) = 0;
  // Nothing more will arrive at `vertex` from its own ray (one per created or
  // continued vertex).
  virtual void vertex_done(uint32_t vertex) = 0;
  // A hint, no event: events for `vertex` come in a moment.  The engine's
  // loops call it a few items ahead, since they visit vertices in hit order,
  // not in the order the observer stored them, and each visit would otherwise
  // wait for memory.
  virtual void prefetch(uint32_t /*vertex*/) const {}
};

}  // namespace theia
