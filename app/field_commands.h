// `theia field view|stats|image`: what a saved guiding field (render
// --save-field, guiding/field_file.h) holds, as a web page, as numbers and
// as an image of one point's directional distribution.
#pragma once

#include <CLI/CLI.hpp>

#include <array>
#include <string>

namespace theia {

class FieldCommands {
 public:
  explicit FieldCommands(CLI::App& app);
  bool parsed() const;
  int run() const;  // the parsed one's exit code; throws theia::Error

 private:
  CLI::App *view_ = nullptr, *stats_ = nullptr, *image_ = nullptr;
  std::string file_, output_;
  int iteration_ = -1;  // snapshot by iteration; -1: the last
  bool json_ = false;
  int leaf_ = -1;  // stats: also list this leaf's mixture lobes; -1: none
  std::array<float, 3> point_{0.0f, 0.0f, 0.0f};
  int width_ = 256;
};

}  // namespace theia
