#include "core/sampler.h"

namespace theia {

namespace {

// Direction numbers from the primitive polynomials and initial m_i of Joe &
// Kuo (new-joe-kuo-6.21201, dimensions 2-4); dimension 0 is van der Corput.
// Computed at compile time so that no table needs to be kept in the source.
struct SobolPolynomial {
  uint32_t degree;
  uint32_t a;     // inner coefficients, highest first, without the leading and trailing 1
  uint32_t m[3];  // initial direction integers m_1..m_degree
};

constexpr std::array<std::array<uint32_t, 32>, kSobolDimensions> make_sobol_directions() {
  constexpr SobolPolynomial polys[kSobolDimensions - 1] = {{1, 0, {1, 0, 0}}, {2, 1, {1, 3, 0}}, {3, 1, {1, 3, 1}}};
  std::array<std::array<uint32_t, 32>, kSobolDimensions> v{};
  for (uint32_t i = 0; i < 32; ++i) v[0][i] = 1u << (31 - i);
  for (uint32_t d = 1; d < kSobolDimensions; ++d) {
    const SobolPolynomial& p = polys[d - 1];
    uint32_t s = p.degree;
    // m_i (1-based) is an odd integer < 2^i; v_i = m_i / 2^i as a 32-bit fraction.
    uint64_t m[33] = {};
    for (uint32_t i = 1; i <= s; ++i) m[i] = p.m[i - 1];
    for (uint32_t i = s + 1; i <= 32; ++i) {
      uint64_t mi = m[i - s] ^ (m[i - s] << s);
      for (uint32_t k = 1; k < s; ++k)
        if ((p.a >> (s - 1 - k)) & 1u) mi ^= m[i - k] << k;
      m[i] = mi;
    }
    for (uint32_t i = 1; i <= 32; ++i) v[d][i - 1] = uint32_t(m[i] << (32 - i));
  }
  return v;
}

constexpr auto kSobolDirections = make_sobol_directions();

// The Sobol matrix-vector product one index byte at a time: table[k][b] is the
// XOR of the direction numbers selected by byte value b at byte position k.
// Shuffled indices use all 32 bits, so a bit-by-bit loop would take 32 steps.
using SobolByteTables = std::array<std::array<uint32_t, 256>, 4>;

constexpr std::array<SobolByteTables, kSobolDimensions> make_sobol_byte_tables() {
  std::array<SobolByteTables, kSobolDimensions> t{};
  for (uint32_t d = 0; d < kSobolDimensions; ++d)
    for (uint32_t k = 0; k < 4; ++k)
      for (uint32_t b = 0; b < 256; ++b) {
        uint32_t x = 0;
        for (uint32_t j = 0; j < 8; ++j)
          if ((b >> j) & 1u) x ^= kSobolDirections[d][8 * k + j];
        t[d][k][b] = x;
      }
  return t;
}

constexpr auto kSobolByteTables = make_sobol_byte_tables();

}  // namespace

namespace sampler_detail {

constexpr std::array<std::array<uint32_t, 256>, 4> make_sobol1_reversed() {
  // Byte k of y is the bit-reversed byte 3 - k of the index.
  std::array<std::array<uint32_t, 256>, 4> t{};
  for (uint32_t k = 0; k < 4; ++k)
    for (uint32_t b = 0; b < 256; ++b) {
      uint32_t index_byte = reverse_bits(b) >> 24;
      t[k][b] = reverse_bits(kSobolByteTables[1][3 - k][index_byte]);
    }
  return t;
}

constinit const std::array<std::array<uint32_t, 256>, 4> kSobol1Reversed = make_sobol1_reversed();

}  // namespace sampler_detail

namespace {

// A block of keys, one lane each: sample_4d's span form runs every loop over
// all of them (unused lanes compute on zeros), which lets the compiler
// vectorize with fixed trip counts.
constexpr size_t kKeyBlock = 16;
struct KeyBlock {
  uint32_t seed[kKeyBlock], pixel[kKeyBlock], sample[kKeyBlock], first[kKeyBlock];
};

// One pair's two numbers, component0 and component1 of reversed_index
// (sampler_detail), from h = hash(seed, pixel, pair) and the reversed sample
// index.  to_sample's clamp is left out: to_unit_float is below 1 already.
static_assert(to_unit_float(0xffffffffu) == kOneMinusEpsilon);
[[gnu::always_inline]] inline void pair_in_lanes(uint64_t h, uint32_t reversed_sample, float& u0, float& u1) {
  using namespace sampler_detail;
  const PairSeeds s = pair_seeds_of(h);
  const uint32_t y = laine_karras_permutation(reversed_sample, s.shuffle);
  const uint32_t x0 = reverse_bits_by_masks(y), x1 = reversed_sobol1_of_reversed_by_masks(y);
  u0 = to_unit_float(reverse_bits_by_masks(laine_karras_permutation(x0, s.scramble[0])));
  u1 = to_unit_float(reverse_bits_by_masks(laine_karras_permutation(x1, s.scramble[1])));
}

void sample_4d_block(const KeyBlock& in, float u[4][kKeyBlock]) {
  uint64_t h[2][kKeyBlock];
  uint32_t reversed_sample[kKeyBlock];
  for (size_t i = 0; i < kKeyBlock; ++i) {
    // hash(seed, pixel, pair), its first two arguments hashed once for both pairs.
    const uint64_t prefix = hash_extend(hash(in.seed[i]), in.pixel[i]), pair = in.first[i] >> 1;
    h[0][i] = hash_extend(prefix, pair);
    h[1][i] = hash_extend(prefix, pair + 1);
  }
  for (size_t i = 0; i < kKeyBlock; ++i) reversed_sample[i] = reverse_bits_by_masks(in.sample[i]);
  for (size_t i = 0; i < kKeyBlock; ++i) pair_in_lanes(h[0][i], reversed_sample[i], u[0][i], u[1][i]);
  for (size_t i = 0; i < kKeyBlock; ++i) pair_in_lanes(h[1][i], reversed_sample[i], u[2][i], u[3][i]);
}

}  // namespace

void sample_4d(std::span<const SamplerKey> keys, std::span<const uint32_t> first, std::span<vec4> out) {
  for (size_t b = 0; b < keys.size(); b += kKeyBlock) {
    const size_t m = std::min(kKeyBlock, keys.size() - b);
    KeyBlock in{};
    for (size_t i = 0; i < m; ++i) {
      in.seed[i] = keys[b + i].seed;
      in.pixel[i] = keys[b + i].pixel;
      in.sample[i] = keys[b + i].sample;
      in.first[i] = first[b + i];
    }
    float u[4][kKeyBlock];
    sample_4d_block(in, u);
    for (size_t i = 0; i < m; ++i) out[b + i] = vec4(u[0][i], u[1][i], u[2][i], u[3][i]);
  }
}

uint32_t sobol_sample(uint32_t index, uint32_t dim) {
  if (dim == 0) return reverse_bits(index);
  const SobolByteTables& t = kSobolByteTables[dim];
  return t[0][index & 0xffu] ^ t[1][(index >> 8) & 0xffu] ^ t[2][(index >> 16) & 0xffu] ^ t[3][index >> 24];
}

}  // namespace theia
