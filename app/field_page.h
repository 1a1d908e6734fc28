// The field viewer's page (tools/field_view/, embedded in the binary at build
// time) and the one picture it shares with `theia field image`: a leaf's
// directional distribution as a cylindrical map, coloured the same way in
// C++ and in the page's JavaScript so the two can be compared pixel for pixel.
#pragma once

#include "guiding/field_file.h"

#include <cstdint>
#include <string>
#include <vector>

namespace theia {

// width x (width / 2) RGB8: columns phi / 2 pi from 0 at the left, rows cos theta
// from +1 at the top (world axes), each pixel's density (field_leaf_density at
// its centre, seen from p: a mixture's lobes are re-pointed to p) on a log
// scale over three decades below the image's maximum.
std::vector<uint8_t> field_map_rgb(const FieldLeaf& leaf, int width, const vec3& p);

// index.html, viewer.js, field.js (the data) and three.js's files from Debian's libjs-three.
void write_field_page(const FieldFile& field, const std::string& dir);

// The snapshot of an iteration (-1: the last); throws theia::Error naming the file.
const FieldSnapshot& field_snapshot(const FieldFile& field, int iteration, const std::string& path);

}  // namespace theia
