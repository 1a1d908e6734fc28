// pbrt-v4's "loopsubdiv" shape: Loop subdivision of a triangle mesh, then an
// ordinary TriangleMesh.
//
// As pbrt-v4's LoopSubdivide: each level splits every triangle in four, even
// (old) vertices move by the valence rule (beta = 3/16 at valence 3, else
// 3 / (8 valence)), odd (edge) vertices by 3/8-3/8-1/8-1/8; on the boundary
// the crease rules (1/8-6/8-1/8 for even vertices, edge midpoints for odd
// ones).  After the last level every vertex is pushed to its limit position
// (interior: 1 / (valence + 3 / (8 beta)) per ring vertex; boundary: pbrt-v4's
// 1/5-3/5-1/5) and gets pbrt-v4's limit normal, the cross product of the two
// limit tangents.  That normal points against the right-hand normal of the
// winding (a mesh wound clockwise seen from outside gets outward normals), and
// since a mesh's shading normal decides its side, so does the surface.
#pragma once

#include "scene/params.h"
#include "scene/scene.h"

#include <span>
#include <string>

namespace theia {

// Subdivides `levels` times (0: the input connectivity, still pushed to the
// limit surface).  The mesh must be manifold and consistently oriented (each
// edge in at most two triangles, running opposite ways; each vertex's
// triangles one fan); otherwise returns false with *error saying what is
// wrong.  Unreferenced vertices are kept as they are, with a zero normal.
bool loop_subdivide(std::span<const vec3> p, std::span<const uint32_t> indices, int levels, TriangleMesh* out,
                    std::string* error);

// The shape's parameters ("integer levels" = 3, "integer indices", "point3 P")
// to the subdivided mesh in object space; bad input is a file:line error.
// False (with a warning) when there is nothing to subdivide.
bool loop_subdiv_from_params(const ParamList& params, const SourceLoc& loc, TriangleMesh* out);

}  // namespace theia
