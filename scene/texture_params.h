// pbrt-v4 Texture directives to scene/scene.h's Texture: classes, mappings,
// parameter names, defaults, and the errors and warnings for bad or
// unsupported input.  Kept apart from the parser proper, which supplies
// texture and image lookups and the CTM.
#pragma once

#include "scene/params.h"
#include "scene/scene.h"

#include <functional>

namespace theia {

struct TextureLookups {
  // A texture-valued parameter (texture reference or constant) as a texture index.
  std::function<int(const ParamList&, std::string_view name, bool is_float, RGB def, ParamList::SpectrumUse)> texture;
  // An image file named relative to the scene file: colour (converted to the
  // working space) or data.
  std::function<int(const std::string& filename, const std::string& encoding, bool is_color, const SourceLoc&)> image;
};

// `render_from_texture` is the CTM at the directive (pbrt-v4 keeps its inverse
// for every mapping but uv, and turns "dir" of directionmix by it).  Throws
// (file:line:col) on malformed parameters and on classes pbrt-v4 does not have
// for the texture's type; warns and substitutes a constant 0.5 for classes
// theia does not implement (ptex).
Texture parse_texture(const std::string& name, bool is_float, const std::string& cls, const ParamList& params,
                      const Transform& render_from_texture, const SourceLoc& loc, const TextureLookups& lookups);

}  // namespace theia
