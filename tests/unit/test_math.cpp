#include "core/math.h"
#include "core/sampling.h"

#include <gtest/gtest.h>

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
