#include "scene/ply.h"

#include "core/log.h"

#include <algorithm>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <cmath>
#include <filesystem>
#include <optional>
#include <string_view>
#include <utility>

namespace theia {

namespace {

enum class Scalar { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64, Invalid };

Scalar parse_scalar(std::string_view s) {
  if (s == "char" || s == "int8") return Scalar::Int8;
  if (s == "uchar" || s == "uint8") return Scalar::UInt8;
  if (s == "short" || s == "int16") return Scalar::Int16;
  if (s == "ushort" || s == "uint16") return Scalar::UInt16;
  if (s == "int" || s == "int32") return Scalar::Int32;
  if (s == "uint" || s == "uint32") return Scalar::UInt32;
  if (s == "float" || s == "float32") return Scalar::Float32;
  if (s == "double" || s == "float64") return Scalar::Float64;
  return Scalar::Invalid;
}

size_t scalar_size(Scalar s) {
  switch (s) {
    case Scalar::Int8:
    case Scalar::UInt8: return 1;
    case Scalar::Int16:
    case Scalar::UInt16: return 2;
    case Scalar::Int32:
    case Scalar::UInt32:
    case Scalar::Float32: return 4;
    default: return 8;
  }
}

// Where a vertex property goes.
enum class Slot { None, X, Y, Z, NX, NY, NZ, U, V };

struct Property {
  std::string name;
  Scalar type = Scalar::Float32;
  bool is_list = false;
  Scalar count_type = Scalar::UInt8;
  Slot slot = Slot::None;
  bool is_face_indices = false;
};

struct Element {
  std::string name;
  size_t count = 0;
  std::vector<Property> props;
};

// The values an integer type holds (what a binary file can store), none for the float types.
std::optional<std::pair<double, double>> integer_range(Scalar s) {
  switch (s) {
    case Scalar::Int8: return std::pair{-128.0, 127.0};
    case Scalar::UInt8: return std::pair{0.0, 255.0};
    case Scalar::Int16: return std::pair{-32768.0, 32767.0};
    case Scalar::UInt16: return std::pair{0.0, 65535.0};
    case Scalar::Int32: return std::pair{-2147483648.0, 2147483647.0};
    case Scalar::UInt32: return std::pair{0.0, 4294967295.0};
    default: return std::nullopt;
  }
}

enum class Format { Ascii, BinaryLE, BinaryBE };

template <typename T>
T load(const char* p, bool swap) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  if (swap) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    for (size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
    std::memcpy(&v, b, sizeof(T));
  }
  return v;
}

// Reads values one at a time from the body, in either encoding.
class BodyReader {
 public:
  BodyReader(const std::string& path, const char* p, const char* end, Format f)
      : path_(path), p_(p), end_(end), ascii_(f == Format::Ascii),
        swap_((f == Format::BinaryBE) == (std::endian::native == std::endian::little)) {}

  // Bytes left in the body, and the fewest one value of type t takes (an
  // ASCII value is at least a digit and a separator): what a count in the
  // header or a list length must fit in before anything is allocated for it.
  size_t remaining() const { return size_t(end_ - p_); }
  size_t min_bytes(Scalar t) const { return ascii_ ? 2 : scalar_size(t); }

  // The next n bytes of a binary body, skipped over; throws where fewer are left.
  const char* take(size_t n, const char* what) {
    if (size_t(end_ - p_) < n) truncated(what);
    const char* q = p_;
    p_ += n;
    return q;
  }
  bool ascii() const { return ascii_; }
  bool swap() const { return swap_; }

  double read(Scalar t, const char* what) {
    if (ascii_) return read_ascii(t, what);
    size_t n = scalar_size(t);
    if (size_t(end_ - p_) < n) truncated(what);
    const char* q = p_;
    p_ += n;
    switch (t) {
      case Scalar::Int8: return double(int8_t(*q));
      case Scalar::UInt8: return double(uint8_t(*q));
      case Scalar::Int16: return double(load<int16_t>(q, swap_));
      case Scalar::UInt16: return double(load<uint16_t>(q, swap_));
      case Scalar::Int32: return double(load<int32_t>(q, swap_));
      case Scalar::UInt32: return double(load<uint32_t>(q, swap_));
      case Scalar::Float32: return double(load<float>(q, swap_));
      default: return load<double>(q, swap_);
    }
  }

