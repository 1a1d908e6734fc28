// What the `theia` process loads: OpenImageIO's dependency tree (through
// libtheia_oiio.so) only when an image in a format that neither OpenEXR nor
// core/image_readers.h reads (PNG, JPEG, ...) is read, never for a render of
// EXR, TGA, BMP, HDR or PFM images.
#include "render_helpers.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <string>

namespace {

using theia::test::RunResult;

// The libraries the dynamic loader opens, from its own trace.
RunResult run_traced(const std::string& args) {
  return theia::test::run_shell("LD_DEBUG=files " + std::string(THEIA_BINARY) + " " + args);
}

bool loaded(const RunResult& r, const std::string& library) {
  return r.output.find("file=" + library) != std::string::npos;
}

}  // namespace

TEST(SharedLibraries, OpenImageIOIsLoadedOnlyForFormatsOpenExrDoesNotRead) {
  theia::test::TempDir tmp("theia_startup");
  std::string scene = std::string(THEIA_SCENES) + "/cornell-box/scene.pbrt";
  RunResult render = run_traced("render " + scene + " -o " + tmp.file("out.exr") + " --spp 1 -q");
  ASSERT_EQ(render.exit_code, 0) << render.output;
  ASSERT_TRUE(loaded(render, "libembree3")) << "no loader trace:\n" << render.output;
  EXPECT_FALSE(loaded(render, "libOpenImageIO")) << render.output;
  EXPECT_FALSE(loaded(render, "libtheia_oiio")) << render.output;

  RunResult exr = run_traced("diff " + tmp.file("out.exr") + " " + tmp.file("out.exr"));
  ASSERT_EQ(exr.exit_code, 0) << exr.output;
  EXPECT_FALSE(loaded(exr, "libOpenImageIO")) << exr.output;

  // The preview PNG is read through the module, found from the binary's run path.
  RunResult png = run_traced("diff " + tmp.file("out.png") + " " + tmp.file("out.png"));
  ASSERT_EQ(png.exit_code, 0) << png.output;
  EXPECT_TRUE(loaded(png, "libtheia_oiio.so")) << png.output;
  EXPECT_TRUE(loaded(png, "libOpenImageIO")) << png.output;
  EXPECT_NE(png.output.find("relMSE 0"), std::string::npos) << png.output;

  // A TGA texture (core/image_readers.h) is not.
  tmp.write("img.tga", std::string("\0\0\x02\0\0\0\0\0\0\0\0\0\x02\0\x01\0\x18\0\x10\x20\x30\x40\x50\x60", 24));
  RunResult tga = run_traced("diff " + tmp.file("img.tga") + " " + tmp.file("img.tga"));
  ASSERT_EQ(tga.exit_code, 0) << tga.output;
  EXPECT_FALSE(loaded(tga, "libOpenImageIO")) << tga.output;
  EXPECT_NE(tga.output.find("relMSE 0"), std::string::npos) << tga.output;
}
