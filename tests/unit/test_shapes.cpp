// Shape sampling for area lights: sampled points lie on the shape with the
// normal tracing reports, pdf() agrees with sample(), and the estimators
// E[1/pdf] reproduce solid angles and areas.  (Chi-square tests of the
// sampled distributions live in the statistical suite.)
#include "scene/accel.h"
#include "scene/shapes.h"
#include "scene/surface_crossing.h"
#include "tests/unit/scene_builders.h"

#include <gtest/gtest.h>

#include <array>
#include <random>

using namespace theia;
using namespace theia::test;

namespace {

// Two triangles: [x0, x1] x [y0, y1] at height z.
TriangleMesh quad(float x0, float x1, float y0, float y1, float z) {
  TriangleMesh m;
  m.p = {vec3(x0, y0, z), vec3(x1, y0, z), vec3(x1, y1, z), vec3(x0, y1, z)};
  m.indices = {0, 1, 2, 0, 2, 3};
  return m;
}

struct Stats {
  double sum = 0, sum2 = 0;
  int n = 0;
  void add(double x) {
    sum += x;
    sum2 += x * x;
    ++n;
  }
  double mean() const { return sum / n; }
  double stderr_() const { return std::sqrt(std::max(0.0, sum2 / n - mean() * mean()) / n); }
};

#define EXPECT_ESTIMATE(stats, expected)                                                         \
  do {                                                                                           \
    double m_ = (stats).mean(), e_ = (expected);                                                 \
    EXPECT_NEAR(m_, e_, 4.0 * (stats).stderr_() + 1e-5 * std::abs(e_)) << "estimate vs exact"; \
    EXPECT_NEAR(m_, e_, 0.01 * std::abs(e_)) << "estimate vs exact, relative";                 \
  } while (0)

struct Checked {
  int samples = 0, checked = 0, traced = 0;
  Stats inv_pdf;        // E[1/pdf] = solid angle subtended (counting every sampled point)
  Stats area_estimate;  // E[d^2 / (cos pdf)] = E[1 / area pdf] = area
};

// Draws n samples of `shape` from ref; each sampled point must lie where a ray
// from ref towards it hits the shape (when that ray's first hit is the point),
// with the same normal, uv and the same pdf from pdf().
Checked check_samples(const Scene& sc, const Accel& a, const ShapeSampling& ss, int shape,
                      const ShapeSampleContext& ref, int n, bool check_uv = true) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  Checked c;
  for (int i = 0; i < n; ++i) {
    std::optional<ShapeSample> s = ss.sample(shape, ref, vec2(u(rng), u(rng)), u(rng));
    if (!s) continue;
    ++c.samples;
    EXPECT_GT(s->pdf, 0.0f);
    vec3 d = s->p - ref.p;
    float d2 = glm::dot(d, d);
    vec3 wi = d / std::sqrt(d2);
    c.inv_pdf.add(1.0 / s->pdf);
    c.area_estimate.add(double(d2) / (std::abs(glm::dot(s->n, wi)) * double(s->pdf)));
    // pdf() at exactly the sampled point reproduces sample()'s pdf.
    SurfaceInteraction at;
    at.p = s->p;
    at.ng = at.ns = s->n;
    at.shape = shape;
    EXPECT_NEAR(ss.pdf(shape, ref, wi, at), s->pdf, 1e-6f * s->pdf);
    if (i % 16 != 0) continue;  // tracing is the slow part: check a subset
    // At the silhouette the ray towards the point may graze past in float.
    if (std::abs(glm::dot(s->n, wi)) < 1e-3f) continue;
    ++c.checked;
    Ray r{ref.p, 0.0f, wi, kInfinity};
    Hit h = a.intersect1(r);
    if (!h.hit()) {
      ADD_FAILURE() << "sampled point not hit: p = " << s->p.x << " " << s->p.y << " " << s->p.z;
      continue;
    }
    SurfaceInteraction si = compute_interaction(sc, a, r, h);
    // Hidden behind the shape's own front: a different point, not float error.
    if (glm::length(si.p - s->p) > 2e-5f * (std::sqrt(d2) + glm::length(s->p))) continue;
    ++c.traced;
    EXPECT_EQ(si.shape, shape);
    EXPECT_NEAR(glm::dot(si.ng, s->n), 1.0f, 1e-4f) << "sampled normal must be the traced ng";
    EXPECT_LE(glm::length(s->p_error), 1e-3f * glm::length(s->p) + 1e-6f);
    if (check_uv) {
      EXPECT_NEAR(si.uv.x, s->uv.x, 2e-3f);
      EXPECT_NEAR(si.uv.y, s->uv.y, 2e-3f);
    }
    // The traced point differs from the sampled one by float error, which the
    // 1/cos of the solid-angle conversion amplifies at grazing angles.
    if (std::abs(glm::dot(s->n, wi)) > 0.05f) {
      EXPECT_NEAR(ss.pdf(shape, ref, wi, si), s->pdf, 2e-3f * s->pdf);
    }
  }
  return c;
}

}  // namespace

