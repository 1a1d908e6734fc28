#include "core/radix_sort.h"

#include <algorithm>
#include <tbb/parallel_for.h>

#include <array>

namespace theia {

namespace {

constexpr int kDigitBits = 11;
constexpr size_t kBuckets = size_t(1) << kDigitBits;
// Below this many pairs a pass is cheaper on one thread than split.
constexpr size_t kParallelMin = size_t(1) << 15;
constexpr size_t kChunkMin = size_t(1) << 13;

uint32_t digit(const SortPair& p, int shift) { return uint32_t((p.key >> shift) & (kBuckets - 1)); }

}  // namespace

// Each pass: per-chunk digit histograms, then every chunk scatters its pairs
// to offsets that put all smaller digits first and, within a digit, earlier
// chunks first, so the sort stays stable and its result does not depend on
// how many chunks there are.
void radix_sort(std::vector<SortPair>& pairs, std::vector<SortPair>& scratch, int key_bits) {
  const size_t n = pairs.size();
  if (n < 2) return;
  scratch.resize(n);
  const size_t chunks = n < kParallelMin ? 1 : std::min<size_t>(64, n / kChunkMin);
  const size_t chunk_size = (n + chunks - 1) / chunks;
  std::vector<uint32_t> count(chunks * kBuckets);
  std::vector<SortPair>* src = &pairs;
  std::vector<SortPair>* dst = &scratch;
  auto for_each_chunk = [&](auto&& f) {
    if (chunks == 1) return f(size_t(0));
    tbb::parallel_for(size_t(0), chunks, [&](size_t c) { f(c); });
  };
  for (int shift = 0; shift < key_bits; shift += kDigitBits) {
    for_each_chunk([&](size_t c) {
      uint32_t* h = count.data() + c * kBuckets;
      std::fill(h, h + kBuckets, 0u);
      for (size_t i = c * chunk_size, e = std::min(n, i + chunk_size); i < e; ++i) ++h[digit((*src)[i], shift)];
    });
    // A pass whose digit is the same for every key moves nothing: skip it.
    const uint32_t first = digit((*src)[0], shift);
    size_t same = 0;
    for (size_t c = 0; c < chunks; ++c) same += count[c * kBuckets + first];
    if (same == n) continue;
    uint32_t sum = 0;
    for (size_t d = 0; d < kBuckets; ++d)
      for (size_t c = 0; c < chunks; ++c) {
        uint32_t t = count[c * kBuckets + d];
        count[c * kBuckets + d] = sum;
        sum += t;
      }
    for_each_chunk([&](size_t c) {
      uint32_t* offset = count.data() + c * kBuckets;
      for (size_t i = c * chunk_size, e = std::min(n, i + chunk_size); i < e; ++i)
        (*dst)[offset[digit((*src)[i], shift)]++] = (*src)[i];
    });
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
