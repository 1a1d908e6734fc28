// What the fuzz targets share: the input as a file (the PLY and image
// readers take paths), one per process, and the exceptions that are a
// correct answer to bad input.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <unistd.h>

namespace theia::fuzz {

// Writes the input to a file of this process with the given extension and returns its path.
// In /dev/shm (memory) where there is one: rewriting a truncated file on a disk
// file system makes ext4 start writeback at every close (auto_da_alloc), and the
// targets then waited on the disk most of their time (PLY: 1.6 CPU-s in 21 s).
inline std::string write_input(const uint8_t* data, size_t size, const std::string& extension) {
  static const std::string dir = ::access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
  std::string path = dir + "/theia-fuzz-" + std::to_string(::getpid()) + extension;
  if (FILE* f = std::fopen(path.c_str(), "wb")) {
    if (size > 0) std::fwrite(data, 1, size, f);
    std::fclose(f);
  }
  return path;
}

}  // namespace theia::fuzz
