// The caustic pass's float estimate of a sphere light's first ray
// (wavefront/caustic_first_ray.h) drops a light path before sample_le only
// when the exact ray, tested as the pass tests it (may_meet on emitted_ray),
// misses every caster box too: otherwise the pass would lose caustic paths
// and its image would change.  Held over many random samples against boxes
// around the light, boxes that hug the sphere, and boxes built to graze the
// exact ray (a corner on it, or just off it), for spheres from tiny to huge,
// moved far from the origin, scaled unevenly, mirrored, two-sided and cut.
#include "core/math.h"
#include "scene/accel.h"
#include "scene/lights.h"
#include "scene/parser.h"
#include "wavefront/caustic_first_ray.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

using namespace theia;
using namespace theia::caustic_first_ray;

namespace {

struct SphereCase {
  std::string name, transform, light, shape;
};

// u in [0, 1): uniform, or pushed to an end of the square, where the cosine
// direction grazes the sphere and the (z, phi) point nears a pole or a cut.
float sample_u(std::mt19937& rng) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float x = u(rng);
  switch (rng() % 4) {
    case 0: return std::min(1.0f - std::ldexp(u(rng), -int(rng() % 24)), kOneMinusEpsilon);
    case 1: return std::ldexp(u(rng), -int(rng() % 24));
    default: return x;
  }
}

// Boxes around the light: random ones from just off its surface to far away,
// and thin slabs tangent to it (rays leaving near the tangent point graze them).
std::vector<Bounds3> boxes_around(std::mt19937& rng, vec3 centre, float size) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f), e(0.0f, 1.0f);
  std::vector<Bounds3> boxes;
  for (int i = 0; i < 24; ++i) {
    const vec3 dir = glm::normalize(vec3(u(rng), u(rng), u(rng)));
    const float dist = size * std::pow(10.0f, 0.2f + 2.5f * e(rng));
    const vec3 half = size * std::pow(10.0f, 2.0f * u(rng)) * vec3(e(rng), e(rng), e(rng)) + vec3(1e-6f * size);
    const vec3 c = centre + dist * dir;
    boxes.emplace_back(c - half, c + half);
  }
  for (int a = 0; a < 3; ++a)
    for (float s : {-1.0f, 1.0f}) {
      vec3 lo = centre - vec3(3.0f * size), hi = centre + vec3(3.0f * size);
      // A slab just beyond the sphere's extent (size bounds it) along axis a.
      const float face = centre[a] + s * size * 1.0001f;
      lo[a] = s > 0 ? face : face - 0.01f * size;
      hi[a] = s > 0 ? face + 0.01f * size : face;
      boxes.emplace_back(lo, hi);
    }
  return boxes;
}

// A box with a corner at distance t along the ray, shifted across it by
// `off` (relative to t): the exact ray only just meets it or only just misses.
Bounds3 grazing_box(const Ray& ray, float t, float off, float extent, std::mt19937& rng) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  const vec3 q = ray.o + t * ray.d + off * t * glm::normalize(vec3(u(rng), u(rng), u(rng)));
  vec3 lo = q, hi = q;
  for (int a = 0; a < 3; ++a) {
    if (rng() % 2) hi[a] += extent;
    else lo[a] -= extent;
  }
  return Bounds3(lo, hi);
}

}  // namespace

