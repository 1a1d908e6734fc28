// Which side of a two-sided area light an emitted ray leaves (pbrt-v4's
// DiffuseAreaLight::SampleLe), shared by sample_le and the caustic pass's
// estimate of the same ray (wavefront/caustics.cpp), which must agree to the bit.
#pragma once

#include "core/math.h"
#include "core/sampling.h"

namespace theia {

// The first coordinate picks the side, each half the time, and is stretched
// back to [0, 1): true for the side against the normal.
inline bool emission_back_side(vec2& u_dir) {
  if (u_dir.x < 0.5f) {
    u_dir.x = std::min(u_dir.x * 2.0f, kOneMinusEpsilon);
    return false;
  }
  u_dir.x = std::min((u_dir.x - 0.5f) * 2.0f, kOneMinusEpsilon);
  return true;
}

}  // namespace theia
