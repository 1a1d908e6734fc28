// pbrt-v4's named scattering presets (MakeNamedMedium "preset"): measured
// sigma_a and reduced sigma_s' of real media, in mm^-1, as pbrt-v4's
// GetMediumScatteringProperties gives them (sigma_s' is used as sigma_s).
#pragma once

#include "core/math.h"

#include <string>
#include <string_view>

namespace theia {

struct MediumPreset {
  std::string_view name;
  RGB sigma_s, sigma_a;  // linear sRGB, mm^-1
};

// nullptr when `name` is not a preset (names are case-sensitive, as in pbrt-v4).
const MediumPreset* find_medium_preset(std::string_view name);
// Every preset name, quoted and comma-separated, for an error message.
std::string medium_preset_names();

}  // namespace theia