TEST(ShapeSampling, SphereConeFromOutside) {
  for (bool reverse : {false, true}) {
    Scene sc;
    vec3 c(1, 2, 3);
    float radius = 2.0f;
    int s = make_emissive(sc, add_sphere(sc, {}, translate(c) * rotate(30, vec3(1, 1, 0)) * scale(vec3(radius)), reverse));
    Accel a(sc);
    ShapeSampling ss(sc);
    EXPECT_NEAR(ss.area(s), 4.0f * kPi * radius * radius, 1e-3f);
    ShapeSampleContext ref{c + vec3(0, 7, 0), vec3(0)};
    // Phi wraps around at the seam, so uv is checked only away from it.
    Checked k = check_samples(sc, a, ss, s, ref, 20000, false);
    EXPECT_EQ(k.samples, 20000);
    EXPECT_GT(k.traced, 1000);
    double cos_max = std::sqrt(1.0 - sqr(radius / 7.0));
    EXPECT_ESTIMATE(k.inv_pdf, 2.0 * kPi * (1.0 - cos_max));
    // Uniform over the cone: E[cos theta] = (1 + cos_max) / 2, and every
    // sample is on the visible cap.
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    Stats cos_theta;
    vec3 axis = glm::normalize(c - ref.p);
    for (int i = 0; i < 20000; ++i) {
      ShapeSample smp = *ss.sample(s, ref, vec2(u(rng), u(rng)), u(rng));
      EXPECT_NEAR(glm::length(smp.p - c), radius, 1e-5f);
      vec3 outward = glm::normalize(smp.p - c);
      EXPECT_NEAR(glm::dot(smp.n, outward), reverse ? -1.0f : 1.0f, 1e-5f);
      EXPECT_GE(glm::dot(outward, ref.p - smp.p), -1e-4f);
      cos_theta.add(glm::dot(glm::normalize(smp.p - ref.p), axis));
    }
    EXPECT_ESTIMATE(cos_theta, 0.5 * (1.0 + cos_max));
  }
}

TEST(ShapeSampling, SphereConeAtSmallAngles) {
  Scene sc;
  vec3 c(5, 0, 0);
  int s = make_emissive(sc, add_sphere(sc, {}, translate(c)));
  Accel a(sc);
  ShapeSampling ss(sc);
  ShapeSampleContext ref{c + vec3(0, 0, 1000), vec3(0, 0, -1)};
  Checked k = check_samples(sc, a, ss, s, ref, 4000, false);
  EXPECT_EQ(k.samples, 4000);
  EXPECT_EQ(k.traced, 250);  // every traced sample is on the visible cap
  EXPECT_ESTIMATE(k.inv_pdf, 2.0 * kPi * (1.0 - std::sqrt(1.0 - 1e-6)));
}