 private:
  // An ASCII value of an integer type is a whole number in its range, as a
  // binary one is (a list length read as "nan" once reached an allocation).
  double read_ascii(Scalar t, const char* what) {
    while (p_ < end_ && (*p_ == ' ' || *p_ == '\t' || *p_ == '\r' || *p_ == '\n')) ++p_;
    if (p_ >= end_) truncated(what);
    const char* b = p_;
    while (p_ < end_ && !(*p_ == ' ' || *p_ == '\t' || *p_ == '\r' || *p_ == '\n')) ++p_;
    const char* s = b;
    if (*s == '+') ++s;
    double v;
    auto [ptr, ec] = std::from_chars(s, p_, v);
    if (ec != std::errc() || ptr != p_)
      throw_error("{}: error: bad number \"{}\" in the {} data, expected a number", path_, std::string_view(b, size_t(p_ - b)), what);
    const auto range = integer_range(t);
    if (range && !(v >= range->first && v <= range->second && v == std::floor(v)))
      throw_error("{}: error: bad number \"{}\" in the {} data, expected a whole number in [{}, {}]", path_,
                  std::string_view(b, size_t(p_ - b)), what, range->first, range->second);
    return v;
  }
  [[noreturn]] void truncated(const char* what) const {
    throw_error("{}: error: unexpected end of file in the {} data, expected more values", path_, what);
  }

  const std::string& path_;
  const char* p_;
  const char* end_;
  bool ascii_;
  bool swap_;
};

Slot vertex_slot(std::string_view n) {
  if (n == "x") return Slot::X;
  if (n == "y") return Slot::Y;
  if (n == "z") return Slot::Z;
  if (n == "nx") return Slot::NX;
  if (n == "ny") return Slot::NY;
  if (n == "nz") return Slot::NZ;
  if (n == "u" || n == "s" || n == "texture_u" || n == "texture_s") return Slot::U;
  if (n == "v" || n == "t" || n == "texture_v" || n == "texture_t") return Slot::V;
  return Slot::None;
}

}  // namespace

