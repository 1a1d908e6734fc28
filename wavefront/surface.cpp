// Stage: shade surface hits.  Each hit reads as its steps: the interaction,
// emission, pass-through, first-hit AOVs, direct light (a shadow ray), the
// continuation (BSDF or guide), Russian roulette, the vertex reported to the
// observer, the next ray queued.
#include "wavefront/engine_impl.h"

#include "scene/surface_crossing.h"

namespace theia {

template <bool kObserve>
void WavefrontEngine::Impl::shade_surface(const Ray& ray, const Hit& hit, uint32_t slot, const ContinuationDraw& draw,
                                         ShadeOutput& out) {
  PathState& ps = pool[slot];
  // An "interface" surface (by its own material, not a mix's choice), neither
  // a light nor a holdout: the ray goes on as it was, and the crossing's
  // point, error bound and normal are all the step below reads (the same
  // ones compute_interaction gives, without uv, derivatives, tangents and the
  // BSDF).  Interfaces matter only in scenes with media.
  // The medium stage crosses them itself (track_through_interfaces); this
  // serves a path past its bound of crossings.
  if (const int shape = passing_shape(hit, ps); shape >= 0) {
    ++out.vertices;
    const SurfaceCrossing c = surface_crossing(scene, accel, ray, hit, shape);
    return queue_ray(slot, c, spawn_ray(c, glm::normalize(ray.d)), out);
  }
  const SurfaceInteraction si = compute_interaction(scene, accel, ray, hit);
  // A holdout matte blocks the ray and adds neither colour nor alpha.
  if (si.shape >= 0 && scene.shapes[size_t(si.shape)].holdout) return finish_path<kObserve>(slot, out);
  if (ps.alpha_only) {
    film.splat_first_hit(ps.pixel, ps.filter_weight, true, bsdf_albedo(make_bsdf(scene, si, footprint(si))), si.ns,
                         si.t);
    return finish_path<kObserve>(slot, out);
  }
  if (add_surface_emission<kObserve>(slot, ray, si, out)) return;  // a virtual light: the ray went on
  ++out.vertices;

  ShadingPoint v{ps, slot, si, make_bsdf(scene, si, footprint(si)), draw};
  // An "interface" surface: continue the ray as it was, without a bounce.
  if (bsdf_is_passthrough(v.bsdf)) return queue_ray(slot, si, spawn_ray(si, -si.wo), out);
  v.ns = v.bsdf.shading.n;
  if (ps.depth == 0 && counts_for_alpha(ps.sample))
    film.splat_first_hit(ps.pixel, ps.filter_weight, true, bsdf_albedo(v.bsdf), v.ns, si.t);
  if (int(ps.depth) >= opt.max_depth) return finish_path<kObserve>(slot, out);

  prepare_vertex<kObserve>(v);
  if (draws_light_sample(v)) sample_direct_light<kObserve>(v, out);
  // pdf guard: a direction with pdf 0 (or NaN) ends the path instead of dividing by it.
  // Without an observer (which reports every vertex's pdf) a layered
  // sample's MIS pdf waits for an emitter to need it (kDeferredPdf).
  DeferredPdf* defer = !kObserve && !pool.deferred_pdf.empty() ? &pool.deferred_pdf[slot] : nullptr;
  std::optional<Continuation> c = sample_continuation(v, defer);
  if (!c || !(c->bs.pdf > 0.0f)) return finish_path<kObserve>(slot, out);
  continue_path<kObserve>(v, *c, out);
}

int WavefrontEngine::Impl::passing_shape(const Hit& hit, const PathState& ps) const {
  if (pool.medium.empty() || ps.alpha_only) return -1;
  const int shape = accel.shape_index(hit);
  const bool passes = shape >= 0 && scene.shapes[size_t(shape)].area_light < 0 &&
                      shape_crossing(scene, shape) == ShapeCrossing::Passes;
  return passes ? shape : -1;
}

// The vertex's sample dimensions, throughput, caustic flags, roughening and
// whether (and with which selection probability) it is guided.
template <bool kObserve>
void WavefrontEngine::Impl::prepare_vertex(ShadingPoint& v) const {
  const PathState& ps = v.ps;
  v.dims = bounce_dims(ps.depth);
  v.beta = int(ps.depth) == opt.throughput_reset_bounce ? RGB(1.0f) : ps.beta;
  v.caustic_flags = caustic_flags(ps, v.bsdf);
  // Roughened after the caustic flags, so that camera paths leave the caustic
  // pass the paths they leave it without roughening (its light paths see the
  // scene's own BSDFs).  A camera ray's alpha' is 0: nothing changes at depth 0.
  if (!pool.roughness.empty() && pool.roughness[v.slot] > 0.0f)
    bsdf_roughen(v.bsdf, opt.roughening, pool.roughness[v.slot]);
  // Only a guide or the recorder (which trains only where guiding applies) asks.
  v.guidable = (kObserve || hooks.guide) && bsdf_is_guidable(v.bsdf, opt.guiding.min_roughness);
  if (hooks.guide && v.guidable) {
    v.guide_region = hooks.guide->region(v.si.p);
    if (v.guided()) v.guide_fraction = guide_share(v.guide_region);
  }
}

// The sampled direction's throughput, Russian roulette, the vertex reported
// to the observer, the path's state advanced and its next ray queued.
template <bool kObserve>
void WavefrontEngine::Impl::continue_path(ShadingPoint& v, const Continuation& c, ShadeOutput& out) {
  PathState& ps = v.ps;
  const uint32_t slot = v.slot;
  const SurfaceInteraction& si = v.si;
  const BSDFSample& bs = c.bs;
  RGB local = bs.f * (std::abs(glm::dot(bs.wi, v.ns)) / bs.pdf);
  RGB beta = v.beta * local;
  // Radiance refracted into a denser medium is scaled by 1/eta^2; roulette
  // undoes that scale so that it does not kill paths inside glass.
  const float eta_scale = bs.is_transmission() ? ps.eta_scale * sqr(bs.eta) : ps.eta_scale;
  double correction = 1.0;
  if (!pool.roulette_correction.empty()) correction = pool.roulette_correction[slot] *= c.roulette;
  const float adjoint = pool.pixel_estimate.empty() ? -1.0f : adjoint_survival(v, c, beta);
  float survival = 1.0f;
  if (!survives_roulette(ps, v.draw.u.w, beta, local, eta_scale, correction, adjoint, survival) ||
      !is_finite(beta) ||
      is_black(beta))
    return finish_path<kObserve>(slot, out);
  if constexpr (kObserve) report_vertex(v, c, local, survival);

  ps.beta = beta;
  ps.depth = uint16_t(ps.depth + 1);
  ps.prev_pdf = c.mis_pdf;
  ps.eta_scale = eta_scale;
  ps.flags = uint8_t((bs.is_specular() ? kPathPrevSpecular : 0) | v.caustic_flags |
                     first_event_bits(ps.flags, event_of_lobe(bs.flags)));
  ps.prev_p = si.p;
  ps.prev_ng = si.ng;
  if (!pool.roughness.empty()) pool.roughness[slot] = sampled_roughness(bs);
  queue_ray(slot, si, spawn_ray(si, bs.wi), out);
}

// Emission found by the BSDF-sampled ray.  True when the hit was a virtual
// light, which emits but does not block: the same ray goes on from its far
// side (re-traced; shadow rays skip it with an Embree filter).
template <bool kObserve>
bool WavefrontEngine::Impl::add_surface_emission(uint32_t slot, const Ray& ray, const SurfaceInteraction& si,
                                                 ShadeOutput& out) {
  const PathState& ps = pool[slot];
  if (si.area_light < 0 || left_to_caustic_pass(ps.flags, si.area_light)) return false;
  const int light = si.area_light;
  RGB Le = area_light_L(lights, light, si, si.wo);
  if (!is_black(Le)) {
    LightSampleContext prev = previous_vertex(ps);
    const int primitive = light_sampler_primitives ? si.prim : -1;
    add_emission<kObserve>(
        ps, light, Le,
        [&] { return area_light_pdf(lights, light, prev, glm::normalize(ray.d), si, primitive >= 0); }, primitive);
  }
  if (!scene.lights[size_t(light)].is_virtual) return false;
  if constexpr (kObserve) {
    observer->vertex_continued(ps.vertex);
    observer->vertex_done(ps.vertex);
  }
  queue_ray(slot, si, spawn_ray(si, ray.d), out);
  return true;
}

// Directly seen caustics: a receiver at the primary hit and a caster right
// after it hand the caster's light from the traced lights to the caustic
// pass, by NEE here and by emission at the next hit.
uint8_t WavefrontEngine::Impl::caustic_flags(const PathState& ps, const BSDF& bsdf) const {
  if (!caustics) return 0;
  if (ps.depth == 0 && bsdf_is_caustic_receiver(bsdf)) return kPathCausticReceiver;
  if (ps.depth == 1 && (ps.flags & kPathCausticReceiver) && bsdf_is_caustic_caster(bsdf, caustics->caster_roughness()))
    return kPathCausticCaster;
  return 0;
}

// The pdf MIS needs for a scattered direction: the BSDF's, or where the
// vertex is guided the mixture's (guided_mis_pdf).
float WavefrontEngine::Impl::scattering_pdf(const ShadingPoint& v, const vec3& wi) const {
  const float p = bsdf_pdf(v.bsdf, v.si.wo, wi);
  if (!v.guided()) return p;
  return guided_mis_pdf(p, hooks.guide->pdf(v.guide_region, wi), mis_guide_share(v));
}

// The MIS weight sample_direct_light left out of a guided vertex's
// contribution, applied to the shadow rays that reach their light: the
// weight scattering_pdf would have given, from the same densities.
void WavefrontEngine::Impl::apply_deferred_nee_mis() {
  ShadowQueue& s = shadows;
  if (s.deferred_mis.empty()) return;
  stage_loop(s.size(), 1024, [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const DeferredNeeMIS& d = s.deferred_mis[i];
      if (blocked[i] || d.region == kNoGuideRegion) continue;
      const float p = guided_mis_pdf(d.bsdf_pdf, hooks.guide->pdf(d.region, d.wi), d.selection);
      s.contribution[i] *= power_heuristic(1, d.light_pdf, 1, p);
    }
  });
}

