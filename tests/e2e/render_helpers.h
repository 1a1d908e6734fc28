// Shared helpers for end-to-end tests: render a scene in-process and read pixels.
#pragma once

#include "app/render.h"
#include "core/image.h"
#include "scene/camera.h"
#include "scene/parser.h"
#include "scene/texture.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <string>
#include <sys/wait.h>
#include <vector>

namespace theia::test {

inline Scene load_test_scene(const std::string& text) {
  Scene s = parse_scene_string(text, "<test>", ".");
  load_images(s);
  return s;
}

inline Scene load_test_scene_file(const std::string& path) {
  Scene s = load_scene(path);
  load_images(s);
  return s;
}

// A diffuse sphere of radius 1 seen from 5 away inside a constant environment
// of radiance 1 (the white furnace: with albedo 1 every pixel is 1).
inline std::string furnace_sphere_scene(int resolution, float fov, float albedo, int max_depth = 50) {
  const std::string a = std::to_string(albedo);
  return "Film \"rgb\" \"integer xresolution\" [" + std::to_string(resolution) + "] \"integer yresolution\" [" +
         std::to_string(resolution) + "]\nIntegrator \"volpath\" \"integer maxdepth\" [" + std::to_string(max_depth) +
         "]\nLookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [" + std::to_string(fov) +
         "]\nWorldBegin\nLightSource \"infinite\" \"rgb L\" [1 1 1]\nMaterial \"diffuse\" \"rgb reflectance\" [" + a +
         " " + a + " " + a + "]\nShape \"sphere\" \"float radius\" [1]\n";
}

// A one-sided area light facing up under a rough metal ceiling: the floor
// sees the light only through the ceiling, so nearly all of its light is a
// caustic (light -> ceiling -> floor -> camera).  The caustic tests' scene.
inline std::string mirror_room_scene(int width, int height, float ceiling_roughness) {
  return "Film \"rgb\" \"integer xresolution\" [" + std::to_string(width) + "] \"integer yresolution\" [" +
         std::to_string(height) + R"(]
  Integrator "volpath" "integer maxdepth" [5]
  LookAt 0 5 -9  0 0 0  0 1 0
  Camera "perspective" "float fov" [45]
  WorldBegin
  AttributeBegin
    AreaLightSource "diffuse" "rgb L" [20 20 20]
    Material "diffuse" "rgb reflectance" [0 0 0]
    Shape "trianglemesh" "point3 P" [-1.5 3 -1.5  1.5 3 -1.5  1.5 3 1.5  -1.5 3 1.5] "integer indices" [0 2 1 0 3 2]
  AttributeEnd
  Material "conductor" "float roughness" [)" +
         std::to_string(ceiling_roughness) + R"(] "bool remaproughness" false "rgb eta" [0.2 0.9 1.1] "rgb k" [3.9 2.4 2.1]
  Shape "trianglemesh" "point3 P" [-3 5 -3  3 5 -3  3 5 3  -3 5 3] "integer indices" [0 1 2 0 2 3]
  Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
  Shape "trianglemesh" "point3 P" [-8 0 -8  8 0 -8  8 0 8  -8 0 8] "integer indices" [0 1 2 0 2 3]
)";
}

// A diffuse sphere of this radius on a floor, a small emitter, an environment:
// a few bounces, fast (the resume and split-frame tests' scene, 32x24 at 40 spp).
inline std::string sphere_floor_scene(float radius) {
  return R"(Film "rgb" "integer xresolution" [32] "integer yresolution" [24]
LookAt 0 1 -5  0 0 0  0 1 0
Camera "perspective" "float fov" [35]
Sampler "sobol" "integer pixelsamples" [40]
WorldBegin
LightSource "infinite" "rgb L" [1 1 1]
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [4 4 4]
  Shape "sphere" "float radius" [0.3]
AttributeEnd
Material "diffuse" "rgb reflectance" [0.7 0.5 0.3]
Shape "sphere" "float radius" [)" +
         std::to_string(radius) + R"(]
Shape "trianglemesh" "point3 P" [-4 -1 -4  4 -1 -4  4 -1 4  -4 -1 4] "integer indices" [0 1 2 0 2 3]
)";
}

