// libFuzzer target: the pbrt-v4 scene parser on arbitrary text.  A located
// theia::Error is the correct answer to bad input; anything else (a crash, a
// hang, another exception, an allocation beyond the fuzzer's limit) is a bug.
#include "core/log.h"
#include "scene/parser.h"

#include <cstddef>
#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  theia::set_verbosity(theia::Verbosity::Quiet);
  try {
    // Includes and file names resolve against a folder that holds nothing.
    theia::parse_scene_string(std::string(reinterpret_cast<const char*>(data), size), "fuzz.pbrt",
                              "/nonexistent-theia-fuzz");
  } catch (const theia::Error&) {
  }
  return 0;
}
