// Triangle meshes from files and patches: PLY (ASCII, binary little and big
// endian) and pbrt-v4 bilinear patches.
#pragma once

#include "scene/scene.h"

#include <string>

namespace theia {

// Reads vertices (x y z; nx ny nz; u v | s t | texture_u texture_v |
// texture_s texture_t) and faces (`vertex_indices` or `vertex_index` lists of
// 3 or 4; quads are split into two triangles, other polygons skipped with a
// warning).  Any scalar type (char .. double) is accepted for any property.
// Other elements and properties (face_indices, ...) are skipped.  Throws
// theia::Error ("PATH: error: ...") for malformed or truncated files.
TriangleMesh read_ply(const std::string& path);

// pbrt-v4 bilinear patches (indices: 4 per patch, p00 p10 p01 p11) as
// triangles: a planar patch becomes two, a curved one a 16x16 grid of the
// bilinear surface with N and uv interpolated (uv defaults to the patch's
// (u, v)).  Without N, curved patches get the surface normal dp/du x dp/dv,
// negated when `flip_normals` (pbrt-v4: ReverseOrientation xor a
// handedness-swapping transform); planar ones then get it too.
TriangleMesh tessellate_bilinear_patches(const TriangleMesh& patches, bool flip_normals);

}  // namespace theia
