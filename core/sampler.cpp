#include "core/sampler.h"

#include "core/hash.h"

#include <array>

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

// Per pair k of a pixel: the seeds of the index shuffle and of the two scrambles.
struct PairSeeds {
  uint32_t shuffle, scramble[2];
};

inline PairSeeds pair_seeds(const SamplerKey& key, uint32_t pair) {
  uint64_t h = hash(key.seed, key.pixel, pair);
  // One more cheap multiply-xorshift decorrelates the third seed from the first two.
  uint64_t h2 = (h ^ (h >> 29)) * 0xbf58476d1ce4e5b9ull;
  return {uint32_t(h), {uint32_t(h >> 32), uint32_t(h2 >> 32)}};
}

// Burley's hash on bit-reversed values: bit i of the result depends only on
// bits 0..i of x, which after reversal are the more significant digits.
inline uint32_t laine_karras_permutation(uint32_t x, uint32_t seed) {
  x += seed;
  x ^= x * 0x6c50b47cu;
  x ^= x * 0xb82f1e52u;
  x ^= x * 0xc7afe638u;
  x ^= x * 0x8d22f6e6u;
  return x;
}

inline uint32_t reverse_bits_fast(uint32_t x) {
  x = __builtin_bswap32(x);
  x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  return ((x >> 4) & 0x0f0f0f0fu) | ((x & 0x0f0f0f0fu) << 4);
}

inline uint32_t sobol_fast(uint32_t index, uint32_t dim) {
  const SobolByteTables& t = kSobolByteTables[dim];
  return t[0][index & 0xffu] ^ t[1][(index >> 8) & 0xffu] ^ t[2][(index >> 16) & 0xffu] ^ t[3][index >> 24];
}

inline float to_sample(uint32_t x) { return std::min(to_unit_float(x), kOneMinusEpsilon); }

// Owen-scrambling the index permutes the samples so that any 2^m prefix is
// one aligned block of 2^m Sobol points, i.e. a full net.
inline uint32_t shuffled_index(uint32_t sample, uint32_t seed) {
  return reverse_bits_fast(laine_karras_permutation(reverse_bits_fast(sample), seed));
}

// Dimension 0 of Sobol is the bit reversal of the index, so its nested
// scramble reverse(LK(reverse(reverse(i)))) needs only one reversal.
inline float component0(uint32_t index, uint32_t seed) {
  return to_sample(reverse_bits_fast(laine_karras_permutation(index, seed)));
}
inline float component1(uint32_t index, uint32_t seed) {
  uint32_t x = reverse_bits_fast(sobol_fast(index, 1));
  return to_sample(reverse_bits_fast(laine_karras_permutation(x, seed)));
}

}  // namespace

uint32_t reverse_bits(uint32_t x) { return reverse_bits_fast(x); }

uint32_t sobol_sample(uint32_t index, uint32_t dim) { return dim == 0 ? reverse_bits(index) : sobol_fast(index, dim); }

uint32_t nested_uniform_scramble(uint32_t x, uint32_t seed) {
  return reverse_bits_fast(laine_karras_permutation(reverse_bits_fast(x), seed));
}

float sample_1d(const SamplerKey& key, uint32_t dimension) {
  PairSeeds s = pair_seeds(key, dimension >> 1);
  uint32_t index = shuffled_index(key.sample, s.shuffle);
  return (dimension & 1u) ? component1(index, s.scramble[1]) : component0(index, s.scramble[0]);
}

vec2 sample_2d(const SamplerKey& key, uint32_t dimension) {
  if (dimension & 1u) return {sample_1d(key, dimension), sample_1d(key, dimension + 1)};
  PairSeeds s = pair_seeds(key, dimension >> 1);
  uint32_t index = shuffled_index(key.sample, s.shuffle);
  return {component0(index, s.scramble[0]), component1(index, s.scramble[1])};
}

}  // namespace theia
