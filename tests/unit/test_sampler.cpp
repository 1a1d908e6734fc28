#include "core/hash.h"
#include "core/sampler.h"

#include <boost/math/special_functions/gamma.hpp>
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <set>
#include <vector>

using namespace theia;

namespace {

// True when the points form a (0,m,2)-net: exactly one point in every
// elementary interval [i / 2^a, (i+1) / 2^a) x [j / 2^b, (j+1) / 2^b), a + b = m.
bool is_02_net(const std::vector<vec2>& pts, int m, std::string* why) {
  size_t n = size_t(1) << m;
  if (pts.size() != n) return false;
  for (int a = 0; a <= m; ++a) {
    int b = m - a;
    std::vector<int> count(n, 0);
    for (vec2 p : pts) {
      // Exact: scaling by a power of two and truncating cannot round across a cell.
      size_t i = size_t(std::ldexp(p.x, a)), j = size_t(std::ldexp(p.y, b));
      ++count[(j << a) + i];
    }
    for (size_t c = 0; c < n; ++c)
      if (count[c] != 1) {
        *why = "m = " + std::to_string(m) + ", a = " + std::to_string(a) + ": cell " + std::to_string(c) + " has " +
               std::to_string(count[c]) + " points";
        return false;
      }
  }
  return true;
}

std::vector<vec2> pixel_pairs(SamplerKey key, uint32_t dim, int n) {
  std::vector<vec2> pts;
  for (int i = 0; i < n; ++i) {
    key.sample = uint32_t(i);
    pts.push_back(sample_2d(key, dim));
  }
  return pts;
}

double correlation(const std::vector<double>& a, const std::vector<double>& b) {
  double n = double(a.size()), ma = 0, mb = 0;
  for (size_t i = 0; i < a.size(); ++i) ma += a[i] / n, mb += b[i] / n;
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return sab / std::sqrt(saa * sbb);
}

}  // namespace

TEST(Hash, IsDeterministicAndOrderSensitive) {
  EXPECT_EQ(hash(1, 2, 3), hash(1, 2, 3));
  EXPECT_NE(hash(1, 2), hash(2, 1));
  EXPECT_NE(hash(7), hash(7, 0));
  EXPECT_NE(hash(0u), hash(1u));
  // Flipping any single input bit changes about half the output bits.
  double total = 0;
  for (int bit = 0; bit < 32; ++bit) total += std::popcount(hash(12345u) ^ hash(12345u ^ (1u << bit)));
  EXPECT_NEAR(total / 32.0, 32.0, 3.0);
}

TEST(Hash, ToUnitFloatIsExactAndBelowOne) {
  EXPECT_EQ(to_unit_float(0u), 0.0f);
  EXPECT_LT(to_unit_float(0xffffffffu), 1.0f);
  EXPECT_EQ(to_unit_float(0x80000000u), 0.5f);
  // Just below a stratum boundary stays below it (plain v * 2^-32 would round up to 0.5).
  EXPECT_LT(to_unit_float(0x7fffffffu), 0.5f);
}

// reverse_bits at run time (one GF(2) affine transform where the CPU has
// GFNI) against its definition, bit by bit, and against its compile-time self.
TEST(Sobol, ReverseBitsReversesEveryBit) {
  static_assert(reverse_bits(1u) == 0x80000000u && reverse_bits(0x12345678u) == 0x1e6a2c48u);
  uint64_t state = 1;
  for (int i = 0; i < 100000; ++i) {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    const uint32_t x = uint32_t(state >> 32);
    uint32_t expected = 0;
    for (int b = 0; b < 32; ++b) expected |= ((x >> b) & 1u) << (31 - b);
    ASSERT_EQ(reverse_bits(x), expected) << x;
  }
}

// The vector lanes' forms of the reversal and of Sobol's dimension 1 are the
// scalar ones.  Both dimension-1 forms are linear over GF(2), so agreeing on
// every basis vector, as checked here, makes them the same map.
TEST(Sobol, TheFormsWithoutTablesOrByteSwapsAreTheSame) {
  for (uint32_t b = 0; b < 32; ++b) {
    EXPECT_EQ(reverse_bits_by_masks(1u << b), reverse_bits(1u << b)) << b;
    EXPECT_EQ(sampler_detail::reversed_sobol1_of_reversed_by_masks(1u << b),
              sampler_detail::reversed_sobol1_of_reversed(1u << b))
        << b;
  }
  for (uint32_t i = 0; i < 100000; ++i) {
    const uint32_t x = uint32_t(hash(i));
    EXPECT_EQ(reverse_bits_by_masks(x), reverse_bits(x));
    EXPECT_EQ(sampler_detail::reversed_sobol1_of_reversed_by_masks(x), sampler_detail::reversed_sobol1_of_reversed(x));
  }
}

