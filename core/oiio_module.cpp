// libtheia_oiio.so: OpenImageIO's image readers behind the one entry point
// declared in core/oiio_module.h.  Built on its own (not part of theia_core)
// and loaded with dlopen; everything but the entry point is hidden.
#include "core/oiio_module.h"

#include <OpenImageIO/imageio.h>

#include <filesystem>

namespace {

bool fail(std::string& error, std::string why, const char* otherwise) {
  error = why.empty() ? otherwise : std::move(why);
  return false;
}

}  // namespace

extern "C" __attribute__((visibility("default"))) bool theia_oiio_read_image(const char* path,
                                                                              theia::ImageBuffer& img,
                                                                              theia::ImageFileInfo& info,
                                                                              const theia::ImageReserve& reserve,
                                                                              std::string& error) try {
  OIIO::ImageSpec config;
  // Keep straight alpha as stored: textures and metrics want the file's values,
  // not OpenImageIO's premultiplied conversion of PNG/TGA.
  config.attribute("oiio:UnassociatedAlpha", 1);
  auto in = OIIO::ImageInput::open(path, &config);
  if (!in) return fail(error, OIIO::geterror(), "unknown format");
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 || spec.depth > 1)
    return fail(error,
                "unsupported image shape " + std::to_string(spec.width) + "x" + std::to_string(spec.height) + "x" +
                    std::to_string(spec.depth) + " with " + std::to_string(spec.nchannels) + " channels",
                "");

  std::error_code ec;
  const uintmax_t file_bytes = std::filesystem::file_size(path, ec);
  if (ec) return fail(error, ec.message(), "cannot stat the file");
  const std::string refused = theia::image_size_refusal(uint64_t(spec.width), uint64_t(spec.height),
                                                        uint64_t(spec.nchannels), uint64_t(file_bytes), reserve);
  if (!refused.empty()) return fail(error, refused, "");
  img.width = spec.width;
  img.height = spec.height;
  img.channels.clear();
  for (int c = 0; c < spec.nchannels; ++c) {
    std::string name = c < int(spec.channelnames.size()) ? spec.channelnames[size_t(c)] : std::string();
    img.channels.push_back(name.empty() ? "channel" + std::to_string(c) : name);
  }
  img.data.resize(img.pixel_count() * size_t(spec.nchannels));
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, img.data.data()))
    return fail(error, "cannot read pixels: " + in->geterror(), "cannot read pixels");
  info.format_name = in->format_name();
  auto bt = OIIO::TypeDesc::BASETYPE(spec.format.basetype);
  info.float_pixels = bt == OIIO::TypeDesc::HALF || bt == OIIO::TypeDesc::FLOAT || bt == OIIO::TypeDesc::DOUBLE;
  in->close();
  return true;
} catch (const std::exception& e) {
  return fail(error, e.what(), "unknown error");
}
