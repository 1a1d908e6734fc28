#include "scene/filter.h"

#include "core/log.h"
#include "core/sampling.h"

#include <array>
#include <vector>

namespace theia {

namespace {

// The unit-area Gaussian of sigma as scale exp(-x^2 falloff): every camera
// sample's weight evaluates it twice (sample_gaussian), with the filter's
// two constants made once (the division and square root they replace were
// a fifth of the sample).
float gaussian_scale(float sigma) { return 1.0f / std::sqrt(2.0f * kPi * sigma * sigma); }
float gaussian_falloff(float sigma) { return 1.0f / (2.0f * sigma * sigma); }
float gaussian(float x, float scale, float falloff) { return scale * std::exp(-x * x * falloff); }
float gaussian(float x, float sigma) { return gaussian(x, gaussian_scale(sigma), gaussian_falloff(sigma)); }

// Integral of the unit-area Gaussian over [-r, r].
float gaussian_integral(float r, float sigma) { return std::erf(r / (sigma * std::sqrt(2.0f))); }

float gaussian_1d(float x, float sigma, float offset) { return std::max(0.0f, gaussian(x, sigma) - offset); }

// Samples Gaussian filters, a block at a time (sample_filter).  The
// exponents, and then the weights, are loops that vectorize; the
// exponentials between them are libm's, one by one.  The weight's x factor
// fuses its product and offset and the y factor does not: what GCC chose
// for the one-sample code this replaced, kept so that images stay the same
// bit for bit, and written out (mul_add; a product stored by one loop and
// offset by the next) so that no compiler's contraction changes it.
[[gnu::noinline]] void sample_gaussian(const Filter& f, std::span<const vec2> u, std::span<FilterSample> out) {
  constexpr size_t kBlock = 64;
  for (size_t first = 0; first < u.size(); first += kBlock) {
    const size_t m = std::min(kBlock, u.size() - first);
    std::array<float, kBlock> ux, uy, x, y, inv_pdf_x, inv_pdf_y, gx, gy;
    for (size_t i = 0; i < m; ++i) ux[i] = u[first + i].x, uy[i] = u[first + i].y;
    f.gaussian_axis[0].sample({ux.data(), m}, {x.data(), m}, {inv_pdf_x.data(), m});
    f.gaussian_axis[1].sample({uy.data(), m}, {y.data(), m}, {inv_pdf_y.data(), m});
    for (size_t i = 0; i < m; ++i) gx[i] = -x[i] * x[i] * f.gaussian_falloff, gy[i] = -y[i] * y[i] * f.gaussian_falloff;
    for (size_t i = 0; i < m; ++i) gx[i] = std::exp(gx[i]), gy[i] = f.gaussian_scale * std::exp(gy[i]);
    for (size_t i = 0; i < m; ++i) {
      const float fx = std::max(0.0f, mul_add(f.gaussian_scale, gx[i], -f.gaussian_offset.x));
      const float fy = std::max(0.0f, gy[i] - f.gaussian_offset.y);
      out[first + i] = {{x[i], y[i]}, fx * fy * inv_pdf_x[i] * inv_pdf_y[i]};
    }
  }
}

float gaussian_eval(const Filter& f, vec2 p) {
  const float gx = gaussian(p.x, f.gaussian_scale, f.gaussian_falloff);
  const float gy = gaussian(p.y, f.gaussian_scale, f.gaussian_falloff);
  return std::max(0.0f, gx - f.gaussian_offset.x) * std::max(0.0f, gy - f.gaussian_offset.y);
}

// The equal-probability segments of one axis's factor over [-r, r].
EqualMass1D gaussian_axis(float r, float sigma, float offset) {
  std::vector<float> table(kGaussianCells);
  for (int i = 0; i < kGaussianCells; ++i)
    table[size_t(i)] = gaussian_1d((2.0f * (float(i) + 0.5f) / float(kGaussianCells) - 1.0f) * r, sigma, offset);
  return EqualMass1D(Distribution1D(table), kGaussianSegments, -r, r,
                     [&](float x) { return gaussian_1d(x, sigma, offset); });
}

// Mitchell-Netravali over [-2, 2]; integrates to 1 for every B and C.
float mitchell_1d(float x, float b, float c) {
  x = std::abs(x);
  if (x <= 1.0f)
    return ((12.0f - 9.0f * b - 6.0f * c) * x * x * x + (-18.0f + 12.0f * b + 6.0f * c) * x * x + (6.0f - 2.0f * b)) *
           (1.0f / 6.0f);
  if (x <= 2.0f)
    return ((-b - 6.0f * c) * x * x * x + (6.0f * b + 30.0f * c) * x * x + (-12.0f * b - 48.0f * c) * x +
            (8.0f * b + 24.0f * c)) *
           (1.0f / 6.0f);
  return 0.0f;
}

template <typename T>
T sinc(T x) {
  T px = T(kPi) * x;
  // sin(x)/x rounds to 1 wherever 1 - x^2/6 does.
  return T(1) + px * px == T(1) ? T(1) : std::sin(px) / px;
}

float windowed_sinc(float x, float radius, float tau) {
  return std::abs(x) > radius ? 0.0f : sinc(x) * sinc(x / tau);
}

// Composite Simpson of the windowed sinc over [-r, r]; the function is
// smooth inside, so 4096 intervals leave only float rounding.
float windowed_sinc_integral(float r, float tau) {
  const int n = 4096;
  double h = 2.0 * r / n, sum = 0.0;
  for (int i = 0; i <= n; ++i) {
    double x = -double(r) + i * h;
    double w = (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0);
    sum += w * sinc(x) * sinc(x / double(tau));
  }
  return float(sum * h / 3.0);
}

bool inside(const Filter& f, vec2 p) { return std::abs(p.x) <= f.radius.x && std::abs(p.y) <= f.radius.y; }

float tabulated_eval(const Filter& f, vec2 p) {
  switch (f.kind) {
    case FilterKind::Gaussian: return gaussian_eval(f, p);
    case FilterKind::Mitchell:
      return mitchell_1d(2.0f * p.x / f.radius.x, f.b, f.c) * mitchell_1d(2.0f * p.y / f.radius.y, f.b, f.c);
    case FilterKind::Lanczos: return windowed_sinc(p.x, f.radius.x, f.tau) * windowed_sinc(p.y, f.radius.y, f.tau);
    default: return 0.0f;
  }
}

}  // namespace

Filter make_filter(const FilterParams& params) {
  Filter f;
  f.kind = params.kind;
  f.radius = params.radius;
  f.sigma = params.sigma;
  f.b = params.b;
  f.c = params.c;
  f.tau = params.tau;
  // Mitchell's and Lanczos' sampling table holds (32 radius)^2 cells: a radius of 1e30 would ask for all memory.
  if (!(f.radius.x > 0.0f && f.radius.y > 0.0f && f.radius.x <= kMaxFilterRadius && f.radius.y <= kMaxFilterRadius))
    throw_error("filter: \"radius\" must be positive and at most {} pixels, got ({}, {})", kMaxFilterRadius,
                f.radius.x, f.radius.y);
  switch (f.kind) {
    case FilterKind::Box: f.integral = 4.0f * f.radius.x * f.radius.y; return f;
    case FilterKind::Triangle: f.integral = sqr(f.radius.x) * sqr(f.radius.y); return f;
    case FilterKind::Gaussian:
      if (!(f.sigma > 0.0f && std::isfinite(f.sigma)))
        throw_error("gaussian filter: \"sigma\" must be positive and finite, got {}", f.sigma);
      f.gaussian_scale = gaussian_scale(f.sigma);
      f.gaussian_falloff = gaussian_falloff(f.sigma);
      f.gaussian_offset = {gaussian(f.radius.x, f.sigma), gaussian(f.radius.y, f.sigma)};
      f.integral = (gaussian_integral(f.radius.x, f.sigma) - 2.0f * f.radius.x * f.gaussian_offset.x) *
                   (gaussian_integral(f.radius.y, f.sigma) - 2.0f * f.radius.y * f.gaussian_offset.y);
      for (int a = 0; a < 2; ++a) f.gaussian_axis[a] = gaussian_axis(f.radius[a], f.sigma, f.gaussian_offset[a]);
      return f;
    case FilterKind::Mitchell:
      if (!(std::isfinite(f.b) && std::isfinite(f.c)))
        throw_error("mitchell filter: \"B\" and \"C\" must be finite, got {} and {}", f.b, f.c);
      f.integral = f.radius.x * f.radius.y / 4.0f;
      break;
    case FilterKind::Lanczos:
      if (!(f.tau > 0.0f && std::isfinite(f.tau)))
        throw_error("sinc filter: \"tau\" must be positive and finite, got {}", f.tau);
      f.integral = windowed_sinc_integral(f.radius.x, f.tau) * windowed_sinc_integral(f.radius.y, f.tau);
      break;
  }

  // pbrt-v4's FilterSampler: |f| sampled at cell centres, 32 cells per unit radius.
  int nx = std::max(1, int(32.0f * f.radius.x)), ny = std::max(1, int(32.0f * f.radius.y));
  std::vector<float> table(size_t(nx) * size_t(ny));
  for (int y = 0; y < ny; ++y)
    for (int x = 0; x < nx; ++x) {
      vec2 t((float(x) + 0.5f) / float(nx), (float(y) + 0.5f) / float(ny));
      table[size_t(y) * size_t(nx) + size_t(x)] = std::abs(tabulated_eval(f, (2.0f * t - 1.0f) * f.radius));
    }
  f.distribution = Distribution2D(table, nx, ny);
  f.table_size = ivec2(nx, ny);
  return f;
}

float filter_eval(const Filter& f, vec2 p) {
  if (!inside(f, p)) return 0.0f;
  switch (f.kind) {
    case FilterKind::Box: return 1.0f;
    case FilterKind::Triangle: return (f.radius.x - std::abs(p.x)) * (f.radius.y - std::abs(p.y));
    default: return tabulated_eval(f, p);
  }
}

FilterSample sample_filter(const Filter& f, vec2 u) {
  switch (f.kind) {
    case FilterKind::Box: return {(2.0f * u - 1.0f) * f.radius, 1.0f};
    case FilterKind::Triangle: return {{sample_tent(u.x, f.radius.x), sample_tent(u.y, f.radius.y)}, 1.0f};
    case FilterKind::Gaussian: {
      FilterSample s;
      sample_gaussian(f, {&u, 1}, {&s, 1});
      return s;
    }
    default: {
      float pdf = 0.0f;
      ivec2 cell(0);
      vec2 t = f.distribution.sample_continuous(u, &pdf, &cell);
      vec2 p = glm::clamp((2.0f * t - 1.0f) * f.radius, -f.radius, f.radius);
      // The table's density over [0,1)^2 becomes a density over the filter's extent.
      pdf /= 4.0f * f.radius.x * f.radius.y;
      if (!(pdf > 0.0f)) return {p, 0.0f};
      // pbrt-v4's f[cell] / pdf is +-integral(|table|) up to rounding; taken
      // exactly, so that opposite weights cancel to exactly 0.
      vec2 centre = ((vec2(cell) + 0.5f) / vec2(f.table_size) * 2.0f - 1.0f) * f.radius;
      return {p, std::copysign(f.distribution.integral() * 4.0f * f.radius.x * f.radius.y, tabulated_eval(f, centre))};
    }
  }
}

void sample_filter(const Filter& f, std::span<const vec2> u, std::span<FilterSample> out) {
  if (f.kind == FilterKind::Gaussian) return sample_gaussian(f, u, out);
  for (size_t i = 0; i < u.size(); ++i) out[i] = sample_filter(f, u[i]);
}

float filter_pdf(const Filter& f, vec2 p) {
  if (!inside(f, p)) return 0.0f;
  switch (f.kind) {
    case FilterKind::Box: return 1.0f / (4.0f * f.radius.x * f.radius.y);
    case FilterKind::Triangle: return tent_pdf(p.x, f.radius.x) * tent_pdf(p.y, f.radius.y);
    case FilterKind::Gaussian: return f.gaussian_axis[0].pdf(p.x) * f.gaussian_axis[1].pdf(p.y);
    default: return f.distribution.pdf((p / f.radius + 1.0f) * 0.5f) / (4.0f * f.radius.x * f.radius.y);
  }
}

}  // namespace theia
