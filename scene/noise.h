// pbrt-v4's Perlin noise and the sums of octaves its procedural textures use
// (fbm, wrinkled, windy, marble, dots).  Deterministic: one fixed permutation
// table (Perlin's), no state.
#pragma once

#include "core/math.h"

namespace theia {

// Gradient noise in about [-1, 1]: 0 at every integer lattice point, C2 continuous.
// pbrt-v4's Noise(x, y = 0.5, z = 0.5).
float perlin_noise(float x, float y = 0.5f, float z = 0.5f);
inline float perlin_noise(vec3 p) { return perlin_noise(p.x, p.y, p.z); }
// pbrt-v4's DNoise: the noise's gradient by forward differences of 0.01.
inline vec3 perlin_noise_gradient(vec3 p) {
  const float delta = 0.01f, n = perlin_noise(p);
  return (vec3(perlin_noise(p + vec3(delta, 0.0f, 0.0f)), perlin_noise(p + vec3(0.0f, delta, 0.0f)),
               perlin_noise(p + vec3(0.0f, 0.0f, delta))) -
          vec3(n)) /
         delta;
}

// How many octaves a sum of noise keeps for a footprint of (dpdx, dpdy) in
// texture space: -1 - log2(max |dp|^2) / 2, clamped to [0, max_octaves].  The
// fraction fades the last octave in.  A zero footprint keeps max_octaves.
float noise_octaves(vec3 dpdx, vec3 dpdy, int max_octaves);

// pbrt-v4's FBm: sum of omega^i Noise(1.99^i p) over noise_octaves octaves.
float fbm(vec3 p, vec3 dpdx, vec3 dpdy, float omega, int max_octaves);
// pbrt-v4's Turbulence: the same with |Noise|; octaves the footprint drops are
// replaced by their mean 0.2 omega^i.
float turbulence(vec3 p, vec3 dpdx, vec3 dpdy, float omega, int max_octaves);

}  // namespace theia
