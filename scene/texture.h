// Texture images and texture evaluation for scene/scene.h's Texture and Image.
//
// Conventions are pbrt-v4's: texture (s, t) has t = 0 at the bottom of the
// image, pixel centres sit at half-integers, lookups are bilinear (nearest
// for the "point" filter, MIP-mapped for "trilinear" and "ewa", scene/mipmap.h), and an
// imagemap is scale * lookup, inverted (1 - that, clamped at 0) if asked.
// Evaluation runs on the hot shading path: it allocates nothing, takes no
// locks and makes no virtual calls (a switch on TextureKind).
#pragma once

#include "scene/scene.h"

#include "core/image.h"

#include <cstdint>
#include <string>

namespace theia {

// Reads every Scene::images[i] from its filename (in parallel) into linear
// float pixels: 1 channel (grey), 2 (grey, alpha), 3 (RGB) or 4 (RGBA; R, G,
// B, A picked by name when the file has more channels).  Integer files (PNG,
// TGA, JPEG, ...) are decoded by Image::encoding: "sRGB" (their default),
// "linear" or "gamma G" (v^G); alpha is never decoded.  Float files (EXR,
// PFM, HDR) are linear whatever the encoding says, as in pbrt-v4.  Relative
// filenames are looked up beside Scene::path first, then as given.  Images
// with pixels already present and no filename are left alone.  Throws
// theia::Error naming the file.  Then builds the MIP pyramids trilinear and EWA
// textures need (build_mipmaps, scene/mipmap.h).
// `max_bytes`: what the images' float values may take together (the memory
// limit's share left for them), checked from each header before its pixels
// are allocated; the image at which they would exceed it is a located error.
void load_images(Scene& scene, uint64_t max_bytes = UINT64_MAX);
// One image; `base_dir` as above ("" = as given); `reserve` as read_image_file's (core/image.h).
void load_image(Image& image, const std::string& base_dir = "", const ImageReserve& reserve = {});

// uv's screen-space derivatives: the filter footprint of trilinear and EWA imagemaps
// (all zero = no footprint: level 0).  theia has no ray differentials; the
// engine approximates them from the camera (texture_footprint, scene/camera.h).
struct UVFootprint {
  float dudx = 0, dudy = 0, dvdx = 0, dvdy = 0;
};
// Whether evaluating the texture (and the textures it reads) reads the
// footprint: trilinear and EWA imagemaps and the 2D checkerboard; elsewhere the
// engine need not compute one.  True past a nesting depth of 16 (a cycle).
bool texture_reads_footprint(const Scene& scene, int texture, int depth = 0);
// p is in render space; n is the geometric normal (only "directionmix" reads
// it; zero where the caller has none, e.g. alpha tests).
struct TextureEvalContext {
  vec2 uv;
  vec3 p;
  UVFootprint fp;
  vec3 n{0.0f};
};

// pbrt-v4's 2D texture coordinates: st and its screen-space derivatives
// (dst0 = (ds/dx, dt/dx), dst1 = (ds/dy, dt/dy)).  Only the uv mapping has
// derivatives: theia has no dp/dx, dp/dy, so spherical, cylindrical and planar
// mappings return a zero footprint.
struct TexCoord2D {
  vec2 st;
  vec2 dst0{0.0f}, dst1{0.0f};
};
TexCoord2D map_texture_2d(const Texture& tex, const TextureEvalContext& ctx);

// pbrt-v4's filtered checkerboard weight of tex2 (0 = tex1, 1 = tex2, between
// them near an edge inside the footprint): 2D over st, 3D (Point3D mapping)
// over p in texture space with a zero footprint.
float checkerboard_weight(const Texture& tex, const TextureEvalContext& ctx);
// pbrt-v4's InsidePolkaDot: one dot of radius 0.35 in about half the unit
// cells around integer st, its centre jittered by noise.
bool inside_polka_dot(vec2 st);

// Spectrum texture.  A missing child (index -1) takes pbrt-v4's default for
// that slot: checkerboard tex1 = 1, tex2 = 0; scale tex = 1, scale = 1;
// mix and directionmix tex1 = 0, tex2 = 1, amount = 0.5; dots inside 0,
// outside 1 (scene/texture_params.cpp says why).
RGB eval_texture(const Scene& scene, int texture, const TextureEvalContext& ctx);
// Float texture: the first channel wherever a texture or image has several.
float eval_float_texture(const Scene& scene, int texture, const TextureEvalContext& ctx);

// Bilinear lookup in texture coordinates: st in [0,1]^2, t = 0 the bottom row.
// Grey images return (v, v, v).  An image without pixels returns black.
RGB image_lookup_bilinear(const Image& image, vec2 st, WrapMode wrap);
// Nearest texel (pbrt-v4's "point" filter), st as above.
RGB image_lookup_nearest(const Image& image, vec2 st, WrapMode wrap);
// The same in raster coordinates, p in [0,1]^2 with (0, 0) the top-left corner
// (pbrt-v4's Image::Bilerp): for environment maps, which are not flipped.
RGB image_bilerp(const Image& image, vec2 p, WrapMode wrap);
// One texel, integer raster coordinates remapped by `wrap`; black outside
// the image for WrapMode::Black.
RGB image_texel(const Image& image, ivec2 p, WrapMode wrap);
// The texel at p, which must lie in the (non-empty) image.
inline RGB texel_value(const Image& img, ivec2 p) {
  const float* v = &img.pixels[(size_t(p.y) * size_t(img.width) + size_t(p.x)) * size_t(img.channels)];
  return img.channels >= 3 ? RGB(v[0], v[1], v[2]) : RGB(v[0]);
}

}  // namespace theia
