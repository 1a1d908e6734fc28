// Helpers every test file may use: scratch directories that clean up after themselves.
#pragma once

#include "scene/scene.h"

#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

namespace theia::test {

// A fresh directory under the system temp dir, removed with the object.  The
// name carries the process id and a counter, so parallel test processes and
// repeated runs never share one.
struct TempDir {
  std::filesystem::path path;

  explicit TempDir(const std::string& prefix = "theia") {
    static std::atomic<int> counter{0};
    path = std::filesystem::temp_directory_path() /
           (prefix + "_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  std::string file(const std::string& name) const { return (path / name).string(); }
  // Writes bytes to path/name (creating folders) and returns the full path.
  std::string write(const std::string& name, const std::string& bytes) const {
    std::filesystem::path p = path / name;
    std::filesystem::create_directories(p.parent_path());
    std::ofstream(p, std::ios::binary) << bytes;
    return p.string();
  }
};

// A test fixture with its own scratch directory: `dir` and `file(name)`.
class TempDirTest : public ::testing::Test {
 protected:
  TempDirTest() : tmp_(::testing::UnitTest::GetInstance()->current_test_info()->name()), dir(tmp_.path) {}
  std::string file(const std::string& name) const { return tmp_.file(name); }

 private:
  TempDir tmp_;

 protected:
  std::filesystem::path dir;
};

// A w x h image of `channels` (1 or 3) linear values, texel(x, y) with row 0
// at the top; a one-channel image takes the texel's first component.
template <typename TexelFn>
Image make_image(int w, int h, int channels, TexelFn texel) {
  Image img;
  img.width = w;
  img.height = h;
  img.channels = channels;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      RGB c = texel(x, y);
      for (int k = 0; k < channels; ++k) img.pixels.push_back(c[k]);
    }
  return img;
}

}  // namespace theia::test
