// MIP pyramids for image textures and pbrt-v4's trilinear and EWA MIPMap filters.
//
// Levels are area-weighted box reductions to ceil(n / 2) texels per axis down
// to 1x1: every output texel averages exactly the input area it covers, so
// each level keeps the image's mean (odd sizes included) and the last level
// is the mean.  The box never reaches outside the image, so the wrap mode
// plays no part in building; lookups apply it per level.
#pragma once

#include "scene/scene.h"

#include <cstddef>

namespace theia {

// Image::mip for one image (replaces any existing levels).
void build_mip_pyramid(Image& image);
// Pyramids, in parallel, for every image a trilinear or EWA imagemap texture
// reads; other images are left without one.
void build_mipmaps(Scene& scene);
// True for the filters that read a pyramid and so need a footprint.
inline bool filter_uses_mipmap(TextureFilter f) { return f == TextureFilter::Trilinear || f == TextureFilter::EWA; }

// Bytes of texel storage: all images and their pyramids / the pyramids alone.
size_t texture_memory_bytes(const Scene& scene);
size_t mip_memory_bytes(const Scene& scene);

// pbrt-v4's MIPMap::Filter with trilinear interpolation.  st as in
// image_lookup_bilinear (t = 0 the bottom row); dst0 = (ds/dx, dt/dx), dst1 =
// (ds/dy, dt/dy).  The filter width 2 max|d| picks the continuous level
// n_levels - 1 + log2(width), as pbrt-v4 does (exactly log2 of the width in
// level-0 texels for power-of-two images; a little coarser otherwise, as
// pbrt-v4's upsampled level 0 is); the lookup lerps bilinear lookups in the levels
// either side (level 0 below 0, the 1x1 mean at or past the last).  An image
// without a pyramid gets level-0 bilinear.
RGB image_lookup_trilinear(const Image& image, vec2 st, vec2 dst0, vec2 dst1, WrapMode wrap);

// pbrt-v4's MIPMap::Filter with EWA: the footprint is the ellipse with axes
// dst0 and dst1 (st, dst as above), its eccentricity clamped at
// max_anisotropy by growing the minor axis; the level comes from the minor
// axis (n_levels - 1 + log2 |minor|, at least 0), and the lookup lerps
// Gaussian-weighted sums over the ellipse (pbrt-v4's weight table, the
// ellipse widened by one texel for reconstruction) in the levels either side.
// No footprint is level-0 bilinear; at or past the last level it is the 1x1
// mean, as for trilinear (pbrt-v4 would still filter its one texel through
// the wrap mode there, darkening "black" wrap).  One deviation: pbrt-v4 flips
// t for the image but not dt/dx, dt/dy, which mirrors a sheared ellipse;
// theia flips both.  An image without a pyramid gets level-0 bilinear.
RGB image_lookup_ewa(const Image& image, vec2 st, vec2 dst0, vec2 dst1, WrapMode wrap, float max_anisotropy);

}  // namespace theia