TEST(ShapeSampling, SphereFromInsideCoversEveryDirection) {
  Scene sc;
  int s = make_emissive(sc, add_sphere(sc, {}, translate(vec3(-1, 0, 2)) * scale(vec3(3))));
  Accel a(sc);
  ShapeSampling ss(sc);
  ShapeSampleContext ref{vec3(0, 1, 2.5f), vec3(0)};
  Checked k = check_samples(sc, a, ss, s, ref, 100000);
  EXPECT_EQ(k.traced, 6250);  // from inside the first hit is always the sampled point
  EXPECT_ESTIMATE(k.inv_pdf, 4.0 * kPi);
  EXPECT_ESTIMATE(k.area_estimate, 4.0 * kPi * 9.0);
}

TEST(ShapeSampling, PartialSphereAndEllipsoidAreas) {
  {
    Scene sc;
    SphereParams p{1.0f, -0.5f, 0.8f, 200.0f};
    int s = make_emissive(sc, add_sphere(sc, p, translate(vec3(0, 0, 10)) * scale(vec3(3)), true));
    Accel a(sc);
    ShapeSampling ss(sc);
    double area = 9.0 * radians(200.0f) * 1.0 * 1.3;
    EXPECT_NEAR(ss.area(s), area, 1e-4 * area);
    ShapeSampleContext ref{vec3(1, 1, 0), vec3(0, 0, 1)};
    Checked k = check_samples(sc, a, ss, s, ref, 100000);
    EXPECT_GT(k.traced, 1000);
    EXPECT_ESTIMATE(k.area_estimate, area);
  }
  {
    // Oblate spheroid, semi-axes (2, 2, 1): S = 2 pi a^2 (1 + (1 - e^2) / e atanh e).
    Scene sc;
    int s = make_emissive(sc, add_sphere(sc, {}, translate(vec3(0, 0, 5)) * rotate(40, vec3(0, 1, 0)) * scale(vec3(2, 2, 1))));
    Accel a(sc);
    ShapeSampling ss(sc);
    double e = std::sqrt(1.0 - 1.0 / 4.0);
    double area = 2.0 * kPi * 4.0 * (1.0 + (1.0 - e * e) / e * std::atanh(e));
    EXPECT_NEAR(ss.area(s), area, 1e-4 * area);
    ShapeSampleContext ref{vec3(0.5f, -0.5f, 0), vec3(0, 0, 1)};
    Checked k = check_samples(sc, a, ss, s, ref, 100000, false);
    EXPECT_GT(k.traced, 1000);
    EXPECT_ESTIMATE(k.area_estimate, area);
    // From inside, every direction is covered exactly once.
    ShapeSampleContext inside{vec3(0.3f, 0.2f, 5.1f), vec3(0)};
    Checked ki = check_samples(sc, a, ss, s, inside, 100000, false);
    EXPECT_EQ(ki.traced, 6250);
    EXPECT_ESTIMATE(ki.inv_pdf, 4.0 * kPi);
  }
}

TEST(ShapeSampling, QuadSubtendsItsSolidAngle) {
  Scene sc;
  int s = make_emissive(sc, add_mesh(sc, quad(-1, 1, -0.5f, 1.5f, 0)));
  Accel a(sc);
  ShapeSampling ss(sc);
  EXPECT_NEAR(ss.area(s), 4.0f, 1e-5f);
  ShapeSampleContext ref{vec3(0.3f, 0.2f, 1.5f), vec3(0, 0, -1)};
  Checked k = check_samples(sc, a, ss, s, ref, 100000);
  EXPECT_EQ(k.traced, 6250);
  // Numerical solid angle: midpoint rule for the integral of cos / d^2 over the quad.
  const int n = 2000;
  double omega = 0.0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      double x = -1.0 + 2.0 * (i + 0.5) / n, y = -0.5 + 2.0 * (j + 0.5) / n;
      double dx = x - 0.3, dy = y - 0.2, dz = -1.5;
      double d2 = dx * dx + dy * dy + dz * dz;
      omega += 1.5 / (d2 * std::sqrt(d2)) * (4.0 / (double(n) * n));
    }
  EXPECT_ESTIMATE(k.inv_pdf, omega);
  EXPECT_ESTIMATE(k.area_estimate, 4.0);
}

