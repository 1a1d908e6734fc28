// What the light-sampler unit tests share: a parsed scene with its lights
// (street_scene.h's streets), and radiance patterns for the street's quads.
#pragma once

#include "core/hash.h"
#include "scene/accel.h"
#include "scene/lights.h"
#include "scene/parser.h"

#include <cmath>
#include <string>

namespace theia::test {

// Radiances over three decades, and a pattern with every third quad black.
inline float varied(int k) { return 0.3f * std::pow(10.0f, float(hash(uint64_t(k)) % 1000) / 333.0f); }
inline float dark(int k) { return k % 3 == 0 ? 0.0f : 1.0f; }

struct LightFixture {
  Scene scene;
  Accel accel;
  LightSet lights;
  explicit LightFixture(const std::string& text)
      : scene(parse_scene_string(text, "<light-sampler-test>", ".")), accel(scene), lights(scene, accel) {}
};

}  // namespace theia::test
