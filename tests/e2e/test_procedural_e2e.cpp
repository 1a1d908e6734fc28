// End-to-end: a scene using every pbrt-v4 mapping and procedural texture
// (as colours, roughness and bump maps) loads without a warning and renders
// finite, with the patterns visible.
#include "render_helpers.h"

#include "core/log.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace theia;
using namespace theia::test;

namespace {

const char* kScene = R"(
Film "rgb" "integer xresolution" [48] "integer yresolution" [32]
Integrator "volpath" "integer maxdepth" [4]
LookAt 0 4 -9  0 0.5 0  0 1 0
Camera "perspective" "float fov" [40]
WorldBegin
LightSource "infinite" "rgb L" [0.6 0.6 0.6]
LightSource "distant" "point3 from" [1 3 -2] "point3 to" [0 0 0] "rgb L" [2 2 2]

Texture "fbm" "float" "fbm" "integer octaves" 6 "float roughness" 0.6
Texture "wrinkled" "float" "wrinkled" "integer octaves" 5
Texture "windy" "float" "windy"
Texture "bumps" "float" "scale" "texture tex" "wrinkled" "float scale" 0.02
Texture "marble" "spectrum" "marble" "float scale" 3 "float variation" 0.8
Texture "dots" "spectrum" "dots" "rgb inside" [0.9 0.1 0.1] "rgb outside" [0.1 0.1 0.9] "float uscale" 8 "float vscale" 8
Texture "bilerp" "spectrum" "bilerp" "rgb v00" [1 0 0] "rgb v01" [0 1 0] "rgb v10" [0 0 1] "rgb v11" [1 1 1]
  "string mapping" "planar" "vector3 v1" [0.1 0 0] "vector3 v2" [0 0 0.1] "float udelta" 0.5 "float vdelta" 0.5
Texture "check3" "spectrum" "checkerboard" "integer dimension" 3 "texture tex1" "marble" "rgb tex2" [0.2 0.2 0.2]
Texture "sph" "spectrum" "checkerboard" "string mapping" "spherical" "rgb tex1" [0.8 0.8 0.8] "rgb tex2" [0.1 0.4 0.1]
Texture "dir" "spectrum" "directionmix" "texture tex1" "dots" "texture tex2" "sph" "vector3 dir" [0 1 0]
Texture "windmix" "spectrum" "mix" "texture tex1" "bilerp" "rgb tex2" [0.5 0.5 0.5] "texture amount" "windy"

AttributeBegin
  Material "diffuse" "texture reflectance" "windmix" "texture displacement" "bumps"
  Shape "trianglemesh" "point3 P" [-10 0 -10  10 0 -10  10 0 10  -10 0 10] "integer indices" [0 1 2 0 2 3]
    "point2 uv" [0 0 1 0 1 1 0 1]
AttributeEnd
AttributeBegin
  Translate -2.2 1 0
  Material "diffuse" "texture reflectance" "dir"
  Shape "sphere" "float radius" 1
AttributeEnd
AttributeBegin
  Translate 0 1 0
  Material "coateddiffuse" "texture reflectance" "check3" "texture roughness" "fbm"
  Shape "sphere" "float radius" 1
AttributeEnd
AttributeBegin
  Translate 2.2 1 0
  Rotate -90 1 0 0
  Texture "cyl_local" "spectrum" "checkerboard" "string mapping" "cylindrical" "rgb tex1" [0.9 0.9 0.9] "rgb tex2" [0.05 0.05 0.05]
  Material "diffuse" "texture reflectance" "cyl_local"
  Shape "sphere" "float radius" 1
AttributeEnd
)";

}  // namespace

TEST(ProceduralTextures, SceneWithEveryTextureLoadsCleanlyAndRendersFinite) {
  int before = warning_count();
  Scene scene = load_test_scene(kScene);
  EXPECT_EQ(warning_count() - before, 0);
  RenderResult r = render_scene(scene, quick_config(4));
  EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
  for (float v : r.image.data) ASSERT_TRUE(std::isfinite(v));
  // The patterns show: the image is far from flat.  No pixel has negative
  // luminance (channels may be: the output is sRGB, and saturated working-space
  // colours, e.g. where the bilerp extrapolates and is clamped, lie outside it).
  double sum = 0.0, sum2 = 0.0;
  int n = 0;
  for (int y = 0; y < r.image.height; ++y)
    for (int x = 0; x < r.image.width; ++x) {
      RGB c = pixel_rgb(r.image, x, y);
      double l = 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
      EXPECT_GE(l, -1e-6);
      sum += l;
      sum2 += l * l;
      ++n;
    }
  double mean = sum / n, sd = std::sqrt(std::max(0.0, sum2 / n - mean * mean));
  EXPECT_GT(mean, 0.05);
  EXPECT_GT(sd, 0.2 * mean);
}
