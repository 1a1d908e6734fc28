#include "core/image.h"
#include "core/log.h"
#include "tests/test_util.h"

#include <OpenEXR/ImfRgbaFile.h>
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <utility>
#include <unistd.h>

namespace theia {
namespace {

namespace fs = std::filesystem;

// A fresh directory per test, removed afterwards.
class ImageFiles : public theia::test::TempDirTest {
 protected:
  // Files in the directory other than the expected ones (e.g. stray .tmp files).
  std::vector<std::string> listing() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }
  // Reading `name` fails with one line that names the file and says `says`.
  void expect_refused(const std::string& name, const std::string& says) {
    SCOPED_TRACE(name);
    try {
      theia::read_image_file(file(name));
      FAIL() << "expected theia::Error";
    } catch (const theia::Error& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(file(name) + ": cannot read image (", 0), 0u) << what;
      EXPECT_NE(what.find(says), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
};

// A little-endian RGB PFM by hand (OpenImageIO 2.4 reads PFM but cannot
// write it).  PFM stores the bottom row first.
void write_pfm(const std::string& path, int w, int h, const std::vector<float>& top_down_rgb) {
  std::ofstream f(path, std::ios::binary);
  f << "PF\n" << w << " " << h << "\n-1.0\n";
  for (int y = h - 1; y >= 0; --y)
    f.write(reinterpret_cast<const char*>(&top_down_rgb[size_t(y) * size_t(w) * 3]),
            std::streamsize(sizeof(float) * size_t(w) * 3));
  ASSERT_TRUE(f.good());
}

// Writes raw 8-bit pixels with OpenImageIO directly, as another program would.
void write_u8(const std::string& path, int w, int h, int nc, const std::vector<uint8_t>& px) {
  auto out = OIIO::ImageOutput::create(path);
  ASSERT_TRUE(out) << OIIO::geterror();
  OIIO::ImageSpec spec(w, h, nc, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:UnassociatedAlpha", 1);  // the bytes are the file's bytes
  ASSERT_TRUE(out->open(path, spec)) << out->geterror();
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px.data())) << out->geterror();
  ASSERT_TRUE(out->close());
}

TEST_F(ImageFiles, ExrRoundTripKeepsChannelNamesAndValuesExactly) {
  std::vector<std::string> names = {"R", "G", "B", "A", "albedo.R", "albedo.G", "albedo.B",
                                    "N.X", "N.Y", "N.Z", "depth.Z"};
  ImageBuffer img(5, 3, names);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      for (int c = 0; c < img.num_channels(); ++c)
        // Values that half precision could not hold exactly.
        img.at(x, y, c) = (float(x) + 10.0f * float(y) + 100.0f * float(c)) * 1.0001f - 37.123456f + 1e-7f * float(c);
  img.at(0, 0, 10) = 123456.789f;
  img.at(1, 0, 7) = -0.3333333f;
  std::string path = file("multi.exr");
  write_exr(path, img);

  ImageFileInfo info;
  ImageBuffer back = read_image_file(path, &info);
  EXPECT_TRUE(info.float_pixels);
  EXPECT_EQ(info.format_name, "openexr");
  ASSERT_EQ(back.width, 5);
  ASSERT_EQ(back.height, 3);
  ASSERT_EQ(back.num_channels(), img.num_channels());
  // OpenEXR stores channels sorted by name, so compare by name, not position.
  for (int c = 0; c < img.num_channels(); ++c) {
    int bc = back.channel_index(img.channels[size_t(c)]);
    ASSERT_GE(bc, 0) << "missing channel " << img.channels[size_t(c)];
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x)
        EXPECT_EQ(back.at(x, y, bc), img.at(x, y, c)) << img.channels[size_t(c)] << " at " << x << "," << y;
  }
  EXPECT_EQ(listing(), std::vector<std::string>{"multi.exr"});
}

TEST_F(ImageFiles, AtomicWritesReplaceAndLeaveNoTemporary) {
  ImageBuffer a(2, 2, {"R", "G", "B"}, 1.0f), b(2, 2, {"R", "G", "B"}, 2.0f);
  std::string path = file("out.exr");
  write_exr(path, a);
  write_exr(path, b);  // overwrite in place
  EXPECT_EQ(read_image_file(path).at(1, 1, 2), 2.0f);
  write_png_srgb(file("out.png"), b, 0, 1, 2);
  EXPECT_EQ(listing(), (std::vector<std::string>{"out.exr", "out.png"}));

  // A failed write reports the path and leaves nothing behind.
  std::string bad = file("missing_dir/out.exr");
  try {
    write_exr(bad, a);
    FAIL() << "expected theia::Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(bad + ".tmp"));
  EXPECT_THROW(write_exr(file("bad.exr"), ImageBuffer()), Error);
  EXPECT_THROW(write_png_srgb(file("bad.png"), a, 0, 1, 3), Error);
  EXPECT_EQ(listing(), (std::vector<std::string>{"out.exr", "out.png"}));
}

TEST_F(ImageFiles, PngPreviewIsSrgbEncodedAndClamped) {
  ImageBuffer img(3, 2, {"X", "R", "G", "B"});
  const float v[6] = {0.0f, 0.5f, 1.0f, -1.0f, 7.0f, std::nanf("")};
  for (int i = 0; i < 6; ++i) {
    img.at(i % 3, i / 3, 1) = v[i];
    img.at(i % 3, i / 3, 2) = v[i];
    img.at(i % 3, i / 3, 3) = 0.5f;
    img.at(i % 3, i / 3, 0) = 100.0f;  // not selected
  }
  std::string path = file("preview.png");
  write_png_srgb(path, img, 1, 2, 3);

  auto in = OIIO::ImageInput::open(path);
  ASSERT_TRUE(in);
  EXPECT_EQ(in->spec().get_string_attribute("oiio:ColorSpace"), "sRGB");  // the file's sRGB chunk
  ASSERT_EQ(in->spec().nchannels, 3);
  ASSERT_EQ(in->spec().format, OIIO::TypeDesc::UINT8);
  std::vector<uint8_t> px(3 * 2 * 3);
  ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, px.data()));
  const int expected[6] = {0, 188, 255, 0, 255, 0};
  for (int i = 0; i < 6; ++i) {
    EXPECT_EQ(px[size_t(3 * i)], expected[i]) << "pixel " << i;
    EXPECT_EQ(px[size_t(3 * i + 1)], expected[i]) << "pixel " << i;
    EXPECT_EQ(px[size_t(3 * i + 2)], 188);
  }
}

