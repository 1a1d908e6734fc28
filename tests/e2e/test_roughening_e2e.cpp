// Path-space regularisation end to end (--roughening, EngineOptions::roughening):
// the white furnace still holds, roughening changes only what follows a
// rough bounce, the image does not depend on thread count or batch size
// (guided or not), and the option refuses values outside [0, 1].
#include "core/log.h"
#include "render_helpers.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

using namespace theia;
using namespace theia::test;

namespace {

// A white diffuse sphere beside a smooth glass sphere and a perfect mirror
// sphere in a constant environment of radiance 1: nothing absorbs, so every
// pixel is 1.  Glass and mirror are seen after a diffuse bounce, where
// roughening makes them rough.
std::string furnace_scene(int resolution) {
  return "Film \"rgb\" \"integer xresolution\" [" + std::to_string(resolution) + "] \"integer yresolution\" [" +
         std::to_string(resolution) + R"(]
Integrator "volpath" "integer maxdepth" [64]
LookAt 0 0 -7  0 0 0  0 1 0
Camera "perspective" "float fov" [40]
WorldBegin
LightSource "infinite" "rgb L" [1 1 1]
AttributeBegin
  Material "diffuse" "rgb reflectance" [1 1 1]
  Translate -1.1 0 0
  Shape "sphere" "float radius" [1]
AttributeEnd
AttributeBegin
  Material "dielectric" "float eta" [1.5]
  Translate 1.1 0.6 0
  Shape "sphere" "float radius" [1]
AttributeEnd
AttributeBegin
  Material "conductor" "float roughness" [0] "rgb eta" [1 1 1] "rgb k" [10000 10000 10000]
  Translate 0.6 -1.4 -0.8
  Shape "sphere" "float radius" [0.6]
AttributeEnd
)";
}

RenderConfig roughening_config(int spp, float gamma) {
  RenderConfig c = quick_config(spp);
  c.roughening = gamma;
  c.caustics.enabled = false;
  return c;
}

}  // namespace

// Roughening makes lossless interfaces lossy at most (single-scattering
// microfacets), never brighter: the furnace stays at 1 or a little under.
TEST(RougheningE2E, WhiteFurnaceCreatesNoEnergy) {
  Scene scene = load_test_scene(furnace_scene(24));
  RenderResult plain = render_scene(scene, roughening_config(64, 0.0f));
  RenderResult rough = render_scene(scene, roughening_config(64, 0.5f));
  const RGB m0 = image_mean(plain.image), m1 = image_mean(rough.image);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(m0[c], 1.0f, 0.01f) << "channel " << c;
    EXPECT_LE(m1[c], 1.0f + 0.01f) << "channel " << c;
    EXPECT_GT(m1[c], 0.9f) << "channel " << c;
  }
  EXPECT_EQ(rough.log["dropped_samples"].get<uint64_t>(), 0u);
  // It did something: the glass and mirror seen in the diffuse sphere blur.
  EXPECT_GT(max_relative_difference(plain.image, rough.image), 1e-3);
}

// The camera ray's alpha' is 0 and a delta lobe hands on 0: a scene of
// smooth glass and mirrors alone, lit by the environment, is unchanged.
TEST(RougheningE2E, NothingChangesWithoutARoughBounce) {
  const std::string text = R"(Film "rgb" "integer xresolution" [16] "integer yresolution" [16]
Integrator "volpath" "integer maxdepth" [16]
LookAt 0 0 -5  0 0 0  0 1 0
Camera "perspective" "float fov" [30]
WorldBegin
LightSource "infinite" "rgb L" [0.5 0.7 1]
Material "dielectric" "float eta" [1.5]
Shape "sphere" "float radius" [1]
)";
  Scene scene = load_test_scene(text);
  // One thread: with two the film's sums depend on the order threads add
  // (1e-7), and the claim here is bit equality.
  RenderConfig plain = roughening_config(8, 0.0f), rough = roughening_config(8, 1.0f);
  plain.threads = rough.threads = 1;
  RenderResult a = render_scene(scene, plain);
  RenderResult b = render_scene(scene, rough);
  EXPECT_EQ(max_relative_difference(a.image, b.image), 0.0);
}

TEST(RougheningE2E, IndependentOfThreadsAndBatchSizeGuidedOrNot) {
  Scene scene = load_test_scene(mirror_room_scene(32, 24, 0.0f));
  for (bool guided : {false, true}) {
    RenderConfig a = roughening_config(16, 0.05f), b = roughening_config(16, 0.05f);
    a.guiding.enabled = b.guiding.enabled = guided ? OnOffAuto::On : OnOffAuto::Off;
    a.threads = 1;
    a.batch_size = 1024;
    a.max_paths = 4096;
    b.threads = 2;
    RenderResult ra = render_scene(scene, a), rb = render_scene(scene, b);
    EXPECT_LT(max_relative_difference(ra.image, rb.image), 1e-4) << (guided ? "guided" : "unguided");
    EXPECT_EQ(ra.log["options"]["roughening"].get<float>(), 0.05f);
  }
}

TEST(RougheningE2E, RefusesValuesOutsideZeroToOne) {
  for (float gamma : {1.5f, -0.1f, std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    RenderOptions o;
    o.roughening = gamma;
    EXPECT_THROW(check(o), Error) << gamma;
  }
  for (float gamma : {0.0f, 0.01f, 1.0f}) {
    RenderOptions o;
    o.roughening = gamma;
    EXPECT_NO_THROW(check(o)) << gamma;
  }
}
