// libFuzzer target: image loading as textures and lights load images
// (scene/texture.h: the file read, channels chosen, encoding applied,
// non-finite and huge texels clamped).  The first byte picks the format by
// extension, as a scene names its files; the rest is the file.
#include "core/log.h"
#include "fuzz/fuzz_input.h"
#include "scene/texture.h"

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>

static constexpr uint64_t kMaxValues = uint64_t(1) << 16;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  theia::set_verbosity(theia::Verbosity::Quiet);
  if (size == 0) return 0;
  static const char* const kExtensions[] = {".exr", ".pfm", ".png", ".tga", ".hdr"};
  const std::string path = theia::fuzz::write_input(data + 1, size - 1, kExtensions[data[0] % 5]);
  theia::Image image;
  image.filename = path;
  image.is_color = (data[0] / 5) % 2 == 0;
  // Decoded sizes are capped through the loader's own limit (the route
  // --memory-limit takes): a 4 KB input may decode to 16 million values, and
  // zeroing and converting those was most of an input's time, for no more code
  // than a small image reaches.
  static const theia::ImageReserve cap = [](uint64_t w, uint64_t h, uint64_t c) {
    return w * h * c <= kMaxValues ? std::string() : std::string("over the fuzzing cap");
  };
  try {
    theia::load_image(image, "", cap);
  } catch (const theia::Error&) {
    return 0;
  }
  // What a loaded image promises the renderer: finite texels, a consistent size.
  if (image.pixels.size() != size_t(image.width) * size_t(image.height) * size_t(image.channels)) std::abort();
  for (float v : image.pixels)
    if (!std::isfinite(v)) std::abort();
  return 0;
}
