// libtheia_oiio.so: OpenImageIO's image readers behind the one entry point
// declared in core/oiio_module.h.  Built on its own (not part of theia_core)
// and loaded with dlopen; everything but the entry point is hidden.
#include "core/oiio_module.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string_view>
#include <vector>

namespace {

bool fail(std::string& error, std::string why, const char* otherwise) {
  error = why.empty() ? otherwise : std::move(why);
  return false;
}

// Formats a misnamed file (a JPEG named .png) is recognised in by its first
// bytes: each reader's valid_file reads a few bytes (microseconds), where
// OpenImageIO's own fallback opens the file with every plugin it has (LibRaw,
// DICOM, ffmpeg, ...: a millisecond, most of the time of a corrupt image).
// Not JPEG 2000 (its check decodes; 0.6 ms) nor Targa (no magic number).
constexpr const char* kFormatsByMagic[] = {"png", "jpeg", "tiff", "openexr", "hdr", "bmp", "gif",
                                           "webp", "psd", "dds", "pnm", "sgi", "ico", "heif"};

// The reader of the format the file's extension names when its first bytes
// agree, else the reader of kFormatsByMagic that recognises them, else none
// (with why in `error`): a corrupt file is answered by its own reader alone.
std::unique_ptr<OIIO::ImageInput> reader_for(const std::string& path, std::string& error) {
  std::string ext = std::filesystem::path(path).extension().string();
  if (!ext.empty()) ext.erase(0, 1);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  std::unique_ptr<OIIO::ImageInput> named = ext.empty() ? nullptr : OIIO::ImageInput::create(ext);
  (void)OIIO::geterror();  // "no reader for this extension" is not the answer
  if (named && named->valid_file(path)) return named;
  for (const char* format : kFormatsByMagic) {
    if (named && std::string_view(named->format_name()) == format) continue;
    auto other = OIIO::ImageInput::create(format);
    if (other && other->valid_file(path)) return other;
  }
  (void)OIIO::geterror();
  error = named ? std::string("not a ") + named->format_name() + " file, nor one of another format by its first bytes"
                : "unknown image format (neither its extension nor its first bytes name one)";
  return nullptr;
}

// OpenImageIO 2.4's PNG reader leaks its error message whenever a read comes
// up short, i.e. on every truncated PNG (PNGInput::PngReadCallback: libpng's
// longjmp skips the string's destructor).  So a PNG reaches it only when its
// chunks fit in the file (png_truncation), and through ZeroPaddedFile: a read
// past the end (the header of a chunk after the last) gets zeros, an invalid
// chunk type libpng refuses at once, and the file is refused as truncated
// whatever libpng made of them.
class ZeroPaddedFile final : public OIIO::Filesystem::IOFile {
 public:
  explicit ZeroPaddedFile(const std::string& path) : IOFile(path, Read) {}
  size_t read(void* buf, size_t size) override { return padded(buf, IOFile::read(buf, size), size); }
  size_t pread(void* buf, size_t size, int64_t offset) override {
    return padded(buf, IOFile::pread(buf, size, offset), size);
  }
  bool read_past_end = false;

 private:
  size_t padded(void* buf, size_t got, size_t size) {
    if (got >= size) return got;
    std::memset(static_cast<char*>(buf) + got, 0, size - got);
    read_past_end = true;
    return size;
  }
};

// Why a PNG's chunks (after the 8-byte signature: length, type, data, CRC)
// run past the end of the file, or "" when each chunk libpng reads is whole:
// those up to the image data and its IDAT chunks (it reads no further).
// Otherwise libpng would read the missing bytes of a chunk as zeros (up to
// 2 GB of them, CRC'd) before refusing it.
std::string png_truncation(const std::string& path) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f || std::fseek(f.get(), 0, SEEK_END) != 0) return "";  // open() says why
  const long size = std::ftell(f.get());
  bool in_image_data = false;
  for (long pos = 8; pos < size;) {
    unsigned char header[8];
    if (size - pos < 8 || std::fseek(f.get(), pos, SEEK_SET) != 0 || std::fread(header, 1, 8, f.get()) != 8)
      return in_image_data ? "" : "truncated: the file ends inside the header of a chunk at byte " + std::to_string(pos);
    const bool idat = std::memcmp(header + 4, "IDAT", 4) == 0;
    if ((in_image_data && !idat) || std::memcmp(header + 4, "IEND", 4) == 0) break;
    const long length = long(header[0]) << 24 | long(header[1]) << 16 | long(header[2]) << 8 | long(header[3]);
    if (length > size - pos - 12)
      return "truncated: a chunk at byte " + std::to_string(pos) + " holds " + std::to_string(length) +
             " bytes, the file ends at byte " + std::to_string(size);
    in_image_data = idat;
    pos += 12 + length;
  }
  return "";
}

// The first subimage's pixels as float, converted as read_image converts
// them.  Scanlines are read as stored first: read_image's own conversion goes
// through a buffer sized for 2^26 bytes of scanlines whatever the image's size
// (64 MB for a 4x4 PNG), which AddressSanitizer maps and poisons at every read.
bool read_as_float(OIIO::ImageInput& in, std::vector<float>& out) {
  const OIIO::ImageSpec& spec = in.spec();
  if (spec.tile_width > 0 || !spec.channelformats.empty())  // tiles, or channels of different types
    return in.read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, out.data());
  std::vector<unsigned char> stored(out.size() * spec.format.size());
  if (!in.read_native_scanlines(0, 0, spec.y, spec.y + spec.height, spec.z, stored.data())) return false;
  constexpr size_t kStep = size_t(1) << 24;  // convert_pixel_values counts in int
  for (size_t i = 0; i < out.size(); i += kStep)
    if (!OIIO::convert_pixel_values(spec.format, &stored[i * spec.format.size()], OIIO::TypeDesc::FLOAT, &out[i],
                                    int(std::min(kStep, out.size() - i))))
      return false;
  return true;
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
  std::unique_ptr<ZeroPaddedFile> png_file;  // outlives `in`, which reads through it
  auto in = reader_for(path, error);
  if (!in) return false;
  if (std::string_view(in->format_name()) == "png") {
    if (std::string why = png_truncation(path); !why.empty()) return fail(error, why, "");
    png_file = std::make_unique<ZeroPaddedFile>(path);
    in->set_ioproxy(png_file.get());
  }
  auto reader_error = [&] {
    return png_file && png_file->read_past_end ? std::string("truncated: the file ends inside its PNG data")
                                               : in->geterror();
  };
  OIIO::ImageSpec opened;
  if (!in->open(path, opened, config) || (png_file && png_file->read_past_end))
    return fail(error, reader_error(), "cannot open");
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
  if (!read_as_float(*in, img.data) || (png_file && png_file->read_past_end))
    return fail(error, "cannot read pixels: " + reader_error(), "cannot read pixels");
  info.format_name = in->format_name();
  auto bt = OIIO::TypeDesc::BASETYPE(spec.format.basetype);
  info.float_pixels = bt == OIIO::TypeDesc::HALF || bt == OIIO::TypeDesc::FLOAT || bt == OIIO::TypeDesc::DOUBLE;
  in->close();
  return true;
} catch (const std::exception& e) {
  return fail(error, e.what(), "unknown error");
}
