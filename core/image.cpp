#include "core/image.h"

#include "core/image_readers.h"
#include "core/log.h"
#include "core/oiio_module.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfThreading.h>
#include <OpenEXR/ImfVersion.h>
#include <dlfcn.h>
#include <png.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <string_view>
#include <system_error>
#include <thread>

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

float srgb_texel_to_linear(float v) {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) t[size_t(i)] = srgb_to_linear(float(i) * (1.0f / 255.0f));
    return t;
  }();
  if (v >= 0.0f && v <= 1.0f) {
    const int code = int(v * 255.0f + 0.5f);
    if (v == float(code) * (1.0f / 255.0f)) return table[size_t(code)];
  }
  return srgb_to_linear(v);
}

namespace {

// ---------------------------------------------------------------- OpenEXR

bool is_exr_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  char magic[4] = {};
  return f.read(magic, sizeof(magic)) && Imf::isImfMagic(magic);
}

// OpenEXR (de)compresses blocks on its own thread pool, which is empty until
// asked for; OpenImageIO, which wrote theia's EXRs before, sized it to the cores.
void start_exr_threads() {
  static std::once_flag once;
  std::call_once(once, [] { Imf::setGlobalThreadCount(int(std::max(1u, std::thread::hardware_concurrency()))); });
}

bool iequals(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
         });
}

struct ExrChannel {
  std::string name, layer, suffix;  // "albedo.R" -> "albedo", "R"; "R" -> "", "R"
  int rank = 0;
  Imf::PixelType type = Imf::FLOAT;
};

// OpenEXR lists channels alphabetically (B G R).  They are presented in the
// order OpenImageIO gave them, so that positional readers keep working: by
// layer, and within a layer the colour channels, then alpha and depth (or,
// in a layer holding X with Y or Z, a vector: colour, X Y Z, then alpha),
// then the rest by name.
void sort_exr_channels(std::vector<ExrChannel>& chans) {
  static constexpr std::string_view colour_order[] = {"R", "Red", "G", "Green", "B", "Blue", "Y", "real", "imag", "A",
                                                "Alpha", "AR", "RA", "AG", "GA", "AB", "BA", "Z", "Depth", "Zback"};
  static constexpr std::string_view vector_order[] = {"R",    "Red", "G",  "Green", "B",  "Blue", "X",
                                                "Y",    "Z",   "real", "imag", "A", "Alpha", "AR",
                                                "RA",   "AG",  "GA", "AB",    "BA", "Depth", "Zback"};
  auto by_layer = [](const ExrChannel& a, const ExrChannel& b) { return a.layer < b.layer; };
  std::stable_sort(chans.begin(), chans.end(), by_layer);
  for (auto first = chans.begin(); first != chans.end();) {
    auto last = std::find_if(first, chans.end(), [&](const ExrChannel& c) { return c.layer != first->layer; });
    auto has = [&](std::string_view s) {
      return std::any_of(first, last, [&](const ExrChannel& c) { return iequals(c.suffix, s); });
    };
    bool is_vector = has("X") && (has("Y") || has("Z"));
    for (auto c = first; c != last; ++c) {
      auto find_rank = [&](const auto& order) {
        for (size_t i = 0; i < std::size(order); ++i)
          if (iequals(c->suffix, order[i])) return int(i);
        return int(std::size(order));
      };
      c->rank = is_vector ? find_rank(vector_order) : find_rank(colour_order);
    }
    std::sort(first, last, [](const ExrChannel& a, const ExrChannel& b) {
      return a.rank != b.rank ? a.rank < b.rank : a.suffix < b.suffix;
    });
    first = last;
  }
}