// EXR (read with OpenEXR itself) and TGA, BMP, HDR and PFM (read by
// core/image_readers.h) must come back as OpenImageIO reads them: the same
// shape, channel names and order (for EXR colour first within a layer, not
// OpenEXR's alphabetical B G R), values and format name.
void expect_read_as_openimageio_reads(const std::string& path) {
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  auto in = OIIO::ImageInput::open(path, &config);
  ASSERT_TRUE(in) << OIIO::geterror();
  const OIIO::ImageSpec& spec = in->spec();
  std::vector<float> expected(size_t(spec.width) * size_t(spec.height) * size_t(spec.nchannels));
  ASSERT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, expected.data())) << in->geterror();
  ImageFileInfo info;
  ImageBuffer img = read_image_file(path, &info);
  EXPECT_EQ(info.format_name, in->format_name());
  auto bt = OIIO::TypeDesc::BASETYPE(spec.format.basetype);
  EXPECT_EQ(info.float_pixels, bt == OIIO::TypeDesc::HALF || bt == OIIO::TypeDesc::FLOAT);
  ASSERT_EQ(img.width, spec.width);
  ASSERT_EQ(img.height, spec.height);
  EXPECT_EQ(img.channels, spec.channelnames);
  ASSERT_EQ(img.data.size(), expected.size());
  EXPECT_EQ(img.data, expected);
}

TEST_F(ImageFiles, ExrChannelOrderAndValuesMatchOpenImageIO) {
  // Layers, a vector layer (X Y Z) and alpha; written in a scrambled order.
  std::vector<std::string> names = {"depth.Z", "B", "N.Z", "albedo.G", "A", "R", "N.X", "G", "albedo.B",
                                    "N.Y", "albedo.R", "Z", "custom"};
  ImageBuffer img(4, 3, names);
  for (size_t i = 0; i < img.data.size(); ++i) img.data[i] = 0.1f * float(i) - 2.0f;
  write_exr(file("layers.exr"), img);
  expect_read_as_openimageio_reads(file("layers.exr"));
  ImageBuffer back = read_image_file(file("layers.exr"));
  EXPECT_EQ(back.channels, (std::vector<std::string>{"R", "G", "B", "A", "Z", "custom", "N.X", "N.Y", "N.Z",
                                                     "albedo.R", "albedo.G", "albedo.B", "depth.Z"}));
}

