// End-to-end render of pbrt-v4's cylinder against a closed form: a diffuse
// plane under a cylinder area light given by "power" (pbrt-v4's object-space
// area, one-sided outward emission, area sampling and MIS together).
#include "render_helpers.h"
#include "scene/camera.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

using namespace theia;
using namespace theia::test;

// A horizontal cylinder (axis along x, radius 0.25, length 2, centre height
// 1.2) of power 10 above a diffuse plane, seen from a camera between the two
// looking down.  Its radiance is phi / (pi * 2 pi r * 2), and the plane's
// L = rho / pi * integral of L cos cos / d^2 over the cylinder's side that
// faces the point (the other side faces away; the open ends emit nothing).
TEST(CylinderLight, DiffusePlaneMatchesTheIrradianceIntegral) {
  const float rho = 0.5f, phi = 10.0f, radius = 0.25f, height = 1.2f;
  Scene scene = load_test_scene(R"(
    Film "rgb" "integer xresolution" [24] "integer yresolution" [24]
    PixelFilter "box" "float xradius" [0.5] "float yradius" [0.5]
    LookAt 0 0.8 0  0 0 0  0 0 1
    Camera "perspective" "float fov" [90]
    WorldBegin
    AttributeBegin
    Material "diffuse" "rgb reflectance" [0 0 0]
    AreaLightSource "diffuse" "float power" 10
    Translate 0 1.2 0
    Rotate 90 0 1 0
    Shape "cylinder" "float radius" 0.25 "float zmin" -1 "float zmax" 1
    AttributeEnd
    Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
    Shape "trianglemesh" "point3 P" [-10 0 -10  10 0 -10  10 0 10  -10 0 10]
      "integer indices" [0 1 2 0 2 3]
  )");
  const double L = phi / (kPi * 2.0 * kPi * radius * 2.0);
  auto predicted = [&](const vec3& p) {
    // Rotate 90 about y takes object (x, y, z) to (z, y, -x).
    const int n_phi = 256, n_z = 64;
    double e = 0.0;
    for (int i = 0; i < n_phi; ++i) {
      double a = 2.0 * M_PI * (i + 0.5) / n_phi;
      glm::dvec3 n(0.0, std::sin(a), -std::cos(a));
      for (int j = 0; j < n_z; ++j) {
        double z = -1.0 + 2.0 * (j + 0.5) / n_z;
        glm::dvec3 q(z, height + radius * std::sin(a), -radius * std::cos(a));
        glm::dvec3 d = glm::dvec3(p) - q;
        double d2 = glm::dot(d, d);
        double cos_l = glm::dot(n, d) / std::sqrt(d2), cos_p = -d.y / std::sqrt(d2);
        if (cos_l > 0.0 && cos_p > 0.0) e += cos_l * cos_p / d2;
      }
    }
    return rho / kPi * L * e * (2.0 * M_PI * radius / n_phi) * (2.0 / n_z);
  };
  RenderResult r = render_scene(scene, quick_config(256));
  Camera cam = make_camera(scene.camera, scene.film);
  // Under the cylinder (|z| small) and to either side of it; one pixel is
  // noisy to a few percent at 256 spp, a sum over ~190 to well under 1%.
  expect_region_sums_match(
      r.image, cam, 3, [](vec3 p) { return std::abs(p.z) < 0.25f ? 0 : p.z > 0.0f ? 1 : 2; }, predicted, 0.01,
      {"under", "+z side", "-z side"});
  EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
}
