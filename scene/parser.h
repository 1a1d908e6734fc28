// The pbrt-v4 scene format (https://pbrt.org/fileformat-v4) read into a Scene.
//
// What theia cannot render yet is reported with one counted warning and
// substituted (materials other than diffuse, unsupported shapes and lights);
// what is malformed throws theia::Error "FILE:LINE:COLUMN: error: ...".
// Images are only recorded in Scene::images (absolute path, encoding); they
// are loaded elsewhere.
//
// Conventions worth knowing when reading the result:
// - render space = pbrt's world space;
// - triangle meshes (trianglemesh, plymesh, bilinearmesh) are baked with the
//   CTM into render space at the Shape (inside ObjectBegin too: a prototype's
//   "object space" is the world space of its definition, and an Instance
//   carries the CTM at ObjectInstance); their Shape::render_from_object is
//   the identity.  Normals use the inverse transpose and are negated under
//   ReverseOrientation, as pbrt-v4 does when it creates the mesh;
// - a bilinear patch becomes two triangles when planar, else a 16x16 grid of
//   the bilinear surface with interpolated N and uv (default uv: the patch's
//   (u, v)); generated normals follow pbrt-v4's geometric normal;
// - PLY quads are split into two triangles (v0 v1 v2, v0 v2 v3).
#pragma once

#include "scene/scene.h"

#include <string>

namespace theia {

Scene load_scene(const std::string& path);
Scene parse_scene_string(const std::string& text, const std::string& name = "<string>",
                         const std::string& base_dir = ".");

}  // namespace theia
