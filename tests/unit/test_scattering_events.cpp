// Scattering-event labels (seeds/000 ch. 1 section 6): a direction that a
// guide or light sampling chose is labelled as BSDF sampling labels it.
// For every BxDF kind, each non-delta BSDF sample's kind (diffuse or glossy)
// is bsdf_nondelta_kind, which labels NEE directions; for the guidable
// kinds, bsdf_event (what a guided direction gets) reports that kind too.
#include "scene/bsdf.h"
#include "scene/hair.h"

#include "core/hash.h"
#include "core/sampling.h"
#include "tests/unit/bxdf_test_util.h"

#include <gtest/gtest.h>

using namespace theia;
using namespace theia::test;

namespace {

vec2 u2(uint64_t h) { return {to_unit_float(uint32_t(h)), to_unit_float(uint32_t(h >> 32))}; }

uint8_t kind(uint8_t flags) { return flags & (kLobeDiffuse | kLobeGlossy | kLobeSpecular); }

struct Case {
  std::string name;
  BxDF bxdf;
  uint8_t expected;  // bsdf_nondelta_kind
};

std::vector<Case> every_kind() {
  return {{"diffuse", diffuse(RGB(0.8f)), kLobeDiffuse},
          {"rough conductor", conductor(0.3f, 0.3f), kLobeGlossy},
          {"rough dielectric", dielectric(0.4f, 1.5f), kLobeGlossy},
          {"diffuse transmission", diffuse_transmission(RGB(0.4f), RGB(0.5f)), kLobeDiffuse},
          // A smooth coat: specular reflections and glossy walk exits.
          {"coated diffuse, smooth coat", coated_diffuse(0.0f, RGB(0.6f), RGB(0.3f)), kLobeGlossy},
          {"coated diffuse, rough coat", coated_diffuse(0.3f, RGB(0.6f)), kLobeGlossy},
          {"coated conductor", coated_conductor(0.0f, 0.2f), kLobeGlossy},
          {"hair", make_hair_bxdf(0.3f, 1.55f, RGB(0.5f, 0.8f, 1.2f), 0.3f, 0.3f, 2.0f), kLobeGlossy},
          // Only delta lobes: no direction of theirs is ever labelled this way
          // (no NEE, no guide), the function still answers.
          {"mirror", conductor(0.0f, 0.0f), kLobeDiffuse},
          {"thin dielectric", ThinDielectricBxDF{1.5f}, kLobeDiffuse}};
}

}  // namespace

TEST(ScatteringEvents, NonDeltaSamplesHaveTheKindThatLabelsLightAndGuideDirections) {
  const Frame frame = Frame::from_z(vec3(0.0f, 0.0f, 1.0f));
  for (const Case& c : every_kind()) {
    SCOPED_TRACE(c.name);
    const BSDF b = bsdf_from(c.bxdf, frame, frame.n);
    EXPECT_EQ(bsdf_nondelta_kind(b), c.expected);
    const bool guidable = bsdf_is_guidable(b, 0.0f);
    int non_delta = 0, events = 0;
    for (uint64_t i = 0; i < 4000; ++i) {
      const uint64_t h = hash(i, 77);
      // Incident directions over both hemispheres (transmission from below).
      vec3 wo = sample_uniform_sphere(u2(hash(h, 1)));
      if (std::abs(wo.z) < 0.05f) continue;
      auto s = bsdf_sample(b, wo, to_unit_float(uint32_t(hash(h, 2))), u2(hash(h, 3)));
      if (!s || s->is_specular()) continue;
      ++non_delta;
      ASSERT_EQ(kind(s->flags), c.expected) << "sample " << i;
      if (!guidable) continue;
      auto e = bsdf_event(b, wo, s->wi);
      if (!e) continue;
      ++events;
      // The lobe a guided direction is given: the sample's, kind and side.
      ASSERT_EQ(kind(e->flags), kind(s->flags)) << "sample " << i;
      ASSERT_EQ(e->flags & (kLobeReflection | kLobeTransmission), s->flags & (kLobeReflection | kLobeTransmission));
    }
    const bool has_non_delta = c.name != "mirror" && c.name != "thin dielectric";
    if (has_non_delta) { EXPECT_GT(non_delta, 1000); }
    if (guidable) { EXPECT_GT(events, 1000); }
  }
}
