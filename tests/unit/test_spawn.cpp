// Robust spawning: rays spawned from hits on far-away, tiny and axis-aligned
// quadrics and meshes never re-hit the point they leave, and rays to a
// light point are not blocked by either end.
#include "scene/accel.h"
#include "scene/shapes.h"
#include "scene/surface_crossing.h"
#include "tests/unit/scene_builders.h"
#include "tests/unit/trace_util.h"

#include <gtest/gtest.h>

#include <random>

using namespace theia;
using namespace theia::test;

namespace {

// Rays spawned from hits on `shape` never re-hit the point they leave: an
// outward ray off a convex surface hits nothing, an inward one only the far side.
void check_no_self_intersection(const Scene& sc, const Accel& a, vec3 center, float radius, int n) {
  std::mt19937 rng(11);
  int outward_hits = 0, inward_self = 0, primary_misses = 0;
  for (int i = 0; i < n; ++i) {
    vec3 o = center + 3.0f * radius * random_direction(rng);
    vec3 target = center + 0.95f * radius * random_direction(rng);
    Ray r = make_ray(o, target - o);
    Traced t = trace(sc, a, r);
    if (!t.hit.hit()) {
      ++primary_misses;
      continue;
    }
    vec3 n_out = t.si.ng;
    // Outward: any direction in the hemisphere of the outward normal.
    vec3 d = random_direction(rng);
    if (glm::dot(d, n_out) < 0.0f) d = -d;
    Ray out = spawn_ray(t.si, d);
    if (a.intersect1(out).hit()) ++outward_hits;
    // Inward: must reach the far side, a chord of at least ~0.3 radius away
    // for directions within 80 degrees of -n.
    vec3 din = random_direction(rng);
    if (glm::dot(din, n_out) > 0.0f) din = -din;
    if (glm::dot(din, -n_out) < 0.17f) din = glm::normalize(din - n_out);
    Ray in = spawn_ray(t.si, din);
    Traced back = trace(sc, a, in);
    if (!back.hit.hit() || glm::length(back.si.p - t.si.p) < 0.1f * radius) ++inward_self;
  }
  EXPECT_EQ(primary_misses, 0);
  EXPECT_EQ(outward_hits, 0);
  EXPECT_EQ(inward_self, 0);
}

}  // namespace

TEST(AccelSpawn, FarAwayAndTinySpheresDoNotSelfIntersect) {
  {
    Scene sc;
    vec3 c(1e5f, -1e5f, 1e5f);
    add_sphere(sc, {}, translate(c));
    Accel a(sc);
    check_no_self_intersection(sc, a, c, 1.0f, 4000);
  }
  {
    Scene sc;
    add_sphere(sc, {}, scale(vec3(1e5f)));
    Accel a(sc);
    check_no_self_intersection(sc, a, vec3(0), 1e5f, 4000);
  }
  {
    Scene sc;
    vec3 c(0.3f, 0.2f, 0.1f);
    add_sphere(sc, {}, translate(c) * scale(vec3(1e-4f)));
    Accel a(sc);
    check_no_self_intersection(sc, a, c, 1e-4f, 4000);
  }
  {
    // The same through an instance.
    Scene sc;
    int s = add_sphere(sc, {}, Transform{}, false, false);
    sc.prototypes.push_back({"ball", {s}});
    vec3 c(-3e4f, 2e4f, 5e4f);
    sc.instances.push_back({0, translate(c) * scale(vec3(7.0f))});
    Accel a(sc);
    check_no_self_intersection(sc, a, c, 7.0f, 4000);
  }
}

// Long enough that every ray check_no_self_intersection traces meets the
// side before an open end.
TEST(AccelSpawn, FarAwayAndTinyCylindersDoNotSelfIntersect) {
  const CylinderParams tall{1.0f, -1000.0f, 1000.0f, 360.0f};
  {
    Scene sc;
    vec3 c(1e5f, -1e5f, 1e5f);
    add_cylinder(sc, tall, translate(c) * rotate(30, vec3(1, 2, 0)));
    Accel a(sc);
    check_no_self_intersection(sc, a, c, 1.0f, 4000);
  }
  {
    Scene sc;
    vec3 c(0.3f, 0.2f, 0.1f);
    add_cylinder(sc, tall, translate(c) * scale(vec3(1e-4f)));
    Accel a(sc);
    check_no_self_intersection(sc, a, c, 1e-4f, 4000);
  }
}

