// libFuzzer target: the PLY reader on arbitrary bytes (ASCII and binary
// bodies, headers with any counts).  theia::Error is the correct answer.
#include "core/log.h"
#include "fuzz/fuzz_input.h"
#include "scene/ply.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  theia::set_verbosity(theia::Verbosity::Quiet);
  const std::string path = theia::fuzz::write_input(data, size, ".ply");
  try {
    theia::read_ply(path);
  } catch (const theia::Error&) {
  }
  return 0;
}
