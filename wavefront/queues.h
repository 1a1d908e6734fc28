// The wavefront's queues, each declared once as a table of fields.
//
// A queue is a structure of arrays: the tracing stages read only `rays`, the
// stages after them only the fields they need.  Each table below generates
// the struct; clear, append, gather (reorder) and the bytes a queue holds
// are generic over its fields, so a field added to a table is cleared,
// merged, sorted and counted with no other line changed.  A field that
// belongs to a feature (the curve skip, the observer's MIS weight) stays
// empty when the feature is off: every operation passes an empty field by.
#pragma once

#include "core/color.h"
#include "core/directional_guide.h"
#include "core/light_sampler.h"
#include "scene/accel.h"

#include <tbb/parallel_for.h>

#include <cstdint>
#include <span>
#include <vector>

namespace theia {

// A guided vertex's NEE MIS weight, left for when its shadow ray turns out
// unoccluded (the guide's pdf is a quadtree descent, and most shadow rays of
// an indirectly lit scene are blocked).  region == kNoGuideRegion: the
// weight is already in the contribution.
struct DeferredNeeMIS {
  vec3 wi{0.0f};
  uint32_t region = kNoGuideRegion;
  float light_pdf = 0.0f;
  float bsdf_pdf = 0.0f;
  float selection = 0.0f;  // the guide's share of the mixture the weight compares against
};

#define THEIA_QUEUE_MEMBER(type, name, doc) std::vector<type> name;
#define THEIA_QUEUE_VISIT(type, name, doc) f(name);
#define THEIA_QUEUE_ZIP(type, name, doc) f(a.name, b.name);
#define THEIA_QUEUE_SIZEOF(type, name, doc) +sizeof(type)
#define THEIA_DECLARE_QUEUE(Name, FIELDS)                                  \
  struct Name {                                                             \
    FIELDS(THEIA_QUEUE_MEMBER)                                              \
    static constexpr size_t kItemBytes = 0 FIELDS(THEIA_QUEUE_SIZEOF);      \
    size_t size() const { return rays.size(); }                             \
    template <class F>                                                      \
    void for_each_field(F&& f) {                                            \
      FIELDS(THEIA_QUEUE_VISIT)                                             \
    }                                                                       \
    template <class F>                                                      \
    void for_each_field(F&& f) const {                                      \
      FIELDS(THEIA_QUEUE_VISIT)                                             \
    }                                                                       \
    /* f(a.field, b.field) for every field, in table order */               \
    template <class A, class B, class F>                                    \
    static void zip(A& a, B& b, F&& f) {                                    \
      FIELDS(THEIA_QUEUE_ZIP)                                               \
    }                                                                       \
  };

// Rays waiting to be traced, binned by direction (wavefront/engine.cpp).
//   type       name      meaning
#define THEIA_RAY_QUEUE_FIELDS(F)                     \
  F(Ray, rays, "origin, direction, extent")          \
  F(uint32_t, paths, "path-pool slot of each ray")

// Shadow rays: everything needed to splat their contribution if unoccluded,
// so that no path waits on one.
#define THEIA_SHADOW_QUEUE_FIELDS(F)                                                                \
  F(Ray, rays, "from the shading point to the light sample")                                       \
  F(RGB, contribution, "beta * f * L * w / pdf * filter weight: what reaches the film if unoccluded") \
  F(uint32_t, pixel, "film pixel")                                                                 \
  F(uint32_t, sample, "sample index (which half buffer of the film)")                              \
  F(uint32_t, vertex, "the observer's handle of the NEE vertex (only with an observer)")      \
  F(float, mis_weight, "the MIS weight inside the contribution (only with an observer)")          \
  F(SampledLight, chosen, "the light sampler's choice (only when it learns from outcomes)")       \
  F(PrimRef, skip, "the curve segment the ray leaves (only in scenes with curves)")                   \
  F(int32_t, medium, "the medium the ray starts in (only in scenes with media)")                   \
  F(uint8_t, event, "the path's PathEvent, its film layer (only with --aov-events)")             \
  F(DeferredNeeMIS, deferred_mis, "a guided vertex's MIS weight still to apply (guided, unobserved, no media)")

// Rays that hit nothing: infinite lights see them (the escaped-ray stage).
#define THEIA_ESCAPED_QUEUE_FIELDS(F)          \
  F(Ray, rays, "the ray that left the scene") \
  F(uint32_t, paths, "path-pool slot")

THEIA_DECLARE_QUEUE(RayQueue, THEIA_RAY_QUEUE_FIELDS)
THEIA_DECLARE_QUEUE(ShadowQueue, THEIA_SHADOW_QUEUE_FIELDS)
THEIA_DECLARE_QUEUE(EscapedQueue, THEIA_ESCAPED_QUEUE_FIELDS)

template <class Q>
void queue_clear(Q& q) {
  q.for_each_field([](auto& v) { v.clear(); });
}

// Appends items [begin, end) of `o` (a field empty in `o` stays as it is in `q`).
template <class Q>
void queue_append(Q& q, const Q& o, size_t begin, size_t end) {
  Q::zip(q, o, [&](auto& to, const auto& from) {
    if (!from.empty()) to.insert(to.end(), from.begin() + ptrdiff_t(begin), from.begin() + ptrdiff_t(end));
  });
}

// Appends every item of `o`.
template <class Q>
void queue_append(Q& q, const Q& o) {
  queue_append(q, o, 0, o.size());
}

// q[i] = q[order[i]] for every present field, gathered in parallel through
// `scratch` (whose vectors are reused from call to call).
template <class Q>
void queue_gather(Q& q, std::span<const uint32_t> order, Q& scratch) {
  Q::zip(q, scratch, [&](auto& v, auto& out) {
    if (v.empty()) return;
    out.resize(order.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, order.size(), 8192), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t k = r.begin(); k < r.end(); ++k) out[k] = v[order[k]];
    });
    v.swap(out);
  });
}

// Bytes the queue's storage holds (capacity, so that a peak stays counted).
template <class Q>
size_t queue_bytes(const Q& q) {
  size_t bytes = 0;
  q.for_each_field([&](const auto& v) { bytes += v.capacity() * sizeof(typename std::decay_t<decltype(v)>::value_type); });
  return bytes;
}

}  // namespace theia