TriangleMesh read_ply(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw_error("{}: error: cannot open the PLY file: it is a directory", path);
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw_error("{}: error: cannot open the PLY file: {}", path, std::strerror(errno));
  std::string data;
  std::fseek(f, 0, SEEK_END);
  long size = std::ftell(f);
  std::fseek(f, 0, SEEK_SET);
  data.resize(size > 0 ? size_t(size) : 0);
  data.resize(std::fread(data.data(), 1, data.size(), f));
  std::fclose(f);

  // ---- header, line by line
  size_t pos = 0;
  int line_no = 0;
  auto next_line = [&](std::string_view* line) {
    if (pos >= data.size()) return false;
    size_t nl = data.find('\n', pos);
    size_t e = nl == std::string::npos ? data.size() : nl;
    *line = std::string_view(data).substr(pos, e - pos);
    if (!line->empty() && line->back() == '\r') line->remove_suffix(1);
    pos = nl == std::string::npos ? data.size() : nl + 1;
    ++line_no;
    return true;
  };
  auto words = [](std::string_view line) {
    std::vector<std::string_view> w;
    size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
      size_t b = i;
      while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
      if (i > b) w.push_back(line.substr(b, i - b));
    }
    return w;
  };

  std::string_view line;
  if (!next_line(&line) || line != "ply") throw_error("{}: error: not a PLY file, expected \"ply\" on the first line", path);
  Format format = Format::Ascii;
  bool have_format = false, have_end = false;
  std::vector<Element> elements;
  while (next_line(&line)) {
    auto w = words(line);
    if (w.empty() || w[0] == "comment" || w[0] == "obj_info") continue;
    if (w[0] == "end_header") {
      have_end = true;
      break;
    }
    if (w[0] == "format" && w.size() >= 2) {
      if (w[1] == "ascii") format = Format::Ascii;
      else if (w[1] == "binary_little_endian") format = Format::BinaryLE;
      else if (w[1] == "binary_big_endian") format = Format::BinaryBE;
      else throw_error("{}:{}: error: unknown PLY format \"{}\", expected ascii, binary_little_endian or binary_big_endian", path, line_no, w[1]);
      have_format = true;
    } else if (w[0] == "element" && w.size() == 3) {
      Element e;
      e.name = std::string(w[1]);
      unsigned long long n = 0;
      auto [ptr, ec] = std::from_chars(w[2].data(), w[2].data() + w[2].size(), n);
      if (ec != std::errc() || ptr != w[2].data() + w[2].size())
        throw_error("{}:{}: error: bad element count \"{}\", expected a non-negative integer", path, line_no, w[2]);
      e.count = size_t(n);
      elements.push_back(std::move(e));
    } else if (w[0] == "property" && !elements.empty() && (w.size() == 3 || (w.size() == 5 && w[1] == "list"))) {
      Property p;
      bool list = w.size() == 5;
      p.name = std::string(w.back());
      p.is_list = list;
      p.type = parse_scalar(list ? w[3] : w[1]);
      if (list) p.count_type = parse_scalar(w[2]);
      if (p.type == Scalar::Invalid || p.count_type == Scalar::Invalid)
        throw_error("{}:{}: error: unknown PLY property type in \"{}\", expected char, uchar, short, ushort, int, uint, float or double", path, line_no, line);
      Element& e = elements.back();
      if (e.name == "vertex" && !list) p.slot = vertex_slot(p.name);
      if (e.name == "face" && list) p.is_face_indices = p.name == "vertex_indices" || p.name == "vertex_index";
      e.props.push_back(std::move(p));
    } else {
      throw_error("{}:{}: error: malformed PLY header line \"{}\", expected format, element, property, comment or end_header", path, line_no, line);
    }
  }
  if (!have_end) throw_error("{}: error: PLY header without end_header", path);
  if (!have_format) throw_error("{}: error: PLY header without a format line", path);

  // ---- body
  TriangleMesh mesh;
  BodyReader in(path, data.data() + pos, data.data() + data.size(), format);
  size_t vertex_count = 0;
  bool has_n = false, has_uv = false;
  int skipped_faces = 0;
  std::vector<double> list_values;
  // One vertex property's value, checked and stored.
  auto set_vertex = [&](size_t i, const Property& p, double v) {
    if (p.slot != Slot::None && !std::isfinite(float(v)))
      throw_error("{}: error: vertex {} has a non-finite or out-of-range {} ({}), expected finite values", path, i,
                  p.name, v);
    switch (p.slot) {
      case Slot::X: mesh.p[i].x = float(v); break;
      case Slot::Y: mesh.p[i].y = float(v); break;
      case Slot::Z: mesh.p[i].z = float(v); break;
      case Slot::NX: if (has_n) mesh.n[i].x = float(v); break;
      case Slot::NY: if (has_n) mesh.n[i].y = float(v); break;
      case Slot::NZ: if (has_n) mesh.n[i].z = float(v); break;
      case Slot::U: if (has_uv) mesh.uv[i].x = float(v); break;
      case Slot::V: if (has_uv) mesh.uv[i].y = float(v); break;
      default: break;
    }
  };
  // Face i's n vertex indices (v[0..n) read where n <= 4): a triangle, a quad
  // as two, anything else skipped.
  auto add_face = [&](size_t i, const double* v, size_t n) {
    if (n != 3 && n != 4) {
      ++skipped_faces;
      return;
    }
    uint32_t idx[4];
    for (size_t k = 0; k < n; ++k) {
      if (v[k] < 0 || v[k] >= double(vertex_count) || v[k] != std::floor(v[k]))
        throw_error("{}: error: face {} has vertex index {}, expected an integer in [0, {})", path, i, v[k], vertex_count);
      idx[k] = uint32_t(v[k]);
    }
    mesh.indices.insert(mesh.indices.end(), {idx[0], idx[1], idx[2]});
    if (n == 4) mesh.indices.insert(mesh.indices.end(), {idx[0], idx[2], idx[3]});
  };
  size_t claimed = 0;  // the body's smallest size the header implies
  for (const Element& e : elements) {
    size_t per_item = 0;
    for (const Property& p : e.props) per_item += in.min_bytes(p.is_list ? p.count_type : p.type);
    if (per_item > 0 && e.count > (in.remaining() - std::min(claimed, in.remaining())) / per_item)
      throw_error("{}: error: the header claims {} {} elements (at least {} bytes each), but the file holds only {} "
                  "bytes after its header, expected the counts the data has", path, e.count, e.name, per_item,
                  in.remaining());
    claimed += e.count * per_item;
  }
  for (const Element& e : elements) {
    bool is_vertex = e.name == "vertex", is_face = e.name == "face";
    if (is_vertex) {
      vertex_count = e.count;
      bool slots[9] = {};
      for (const Property& p : e.props) slots[int(p.slot)] = true;
      if (!slots[int(Slot::X)] || !slots[int(Slot::Y)] || !slots[int(Slot::Z)])
        throw_error("{}: error: vertex element without x, y and z properties", path);
      has_n = slots[int(Slot::NX)] && slots[int(Slot::NY)] && slots[int(Slot::NZ)];
      has_uv = slots[int(Slot::U)] && slots[int(Slot::V)];
      mesh.p.resize(e.count);
      if (has_n) mesh.n.resize(e.count);
      if (has_uv) mesh.uv.resize(e.count);
    }
    if (is_face) mesh.indices.reserve(e.count * 3);
    // Binary vertices of float properties only, what exporters write: each
    // record read where it lies, without read()'s dispatch on the type per
    // value (that dispatch was most of a PLY's load: 3.5% of material-testball
    // at 16 spp).  The same values, checks and messages as the general loop.
    const bool float_vertices = is_vertex && !in.ascii() && std::all_of(e.props.begin(), e.props.end(), [](const Property& p) {
      return !p.is_list && p.type == Scalar::Float32;
    });
    if (float_vertices) {
      const size_t stride = 4 * e.props.size();
      for (size_t i = 0; i < e.count; ++i) {
        const char* rec = in.take(stride, e.name.c_str());
        for (size_t k = 0; k < e.props.size(); ++k)
          set_vertex(i, e.props[k], double(load<float>(rec + 4 * k, in.swap())));
      }
      continue;
    }
    // Binary faces whose one property is the index list with a uchar length
    // and int or uint indices, likewise.
    const Property* fp = e.props.size() == 1 ? &e.props[0] : nullptr;
    const bool int_faces = is_face && !in.ascii() && fp && fp->is_list && fp->is_face_indices &&
                           fp->count_type == Scalar::UInt8 &&
                           (fp->type == Scalar::Int32 || fp->type == Scalar::UInt32);
    if (int_faces) {
      for (size_t i = 0; i < e.count; ++i) {
        const size_t count = uint8_t(*in.take(1, e.name.c_str()));
        if (count > in.remaining() / 4)
          throw_error("{}: error: unexpected end of file in the {} data: a list of {} values, {} bytes left, expected "
                      "more values", path, e.name, double(count), in.remaining());
        const char* q = in.take(4 * count, e.name.c_str());
        double v[4] = {};
        for (size_t k = 0; k < std::min<size_t>(count, 4); ++k)
          v[k] = fp->type == Scalar::Int32 ? double(load<int32_t>(q + 4 * k, in.swap()))
                                           : double(load<uint32_t>(q + 4 * k, in.swap()));
        add_face(i, v, count);
      }
      continue;
    }
    for (size_t i = 0; i < e.count; ++i) {
      for (const Property& p : e.props) {
        if (!p.is_list) {
          double v = in.read(p.type, e.name.c_str());
          if (is_vertex) set_vertex(i, p, v);
          continue;
        }
        double count = in.read(p.count_type, e.name.c_str());
        if (!(count >= 0)) throw_error("{}: error: negative list length in the {} data", path, e.name);
        if (count > double(in.remaining() / in.min_bytes(p.type)))
          throw_error("{}: error: unexpected end of file in the {} data: a list of {} values, {} bytes left, expected "
                      "more values", path, e.name, count, in.remaining());
        list_values.resize(size_t(count));
        for (double& v : list_values) v = in.read(p.type, e.name.c_str());
        if (is_face && p.is_face_indices) add_face(i, list_values.data(), list_values.size());
      }
    }
  }
  if (skipped_faces > 0)
    log_warning("{}: skipped {} faces that are neither triangles nor quads", path, skipped_faces);
  return mesh;
}

