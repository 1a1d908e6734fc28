#include "core/image_readers.h"

#include "core/log.h"

#include <stb/stb_image.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>

namespace theia {

namespace fs = std::filesystem;

namespace {

uint64_t file_size(const std::string& path) {
  std::error_code ec;
  const uintmax_t n = fs::file_size(path, ec);
  if (ec) throw_error("{}: cannot read image ({})", path, ec.message());
  return n;
}

bool starts_with(const std::string& bytes, std::string_view magic) { return bytes.compare(0, magic.size(), magic) == 0; }

std::string lowercase_extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

// OpenImageIO's names: Y for one channel, R G B A otherwise; a second
// channel beside grey is its alpha.
std::vector<std::string> channel_names(int n) {
  if (n == 1) return {"Y"};
  if (n == 2) return {"Y", "A"};
  std::vector<std::string> names = {"R", "G", "B", "A"};
  names.resize(size_t(n));
  return names;
}

// ---------------------------------------------------------------- PFM

// "PF" (RGB) or "Pf" (grey), width, height, scale (negative: little-endian),
// each after white space, one white-space byte, then rows of floats from the
// bottom of the image up.
struct PfmHeader {
  int channels = 0;
  long long width = 0, height = 0;
  bool little_endian = true;
  uint64_t data_offset = 0;
};

PfmHeader read_pfm_header(std::istream& in, const std::string& path) {
  auto fail = [&](const char* what) -> PfmHeader { throw_error("{}: not a valid PFM file ({})", path, what); };
  PfmHeader h;
  char magic[2] = {};
  if (!in.read(magic, 2) || magic[0] != 'P' || (magic[1] != 'F' && magic[1] != 'f')) return fail("no PF/Pf magic");
  h.channels = magic[1] == 'F' ? 3 : 1;
  double scale = 0.0;
  if (!(in >> h.width >> h.height >> scale)) return fail("header");
  if (h.width <= 0 || h.height <= 0 || h.width > (1 << 24) || h.height > (1 << 24)) return fail("image size");
  if (!std::isfinite(scale) || scale == 0.0) return fail("scale");
  if (!std::isspace(in.get())) return fail("no white space after the scale");
  h.little_endian = scale < 0.0;
  h.data_offset = uint64_t(in.tellg());
  return h;
}

// ---------------------------------------------------------------- stb_image

struct StbFree {
  void operator()(void* p) const { stbi_image_free(p); }
};

template <typename T>
std::unique_ptr<T, StbFree> stb_pixels(T* p) {
  return std::unique_ptr<T, StbFree>(p);
}

const char* stb_format_name(const std::string& bytes, const std::string& path) {
  if (starts_with(bytes, "BM")) return "bmp";
  if (starts_with(bytes, "#?RADIANCE") || starts_with(bytes, "#?RGBE")) return "hdr";
  return lowercase_extension(path) == ".tga" ? "targa" : nullptr;
}

std::string first_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::string bytes(16, '\0');
  f.read(bytes.data(), std::streamsize(bytes.size()));
  bytes.resize(size_t(f.gcount()));
  return bytes;
}

}  // namespace

ImageReader image_reader_for(const std::string& path) {
  const std::string bytes = first_bytes(path);
  if (starts_with(bytes, "PF") || starts_with(bytes, "Pf")) return ImageReader::PFM;
  return stb_format_name(bytes, path) ? ImageReader::StbImage : ImageReader::OpenImageIO;
}

ImageBuffer read_pfm(const std::string& path, ImageFileInfo* info, const ImageReserve& reserve) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_error("{}: cannot open", path);
  const PfmHeader h = read_pfm_header(in, path);
  const uint64_t values = uint64_t(h.width) * uint64_t(h.height) * uint64_t(h.channels);
  const uint64_t size = file_size(path);
  if (h.data_offset > size || (size - h.data_offset) / sizeof(float) < values)
    throw_error("{}: cannot read image ({})", path,
                image_size_error(uint64_t(h.width), uint64_t(h.height), uint64_t(h.channels), size));
  const std::string refused = reserve ? reserve(uint64_t(h.width), uint64_t(h.height), uint64_t(h.channels)) : "";
  if (!refused.empty()) throw_error("{}: cannot read image ({})", path, refused);

  ImageBuffer img(int(h.width), int(h.height), channel_names(h.channels));
  const size_t row = size_t(h.width) * size_t(h.channels);
  for (long long y = h.height - 1; y >= 0; --y)
    if (!in.read(reinterpret_cast<char*>(&img.data[size_t(y) * row]), std::streamsize(row * sizeof(float))))
      throw_error("{}: not a valid PFM file (truncated pixel data)", path);
  if (h.little_endian != (std::endian::native == std::endian::little))
    for (float& v : img.data) v = std::bit_cast<float>(__builtin_bswap32(std::bit_cast<uint32_t>(v)));
  if (info) *info = {"pnm", true};  // OpenImageIO reads PFM with its PNM plugin
  return img;
}

ImageBuffer read_with_stb_image(const std::string& path, ImageFileInfo* info, const ImageReserve& reserve) {
  const char* format = stb_format_name(first_bytes(path), path);
  int w = 0, h = 0, n = 0;
  if (!format || !stbi_info(path.c_str(), &w, &h, &n))
    throw_error("{}: cannot read image ({})", path, stbi_failure_reason() ? stbi_failure_reason() : "unknown format");
  const uint64_t uw = uint64_t(std::max(w, 0)), uh = uint64_t(std::max(h, 0)), un = uint64_t(std::max(n, 0));
  const std::string refused = w <= 0 || h <= 0 || n <= 0 ? image_size_error(uw, uh, un, file_size(path))
                                                         : image_size_refusal(uw, uh, un, file_size(path), reserve);
  if (!refused.empty()) throw_error("{}: cannot read image ({})", path, refused);

  const size_t values = size_t(w) * size_t(h) * size_t(n);
  ImageBuffer img(w, h, channel_names(n));
  bool float_pixels = false;
  auto failed = [&]() -> ImageBuffer {
    throw_error("{}: cannot read image ({})", path, stbi_failure_reason() ? stbi_failure_reason() : "decoding failed");
  };
  const int info_w = w, info_h = h, info_n = n;
  auto same_shape = [&] { return w == info_w && h == info_h && n == info_n; };
  if (std::strcmp(format, "hdr") == 0) {
    auto px = stb_pixels(stbi_loadf(path.c_str(), &w, &h, &n, 0));
    if (!px || !same_shape()) return failed();
    std::copy_n(px.get(), values, img.data.begin());
    float_pixels = true;
  } else {
    auto px = stb_pixels(stbi_load(path.c_str(), &w, &h, &n, 0));
    if (!px || !same_shape()) return failed();
    std::transform(px.get(), px.get() + values, img.data.begin(),
                   [](uint8_t v) { return float(v) * (1.0f / 255.0f); });
  }
  if (info) *info = {format, float_pixels};
  return img;
}

}  // namespace theia
