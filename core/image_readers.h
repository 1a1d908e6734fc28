// Readers for the formats textures often come in, without OpenImageIO: PFM
// by hand (a header and raw floats, as pbrt-v4 reads it too), TGA, BMP and
// Radiance HDR through Debian's stb_image.  Loading OpenImageIO's dependency
// tree costs a process about 120 MB of resident memory (core/oiio_module.h),
// more than most scenes' geometry.  PNG and JPEG stay with OpenImageIO, whose
// libpng and libjpeg are hardened against hostile files where stb_image's
// decoders of those formats have had crashes reported.
//
// Each reader returns what OpenImageIO's would (tested against it): the
// stored values as float (8-bit x (1 / 255), its rounding), row 0 at the
// top, channels named R G B A, or Y (and A) for grey, straight alpha.
#pragma once

#include "core/image.h"

#include <string>

namespace theia {

enum class ImageReader { OpenEXR, PFM, StbImage, OpenImageIO };

// Chosen from the file's first bytes (TGA, which has no magic number, by its extension).
ImageReader image_reader_for(const std::string& path);

// Throw theia::Error("path: reason"), before allocating anything the file
// cannot hold or `reserve` refuses (core/image.h).
ImageBuffer read_pfm(const std::string& path, ImageFileInfo* info, const ImageReserve& reserve = {});
ImageBuffer read_with_stb_image(const std::string& path, ImageFileInfo* info, const ImageReserve& reserve = {});

}  // namespace theia
