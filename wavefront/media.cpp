// Stage: medium interactions, between tracing and surface shading, only in
// scenes with media, run in the trace loop on each chunk of rays as soon as
// it is traced (engine.cpp trace_closest).  Each ray of a path inside a medium is tracked to its
// hit (or to infinity): it passes with its throughput reweighted and goes on
// to the surface or escaped-ray stage, or it is absorbed, or it scatters at
// a medium vertex (NEE through the media, a phase-function sample, roulette)
// and leaves the batch.  Shadow rays in such scenes carry their start medium
// and are attenuated segment by segment through every medium they cross.
#include "wavefront/engine_impl.h"

#include "scene/microfacet.h"
#include "scene/surface_crossing.h"

#include <bit>

namespace theia {

namespace {

// How many paths ahead the medium stage fetches its path records: a path's
// tracking and crossings take long enough that a few hide the misses.
constexpr size_t kMediumPrefetchDistance = 4;

// Tracking numbers are keyed by the ray itself as well as the path sample,
// so two segments of one path (across an interface, at one depth) never
// share a stream.
uint64_t ray_key(const Ray& r, uint64_t salt) {
  return hash(salt, std::bit_cast<uint32_t>(r.o.x), std::bit_cast<uint32_t>(r.o.y), std::bit_cast<uint32_t>(r.o.z),
              std::bit_cast<uint32_t>(r.d.x), std::bit_cast<uint32_t>(r.d.y), std::bit_cast<uint32_t>(r.d.z));
}

// A point in a medium as an interaction: no surface, no normal, no offset.
SurfaceInteraction medium_point(const vec3& p, const vec3& wo) {
  SurfaceInteraction si;
  si.p = p;
  si.wo = wo;
  return si;
}

}  // namespace

// The medium stage checks for the observer at run time rather than being
// compiled twice as surface shading is: the tracking numbers are hashed from
// the ray's bits, so a scattering point rounded differently by a second
// instantiation (contracted multiply-adds) would send the path elsewhere,
// and the recorder's debug layers could no longer be checked against the
// image an unobserved render makes.
void WavefrontEngine::Impl::end_path(uint32_t slot, ShadeOutput& out) {
  if (observer)
    finish_path<true>(slot, out);
  else
    finish_path<false>(slot, out);
}

void WavefrontEngine::Impl::handle_medium_interactions(Batch& b, size_t begin, size_t end, ShadeOutput& out) {
  for (size_t i = begin; i < end; ++i) {
    // The rays are in their sort order, which scatters the path records
    // (and the medium and flight-depth tables): fetch a few paths ahead.
    if (i + kMediumPrefetchDistance < end) {
      const uint32_t ahead = b.paths[i + kMediumPrefetchDistance];
      __builtin_prefetch(&pool[ahead]);
      pool.prefetch_cold(ahead);
    }
    blocked[i] = track_through_interfaces(b.rays[i], hits[i], b.paths[i], out);
  }
}

// Free flight to the hit, and on through every interface the path's ray
// passes (shade_surface's pass-through, done here): the ray is re-traced
// from the crossing at once instead of going round the wavefront again
// (queued, sorted, traced in a later batch, its hit sorted and shaded only
// to be queued again), which was most of what a crossing cost besides its
// trace.  The rays, hits and tracking numbers are those the round trip
// made; paths only reach their later splats sooner, so the film sums them
// in another order.  `ray` and `hit` become the ones the path goes on with.
// True when the path left the batch here (scattered or absorbed).
bool WavefrontEngine::Impl::track_through_interfaces(Ray& ray, Hit& hit, uint32_t slot, ShadeOutput& out) {
  // A ray caught crossing back and forth is left to shading past this many.
  constexpr int kMaxCrossings = 64;
  for (int crossing = 0; crossing < kMaxCrossings; ++crossing) {
    if (interact_in_medium(ray, hit, slot, out)) return true;
    const int shape = passing_shape(hit, pool[slot]);
    if (shape < 0) return false;
    ++out.vertices;
    const SurfaceCrossing c = surface_crossing(scene, accel, ray, hit, shape);
    // Traced from its own record and copied into `ray` after the trace, and
    // the hit written where it is kept: copied right after spawn_ray, and
    // after intersect1's return, each was read back as one wide load of
    // narrow stores, which waits for them to reach the cache (two fifths,
    // then three fifths of this function's time on smoke-grid).
    const Ray next = spawn_ray(c, glm::normalize(ray.d));
    if (!pool.curve_skip.empty()) pool.curve_skip[slot] = c.skip;
    pool.medium[slot] = medium_after(scene, c.shape, c.ng, next.d, pool.medium[slot]);
    const PrimRef skip = pool.curve_skip.empty() ? PrimRef{} : pool.curve_skip[slot];
    accel.intersect(std::span<const Ray>(&next, 1), std::span<Hit>(&hit, 1), false, std::span<const PrimRef>(&skip, 1));
    ray = next;
    ++out.retraced;
    if (opt.capture_rays) out.retraced_rays.push_back(ray);
  }
  return false;
}

// True when the path left the batch here (scattered or absorbed).
bool WavefrontEngine::Impl::interact_in_medium(const Ray& ray, const Hit& hit, uint32_t slot, ShadeOutput& out) {
  PathState& ps = pool[slot];
  const int medium = pool.medium[slot];
  if (medium < 0 || ps.alpha_only) return false;
  TrackingRng rng{ray_key(ray, hash(opt.seed, ps.pixel, ps.sample, ps.depth))};
  // The first flight at a depth starts with the path's stratified number;
  // a second one at the same depth (beyond an interface) must not reuse it.
  if (pool.flight_depth[slot] != ps.depth + 1) {
    rng.first = sample1(ps, bounce_dims(ps.depth).medium_flight);
    pool.flight_depth[slot] = uint16_t(ps.depth + 1);
  }
  const float tmax = hit.geom == kInvalidId ? kInfinity : hit.t;
  const FreeFlight ff = sample_free_flight(scene.media[size_t(medium)], ray, tmax, ps.beta, rng);
  // pbrt-v4 adds a medium's emission below the depth limit only.  It is
  // light arriving along the path's ray: the vertex the ray left gets it
  // (not MIS-weighted: nothing samples a medium's emission directly).
  if (!is_black(ff.emitted) && int(ps.depth) < opt.max_depth) {
    const RGB contribution = ps.filter_weight * ff.emitted;
    if (splats_emission(ps.depth)) film.splat(ps.pixel, ps.sample, contribution, path_event(ps.flags));
    if (observer) observer->emission_added(ps.vertex, ps.pixel, contribution, 1.0f);
  }
  switch (ff.event) {
    case MediumEvent::None:
      ps.beta = ff.beta;
      return false;
    case MediumEvent::Absorb:
      break;
    case MediumEvent::Scatter:
      scatter_in_medium(ray, ff, slot, medium, out);
      return true;
  }
  end_path(slot, out);
  return true;
}

// A medium vertex as the observer takes it: no normal, a Henyey-Greenstein
// lobe whose "roughness" is 1 - |g| (0: a delta-like forward peak).
static PathVertexInfo medium_vertex_info(const MediumVertex& v, const vec3& wi, const RGB& local, float pdf) {
  PathVertexInfo info = path_vertex_info(v.ps, v.si.p, v.beta, wi, local, pdf);
  info.roughness = 1.0f - std::min(std::abs(v.g), 1.0f);
  info.in_medium = true;
  return info;
}

// A real scattering vertex: NEE with MIS against the phase function, then
// the scattered direction (the phase function's sample, or where a guide
// has learned the region, phase and guide combined: guided_phase.h) and
// roulette.  The observer sees both as a surface vertex's: the NEE ray's
// vertex and the scattered ray's, flagged in-medium, whose local factor is
// phase / pdf (1 for an unguided Henyey-Greenstein sample) with the roulette
// compensation.
void WavefrontEngine::Impl::scatter_in_medium(const Ray& ray, const FreeFlight& ff, uint32_t slot, int medium,
                                              ShadeOutput& out) {
  PathState& ps = pool[slot];
  if (int(ps.depth) >= opt.max_depth) return end_path(slot, out);
  ++out.vertices;
  MediumVertex v{ps, medium_point(ray.o + ray.d * ff.t, -glm::normalize(ray.d)), scene.media[size_t(medium)].g,
                 bounce_dims(ps.depth)};
  // The throughput-reset image (recorder debug, bounce N) starts at this vertex.
  v.beta = int(ps.depth) == opt.throughput_reset_bounce ? RGB(1.0f) : ff.beta;
  v.u_continuation = sample_4d(sampler_key(ps), v.dims.bsdf_dir);
  if (hooks.guide) {
    v.guide_region = hooks.guide->region(v.si.p);
    if (v.guided()) v.guide_fraction = guide_share(v.guide_region);
  }
  // In a sealed medium every shadow ray would be blocked: none is sampled,
  // unless an observer or a learning light sampler is told of each one.
  const bool nee_blocked = sealed_media[size_t(medium)] && !observer && !light_sampler_learns;
  if (int(ps.depth) >= opt.throughput_reset_bounce && !nee_blocked) sample_direct_light_in_medium(v, medium, out);

  const std::optional<PhaseContinuation> c = sample_phase_continuation(v);
  if (!c) return end_path(slot, out);
  RGB local = v.guided() ? RGB(c->phase / c->pdf) : RGB(1.0f);
  RGB beta = v.beta * local;
  double correction = 1.0;
  if (!pool.roulette_correction.empty()) correction = pool.roulette_correction[slot] *= c->roulette;
  float survival = 1.0f;
  if (!survives_roulette(ps, v.u_continuation.w, beta, local, ps.eta_scale, correction, -1.0f, survival) ||
      !is_finite(beta) || is_black(beta))
    return end_path(slot, out);
  if (observer) {
    const uint32_t child = observer->vertex_created(ps.vertex, medium_vertex_info(v, c->wi, local, c->pdf * survival));
    observer->vertex_done(ps.vertex);
    ps.vertex = child;
  }
  ps.beta = beta;
  ps.depth = uint16_t(ps.depth + 1);
  ps.prev_pdf = c->mis_pdf;
  ps.flags = first_event_bits(ps.flags, kEventVolume);
  ps.prev_p = v.si.p;
  ps.prev_ng = vec3(0.0f);
  queue_ray(slot, v.si, Ray{v.si.p, 0.0f, c->wi, kInfinity}, out);
}

// The scattered direction: where the vertex is not guided, the phase
// function's sample (the numbers it drew before guiding existed), else
// phase function and guide combined as the options say.
std::optional<PhaseContinuation> WavefrontEngine::Impl::sample_phase_continuation(const MediumVertex& v) const {
  if (!v.guided()) {
    PhaseContinuation c;
    c.wi = sample_henyey_greenstein(v.si.wo, v.g, vec2(v.u_continuation), &c.pdf);
    if (!(c.pdf > 0.0f)) return std::nullopt;
    c.phase = c.mis_pdf = c.pdf;
    return c;
  }
  GuidedDraw u{0.0f, vec2(v.u_continuation)};
  if (opt.guiding.mixing == GuideMixing::OneSampleMIS)
    return sample_guided_phase_mis(v.si.wo, v.g, *hooks.guide, v.guide_region, v.guide_fraction, u);
  u.u_guide = sample2(v.ps, v.dims.guide_dir);
  u.u_pick = sample1(v.ps, v.dims.guide_pick);
  return sample_guided_phase_ris(v.si.wo, v.g, *hooks.guide, v.guide_region, opt.guiding.defensive, u);
}

// The density MIS against light sampling takes for a direction from a
// medium vertex: the phase function's, or where the vertex is guided the
// mixture's (as scattering_pdf at surfaces).
float WavefrontEngine::Impl::phase_mis_pdf(const MediumVertex& v, const vec3& wi) const {
  const float phase = henyey_greenstein(glm::dot(v.si.wo, wi), v.g);
  if (!v.guided()) return phase;
  const float c = opt.guiding.mixing == GuideMixing::Resampled ? kRISCandidateShare : v.guide_fraction;
  return guided_mis_pdf(phase, hooks.guide->pdf(v.guide_region, wi), c);
}

// NEE from a medium vertex: a shadow ray through the media, MIS-weighted
// against the phase function.
void WavefrontEngine::Impl::sample_direct_light_in_medium(const MediumVertex& v, int medium, ShadeOutput& out) {
  const PathState& ps = v.ps;
  const LightSampleContext ctx{v.si.p, vec3(0.0f), vec3(0.0f), vec3(0.0f)};
  // One draw of the light_choice/light_prim pair, as sample_direct_light does.
  const vec2 u_light = sample2(ps, v.dims.light_choice);
  auto sl = light_sampler.sample(ctx, u_light.x);
  if (!sl || light_faces_away(lights, sl->light, v.si.p)) return;
  auto ls = sample_li(lights, sl->light, ctx, sample2(ps, v.dims.light_point), u_light.y);
  const float light_pdf = ls ? sl->pmf * ls->pdf : 0.0f;
  if (!ls || !(light_pdf > 0.0f) || !std::isfinite(light_pdf)) return;
  const float phase = henyey_greenstein(glm::dot(v.si.wo, ls->wi), v.g);
  const float w = ls->is_delta ? 1.0f : power_heuristic(1, light_pdf, 1, phase_mis_pdf(v, ls->wi));
  const RGB contribution = ps.filter_weight * v.beta * (phase * w / light_pdf) * ls->L;
  if (!is_finite(contribution) || is_black(contribution)) return;
  queue_shadow(out, spawn_ray_to(v.si, ls->p_light, ls->p_light_error, ls->n_light), contribution, ps, *sl, {},
               medium, path_event(first_event_bits(ps.flags, kEventVolume)));
  if (observer) {
    out.shadows.mis_weight.push_back(w);
    PathVertexInfo info = medium_vertex_info(v, ls->wi, RGB(phase / light_pdf), light_pdf);
    info.is_nee = true;
    info.delta_light = ls->is_delta;
    out.shadows.vertex.push_back(observer->vertex_created(ps.vertex, info));
  }
}

// ---------------------------------------------------------------- shadow rays

void WavefrontEngine::Impl::attenuate_shadow_rays_in_media() {
  ShadowQueue& s = shadows;
  ScopedTimer timer(stats.phases[Phase::TraceShadow]);
  stage_loop(s.size(), 64, [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const PrimRef skip = s.skip.empty() ? PrimRef{} : s.skip[i];
      const RGB T = shadow_transmittance(s.rays[i], s.medium[i], skip, hash(opt.seed, s.pixel[i], s.sample[i]));
      s.contribution[i] *= T;
      blocked[i] = is_black(T) ? 1 : 0;
    }
  });
}

