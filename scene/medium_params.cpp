#include "scene/medium_params.h"

#include "core/color.h"
#include "scene/media.h"

#include <algorithm>
#include <cmath>

namespace theia {

namespace {

using SpectrumUse = ParamList::SpectrumUse;

// A coefficient (default 1, as in pbrt-v4) in the working space.  Grey
// stays exactly grey (the matrix would leave it off by an ulp, and the
// tracking would then see a chromatic medium).
RGB coefficient(const ParamList& params, std::string_view name) {
  const RGB c = params.get_spectrum_srgb(name, SpectrumUse::Reflectance, RGB(1.0f)).value_or(RGB(1.0f));
  return c.x == c.y && c.y == c.z ? c : srgb_to_working(c);
}

// The coefficients every type shares: sigma_a and sigma_s (default 1, as in
// pbrt-v4) times "scale", g in (-1, 1), Le times "Lescale".
void read_coefficients(const ParamList& params, const SourceLoc& loc, Medium& m) {
  if (const Param* p = params.find("preset", ParamType::String))
    throw_at(p->loc, "medium preset \"{}\" is not supported yet, expected \"sigma_a\" and \"sigma_s\"", p->strings[0]);
  // Coefficients convert to the working space as colours do (linearly): then
  // 1 - sigma t, the first order of every channel's transmittance, is the
  // colour pbrt-v4's spectral transmittance gives.
  m.sigma_a = coefficient(params, "sigma_a");
  m.sigma_s = coefficient(params, "sigma_s");
  const float scale = params.get_float("scale", 1.0f);
  if (!(scale >= 0.0f)) throw_at(params.find("scale", ParamType::Float)->loc, "\"float scale\" is {}, expected >= 0", scale);
  m.sigma_a *= scale;
  m.sigma_s *= scale;
  if (!(glm::all(glm::greaterThanEqual(m.sigma_a, RGB(0.0f))) && glm::all(glm::greaterThanEqual(m.sigma_s, RGB(0.0f)))))
    throw_at(loc, "medium \"{}\" has a negative sigma_a or sigma_s, expected >= 0", m.name);
  m.g = params.get_float("g", 0.0f);
  if (!(std::abs(m.g) < 1.0f)) throw_at(params.find("g", ParamType::Float)->loc, "\"float g\" is {}, expected -1 < g < 1", m.g);
  m.Le = params.get_spectrum("Le", SpectrumUse::Illuminant, RGB(0.0f)).value_or(RGB(0.0f));
}

void read_grid(const ParamList& params, const SourceLoc& loc, Medium& m) {
  std::span<const double> density = params.get_floats("density");
  if (density.empty()) throw_at(loc, "uniformgrid medium \"{}\" without \"float density\", expected nx*ny*nz values", m.name);
  if (params.find("temperature", ParamType::Float))
    throw_at(loc, "uniformgrid \"temperature\" is not supported yet, expected \"Le\" for emission");
  m.nx = params.get_int("nx", 1);
  m.ny = params.get_int("ny", 1);
  m.nz = params.get_int("nz", 1);
  if (m.nx < 1 || m.ny < 1 || m.nz < 1)
    throw_at(loc, "uniformgrid resolution {} x {} x {}, expected nx, ny, nz >= 1", m.nx, m.ny, m.nz);
  const uint64_t n = uint64_t(m.nx) * uint64_t(m.ny) * uint64_t(m.nz);
  if (density.size() != n)
    throw_at(params.find("density", ParamType::Float)->loc, "uniformgrid has {} density values, expected nx*ny*nz = {}",
             density.size(), n);
  m.density.resize(n);
  for (size_t i = 0; i < n; ++i) {
    // A negative density would be negative extinction (energy from nowhere).
    if (!(density[i] >= 0.0))
      throw_at(params.find("density", ParamType::Float)->loc, "density value {} is {}, expected >= 0", i, density[i]);
    m.density[i] = float(density[i]);
  }
  m.max_density = *std::max_element(m.density.begin(), m.density.end());
  build_majorant_grid(m);
  std::span<const double> le_scale = params.get_floats("Lescale");
  if (le_scale.size() > 1) throw_at(loc, "a \"Lescale\" grid is not supported yet, expected one value");
  m.p0 = params.get_point3("p0", vec3(0.0f));
  m.p1 = params.get_point3("p1", vec3(1.0f));
  if (!(m.p0.x < m.p1.x && m.p0.y < m.p1.y && m.p0.z < m.p1.z))
    throw_at(loc, "uniformgrid bounds p0 ({}, {}, {}) - p1 ({}, {}, {}), expected p0 < p1 on every axis", m.p0.x, m.p0.y,
             m.p0.z, m.p1.x, m.p1.y, m.p1.z);
}

}  // namespace

Medium read_medium(const std::string& name, const std::string& type, const ParamList& params, const SourceLoc& loc,
                   const Transform& render_from_medium) {
  Medium m;
  m.name = name;
  m.loc = loc;
  m.render_from_medium = render_from_medium;
  if (type == "homogeneous") {
    m.kind = MediumKind::Homogeneous;
  } else if (type == "uniformgrid") {
    m.kind = MediumKind::UniformGrid;
    read_grid(params, loc, m);
  } else if (type == "rgbgrid" || type == "cloud" || type == "nanovdb") {
    throw_at(loc, "medium type \"{}\" is not supported yet, expected \"homogeneous\" or \"uniformgrid\"", type);
  } else {
    throw_at(loc, "unknown medium type \"{}\", expected \"homogeneous\" or \"uniformgrid\"", type);
  }
  read_coefficients(params, loc, m);
  m.Le *= params.get_float("Lescale", 1.0f);
  params.report_unused();
  return m;
}

}  // namespace theia
