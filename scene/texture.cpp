#include "scene/texture.h"

#include "core/color.h"
#include "core/image.h"
#include "core/log.h"
#include "scene/mipmap.h"
#include "scene/tokenizer.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cassert>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <optional>
#include <system_error>
#include <type_traits>

namespace theia {

namespace fs = std::filesystem;

// ---------------------------------------------------------------- loading

namespace {

enum class Encoding { SRGB, Linear, Gamma };

struct ParsedEncoding {
  Encoding kind = Encoding::SRGB;
  float gamma = 1.0f;
};

bool iequals(const std::string& a, const char* b) {
  size_t n = std::char_traits<char>::length(b);
  if (a.size() != n) return false;
  for (size_t i = 0; i < n; ++i)
    if (std::tolower(static_cast<unsigned char>(a[i])) != std::tolower(static_cast<unsigned char>(b[i])))
      return false;
  return true;
}

ParsedEncoding parse_encoding(const std::string& filename, const std::string& text, bool float_pixels) {
  size_t b = text.find_first_not_of(" \t"), e = text.find_last_not_of(" \t");
  std::string s = b == std::string::npos ? std::string() : text.substr(b, e - b + 1);
  if (s.empty()) return {float_pixels ? Encoding::Linear : Encoding::SRGB, 1.0f};
  if (iequals(s, "sRGB")) return {Encoding::SRGB, 1.0f};
  if (iequals(s, "linear")) return {Encoding::Linear, 1.0f};
  if (s.size() > 5 && iequals(s.substr(0, 5), "gamma") && (s[5] == ' ' || s[5] == '\t')) {
    std::string g = s.substr(s.find_first_not_of(" \t", 5));
    float gamma = 0.0f;
    auto [end, ec] = std::from_chars(g.data(), g.data() + g.size(), gamma);
    if (ec == std::errc() && end == g.data() + g.size() && gamma > 0.0f && std::isfinite(gamma))
      return {Encoding::Gamma, gamma};
  }
  throw_error("{}: unknown colour encoding \"{}\" (expected \"sRGB\", \"linear\" or \"gamma G\" with G > 0)",
              filename, text);
}

std::string resolve_path(const std::string& filename, const std::string& base_dir) {
  fs::path p(filename);
  if (p.is_absolute() || base_dir.empty()) return filename;
  std::error_code ec;
  fs::path beside = fs::path(base_dir) / p;
  if (fs::exists(beside, ec)) return beside.string();
  return filename;
}

// Which file channels become the texture's 1, 2, 3 or 4 channels.
std::vector<int> texture_channels(const ImageBuffer& buf) {
  int n = buf.num_channels();
  if (n <= 2) return n == 1 ? std::vector<int>{0} : std::vector<int>{0, 1};
  std::vector<int> ch = buf.rgb_channel_indices();
  int a = buf.channel_index("A");
  if (a < 0 && n == 4) a = 3;
  if (a >= 0) ch.push_back(a);
  return ch;
}

}  // namespace

void load_image(Image& image, const std::string& base_dir, const ImageReserve& reserve) {
  if (image.filename.empty()) {
    if (!image.pixels.empty()) return;
    throw_error("image without a filename and without pixels");
  }
  std::string path = resolve_path(image.filename, base_dir);
  ImageFileInfo info;
  ImageBuffer buf = read_image_file(path, &info, reserve);
  ParsedEncoding enc = parse_encoding(path, image.encoding, info.float_pixels);
  // pbrt-v4 applies an encoding only to integer pixels; float files are linear.
  if (info.float_pixels) enc.kind = Encoding::Linear;

  std::vector<int> ch = texture_channels(buf);
  int nc = int(ch.size());
  int alpha = (nc == 2 || nc == 4) ? nc - 1 : -1;
  image.width = buf.width;
  image.height = buf.height;
  image.channels = nc;
  size_t src_nc = buf.channels.size();
  // Where the texture keeps the file's channels as they are, the file's
  // buffer becomes the texture's: a second copy of a large picture is
  // another run of fresh pages for the kernel to zero.
  bool in_place = src_nc == size_t(nc);
  for (int c = 0; c < nc; ++c) in_place = in_place && ch[size_t(c)] == c;
  if (!in_place) image.pixels.resize(buf.pixel_count() * size_t(nc));
  std::vector<float>& out = in_place ? buf.data : image.pixels;
  for (size_t i = 0; i < buf.pixel_count(); ++i)
    for (int c = 0; c < nc; ++c) {
      float v = buf.data[i * src_nc + size_t(ch[size_t(c)])];
      if (c != alpha) {
        if (enc.kind == Encoding::SRGB)
          v = srgb_texel_to_linear(v);
        else if (enc.kind == Encoding::Gamma)
          v = std::pow(std::max(v, 0.0f), enc.gamma);
      }
      out[i * size_t(nc) + size_t(c)] = v;
    }
  if (in_place) image.pixels = std::move(buf.data);
  // A texel that is NaN, infinite or beyond kMaxEmission would put the same
  // (or an overflow) into every path that reads it: documented clamp to 0,
  // with one warning per image.  Negative float texels stay (float images are
  // linear data, tests/unit/test_texture.cpp).
  size_t non_finite = 0;
  for (float& v : image.pixels)
    if (!(std::abs(v) <= kMaxEmission)) {
      ++non_finite;
      v = 0.0f;
    }
  if (non_finite > 0)
    log_warning("{}: {} non-finite or huge (beyond {:g}) texel values clamped to 0", path, non_finite,
                double(kMaxEmission));
  // (Clamped first: the conversion would spread one NaN channel over three.)
  // Colour images join the working colour space once, here, so lookups stay plain.
  if (image.is_color && nc >= 3)
    for (size_t i = 0; i < buf.pixel_count(); ++i) {
      float* px = &image.pixels[i * size_t(nc)];
      RGB w = srgb_to_working(RGB(px[0], px[1], px[2]));
      px[0] = w.x;
      px[1] = w.y;
      px[2] = w.z;
    }
}

namespace {

// The scene's images against a byte limit while they load in parallel: each
// reserves its float values (the file's width x height x channels) once its
// header is read, before they are allocated.  The image a refusal names does
// not depend on which thread came first: it is the first, in scene order, at
// which the sizes add up beyond the limit (what a sequential load refuses).
std::string size_text(uint64_t bytes) {
  return bytes < 100'000 ? fmt::format("{} bytes", bytes) : fmt::format("{:.1f} MB", double(bytes) * 1e-6);
}

struct ImageBudget {
  struct Size {
    uint64_t width = 0, height = 0, channels = 0;
    uint64_t bytes() const { return width * height * channels * sizeof(float); }
  };
  uint64_t limit;
  std::vector<Size> asked;      // per image, what its header asked for (0 if never read)
  std::vector<uint8_t> refused;  // per image
  std::atomic<uint64_t> used{0};

