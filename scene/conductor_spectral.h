// Conductors from spectral optical constants, as pbrt-v4 renders them.
//
// pbrt-v4 turns a conductor's eta and k into spectra at load time (an "rgb"
// value by its RGB-to-spectrum upsampling for unbounded spectra, a named metal
// by its measured table) and evaluates the complex Fresnel equations per
// wavelength.  The film then sees the spectral reflectance averaged under the
// light's spectrum.  Fresnel of per-band eta and k is a different average:
// for eta (0.2 0.9 1.1), k (3.9 2.4 1.6) it is 3.8% low in red at normal
// incidence, and no single (eta, k) per channel follows the spectral curve
// over angle within 1% (its red dips 4% at cos 0.24 where a Fresnel curve
// stays flat).  So theia tabulates the spectral reflectance over cos theta
// once per material, projected to RGB as pbrt-v4's film records it under a
// white ("rgb L" = D65) light, and the renderer interpolates the table.
#pragma once

#include "core/math.h"

#include <functional>
#include <vector>

namespace theia {

// Entries of a tabulated conductor Fresnel, at cos theta = i / (size - 1):
// linear interpolation stays within 0.2% of the spectral curve even for a
// weakly absorbing k (~0.3), within 0.04% for ordinary metals.
inline constexpr int kConductorFresnelTableSize = 64;

// A spectrum as a function of wavelength in nm.
using SpectrumFn = std::function<double(double lambda_nm)>;

// pbrt-v4's RGBUnboundedSpectrum: scale * S(c0 x^2 + c1 x + c2), x the
// wavelength mapped from [360, 830] nm to [0, 1], S(y) = 1/2 + y / (2 sqrt(1 + y^2)),
// scale = 2 max(rgb), and c fitted so that the sigmoid spectrum, seen as a
// reflectance under D65, has the linear-sRGB colour rgb / scale.  A grey rgb
// gives the constant spectrum exactly.
struct SigmoidSpectrum {
  double c0 = 0.0, c1 = 0.0, c2 = 0.0, scale = 0.0;
  double operator()(double lambda_nm) const;
};
SigmoidSpectrum rgb_unbounded_spectrum(const RGB& srgb);

// The linear-sRGB colour of reflectance spectrum r under D65 with the CIE 1931
// observer, normalised so that r = 1 gives (1, 1, 1): what pbrt-v4's RGB film
// records for a surface of that reflectance lit by a white "rgb L" light.
RGB reflectance_srgb_under_d65(const SpectrumFn& r);

// The complex Fresnel reflectance of eta(lambda) + i k(lambda), per wavelength,
// projected by reflectance_srgb_under_d65, at cos theta = i / (kConductorFresnelTableSize - 1),
// in the working space and clamped to [0, 1].
std::vector<RGB> tabulate_conductor_fresnel(const SpectrumFn& eta, const SpectrumFn& k);

// One entry of such a table at cos theta (linear interpolation).
RGB lookup_conductor_fresnel(const RGB* table, float cos_theta);

}  // namespace theia