static PathVertexInfo vertex_info(const ShadingPoint& v, const vec3& wi, const RGB& local, float pdf) {
  PathVertexInfo info = path_vertex_info(v.ps, v.si.p, v.beta, wi, local, pdf);
  info.n = v.ns;
  info.guidable = v.guidable;
  return info;
}

// Next-event estimation: a shadow ray carrying its unoccluded contribution.
template <bool kObserve>
void WavefrontEngine::Impl::sample_direct_light(ShadingPoint& v, ShadeOutput& out) {
  const PathState& ps = v.ps;
  const LightSampleContext ctx{v.si.p, v.si.p_error, v.si.ng, v.ns};
  // light_choice and light_prim are one pair of slots (sample_dims.h): one
  // draw of the pair gives both numbers, bit for bit the two 1D draws, for
  // one hash and index shuffle instead of two.
  // Where they decide nothing (one light: light_choice_fixed) they are not drawn.
  static_assert(bounce_dims(0).light_prim == bounce_dims(0).light_choice + 1 && bounce_dims(0).light_choice % 2 == 0);
  const vec2 u_light = light_choice_fixed ? vec2(0.5f) : sample2(ps, v.dims.light_choice);
  auto sl = light_sampler.sample(ctx, u_light.x);
  if (!sl || left_to_caustic_pass(v.caustic_flags, sl->light) || light_faces_away(lights, sl->light, v.si.p)) return;
  auto ls = sample_li(lights, sl->light, ctx, sample2(ps, v.dims.light_point), u_light.y, true, sl->primitive);
  // pdf guard: the product of selection and sampling pdfs can underflow to 0
  // (a light of 1e-3 beside one of 1e9); such a sample is dropped, never divided by.
  const float light_pdf = ls ? sl->pmf * ls->pdf : 0.0f;
  if (!ls || !(light_pdf > 0.0f) || !std::isfinite(light_pdf)) return;
  const RGB f = bsdf_f(v.bsdf, v.si.wo, ls->wi) * std::abs(glm::dot(ls->wi, v.ns));
  if (is_black(f)) return;
  // Guided and unobserved: the weight waits for the shadow ray's outcome
  // (apply_deferred_nee_mis), the contribution is queued without it.
  const bool defer = !kObserve && !ls->is_delta && v.guided() && defers_nee_mis();
  const float w = ls->is_delta || defer ? 1.0f : power_heuristic(1, light_pdf, 1, scattering_pdf(v, ls->wi));
  const RGB contribution = ps.filter_weight * v.beta * f * (ls->L * (w / light_pdf));
  if (!is_finite(contribution) || is_black(contribution)) return;

  const Ray ray = spawn_ray_to(v.si, ls->p_light, ls->p_light_error, ls->n_light);
  const int medium = pool.medium.empty() ? -1 : medium_after(scene, v.si.shape, v.si.ng, ray.d, pool.medium[v.slot]);
  // Labelled as a BSDF sample of ls->wi would be (no delta lobe makes it);
  // asked of the BSDF only when the film keeps event layers.
  const uint8_t event =
      film.aov_events() ? path_event(first_event_bits(ps.flags, event_of_lobe(bsdf_nondelta_kind(v.bsdf)))) : 0;
  queue_shadow(out, ray, contribution, ps, *sl, v.si.skip, medium, event);
  ShadowQueue& q = out.shadows;
  if (defer)
    q.deferred_mis.back() =
        DeferredNeeMIS{ls->wi, v.guide_region, light_pdf, bsdf_pdf(v.bsdf, v.si.wo, ls->wi), mis_guide_share(v)};
  if constexpr (kObserve) {
    q.mis_weight.push_back(w);
    PathVertexInfo info = vertex_info(v, ls->wi, f / light_pdf, light_pdf);
    info.is_nee = true;
    info.delta_light = ls->is_delta;
    q.vertex.push_back(observer->vertex_created(ps.vertex, info));
  }
}

