// The renderer's working colour space.
//
// Scenes give colours in linear sRGB (pbrt-v4's default colour space), and
// outputs are linear sRGB too, but theia multiplies colours in linear
// Rec.2020 (same D65 white, wider primaries).  pbrt-v4 renders spectrally;
// a component-wise product of RGB triples only approximates the product of
// two spectra, and how well depends on the primaries.  On the Cornell box,
// modelled spectrally as pbrt-v4 does it (tools/spectral_gap.py), rendering
// in linear sRGB puts the image's blue mean 3.8% above the spectral result;
// in Rec.2020 every channel is within 1%.  Greys are unchanged by the
// conversion (its rows sum to one), so furnace tests are unaffected, and
// colours inside the sRGB gamut stay non-negative in Rec.2020.
#pragma once

#include "core/math.h"

namespace theia {

// Linear sRGB -> linear Rec.2020 (ITU-R BT.2087), and its inverse.
inline constexpr float kSrgbToWorking[3][3] = {{0.627404f, 0.329283f, 0.043313f},
                                               {0.069097f, 0.919540f, 0.011362f},
                                               {0.016391f, 0.088013f, 0.895595f}};
inline constexpr float kWorkingToSrgb[3][3] = {{1.660491f, -0.587641f, -0.072850f},
                                               {-0.124550f, 1.132900f, -0.008349f},
                                               {-0.018151f, -0.100579f, 1.118730f}};

inline RGB apply_matrix(const float (&m)[3][3], const RGB& c) {
  return {m[0][0] * c.x + m[0][1] * c.y + m[0][2] * c.z, m[1][0] * c.x + m[1][1] * c.y + m[1][2] * c.z,
          m[2][0] * c.x + m[2][1] * c.y + m[2][2] * c.z};
}

// A colour from the scene (linear sRGB) in the working space.
inline RGB srgb_to_working(const RGB& c) { return apply_matrix(kSrgbToWorking, c); }
// A working-space colour for output (linear sRGB).
inline RGB working_to_srgb(const RGB& c) { return apply_matrix(kWorkingToSrgb, c); }

}  // namespace theia