  ImageBudget(uint64_t max_bytes, size_t images) : limit(max_bytes), asked(images), refused(images, 0) {}

  ImageReserve reserve_for(size_t i) {
    if (limit == UINT64_MAX) return {};
    return [this, i](uint64_t w, uint64_t h, uint64_t c) -> std::string {
      asked[i] = {w, h, c};  // the reader's file-size check keeps w * h * c far from overflow
      const uint64_t bytes = asked[i].bytes();
      if (used.fetch_add(bytes) + bytes <= limit) return {};
      used.fetch_sub(bytes);
      refused[i] = 1;
      return "over the memory limit";
    };
  }
  // After the loads: the image named for the limit (or none), and why.
  std::optional<std::pair<size_t, std::string>> refusal(const std::vector<Image>& images) const {
    if (std::find(refused.begin(), refused.end(), 1) == refused.end()) return std::nullopt;
    uint64_t total = 0;
    for (size_t i = 0; i < asked.size(); ++i) {
      total += asked[i].bytes();
      if (total <= limit) continue;
      const Size& s = asked[i];
      std::string with =
          total > s.bytes() ? fmt::format(" ({} with the images before it)", size_text(total)) : std::string();
      return std::pair{i, fmt::format("{}: its {}x{}x{} float values need {}{}, over the {} the memory limit leaves "
                                      "for the scene's images (--memory-limit)",
                                      images[i].filename, s.width, s.height, s.channels, size_text(s.bytes()), with,
                                      size_text(limit))};
    }
    return std::nullopt;
  }
};

}  // namespace

void load_images(Scene& scene, uint64_t max_bytes) {
  std::string base_dir;
  if (!scene.path.empty()) base_dir = fs::path(scene.path).parent_path().string();
  size_t n = scene.images.size();
  ImageBudget budget(max_bytes, n);
  // Collect per-image errors and report in index order, so the message does
  // not depend on which thread failed first.
  std::vector<std::string> errors(n);
  tbb::parallel_for(size_t(0), n, [&](size_t i) {
    try {
      load_image(scene.images[i], base_dir, budget.reserve_for(i));
    } catch (const std::exception& e) {
      const Image& image = scene.images[i];
      errors[i] = e.what();
      if (image.filename.empty())
        errors[i] = fmt::format("image #{}: {}", i, e.what());
      else if (errors[i].find(image.filename) == std::string::npos)
        errors[i] = fmt::format("{}: {}", image.filename, e.what());
      // The scene line that asked for the image, in the one located format.
      if (!image.loc.file.empty()) errors[i] = fmt::format("{}: error: {}", format_loc(image.loc), errors[i]);
    }
  });
  if (auto refusal = budget.refusal(scene.images)) {
    for (size_t i = 0; i < n; ++i)
      if (budget.refused[i]) errors[i].clear();
    const Image& image = scene.images[refusal->first];
    errors[refusal->first] =
        image.loc.file.empty() ? refusal->second : fmt::format("{}: error: {}", format_loc(image.loc), refusal->second);
  }
  size_t failed = 0;
  const std::string* first = nullptr;
  for (const std::string& e : errors)
    if (!e.empty()) {
      if (!first) first = &e;
      ++failed;
    }
  if (failed == 1) throw Error(*first);
  if (failed > 1) throw_error("{} (and {} more images failed to load)", *first, failed - 1);
  build_mipmaps(scene);
}

// ---------------------------------------------------------------- lookups

namespace {

// Integer texel coordinates into the image, or false for black (pbrt-v4's
// RemapPixelCoords).
inline bool remap_texel(ivec2& p, int w, int h, WrapMode wrap) {
  if (wrap == WrapMode::OctahedralSphere) {
    // Mirror across the edges so an octahedral map of the sphere is continuous.
    if (p.x < 0) {
      p.x = -p.x;
      p.y = h - 1 - p.y;
    } else if (p.x >= w) {
      p.x = 2 * w - 1 - p.x;
      p.y = h - 1 - p.y;
    }
    if (p.y < 0) {
      p.x = w - 1 - p.x;
      p.y = -p.y;
    } else if (p.y >= h) {
      p.x = w - 1 - p.x;
      p.y = 2 * h - 1 - p.y;
    }
    if (w == 1) p.x = 0;
    if (h == 1) p.y = 0;
    // Only a footprint one texel past the edge is mirrored exactly; clamp
    // anything further rather than read outside the buffer.
    p.x = std::clamp(p.x, 0, w - 1);
    p.y = std::clamp(p.y, 0, h - 1);
    return true;
  }
  if (p.x >= 0 && p.x < w && p.y >= 0 && p.y < h) return true;
  switch (wrap) {
    case WrapMode::Repeat:
      p.x = ((p.x % w) + w) % w;
      p.y = ((p.y % h) + h) % h;
      return true;
    case WrapMode::Clamp:
      p.x = std::clamp(p.x, 0, w - 1);
      p.y = std::clamp(p.y, 0, h - 1);
      return true;
    default:
      return false;
  }
}

// Keeps float-to-int conversion defined for huge or NaN coordinates.
inline float sane_coord(float x) { return std::fmin(std::fmax(x, -1e8f), 1e8f); }

}  // namespace

RGB image_texel(const Image& image, ivec2 p, WrapMode wrap) {
  if (image.pixels.empty() || image.width <= 0 || image.height <= 0) return RGB(0.0f);
  if (!remap_texel(p, image.width, image.height, wrap)) return RGB(0.0f);
  return texel_value(image, p);
}

RGB image_bilerp(const Image& image, vec2 p, WrapMode wrap) {
  if (image.pixels.empty() || image.width <= 0 || image.height <= 0) return RGB(0.0f);
  float x = sane_coord(p.x * float(image.width) - 0.5f), y = sane_coord(p.y * float(image.height) - 0.5f);
  float fx = std::floor(x), fy = std::floor(y);
  int xi = int(fx), yi = int(fy);
  float dx = x - fx, dy = y - fy;
  RGB v00 = image_texel(image, {xi, yi}, wrap), v10 = image_texel(image, {xi + 1, yi}, wrap);
  RGB v01 = image_texel(image, {xi, yi + 1}, wrap), v11 = image_texel(image, {xi + 1, yi + 1}, wrap);
  return (1 - dx) * (1 - dy) * v00 + dx * (1 - dy) * v10 + (1 - dx) * dy * v01 + dx * dy * v11;
}

RGB image_lookup_nearest(const Image& image, vec2 st, WrapMode wrap) {
  if (image.pixels.empty() || image.width <= 0 || image.height <= 0) return RGB(0.0f);
  float x = sane_coord(st.x * float(image.width) - 0.5f), y = sane_coord((1.0f - st.y) * float(image.height) - 0.5f);
  return image_texel(image, {int(std::round(x)), int(std::round(y))}, wrap);
}

RGB image_lookup_bilinear(const Image& image, vec2 st, WrapMode wrap) {
  // Texture t runs bottom to top; image rows run top to bottom.
  return image_bilerp(image, vec2(st.x, 1.0f - st.y), wrap);
}

}  // namespace theia
