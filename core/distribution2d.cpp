#include "core/distribution2d.h"

#include "core/log.h"

namespace theia {

Distribution2D::Distribution2D(std::span<const float> f, int nu_, int nv_) : nu(nu_), nv(nv_) {
  if (nu <= 0 || nv <= 0 || f.size() != size_t(nu) * size_t(nv))
    throw_error("Distribution2D: {} values given for a {}x{} table", f.size(), nu, nv);
  conditional.reserve(size_t(nv));
  std::vector<float> row_integrals(static_cast<size_t>(nv));
  for (int v = 0; v < nv; ++v) {
    conditional.emplace_back(f.subspan(size_t(v) * size_t(nu), size_t(nu)));
    row_integrals[size_t(v)] = conditional.back().integral;
  }
  marginal = Distribution1D(row_integrals);
}

vec2 Distribution2D::sample_continuous(vec2 u, float* pdf_out, ivec2* cell) const {
  float pdf_v = 0.0f, pdf_u = 0.0f;
  int row = 0, col = 0;
  float y = marginal.sample_continuous(u.y, &pdf_v, &row);
  float x = conditional[size_t(row)].sample_continuous(u.x, &pdf_u, &col);
  if (pdf_out) *pdf_out = pdf_u * pdf_v;
  if (cell) *cell = ivec2(col, row);
  return {x, y};
}

float Distribution2D::pdf(vec2 p) const {
  int col = std::clamp(int(p.x * float(nu)), 0, nu - 1);
  int row = std::clamp(int(p.y * float(nv)), 0, nv - 1);
  // An all-zero table samples uniformly (see Distribution1D), so its density is 1.
  if (marginal.integral == 0.0f) return 1.0f;
  return conditional[size_t(row)].func[size_t(col)] / marginal.integral;
}

}  // namespace theia