TEST(ShapeSampling, MeshNormalsFollowOrientationRules) {
  struct Case {
    bool reverse, swaps, with_n;
    float nz;
  };
  for (Case c : {Case{false, false, false, 1}, Case{true, false, false, -1}, Case{false, true, false, -1},
                 Case{true, true, false, 1}, Case{false, false, true, -1}, Case{true, false, true, -1}}) {
    Scene sc;
    TriangleMesh m = quad(0, 1, 0, 2, 0);
    if (c.with_n) m.n.assign(4, glm::normalize(vec3(0.1f, 0.2f, -1)));
    m.uv = {vec2(0, 0), vec2(1, 0), vec2(1, 1), vec2(0, 1)};
    int s = make_emissive(sc, add_mesh(sc, m, c.reverse, c.swaps));
    Accel a(sc);
    ShapeSampling ss(sc);
    for (float side : {1.0f, -1.0f}) {
      ShapeSampleContext ref{vec3(0.4f, 0.7f, side * 0.8f), vec3(0)};
      Checked k = check_samples(sc, a, ss, s, ref, 3200);
      EXPECT_EQ(k.traced, 200);
      std::optional<ShapeSample> smp = ss.sample(s, ref, vec2(0.3f, 0.6f), 0.7f);
      ASSERT_TRUE(smp);
      EXPECT_EQ(smp->n, vec3(0, 0, c.nz));
    }
  }
}

// A mesh light whose triangles face every way (a tetrahedron): each sampled
// point carries its own triangle's normal (ShapeSampling keeps the unit
// normals made once; an entry read for the wrong triangle fails here, which
// a flat quad's two triangles could not show), the one a ray traced to the
// point finds, reversed with the shape's orientation.
TEST(ShapeSampling, EachPointOfAMeshLightHasItsOwnTrianglesNormal) {
  TriangleMesh m;
  m.p = {vec3(0, 0, 0), vec3(1, 0, 0), vec3(0, 1, 0), vec3(0.2f, 0.3f, 1)};
  m.indices = {0, 2, 1, 0, 1, 3, 1, 2, 3, 2, 0, 3};
  for (bool reverse : {false, true}) {
    Scene sc;
    int s = make_emissive(sc, add_mesh(sc, m, reverse));
    Accel a(sc);
    ShapeSampling ss(sc);
    std::mt19937 rng(9);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    std::array<int, 4> per_triangle{};
    for (int i = 0; i < 4000; ++i) {
      std::optional<ShapeSample> smp = ss.sample_area(s, vec2(u(rng), u(rng)), u(rng));
      ASSERT_TRUE(smp);
      ASSERT_TRUE(smp->prim >= 0 && smp->prim < 4);
      ++per_triangle[size_t(smp->prim)];
      const vec3 n = triangle_unit_normal(sc.meshes[0], size_t(smp->prim));
      ASSERT_EQ(smp->n, reverse ? -n : n) << "triangle " << smp->prim;
    }
    for (int k : per_triangle) EXPECT_GT(k, 400);
    // From outside, the traced normal at each sampled point agrees.
    Checked k = check_samples(sc, a, ss, s, ShapeSampleContext{vec3(2, 2, 2), vec3(0)}, 3200, false);
    EXPECT_GT(k.traced, 40);
  }
}

TEST(ShapeSampling, PartialDiskUnderNonUniformScale) {
  for (bool reverse : {false, true}) {
    Scene sc;
    DiskParams p;
    p.height = 0.5f;
    p.radius = 2;
    p.innerradius = 0.7f;
    p.phimax = 250;
    Transform t = translate(vec3(1, 1, 1)) * rotate(20, vec3(0, 1, 0)) * scale(vec3(1.5f, 0.5f, -2));
    int s = make_emissive(sc, add_disk(sc, p, t, reverse));
    Accel a(sc);
    ShapeSampling ss(sc);
    double area = 0.5 * radians(250.0f) * (4.0 - 0.49) * 1.5 * 0.5;
    EXPECT_NEAR(ss.area(s), area, 1e-5 * area);
    ShapeSampleContext ref{vec3(0.5f, 0.2f, 4.0f), vec3(0)};
    Checked k = check_samples(sc, a, ss, s, ref, 100000);
    EXPECT_EQ(k.traced, 6250);
    EXPECT_ESTIMATE(k.area_estimate, area);
    // Samples stay inside the annulus sector in object space.
    std::mt19937 rng(2);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    Transform inv = t.inverse();
    for (int i = 0; i < 2000; ++i) {
      vec3 q = inv.point(ss.sample(s, ref, vec2(u(rng), u(rng)), u(rng))->p);
      float r = std::sqrt(q.x * q.x + q.y * q.y);
      EXPECT_NEAR(q.z, 0.5f, 1e-5f);
      EXPECT_GE(r, 0.7f - 1e-5f);
      EXPECT_LE(r, 2.0f + 1e-5f);
      float phi = std::atan2(q.y, q.x);
      if (phi < 0) phi += 2 * kPi;
      EXPECT_LE(phi, radians(250.0f) + 1e-4f);
    }
  }
}

