// Render state on disk, for render farms that move a job between machines.
//
// A checkpoint is a pair of files in the checkpoint directory:
//   checkpoint-NNNNNN.exr  every image plane (float32 OpenEXR, so a user can
//                          open it: R G B A are the image so far),
//   checkpoint-NNNNNN.bin  a versioned binary: fingerprints of the scene and of
//                          the options that change the image, the EXR's size
//                          and checksum, then named, versioned sections that
//                          subsystems register, and a checksum of it all.
// The .bin is written last (temporary name, flushed, fsync'd, renamed), so it
// is the commit mark: a pair without a valid .bin does not exist.  The newest
// generation and the one before it are kept; older ones are deleted only after
// a new pair is complete.  Reading tries generations newest first and skips
// any that is truncated or corrupt.
#pragma once

#include "core/bytes.h"
#include "core/image.h"

#include <cstdint>
#include <cstring>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace theia {

inline constexpr uint32_t kCheckpointFormatVersion = 1;

struct CheckpointSection {
  std::string name;
  uint32_t version = 1;
  std::vector<uint8_t> bytes;
};

struct Checkpoint {
  uint64_t generation = 0;     // increases with every checkpoint of a render
  uint64_t scene_hash = 0;
  uint64_t options_hash = 0;
  ImageBuffer image;           // every plane, written as OpenEXR
  std::vector<CheckpointSection> sections;

  const CheckpointSection* find(const std::string& name) const;
};

// Writes generation c.generation atomically and deletes generations older
// than the previous one.  Throws theia::Error on I/O failure.
void write_checkpoint(const std::string& dir, const Checkpoint& c);

// The newest valid checkpoint in dir, or nothing if dir holds none.  Each
// generation found invalid (truncated, corrupt, unreadable EXR) is described in
// *rejected (when given); if some exist but none is valid, throws theia::Error
// naming what was wrong with each.
std::optional<Checkpoint> read_latest_checkpoint(const std::string& dir, std::vector<std::string>* rejected = nullptr);

// Paths of a generation's files.
std::string checkpoint_bin_path(const std::string& dir, uint64_t generation);
std::string checkpoint_exr_path(const std::string& dir, uint64_t generation);

}  // namespace theia

namespace theia {

// A subsystem whose state must survive a resume (guiding field, cache points,
// recorder skip rate) registers one of these; its bytes go in a section of
// that name and version.  load() gets the version that was written and throws
// theia::Error if it cannot read it.
struct CheckpointParticipant {
  std::string name;
  uint32_t version = 1;
  std::function<std::vector<uint8_t>()> save;
  std::function<void(const CheckpointSection&)> load;
};

}  // namespace theia