// The continuation direction: a BSDF sample where the vertex is not guided,
// else guide and BSDF combined as the options say.  An unguided vertex
// draws exactly the numbers it drew before guiding existed.
std::optional<Continuation> WavefrontEngine::Impl::sample_continuation(const ShadingPoint& v,
                                                                      DeferredPdf* defer) const {
  if (!v.guided()) {
    std::optional<BSDFSample> bs = bsdf_sample(v.bsdf, v.si.wo, v.draw.u.z, vec2(v.draw.u), TransportMode::Radiance,
                                               defer, &v.draw.cosine);
    if (!bs) return std::nullopt;
    return Continuation{*bs, bs->pdf_deferred ? kDeferredPdf : bs->pdf, 1.0};
  }
  GuidedDraw u{v.draw.u.z, vec2(v.draw.u)};
  if (opt.guiding.mixing == GuideMixing::Resampled) {
    u.u_guide = sample2(v.ps, v.dims.guide_dir);
    u.u_pick = sample1(v.ps, v.dims.guide_pick);
    return sample_guided_ris(v.bsdf, v.si.wo, v.ns, *hooks.guide, v.guide_region, opt.guiding.defensive, u);
  }
  return sample_guided_mis(v.bsdf, v.si.wo, *hooks.guide, v.guide_region, v.guide_fraction, u);
}

