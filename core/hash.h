// Integer hashing: the source of every random number in theia.  Random values
// are pure functions of integer keys (seed, pixel, sample, dimension), never
// of a stateful generator, so results do not depend on scheduling.
#pragma once

#include "core/math.h"

#include <cstddef>
#include <cstdint>
#include <type_traits>

namespace theia {

// A bijective 64-bit finaliser (pbrt-v4's MixBits, a splitmix64 variant):
// every input bit affects every output bit with probability close to 1/2.
constexpr uint64_t mix_bits(uint64_t v) {
  v ^= v >> 31;
  v *= 0x7fb5d329728ea185ull;
  v ^= v >> 27;
  v *= 0x81dadef4bc2dd44dull;
  v ^= v >> 33;
  return v;
}

// hash(args..., next) from h = hash(args...): keys that share a prefix hash
// it once.
constexpr uint64_t hash_extend(uint64_t h, uint64_t next) {
  return mix_bits(h ^ (next * 0xbf58476d1ce4e5b9ull + 0x94d049bb133111ebull));
}

// Hash of a few integers.  Order matters: hash(a, b) != hash(b, a), and
// hash(a) != hash(a, 0), because each argument adds a mixing round.
template <typename... Args>
constexpr uint64_t hash(Args... args) {
  static_assert(sizeof...(Args) > 0 && (std::is_integral_v<Args> && ...), "hash() takes integers");
  uint64_t h = 0x9e3779b97f4a7c15ull;
  ((h = hash_extend(h, static_cast<uint64_t>(args))), ...);
  return h;
}

// Hash of a byte string (checksums of checkpoint files, scene fingerprints).
// Not cryptographic: it detects truncation and corruption, not tampering.
inline uint64_t hash_bytes(const void* data, size_t size, uint64_t seed = 0) {
  const unsigned char* p = static_cast<const unsigned char*>(data);
  uint64_t h = mix_bits(seed ^ 0x9e3779b97f4a7c15ull ^ size);
  size_t i = 0;
  for (; i + 8 <= size; i += 8) {
    uint64_t w;
    __builtin_memcpy(&w, p + i, 8);
    h = mix_bits(h ^ w) + 0x94d049bb133111ebull;
  }
  uint64_t tail = 0;
  for (size_t k = 0; i < size; ++i, ++k) tail |= uint64_t(p[i]) << (8 * k);
  return mix_bits(h ^ tail);
}

// Uniform float in [0, 1).  Only the top 24 bits are used so that the
// conversion is exact: v / 2^32 rounded to float could round up to 1, or
// across a stratum boundary, and break the stratification of a (0,2)-net.
constexpr float to_unit_float(uint32_t v) { return float(v >> 8) * 0x1p-24f; }

}  // namespace theia