TEST(ShapeSampling, FullDiskAndMirroredSphere) {
  Scene sc;
  int d = make_emissive(sc, add_disk(sc, {0.0f, 1.5f, 0.0f, 360.0f}, translate(vec3(0, 0, -2))));
  int s = make_emissive(sc, add_sphere(sc, {}, translate(vec3(4, 0, 0)) * scale(vec3(-1, 1, 1))));  // mirror: inward normal
  Accel a(sc);
  ShapeSampling ss(sc);
  EXPECT_NEAR(ss.area(d), kPi * 2.25f, 1e-5f);
  ShapeSampleContext ref{vec3(0.2f, 0.1f, 1), vec3(0)};
  Checked k = check_samples(sc, a, ss, d, ref, 100000);
  EXPECT_GT(k.traced, 5000);
  EXPECT_ESTIMATE(k.area_estimate, kPi * 2.25);
  std::optional<ShapeSample> smp = ss.sample(s, ref, vec2(0.5f), 0.5f);
  ASSERT_TRUE(smp);
  EXPECT_LT(glm::dot(smp->n, smp->p - vec3(4, 0, 0)), 0.0f);
  check_samples(sc, a, ss, s, ref, 3200, false);
}

// pbrt-v4 samples a cylinder uniformly in (z, phi): uniform by area under a
// similarity.  Under a non-uniform scale the density follows the area scale.
TEST(ShapeSampling, CylinderByAreaUnderSimilarityAndNonUniformScale) {
  for (bool reverse : {false, true}) {
    Scene sc;
    CylinderParams p{0.5f, -0.4f, 1.1f, 250.0f};
    Transform t = translate(vec3(1, -2, 3)) * rotate(35, vec3(1, 0, 1)) * scale(vec3(2));
    int s = make_emissive(sc, add_cylinder(sc, p, t, reverse));
    Accel a(sc);
    ShapeSampling ss(sc);
    double area = 4.0 * radians(250.0f) * 0.5 * 1.5;
    EXPECT_NEAR(ss.area(s), area, 1e-5 * area);
    EXPECT_NEAR(pbrt_quadric_area(sc.shapes[size_t(s)]), area / 4.0, 1e-6 * area);
    ShapeSampleContext ref{vec3(3.5f, -1.0f, 4.5f), vec3(0)};
    Checked k = check_samples(sc, a, ss, s, ref, 100000);
    EXPECT_GT(k.traced, 2000);
    EXPECT_ESTIMATE(k.area_estimate, area);
    // Normals are the transformed outward normals (flipped by ReverseOrientation),
    // and samples stay on the partial side in object space.
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    Transform inv = t.inverse();
    for (int i = 0; i < 2000; ++i) {
      ShapeSample smp = *ss.sample(s, ref, vec2(u(rng), u(rng)), u(rng));
      vec3 q = inv.point(smp.p);
      EXPECT_NEAR(std::sqrt(q.x * q.x + q.y * q.y), 0.5f, 1e-5f);
      EXPECT_GE(q.z, -0.4f - 1e-5f);
      EXPECT_LE(q.z, 1.1f + 1e-5f);
      float phi = std::atan2(q.y, q.x);
      if (phi < 0) phi += 2 * kPi;
      EXPECT_LE(phi, radians(250.0f) + 1e-4f);
      vec3 n_out = glm::normalize(t.normal(vec3(q.x, q.y, 0)));
      EXPECT_NEAR(glm::dot(smp.n, n_out), reverse ? -1.0f : 1.0f, 1e-5f);
    }
  }
  {
    // An elliptic cylinder: semi-axes 2 and 0.5, height 3.  Its area is the
    // ellipse's perimeter (a fine polygon) times the height.
    Scene sc;
    Transform t = translate(vec3(0, 0, 6)) * rotate(50, vec3(0, 1, 0)) * scale(vec3(2, 0.5f, 1.5f));
    int s = make_emissive(sc, add_cylinder(sc, {}, t));
    Accel a(sc);
    ShapeSampling ss(sc);
    double perimeter = 0.0;
    const int n = 200000;
    for (int i = 0; i < n; ++i) {
      double a0 = 2.0 * M_PI * i / n, a1 = 2.0 * M_PI * (i + 1) / n;
      perimeter += std::hypot(2.0 * (std::cos(a1) - std::cos(a0)), 0.5 * (std::sin(a1) - std::sin(a0)));
    }
    double area = perimeter * 3.0;
    EXPECT_NEAR(ss.area(s), area, 1e-4 * area);
    ShapeSampleContext ref{vec3(0.5f, -0.5f, 0), vec3(0, 0, 1)};
    Checked k = check_samples(sc, a, ss, s, ref, 100000, false);
    EXPECT_GT(k.traced, 1000);
    EXPECT_ESTIMATE(k.area_estimate, area);
  }
}

