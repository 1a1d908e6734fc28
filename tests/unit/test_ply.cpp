#include "core/log.h"
#include "scene/ply.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <bit>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

using namespace theia;
using theia::test::TempDir;
namespace fs = std::filesystem;

namespace {


// A square (one quad) and a triangle, with distinct normals and uvs so that a
// mix-up of vertices or properties shows.
const std::vector<vec3> kP = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {2, 0.5f, 0.25f}};
const std::vector<vec3> kN = {{0, 0, 1}, {0, 0.6f, 0.8f}, {0.6f, 0, 0.8f}, {0, -0.6f, 0.8f}, {1, 0, 0}};
const std::vector<vec2> kUV = {{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0.5f, 0.25f}};
const std::vector<std::vector<int>> kFaces = {{0, 1, 2, 3}, {1, 4, 2}};
const std::vector<uint32_t> kIndices = {0, 1, 2, 0, 2, 3, 1, 4, 2};

enum class Fmt { Ascii, LE, BE };

struct Writer {
  Fmt fmt;
  std::string body;
  template <typename T>
  void put(T v) {
    if (fmt == Fmt::Ascii) {
      body += std::to_string(v) + " ";
      return;
    }
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    bool big_host = std::endian::native == std::endian::big;
    if ((fmt == Fmt::BE) != big_host) std::reverse(b, b + sizeof(T));
    body.append(b, sizeof(T));
  }
  void end_row() {
    if (fmt == Fmt::Ascii) body += "\n";
  }
};

// Positions as float, normals as double, uv as float (named u/v or s/t),
// an unrelated per-vertex uchar, an extra element, and faces as
// uchar-counted int lists followed by face_indices.
std::string make_ply(Fmt fmt, bool normals, bool uv, const char* uname = "u", const char* vname = "v",
                     std::vector<std::vector<int>> faces = kFaces) {
  std::string h = "ply\nformat ";
  h += fmt == Fmt::Ascii ? "ascii" : fmt == Fmt::LE ? "binary_little_endian" : "binary_big_endian";
  h += " 1.0\ncomment written by test_ply\nelement vertex " + std::to_string(kP.size()) +
       "\nproperty float x\nproperty float y\nproperty float z\n";
  if (normals) h += "property double nx\nproperty double ny\nproperty double nz\n";
  if (uv) h += std::string("property float ") + uname + "\nproperty float " + vname + "\n";
  h += "property uchar red\n";
  h += "element material 1\nproperty short id\n";
  h += "element face " + std::to_string(faces.size()) +
       "\nproperty list uchar int vertex_indices\nproperty int face_indices\nend_header\n";
  Writer w{fmt, {}};
  for (size_t i = 0; i < kP.size(); ++i) {
    w.put(kP[i].x), w.put(kP[i].y), w.put(kP[i].z);
    if (normals) w.put(double(kN[i].x)), w.put(double(kN[i].y)), w.put(double(kN[i].z));
    if (uv) w.put(kUV[i].x), w.put(kUV[i].y);
    w.put(uint8_t(200));
    w.end_row();
  }
  w.put(int16_t(-7));
  w.end_row();
  for (size_t f = 0; f < faces.size(); ++f) {
    if (fmt == Fmt::Ascii) w.put(int(faces[f].size()));
    else w.put(uint8_t(faces[f].size()));
    for (int i : faces[f]) w.put(int32_t(i));
    w.put(int32_t(f));
    w.end_row();
  }
  return h + w.body;
}

