#include "core/image.h"

#include "core/log.h"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <system_error>

namespace theia {

namespace fs = std::filesystem;

int ImageBuffer::channel_index(const std::string& name) const {
  for (size_t i = 0; i < channels.size(); ++i)
    if (channels[i] == name) return int(i);
  return -1;
}

std::vector<int> ImageBuffer::rgb_channel_indices() const {
  int r = channel_index("R"), g = channel_index("G"), b = channel_index("B");
  if (r >= 0 && g >= 0 && b >= 0) return {r, g, b};
  std::vector<int> idx;
  for (int c = 0; c < std::min(3, num_channels()); ++c) idx.push_back(c);
  return idx;
}

float srgb8_to_linear(uint8_t v) {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) t[size_t(i)] = srgb_to_linear(float(i) / 255.0f);
    return t;
  }();
  return table[v];
}

ImageBuffer read_image_file(const std::string& path, ImageFileInfo* info) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw_error("{}: no such file", path);
  OIIO::ImageSpec config;
  // Keep straight alpha as stored: textures and metrics want the file's values,
  // not OpenImageIO's premultiplied conversion of PNG/TGA.
  config.attribute("oiio:UnassociatedAlpha", 1);
  auto in = OIIO::ImageInput::open(path, &config);
  if (!in) {
    std::string why = OIIO::geterror();
    throw_error("{}: cannot read image ({})", path, why.empty() ? "unknown format" : why);
  }
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 || spec.depth > 1)
    throw_error("{}: unsupported image shape {}x{}x{} with {} channels", path, spec.width, spec.height,
                spec.depth, spec.nchannels);

  ImageBuffer img;
  img.width = spec.width;
  img.height = spec.height;
  img.channels.reserve(size_t(spec.nchannels));
  for (int c = 0; c < spec.nchannels; ++c) {
    std::string name = c < int(spec.channelnames.size()) ? spec.channelnames[size_t(c)] : std::string();
    img.channels.push_back(name.empty() ? fmt::format("channel{}", c) : name);
  }
  img.data.resize(img.pixel_count() * size_t(spec.nchannels));
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, img.data.data()))
    throw_error("{}: cannot read pixels ({})", path, in->geterror());
  if (info) {
    info->format_name = in->format_name();
    auto bt = OIIO::TypeDesc::BASETYPE(spec.format.basetype);
    info->float_pixels = bt == OIIO::TypeDesc::HALF || bt == OIIO::TypeDesc::FLOAT || bt == OIIO::TypeDesc::DOUBLE;
  }
  in->close();
  return img;
}

namespace {

// Writes through a temporary file and renames it over `path`, so readers never
// see a partial file and an existing output survives a failed write.
void write_atomic(const std::string& path, const char* format, const OIIO::ImageSpec& spec, OIIO::TypeDesc type,
                  const void* pixels) {
  std::string tmp = path + ".tmp";
  // Named by format, not by extension: "x.exr.tmp" has no extension OIIO knows.
  auto out = OIIO::ImageOutput::create(format);
  if (!out) throw_error("{}: no OpenImageIO writer for {} ({})", path, format, OIIO::geterror());
  std::error_code ec;
  auto fail = [&](const std::string& why) {
    out.reset();
    fs::remove(tmp, ec);
    throw_error("{}: cannot write image ({})", path, why);
  };
  if (!out->open(tmp, spec)) fail(out->geterror());
  if (!out->write_image(type, pixels)) fail(out->geterror());
  if (!out->close()) fail(out->geterror());
  out.reset();
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw_error("{}: cannot rename {} into place ({})", path, tmp, ec.message());
  }
}

void check_buffer(const std::string& path, const ImageBuffer& img) {
  if (img.width <= 0 || img.height <= 0 || img.channels.empty())
    throw_error("{}: cannot write an empty image ({}x{}, {} channels)", path, img.width, img.height,
                img.channels.size());
  if (img.data.size() != img.pixel_count() * img.channels.size())
    throw_error("{}: image buffer holds {} values, expected {}x{}x{}", path, img.data.size(), img.width,
                img.height, img.channels.size());
}

}  // namespace

void write_exr(const std::string& path, const ImageBuffer& img, const char* compression) {
  check_buffer(path, img);
  OIIO::ImageSpec spec(img.width, img.height, img.num_channels(), OIIO::TypeDesc::FLOAT);
  spec.channelnames = img.channels;
  spec.alpha_channel = img.channel_index("A");
  spec.z_channel = -1;
  spec.attribute("compression", compression);
  write_atomic(path, "openexr", spec, OIIO::TypeDesc::FLOAT, img.data.data());
}

void write_png_srgb(const std::string& path, const ImageBuffer& img, int r, int g, int b) {
  check_buffer(path, img);
  for (int c : {r, g, b})
    if (c < 0 || c >= img.num_channels())
      throw_error("{}: channel index {} out of range (image has {} channels)", path, c, img.num_channels());
  std::vector<uint8_t> px(img.pixel_count() * 3);
  size_t nc = img.channels.size();
  for (size_t i = 0; i < img.pixel_count(); ++i) {
    const float* p = &img.data[i * nc];
    px[3 * i + 0] = linear_to_srgb8(p[r]);
    px[3 * i + 1] = linear_to_srgb8(p[g]);
    px[3 * i + 2] = linear_to_srgb8(p[b]);
  }
  OIIO::ImageSpec spec(img.width, img.height, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", "sRGB");
  write_atomic(path, "png", spec, OIIO::TypeDesc::UINT8, px.data());
}

}  // namespace theia