// Bytes OpenEXR 3.1 reads for an attribute value of a fixed-size type,
// whatever the size the file declares (0: it reads the declared size).
uint64_t exr_fixed_value_bytes(const std::string& type) {
  static constexpr std::pair<std::string_view, uint64_t> sizes[] = {
      {"box2i", 16}, {"box2f", 16}, {"chromaticities", 32}, {"compression", 1}, {"deepImageState", 1},
      {"double", 8}, {"envmap", 1},  {"float", 4},           {"int", 4},         {"keycode", 28},
      {"lineOrder", 1}, {"m33f", 36}, {"m33d", 72},          {"m44f", 64},       {"m44d", 128},
      {"rational", 8}, {"tiledesc", 9}, {"timecode", 8},     {"v2i", 8},         {"v2f", 8},
      {"v2d", 16},     {"v3i", 12},     {"v3f", 12},         {"v3d", 24}};
  for (const auto& [name, bytes] : sizes)
    if (type == name) return bytes;
  return 0;
}

// Why an OpenEXR header asks for more than its file holds, or "" (OpenEXR
// judges the rest).  OpenEXR 3.1 allocates what a header declares before it
// reads it: an attribute's value (a 138-byte file claiming a 1.8 GB string
// was found by fuzzing), a preview image, and line buffers sized by the data
// window (a 424-byte file took minutes).  Each header (one, or a list in a
// multi-part file) is a sequence of name, type name, 4-byte little-endian
// size and value, ended by an empty name; values are walked as OpenEXR reads
// them (a channel list up to its empty name, fixed-size types by their type).
std::string exr_header_refusal(const std::string& path, uint64_t file_bytes) {
  std::ifstream f(path, std::ios::binary);
  char start[8];
  if (!f.read(start, 8)) return "";
  const bool multipart = (uint8_t(start[5]) & 0x10) != 0;  // version flags, bit 12
  auto read_name = [&](std::string& name) {
    name.clear();
    for (char c; f.get(c);) {
      if (c == '\0') return true;
      if (name.size() == 255) return false;
      name += c;
    }
    return false;
  };
  auto read_u32 = [&](uint32_t& v) {
    unsigned char b[4];
    if (!f.read(reinterpret_cast<char*>(b), 4)) return false;
    v = uint32_t(b[0]) | uint32_t(b[1]) << 8 | uint32_t(b[2]) << 16 | uint32_t(b[3]) << 24;
    return true;
  };
  auto left = [&] { return file_bytes - std::min(uint64_t(f.tellg()), file_bytes); };
  auto too_big = [&](const std::string& name, uint64_t bytes) {
    return fmt::format("header attribute \"{}\" claims {} bytes, more than the file's {} (truncated or corrupt)", name,
                       bytes, file_bytes);
  };
  for (std::string name, type;;) {
    if (!read_name(name)) return "";
    if (name.empty()) {  // the end of a header; in a multi-part file, an empty header ends the list
      if (!multipart || f.peek() == 0 || f.peek() == EOF) return "";
      continue;
    }
    uint32_t size = 0;
    if (!read_name(type) || !read_u32(size)) return "";
    if (int32_t(size) < 0 || size > left()) return too_big(name, size);
    if (type == "chlist") {
      for (std::string channel; read_name(channel) && !channel.empty();)
        if (!f.seekg(16, std::ios::cur)) return "";
    } else if (type == "preview") {
      uint32_t w = 0, h = 0;
      if (!read_u32(w) || !read_u32(h)) return "";
      if (uint64_t(w) * h * 4 > left()) return too_big(name, uint64_t(w) * h * 4);
      f.seekg(std::streamoff(uint64_t(w) * h * 4), std::ios::cur);
    } else if (type == "stringvector") {
      for (uint64_t read = 0; read < size;) {
        uint32_t n = 0;
        if (!read_u32(n)) return "";
        if (n > left()) return too_big(name, n);
        f.seekg(n, std::ios::cur);
        read += 4 + uint64_t(n);
      }
    } else if (name == "dataWindow" && type == "box2i") {
      int32_t box[4];
      if (!f.read(reinterpret_cast<char*>(box), 16)) return "";
      const int64_t w = int64_t(box[2]) - box[0] + 1, h = int64_t(box[3]) - box[1] + 1;
      if (w > 0 && h > 0 && !image_size_fits(uint64_t(w), uint64_t(h), 1, file_bytes))
        return image_size_error(uint64_t(w), uint64_t(h), 1, file_bytes);
    } else {
      const uint64_t fixed = exr_fixed_value_bytes(type);
      f.seekg(std::streamoff(fixed ? fixed : size), std::ios::cur);
    }
    if (!f) return "";
  }
}