TEST(Sobol, DirectionNumbersGiveKnownPoints) {
  // First points of each dimension, from the recurrences of Joe & Kuo's polynomials by hand.
  const float expect[4][8] = {{0, .5f, .25f, .75f, .125f, .625f, .375f, .875f},
                              {0, .5f, .75f, .25f, .625f, .125f, .375f, .875f},
                              {0, .5f, .75f, .25f, .375f, .875f, .625f, .125f},
                              {0, .5f, .75f, .25f, .125f, .625f, .875f, .375f}};
  for (uint32_t d = 0; d < kSobolDimensions; ++d)
    for (uint32_t i = 0; i < 8; ++i) EXPECT_EQ(sobol_sample(i, d) * 0x1p-32, expect[d][i]) << d << " " << i;
}

TEST(Sobol, EveryDimensionIsA01SequenceAndTheFirstTwoA02Sequence) {
  for (int m = 0; m <= 14; ++m) {
    size_t n = size_t(1) << m;
    for (uint32_t d = 0; d < kSobolDimensions; ++d) {
      std::set<uint32_t> strata;
      for (uint32_t i = 0; i < n; ++i) strata.insert(m == 0 ? 0 : sobol_sample(i, d) >> (32 - m));
      EXPECT_EQ(strata.size(), n) << "dim " << d << " m " << m;
    }
    std::vector<vec2> pts;
    for (uint32_t i = 0; i < n; ++i)
      pts.push_back({float(sobol_sample(i, 0) >> 8) * 0x1p-24f, float(sobol_sample(i, 1) >> 8) * 0x1p-24f});
    std::string why;
    EXPECT_TRUE(is_02_net(pts, m, &why)) << why;
  }
}

TEST(Sobol, NestedUniformScrambleIsAnOwenScramble) {
  // A bijection that maps values sharing their top j bits to values sharing
  // their top j bits (the scramble of a digit depends only on the digits above).
  for (uint32_t seed : {0u, 1u, 0xdeadbeefu}) {
    std::set<uint32_t> images;
    for (uint32_t k = 0; k < (1u << 12); ++k) images.insert(nested_uniform_scramble(k << 20, seed) >> 20);
    EXPECT_EQ(images.size(), 1u << 12);
    for (uint32_t x : {0x12345678u, 0xfedcba98u, 0x80000001u})
      for (int j = 1; j < 32; ++j) {
        uint32_t y = x ^ (1u << (31 - j));  // differs first at bit j from the top
        uint32_t sx = nested_uniform_scramble(x, seed), sy = nested_uniform_scramble(y, seed);
        EXPECT_EQ(sx >> (32 - j), sy >> (32 - j));
        EXPECT_NE((sx >> (31 - j)) & 1u, (sy >> (31 - j)) & 1u);
      }
  }
}

// The camera stage hashes a pixel's film pair once and draws all its samples
// from it: every draw must be sample_1d's pair, bit for bit, whatever sample
// the key the pair was made from names.
TEST(Sampler, APairSamplerDrawsEverySampleOfItsPixel) {
  for (uint32_t dim : {0u, 2u, 10u}) {
    const PairSampler pair(SamplerKey{9, 4321, 77}, dim);
    for (uint32_t i = 0; i < 300; ++i) {
      const SamplerKey key{9, 4321, i};
      const vec2 u = pair(i);
      EXPECT_EQ(std::bit_cast<uint32_t>(u.x), std::bit_cast<uint32_t>(sample_1d(key, dim))) << dim << " " << i;
      EXPECT_EQ(std::bit_cast<uint32_t>(u.y), std::bit_cast<uint32_t>(sample_1d(key, dim + 1))) << dim << " " << i;
    }
  }
}