TEST_F(ImageFiles, ReadsHalfTiledAndWindowedExrAsOpenImageIODoes) {
  // Half RGBA with a data window away from the origin, as another program would write it.
  std::vector<float> px(5 * 3 * 4);
  for (size_t i = 0; i < px.size(); ++i) px[i] = 0.25f * float(i) - 3.0f;
  OIIO::ImageSpec spec(5, 3, 4, OIIO::TypeDesc::HALF);
  spec.x = 7;
  spec.y = -2;
  std::string windowed = file("windowed.exr");
  auto out = OIIO::ImageOutput::create(windowed);
  ASSERT_TRUE(out && out->open(windowed, spec)) << OIIO::geterror();
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
  ASSERT_TRUE(out->close());
  expect_read_as_openimageio_reads(windowed);
  EXPECT_EQ(read_image_file(windowed).data, px);  // all exact in half

  // Tiled float.
  OIIO::ImageSpec tiled(9, 7, 3, OIIO::TypeDesc::FLOAT);
  tiled.tile_width = tiled.tile_height = 4;
  std::vector<float> tpx(9 * 7 * 3);
  for (size_t i = 0; i < tpx.size(); ++i) tpx[i] = std::sin(float(i));
  std::string tpath = file("tiled.exr");
  out = OIIO::ImageOutput::create(tpath);
  ASSERT_TRUE(out && out->open(tpath, tiled)) << OIIO::geterror();
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, tpx.data()));
  ASSERT_TRUE(out->close());
  expect_read_as_openimageio_reads(tpath);
  EXPECT_EQ(read_image_file(tpath).data, tpx);
}

TEST_F(ImageFiles, SubsampledExrIsRefusedNamingTheFile) {
  // Luminance-chroma: RY and BY at half resolution.
  const int w = 4, h = 4;
  std::vector<Imf::Rgba> px(size_t(w * h), Imf::Rgba(0.5f, 0.25f, 0.125f, 1.0f));
  std::string path = file("yc.exr");
  {
    Imf::RgbaOutputFile out(path.c_str(), w, h, Imf::WRITE_YCA);
    out.setFrameBuffer(px.data(), 1, w);
    out.writePixels(h);
  }
  try {
    read_image_file(path);
    FAIL() << "expected theia::Error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(path + ": subsampled channel", 0), 0u) << e.what();
  }
}

TEST_F(ImageFiles, ExrCompressionIsChosenByNameAndLossless) {
  ImageBuffer img(6, 5, {"R", "G", "B"});
  for (size_t i = 0; i < img.data.size(); ++i) img.data[i] = std::cos(float(i)) * 1000.0f;
  for (const char* method : {"none", "zip", "zips", "piz", "rle"}) {
    std::string path = file(std::string(method) + ".exr");
    write_exr(path, img, method);
    EXPECT_EQ(read_image_file(path).data, img.data) << method;
  }
  try {
    write_exr(file("bad.exr"), img, "lzma");
    FAIL() << "expected theia::Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("lzma"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(file("bad.exr")));
}

TEST_F(ImageFiles, ReadsPfmWithRowZeroAtTheTop) {
  std::string path = file("img.pfm");
  const int w = 3, h = 2;
  std::vector<float> px(w * h * 3);
  for (size_t i = 0; i < px.size(); ++i) px[i] = 0.25f * float(i) - 1.5f;
  write_pfm(path, w, h, px);
  ImageFileInfo info;
  ImageBuffer img = read_image_file(path, &info);
  EXPECT_TRUE(info.float_pixels);
  ASSERT_EQ(img.width, w);
  ASSERT_EQ(img.height, h);
  ASSERT_EQ(img.num_channels(), 3);
  EXPECT_EQ(img.data, px);
  EXPECT_EQ(img.rgb_channel_indices(), (std::vector<int>{0, 1, 2}));
}

TEST_F(ImageFiles, ReadsEightBitPngAndTgaAsStoredCodeValues) {
  // RGBA with a non-opaque alpha: values must come back unpremultiplied.
  std::vector<uint8_t> px = {0, 64, 128, 255, 200, 100, 50, 128, 255, 255, 255, 0, 10, 20, 30, 40};
  for (const char* name : {"img.png", "img.tga"}) {
    std::string path = file(name);
    write_u8(path, 2, 2, 4, px);
    ImageFileInfo info;
    ImageBuffer img = read_image_file(path, &info);
    EXPECT_FALSE(info.float_pixels) << name;
    ASSERT_EQ(img.width, 2) << name;
    ASSERT_EQ(img.height, 2) << name;
    ASSERT_EQ(img.num_channels(), 4) << name;
    EXPECT_EQ(img.channels[3], "A") << name;
    for (size_t i = 0; i < px.size(); ++i) EXPECT_FLOAT_EQ(img.data[i], float(px[i]) / 255.0f) << name << " " << i;
  }
}

// A test image with gradients and edges, as `type`.
void write_with_openimageio(const std::string& path, int nc, OIIO::TypeDesc type,
                            const std::string& compression = "") {
  const int w = 37, h = 21;
  std::vector<float> px(size_t(w) * h * size_t(nc));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < nc; ++c)
        px[(size_t(y) * w + size_t(x)) * size_t(nc) + size_t(c)] =
            c == 3 ? float((x * 7 + y) % 11) / 10.0f : float((x * (c + 1) + y * 3) % 17) / 16.0f * (x < 18 ? 1.0f : 0.5f);
  auto out = OIIO::ImageOutput::create(path);
  ASSERT_TRUE(out) << OIIO::geterror();
  OIIO::ImageSpec spec(w, h, nc, type);
  spec.attribute("oiio:UnassociatedAlpha", 1);
  if (!compression.empty()) spec.attribute("compression", compression);
  ASSERT_TRUE(out->open(path, spec)) << out->geterror();
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, px.data())) << out->geterror();
  ASSERT_TRUE(out->close());
}

