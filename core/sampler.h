// Low-discrepancy samples without sampler state (Burley 2020, "Practical
// Hash-based Owen Scrambling").
//
// Every value is a pure function of (seed, pixel, sample index, dimension), so
// the wavefront can draw any path's next number from the path's own indices
// without storing a sampler.  Dimensions come in pairs (2k, 2k+1); each pair is
// an independent 2D Sobol (0,2)-sequence, Owen-scrambled and with its sample
// index shuffled by a nested-uniform scramble, both seeded by
// hash(seed, pixel, k).  Hence:
//  - any prefix of 2^m samples of a pixel is a (0,m,2)-net in every pair and
//    stratified in every single dimension, whatever m;
//  - different pairs, pixels and seeds are decorrelated (independent scrambles).
#pragma once

#include "core/math.h"

#include <cstdint>

namespace theia {

struct SamplerKey {
  uint32_t seed = 0;
  uint32_t pixel = 0;   // y * width + x
  uint32_t sample = 0;  // sample index within the pixel
};

// Value of `dimension` in [0, 1).
float sample_1d(const SamplerKey& key, uint32_t dimension);

// (sample_1d(key, dimension), sample_1d(key, dimension + 1)).  With an even
// dimension the two form one jointly stratified 2D pattern; with an odd one
// they come from two different pairs and are only individually stratified.
vec2 sample_2d(const SamplerKey& key, uint32_t dimension);

// ---------------------------------------------------------------- building blocks

// Unscrambled Sobol sequence, dimensions 0..3 (Joe & Kuo direction numbers),
// as a 32-bit fixed-point fraction.  Dimensions 0 and 1 form a (0,2)-sequence.
uint32_t sobol_sample(uint32_t index, uint32_t dim);
inline constexpr uint32_t kSobolDimensions = 4;

uint32_t reverse_bits(uint32_t x);
// Owen scrambling in base 2 of a 32-bit fixed-point fraction: each bit is
// flipped by a hash of the bits above it (Laine-Karras permutation on the
// reversed bits, with Burley's constants).
uint32_t nested_uniform_scramble(uint32_t x, uint32_t seed);

}  // namespace theia
