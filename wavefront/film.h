// The film: per-pixel sums that many threads splat into at once.
//
// Every sample contributes weight * value to its own pixel (filter importance
// sampling: no sample touches a neighbour), so a pixel is sum(w L) / sum(w).
// A value that is NaN or infinite is dropped and counted, never stored.
#pragma once

#include "core/image.h"
#include "core/math.h"

#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

namespace theia {

// An extra RGB layer of per-pixel sums (interleaved RGB), resolved like the
// beauty (divided by the pixel's weight) as channels NAME.R NAME.G NAME.B:
// how other subsystems (the recorder's debug buffers) reach the EXR.
struct FilmLayer {
  std::string name;
  std::vector<float> rgb;
};

struct Film {
  int width = 0, height = 0;
  // Planar float sums, one entry per pixel each.
  std::vector<float> r, g, b;      // sum of w * L
  std::vector<float> weight;       // sum of w
  std::vector<float> alpha;        // sum of w where the camera ray hit geometry
  std::vector<float> albedo[3];    // first-hit AOVs, sums of w * value
  std::vector<float> normal[3];
  std::vector<float> depth;
  std::atomic<uint64_t> dropped{0};  // non-finite contributions discarded
  std::vector<FilmLayer> layers;     // extra layers, after the AOVs

  Film(int w, int h);
  size_t pixel_count() const { return size_t(width) * size_t(height); }
  size_t memory_bytes() const { return pixel_count() * 13 * sizeof(float); }

  void add_weight(uint32_t pixel, float w);
  void splat(uint32_t pixel, const RGB& weighted_L);
  void splat_first_hit(uint32_t pixel, float w, bool hit, const RGB& albedo, const vec3& n, float depth);
};

// Resolve to an image with channels R G B A albedo.R albedo.G albedo.B N.X N.Y N.Z depth.Z,
// then LAYER.R LAYER.G LAYER.B for each extra layer.
ImageBuffer resolve_film(const Film& film);

}  // namespace theia
