// The MakeNamedMedium directive read into a `Medium` with pbrt-v4's defaults
// and checks (kept out of parser.cpp).
#pragma once

#include "scene/params.h"
#include "scene/scene.h"

#include <string>

namespace theia {

// `type` "homogeneous", "uniformgrid", "rgbgrid", "cloud" or "nanovdb"
// (its file relative to `base_dir`); `render_from_medium` is the CTM at the
// directive.
Medium read_medium(const std::string& name, const std::string& type, const ParamList& params, const SourceLoc& loc,
                   const Transform& render_from_medium, const std::string& base_dir);

}  // namespace theia
