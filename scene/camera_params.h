// The Camera, Film and PixelFilter directives read into the scene's plain
// parameters with pbrt-v4's defaults (kept apart from the parser proper,
// which owns the transforms and the directive dispatch).
#pragma once

#include "scene/params.h"
#include "scene/scene.h"

namespace theia {

// Everything but render_from_camera, which the caller sets from its CTM.
void read_camera(const std::string& type, const ParamList& params, const SourceLoc& loc, CameraParams& camera);
void read_film(const std::string& type, const ParamList& params, const SourceLoc& loc, FilmParams& film);
void read_pixel_filter(const std::string& type, const ParamList& params, const SourceLoc& loc, FilterParams& filter);

}  // namespace theia
