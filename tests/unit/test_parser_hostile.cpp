// Hostile input (issue 16): each case is the exact input that crashed,
// hung or rendered garbage, and the one located error or warning it gets now.
#include "checkpoint/checkpoint.h"
#include "core/log.h"
#include "core/image.h"
#include "scene/parser.h"
#include "scene/texture.h"
#include "tests/test_util.h"
#include "wavefront/film.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

using namespace theia;
using theia::test::TempDir;
namespace fs = std::filesystem;

namespace {

// The error f() throws, or "no error".
template <class F>
std::string error_from(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

std::string error_of(const std::string& text) {
  return error_from([&] { parse_scene_string(text, "test.pbrt", "."); });
}

// A PFM header claiming w x h RGB pixels, then `body` bytes of zeros.
std::string pfm(int w, int h, size_t body) {
  return fmt::format("PF\n{} {}\n-1.0\n", w, h) + std::string(body, '\0');
}

}  // namespace

// ---------------------------------------------------------------- camera, film, filter

TEST(ParserHostile, CameraErrorsNameTheCameraDirective) {
  EXPECT_EQ(error_of("Film \"rgb\"\nCamera \"perspective\" \"float fov\" [0]\nWorldBegin"),
            "test.pbrt:2:1: error: perspective camera: \"fov\" must be in (0, 180) degrees, got 0");
  EXPECT_EQ(error_of("Camera \"perspective\" \"float lensradius\" [-1]\nWorldBegin"),
            "test.pbrt:1:1: error: perspective camera: \"lensradius\" must be non-negative, got -1");
  EXPECT_EQ(error_of("Camera \"orthographic\" \"float lensradius\" [1] \"float focaldistance\" [0]\nWorldBegin"),
            "test.pbrt:1:1: error: orthographic camera: \"focaldistance\" must be positive, got 0");
  EXPECT_EQ(error_of("Camera \"perspective\" \"float fov\" [45]\nWorldBegin"), "no error");
}

TEST(ParserHostile, FilterErrorsNameThePixelFilterDirective) {
  EXPECT_EQ(error_of("\nPixelFilter \"gaussian\" \"float xradius\" [0]\nWorldBegin"),
            "test.pbrt:2:1: error: filter: \"radius\" must be positive and at most 32 pixels, got (0, 1.5)");
  // A radius of 1e30 asked for a sampling table of (32e30)^2 cells.
  EXPECT_EQ(error_of("PixelFilter \"mitchell\" \"float yradius\" [1e30]\nWorldBegin"),
            "test.pbrt:1:1: error: filter: \"radius\" must be positive and at most 32 pixels, got (2, 1e+30)");
  EXPECT_EQ(error_of("PixelFilter \"gaussian\" \"float sigma\" [0]\nWorldBegin"),
            "test.pbrt:1:1: error: gaussian filter: \"sigma\" must be positive and finite, got 0");
  EXPECT_EQ(error_of("PixelFilter \"sinc\" \"float xradius\" [32] \"float yradius\" [32]\nWorldBegin"), "no error");
}

TEST(ParserHostile, FilmResolutionBeyond32BitPixelIndicesIsAnError) {
  EXPECT_EQ(error_of("Film \"rgb\" \"integer xresolution\" [100000] \"integer yresolution\" [100000]\nWorldBegin"),
            "test.pbrt:1:1: error: film resolution 100000x100000, expected fewer than 2^32 pixels");
}

// ---------------------------------------------------------------- emission and texels

TEST(ParserHostile, EmissionThatWouldOverflowIsAnError) {
  EXPECT_EQ(error_of("WorldBegin\nAreaLightSource \"diffuse\" \"rgb L\" [3e38 3e38 3e38]\nShape \"sphere\""),
            "test.pbrt:2:1: error: emission 3e+38 (after \"scale\" and \"power\"), expected at most 1e+20");
  EXPECT_EQ(error_of("WorldBegin\nLightSource \"point\" \"rgb I\" [3e38 3e38 3e38]"),
            "test.pbrt:2:1: error: emission 3e+38 (after \"scale\" and \"power\"), expected at most 1e+20");
  // Within float's range one by one, beyond the limit together.
  EXPECT_EQ(error_of("WorldBegin\nLightSource \"infinite\" \"rgb L\" [1e19 1e19 1e19] \"float scale\" [100]"),
            "test.pbrt:2:1: error: emission 1e+21 (after \"scale\" and \"power\"), expected at most 1e+20");
  EXPECT_EQ(error_of("WorldBegin\nLightSource \"distant\" \"rgb L\" [1e9 1e9 1e9]"), "no error");
}

TEST(ParserHostile, HugeTexelsAreClampedToZeroWithOneWarning) {
  TempDir dir;
  std::vector<float> px = {3e38f, 1.0f, 0.5f, 2e20f, -3e38f, 0.25f};
  std::string bytes = "PF\n2 1\n-1.0\n";
  bytes.append(reinterpret_cast<const char*>(px.data()), px.size() * sizeof(float));
  Image image;
  image.filename = dir.write("huge.pfm", bytes);
  image.encoding = "linear";
  int before = warning_count();
  load_image(image, "");
  EXPECT_EQ(warning_count() - before, 1);
  ASSERT_EQ(image.pixels.size(), 6u);
  const std::vector<float> want = {0.0f, 1.0f, 0.5f, 0.0f, 0.0f, 0.25f};
  for (size_t i = 0; i < want.size(); ++i) EXPECT_EQ(image.pixels[i], want[i]) << i;
}

TEST(ParserHostile, ImageLoadErrorsNameTheSceneLine) {
  TempDir dir;
  dir.write("bad.png", "garbage, not a PNG");
  Scene s = parse_scene_string(
      "WorldBegin\nTexture \"t\" \"spectrum\" \"imagemap\"\n  \"string filename\" \"bad.png\"\n", "test.pbrt",
      dir.path.string());
  std::string e = error_from([&] { load_images(s); });
  EXPECT_EQ(e.rfind("test.pbrt:3:3: error: " + (dir.path / "bad.png").string() + ": cannot read image (", 0), 0u)
      << e;
}

TEST(ImageHostile, HeaderSizesBeyondTheFileAreRefusedBeforeAllocating) {
  TempDir dir;
  // 16000 x 16000 RGB floats (3 GB) promised by a header over a 100-byte body.
  const std::string big = dir.write("big.pfm", pfm(16000, 16000, 100));
  EXPECT_EQ(error_from([&] { read_image_file(big); }),
            big + ": cannot read image (the header's 16000x16000x3 values cannot come from a file of " +
                std::to_string(fs::file_size(big)) + " bytes (truncated or corrupt))");
  // A whole small image still loads.
  const std::string ok = dir.write("ok.pfm", pfm(4, 2, 4 * 2 * 3 * sizeof(float)));
  EXPECT_EQ(read_image_file(ok).pixel_count(), 8u);
}

// Textures count against the memory limit: each image's float values are
// checked from its header before they are allocated, and the image at which
// the scene's images (in scene order) would exceed what is left is named with
// the scene line that loaded it, whichever thread read it first.
TEST(ImageHostile, TexturesBeyondTheMemoryLeftAreRefusedWithTheirSceneLine) {
  TempDir dir;
  const size_t bytes = 8 * 8 * 3 * sizeof(float);  // 768
  const std::string a = dir.write("a.pfm", pfm(8, 8, bytes));
  const std::string b = dir.write("b.pfm", pfm(8, 8, bytes));
  const std::string text = "WorldBegin\nTexture \"a\" \"spectrum\" \"imagemap\" \"string filename\" \"a.pfm\"\n"
                           "Texture \"b\" \"spectrum\" \"imagemap\" \"string filename\" \"b.pfm\"\n";
  auto load = [&](uint64_t max_bytes) {
    Scene s = parse_scene_string(text, "test.pbrt", dir.path.string());
    return error_from([&] { load_images(s, max_bytes); });
  };
  const std::string left = ", over the 1000 bytes the memory limit leaves for the scene's images (--memory-limit)";
  for (int repeat = 0; repeat < 4; ++repeat)
    EXPECT_EQ(load(1000), "test.pbrt:3:35: error: " + b +
                              ": its 8x8x3 float values need 768 bytes (1536 bytes with the images before it)" + left);
  EXPECT_EQ(load(700), "test.pbrt:2:35: error: " + a +
                           ": its 8x8x3 float values need 768 bytes, over the 700 bytes the memory limit leaves for "
                           "the scene's images (--memory-limit)");
  EXPECT_EQ(load(1536), "no error");
  // Megabytes where they are megabytes.
  const std::string big = dir.write("big.pfm", pfm(512, 512, 512 * 512 * 3 * sizeof(float)));
  Image image;
  image.filename = big;
  Scene s;
  s.images.push_back(image);
  EXPECT_EQ(error_from([&] { load_images(s, 1'000'000); }),
            big + ": its 512x512x3 float values need 3.1 MB, over the 1.0 MB the memory limit leaves for the scene's "
                  "images (--memory-limit)");
}

// ---------------------------------------------------------------- the film

TEST(FilmHostile, ValuesThatWouldOverflowItsSumsAreDroppedAndCounted) {
  Film film(2, 1);
  film.splat(0, 0, RGB(3e38f, 1.0f, 1.0f), kEventEmission);
  film.splat(0, 1, RGB(3e38f, 1.0f, 1.0f), kEventEmission);
  film.splat(0, 2, RGB(1.0f, INFINITY, 1.0f), kEventEmission);
  film.splat(0, 3, RGB(1.0f, 1.0f, -2e30f), kEventEmission);
  film.splat(1, 0, RGB(1e30f, 2.0f, 3.0f), kEventEmission);  // at the bound: kept
  EXPECT_EQ(film.dropped.load(), 4u);
  EXPECT_EQ(film.r[0], 0.0f);
  EXPECT_EQ(film.r[1], 1e30f);
  EXPECT_EQ(film.b[1], 3.0f);
  // 1e8 samples at the bound still sum to a finite float.
  EXPECT_TRUE(std::isfinite(1e8f * kMaxSampleValue));
}

// ---------------------------------------------------------------- includes

TEST(ParserHostile, IncludeNestingIsLimited) {
  TempDir dir;
  // 70 distinct files, each including the next: no cycle, but too deep.
  for (int i = 0; i < 70; ++i) dir.write(fmt::format("f{}.pbrt", i), fmt::format("Include \"f{}.pbrt\"\n", i + 1));
  dir.write("f70.pbrt", "WorldBegin\n");
  std::string e = error_from([&] { load_scene(dir.file("f0.pbrt")); });
  EXPECT_NE(e.find(": error: Include nested 64 files deep, expected at most 64"), std::string::npos) << e;
}

// ---------------------------------------------------------------- checkpoints

TEST(ParserHostile, AStrayCheckpointNameIsNotAGeneration) {
  TempDir dir;
  dir.write("checkpoint-abcdef.bin", "stray");
  dir.write("checkpoint-+12345.bin", "stray");
  std::vector<std::string> rejected;
  EXPECT_FALSE(read_latest_checkpoint(dir.path.string(), &rejected));
  EXPECT_TRUE(rejected.empty());
}