// Adjoint-driven roulette (seeds/000 ch. 1 section 4.2, Vorba and Krivanek
// 2016): the continuation's expected contribution, its throughput times the
// radiance the field expects from its direction, against the path's pixel
// estimate, the field's outgoing radiance at its first guided vertex times
// the throughput there (a diffuse guess: albedo x integral / 2 pi).  A path
// survives surely above a third of the estimate (the lower edge of Vorba's
// weight window, s = 5), in proportion below, and at least with the floor
// (GuidedSampling::roulette_floor: the estimates are coarse; the floor bounds
// a survivor's weight).  -1 (the throughput rule) where the vertex is not
// guided or nothing is known.
float WavefrontEngine::Impl::adjoint_survival(const ShadingPoint& v, const Continuation& c, const RGB& beta) {
  if (!v.guided()) return -1.0f;
  const float integral = hooks.guide->radiance_integral(v.guide_region);
  float& estimate = pool.pixel_estimate[v.slot];
  if (estimate == 0.0f) {
    estimate = luminance(v.ps.filter_weight * v.beta * bsdf_albedo(v.bsdf)) * integral * kInv2Pi;
    if (!(estimate > 0.0f) || !std::isfinite(estimate)) estimate = 0.0f;
  }
  if (estimate == 0.0f) return -1.0f;
  const float expected = luminance(v.ps.filter_weight * beta) * c.guide_pdf * integral;
  if (!std::isfinite(expected)) return -1.0f;
  return std::clamp(3.0f * expected / estimate, opt.guiding.roulette_floor, 1.0f);
}

// The scattering vertex, to the observer: the path's handle moves to it.
// Only survivors of roulette are reported, so the density of a reported
// direction is the sampling pdf times the survival probability: training
// with that pdf does not learn survival times radiance.
void WavefrontEngine::Impl::report_vertex(ShadingPoint& v, const Continuation& c, const RGB& local, float survival) {
  const BSDFSample& bs = c.bs;
  PathVertexInfo info = vertex_info(v, bs.wi, local, bs.pdf * survival);
  info.lobe_flags = bs.flags;
  info.roughness = bs.roughness;
  if (v.guided() && opt.guiding.mixing == GuideMixing::OneSampleMIS) {
    info.bsdf_ratio = c.bsdf_pdf / bs.pdf;
    info.guide_ratio = c.guide_pdf / bs.pdf;
  }
  uint32_t child = observer->vertex_created(v.ps.vertex, info);
  observer->vertex_done(v.ps.vertex);
  v.ps.vertex = child;
}

template void WavefrontEngine::Impl::shade_surface<true>(const Ray&, const Hit&, uint32_t, const ContinuationDraw&,
                                                        ShadeOutput&);
template void WavefrontEngine::Impl::shade_surface<false>(const Ray&, const Hit&, uint32_t, const ContinuationDraw&,
                                                         ShadeOutput&);

}  // namespace theia
