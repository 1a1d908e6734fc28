// The LightSampler interface's feedback defaults (core/light_sampler.h): the
// baseline samplers learn nothing, so the engine reports no shadow ray to
// them, and a report or an update leaves what they sample unchanged.
#include "cachepoints/light_sampler.h"

#include <gtest/gtest.h>

using namespace theia;

TEST(LightSamplerFeedback, UniformSamplerLearnsNothing) {
  UniformLightSampler sampler(4);
  const LightSampler& s = sampler;
  EXPECT_FALSE(s.wants_feedback());
  LightSampleContext ctx;
  const float before = s.pmf(ctx, 2);
  for (int i = 0; i < 16; ++i) s.record_shadow(SampledLight{2, before}, false);
  sampler.update();
  EXPECT_EQ(s.pmf(ctx, 2), before);
  EXPECT_EQ(s.sample(ctx, 0.6f)->light, 2);
}
