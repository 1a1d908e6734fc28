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
//
// sample_1d and sample_2d are inline: a path vertex draws several dimensions
// of one key, and inlined the compiler shares the key's hashing of (seed,
// pixel) and its bit-reversed sample index between them.
#pragma once

#include "core/hash.h"
#include "core/math.h"

#include <array>
#include <cstdint>
#include <span>
#include <type_traits>
#if defined(__GFNI__)
#include <immintrin.h>
#endif

namespace theia {

struct SamplerKey {
  uint32_t seed = 0;
  uint32_t pixel = 0;   // y * width + x
  uint32_t sample = 0;  // sample index within the pixel
};

// Value of `dimension` in [0, 1).
inline float sample_1d(const SamplerKey& key, uint32_t dimension);

// (sample_1d(key, dimension), sample_1d(key, dimension + 1)).  With an even
// dimension the two form one jointly stratified 2D pattern; with an odd one
// they come from two different pairs and are only individually stratified.
// Always inlined: with several call sites in one file GCC outlined it, and a
// call cost more than the shared hashing saves.
[[gnu::always_inline]] inline vec2 sample_2d(const SamplerKey& key, uint32_t dimension);

// (sample_1d(key, first), ..., sample_1d(key, first + 3)) for an even
// `first`: two whole pairs, such as a path vertex's continuation
// (sample_dims.h).
inline vec4 sample_4d(const SamplerKey& key, uint32_t first);
// sample_4d(keys[i], first[i]) for a block of keys, bit for bit, in loops
// across the keys that the compiler vectorizes: the shading stage draws a
// chunk of hits' numbers before it shades them, so that the draws leave each
// hit's chain of dependent steps (the hashing is a chain of multiplies).
void sample_4d(std::span<const SamplerKey> keys, std::span<const uint32_t> first, std::span<vec4> out);

// sample_2d(key, dimension) of one (seed, pixel) and even dimension for any
// sample index, the pair's seeds hashed once: the camera stage draws a
// pixel's film offsets, one sample after another, from one pair.
class PairSampler;

// ---------------------------------------------------------------- building blocks

// Unscrambled Sobol sequence, dimensions 0..3 (Joe & Kuo direction numbers),
// as a 32-bit fixed-point fraction.  Dimensions 0 and 1 form a (0,2)-sequence.
uint32_t sobol_sample(uint32_t index, uint32_t dim);
inline constexpr uint32_t kSobolDimensions = 4;

// reverse_bits by shifts and masks only (no byte swap): what a loop over many
// values vectorizes, and reverse_bits itself where the target has no GFNI.
constexpr uint32_t reverse_bits_by_masks(uint32_t x) {
  x = (x >> 16) | (x << 16);
  x = ((x >> 8) & 0x00ff00ffu) | ((x & 0x00ff00ffu) << 8);
  x = ((x >> 4) & 0x0f0f0f0fu) | ((x & 0x0f0f0f0fu) << 4);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  return ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
}

constexpr uint32_t reverse_bits(uint32_t x) {
#if defined(__GFNI__)
  // One affine transform over GF(2) reverses the bits of every byte, then
  // the bytes swap: a few instructions instead of three mask-and-shift steps.
  if (!std::is_constant_evaluated()) {
    const __m128i v = _mm_gf2p8affine_epi64_epi8(_mm_cvtsi32_si128(int(x)), _mm_set1_epi64x(0x8040201008040201ll), 0);
    return __builtin_bswap32(uint32_t(_mm_cvtsi128_si32(v)));
  }
#endif
  return reverse_bits_by_masks(x);
}

// Burley's hash on bit-reversed values: bit i of the result depends only on
// bits 0..i of x, which after reversal are the more significant digits.
constexpr uint32_t laine_karras_permutation(uint32_t x, uint32_t seed) {
  x += seed;
  x ^= x * 0x6c50b47cu;
  x ^= x * 0xb82f1e52u;
  x ^= x * 0xc7afe638u;
  x ^= x * 0x8d22f6e6u;
  return x;
}

// Owen scrambling in base 2 of a 32-bit fixed-point fraction: each bit is
// flipped by a hash of the bits above it (Laine-Karras permutation on the
// reversed bits, with Burley's constants).
constexpr uint32_t nested_uniform_scramble(uint32_t x, uint32_t seed) {
  return reverse_bits(laine_karras_permutation(reverse_bits(x), seed));
}

// ---------------------------------------------------------------- the sampler

namespace sampler_detail {

// Sobol dimension 1 of the bit-reversed index, bit-reversed, one byte of the
// unreversed index at a time: table[k][b] is the XOR of the reversed
// direction numbers that byte value b at byte position k selects.  Both
// reversals fold into the table (reversal distributes over XOR).
extern const std::array<std::array<uint32_t, 256>, 4> kSobol1Reversed;

inline uint32_t reversed_sobol1_of_reversed(uint32_t y) {
  const auto& t = kSobol1Reversed;
  return t[0][y & 0xffu] ^ t[1][(y >> 8) & 0xffu] ^ t[2][(y >> 16) & 0xffu] ^ t[3][y >> 24];
}
// The same without tables, for vector lanes.  Sobol's dimension 1 is the
// Pascal matrix mod 2: by Lucas' theorem, before the final reversal bit i
// is the XOR of the bits j of y whose positions are subsets of i's (as 5-bit
// numbers), a subset sum taken one bit of the position per step.
constexpr uint32_t reversed_sobol1_of_reversed_by_masks(uint32_t y) {
  y ^= (y << 1) & 0xaaaaaaaau;
  y ^= (y << 2) & 0xccccccccu;
  y ^= (y << 4) & 0xf0f0f0f0u;
  y ^= (y << 8) & 0xff00ff00u;
  y ^= (y << 16) & 0xffff0000u;
  return reverse_bits_by_masks(y);
}

// Per pair k of a pixel: the seeds of the index shuffle and of the two scrambles.
struct PairSeeds {
  uint32_t shuffle, scramble[2];
};

// h = hash(seed, pixel, pair).
inline PairSeeds pair_seeds_of(uint64_t h) {
  // One more cheap multiply-xorshift decorrelates the third seed from the first two.
  uint64_t h2 = (h ^ (h >> 29)) * 0xbf58476d1ce4e5b9ull;
  return {uint32_t(h), {uint32_t(h >> 32), uint32_t(h2 >> 32)}};
}
inline PairSeeds pair_seeds(const SamplerKey& key, uint32_t pair) {
  return pair_seeds_of(hash(key.seed, key.pixel, pair));
}

inline float to_sample(uint32_t x) { return std::min(to_unit_float(x), kOneMinusEpsilon); }

// The pair's sample index is Owen-scrambled, which permutes the samples so
// that any 2^m prefix is one aligned block of 2^m Sobol points, a full net:
// index = reverse(y).  y is what the components need: dimension 0 of Sobol
// is the reversal of the index, so its scramble is reverse(LK(index)), and
// dimension 1 reads y through kSobol1Reversed.
inline uint32_t reversed_index(uint32_t sample, uint32_t shuffle) {
  return laine_karras_permutation(reverse_bits(sample), shuffle);
}
inline float component0(uint32_t y, uint32_t seed) {
  return to_sample(reverse_bits(laine_karras_permutation(reverse_bits(y), seed)));
}
inline float component1(uint32_t y, uint32_t seed) {
  return to_sample(reverse_bits(laine_karras_permutation(reversed_sobol1_of_reversed(y), seed)));
}

}  // namespace sampler_detail

inline float sample_1d(const SamplerKey& key, uint32_t dimension) {
  using namespace sampler_detail;
  PairSeeds s = pair_seeds(key, dimension >> 1);
  uint32_t y = reversed_index(key.sample, s.shuffle);
  return (dimension & 1u) ? component1(y, s.scramble[1]) : component0(y, s.scramble[0]);
}

class PairSampler {
 public:
  PairSampler(const SamplerKey& key, uint32_t even_dimension)
      : seeds_(sampler_detail::pair_seeds(key, even_dimension >> 1)) {}
  [[gnu::always_inline]] vec2 operator()(uint32_t sample) const {
    using namespace sampler_detail;
    const uint32_t y = reversed_index(sample, seeds_.shuffle);
    return {component0(y, seeds_.scramble[0]), component1(y, seeds_.scramble[1])};
  }

 private:
  sampler_detail::PairSeeds seeds_;
};

inline vec2 sample_2d(const SamplerKey& key, uint32_t dimension) {
  if (dimension & 1u) return {sample_1d(key, dimension), sample_1d(key, dimension + 1)};
  return PairSampler(key, dimension)(key.sample);
}

inline vec4 sample_4d(const SamplerKey& key, uint32_t first) {
  return {sample_2d(key, first), sample_2d(key, first + 2)};
}

}  // namespace theia
