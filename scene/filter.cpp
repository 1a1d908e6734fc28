#include "scene/filter.h"

#include "core/log.h"
#include "core/sampling.h"

#include <vector>

namespace theia {

namespace {

float gaussian(float x, float sigma) {
  return std::exp(-x * x / (2.0f * sigma * sigma)) / std::sqrt(2.0f * kPi * sigma * sigma);
}

// Integral of the unit-area Gaussian over [-r, r].
float gaussian_integral(float r, float sigma) { return std::erf(r / (sigma * std::sqrt(2.0f))); }

float gaussian_eval(const Filter& f, vec2 p) {
  return std::max(0.0f, gaussian(p.x, f.sigma) - f.gaussian_offset.x) *
         std::max(0.0f, gaussian(p.y, f.sigma) - f.gaussian_offset.y);
}

bool inside(const Filter& f, vec2 p) { return std::abs(p.x) <= f.radius.x && std::abs(p.y) <= f.radius.y; }

}  // namespace

Filter make_filter(const FilterParams& params) {
  Filter f;
  f.kind = params.kind;
  f.radius = params.radius;
  f.sigma = params.sigma;
  if (!(f.radius.x > 0.0f && f.radius.y > 0.0f && std::isfinite(f.radius.x) && std::isfinite(f.radius.y)))
    throw_error("filter: \"radius\" must be positive and finite, got ({}, {})", f.radius.x, f.radius.y);
  if (f.kind != FilterKind::Gaussian) return f;
  if (!(f.sigma > 0.0f && std::isfinite(f.sigma)))
    throw_error("gaussian filter: \"sigma\" must be positive and finite, got {}", f.sigma);
  f.gaussian_offset = {gaussian(f.radius.x, f.sigma), gaussian(f.radius.y, f.sigma)};

  // pbrt-v4's FilterSampler: f sampled at cell centres, 32 cells per unit radius.
  int nx = std::max(1, int(32.0f * f.radius.x)), ny = std::max(1, int(32.0f * f.radius.y));
  std::vector<float> table(size_t(nx) * size_t(ny));
  for (int y = 0; y < ny; ++y)
    for (int x = 0; x < nx; ++x) {
      vec2 t((float(x) + 0.5f) / float(nx), (float(y) + 0.5f) / float(ny));
      table[size_t(y) * size_t(nx) + size_t(x)] = std::abs(gaussian_eval(f, (2.0f * t - 1.0f) * f.radius));
    }
  f.distribution = Distribution2D(table, nx, ny);
  return f;
}

float filter_eval(const Filter& f, vec2 p) {
  switch (f.kind) {
    case FilterKind::Box: return inside(f, p) ? 1.0f : 0.0f;
    case FilterKind::Triangle:
      return std::max(0.0f, f.radius.x - std::abs(p.x)) * std::max(0.0f, f.radius.y - std::abs(p.y));
    case FilterKind::Gaussian: return inside(f, p) ? gaussian_eval(f, p) : 0.0f;
  }
  return 0.0f;
}

float filter_integral(const Filter& f) {
  switch (f.kind) {
    case FilterKind::Box: return 4.0f * f.radius.x * f.radius.y;
    case FilterKind::Triangle: return sqr(f.radius.x) * sqr(f.radius.y);
    case FilterKind::Gaussian:
      return (gaussian_integral(f.radius.x, f.sigma) - 2.0f * f.radius.x * f.gaussian_offset.x) *
             (gaussian_integral(f.radius.y, f.sigma) - 2.0f * f.radius.y * f.gaussian_offset.y);
  }
  return 0.0f;
}

FilterSample sample_filter(const Filter& f, vec2 u) {
  switch (f.kind) {
    case FilterKind::Box: return {(2.0f * u - 1.0f) * f.radius, 1.0f};
    case FilterKind::Triangle: return {{sample_tent(u.x, f.radius.x), sample_tent(u.y, f.radius.y)}, 1.0f};
    case FilterKind::Gaussian: {
      float pdf = 0.0f;
      vec2 t = f.distribution.sample_continuous(u, &pdf);
      vec2 p = (2.0f * t - 1.0f) * f.radius;
      // The table's density over [0,1)^2 becomes a density over the filter's extent.
      pdf /= 4.0f * f.radius.x * f.radius.y;
      return {p, pdf > 0.0f ? gaussian_eval(f, p) / pdf : 0.0f};
    }
  }
  return {vec2(0.0f), 0.0f};
}

float filter_pdf(const Filter& f, vec2 p) {
  if (!inside(f, p)) return 0.0f;
  switch (f.kind) {
    case FilterKind::Box: return 1.0f / (4.0f * f.radius.x * f.radius.y);
    case FilterKind::Triangle: return tent_pdf(p.x, f.radius.x) * tent_pdf(p.y, f.radius.y);
    case FilterKind::Gaussian:
      return f.distribution.pdf((p / f.radius + 1.0f) * 0.5f) / (4.0f * f.radius.x * f.radius.y);
  }
  return 0.0f;
}

}  // namespace theia