// The first part of a scanline or tiled file, every channel as float.
ImageBuffer read_exr(const std::string& path, ImageFileInfo* info, const ImageReserve& reserve) {
  std::error_code ec;
  const uintmax_t file_bytes = fs::file_size(path, ec);
  if (ec) throw_error("{}: cannot read image ({})", path, ec.message());
  if (std::string why = exr_header_refusal(path, file_bytes); !why.empty())
    throw_error("{}: cannot read image ({})", path, why);
  start_exr_threads();
  Imf::InputFile file(path.c_str());
  const Imf::Header& header = file.header();
  const Imath::Box2i dw = header.dataWindow();
  int width = dw.max.x - dw.min.x + 1, height = dw.max.y - dw.min.y + 1;
  if (width <= 0 || height <= 0 || header.channels().begin() == header.channels().end())
    throw_error("{}: unsupported image shape {}x{} without channels", path, width, height);
  if (info) {
    info->format_name = "openexr";
    info->float_pixels = false;
    for (auto it = header.channels().begin(); it != header.channels().end(); ++it)
      info->float_pixels |= it.channel().type != Imf::UINT;
  }
  std::vector<ExrChannel> chans;
  for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
    // Luminance-chroma files (Y RY BY); OpenImageIO 2.4 refused them too.
    if (it.channel().xSampling != 1 || it.channel().ySampling != 1)
      throw_error("{}: subsampled channel {} is not supported", path, it.name());
    ExrChannel c;
    c.name = it.name();
    size_t dot = c.name.rfind('.');
    c.layer = dot == std::string::npos ? std::string() : c.name.substr(0, dot);
    c.suffix = dot == std::string::npos ? c.name : c.name.substr(dot + 1);
    c.type = it.channel().type;
    chans.push_back(std::move(c));
  }
  sort_exr_channels(chans);

  const std::string refused =
      image_size_refusal(uint64_t(width), uint64_t(height), chans.size(), uint64_t(file_bytes), reserve);
  if (!refused.empty()) throw_error("{}: cannot read image ({})", path, refused);
  ImageBuffer img;
  img.width = width;
  img.height = height;
  for (const ExrChannel& c : chans) img.channels.push_back(c.name);
  img.data.resize(img.pixel_count() * chans.size());
  const size_t x_stride = sizeof(float) * chans.size(), y_stride = x_stride * size_t(width);
  Imf::FrameBuffer fb;
  for (size_t k = 0; k < chans.size(); ++k)
    fb.insert(chans[k].name, Imf::Slice::Make(Imf::FLOAT, &img.data[k], dw, x_stride, y_stride));
  file.setFrameBuffer(fb);
  file.readPixels(dw.min.y, dw.max.y);
  return img;
}

Imf::Compression exr_compression(const std::string& path, const char* name) {
  static constexpr std::pair<const char*, Imf::Compression> methods[] = {
      {"none", Imf::NO_COMPRESSION}, {"rle", Imf::RLE_COMPRESSION},     {"zips", Imf::ZIPS_COMPRESSION},
      {"zip", Imf::ZIP_COMPRESSION}, {"piz", Imf::PIZ_COMPRESSION},     {"pxr24", Imf::PXR24_COMPRESSION},
      {"b44", Imf::B44_COMPRESSION}, {"b44a", Imf::B44A_COMPRESSION},   {"dwaa", Imf::DWAA_COMPRESSION},
      {"dwab", Imf::DWAB_COMPRESSION}};
  for (const auto& [n, c] : methods)
    if (std::string_view(name) == n) return c;
  throw_error("{}: unknown OpenEXR compression '{}'", path, name);
}