TEST(ShapeSampling, NonEmissiveShapesAreNotSampled) {
  Scene sc;
  add_sphere(sc, {});
  ShapeSampling ss(sc);
  EXPECT_FALSE(ss.sample(0, {vec3(0, 0, 5), vec3(0)}, vec2(0.5f), 0.5f));
  EXPECT_EQ(ss.area(0), 0.0f);
  EXPECT_EQ(ss.area(7), 0.0f);
}

// The triangle data shading reads per hit, which decides whether the engine
// fetches it ahead; and the fetches themselves, which must accept a hit of
// any kind (a mesh at top level or instanced, a quadric, a miss).
TEST(TriangleMeshes, BytesCountEveryArrayAndPrefetchAcceptsEveryHit) {
  Scene sc;
  TriangleMesh m = quad(-1, 1, -1, 1, 0);
  m.n.assign(m.p.size(), vec3(0, 0, 1));
  m.uv.assign(m.p.size(), vec2(0.5f));
  const int mesh_shape = add_mesh(sc, m);
  add_mesh(sc, quad(-1, 1, -1, 1, 2));
  EXPECT_EQ(triangle_mesh_bytes(sc), 2 * 6 * sizeof(uint32_t) + 2 * 4 * sizeof(vec3) + 4 * sizeof(vec3) +
                                         4 * sizeof(vec2));
  add_sphere(sc, SphereParams{}, translate(vec3(0, 0, -5)));
  sc.prototypes.push_back({"quad", {add_mesh(sc, quad(-1, 1, -1, 1, 0), false, false, false)}});
  sc.instances.push_back({0, translate(vec3(5, 0, 0))});
  const Accel accel(sc);
  const TrianglePrefetcher prefetch(sc, accel);
  int kinds = 0;
  for (vec3 o : {vec3(0, 0, 1), vec3(0, 0, -2), vec3(5, 0, 1), vec3(9, 9, 9)}) {
    Ray ray{o, 0.0f, vec3(0, 0, -1), kInfinity};
    const Hit hit = accel.intersect1(ray, PrimRef{});
    prefetch.indices(hit);
    prefetch.vertices(hit);
    kinds += hit.geom != kInvalidId;
    if (o == vec3(0, 0, 1)) {
      EXPECT_EQ(accel.shape_index(hit), mesh_shape);
    }
  }
  EXPECT_EQ(kinds, 3);  // the mesh, the sphere, the instance; the last ray misses
}
