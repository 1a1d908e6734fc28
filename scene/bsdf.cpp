#include "scene/bsdf.h"

#include "core/color.h"

#include "core/hash.h"
#include "core/sampling.h"
#include "scene/texture.h"

#include <bit>
#include <memory>

namespace theia {

namespace {

uint32_t float_bits(float f) { return std::bit_cast<uint32_t>(f); }

// pbrt-v4's MixMaterial::ChooseMaterial: amount is the probability of the
// second material, decided by a hash of the hit so that it is deterministic.
const Material* resolve_mix(const Scene& scene, const Material* m, const SurfaceInteraction& si,
                            const TextureEvalContext& tc) {
  for (int guard = 0; m && m->kind == MaterialKind::Mix && guard < 16; ++guard) {
    float amount = m->amount >= 0 ? eval_float_texture(scene, m->amount, tc) : 0.5f;
    int pick;
    if (amount <= 0.0f) pick = m->mix[0];
    else if (amount >= 1.0f) pick = m->mix[1];
    else {
      uint64_t h = hash(float_bits(si.p.x), float_bits(si.p.y), float_bits(si.p.z), float_bits(si.wo.x),
                        float_bits(si.wo.y), float_bits(si.wo.z), m->mix[0], m->mix[1]);
      float u = to_unit_float(uint32_t(h >> 32));
      pick = amount < u ? m->mix[0] : m->mix[1];
    }
    m = pick >= 0 ? &scene.materials[size_t(pick)] : nullptr;
  }
  return m;
}

// A material's constant parameters (a coat's roughness, thickness, g and
// albedo, most reflectances) are read here, as eval_texture would return them,
// without its call and dispatch: a coated hit reads six of them.
float tex_float(const Scene& scene, int t, const TextureEvalContext& tc, float def) {
  if (t < 0) return def;
  const Texture& tex = scene.textures[size_t(t)];
  return tex.kind == TextureKind::Constant ? tex.value.x : eval_float_texture(scene, t, tc);
}
RGB tex_rgb(const Scene& scene, int t, const TextureEvalContext& tc, RGB def) {
  if (t < 0) return def;
  const Texture& tex = scene.textures[size_t(t)];
  return tex.kind == TextureKind::Constant ? tex.value : eval_texture(scene, t, tc);
}

TrowbridgeReitz distribution(const Scene& scene, int u_tex, int v_tex, bool remap, const TextureEvalContext& tc) {
  float u = tex_float(scene, u_tex, tc, 0.0f), v = tex_float(scene, v_tex, tc, 0.0f);
  if (remap) {
    u = TrowbridgeReitz::roughness_to_alpha(u);
    v = TrowbridgeReitz::roughness_to_alpha(v);
  }
  return {std::max(u, 0.0f), std::max(v, 0.0f)};
}

// Shading frame with s along dpdu (so that anisotropic roughness follows the
// surface parameterisation, as in pbrt-v4), bump- or normal-mapped if asked.
Frame shading_frame(const Scene& scene, const Material* m, const SurfaceInteraction& si,
                    const TextureEvalContext& tc) {
  vec3 ns = si.ns, dpdu = si.dpdu, dpdv = si.dpdv;
  bool mapped = false;
  if (m && m->normal_map >= 0 && !scene.images[size_t(m->normal_map)].pixels.empty()) {
    // Tangent-space normal in [0,1]^3; image row 0 is the top, so v flips.
    RGB c = image_bilerp(scene.images[size_t(m->normal_map)], vec2(si.uv.x, 1.0f - si.uv.y), WrapMode::Repeat);
    vec3 nt = 2.0f * c - vec3(1.0f);
    float ulen = glm::length(dpdu), vlen = glm::length(dpdv);
    vec3 x = dpdu - ns * glm::dot(ns, dpdu);
    if (glm::dot(nt, nt) > 0.0f && glm::dot(x, x) > 0.0f && ulen > 0.0f) {
      x = glm::normalize(x);
      vec3 y = glm::cross(ns, x);
      vec3 n = glm::normalize(glm::normalize(nt).x * x + glm::normalize(nt).y * y + glm::normalize(nt).z * ns);
      vec3 u = dpdu - n * glm::dot(n, dpdu);
      if (glm::dot(u, u) > 0.0f) {
        dpdu = glm::normalize(u) * ulen;
        dpdv = glm::normalize(glm::cross(n, dpdu)) * vlen;
        mapped = true;
      }
    }
  } else if (m && m->displacement >= 0) {
    // pbrt-v4's BumpMap: offsets of half the footprint, so the finite
    // difference sees the bumps the filtered texture still shows; its
    // fixed fallback without one.
    const UVFootprint& fp = tc.fp;
    float du = 0.5f * (std::abs(fp.dudx) + std::abs(fp.dudy)), dv = 0.5f * (std::abs(fp.dvdx) + std::abs(fp.dvdy));
    if (!(du > 0.0f) || !std::isfinite(du)) du = 0.0005f;
    if (!(dv > 0.0f) || !std::isfinite(dv)) dv = 0.0005f;
    float d = eval_float_texture(scene, m->displacement, tc);
    float d_u = eval_float_texture(scene, m->displacement, {si.uv + vec2(du, 0.0f), si.p + du * si.dpdu, tc.fp, tc.n});
    float d_v = eval_float_texture(scene, m->displacement, {si.uv + vec2(0.0f, dv), si.p + dv * si.dpdv, tc.fp, tc.n});
    // The partials of the displaced surface p + d n: its slope along n and its
    // curvature term d dn/du (which shrinks the tilt where d is above a curved surface).
    dpdu = si.dpdu + (d_u - d) / du * ns + d * si.dndu;
    dpdv = si.dpdv + (d_v - d) / dv * ns + d * si.dndv;
    mapped = true;
  }
  if (mapped) {
    vec3 n = glm::cross(dpdu, dpdv);
    if (glm::dot(n, n) > 0.0f && std::isfinite(n.x + n.y + n.z)) {
      n = glm::normalize(n);
      ns = glm::dot(n, si.ng) < 0.0f ? -n : n;  // on the geometric normal's side
    }
  }
  vec3 s = dpdu - ns * glm::dot(ns, dpdu);
  if (!(glm::dot(s, s) > 1e-12f) || !std::isfinite(s.x + s.y + s.z)) return Frame::from_z(ns);
  s = glm::normalize(s);
  return Frame{s, glm::cross(ns, s), ns};
}

// The hair frame keeps x exactly along the fibre (pbrt-v4 builds it from
// dpdu and the normal): sin(theta) = w.x only holds if x is the tangent, so
// here the normal is made perpendicular to dpdu rather than dpdu to the normal.
Frame hair_frame(const Frame& shading, const vec3& dpdu) {
  if (!(glm::dot(dpdu, dpdu) > 0.0f) || !std::isfinite(dpdu.x + dpdu.y + dpdu.z)) return shading;
  vec3 x = glm::normalize(dpdu);
  vec3 z = shading.n - x * glm::dot(x, shading.n);
  if (!(glm::dot(z, z) > 1e-12f)) return shading;
  z = glm::normalize(z);
  return Frame{x, glm::cross(z, x), z};
}

// The offset h in [-1, 1] from the fibre's axis at which the ray met it, in
// the hair model's sense: the ray's distance from the axis over the radius,
// positive along y = z x x of the hair frame when z faces wo (then gamma_o =
// asin(h) and the R lobe leaves at phi_o - 2 gamma_o, the mirror image of wo
// in the fibre's normal).  pbrt-v4 reads it from v across its ray-facing
// ribbons (h = -1 + 2v); theia's curves need their own:
//  - round ("cylinder") curves are real tubes, where Embree's v is always 0
//    (h = -1 would make every hit grazing, Fresnel 1, a lossless mirror):
//    h is where wo meets the tube's normal, -wo.y / |(wo.y, wo.z)| when the
//    frame's z is the outward normal;
//  - flat curves face the ray; Embree's v runs 1..-1 along dpdv;
//  - ribbons: pbrt-v4's -1 + 2v, v running along dpdv before the normal was
//    flipped (ReverseOrientation), signed by the side the ray comes from;
//  - any other shape, pbrt-v4's -1 + 2v.
// dpdv is compared with y rather than assumed along it: an instance's mirror
// turns the frame's y but not the direction in which v grows.
float hair_offset(const Scene& scene, const SurfaceInteraction& si, const Frame& frame) {
  const Shape* shape = si.shape >= 0 ? &scene.shapes[size_t(si.shape)] : nullptr;
  if (!shape || shape->kind != ShapeKind::Curve || shape->curves < 0) return -1.0f + 2.0f * si.uv.y;
  vec3 wo = frame.to_local(si.wo);
  float side = wo.z < 0.0f ? -1.0f : 1.0f;
  float along_y = glm::dot(si.dpdv, frame.t) * side < 0.0f ? -1.0f : 1.0f;  // dpdv along y (z facing wo)?
  switch (scene.curves[size_t(shape->curves)].type) {
    case CurveType::Cylinder: {
      float len = std::sqrt(sqr(wo.y) + sqr(wo.z));
      return len > 0.0f ? -side * wo.y / len : 0.0f;
    }
    case CurveType::Flat: return -along_y * si.uv.y;
    case CurveType::Ribbon: {
      bool flipped = shape->reverse_orientation != shape->transform_swaps_handedness;
      return (flipped ? -along_y : along_y) * (-1.0f + 2.0f * si.uv.y);
    }
  }
  return 0.0f;
}

void set_lobes(BSDF& b) {
  const BxDF& x = b.bxdf;
  const uint8_t flags = b.flags = bxdf_flags(x);
  auto kind_bits = [](const TrowbridgeReitz& d) { return d.effectively_smooth() ? kLobeSpecular : kLobeGlossy; };
  switch (x.kind) {
    case BxDFKind::Diffuse:
      b.lobe_count = 1;
      b.lobes[0] = {uint8_t(kLobeReflection | kLobeDiffuse), 1.0f, x.diffuse.r};
      break;
    case BxDFKind::Conductor:
      b.lobe_count = 1;
      b.lobes[0] = {uint8_t(kLobeReflection | kind_bits(x.conductor.distrib)), x.conductor.distrib.roughness(),
                    conductor_fresnel(1.0f, x.conductor)};
      break;
    case BxDFKind::Dielectric:
    case BxDFKind::ThinDielectric: {
      bool thin = x.kind == BxDFKind::ThinDielectric;
      float eta = thin ? x.thin.eta : x.dielectric.eta;
      uint8_t k = thin ? uint8_t(kLobeSpecular) : uint8_t(kind_bits(x.dielectric.distrib));
      float rough = thin ? 0.0f : x.dielectric.distrib.roughness();
      float r0 = fresnel_dielectric(1.0f, eta);
      b.lobe_count = 2;
      b.lobes[0] = {uint8_t(kLobeReflection | k), rough, RGB(r0)};
      b.lobes[1] = {uint8_t(kLobeTransmission | k), rough, RGB(1.0f - r0)};
      break;
    }
    case BxDFKind::DiffuseTransmission:
      b.lobe_count = 2;
      b.lobes[0] = {uint8_t(kLobeReflection | kLobeDiffuse), 1.0f, x.diffuse_transmission.r};
      b.lobes[1] = {uint8_t(kLobeTransmission | kLobeDiffuse), 1.0f, x.diffuse_transmission.t};
      break;
    case BxDFKind::CoatedDiffuse:
      b.lobe_count = 1;
      b.lobes[0] = {flags, 1.0f, x.coated_diffuse.base.r};
      break;
    case BxDFKind::CoatedConductor: {
      const CoatedConductorBxDF& c = x.coated_conductor;
      b.lobe_count = 1;
      b.lobes[0] = {flags, std::max(c.top.distrib.roughness(), c.base.distrib.roughness()), conductor_fresnel(1.0f, c.base)};
      break;
    }
    case BxDFKind::Hair:
      // One glossy lobe over the whole sphere; its albedo is the colour the
      // absorption stands for (the inverse of pbrt-v4's SigmaAFromReflectance).
      b.lobe_count = 1;
      b.lobes[0] = {flags, x.hair.beta_m, srgb_to_working(hair_reflectance_from_sigma_a(x.hair.sigma_a, x.hair.beta_n))};
      break;
    case BxDFKind::None: b.lobe_count = 0; break;
  }
}

}  // namespace

BSDF bsdf_from(const BxDF& bxdf, const Frame& shading, const vec3& ng) {
  BSDF b;
  b.shading = shading;
  b.ng = ng;
  b.bxdf = bxdf;
  set_lobes(b);
  return b;
}

BSDF make_bsdf(const Scene& scene, const SurfaceInteraction& si, const UVFootprint& fp) {
  BSDF bsdf;
  bsdf.ng = si.ng;
  const TextureEvalContext tc{si.uv, si.p, fp, si.ng};
  const Material* m = si.material >= 0 ? &scene.materials[size_t(si.material)] : nullptr;
  m = resolve_mix(scene, m, si, tc);
  if (m && m->kind == MaterialKind::Interface) m = nullptr;
  if (!m && si.material >= 0) {
    bsdf.kind = MaterialKind::Interface;
    bsdf.shading = Frame::from_z(si.ns);
    return bsdf;  // no surface
  }
  bsdf.kind = m ? m->kind : MaterialKind::Diffuse;
  bsdf.shading = shading_frame(scene, m, si, tc);
  BxDF& x = bsdf.bxdf;
  auto reflectance = [&](RGB def) { return glm::clamp(tex_rgb(scene, m ? m->reflectance : -1, tc, def), RGB(0.0f), RGB(1.0f)); };
  auto conductor = [&](int eta, int k, int refl) {
    ConductorBxDF c;
    if (refl >= 0) {
      // pbrt-v4's reflectance form: eta = 1 and the k that gives r at normal incidence.
      // The reflectance is a colour (working space); k lives in sRGB bands like a scene's k.
      RGB r = glm::clamp(working_to_srgb(eval_texture(scene, refl, tc)), RGB(0.0f), RGB(0.9999f));
      c.eta = RGB(1.0f);
      c.k = 2.0f * glm::sqrt(r) / glm::sqrt(glm::max(RGB(1.0f) - r, RGB(0.0f)));
    } else {
      c.eta = tex_rgb(scene, eta, tc, RGB(1.0f));
      c.k = glm::max(tex_rgb(scene, k, tc, RGB(0.0f)), RGB(0.0f));
      if (!m->conductor_fresnel.empty()) c.fresnel_table = m->conductor_fresnel.data();
    }
    return c;
  };
  switch (bsdf.kind) {
    case MaterialKind::Diffuse: x = DiffuseBxDF{reflectance(RGB(0.5f))}; break;
    case MaterialKind::Conductor: {
      ConductorBxDF c = conductor(m->conductor_eta, m->conductor_k, m->reflectance);
      c.distrib = distribution(scene, m->uroughness, m->vroughness, m->remap_roughness, tc);
      x = c;
      break;
    }
    case MaterialKind::Dielectric:
      x = DielectricBxDF{distribution(scene, m->uroughness, m->vroughness, m->remap_roughness, tc), m->eta};
      break;
    case MaterialKind::ThinDielectric: x = ThinDielectricBxDF{m->eta}; break;
    case MaterialKind::DiffuseTransmission:
      x = DiffuseTransmissionBxDF{
          glm::clamp(m->scale * tex_rgb(scene, m->reflectance, tc, RGB(0.25f)), RGB(0.0f), RGB(1.0f)),
          glm::clamp(m->scale * tex_rgb(scene, m->transmittance, tc, RGB(0.25f)), RGB(0.0f), RGB(1.0f))};
      break;
    case MaterialKind::CoatedDiffuse:
    case MaterialKind::CoatedConductor: {
      DielectricBxDF top{distribution(scene, m->uroughness, m->vroughness, m->remap_roughness, tc),
                         m->eta == 0.0f ? 1.0f : m->eta};
      LayerParams layer;
      layer.thickness = std::max(tex_float(scene, m->thickness, tc, 0.01f), 0.0f);
      layer.g = std::clamp(tex_float(scene, m->g, tc, 0.0f), -0.99f, 0.99f);
      layer.albedo = glm::clamp(tex_rgb(scene, m->albedo, tc, RGB(0.0f)), RGB(0.0f), RGB(1.0f));
      layer.max_depth = m->max_depth;
      layer.n_samples = m->n_samples;
      if (bsdf.kind == MaterialKind::CoatedDiffuse) {
        x = CoatedDiffuseBxDF{top, DiffuseBxDF{reflectance(RGB(0.5f))}, layer};
      } else {
        // The base sits in the coating's medium: its index is relative to the coat's (pbrt-v4).
        ConductorBxDF base = conductor(m->conductor_eta, m->conductor_k, m->reflectance);
        base.eta /= top.eta;
        base.k /= top.eta;
        base.distrib = distribution(scene, m->conductor_uroughness, m->conductor_vroughness, m->remap_roughness, tc);
        x = CoatedConductorBxDF{top, base, layer};
      }
      break;
    }
    case MaterialKind::Hair: {
      // pbrt-v4's HairMaterial.  The hair frame's x is dpdu, along the
      // fibre; h is where across it the ray met it (hair_offset).
      float beta_n = std::clamp(tex_float(scene, m->beta_n, tc, 0.3f), 0.0f, 1.0f);
      RGB sigma_a;
      if (m->sigma_a >= 0) sigma_a = glm::max(eval_texture(scene, m->sigma_a, tc), RGB(0.0f));
      else if (m->reflectance >= 0)  // a colour: to the sRGB bands sigma_a lives in
        sigma_a = hair_sigma_a_from_reflectance(
            glm::clamp(working_to_srgb(eval_texture(scene, m->reflectance, tc)), RGB(0.0f), RGB(1.0f)), beta_n);
      else
        sigma_a = hair_sigma_a_from_concentration(std::max(tex_float(scene, m->eumelanin, tc, 0.0f), 0.0f),
                                                  std::max(tex_float(scene, m->pheomelanin, tc, 0.0f), 0.0f));
      bsdf.shading = hair_frame(bsdf.shading, si.dpdu);
      x = make_hair_bxdf(hair_offset(scene, si, bsdf.shading), m->eta, sigma_a,
                              tex_float(scene, m->beta_m, tc, 0.3f), beta_n, tex_float(scene, m->hair_alpha, tc, 2.0f));
      break;
    }
    case MaterialKind::Mix:
    case MaterialKind::Interface: break;  // resolved above
  }
  set_lobes(bsdf);
  return bsdf;
}

bool material_reads_footprint(const Scene& scene, int material, int depth) {
  if (material < 0) return false;
  if (depth > 16) return true;
  const Material& m = scene.materials[size_t(material)];
  if (m.displacement >= 0) return true;
  for (int t : {m.reflectance, m.transmittance, m.uroughness, m.vroughness, m.conductor_eta, m.conductor_k,
                m.conductor_uroughness, m.conductor_vroughness, m.thickness, m.g, m.albedo, m.sigma_a, m.eumelanin,
                m.pheomelanin, m.beta_m, m.beta_n, m.hair_alpha, m.amount})
    if (texture_reads_footprint(scene, t)) return true;
  return m.kind == MaterialKind::Mix &&
         (material_reads_footprint(scene, m.mix[0], depth + 1) || material_reads_footprint(scene, m.mix[1], depth + 1));
}

// pbrt-v4's roughness parameters reach the distribution already as alphas
// (remaproughness true: alpha = sqrt(roughness), else alpha = roughness), so
// eq. 25 applies to alpha_x and alpha_y, each on its own.
static void roughen(TrowbridgeReitz& d, float gamma, float prev) {
  d.alpha_x = regularized_roughness(d.alpha_x, gamma, prev);
  d.alpha_y = regularized_roughness(d.alpha_y, gamma, prev);
}

void bsdf_roughen(BSDF& bsdf, float gamma, float prev) {
  BxDF& x = bsdf.bxdf;
  switch (x.kind) {
    case BxDFKind::Conductor: roughen(x.conductor.distrib, gamma, prev); break;
    case BxDFKind::Dielectric: roughen(x.dielectric.distrib, gamma, prev); break;
    case BxDFKind::CoatedDiffuse: roughen(x.coated_diffuse.top.distrib, gamma, prev); break;
    case BxDFKind::CoatedConductor:
      roughen(x.coated_conductor.top.distrib, gamma, prev);
      roughen(x.coated_conductor.base.distrib, gamma, prev);
      break;
    default: return;  // diffuse lobes are as rough as eq. 25 goes; thin dielectric and hair stay (bsdf.h)
  }
  set_lobes(bsdf);
}

RGB bsdf_f(const BSDF& bsdf, const vec3& wo_world, const vec3& wi_world, TransportMode mode) {
  vec3 wo = bsdf.shading.to_local(wo_world), wi = bsdf.shading.to_local(wi_world);
  if (wo.z == 0.0f) return RGB(0.0f);
  return bxdf_f(bsdf.bxdf, wo, wi, mode);
}

bool bsdf_is_caustic_caster(const BSDF& bsdf, float max_roughness) {
  if (bsdf.kind != MaterialKind::Conductor && bsdf.kind != MaterialKind::Dielectric &&
      bsdf.kind != MaterialKind::ThinDielectric)
    return false;
  if (bsdf.lobe_count == 0) return false;
  for (int i = 0; i < bsdf.lobe_count; ++i)
    if (!(bsdf.lobes[i].roughness <= max_roughness)) return false;
  return true;
}

bool bsdf_is_caustic_receiver(const BSDF& bsdf) {
  if (bsdf.lobe_count == 0) return false;
  for (int i = 0; i < bsdf.lobe_count; ++i)
    if ((bsdf.lobes[i].flags & (kLobeGlossy | kLobeSpecular)) || !(bsdf.lobes[i].flags & kLobeDiffuse)) return false;
  return true;
}

float bsdf_lobe_pdf(const BSDF& bsdf, int lobe, const vec3& wo_world, const vec3& wi_world) {
  vec3 wo = bsdf.shading.to_local(wo_world), wi = bsdf.shading.to_local(wi_world);
  if (wo.z == 0.0f || lobe != lobe_of(bsdf, wo, wi)) return 0.0f;
  return bxdf_pdf(bsdf.bxdf, wo, wi);
}

float bsdf_pdf(const BSDF& bsdf, const vec3& wo_world, const vec3& wi_world) {
  vec3 wo = bsdf.shading.to_local(wo_world), wi = bsdf.shading.to_local(wi_world);
  if (wo.z == 0.0f) return 0.0f;
  return bxdf_pdf(bsdf.bxdf, wo, wi);
}

DeferredPdf::DeferredPdf(const BxDF& b, const vec3& o, const vec3& i, TransportMode m)
    : top(b.kind == BxDFKind::CoatedDiffuse ? b.coated_diffuse.top : b.coated_conductor.top), wo(o), wi(i),
      n_samples(b.kind == BxDFKind::CoatedDiffuse ? b.coated_diffuse.layer.n_samples
                                                  : b.coated_conductor.layer.n_samples),
      kind(b.kind), mode(m) {
  if (kind == BxDFKind::CoatedDiffuse) std::construct_at(&diffuse, b.coated_diffuse.base);
  else std::construct_at(&conductor, b.coated_conductor.base);
}

// The layer's other parameters are left at their defaults: the layered pdf
// does not read them.
float deferred_pdf(const DeferredPdf& d) {
  if (d.kind == BxDFKind::CoatedDiffuse) {
    CoatedDiffuseBxDF b;
    b.top = d.top;
    b.base = d.diffuse;
    b.layer.n_samples = d.n_samples;
    return bxdf_pdf(BxDF(b), d.wo, d.wi, d.mode);
  }
  CoatedConductorBxDF b;
  b.top = d.top;
  b.base = d.conductor;
  b.layer.n_samples = d.n_samples;
  return bxdf_pdf(BxDF(b), d.wo, d.wi, d.mode);
}

std::optional<BSDFSample> any_bsdf_sample(const BSDF& bsdf, const vec3& wo, float u_lobe, vec2 u, TransportMode mode,
                                          DeferredPdf* defer, const vec3* cosine) {
  auto bs = bxdf_sample(bsdf.bxdf, wo, u_lobe, u, mode, kSampleAll, cosine);
  if (!bs) return std::nullopt;
  RGB f = bs->f;
  float pdf = bs->pdf;
  const bool proportional = bs->pdf_is_proportional && !bs->is_specular();
  if (proportional && defer) {
    *defer = DeferredPdf{bsdf.bxdf, wo, bs->wi, mode};
  } else if (proportional) {
    pdf = bxdf_pdf(bsdf.bxdf, wo, bs->wi, mode);
    if (!(pdf > 0.0f)) return std::nullopt;
    f = bs->f * (pdf / bs->pdf);
  }
  return world_sample(bsdf, wo, *bs, f, pdf, proportional && defer);
}

std::optional<BSDFSample> bsdf_event(const BSDF& bsdf, const vec3& wo_world, const vec3& wi_world) {
  vec3 wo = bsdf.shading.to_local(wo_world), wi = bsdf.shading.to_local(wi_world);
  if (wo.z == 0.0f || wi.z == 0.0f || bsdf.lobe_count == 0) return std::nullopt;
  BSDFSample s;
  s.f = bxdf_f(bsdf.bxdf, wo, wi);
  s.pdf = bxdf_pdf(bsdf.bxdf, wo, wi);
  s.wi = wi_world;
  s.lobe = lobe_of(bsdf, wo, wi);
  s.flags = bsdf.lobes[s.lobe].flags;
  s.roughness = bsdf.lobes[s.lobe].roughness;
  // A refraction crosses the index from wo's side to wi's (pbrt-v4's etap).
  if (s.is_transmission() && bsdf.bxdf.kind == BxDFKind::Dielectric)
    s.eta = wo.z > 0.0f ? bsdf.bxdf.dielectric.eta : 1.0f / bsdf.bxdf.dielectric.eta;
  if (!is_finite(s.f) || is_black(s.f)) return std::nullopt;
  return s;
}

bool bsdf_is_guidable(const BSDF& bsdf, float min_roughness) {
  // By the BxDF, not the material: a BSDF made by bsdf_from has no material kind.
  if (bsdf.lobe_count == 0 || bsdf.bxdf.kind == BxDFKind::CoatedDiffuse || bsdf.bxdf.kind == BxDFKind::CoatedConductor)
    return false;
  // Hair: R, TT and TRT each span both hemispheres, not the split by hemisphere bsdf_event assumes.
  if (bsdf.bxdf.kind == BxDFKind::Hair) return false;
  if (bsdf.flags & kLobeSpecular) return false;
  for (int i = 0; i < bsdf.lobe_count; ++i)
    if (bsdf.lobes[i].roughness > min_roughness) return true;
  return false;
}

}  // namespace theia