// Transmittance from the ray's origin to its end: traced hit by hit, each
// segment attenuated by ratio tracking in its medium; an "interface"
// surface (or a virtual light) passes the ray on into the medium beyond it,
// any other surface blocks it.  A segment that ends on a blocker is not
// tracked (its numbers are its own, keyed by the segment's ray), and the
// surface is set up only where the ray goes on through it.
// Each trace looks past the passing surfaces (intersect_passing): a blocker
// anywhere on the ray ends it before the segments in front of it are
// tracked only to be multiplied by 0, and past the one passing surface of
// a trace that met nothing else, the ray goes on without another trace
// (which could only find nothing: the segment beyond is the traced one's).
RGB WavefrontEngine::Impl::shadow_transmittance(Ray ray, int medium, PrimRef skip, uint64_t key) const {
  RGB T(1.0f);
  const vec3 end = ray.o + ray.d * ray.tmax;
  // Attenuates T along the segment up to t; false once nothing gets through.
  auto track = [&](float t) {
    if (medium < 0) return true;
    TrackingRng rng{ray_key(ray, key)};
    T *= ratio_tracking(scene.media[size_t(medium)], ray, t, rng);
    return !is_black(T);
  };
  // Interfaces are thin: a ray crosses few of them.  The bound only guards a degenerate loop.
  auto crossing_of = [&](int shape) { return shape >= 0 ? shape_crossing(scene, shape) : ShapeCrossing::Passes; };
  for (int crossing = 0; crossing < 256; ++crossing) {
    const Accel::PassingTrace traced = accel.intersect_passing(ray, skip, false);
    if (traced.stop.hit() && crossing_of(accel.shape_index(traced.stop)) == ShapeCrossing::Blocks) return RGB(0.0f);
    Hit hit = traced.closest();
    if (hit.geom == kInvalidId) {
      track(ray.tmax);
      return T;
    }
    const int shape = accel.shape_index(hit);
    const ShapeCrossing what = crossing_of(shape);
    if (what == ShapeCrossing::Blocks) return RGB(0.0f);
    const bool last = !traced.stop.hit() && traced.passes == 1;
    // Instanced spheres and cylinders were met without their (u, v): the same
    // hit again, with them (top-level ones find theirs in compute_interaction).
    const ShapeKind kind = shape >= 0 ? scene.shapes[size_t(shape)].kind : ShapeKind::TriangleMesh;
    if ((kind == ShapeKind::Sphere || kind == ShapeKind::Cylinder) && hit.inst != kInvalidId)
      hit = accel.intersect1(ray, skip);
    // A mix material's choice reads the whole interaction; passing on needs only the crossing.
    SurfaceCrossing c;
    if (what == ShapeCrossing::AtHit) {
      const SurfaceInteraction si = compute_interaction(scene, accel, ray, hit);
      if (!bsdf_is_passthrough(make_bsdf(scene, si, UVFootprint{}))) return RGB(0.0f);
      c = surface_crossing(si);
    } else {
      c = surface_crossing(scene, accel, ray, hit, shape);
    }
    if (!track(hit.t)) return T;
    medium = medium_after(scene, c.shape, c.ng, ray.d, medium);
    ray = spawn_ray_to(c, end, vec3(0.0f), vec3(0.0f));
    skip = c.skip;
    if (last) {
      track(ray.tmax);
      return T;
    }
  }
  return RGB(0.0f);
}

}  // namespace theia