TEST(CausticFirstRay, EveryDroppedSphereSampleMissesEveryBoxExactly) {
  const std::vector<SphereCase> cases = {
      {"unit", "", "", R"("float radius" 1)"},
      {"tiny far", "Translate 300 -120 45", "", R"("float radius" 0.001)"},
      {"huge", "Translate 10 20 -5", "", R"("float radius" 1000)"},
      {"uneven", "Translate 1 2 3 Rotate 37 1 2 0.5 Scale 3 0.5 1.5", "", R"("float radius" 0.7)"},
      {"mirrored two-sided", "Translate -4 0 2 Scale -1 1 1", R"("bool twosided" true)", R"("float radius" 0.3)"},
      {"reversed cut", "ReverseOrientation Rotate 80 0 1 0",
       "", R"("float radius" 2 "float zmin" -1.2 "float zmax" 1.5 "float phimax" 250)"},
      {"cut two-sided far", "Translate 5000 0 -3000 Rotate 120 1 1 0", R"("bool twosided" true)",
       R"("float radius" 5 "float zmin" 0 "float phimax" 300)"},
  };
  std::mt19937 rng(1234);
  for (const SphereCase& c : cases) {
    const std::string text = fmt::format(
        "WorldBegin\nAttributeBegin\n{}\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1] {}\nShape \"sphere\" {}\n"
        "AttributeEnd\n",
        c.transform, c.light, c.shape);
    Scene scene = parse_scene_string(text, "caustic-first-ray.pbrt", ".");
    Accel accel(scene);
    LightSet lights(scene, accel);
    ASSERT_EQ(scene.lights.size(), 1u) << c.name;
    const SphereEmitter probe = sphere_emitter(scene, 0, {Bounds3(vec3(0.0f))});
    ASSERT_TRUE(probe.valid) << c.name;
    const vec3 centre = vec3(probe.render_from_object * vec4(0.0f, 0.0f, 0.0f, 1.0f));
    const std::vector<Bounds3> boxes = boxes_around(rng, centre, probe.size);
    // The estimate against each box alone, and against all of them (as the pass asks).
    std::vector<SphereEmitter> alone;
    for (const Bounds3& b : boxes) alone.push_back(sphere_emitter(scene, 0, {b}));
    const SphereEmitter all = sphere_emitter(scene, 0, boxes);
    const float size = probe.size;

    size_t dropped = 0, sampled = 0, grazing_met = 0, grazing_missed = 0;
    for (int i = 0; i < 40000; ++i) {
      const vec2 u_pos(sample_u(rng), sample_u(rng)), u_dir(sample_u(rng), sample_u(rng));
      const auto le = sample_le(lights, 0, u_pos, 0.5f, u_dir);
      if (!le) continue;
      ++sampled;
      const Ray exact = emitted_ray(*le);
      for (size_t b = 0; b < boxes.size(); ++b)
        if (!sphere_ray_may_meet(alone[b], u_pos, u_dir)) {
          ++dropped;
          ASSERT_FALSE(may_meet(exact, boxes[b])) << c.name << " u_pos " << u_pos.x << ' ' << u_pos.y << " u_dir "
                                                  << u_dir.x << ' ' << u_dir.y;
        }
      if (!sphere_ray_may_meet(all, u_pos, u_dir)) {
        for (const Bounds3& b : boxes) ASSERT_FALSE(may_meet(exact, b)) << c.name;
      }
      // Boxes that the exact ray only just meets or misses, near and far.
      std::uniform_real_distribution<float> u01(0.0f, 1.0f);
      const float t = size * std::pow(10.0f, 4.0f * u01(rng) - 1.0f);
      const float off = (rng() % 2 ? 1.0f : -1.0f) * std::pow(10.0f, -7.0f + 5.0f * u01(rng));
      const Bounds3 g = grazing_box(exact, t, rng() % 3 == 0 ? 0.0f : off, size * std::pow(10.0f, 3.0f * u01(rng) - 2.0f), rng);
      if (may_meet(exact, g)) {
        ++grazing_met;
        ASSERT_TRUE(sphere_ray_may_meet(sphere_emitter(scene, 0, {g}), u_pos, u_dir)) << c.name << " grazing box at t " << t;
      } else {
        ++grazing_missed;
      }
    }
    // The test is not empty: the estimate drops many samples and the grazing boxes go both ways.
    EXPECT_GT(sampled, 30000u) << c.name;
    EXPECT_GT(dropped, sampled) << c.name;
    EXPECT_GT(grazing_met, 5000u) << c.name;
    EXPECT_GT(grazing_missed, 5000u) << c.name;
  }
}
