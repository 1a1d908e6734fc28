// pbrt-v4's "diffuse" AreaLightSource made concrete for one shape: "power"
// resolved the way pbrt-v4 resolves it.  Kept apart from the parser proper,
// which reads the parameters and supplies the image lookup.
#pragma once

#include "scene/scene.h"

namespace theia {

// An AreaLightSource as declared, before a shape gives it an area.
struct AreaLightParams {
  RGB L{1.0f};          // luminance-normalised "L" times "scale"; RGB("scale") with an image
  int image = -1;       // "filename": index into Scene::images
  float power = -1.0f;  // "power" if > 0
  bool two_sided = false, is_virtual = false;
};

// The Light of emissive shape `shape_index`.  pbrt-v4 makes one
// DiffuseAreaLight per triangle of a mesh, and "power" phi gives each of them
// radiance phi / (pi * sides * area * k_e): theia keeps one Light per shape
// and stores the per-triangle factors (Light::triangle_scale).  Quadrics
// divide by their object-space area (pbrt_quadric_area).  k_e, the image's
// mean luminance, needs the pixels and is applied by LightSet.
Light make_area_light(const Scene& scene, const AreaLightParams& params, const Shape& shape, int shape_index);

}  // namespace theia
