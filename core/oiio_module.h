// The boundary between theia and libtheia_oiio.so, the module through which
// theia reaches OpenImageIO.  Debian's OpenImageIO links about 250 shared
// libraries (OpenCV, GDAL, ffmpeg, ...), and relocating them costs every
// process that loads them a third of a CPU-second and 130 MB, so only a read
// of a format OpenEXR does not handle (PNG, JPEG, TGA, PFM, HDR textures)
// loads the module, with dlopen, on first use (core/image.cpp).
#pragma once

#include "core/image.h"

#include <string>

namespace theia {

inline constexpr const char* kOiioModuleFile = "libtheia_oiio.so";
inline constexpr const char* kOiioReadImageSymbol = "theia_oiio_read_image";

// read_image_file for any format OpenImageIO reads.  Returns false with a
// reason in `error` instead of throwing: no exception crosses the module
// boundary, and the module needs nothing of theia but these plain structs.
using OiioReadImage = bool (*)(const char* path, ImageBuffer& image, ImageFileInfo& info, std::string& error);

// A header promising more pixel values than kMaxImageExpansion per byte of
// the file is refused before anything is allocated (a 16000x16000 header over
// a 100-byte body asked for 3 GB).  Deflate expands at most 1032:1, so PNG
// and ZIP-compressed EXR stay far below; so do RLE, B44 and a flat JPEG.
inline constexpr uint64_t kMaxImageExpansion = 4096;
inline bool image_size_fits(uint64_t width, uint64_t height, uint64_t channels, uint64_t file_bytes) {
  return width * height * channels <= file_bytes * kMaxImageExpansion;
}

}  // namespace theia
