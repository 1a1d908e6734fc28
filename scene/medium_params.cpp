#include "scene/medium_params.h"

#include "core/color.h"
#include "scene/media.h"
#include "scene/medium_presets.h"
#include "scene/vdb_medium.h"

#include <algorithm>
#include <cmath>

namespace theia {

namespace {

using SpectrumUse = ParamList::SpectrumUse;

// sRGB coefficients to the working space.  Grey stays exactly grey (the
// matrix would leave it off by an ulp, and the tracking would then see a
// chromatic medium).
RGB coefficient_to_working(const RGB& c) { return c.x == c.y && c.y == c.z ? c : srgb_to_working(c); }

// A coefficient (default 1, as in pbrt-v4) in the working space.
RGB coefficient(const ParamList& params, std::string_view name) {
  return coefficient_to_working(params.get_spectrum_srgb(name, SpectrumUse::Reflectance, RGB(1.0f)).value_or(RGB(1.0f)));
}

float non_negative(const ParamList& params, std::string_view name, float def) {
  const float v = params.get_float(name, def);
  if (!(v >= 0.0f)) throw_at(params.find(name, ParamType::Float)->loc, "\"float {}\" is {}, expected >= 0", name, v);
  return v;
}

// sigma_a and sigma_s: pbrt-v4's "preset" (a measured medium, mm^-1) when
// given, else the parameters (default 1); both times "scale" where the type
// reads it.  Coefficients convert to the working space as colours do
// (linearly): then 1 - sigma t, the first order of every channel's
// transmittance, is the colour pbrt-v4's spectral transmittance gives.
void read_sigma(const ParamList& params, const SourceLoc& loc, bool scaled, Medium& m) {
  if (const Param* p = params.find("preset", ParamType::String)) {
    const MediumPreset* preset = find_medium_preset(p->strings[0]);
    if (!preset) throw_at(p->loc, "unknown medium preset \"{}\", expected one of {}", p->strings[0], medium_preset_names());
    m.sigma_a = coefficient_to_working(preset->sigma_a);
    m.sigma_s = coefficient_to_working(preset->sigma_s);
  } else {
    m.sigma_a = coefficient(params, "sigma_a");
    m.sigma_s = coefficient(params, "sigma_s");
  }
  if (scaled) {
    const float scale = non_negative(params, "scale", 1.0f);
    m.sigma_a *= scale;
    m.sigma_s *= scale;
  }
  if (!(glm::all(glm::greaterThanEqual(m.sigma_a, RGB(0.0f))) && glm::all(glm::greaterThanEqual(m.sigma_s, RGB(0.0f)))))
    throw_at(loc, "medium \"{}\" has a negative sigma_a or sigma_s, expected >= 0", m.name);
}

void read_g(const ParamList& params, Medium& m) {
  m.g = params.get_float("g", 0.0f);
  if (!(std::abs(m.g) < 1.0f)) throw_at(params.find("g", ParamType::Float)->loc, "\"float g\" is {}, expected -1 < g < 1", m.g);
}

// "Le" (one colour) times "Lescale", for homogeneous and uniformgrid.
void read_Le(const ParamList& params, Medium& m) {
  m.Le = params.get_spectrum("Le", SpectrumUse::Illuminant, RGB(0.0f)).value_or(RGB(0.0f));
  m.Le_scale = non_negative(params, "Lescale", 1.0f);
  m.Le *= m.Le_scale;
}

void read_resolution(const ParamList& params, const SourceLoc& loc, Medium& m) {
  m.nx = params.get_int("nx", 1);
  m.ny = params.get_int("ny", 1);
  m.nz = params.get_int("nz", 1);
  // The product is checked in double: three ints can overflow 64 bits.
  if (m.nx < 1 || m.ny < 1 || m.nz < 1 || double(m.nx) * m.ny * m.nz > 4.0e9)
    throw_at(loc, "grid resolution {} x {} x {}, expected nx, ny, nz >= 1 and at most 4e9 voxels", m.nx, m.ny, m.nz);
}

void read_bounds(const ParamList& params, const SourceLoc& loc, Medium& m) {
  m.p0 = params.get_point3("p0", vec3(0.0f));
  m.p1 = params.get_point3("p1", vec3(1.0f));
  if (!(m.p0.x < m.p1.x && m.p0.y < m.p1.y && m.p0.z < m.p1.z))
    throw_at(loc, "medium bounds p0 ({}, {}, {}) - p1 ({}, {}, {}), expected p0 < p1 on every axis", m.p0.x, m.p0.y, m.p0.z,
             m.p1.x, m.p1.y, m.p1.z);
}

size_t voxel_count(const Medium& m) { return size_t(m.nx) * size_t(m.ny) * size_t(m.nz); }

// A "float" grid of nx*ny*nz values >= 0 (a negative density would be
// negative extinction: energy from nowhere); empty when absent.
std::vector<float> float_grid(const ParamList& params, std::string_view name, const Medium& m) {
  const Param* p = params.find(name, ParamType::Float);
  if (!p) return {};
  if (p->numbers.size() != voxel_count(m))
    throw_at(p->loc, "{} has {} values, expected nx*ny*nz = {}", p->label(), p->numbers.size(), voxel_count(m));
  std::vector<float> v(p->numbers.size());
  for (size_t i = 0; i < v.size(); ++i) {
    if (!(p->numbers[i] >= 0.0)) throw_at(p->loc, "{} value {} is {}, expected >= 0", p->label(), i, p->numbers[i]);
    v[i] = float(p->numbers[i]);
  }
  return v;
}

// An "rgb" grid of nx*ny*nz colours >= 0 in the working space; empty when absent.
std::vector<RGB> rgb_grid(const ParamList& params, std::string_view name, const Medium& m, bool illuminant) {
  if (const Param* s = params.find_any(name, {ParamType::Spectrum, ParamType::Blackbody, ParamType::Float}))
    throw_at(s->loc, "rgbgrid {} must be \"rgb {}\" with nx*ny*nz colours", s->label(), name);
  const Param* p = params.find(name, ParamType::RGB);
  if (!p) return {};
  if (p->numbers.size() != 3 * voxel_count(m))
    throw_at(p->loc, "{} has {} values, expected 3 * nx*ny*nz = {}", p->label(), p->numbers.size(), 3 * voxel_count(m));
  std::vector<RGB> v(voxel_count(m));
  for (size_t i = 0; i < v.size(); ++i) {
    for (int c = 0; c < 3; ++c)
      if (!(p->numbers[3 * i + c] >= 0.0))
        throw_at(p->loc, "{} value {} is {}, expected >= 0", p->label(), 3 * i + c, p->numbers[3 * i + c]);
    const RGB rgb(float(p->numbers[3 * i]), float(p->numbers[3 * i + 1]), float(p->numbers[3 * i + 2]));
    v[i] = illuminant ? srgb_to_working(rgb) : coefficient_to_working(rgb);
  }
  return v;
}

// "temperatureoffset" (pbrt-v4 also takes "temperaturecutoff") and "temperaturescale".
void read_temperature_mapping(const ParamList& params, Medium& m) {
  const float cutoff = params.get_float("temperaturecutoff", 0.0f);
  m.temperature_offset = params.get_float("temperatureoffset", cutoff);
  m.temperature_scale = params.get_float("temperaturescale", 1.0f);
}

void read_uniform_grid(const ParamList& params, const SourceLoc& loc, Medium& m) {
  read_resolution(params, loc, m);
  m.density = float_grid(params, "density", m);
  if (m.density.empty()) throw_at(loc, "uniformgrid medium \"{}\" without \"float density\", expected nx*ny*nz values", m.name);
  m.temperature = float_grid(params, "temperature", m);
  read_temperature_mapping(params, m);
  read_bounds(params, loc, m);
  read_sigma(params, loc, true, m);
  read_g(params, m);
  const Param* le_grid = params.find("Lescale", ParamType::Float);
  if (le_grid && le_grid->numbers.size() > 1) {
    // pbrt-v4's Lescale grid; theia also takes one value as a plain factor.
    m.Le_scale_grid = float_grid(params, "Lescale", m);
    m.Le = params.get_spectrum("Le", SpectrumUse::Illuminant, RGB(0.0f)).value_or(RGB(0.0f));
  } else {
    read_Le(params, m);
  }
  if (!m.temperature.empty() && params.find_any("Le", {ParamType::RGB, ParamType::Spectrum, ParamType::Blackbody}))
    throw_at(loc, "uniformgrid medium \"{}\" has both \"Le\" and \"temperature\", expected one of them", m.name);
  build_blackbody_table(m);
  build_majorant_grid(m);
}

// pbrt-v4's rgbgrid: "sigma_a" and/or "sigma_s" as nx*ny*nz colours (a
// missing one is 1), times "scale"; "Le" colours (which need sigma_a) times "Lescale".
void read_rgb_grid(const ParamList& params, const SourceLoc& loc, Medium& m) {
  read_resolution(params, loc, m);
  m.sigma_a_grid = rgb_grid(params, "sigma_a", m, false);
  m.sigma_s_grid = rgb_grid(params, "sigma_s", m, false);
  m.Le_grid = rgb_grid(params, "Le", m, true);
  if (m.sigma_a_grid.empty() && m.sigma_s_grid.empty())
    throw_at(loc, "rgbgrid medium \"{}\" without \"rgb sigma_a\" or \"rgb sigma_s\", expected nx*ny*nz colours", m.name);
  if (!m.Le_grid.empty() && m.sigma_a_grid.empty())
    throw_at(loc, "rgbgrid medium \"{}\" has \"Le\" without \"sigma_a\", expected both (emission is sigma_a Le)", m.name);
  read_bounds(params, loc, m);
  m.Le_scale = non_negative(params, "Lescale", 1.0f);
  read_g(params, m);
  const float scale = non_negative(params, "scale", 1.0f);
  m.sigma_a = m.sigma_s = RGB(scale);
  build_majorant_grid(m);
}

// pbrt-v4's cloud: it reads neither "scale" nor "Le" (they are reported unused).
void read_cloud(const ParamList& params, const SourceLoc& loc, Medium& m) {
  m.cloud_density = params.get_float("density", 1.0f);
  m.wispiness = params.get_float("wispiness", 1.0f);
  m.frequency = params.get_float("frequency", 5.0f);
  read_bounds(params, loc, m);
  read_sigma(params, loc, false, m);
  read_g(params, m);
  build_majorant_grid(m);
}

void read_nanovdb(const ParamList& params, const SourceLoc& loc, const std::string& base_dir, Medium& m) {
  read_vdb_grids(params, loc, base_dir, m);
  read_temperature_mapping(params, m);
  m.Le_scale = non_negative(params, "Lescale", 1.0f);
  read_sigma(params, loc, true, m);
  read_g(params, m);
  build_blackbody_table(m);
  build_majorant_grid(m);
}

}  // namespace

Medium read_medium(const std::string& name, const std::string& type, const ParamList& params, const SourceLoc& loc,
                   const Transform& render_from_medium, const std::string& base_dir) {
  Medium m;
  m.name = name;
  m.loc = loc;
  m.render_from_medium = render_from_medium;
  if (type == "homogeneous") {
    m.kind = MediumKind::Homogeneous;
    read_sigma(params, loc, true, m);
    read_g(params, m);
    read_Le(params, m);
  } else if (type == "uniformgrid") {
    m.kind = MediumKind::UniformGrid;
    read_uniform_grid(params, loc, m);
  } else if (type == "rgbgrid") {
    m.kind = MediumKind::RGBGrid;
    read_rgb_grid(params, loc, m);
  } else if (type == "cloud") {
    m.kind = MediumKind::Cloud;
    read_cloud(params, loc, m);
  } else if (type == "nanovdb") {
    m.kind = MediumKind::NanoVDB;
    read_nanovdb(params, loc, base_dir, m);
  } else {
    throw_at(loc, "unknown medium type \"{}\", expected \"homogeneous\", \"uniformgrid\", \"rgbgrid\", \"cloud\" or \"nanovdb\"",
             type);
  }
  params.report_unused();
  return m;
}

}  // namespace theia