// Unguided whatever the default (--guiding-auto turns itself off below the
// training budget, but not above it): the engine's estimators on their own.
inline RenderConfig quick_config(int spp) {
  RenderConfig c;
  c.spp = spp;
  c.guiding.enabled = OnOffAuto::Off;
  return c;
}

// Where the central camera ray of pixel (x, y) meets the horizontal plane at
// height `plane_y` (the analytic tests' ground planes).
inline vec3 pixel_on_plane(const Camera& camera, int x, int y, float plane_y = 0.0f) {
  Ray ray = generate_camera_ray(camera, vec2(float(x) + 0.5f, float(y) + 0.5f), vec2(0.5f));
  return ray.o + ((plane_y - ray.o.y) / ray.d.y) * ray.d;
}

// An analytic plane test's comparison over regions: for every pixel, where its
// central ray meets the ground plane picks a region (bin_of(p) in [0, bins)),
// and the region sums the rendered green channel and predicted(p).  A sum over
// a hundred pixels averages the noise of one pixel down to about a percent.
template <class BinOf, class Predict>
void expect_region_sums_match(const ImageBuffer& image, const Camera& camera, int bins, BinOf bin_of,
                              Predict predicted, double tolerance, const std::vector<std::string>& names) {
  std::vector<double> got(size_t(bins), 0.0), want(size_t(bins), 0.0);
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      vec3 p = pixel_on_plane(camera, x, y);
      size_t b = size_t(bin_of(p));
      got[b] += image.data[(size_t(y) * image.width + x) * image.channels.size() + 1];
      want[b] += predicted(p);
    }
  for (size_t b = 0; b < got.size(); ++b) EXPECT_NEAR(got[b] / want[b], 1.0, tolerance) << names[b];
}

inline RGB pixel_rgb(const ImageBuffer& img, int x, int y) {
  size_t nc = img.channels.size();
  const float* p = &img.data[(size_t(y) * img.width + x) * nc];
  return {p[0], p[1], p[2]};
}

inline float pixel_channel(const ImageBuffer& img, int x, int y, int c) {
  return img.data[(size_t(y) * img.width + x) * img.channels.size() + c];
}

inline RGB image_mean(const ImageBuffer& img) {
  glm::dvec3 sum(0.0);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) sum += glm::dvec3(pixel_rgb(img, x, y));
  return RGB(sum / double(img.width * img.height));
}

// Largest per-pixel relative difference over R, G, B (relative to the larger value, floored).
inline double max_relative_difference(const ImageBuffer& a, const ImageBuffer& b, double floor = 1e-3) {
  double worst = 0.0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x)
      for (int c = 0; c < 3; ++c) {
        double va = pixel_channel(a, x, y, c), vb = pixel_channel(b, x, y, c);
        worst = std::max(worst, std::abs(va - vb) / std::max({std::abs(va), std::abs(vb), floor}));
      }
  return worst;
}

// Largest |a - b| / max(|a|, |b|, floor) over every channel, matched by name.
inline double max_channel_difference(const ImageBuffer& a, const ImageBuffer& b, double floor = 1e-3) {
  EXPECT_EQ(a.channels, b.channels);
  EXPECT_EQ(a.data.size(), b.data.size());
  double worst = 0.0;
  for (size_t i = 0; i < std::min(a.data.size(), b.data.size()); ++i)
    worst = std::max(worst, std::abs(double(a.data[i]) - double(b.data[i])) /
                                std::max({std::abs(double(a.data[i])), std::abs(double(b.data[i])), floor}));
  return worst;
}

struct RunResult {
  int exit_code;
  std::string output;  // stdout and stderr together
};

// Runs a shell command; its stdout and stderr together.
inline RunResult run_shell(const std::string& command) {
  std::string cmd = command + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  std::string out;
  std::array<char, 4096> buf;
  while (size_t n = fread(buf.data(), 1, buf.size(), p)) out.append(buf.data(), n);
  int status = pclose(p);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

// Runs the `theia` binary with these arguments.
inline RunResult run_theia(const std::string& args) { return run_shell(std::string(THEIA_BINARY) + " " + args); }

}  // namespace theia::test
