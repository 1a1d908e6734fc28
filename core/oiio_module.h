// The boundary between theia and libtheia_oiio.so, the module through which
// theia reaches OpenImageIO.  Debian's OpenImageIO links about 250 shared
// libraries (OpenCV, GDAL, ffmpeg, ...), and relocating them costs every
// process that loads them a third of a CPU-second and 120 MB, so only a read
// of a format neither OpenEXR nor core/image_readers.h handles (PNG, JPEG,
// TIFF, ...) loads the module, with dlopen, on first use (core/image.cpp).
#pragma once

#include "core/image.h"

#include <string>

namespace theia {

inline constexpr const char* kOiioModuleFile = "libtheia_oiio.so";
inline constexpr const char* kOiioReadImageSymbol = "theia_oiio_read_image";

// read_image_file for any format OpenImageIO reads.  Returns false with a
// reason in `error` instead of throwing: no exception crosses the module
// boundary, and the module needs nothing of theia but these plain structs.
using OiioReadImage = bool (*)(const char* path, ImageBuffer& image, ImageFileInfo& info, const ImageReserve& reserve,
                               std::string& error);

}  // namespace theia
