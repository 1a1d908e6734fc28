// Piecewise-constant 2D distribution over [0, 1)^2 (pbrt-v4's
// PiecewiseConstant2D): a marginal over rows and one conditional per row.
// Used by the Gaussian pixel filter and by environment-map lights.
#pragma once

#include "core/math.h"
#include "core/sampling.h"

#include <span>
#include <vector>

namespace theia {

struct Distribution2D {
  int nu = 0, nv = 0;                       // columns (x), rows (y)
  std::vector<Distribution1D> conditional;  // one per row, over x
  Distribution1D marginal;                  // over rows, weighted by each row's integral

  Distribution2D() = default;
  // f holds nu * nv non-negative weights, row-major: f[y * nu + x].  Negative
  // and non-finite entries count as their absolute value / zero, as in
  // Distribution1D; all-zero input samples uniformly.
  Distribution2D(std::span<const float> f, int nu, int nv);

  // Integral of the tabulated function over [0, 1)^2.
  float integral() const { return marginal.integral; }
  // Returns p in [0, 1)^2 with density *pdf; `cell` receives (column, row).
  vec2 sample_continuous(vec2 u, float* pdf, ivec2* cell = nullptr) const;
  // Density of sample_continuous() at p (p outside [0, 1)^2 is clamped to the border cells).
  float pdf(vec2 p) const;
};

}  // namespace theia
