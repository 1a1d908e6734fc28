#include "wavefront/radix_sort.h"

#include <algorithm>
#include <array>

namespace theia {

void radix_sort(std::vector<SortPair>& pairs, std::vector<SortPair>& scratch, int key_bits) {
  constexpr int kDigitBits = 11;
  constexpr size_t kBuckets = size_t(1) << kDigitBits;
  const size_t n = pairs.size();
  if (n < 2) return;
  scratch.resize(n);
  std::vector<SortPair>* src = &pairs;
  std::vector<SortPair>* dst = &scratch;
  std::array<uint32_t, kBuckets> count;
  for (int shift = 0; shift < key_bits; shift += kDigitBits) {
    count.fill(0);
    for (const SortPair& p : *src) ++count[(p.key >> shift) & (kBuckets - 1)];
    // A pass whose digit is the same for every key moves nothing: skip it.
    if (count[((*src)[0].key >> shift) & (kBuckets - 1)] == n) continue;
    uint32_t sum = 0;
    for (uint32_t& c : count) {
      uint32_t t = c;
      c = sum;
      sum += t;
    }
    for (const SortPair& p : *src) (*dst)[count[(p.key >> shift) & (kBuckets - 1)]++] = p;
    std::swap(src, dst);
  }
  if (src != &pairs) pairs.swap(scratch);
}

static uint32_t spread_bits_10(uint32_t v) {
  v = (v * 0x00010001u) & 0xFF0000FFu;
  v = (v * 0x00000101u) & 0x0F00F00Fu;
  v = (v * 0x00000011u) & 0xC30C30C3u;
  v = (v * 0x00000005u) & 0x49249249u;
  return v;
}

uint32_t morton3(float x, float y, float z) {
  auto quantise = [](float f) { return uint32_t(std::clamp(f * 1024.0f, 0.0f, 1023.0f)); };
  return (spread_bits_10(quantise(x)) << 2) | (spread_bits_10(quantise(y)) << 1) | spread_bits_10(quantise(z));
}

}  // namespace theia
