// Which sample dimension each random decision of a path draws, from one table.
//
// Every number is sample_1d/2d(seed, pixel, sample, dimension) (core/sampler.h);
// pairs (2k, 2k+1) are jointly stratified, so a 2D decision takes an even slot.
// The camera has its own slots; each bounce has pages of kDimsPerPage slots.
// Page 0 holds the surface decisions; a feature that needs numbers of its own
// (a medium's free-flight distance, a cache point's choice, a guide's) takes
// slots on a later page, which lives at its own base far above page 0.  So
// adding a feature moves no existing dimension, and every render that does
// not use it draws exactly the numbers it drew before.
#pragma once

#include "core/sampler.h"
#include "scene/filter.h"
#include "scene/scene.h"

#include <cstdint>

namespace theia {

inline constexpr uint32_t kDimsPerPage = 8;
inline constexpr uint32_t kPageStride = 1u << 24;  // page p of bounce d starts at p * kPageStride + ...

//   slot          page  offset  width  meaning
#define THEIA_BOUNCE_DIMS(F)                                                          \
  F(light_point,   0, 0, 2, "the point on the light (NEE)")                           \
  F(light_choice,  0, 2, 1, "which light (NEE)")                                      \
  F(light_prim,    0, 3, 1, "which primitive of the light (NEE)")                     \
  F(bsdf_dir,      0, 4, 2, "the scattered direction (BSDF or guide)")                \
  F(bsdf_lobe,     0, 6, 1, "which lobe, or guide versus BSDF")                       \
  F(roulette,      0, 7, 1, "Russian roulette")                                       \
  F(guide_dir,     1, 0, 2, "the guide's candidate direction (RIS)")                  \
  F(guide_pick,    1, 2, 1, "which RIS candidate")                                    \
  F(medium_flight, 1, 3, 1, "the first free-flight distance in a medium (delta tracking)") \
  /* page 1, offsets 4..7: free for the next feature (cache points) */

struct CameraDims {
  static constexpr uint32_t film = 0;  // 2D: the point on the pixel (filter importance sampling)
  static constexpr uint32_t lens = 2;  // 2D: the point on the lens
  static constexpr uint32_t count = 4;
};

// Camera sample (pixel, sample)'s point on the pixel and filter weight: the
// camera rays draw it (a block of samples at a time, from a pair made once
// per pixel, through sample_filter's span form: the same bits), and the
// caustic pass weights its splats into that sample by the same weight
// (wavefront/caustics.h).
inline FilterSample camera_filter_sample(const Filter& filter, uint32_t seed, uint32_t pixel, uint32_t sample) {
  return sample_filter(filter, sample_2d(SamplerKey{seed, pixel, sample}, CameraDims::film));
}

// The dimensions of bounce `depth` (the vertex at hit `depth`, 0 = the primary hit).
struct BounceDims {
#define THEIA_BOUNCE_DIM_MEMBER(name, page, offset, width, doc) uint32_t name;
  THEIA_BOUNCE_DIMS(THEIA_BOUNCE_DIM_MEMBER)
#undef THEIA_BOUNCE_DIM_MEMBER
};

constexpr BounceDims bounce_dims(uint32_t depth) {
  const uint32_t base = CameraDims::count + kDimsPerPage * depth;
  return BounceDims{
#define THEIA_BOUNCE_DIM_VALUE(name, page, offset, width, doc) (page) * kPageStride + base + (offset),
      THEIA_BOUNCE_DIMS(THEIA_BOUNCE_DIM_VALUE)
#undef THEIA_BOUNCE_DIM_VALUE
  };
}

// A vertex's continuation draws its numbers four at once (sample_4d: the
// shading stage draws a chunk of hits' fours in vector lanes): bsdf_dir,
// bsdf_lobe and roulette, in a row from an even dimension.
static_assert(bounce_dims(0).bsdf_dir % 2 == 0 && bounce_dims(0).bsdf_lobe == bounce_dims(0).bsdf_dir + 2 &&
              bounce_dims(0).roulette == bounce_dims(0).bsdf_dir + 3);

// True when NEE's light_choice pair (light_choice, light_prim) decides
// nothing, so that the engine need not draw it: one light, not an area light
// (sample_li reads the primitive number only to pick a shape's triangle), and
// a light sampler that neither learns nor names triangles.  Every such sampler
// returns that light for every u (uniform and power: one entry; the light BVH:
// an infinite light takes the whole infinite share, any other is the tree's
// one leaf), which tests/unit/test_light_sampler.cpp checks.  The pair keeps
// its slots, so every other decision draws what it drew.
inline bool light_choice_fixed(const Scene& scene, bool sampler_learns, bool sampler_names_primitives) {
  return scene.lights.size() == 1 && scene.lights[0].kind != LightKind::Area && !sampler_learns &&
         !sampler_names_primitives;
}

// The table's own checks: every slot inside its page, 2D slots on even
// offsets (so that the pair is jointly stratified), no two slots overlapping.
namespace sample_dims_detail {
struct Slot {
  uint32_t page, offset, width;
};
inline constexpr Slot kSlots[] = {
#define THEIA_BOUNCE_DIM_SLOT(name, page, offset, width, doc) {page, offset, width},
    THEIA_BOUNCE_DIMS(THEIA_BOUNCE_DIM_SLOT)
#undef THEIA_BOUNCE_DIM_SLOT
};
constexpr bool table_is_consistent() {
  for (const Slot& a : kSlots) {
    if (a.offset + a.width > kDimsPerPage || (a.width == 2 && a.offset % 2 != 0)) return false;
    for (const Slot& b : kSlots)
      if (&a != &b && a.page == b.page && a.offset < b.offset + b.width && b.offset < a.offset + a.width) return false;
  }
  return true;
}
static_assert(table_is_consistent(), "THEIA_BOUNCE_DIMS: slots must fit their page, pair on even offsets, not overlap");
}  // namespace sample_dims_detail

}  // namespace theia