// A path vertex draws its continuation's four dimensions at once, and the
// shading stage draws a chunk of vertices' fours in vector lanes: each number
// must be sample_1d's, bit for bit, wherever a path's dimensions lie (the
// bounce pages start at 4 + 8 depth; page 1 lies 2^24 further), for keys of
// every size and blocks of every length around the lane count.
TEST(Sampler, FourDimensionsAtOnceAreEachDimensionBitForBit) {
  const uint32_t seeds[] = {0u, 1u, 7u, 0xffffffffu};
  const uint32_t firsts[] = {0u, 4u, 8u, 20u, 132u, (1u << 24) + 4u, (1u << 24) + 62u, 0xfffffffcu};
  std::vector<SamplerKey> keys;
  std::vector<uint32_t> first;
  for (uint32_t seed : seeds)
    for (uint32_t i = 0; i < 2000; ++i) {
      keys.push_back({seed, uint32_t(hash(i, 1u)), i < 1000 ? i : uint32_t(hash(i, 2u))});
      first.push_back(firsts[hash(i, seed) % std::size(firsts)]);
    }
  auto expect_each_dimension = [&](const vec4& u, size_t k) {
    for (int d = 0; d < 4; ++d)
      ASSERT_EQ(std::bit_cast<uint32_t>(u[d]), std::bit_cast<uint32_t>(sample_1d(keys[k], first[k] + uint32_t(d))))
          << keys[k].seed << " " << keys[k].pixel << " " << keys[k].sample << " " << first[k] << " " << d;
  };
  for (size_t k = 0; k < keys.size(); ++k) expect_each_dimension(sample_4d(keys[k], first[k]), k);
  std::vector<vec4> out(keys.size());
  sample_4d(keys, first, out);
  for (size_t k = 0; k < keys.size(); ++k) expect_each_dimension(out[k], k);
  for (size_t length = 1; length <= 40; ++length) {
    const size_t start = 3 * length;
    std::vector<vec4> block(length);
    sample_4d(std::span(keys).subspan(start, length), std::span(first).subspan(start, length), block);
    for (size_t k = 0; k < length; ++k) expect_each_dimension(block[k], start + k);
  }
}

TEST(Sampler, IsAPureFunctionOfItsKey) {
  for (uint32_t dim : {0u, 1u, 2u, 7u, 40u}) {
    SamplerKey key{3, 1234, 17};
    float a = sample_1d(key, dim), b = sample_1d(key, dim);
    EXPECT_EQ(std::bit_cast<uint32_t>(a), std::bit_cast<uint32_t>(b));
    // 1D and 2D access agree, so a consumer may use either.
    EXPECT_EQ(a, sample_2d(key, dim & ~1u)[int(dim & 1u)]);
    EXPECT_EQ(sample_2d(key, dim).y, sample_1d(key, dim + 1));
  }
  auto sequence = [](SamplerKey key, uint32_t dim) {
    std::vector<float> s;
    for (uint32_t i = 0; i < 64; ++i) s.push_back(sample_1d({key.seed, key.pixel, i}, dim));
    return s;
  };
  auto base = sequence({1, 10, 0}, 4);
  EXPECT_NE(base, sequence({2, 10, 0}, 4));
  EXPECT_NE(base, sequence({1, 11, 0}, 4));
  EXPECT_NE(base, sequence({1, 10, 0}, 6));
  EXPECT_NE(base, sequence({1, 10, 0}, 5));
}

// The sampler's definition spelled out from its building blocks: the pair's
// three seeds from hash(seed, pixel, pair), the sample index shuffled by a
// nested-uniform scramble, and the Sobol point of the pair's dimension
// scrambled by its own seed.  sample_1d/2d fold reversals into tables and
// share work between components; their values must be these, bit for bit.
static float reference_sample(const SamplerKey& key, uint32_t dim) {
  uint64_t h = hash(key.seed, key.pixel, dim >> 1);
  uint64_t h2 = (h ^ (h >> 29)) * 0xbf58476d1ce4e5b9ull;
  uint32_t scramble = (dim & 1u) ? uint32_t(h2 >> 32) : uint32_t(h >> 32);
  uint32_t index = nested_uniform_scramble(key.sample, uint32_t(h));
  return std::min(to_unit_float(nested_uniform_scramble(sobol_sample(index, dim & 1u), scramble)), 0x1.fffffep-1f);
}

