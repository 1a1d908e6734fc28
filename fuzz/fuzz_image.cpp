// libFuzzer target: image loading as textures and lights load images
// (scene/texture.h: the file read, channels chosen, encoding applied,
// non-finite and huge texels clamped).  The first byte picks the format by
// extension, as a scene names its files; the rest is the file.
#include "core/log.h"
#include "fuzz/fuzz_input.h"
#include "scene/texture.h"

#include <cmath>
#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  theia::set_verbosity(theia::Verbosity::Quiet);
  if (size == 0) return 0;
  static const char* const kExtensions[] = {".exr", ".pfm", ".png", ".tga", ".hdr"};
  const std::string path = theia::fuzz::write_input(data + 1, size - 1, kExtensions[data[0] % 5]);
  theia::Image image;
  image.filename = path;
  image.is_color = (data[0] / 5) % 2 == 0;
  try {
    theia::load_image(image, "");
  } catch (const theia::Error&) {
    return 0;
  }
  // What a loaded image promises the renderer: finite texels, a consistent size.
  if (image.pixels.size() != size_t(image.width) * size_t(image.height) * size_t(image.channels)) std::abort();
  for (float v : image.pixels)
    if (!std::isfinite(v)) std::abort();
  return 0;
}
