// Spectra reduced to theia's rendering colour space (linear sRGB primaries).
//
// theia renders in RGB, so every spectral quantity in a scene file is turned
// into an RGB triple once, at parse time.  Illuminants are normalised the way
// pbrt-v4 normalises a light's spectrum (luminance Y = 1, "scale" applied by
// the caller), so an emitter renders with the brightness pbrt-v4 gives it.
#pragma once

#include "core/math.h"

#include <span>
#include <string_view>

namespace theia {

// CIE 1931 2-degree colour-matching functions, multi-lobe Gaussian fit of
// Wyman, Sloan & Shirley 2013 (JCGT 2(2)); accurate to well under 1% of peak.
vec3 cie_xyz_cmf(float lambda_nm);

// XYZ (D65 white) to linear sRGB.
RGB xyz_to_linear_srgb(const vec3& xyz);

// A blackbody at temperature T (Kelvin), luminance-normalised (Y = 1).
RGB blackbody_rgb(float temperature_k);

// A spectrum tabulated as (wavelength nm, value) pairs, ascending in
// wavelength, linearly interpolated and zero outside the table (pbrt-v4's
// PiecewiseLinearSpectrum).
//
// As an illuminant: luminance-normalised to Y = 1 (a black spectrum gives 0).
RGB spectrum_to_rgb_illuminant(std::span<const float> lambda, std::span<const float> value);
// As a reflectance seen under an equal-energy white: the RGB of the reflected
// light divided by the RGB of the white itself, so that a constant spectrum c
// maps to the grey (c, c, c).
RGB spectrum_to_rgb_reflectance(std::span<const float> lambda, std::span<const float> value);

// pbrt-v4's named spectra ("stdillum-A", "metal-Cu-eta", ...).  Only a few are
// tabulated so far; the table in spectrum.cpp is meant to grow.  An entry is
// either (wavelength, value) pairs or a blackbody temperature.
struct NamedSpectrum {
  std::string_view name;
  std::span<const float> lambda;
  std::span<const float> value;
  float blackbody_k = 0.0f;  // > 0: a Planckian of this temperature instead of pairs
};
const NamedSpectrum* find_named_spectrum(std::string_view name);

// Value of a tabulated spectrum at one wavelength (0 outside the table): a
// dielectric's index is taken at 550 nm.
float spectrum_at(std::span<const float> lambda, std::span<const float> value, float lambda_nm);

// RGB of a named spectrum, for the given use; nullptr-safe callers check
// find_named_spectrum first.
RGB named_spectrum_rgb(const NamedSpectrum& s, bool illuminant);

}  // namespace theia
