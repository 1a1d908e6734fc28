#include "core/hash.h"
#include "core/math.h"
#include "core/sampling.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <limits>
#include <vector>

using namespace theia;

TEST(Frame, IsOrthonormalForAnyNormal) {
  for (vec3 n : {vec3(0, 0, 1), vec3(0, 0, -1), vec3(1, 0, 0), glm::normalize(vec3(1, -2, 3)),
                 glm::normalize(vec3(-1e-7f, 1e-7f, -1.0f))}) {
    Frame f = Frame::from_z(n);
    EXPECT_NEAR(glm::dot(f.s, f.t), 0.0f, 1e-6f);
    EXPECT_NEAR(glm::dot(f.s, f.n), 0.0f, 1e-6f);
    EXPECT_NEAR(glm::length(f.s), 1.0f, 1e-6f);
    EXPECT_NEAR(glm::length(f.t), 1.0f, 1e-6f);
    vec3 v = glm::normalize(vec3(0.3f, -0.4f, 0.5f));
    vec3 back = f.from_local(f.to_local(v));
    EXPECT_NEAR(glm::length(back - v), 0.0f, 1e-6f);
  }
}

// Bit-for-bit std::nextafter towards +-infinity: zeros of both signs,
// denormals, the largest finite floats, infinities, and random bit patterns.
TEST(NextFloat, EqualsNextafterForEveryKindOfFloat) {
  auto same = [](float a, float b) { return std::bit_cast<uint32_t>(a) == std::bit_cast<uint32_t>(b); };
  std::vector<float> values = {0.0f, -0.0f, std::numeric_limits<float>::denorm_min(),
                               -std::numeric_limits<float>::denorm_min(), std::numeric_limits<float>::min(),
                               -std::numeric_limits<float>::min(), std::numeric_limits<float>::max(),
                               -std::numeric_limits<float>::max(), kInfinity, -kInfinity, 1.0f, -1.0f, 0.5f, -3.25f};
  uint32_t x = 12345u;
  for (int i = 0; i < 100000; ++i) {
    x = x * 1664525u + 1013904223u;
    float v = std::bit_cast<float>(x);
    if (!std::isnan(v)) values.push_back(v);
  }
  for (float v : values) {
    EXPECT_TRUE(same(next_float_up(v), std::nextafter(v, kInfinity))) << v;
    EXPECT_TRUE(same(next_float_down(v), std::nextafter(v, -kInfinity))) << v;
  }
  EXPECT_TRUE(std::isnan(next_float_up(std::numeric_limits<float>::quiet_NaN())));
  EXPECT_TRUE(std::isnan(next_float_down(std::numeric_limits<float>::quiet_NaN())));
}

// The branch-free step toward a side is the two steps above, chosen by the
// side's sign, and no step at all for a side of 0 or NaN.
TEST(NextFloat, TowardASideIsUpOrDownOrNothing) {
  auto same = [](float a, float b) { return std::bit_cast<uint32_t>(a) == std::bit_cast<uint32_t>(b); };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<float> values = {0.0f, -0.0f, std::numeric_limits<float>::denorm_min(),
                               -std::numeric_limits<float>::denorm_min(), std::numeric_limits<float>::max(),
                               -std::numeric_limits<float>::max(), kInfinity, -kInfinity, nan, -nan, 1.0f, -3.25f};
  uint32_t x = 54321u;
  for (int i = 0; i < 100000; ++i) {
    x = x * 1664525u + 1013904223u;
    values.push_back(std::bit_cast<float>(x));  // NaNs of every payload included
  }
  for (float v : values)
    for (float side : {1.0f, 1e-30f, kInfinity, -1.0f, -1e-30f, -kInfinity, 0.0f, -0.0f, nan}) {
      const float want = side > 0.0f ? next_float_up(v) : side < 0.0f ? next_float_down(v) : v;
      EXPECT_TRUE(same(next_float_toward(v, side), want)) << v << " " << side;
    }
}

// The warps' angles go through these polynomials rather than libm: they
// must agree with the exact functions to float precision everywhere, and
// give quarter turns exactly.
TEST(CosSin, TurnAndOctantAgreeWithTheExactFunctions) {
  double worst_turn = 0.0, worst_octant = 0.0;
  for (int i = -(1 << 21); i <= (1 << 21); ++i) {
    const float u = float(i) / float(1 << 20);  // [-2, 2] turns, quarter turns included
    const vec2 cs = cos_sin_turn(u);
    const double phi = 2.0 * 3.14159265358979323846 * double(u);
    worst_turn = std::max({worst_turn, std::abs(double(cs.x) - std::cos(phi)), std::abs(double(cs.y) - std::sin(phi))});
    const float a = float(i) / float(1 << 21) * (kPi / 4.0f);  // [-pi/4, pi/4]
    const vec2 co = cos_sin_octant(a);
    worst_octant = std::max({worst_octant, std::abs(double(co.x) - std::cos(double(a))),
                             std::abs(double(co.y) - std::sin(double(a)))});
  }
  // A float ulp near 1 is 6e-8 (libm's sincosf is within one): two or three.
  EXPECT_LT(worst_turn, 1.8e-7);
  EXPECT_LT(worst_octant, 1.2e-7);
  EXPECT_EQ(cos_sin_turn(0.0f), vec2(1.0f, 0.0f));
  EXPECT_EQ(cos_sin_turn(0.25f), vec2(0.0f, 1.0f));
  EXPECT_EQ(cos_sin_turn(0.5f), vec2(-1.0f, 0.0f));
  EXPECT_EQ(cos_sin_turn(0.75f), vec2(0.0f, -1.0f));
  EXPECT_EQ(cos_sin_turn(-0.25f), vec2(0.0f, -1.0f));
}

