// The LightSampler interface's feedback defaults (core/light_sampler.h): the
// baseline samplers learn nothing, so the engine reports no shadow ray to
// them, and a report or an update leaves what they sample unchanged.  With
// one light that is not an area light, their choice does not depend on u.
#include "cachepoints/light_sampler.h"
#include "tests/unit/light_fixture.h"
#include "wavefront/sample_dims.h"

#include <gtest/gtest.h>

#include <bit>
#include <string>

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

// The engine draws no NEE light_choice pair where it decides nothing
// (wavefront/sample_dims.h light_choice_fixed): with one light that is not
// an area light, every sampler light_choice_fixed lets through must return
// the same choice, pmf and primitive for every u, at every shading point.
TEST(LightSamplerFeedback, OneLightChoiceIgnoresU) {
  const char* lights[] = {
      "LightSource \"infinite\" \"rgb L\" [0.5 0.6 0.7]\n",
      "LightSource \"point\" \"rgb I\" [2 2 2] \"point3 from\" [0 3 0]\n",
      "LightSource \"spot\" \"rgb I\" [5 5 5] \"point3 from\" [0 3 0] \"point3 to\" [0 0 0] \"float coneangle\" [20]\n",
      "LightSource \"distant\" \"rgb L\" [1 1 1] \"point3 from\" [1 3 1] \"point3 to\" [0 0 0]\n",
  };
  const char* floor =
      "Shape \"trianglemesh\" \"point3 P\" [-5 0 -5 5 0 -5 5 0 5 -5 0 5] \"integer indices\" [0 1 2 0 2 3]\n";
  const LightSampleContext contexts[] = {
      {vec3(0.0f), vec3(0.0f), vec3(0, 1, 0), vec3(0, 1, 0)},
      {vec3(2.0f, 0.0f, -3.0f), vec3(0.0f), vec3(0, 1, 0), vec3(0, 1, 0)},
      {vec3(1.0f, 5.0f, 1.0f), vec3(0.0f), vec3(0, -1, 0), vec3(0, -1, 0)},  // above the point light
      {vec3(0.5f, 1.0f, 0.0f), vec3(0.0f), vec3(0.0f), vec3(0.0f)},            // not on a surface
  };
  int fixed = 0;
  for (const char* light : lights) {
    test::LightFixture f(std::string("WorldBegin\n") + light + floor);
    ASSERT_EQ(f.scene.lights.size(), 1u);
    for (const char* name : {"uniform", "power", "bvh", "cachepoints", "local", "auto"}) {
      auto sampler = make_light_sampler(name, f.lights, f.accel);
      if (!light_choice_fixed(f.scene, sampler->wants_feedback(), sampler->chooses_primitives())) continue;
      ++fixed;
      for (const LightSampleContext& ctx : contexts) {
        const auto ref = sampler->sample(ctx, 0.5f);
        for (float u : {0.0f, 1e-7f, 0.25f, 0.5f, 0.75f, 0.99f, kOneMinusEpsilon}) {
          const auto s = sampler->sample(ctx, u);
          ASSERT_EQ(s.has_value(), ref.has_value()) << name << " " << light << " u " << u;
          if (!s) continue;
          EXPECT_EQ(s->light, ref->light) << name << " " << light;
          EXPECT_EQ(std::bit_cast<uint32_t>(s->pmf), std::bit_cast<uint32_t>(ref->pmf)) << name << " " << light;
          EXPECT_EQ(s->primitive, ref->primitive) << name << " " << light;
        }
      }
    }
  }
  EXPECT_GE(fixed, 12);  // at least uniform, power and bvh for each light
}
