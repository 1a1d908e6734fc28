// Split frames: one frame rendered as disjoint sample ranges by many
// processes, then merged.  A sample is a pure function of (seed, pixel,
// sample index), so the part rendering samples [BEGIN, END) (`theia render
// --sample-range BEGIN:END`) holds exactly the film sums a whole render
// accumulates for those samples; adding the parts' sums and resolving gives
// the whole render's image up to float summation order.
//
// A part is two files: PART.exr (R G B A ... the part's own image, to look at,
// then every film plane as sum.NAME, float32) and PART.json (its render log,
// whose "part" object says what the merge checks: the sample range, the
// frame's spp, the scene and options fingerprints, the seed, the image
// options by name, and what learned on its own in the part).
//
// What learns between iterations (guiding, cache points' visibility) learns
// in each part on its own, from the part's first sample: no part waits for
// another, and every part's estimate is unbiased, so their merge is too; but
// it is not the image one process renders, whose later samples use what its
// earlier ones taught.  Such parts say so ("learns"), and the merge says so.
#pragma once

#include "core/image.h"
#include "wavefront/film.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace theia {

struct SampleRange {
  uint32_t begin = 0, end = 0;  // samples [begin, end) of every pixel; end 0: the whole frame
  bool whole() const { return end == 0; }
};

// "BEGIN:END" with 0 <= BEGIN < END; throws theia::Error naming --sample-range.
SampleRange parse_sample_range(const std::string& text);

// What a part's log carries for the merge (log["part"]).
struct PartInfo {
  SampleRange range;
  int spp = 0;                    // the whole frame's samples per pixel
  uint64_t scene_fingerprint = 0;
  uint64_t options_fingerprint = 0;
  uint32_t seed = 0;
  nlohmann::json image_options;   // every image option by name (to name the ones that differ)
  // What learned on its own in the part ("guiding", "cachepoints"); empty:
  // the parts merge to the single-process image.
  std::vector<std::string> learns;
};
nlohmann::json part_json(const PartInfo& part);
// Throws theia::Error naming `what` when `json` is not a part's.
PartInfo part_from_json(const nlohmann::json& json, const std::string& what);

// The part's EXR: its resolved image (what a user opens) followed by the film sums.
ImageBuffer part_image(const ImageBuffer& resolved, const ImageBuffer& sums);

// A part read back: its log's "part", the film sums, the samples it dropped.
struct Part {
  std::string path;  // PART.exr
  PartInfo info;
  nlohmann::json log;
  ImageBuffer image;
};
Part read_part(const std::string& exr_path);

// Checks that the parts are of one frame (scene, image options, seed, size,
// spp, what learns in them) and that their ranges tile [0, spp) with no overlap and no gap; throws
// theia::Error naming the parts (and options) that do not fit.  Returns the
// parts' indices in sample order.
std::vector<size_t> check_parts(const std::vector<Part>& parts);

// The merged film: every part's sums added, in sample order.
void merge_parts(const std::vector<Part>& parts, const std::vector<size_t>& order, Film& film);

// `theia merge PARTS... -o OUT.exr [--log OUT.json]`: checks, adds, writes
// OUT.exr, OUT.png and the log.  Returns the exit code; throws theia::Error.
int run_merge(const std::vector<std::string>& parts, const std::string& output, std::string log_path);

}  // namespace theia