TEST(Transform, NormalsStayPerpendicularUnderNonUniformScale) {
  Transform t(glm::mat4(glm::vec4(2, 0, 0, 0), glm::vec4(0, 1, 0, 0), glm::vec4(0, 0, 0.5f, 0), glm::vec4(1, 2, 3, 1)));
  vec3 tangent(1, 1, 0), n(1, -1, 0);
  EXPECT_NEAR(glm::dot(t.vector(tangent), t.normal(n)), 0.0f, 1e-6f);
  EXPECT_NEAR(glm::length(t.inverse().point(t.point(vec3(4, 5, 6))) - vec3(4, 5, 6)), 0.0f, 1e-5f);
  EXPECT_FALSE(t.swaps_handedness());
}

TEST(Distribution1D, DiscretePmfMatchesWeights) {
  std::vector<float> w{1, 0, 3, 4};
  Distribution1D d(w);
  EXPECT_NEAR(d.discrete_pmf(0), 1.0f / 8, 1e-6f);
  EXPECT_EQ(d.discrete_pmf(1), 0.0f);
  float pmf;
  EXPECT_EQ(d.sample_discrete(0.2f, &pmf), 2);
  EXPECT_NEAR(pmf, 3.0f / 8, 1e-6f);
  // A zero-width cell is never chosen, even at its cdf boundary.
  EXPECT_NE(d.sample_discrete(0.125f), 1);
}

// The guide table only narrows the search: the cell is the whole cdf's
// upper bound for every u, at slice edges, on zero-weight runs, out of range.
TEST(Distribution1D, GuidedLookupFindsTheCellAFullSearchFinds) {
  uint32_t x = 7u;
  auto next = [&x] { return x = x * 1664525u + 1013904223u; };
  for (int n : {1, 2, 3, 7, 48, 63, 64, 65, 200, 1000}) {
    std::vector<float> f(static_cast<size_t>(n));
    for (float& v : f) v = next() % 3 == 0 ? 0.0f : float(next() % 1000) * (next() % 7 == 0 ? 1e-6f : 1.0f);
    Distribution1D d(f);
    std::vector<float> us = {0.0f, -0.0f, -1e-9f, 1.0f, 2.0f, kOneMinusEpsilon, std::numeric_limits<float>::quiet_NaN()};
    for (size_t k = 0; k <= 2 * Distribution1D::kGuideBuckets; ++k) {
      float edge = float(k) / float(Distribution1D::kGuideBuckets);
      us.insert(us.end(), {edge, std::nextafter(edge, 0.0f), std::nextafter(edge, 1.0f)});
    }
    for (float c : d.cdf) us.insert(us.end(), {c, std::nextafter(c, 0.0f), std::nextafter(c, 1.0f)});
    for (int i = 0; i < 20000; ++i) us.push_back(to_unit_float(next()));
    for (float u : us) {
      int full = int(std::upper_bound(d.cdf.begin(), d.cdf.end(), u) - d.cdf.begin()) - 1;
      EXPECT_EQ(d.find_interval(u), std::clamp(full, 0, n - 1)) << "n " << n << " u " << u;
    }
  }
}

TEST(Distribution1D, AllZeroFallsBackToUniform) {
  std::vector<float> w{0, 0, 0, 0};
  Distribution1D d(w);
  EXPECT_NEAR(d.discrete_pmf(3), 0.25f, 1e-6f);
  float pdf;
  float x = d.sample_continuous(0.6f, &pdf);
  EXPECT_NEAR(x, 0.6f, 1e-6f);
  EXPECT_EQ(pdf, 1.0f);
}

#include "core/color.h"

TEST(WorkingColorSpace, RoundTripsGreysAndKeepsTheSrgbGamutNonNegative) {
  for (RGB c : {RGB(1, 0, 0), RGB(0, 1, 0), RGB(0, 0, 1), RGB(0.63f, 0.065f, 0.05f), RGB(17, 12, 4)}) {
    RGB w = srgb_to_working(c);
    EXPECT_GE(std::min({w.x, w.y, w.z}), 0.0f);
    EXPECT_NEAR(glm::length(working_to_srgb(w) - c), 0.0f, 2e-5f * std::max(1.0f, glm::length(c)));
    // Luminance is a property of the colour, not of the space it is written in.
    EXPECT_NEAR(luminance(w), 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z, 2e-4f * std::max(1.0f, c.x + c.y + c.z));
  }
  RGB g = srgb_to_working(RGB(0.5f));
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(g[i], 0.5f, 1e-6f);
}