void expect_mesh(const TriangleMesh& m, bool normals, bool uv) {
  ASSERT_EQ(m.p.size(), kP.size());
  for (size_t i = 0; i < kP.size(); ++i) EXPECT_EQ(m.p[i], kP[i]) << i;
  EXPECT_EQ(m.indices, kIndices);
  EXPECT_EQ(m.triangle_count(), 3u);
  if (normals) {
    ASSERT_EQ(m.n.size(), kN.size());
    for (size_t i = 0; i < kN.size(); ++i) EXPECT_EQ(m.n[i], kN[i]) << i;
  } else {
    EXPECT_TRUE(m.n.empty());
  }
  if (uv) {
    ASSERT_EQ(m.uv.size(), kUV.size());
    for (size_t i = 0; i < kUV.size(); ++i) EXPECT_EQ(m.uv[i], kUV[i]) << i;
  } else {
    EXPECT_TRUE(m.uv.empty());
  }
}

std::string error_of(const std::string& path) {
  try {
    read_ply(path);
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST(Ply, AsciiWithNormalsAndUvReadsBackEqual) {
  TempDir dir;
  expect_mesh(read_ply(dir.write("a.ply", make_ply(Fmt::Ascii, true, true))), true, true);
}

TEST(Ply, BinaryLittleEndianReadsBackEqual) {
  TempDir dir;
  expect_mesh(read_ply(dir.write("le.ply", make_ply(Fmt::LE, true, true))), true, true);
  expect_mesh(read_ply(dir.write("le2.ply", make_ply(Fmt::LE, false, false))), false, false);
}

TEST(Ply, BinaryBigEndianReadsBackEqual) {
  TempDir dir;
  expect_mesh(read_ply(dir.write("be.ply", make_ply(Fmt::BE, true, true))), true, true);
  expect_mesh(read_ply(dir.write("be2.ply", make_ply(Fmt::BE, false, true, "s", "t"))), false, true);
}

TEST(Ply, TextureUvNamesAreRecognised) {
  TempDir dir;
  expect_mesh(read_ply(dir.write("tu.ply", make_ply(Fmt::LE, false, true, "texture_u", "texture_v"))), false, true);
}

TEST(Ply, VertexIndexListNameAndOtherListTypes) {
  TempDir dir;
  std::string h =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty uint8 x\nproperty int16 y\nproperty "
      "float64 z\nelement face 1\nproperty list uint16 uint32 vertex_index\nend_header\n";
  Writer w{Fmt::LE, {}};
  for (int i = 0; i < 3; ++i) w.put(uint8_t(i)), w.put(int16_t(-i)), w.put(double(i) * 0.5);
  w.put(uint16_t(3)), w.put(uint32_t(2)), w.put(uint32_t(1)), w.put(uint32_t(0));
  TriangleMesh m = read_ply(dir.write("t.ply", h + w.body));
  ASSERT_EQ(m.p.size(), 3u);
  EXPECT_EQ(m.p[2], vec3(2, -2, 1));
  EXPECT_EQ(m.indices, (std::vector<uint32_t>{2, 1, 0}));
}

TEST(Ply, PolygonsOtherThanTrianglesAndQuadsAreSkippedWithAWarning) {
  TempDir dir;
  int before = warning_count();
  TriangleMesh m = read_ply(dir.write("p.ply", make_ply(Fmt::Ascii, false, false, "u", "v", {{0, 1, 2, 3, 4}, {1, 4, 2}})));
  EXPECT_EQ(warning_count() - before, 1);
  EXPECT_EQ(m.indices, (std::vector<uint32_t>{1, 4, 2}));
}

TEST(Ply, TruncatedBinaryIsAnError) {
  TempDir dir;
  std::string full = make_ply(Fmt::LE, true, true);
  std::string path = dir.write("cut.ply", full.substr(0, full.size() - 6));
  // The last face's list of 3 indices (12 bytes) finds 10 bytes left: refused before it is read.
  EXPECT_EQ(error_of(path),
            path + ": error: unexpected end of file in the face data: a list of 3 values, 10 bytes left, expected more values");
}

TEST(Ply, IndexOutOfRangeIsAnError) {
  TempDir dir;
  std::string path = dir.write("bad.ply", make_ply(Fmt::Ascii, false, false, "u", "v", {{0, 1, 9}}));
  EXPECT_EQ(error_of(path), path + ": error: face 0 has vertex index 9, expected an integer in [0, 5)");
}

TEST(Ply, MalformedHeaderAndMissingFileAreErrors) {
  TempDir dir;
  std::string path = dir.write("h.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nfoo bar\nend_header\n");
  EXPECT_EQ(error_of(path),
            path + ":5: error: malformed PLY header line \"foo bar\", expected format, element, property, comment or end_header");
  std::string nope = (dir.path / "nope.ply").string();
  EXPECT_EQ(error_of(nope), nope + ": error: cannot open the PLY file: No such file or directory");
  std::string notply = dir.write("x.ply", "hello\n");
  EXPECT_EQ(error_of(notply), notply + ": error: not a PLY file, expected \"ply\" on the first line");
}

TEST(Ply, CountsTheFileCannotHoldAreErrorsBeforeAnyAllocation) {
  TempDir dir;
  // A header claiming 1e8 vertices over a 24-byte body: refused from the
  // file size, not after allocating 1.2 GB for the positions.
  std::string path = dir.write(
      "huge.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 100000000\nproperty float x\nproperty float y\n"
                  "property float z\nend_header\n" + std::string(24, '\0'));
  EXPECT_EQ(error_of(path), path + ": error: the header claims 100000000 vertex elements (at least 12 bytes each), "
                                   "but the file holds only 24 bytes after its header, expected the counts the data has");
  // A list length past the bytes that are left.
  std::string body;
  for (float v : {0.0f, 0.0f, 0.0f}) body.append(reinterpret_cast<const char*>(&v), 4);
  int32_t n = 1000000000;
  body.append(reinterpret_cast<const char*>(&n), 4);
  std::string list = dir.write(
      "list.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                  "property float z\nelement face 1\nproperty list int int vertex_indices\nend_header\n" + body);
  EXPECT_EQ(error_of(list), list + ": error: unexpected end of file in the face data: a list of 1000000000 values, 0 "
                                   "bytes left, expected more values");
}

// An ASCII value of an integer type must be a whole number in the type's
// range, as a binary one is: the fuzzer's list length "nan" passed every
// check and reached an allocation (fuzz/corpus/ply/found-nan-list-length.ply).
TEST(Ply, AsciiIntegersAreWholeNumbersInTheirTypesRange) {
  TempDir dir;
  const std::string header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                             "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                             "0 0 0\n1 0 0\n0 1 0\n";
  auto error = [&](const std::string& face) { return error_of(dir.write("f.ply", header + face)); };
  const std::string path = (dir.path / "f.ply").string();
  EXPECT_EQ(error("nan 0 1 2\n"),
            path + ": error: bad number \"nan\" in the face data, expected a whole number in [0, 255]");
  EXPECT_EQ(error("3 0 1 inf\n"),
            path + ": error: bad number \"inf\" in the face data, expected a whole number in [-2147483648, 2147483647]");
  EXPECT_EQ(error("256 0 1 2\n"),
            path + ": error: bad number \"256\" in the face data, expected a whole number in [0, 255]");
  EXPECT_EQ(error("3 0 1.5 2\n"),
            path + ": error: bad number \"1.5\" in the face data, expected a whole number in [-2147483648, 2147483647]");
  EXPECT_EQ(error("3 0 1 2\n"), "no error");
}

TEST(Ply, NonFiniteVerticesAreErrors) {
  TempDir dir;
  std::string path = dir.write("nan.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                                          "property float z\nend_header\n0 0 0\n1 nan 0\n");
  EXPECT_EQ(error_of(path), path + ": error: vertex 1 has a non-finite or out-of-range y (nan), expected finite values");
  std::string big = dir.write("big.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                                         "property float z\nend_header\n0 0 1e39\n");
  EXPECT_EQ(error_of(big), big + ": error: vertex 0 has a non-finite or out-of-range z (1e+39), expected finite values");
}