TEST(AccelSpawn, FarAwayTriangleMeshDoesNotSelfIntersect) {
  vec3 c(1e5f, 2e5f, -1e5f);
  std::array<vec3, 4> p = {c + vec3(1, 1, 1), c + vec3(1, -1, -1), c + vec3(-1, 1, -1), c + vec3(-1, -1, 1)};
  TriangleMesh m = tetrahedron(p);
  Scene sc;
  add_mesh(sc, m);
  Accel a(sc);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  int bad = 0;
  for (int i = 0; i < 4000; ++i) {
    // A point well inside face f (the offset, ~0.1 here, must not carry the
    // origin past a neighbouring face), seen from its outer side.
    uint32_t f = uint32_t(i % 4);
    vec3 v0 = m.p[m.indices[3 * f]], v1 = m.p[m.indices[3 * f + 1]], v2 = m.p[m.indices[3 * f + 2]];
    float b1 = 0.2f + 0.3f * u(rng), b2 = 0.2f + 0.3f * u(rng) * (0.6f - b1) / 0.3f;
    vec3 target = (1.0f - b1 - b2) * v0 + b1 * v1 + b2 * v2;
    vec3 n_out = glm::normalize(glm::cross(v1 - v0, v2 - v0));
    if (glm::dot(n_out, target - c) < 0.0f) n_out = -n_out;
    vec3 d = random_direction(rng);
    if (glm::dot(d, n_out) < 0.1f) d = glm::normalize(d + n_out);
    Traced t = trace(sc, a, make_ray(target + 10.0f * d, -d));
    ASSERT_TRUE(t.hit.hit());
    ASSERT_EQ(t.hit.prim, f);
    vec3 dout = random_direction(rng);
    if (glm::dot(dout, n_out) < 0.0f) dout = -dout;
    if (a.intersect1(spawn_ray(t.si, dout)).hit()) ++bad;
    Traced back = trace(sc, a, spawn_ray(t.si, -n_out));
    if (!back.hit.hit() || back.hit.prim == t.hit.prim) ++bad;
  }
  EXPECT_EQ(bad, 0);
}

TEST(AccelSpawn, SpawnRayToIsNotBlockedByItsEnds) {
  // Points on a far-away sphere's inside connect to each other and to a disk
  // inside it; pairs the disk genuinely separates are skipped.
  Scene sc;
  vec3 c(2e3f, -1e3f, 500);
  add_sphere(sc, {}, translate(c) * scale(vec3(50)));
  DiskParams dp;
  dp.radius = 10;
  add_disk(sc, dp, translate(c + vec3(0, 0, -20)));
  Accel a(sc);
  std::mt19937 rng(9);
  std::vector<SurfaceInteraction> pts;
  for (int i = 0; i < 400; ++i) {
    // From inside the sphere outwards: hits its inner surface or the disk.
    Ray r = make_ray(c + vec3(0, 0, 5), random_direction(rng));
    Traced t = trace(sc, a, r);
    ASSERT_TRUE(t.hit.hit());
    pts.push_back(t.si);
  }
  int blocked = 0, pairs = 0;
  for (size_t i = 0; i + 1 < pts.size(); i += 2) {
    const SurfaceInteraction &x = pts[i], &y = pts[i + 1];
    // Skip pairs the disk separates (when neither end is on it).
    Ray probe = spawn_ray_to(x, y.p, y.p_error, y.ng);
    Hit h = a.intersect1(probe);
    if (h.hit() && a.shape_index(h) != x.shape && a.shape_index(h) != y.shape) continue;
    ++pairs;
    if (a.occluded1(probe)) ++blocked;
  }
  EXPECT_GT(pairs, 100);
  EXPECT_EQ(blocked, 0);
}

// An axis-aligned plane through the origin has a zero error bound along its
// normal, so rays leave with no offset at all: they must still not re-hit it.
TEST(AccelSpawn, AxisAlignedPlaneThroughOriginDoesNotSelfIntersect) {
  TriangleMesh m;
  m.p = {vec3(-10, 0, -10), vec3(10, 0, -10), vec3(10, 0, 10), vec3(-10, 0, 10)};
  m.indices = {0, 1, 2, 0, 2, 3};
  Scene sc;
  add_mesh(sc, m);
  Accel a(sc);
  std::mt19937 rng(11);
  int bad = 0;
  for (int i = 0; i < 1000; ++i) {
    vec3 o(float(i % 37) * 0.1f - 1.8f, 4.0f, float(i % 23) * 0.1f - 1.1f);
    Traced t = trace(sc, a, make_ray(o, vec3(0, -1, 0)));
    ASSERT_TRUE(t.hit.hit());
    vec3 up = random_direction(rng);
    if (up.y < 0.0f) up.y = -up.y;
    if (a.intersect1(spawn_ray(t.si, up)).hit()) ++bad;
    if (a.occluded1(spawn_ray_to(t.si, vec3(0.5f, 2.0f, 0.25f), vec3(0.0f), vec3(0.0f)))) ++bad;
  }
  EXPECT_EQ(bad, 0);
}