TEST(Sampler, EqualsItsDefinitionBitForBit) {
  uint64_t mismatches = 0, checked = 0;
  for (uint32_t seed : {0u, 7u, 0xdeadbeefu})
    for (uint32_t pixel : {0u, 1u, 4095u, 123457u})
      for (uint32_t sample = 0; sample < 300; ++sample)
        for (uint32_t dim = 0; dim < 24; ++dim) {
          // Small indices (the ones renders use) and indices spread over all 32 bits.
          SamplerKey key{seed, pixel, sample < 150 ? sample : sample * 0x9e3779b1u};
          float want = reference_sample(key, dim);
          vec2 pair = sample_2d(key, dim);
          mismatches += std::bit_cast<uint32_t>(sample_1d(key, dim)) != std::bit_cast<uint32_t>(want);
          mismatches += std::bit_cast<uint32_t>(pair.x) != std::bit_cast<uint32_t>(want);
          mismatches += std::bit_cast<uint32_t>(pair.y) != std::bit_cast<uint32_t>(reference_sample(key, dim + 1));
          checked += 3;
        }
  EXPECT_EQ(mismatches, 0u) << "of " << checked;
}

TEST(Sampler, ValuesLieInTheUnitInterval) {
  for (uint32_t seed : {0u, 0xffffffffu})
    for (uint32_t pixel : {0u, 77u, 0xffffffffu})
      for (uint32_t sample : {0u, 1u, 1000u, 0x7fffffffu, 0xffffffffu})
        for (uint32_t dim = 0; dim < 64; ++dim) {
          float v = sample_1d({seed, pixel, sample}, dim);
          EXPECT_GE(v, 0.0f);
          EXPECT_LT(v, 1.0f);
        }
}

TEST(Sampler, EveryPrefixOfEveryPairIsA02Net) {
  for (uint32_t pixel : {0u, 5u, 99999u})
    for (uint32_t dim : {0u, 2u, 10u, 62u}) {
      std::vector<vec2> all = pixel_pairs({42, pixel, 0}, dim, 1 << 12);
      for (int m = 0; m <= 12; ++m) {
        std::vector<vec2> prefix(all.begin(), all.begin() + (size_t(1) << m));
        std::string why;
        EXPECT_TRUE(is_02_net(prefix, m, &why)) << "pixel " << pixel << " dim " << dim << ": " << why;
      }
    }
}

TEST(Sampler, MeanConvergesFasterThanMonteCarlo) {
  // For f(x) = x, independent samples give an RMS error of 1 / sqrt(12 N);
  // a scrambled net has one point per 1/N stratum, so about 1 / (sqrt(12) N^1.5).
  auto rms_error = [](int n) {
    double sum_sq = 0;
    const int pixels = 64;
    for (uint32_t pixel = 0; pixel < pixels; ++pixel) {
      double mean = 0;
      for (int i = 0; i < n; ++i) mean += sample_1d({9, pixel, uint32_t(i)}, 3);
      sum_sq += sqr(float(mean / n - 0.5));
    }
    return std::sqrt(sum_sq / pixels);
  };
  double e64 = rms_error(64), e1024 = rms_error(1024);
  EXPECT_LT(e64, 0.1 / std::sqrt(12.0 * 64));
  EXPECT_LT(e1024, 0.1 / std::sqrt(12.0 * 1024));
  // 16 times the samples: Monte Carlo gains a factor 4, the net about 64.
  EXPECT_LT(e1024, e64 / 16.0);
}

TEST(Sampler, PairsAndPixelsAreUncorrelated) {
  const int n = 4096;
  auto values = [&](uint32_t pixel, uint32_t dim) {
    std::vector<double> v;
    for (int i = 0; i < n; ++i) v.push_back(sample_1d({5, pixel, uint32_t(i)}, dim));
    return v;
  };
  // 4 / sqrt(N) is four standard deviations of the correlation of independent samples.
  double bound = 4.0 / std::sqrt(double(n));
  EXPECT_LT(std::abs(correlation(values(7, 0), values(7, 2))), bound);
  EXPECT_LT(std::abs(correlation(values(7, 1), values(7, 3))), bound);
  EXPECT_LT(std::abs(correlation(values(7, 0), values(7, 31))), bound);
  EXPECT_LT(std::abs(correlation(values(7, 0), values(8, 0))), bound);

  // The joint distribution of dims 0 and 2 is uniform: an 8x8 histogram passes chi-square.
  std::vector<double> a = values(7, 0), b = values(7, 2);
  std::vector<int> hist(64, 0);
  for (int i = 0; i < n; ++i) ++hist[size_t(int(a[size_t(i)] * 8) * 8 + int(b[size_t(i)] * 8))];
  double stat = 0, expected = n / 64.0;
  for (int h : hist) stat += sqr(float(h - expected)) / expected;
  EXPECT_GT(boost::math::gamma_q(63 / 2.0, stat / 2.0), 0.001) << "chi-square " << stat;
}
