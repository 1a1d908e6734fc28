// What a checkpoint must match to be resumed: the scene it was rendered from.
#pragma once

#include "scene/scene.h"

#include <cstdint>

namespace theia {

// A hash of everything in the scene that can change the image: the scene
// file's text, then the parsed data (geometry, so that a changed PLY or
// Include counts too; materials, textures and their images; lights; camera;
// film; filter).
uint64_t scene_fingerprint(const Scene& scene);

}  // namespace theia
