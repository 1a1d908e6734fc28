// Pixel reconstruction filters, applied by filter importance sampling as
// pbrt-v4 does: each camera sample's film offset is drawn from the filter and
// the sample carries a weight; the film divides sum(w L) by sum(w), so no
// sample touches a neighbouring pixel.
#pragma once

#include "core/distribution2d.h"
#include "core/math.h"
#include "scene/scene.h"

namespace theia {

struct FilterSample {
  vec2 p;        // offset from the pixel centre, in pixels, within the radius
  float weight;  // f(p) / pdf(p) up to a constant factor (see sample_filter)
};

struct Filter {
  FilterKind kind = FilterKind::Gaussian;
  vec2 radius{1.5f};
  float sigma = 0.5f;
  vec2 gaussian_offset{0.0f};  // g(radius) per axis, subtracted so f reaches 0 at the radius
  Distribution2D distribution; // Gaussian only: |f| tabulated over [-radius, radius]
};

// Throws Error for a non-positive or non-finite radius or sigma.
Filter make_filter(const FilterParams& params);

// Box: uniform, weight 1.  Triangle: separable tent, weight 1.  Both are exact
// importance sampling of f / integral(f).  Gaussian: pbrt-v4's FilterSampler,
// sampled from the tabulated |f| at 32 cells per unit radius; the weight is
// f(p) / pdf(p) evaluated at p itself (pbrt-v4 uses the tabulated cell value),
// which keeps E[weight * g(p)] equal to the integral of f * g exactly.
FilterSample sample_filter(const Filter& filter, vec2 u);
// Density of sample_filter()'s offsets.
float filter_pdf(const Filter& filter, vec2 p);
float filter_eval(const Filter& filter, vec2 p);
// Integral of filter_eval over its support.
float filter_integral(const Filter& filter);
inline vec2 filter_radius(const Filter& filter) { return filter.radius; }

}  // namespace theia
