// Pixel reconstruction filters, applied by filter importance sampling as
// pbrt-v4 does: each camera sample's film offset is drawn from the filter and
// the sample carries a weight; the film divides sum(w L) by sum(w), so no
// sample touches a neighbouring pixel.  Mitchell and Lanczos have negative
// lobes: their samples carry negative weights there, which the film sums as
// they are (wavefront/film.h).
#pragma once

#include "core/distribution2d.h"
#include "core/equal_mass.h"
#include "core/math.h"
#include "scene/scene.h"

#include <span>

namespace theia {

struct FilterSample {
  vec2 p;        // offset from the pixel centre, in pixels, within the radius
  float weight;  // f(p) / pdf(p) up to a constant factor (see sample_filter); < 0 in negative lobes
};

struct Filter {
  FilterKind kind = FilterKind::Gaussian;
  vec2 radius{1.5f};
  float sigma = 0.5f;
  vec2 gaussian_offset{0.0f};  // g(radius) per axis, subtracted so f reaches 0 at the radius
  float gaussian_scale = 0.0f, gaussian_falloff = 0.0f;  // g(x) = scale exp(-x^2 falloff)
  float b = 1.0f / 3.0f, c = 1.0f / 3.0f;  // Mitchell
  float tau = 3.0f;                        // Lanczos
  float integral = 0.0f;                   // of f over its support
  Distribution2D distribution; // Mitchell, Lanczos: |f| over [-radius, radius]
  ivec2 table_size{0};
  // Gaussian: f is separable and positive, so each axis is sampled on its own
  // from the quantiles of its factor, in constant time instead of a 2D
  // table's two searches (every camera sample pays for them).
  EqualMass1D gaussian_axis[2];
};

inline constexpr float kMaxFilterRadius = 32.0f;  // pixels
// Per axis of the Gaussian; its quantiles come from a table of kGaussianCells.
inline constexpr int kGaussianSegments = 256, kGaussianCells = 4096;

// Throws Error for a radius that is not in (0, kMaxFilterRadius], a
// non-positive or non-finite sigma or tau, or a non-finite B or C.
Filter make_filter(const FilterParams& params);

// Box: uniform, weight 1.  Triangle: separable tent, weight 1.  Both are exact
// importance sampling of f / integral(f).  Gaussian: per axis, from
// kGaussianSegments equal-probability segments of its factor, linear within
// each (EqualMass1D);
// the weight is f(p) / pdf(p) at p itself, which keeps E[weight * g(p)]
// equal to the integral of f * g exactly.  Mitchell, Lanczos: pbrt-v4's
// FilterSampler, sampled from the tabulated |f| at 32 cells per unit radius.  Mitchell and
// Lanczos: pbrt-v4's weight, the cell's tabulated f over the pdf, which is
// +-integral(|table|) in every cell: a pixel's weights sum to a multiple of
// it, exactly 0 when they cancel (the film leaves that pixel black, as
// pbrt-v4), never to a sliver that would blow sum(w L) / sum(w) up.  The
// price is the table's midpoint-rule bias, second order in the cell size.
FilterSample sample_filter(const Filter& filter, vec2 u);
// out[i] = sample_filter(filter, u[i]) for every i, bit for bit (the camera
// stage draws a run of samples at once): the Gaussian's arithmetic runs
// several samples at a time in vector lanes, its exponentials one by one.
void sample_filter(const Filter& filter, std::span<const vec2> u, std::span<FilterSample> out);
// Density of sample_filter()'s offsets.
float filter_pdf(const Filter& filter, vec2 p);
float filter_eval(const Filter& filter, vec2 p);
// Integral of filter_eval over its support (Lanczos: by quadrature, where
// pbrt-v4 takes a 64x64 jittered estimate).
inline float filter_integral(const Filter& filter) { return filter.integral; }
inline vec2 filter_radius(const Filter& filter) { return filter.radius; }
// Whether sample_filter draws from the tabulated |f| (weights vary, and may be negative).
inline bool filter_is_tabulated(const Filter& filter) {
  return filter.kind != FilterKind::Box && filter.kind != FilterKind::Triangle;
}

}  // namespace theia