// ---------------------------------------------------------------- OpenImageIO, on first use

OiioReadImage oiio_reader(const std::string& path) {
  struct Module {
    OiioReadImage read = nullptr;
    std::string error;
  };
  // Found through the executable's run path (the build tree, or beside it).
  static const Module module = [] {
    Module m;
    void* handle = dlopen(kOiioModuleFile, RTLD_NOW | RTLD_LOCAL);
    if (handle) m.read = reinterpret_cast<OiioReadImage>(dlsym(handle, kOiioReadImageSymbol));
    if (!m.read) m.error = dlerror();
    return m;
  }();
  if (!module.read)
    throw_error("{}: this format is read through OpenImageIO, whose module {} cannot be loaded ({})", path,
                kOiioModuleFile, module.error);
  return module.read;
}

// ---------------------------------------------------------------- writing

// Writes through a temporary file and renames it over `path`, so readers never
// see a partial file and an existing output survives a failed write.
// `write_to(tmp)` reports failure by throwing.
template <typename WriteTo>
void write_atomic(const std::string& path, WriteTo&& write_to) {
  std::string tmp = path + ".tmp";
  std::error_code ec;
  try {
    write_to(tmp);
  } catch (const std::exception& e) {
    fs::remove(tmp, ec);
    throw_error("{}: cannot write image ({})", path, e.what());
  }
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

ImageBuffer read_image_file(const std::string& path, ImageFileInfo* info, const ImageReserve& reserve) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw_error("{}: no such file", path);
  if (is_exr_file(path)) {
    try {
      return read_exr(path, info, reserve);
    } catch (const Error&) {
      throw;
    } catch (const std::exception& e) {
      throw_error("{}: cannot read image ({})", path, e.what());
    }
  }
  switch (image_reader_for(path)) {
    case ImageReader::PFM: return read_pfm(path, info, reserve);
    case ImageReader::StbImage: return read_with_stb_image(path, info, reserve);
    default: break;
  }
  ImageBuffer img;
  ImageFileInfo file_info;
  std::string why;
  if (!oiio_reader(path)(path.c_str(), img, file_info, reserve, why)) throw_error("{}: cannot read image ({})", path, why);
  if (info) *info = std::move(file_info);
  return img;
}

void write_exr(const std::string& path, const ImageBuffer& img, const char* compression) {
  check_buffer(path, img);
  Imf::Header header(img.width, img.height);
  header.compression() = exr_compression(path, compression);
  const size_t x_stride = sizeof(float) * img.channels.size(), y_stride = x_stride * size_t(img.width);
  Imf::FrameBuffer fb;
  for (size_t k = 0; k < img.channels.size(); ++k) {
    header.channels().insert(img.channels[k], Imf::Channel(Imf::FLOAT));
    // OpenEXR's slices take a mutable base pointer, but writing only reads it.
    char* base = const_cast<char*>(reinterpret_cast<const char*>(&img.data[k]));
    fb.insert(img.channels[k], Imf::Slice(Imf::FLOAT, base, x_stride, y_stride));
  }
  start_exr_threads();
  write_atomic(path, [&](const std::string& tmp) {
    Imf::OutputFile out(tmp.c_str(), header);
    out.setFrameBuffer(fb);
    out.writePixels(img.height);
  });
}

// libpng itself rather than OpenImageIO: every render writes this preview,
// and loading OpenImageIO for it would cost each render the start-up the
// module exists to avoid.
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
  write_atomic(path, [&](const std::string& tmp) {
    png_image png{};
    png.version = PNG_IMAGE_VERSION;
    png.width = png_uint_32(img.width);
    png.height = png_uint_32(img.height);
    png.format = PNG_FORMAT_RGB;  // 8-bit: libpng tags it sRGB
    if (!png_image_write_to_file(&png, tmp.c_str(), 0, px.data(), 0, nullptr)) throw std::runtime_error(png.message);
  });
}

}  // namespace theia
