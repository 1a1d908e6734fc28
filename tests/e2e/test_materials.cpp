// End-to-end materials: the engine with dielectric and conductor BSDFs in a
// constant environment (white furnace), against values known independently.
#include "render_helpers.h"
#include "tests/unit/bxdf_test_util.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

using namespace theia;
using namespace theia::test;

namespace {

// A unit sphere filling a 16x16 frame (camera at distance 5, fov 10) in a
// constant environment of radiance 1.
Scene furnace(const std::string& material, int maxdepth = 100) {
  return load_test_scene(fmt::format(R"(
    Film "rgb" "integer xresolution" [16] "integer yresolution" [16]
    Integrator "volpath" "integer maxdepth" [{}]
    LookAt 0 0 -5  0 0 0  0 1 0
    Camera "perspective" "float fov" [10]
    WorldBegin
    LightSource "infinite" "rgb L" [1 1 1]
    {}
    Shape "sphere" "float radius" [1]
  )",
                                     maxdepth, material));
}

void expect_finite(const RenderResult& r, const std::string& what) {
  EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u) << what;
  for (float v : r.image.data) ASSERT_TRUE(std::isfinite(v)) << what;
}

// The film-averaged albedo of the furnace sphere for a reflector of directional
// albedo E(theta_o): the image is the average over the film of E at the angle
// between each camera ray and the sphere normal it hits (one bounce: nothing
// leaving a convex sphere comes back).
template <typename E>
double film_average(const E& albedo) {
  const double t = std::tan(5.0 * kPi / 180.0);
  const int n = 64;
  double sum = 0.0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      glm::dvec3 d = glm::normalize(glm::dvec3(((i + 0.5) / n * 2 - 1) * t, ((j + 0.5) / n * 2 - 1) * t, 1.0));
      glm::dvec3 o(0.0, 0.0, -5.0);
      double b = glm::dot(o, d), c = glm::dot(o, o) - 1.0;
      double hit = -b - std::sqrt(b * b - c);
      glm::dvec3 nrm = o + hit * d;
      sum += albedo(std::acos(std::clamp(-glm::dot(d, nrm), -1.0, 1.0)));
    }
  return sum / (n * n);
}

}  // namespace

// Lossless specular materials keep a white furnace at exactly 1: the smooth
// dielectric's 1/eta^2 on entry and eta^2 on exit cancel (radiance mode), and
// Russian roulette with the eta scale neither kills nor re-weights them.
TEST(MaterialsFurnace, LosslessSpecularSpheresRenderToOne) {
  const std::pair<const char*, const char*> cases[] = {
      {"smooth dielectric 1.5", R"(Material "dielectric" "float eta" [1.5])"},
      {"smooth dielectric 4", R"(Material "dielectric" "float eta" [4])"},
      {"thin dielectric", R"(Material "thindielectric" "float eta" [1.5])"},
      {"smooth mirror", R"(Material "conductor" "rgb eta" [1 1 1] "rgb k" [10000 10000 10000])"},
  };
  for (auto [name, material] : cases) {
    RenderResult r = render_scene(furnace(material), quick_config(16));
    expect_finite(r, name);
    RGB mean = image_mean(r.image);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], 1.0f, 2e-3f) << name << " channel " << c;
  }
}

// Real-valued conductors, rough dielectrics and the layered materials render
// without NaN or Inf and without creating energy.
TEST(MaterialsFurnace, GlossyMaterialsRenderFiniteAndAtMostOne) {
  const std::pair<const char*, const char*> cases[] = {
      {"copper", R"(Material "conductor" "spectrum eta" "metal-Cu-eta" "spectrum k" "metal-Cu-k")"},
      {"rough gold", R"(Material "conductor" "spectrum eta" "metal-Au-eta" "spectrum k" "metal-Au-k" "float roughness" [0.1])"},
      {"rough glass", R"(Material "dielectric" "float eta" [1.5] "float roughness" [0.1])"},
      {"coated diffuse", R"(Material "coateddiffuse" "rgb reflectance" [0.8 0.5 0.3] "float roughness" [0.05])"},
      {"coated conductor", R"(Material "coatedconductor" "float interface.roughness" [0.02])"},
  };
  for (auto [name, material] : cases) {
    RenderResult r = render_scene(furnace(material), quick_config(16));
    expect_finite(r, name);
    RGB mean = image_mean(r.image);
    for (int c = 0; c < 3; ++c) {
      EXPECT_LE(mean[c], 1.01f) << name << " channel " << c;
      EXPECT_GT(mean[c], 0.05f) << name << " channel " << c;
    }
  }
}

// A rough mirror (F = 1) renders to its single-scattering directional albedo,
// computed by the independent quadrature of the unit tests and averaged over
// the angles the film sees.
TEST(MaterialsFurnace, RoughMirrorRendersToItsDirectionalAlbedo) {
  for (float alpha : {0.3f, 1.0f}) {
    // Tabulate E(theta) over the angles the film sees (up to ~0.55 rad).
    std::vector<double> table;
    const int n = 24;
    const double theta_max = 0.6;
    for (int i = 0; i <= n; ++i) table.push_back(ggx_albedo_quadrature(alpha, theta_max * i / n, 200));
    double expected = film_average([&](double theta) {
      double x = std::min(theta / theta_max * n, double(n) - 1e-9);
      int i = int(x);
      return table[size_t(i)] + (x - i) * (table[size_t(i) + 1] - table[size_t(i)]);
    });
    RenderResult r = render_scene(
        furnace(fmt::format(R"(Material "conductor" "rgb eta" [1 1 1] "rgb k" [10000 10000 10000]
                               "bool remaproughness" false "float roughness" [{}])",
                            alpha)),
        quick_config(256));
    expect_finite(r, "rough mirror");
    RGB mean = image_mean(r.image);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], expected, 0.005) << "alpha " << alpha << " channel " << c;
  }
}