TEST_F(ImageFiles, TextureFormatsReadWithoutOpenImageIOAsOpenImageIOReadsThem) {
  for (int nc : {3, 4}) {
    SCOPED_TRACE(nc);
    write_with_openimageio(file("raw.tga"), nc, OIIO::TypeDesc::UINT8);
    expect_read_as_openimageio_reads(file("raw.tga"));
    write_with_openimageio(file("rle.tga"), nc, OIIO::TypeDesc::UINT8, "rle");
    expect_read_as_openimageio_reads(file("rle.tga"));
  }
  write_with_openimageio(file("img.bmp"), 3, OIIO::TypeDesc::UINT8);
  expect_read_as_openimageio_reads(file("img.bmp"));
  write_with_openimageio(file("img.hdr"), 3, OIIO::TypeDesc::FLOAT);
  expect_read_as_openimageio_reads(file("img.hdr"));
  // PFM, written by hand: RGB little-endian, grey big-endian.
  std::vector<float> rgb(4 * 3 * 3);
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = 0.5f * float(i) - 3.0f;
  write_pfm(file("rgb.pfm"), 4, 3, rgb);
  expect_read_as_openimageio_reads(file("rgb.pfm"));
  {
    std::ofstream f(file("grey.pfm"), std::ios::binary);
    f << "Pf\n2 3\n1.0\n";
    for (int i = 0; i < 6; ++i) {
      const uint32_t bits = std::bit_cast<uint32_t>(float(i) * 0.75f), be = __builtin_bswap32(bits);
      f.write(reinterpret_cast<const char*>(&be), 4);
    }
  }
  expect_read_as_openimageio_reads(file("grey.pfm"));
}

// OpenImageIO's formats are read by the reader the extension names when the
// file's first bytes agree, and a misnamed file by the reader its first bytes
// name: each as OpenImageIO's open (which tries every plugin) reads it.
TEST_F(ImageFiles, OpenImageIOFormatsAreReadByTheirExtensionOrFirstBytes) {
  write_with_openimageio(file("img.png"), 4, OIIO::TypeDesc::UINT8);
  write_with_openimageio(file("img.jpg"), 3, OIIO::TypeDesc::UINT8);
  write_with_openimageio(file("img.tif"), 3, OIIO::TypeDesc::UINT16);
  for (const char* name : {"img.png", "img.jpg", "img.tif"}) expect_read_as_openimageio_reads(file(name));
  const std::pair<const char*, const char*> misnamed[] = {{"img.jpg", "jpeg.png"},  {"img.png", "png.jpg"},
                                                          {"img.tif", "tiff.exr"},  {"img.png", "png.hdr"},
                                                          {"img.jpg", "jpeg.texture"}, {"img.png", "png"}};
  for (const auto& [from, to] : misnamed) {
    SCOPED_TRACE(to);
    fs::copy_file(file(from), file(to));
    expect_read_as_openimageio_reads(file(to));
  }
}

