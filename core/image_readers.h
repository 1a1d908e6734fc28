// Readers for the formats textures usually come in, without OpenImageIO:
// PFM by hand (a header and raw floats, as pbrt-v4 reads it too) and the
// 8/16-bit formats (PNG, JPEG, TGA, BMP) and Radiance HDR through Debian's
// stb_image.  Loading OpenImageIO's dependency tree costs a process about
// 125 MB of resident memory (core/oiio_module.h), more than most scenes'
// geometry; it stays the reader of every other format.
//
// Each reader returns what OpenImageIO's would (tested against it): the
// stored values as float (8-bit x (1 / 255), 16-bit x (1 / 65535), its
// rounding), row 0 at the top, channels named R G B A, or Y (and A) for
// grey, straight alpha.
#pragma once

#include "core/image.h"

#include <string>

namespace theia {

enum class ImageReader { OpenEXR, PFM, StbImage, OpenImageIO };

// Chosen from the file's first bytes (TGA, which has no magic number, by its extension).
ImageReader image_reader_for(const std::string& path);

// Throw theia::Error("path: reason"), before allocating anything the file cannot hold.
ImageBuffer read_pfm(const std::string& path, ImageFileInfo* info);
ImageBuffer read_with_stb_image(const std::string& path, ImageFileInfo* info);

}  // namespace theia