TriangleMesh tessellate_bilinear_patches(const TriangleMesh& in, bool flip_normals) {
  constexpr int kGrid = 16;
  size_t patches = in.indices.size() / 4;
  std::vector<uint8_t> planar(patches);
  bool any_curved = false;
  for (size_t k = 0; k < patches; ++k) {
    const uint32_t* q = &in.indices[4 * k];
    vec3 p00 = in.p[q[0]], p10 = in.p[q[1]], p01 = in.p[q[2]], p11 = in.p[q[3]];
    vec3 n = glm::cross(p10 - p00, p01 - p00);
    float extent = std::max({glm::length(p10 - p00), glm::length(p01 - p00), glm::length(p11 - p00)});
    float ln = glm::length(n);
    planar[k] = ln == 0.0f || std::abs(glm::dot(p11 - p00, n / ln)) <= 1e-5f * extent;
    any_curved |= !planar[k];
  }
  float sign = flip_normals ? -1.0f : 1.0f;
  bool want_n = !in.n.empty() || any_curved;
  TriangleMesh out;
  for (size_t k = 0; k < patches; ++k) {
    const uint32_t* q = &in.indices[4 * k];
    int g = planar[k] ? 1 : kGrid;
    out.patch_start.push_back(uint32_t(out.triangle_count()));
    uint32_t base = uint32_t(out.p.size());
    for (int j = 0; j <= g; ++j)
      for (int i = 0; i <= g; ++i) {
        float u = float(i) / float(g), v = float(j) / float(g);
        float w[4] = {(1 - u) * (1 - v), u * (1 - v), (1 - u) * v, u * v};
        auto lerp = [&](const auto& a) { return w[0] * a[q[0]] + w[1] * a[q[1]] + w[2] * a[q[2]] + w[3] * a[q[3]]; };
        out.p.push_back(lerp(in.p));
        out.uv.push_back(in.uv.empty() ? vec2(u, v) : lerp(in.uv));
        if (!want_n) continue;
        if (!in.n.empty()) {
          out.n.push_back(lerp(in.n));
          continue;
        }
        vec3 dpdu = (1 - v) * (in.p[q[1]] - in.p[q[0]]) + v * (in.p[q[3]] - in.p[q[2]]);
        vec3 dpdv = (1 - u) * (in.p[q[2]] - in.p[q[0]]) + u * (in.p[q[3]] - in.p[q[1]]);
        vec3 n = glm::cross(dpdu, dpdv);
        float l = glm::length(n);
        out.n.push_back(l > 0.0f ? sign * n / l : vec3(0.0f));
      }
    // Wound p00 -> p10 -> p11 so that the triangles face along dp/du x dp/dv.
    for (int j = 0; j < g; ++j)
      for (int i = 0; i < g; ++i) {
        uint32_t a = base + uint32_t(j * (g + 1) + i), b = a + 1, c = b + uint32_t(g + 1), d = a + uint32_t(g + 1);
        out.indices.insert(out.indices.end(), {a, b, c, a, c, d});
      }
  }
  out.patch_start.push_back(uint32_t(out.triangle_count()));
  return out;
}

}  // namespace theia