// A corrupt file is answered by its format's reader, one line naming the file;
// bytes no reader recognises are refused without trying every plugin.
TEST_F(ImageFiles, CorruptOrUnknownFilesGetOneErrorNamingTheFile) {
  write_with_openimageio(file("img.png"), 3, OIIO::TypeDesc::UINT8);
  std::ifstream in(file("img.png"), std::ios::binary);
  std::string png((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ofstream(file("truncated.png"), std::ios::binary) << png.substr(0, png.size() / 2);
  // The signature and IHDR, whole: libpng reads past the end for the next chunk
  // (where OpenImageIO 2.4's PNG reader would leak its message).
  const size_t ihdr_end = 8 + 12 + 13;
  std::ofstream(file("ihdr-only.png"), std::ios::binary) << png.substr(0, ihdr_end);
  std::string garbled = png;
  for (size_t i = 16; i < garbled.size(); i += 3) garbled[i] = char(garbled[i] ^ 0x5a);
  std::ofstream(file("garbled.png"), std::ios::binary) << garbled;
  std::ofstream(file("text.png")) << "this is not a png";
  std::ofstream(file("text.xyz")) << "nor any other format";
  const std::pair<const char*, const char*> cases[] = {{"truncated.png", "truncated: a chunk at byte"},
                                                       {"ihdr-only.png", "truncated: the file ends inside"},
                                                       {"garbled.png", ""},
                                                       {"text.png", "not a png file"},
                                                       {"text.xyz", "unknown image format"}};
  for (const auto& [name, says] : cases) expect_refused(name, says);
}

// OpenEXR allocates what a header declares before reading it: an attribute
// claiming 1.8 GB (found by fuzzing) or a data window of 16000x16000 over a
// small file is refused first, naming the file.
TEST_F(ImageFiles, ExrHeadersClaimingMoreThanTheFileHoldsAreRefusedBeforeOpenEXRReadsThem) {
  const std::string magic_and_version("\x76\x2f\x31\x01\x02\0\0\0", 8);
  const std::string huge_size("\x14\x4e\x49\x6e", 4);  // 1,850,297,876 bytes, little-endian
  std::ofstream(file("huge-attribute.exr"), std::ios::binary)
      << magic_and_version << std::string("comments\0string\0", 16) << huge_size << std::string(100, 'x');
  ImageBuffer img(4, 3, {"R", "G", "B"});
  write_exr(file("window.exr"), img);
  std::ifstream in(file("window.exr"), std::ios::binary);
  std::string exr((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string key("dataWindow\0box2i\0\x10\0\0\0", 21);
  const size_t box = exr.find(key);
  ASSERT_NE(box, std::string::npos);
  const int32_t max_corner = 15999;
  exr.replace(box + key.size() + 8, 4, reinterpret_cast<const char*>(&max_corner), 4);
  exr.replace(box + key.size() + 12, 4, reinterpret_cast<const char*>(&max_corner), 4);
  std::ofstream(file("huge-window.exr"), std::ios::binary) << exr;
  // OpenEXR reads a channel list up to its empty name whatever size it declares
  // (a fuzzed file hid its data window so): the check reads it the same way.
  const std::string chlist("channels\0chlist\0", 16);
  const size_t sizes = exr.find(chlist) + chlist.size();
  ASSERT_EQ(exr.find(chlist), exr.find("channels"));
  exr[sizes] = char(exr[sizes] + 20);
  std::ofstream(file("huge-window-behind-chlist.exr"), std::ios::binary) << exr;
  const std::pair<const char*, const char*> cases[] = {{"huge-attribute.exr", "\"comments\" claims 1850297876 bytes"},
                                                       {"huge-window.exr", "16000x16000x1 values"},
                                                       {"huge-window-behind-chlist.exr", "16000x16000x1 values"}};
  for (const auto& [name, says] : cases) expect_refused(name, says);
}

// A header that claims more pixels than its file can hold is refused before
// anything that size is allocated.
TEST_F(ImageFiles, HeadersClaimingMoreThanTheFileHoldsAreRefused) {
  std::ofstream(file("huge.pfm"), std::ios::binary) << "PF\n16000 16000\n-1.0\n" << std::string(100, 'x');
  // 16000 x 16000 RGB: PNG (read by OpenImageIO; IHDR and an empty IDAT with their CRCs) and TGA
  // (core/image_readers.h).
  std::string png("\x89PNG\r\n\x1a\n\0\0\0\rIHDR\0\0\x3e\x80\0\0\x3e\x80\x08\x02\0\0\0\xce\x1c\x48\x89"
                  "\0\0\0\0IDAT\x35\xaf\x06\x1e", 45);
  std::ofstream(file("huge.png"), std::ios::binary) << png << std::string(100, '\0');
  std::string tga("\0\0\x02\0\0\0\0\0\0\0\0\0\x80\x3e\x80\x3e\x18\0", 18);
  std::ofstream(file("huge.tga"), std::ios::binary) << tga << std::string(100, '\0');
  for (const char* name : {"huge.pfm", "huge.png", "huge.tga"}) {
    try {
      read_image_file(file(name));
      FAIL() << name << ": expected theia::Error";
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()).rfind(file(name) + ":", 0), 0u) << e.what();
      EXPECT_NE(std::string(e.what()).find("16000x16000"), std::string::npos) << e.what();
    }
  }
}

TEST_F(ImageFiles, ReadErrorsNameTheFile) {
  std::string missing = file("nope.exr");
  try {
    read_image_file(missing);
    FAIL() << "expected theia::Error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(missing + ":", 0), 0u) << e.what();
  }
  std::string junk = file("junk.png");
  std::ofstream(junk) << "this is not a png";
  try {
    read_image_file(junk);
    FAIL() << "expected theia::Error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(junk + ":", 0), 0u) << e.what();
  }
}

TEST(ImageSrgb, TransferFunctionMatchesTheStandard) {
  EXPECT_EQ(srgb_to_linear(0.0f), 0.0f);
  EXPECT_FLOAT_EQ(srgb_to_linear(1.0f), 1.0f);
  EXPECT_NEAR(srgb_to_linear(0.5f), 0.2140411f, 1e-6f);
  EXPECT_NEAR(srgb_to_linear(0.04f), 0.04f / 12.92f, 1e-9f);  // linear toe
  for (int i = 0; i <= 255; ++i) {
    float lin = srgb8_to_linear(uint8_t(i));
    EXPECT_FLOAT_EQ(lin, srgb_to_linear(float(i) / 255.0f));
    EXPECT_EQ(linear_to_srgb8(lin), i) << "8-bit codes must survive decode + encode";
  }
  EXPECT_EQ(linear_to_srgb8(0.5f), 188);
}

TEST(ImageSrgb, TexelDecodeEqualsTheTransferFunctionBitForBit) {
  // 8-bit code values as the readers give them take the table; anything else the formula.
  for (int i = 0; i <= 255; ++i) {
    const float v = float(i) * (1.0f / 255.0f);
    EXPECT_EQ(srgb_texel_to_linear(v), srgb_to_linear(v)) << i;
    EXPECT_EQ(srgb_texel_to_linear(std::nextafter(v, 2.0f)), srgb_to_linear(std::nextafter(v, 2.0f))) << i;
    const float w = float(i) / 65535.0f;  // 16-bit codes
    EXPECT_EQ(srgb_texel_to_linear(w), srgb_to_linear(w)) << i;
  }
  EXPECT_EQ(srgb_texel_to_linear(-0.25f), srgb_to_linear(-0.25f));
  EXPECT_EQ(srgb_texel_to_linear(1.5f), srgb_to_linear(1.5f));
}

TEST(ImageBufferTest, IndexingIsInterleavedRowMajorFromTheTop) {
  ImageBuffer img(3, 2, {"R", "G"});
  img.at(2, 1, 1) = 5.0f;
  EXPECT_EQ(img.data[(1 * 3 + 2) * 2 + 1], 5.0f);
  EXPECT_EQ(img.channel_index("G"), 1);
  EXPECT_EQ(img.channel_index("B"), -1);
  EXPECT_EQ(img.rgb_channel_indices(), (std::vector<int>{0, 1}));
  ImageBuffer named(1, 1, {"A", "B", "G", "R", "Z"});
  EXPECT_EQ(named.rgb_channel_indices(), (std::vector<int>{3, 2, 1}));
}

}  // namespace
}  // namespace theia
