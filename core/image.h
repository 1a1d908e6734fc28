// Image buffers and image files.  Everything in memory is linear float,
// interleaved, row 0 at the top (OpenImageIO's and pbrt-v4's raster order).
// EXR is read and written with OpenEXR, the PNG preview written with libpng;
// PFM, TGA, BMP and HDR are read by core/image_readers.h, every other
// format (PNG and JPEG included) through OpenImageIO, loaded only when such a file is read
// (core/oiio_module.h says why).  The libraries' headers stay in
// image.cpp so that this header is cheap to include.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace theia {

struct ImageBuffer {
  int width = 0, height = 0;
  std::vector<std::string> channels;  // e.g. R G B A albedo.R ...
  std::vector<float> data;            // width * height * channels.size(), interleaved

  ImageBuffer() = default;
  ImageBuffer(int w, int h, std::vector<std::string> names, float fill = 0.0f)
      : width(w), height(h), channels(std::move(names)),
        data(size_t(w) * size_t(h) * channels.size(), fill) {}

  int num_channels() const { return int(channels.size()); }
  size_t pixel_count() const { return size_t(width) * size_t(height); }
  size_t offset(int x, int y, int c) const {
    return (size_t(y) * size_t(width) + size_t(x)) * channels.size() + size_t(c);
  }
  float& at(int x, int y, int c) { return data[offset(x, y, c)]; }
  float at(int x, int y, int c) const { return data[offset(x, y, c)]; }
  // Index of the channel with this exact name, or -1.
  int channel_index(const std::string& name) const;
  // Indices of R, G, B by name, falling back to the first three channels
  // (fewer if the image has fewer); the convention every metric and preview uses.
  std::vector<int> rgb_channel_indices() const;
};

// What the file held before conversion to float: decides the default
// colour encoding of textures (8/16-bit integer files are display-encoded).
struct ImageFileInfo {
  std::string format_name;    // "openexr", or OpenImageIO's plugin name: "png", "targa", "pnm" (PFM), ...
  bool float_pixels = false;  // half/float/double samples in the file
};

// A header promising more pixel values than kMaxImageExpansion per byte of
// the file is refused before anything is allocated (a 16000x16000 header over
// a 100-byte body asked for 3 GB).  Deflate expands at most 1032:1, so PNG
// and ZIP-compressed EXR stay far below; so do RLE, B44 and a flat JPEG.
// Every reader asks this (core/image_readers.cpp, the OpenImageIO module).
inline constexpr uint64_t kMaxImageExpansion = 4096;
inline bool image_size_fits(uint64_t width, uint64_t height, uint64_t channels, uint64_t file_bytes) {
  if (width == 0 || height == 0 || channels == 0) return true;
  const uint64_t budget =
      file_bytes > UINT64_MAX / kMaxImageExpansion ? UINT64_MAX : file_bytes * kMaxImageExpansion;
  return width <= budget / height && width * height <= budget / channels;
}
// Why such a file is refused, in every reader's words.
inline std::string image_size_error(uint64_t width, uint64_t height, uint64_t channels, uint64_t file_bytes) {
  return "the header's " + std::to_string(width) + "x" + std::to_string(height) + "x" + std::to_string(channels) +
         " values cannot come from a file of " + std::to_string(file_bytes) + " bytes (truncated or corrupt)";
}

// Asked by a reader once the header gives the image's size, before its float
// values are allocated: "" to go on, or why not (the scene's images against
// a memory limit, scene/texture.h).  It must not throw (it is called inside
// the OpenImageIO module too, core/oiio_module.h).
using ImageReserve = std::function<std::string(uint64_t width, uint64_t height, uint64_t channels)>;

// Every reader's check before it allocates: "" or why the header's size is refused.
inline std::string image_size_refusal(uint64_t width, uint64_t height, uint64_t channels, uint64_t file_bytes,
                                      const ImageReserve& reserve) {
  if (!image_size_fits(width, height, channels, file_bytes)) return image_size_error(width, height, channels, file_bytes);
  return reserve ? reserve(width, height, channels) : std::string();
}

// Any format OpenImageIO reads (EXR, PFM, PNG, TGA, JPEG, HDR, ...), first subimage,
// all channels, values as stored (no colour conversion, alpha not premultiplied).
// EXR (told by its magic number, not the name) comes back as OpenImageIO
// presented it: channels by layer, R G B A first within one.
// Throws theia::Error("path: reason"); `reserve` may refuse the size first.
ImageBuffer read_image_file(const std::string& path, ImageFileInfo* info = nullptr, const ImageReserve& reserve = {});

// Multi-channel float32 OpenEXR (zip), channel names as given.  Written to
// path + ".tmp" and renamed, so a crash never leaves a truncated file at path.
// `compression` is an OpenEXR method ("zip" for outputs; checkpoints, written
// often and read rarely, use a faster one).
void write_exr(const std::string& path, const ImageBuffer& img, const char* compression = "zip");

// 8-bit sRGB-encoded preview of channels r, g, b (indices into img.channels),
// clamped to [0, 1]; NaN becomes 0.  Atomic like write_exr.
void write_png_srgb(const std::string& path, const ImageBuffer& img, int r, int g, int b);

// The sRGB transfer function (IEC 61966-2-1), exact rather than a 2.2 power.
inline float srgb_to_linear(float v) {
  if (v <= 0.04045f) return v * (1.0f / 12.92f);
  return std::pow((v + 0.055f) * (1.0f / 1.055f), 2.4f);
}
inline float linear_to_srgb(float v) {
  if (v <= 0.0031308f) return 12.92f * v;
  return 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}
// Clamped, rounded to nearest; NaN maps to 0.
inline uint8_t linear_to_srgb8(float v) {
  if (!(v > 0.0f)) return 0;
  if (v >= 1.0f) return 255;
  return uint8_t(std::lround(linear_to_srgb(v) * 255.0f));
}
// Decodes an 8-bit sRGB code value through a table (exact to float rounding).
float srgb8_to_linear(uint8_t v);
// srgb_to_linear(v), through a table when v is an 8-bit code value as the
// image readers give them (code * (1.0f / 255.0f)): the same value without a
// powf per texel, which was 5% of living-room's 8-spp render.
float srgb_texel_to_linear(float v);

}  // namespace theia
