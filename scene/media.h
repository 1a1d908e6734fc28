// Participating media: the coefficients at a point, and the null-scattering
// estimators along a ray segment (delta tracking for free flight, ratio
// tracking for transmittance) against one majorant per medium.
//
// Coefficients are RGB; the majorant is one number, the largest extinction
// of any channel, so every channel's null coefficient sigma_maj - sigma_t is
// >= 0.  Free flight picks absorption, scattering or a null collision with
// probabilities proportional to the throughput-weighted averages over the
// channels (spectral tracking, Kutz et al. 2017) and weights the throughput by
// each channel's coefficient over that probability, so a chromatic medium is
// sampled without bias and a grey one is plain delta tracking (weights 1).
#pragma once

#include "core/hash.h"
#include "scene/accel.h"
#include "scene/scene.h"

namespace theia {

struct MediumProps {
  RGB sigma_a{0.0f}, sigma_s{0.0f}, Le{0.0f};
};

// Density at a point of medium space: 1 for a homogeneous medium and an
// rgbgrid (whose coefficients are grids themselves), the grid's trilinear
// interpolation between voxel centres (pbrt-v4's SampledGrid::Lookup, zero
// outside) for a uniformgrid or nanovdb, pbrt-v4's procedural density for a
// cloud.
float medium_density(const Medium& m, const vec3& p_medium);
MediumProps medium_props(const Medium& m, const vec3& p_medium);
// Whether medium_props can give any Le (tracking gathers emission only then).
bool medium_is_emissive(const Medium& m);
// The majorant: the largest extinction of any channel anywhere in the medium.
float medium_majorant(const Medium& m);
// The majorant grid (Medium::majorants) of a grid or cloud medium: res^3
// cells over its box, each a bound on the density (an rgbgrid: on sigma_t)
// anywhere inside it, so that tracking's cost follows the local density.
// res is kMajorantGridRes (pbrt-v4's 16) for a cloud and for a grid of 61 or
// more voxels along its longest axis, a cell per 4 of them below that
// (media.cpp majorant_res; the grid holds res^3 values).  Also sets max_density.
inline constexpr int kMajorantGridRes = 16;
void build_majorant_grid(Medium& m);

// pbrt-v4's CloudMedium density at a point of medium space (in [0, 1]):
// kCloudOctaves of noise at "frequency", warped by the noise's gradient
// ("wispiness"), thinned with altitude (y) and solid below y = 0.5.
inline constexpr int kCloudOctaves = 5;
inline constexpr float kCloudNoiseSum = 2.0f * (1.0f - 1.0f / float(1 << kCloudOctaves));  // bounds |sum|
float cloud_density(const Medium& m, const vec3& p_medium);

// A grid's blackbody emission at a temperature (before offset and scale),
// from Medium::blackbody_table: pbrt-v4's BlackbodySpectrum (peak 1) for
// (T - temperatureoffset) * temperaturescale, none at or below kMinEmittingKelvin.
inline constexpr float kMinEmittingKelvin = 100.0f;
RGB blackbody_emission(const Medium& m, float kelvin);
// Fills Medium::blackbody_table (kBlackbodyTableSize entries, lerped) up to
// the hottest temperature the grid can give; empty when nothing emits.
inline constexpr int kBlackbodyTableSize = 512;
void build_blackbody_table(Medium& m);

// A stream of uniform numbers: a pure function of (key, index), so a path's
// tracking draws the same numbers on every thread count and batch order.
// `first`, when in [0, 1), is the first number drawn: a path's stratified
// sample dimension for its first free-flight distance, as pbrt-v4 takes it.
struct TrackingRng {
  uint64_t key = 0;
  float first = -1.0f;
  uint32_t index = 0;
  float next() {
    if (first >= 0.0f) {
      const float u = first;
      first = -1.0f;
      return u;
    }
    return to_unit_float(uint32_t(hash(key, index++)));
  }
};

// The part of ray parameter [t0, t1] (render space, `ray.d` of any length)
// inside the medium, in medium-space distances along a unit direction
// (pbrt-v4 measures a grid's distances in its own space).
struct MediumSegment {
  vec3 o{0.0f}, d{0.0f};  // medium space, |d| = 1
  float s0 = 0.0f, s1 = 0.0f;
  float t_per_s = 1.0f;   // render-space ray parameter per medium-space distance
  bool empty() const { return !(s1 > s0); }
};
MediumSegment medium_segment(const Medium& m, const Ray& ray, float t0, float t1);

enum class MediumEvent : uint8_t { None, Scatter, Absorb };
struct FreeFlight {
  MediumEvent event = MediumEvent::None;
  float t = 0.0f;     // ray parameter of the event
  RGB beta{1.0f};     // throughput after the segment (or at the scattering point)
  RGB emitted{0.0f};  // medium emission gathered along the way, times the throughput
};

// Delta (spectral) tracking over ray parameter [0, tmax] starting with
// throughput `beta`.  Emission is gathered at every tentative collision
// (beta sigma_a Le / sigma_maj), as pbrt-v4 does.
FreeFlight sample_free_flight(const Medium& m, const Ray& ray, float tmax, const RGB& beta, TrackingRng& rng);

// Ratio tracking over ray parameter [0, tmax]: an unbiased estimate of each
// channel's transmittance, with Russian roulette once it falls below 1/4.
RGB ratio_tracking(const Medium& m, const Ray& ray, float tmax, TrackingRng& rng);

// Per medium: 1 where no shadow ray that starts in it can reach a light, so
// that next-event estimation from its vertices would only trace rays that are
// blocked.  Decided from the scene alone, conservatively: the camera is not
// in the medium, and every shape whose sides differ and name it is a full
// sphere (no z or phi cut) at top level holding the medium inside (its normal
// outward), without alpha or emission, whose material blocks shadow rays (not
// "interface", not a mix), with every light (a point-like light's position,
// an area light's bounds) outside every such sphere by a margin.  A path
// enters such a medium only by crossing one of its spheres inwards and leaves
// it by crossing the sphere again, so its vertices lie inside the sphere and
// every segment from them to a light meets the sphere, which blocks it.
std::vector<uint8_t> sealed_media(const Scene& scene);

// pbrt-v4's rule at a surface: a shape whose sides differ sets the medium on
// the side `w` leaves towards (the outside along the geometric normal); any
// other surface keeps `current`.
inline int medium_after(const Scene& scene, int shape, const vec3& ng, const vec3& w, int current) {
  if (shape < 0) return current;
  const Shape& s = scene.shapes[size_t(shape)];
  if (!s.medium_transition()) return current;
  return glm::dot(w, ng) > 0.0f ? s.medium_outside : s.medium_inside;
}

}  // namespace theia
