// Cache points (seeds/002 section 3): light selection from a sparse set of
// points, each holding the lights that matter around it, learned visibility
// included.
//
// Build (between scene load and the first iteration; deterministic, parallel):
// candidates in the bounds of the objects and on the vertices of short pilot
// paths from the camera; near-duplicates merged (KD-tree, nanoflann); per
// point a near list (lights within D = 4 point radii, evaluated exactly at
// each vertex) and far values in 7 sensor bins (6 cardinal planes and the
// fluence), each bin keeping 4..256 lights that carry 97% of its estimated
// energy; far values blurred over the 16 nearest points.
//
// Selection at a vertex: the nearest point; near lights weighted by their
// estimate at the vertex, far lights by the bins weighted with the geometric
// normal (the fluence bin where there is none); every weight times the
// learned visibility; a small uniform share over all emitters keeps every
// light possible (the lists carry 97%, and occlusion is learned, not known).
// pmf() recomputes exactly what sample() chose with, for MIS.
//
// Visibility (section 3.2): every traced shadow ray counts an attempt and, if
// it reached the light, a success, per (point, listed light).  update()
// turns the counts into W = ((s+1)/(a+1) / R_min)^2 below R_min = 0.04, else
// 1, blurred over the same 16 neighbours.  Counts are integers added
// atomically: their sums, and so what is learned, do not depend on the order
// or the thread count.
#pragma once

#include "cachepoints/emitters.h"
#include "core/light_sampler.h"
#include "scene/accel.h"

#include <atomic>
#include <memory>

namespace theia {

struct CachePointParams {
  // Candidates.  The paper's caps (100k in object bounds, 1M on pilot
  // vertices) are for production scenes; the build costs points x lights, so
  // these are sized for scenes of 10^4..10^5 emitters.
  // Object candidates cost build time in proportion and, on many-lights-city
  // (64 spp, seeds 0-2), buy nothing past 1024: relMSE 0.0273 / 0.0403 /
  // 0.0282 with 2048, 0.0281 / 0.0402 / 0.0283 with 1024, 0.0277 / 0.0412 /
  // 0.0291 with 512; whole-process CPU 10.5, 8.0, 7.6 s.
  int object_candidates = 1024;
  int pilot_width = 48, pilot_height = 27;  // pilot paths: one per cell of this grid over the film
  int pilot_depth = 3;
  int max_pilot_candidates = 4096;
  float merge_radius = 1e-5f;   // relative to the scene radius
  int radius_neighbours = 8;    // a point's radius: the distance to this many-th neighbour
  float near_factor = 4.0f;     // D: near when within D point radii
  int max_near = 32;            // the closest ones (at most 64); the rest count as far
  int min_far = 4, max_far = 256;
  float far_energy = 0.97f;
  // The build evaluates at each point only the emitters the light tree cannot
  // rule out: a node is left out when the brightest emitter it could hold
  // delivers at most this share of what was found so far (per group of bins).
  // 0: every emitter at every point.
  float cull = 1e-3f;
  // Section 3.1.4's second merge: points whose light distributions resemble
  // their similar_neighbours nearest ones' are merged into the lowest index
  // among them.  Off: on many-lights-city it keeps 808 of 3,450 points and
  // 29 of 93 MB of tables but costs quality per sample (64 spp, seeds 0-2,
  // relMSE 0.0355 / 0.0425 / 0.0369 against 0.0277 / 0.0414 / 0.0285).
  bool merge_similar = false;
  int similar_neighbours = 20;
  int blur_neighbours = 16;
  float uniform_share = 0.03f;
  float r_min = 0.04f;
  int min_points = 10;          // fewer: every emitter evaluated at every vertex (locally optimal)
  uint32_t seed = 0x63616368;
};

class CachePointSampler final : public LightSampler {
 public:
  CachePointSampler(const LightSet& lights, const Accel& accel, const CachePointParams& params = {});
  ~CachePointSampler() override;

  std::optional<SampledLight> sample(const LightSampleContext& ctx, float u) const override;
  float pmf(const LightSampleContext& ctx, int light) const override { return pmf_primitive(ctx, light, -1); }
  float pmf_primitive(const LightSampleContext& ctx, int light, int primitive) const override;
  const char* name() const override { return "cachepoints"; }
  bool chooses_primitives() const override { return true; }
  bool wants_feedback() const override { return true; }
  void record_shadow(const SampledLight& chosen, bool unoccluded) const override;
  void update() override;
  std::vector<uint8_t> save_state() const override;
  void restore(const std::vector<uint8_t>& state) override;
  std::vector<std::pair<std::string, double>> statistics() const override;

  // For tests: the number of cache points (0 in the locally optimal fallback),
  // the emitters, and the nearest point's (emitter, probability) over its lists
  // and the uniform share, summed per emitter.
  size_t point_count() const;
  const EmitterSet& emitters() const { return emitters_; }
  // The visibility weight the sampler applies to `emitter` at the point nearest p (1 if unlisted).
  float visibility(const vec3& p, int emitter) const;
  // Point c's listed emitters: near ones, then far ones, each part ascending.
  std::vector<uint32_t> listed(size_t point) const;

  struct Impl;

 private:
  EmitterSet emitters_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace theia
