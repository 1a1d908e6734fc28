// A many-lights test scene for the cache-point tests (unit and e2e): a floor
// split by a wall, with `n` x `n` small one-sided emissive quads on each side
// of the wall facing away from it (quad k's radiance from `radiance(k)`),
// optionally a dim sky; `coincident` puts every quad at one place, in the wall.
#pragma once

#include <fmt/format.h>

#include <string>

namespace theia::test {

inline std::string street_scene(int n, float (*radiance)(int), bool sky, bool coincident = false,
                                const std::string& view = "LookAt 0 3 -12  0 1 0  0 1 0\n", float half = 0.2f) {
  std::string s = "Film \"rgb\" \"integer xresolution\" [32] \"integer yresolution\" [24]\n" + view +
                  "Camera \"perspective\" \"float fov\" [50]\nWorldBegin\n";
  if (sky) s += "LightSource \"infinite\" \"rgb L\" [0.01 0.01 0.02]\n";
  s += "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
       "Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point3 P\" [-10 0 -10 10 0 -10 10 0 10 -10 0 10]\n"
       "Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point3 P\" [0 0 -10 0 0 10 0 6 10 0 6 -10]\n";
  int k = 0;
  for (int side = 0; side < 2; ++side)
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j, ++k) {
        const float L = radiance(k), h = half;
        const float x = coincident ? 0.0f : (side == 0 ? -0.05f : 0.05f);
        const float z = coincident ? 0.0f : -8.0f + 16.0f * (float(i) + 0.5f) / float(n);
        const float y = coincident ? 1.0f : 0.5f + 5.0f * (float(j) + 0.5f) / float(n);
        // Winding: facing -x on the left side, +x on the right.
        const std::string P =
            side == 0 ? fmt::format("{} {} {} {} {} {} {} {} {} {} {} {}", x, y - h, z - h, x, y - h, z + h, x, y + h,
                                    z + h, x, y + h, z - h)
                      : fmt::format("{} {} {} {} {} {} {} {} {} {} {} {}", x, y - h, z - h, x, y + h, z - h, x, y + h,
                                    z + h, x, y - h, z + h);
        s += fmt::format(
            "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [{} {} {}]\n"
            "Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point3 P\" [{}]\nAttributeEnd\n",
            L, L, L, P);
      }
  return s;
}

}  // namespace theia::test
