// pbrt-v4 material directives to scene/scene.h's Material: parameter names,
// defaults and the warnings for what theia substitutes.  Kept apart from the
// parser proper, which supplies texture, image and named-material lookups.
#pragma once

#include "scene/params.h"
#include "scene/scene.h"

#include <functional>

namespace theia {

struct MaterialLookups {
  // A texture-valued parameter (texture reference or constant) as a texture index.
  std::function<int(const ParamList&, std::string_view name, bool is_float, RGB def, ParamList::SpectrumUse)> texture;
  // An image file named relative to the scene file, read with the given encoding.
  std::function<int(const std::string& filename, const std::string& encoding, const SourceLoc&)> image;
  // A material defined by MakeNamedMaterial.
  std::function<int(const std::string& name, const SourceLoc&)> named_material;
};

// Throws (file:line) on malformed parameters; warns and substitutes diffuse
// 0.5 for material types theia does not implement.
Material parse_material(const std::string& type, const ParamList& params, const SourceLoc& loc,
                        const MaterialLookups& lookups);

}  // namespace theia
