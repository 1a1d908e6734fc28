#include "scene/bsdf.h"

#include "core/sampling.h"
#include "scene/texture.h"

namespace theia {

BSDF make_bsdf(const Scene& scene, const SurfaceInteraction& si) {
  BSDF bsdf;
  bsdf.shading = Frame::from_z(si.ns);
  bsdf.ng = si.ng;
  const Material* m = si.material >= 0 ? &scene.materials[si.material] : nullptr;
  bsdf.kind = m ? m->kind : MaterialKind::Diffuse;
  switch (bsdf.kind) {
    case MaterialKind::Diffuse: {
      RGB r = m && m->reflectance >= 0 ? eval_texture(scene, m->reflectance, TextureEvalContext{si.uv, si.p})
                                       : RGB(0.5f);
      r = glm::clamp(r, RGB(0.0f), RGB(1.0f));
      bsdf.lobe_count = 1;
      bsdf.lobes[0] = BxDFLobe{uint8_t(kLobeReflection | kLobeDiffuse), 1.0f, r};
      break;
    }
  }
  return bsdf;
}

static RGB lobe_f(const BxDFLobe& lobe, const vec3& wo, const vec3& wi) {
  if (lobe.flags & kLobeDiffuse) {
    if (wo.z * wi.z <= 0.0f) return RGB(0.0f);
    return lobe.albedo * kInvPi;
  }
  return RGB(0.0f);
}

static float lobe_pdf(const BxDFLobe& lobe, const vec3& wo, const vec3& wi) {
  if (lobe.flags & kLobeDiffuse) {
    if (wo.z * wi.z <= 0.0f) return 0.0f;
    return cosine_hemisphere_pdf(std::abs(wi.z));
  }
  return 0.0f;
}

// Lobes are chosen in proportion to their albedo's luminance (uniformly when all are black).
static float lobe_selection_pmf(const BSDF& bsdf, int lobe) {
  if (bsdf.lobe_count == 1) return 1.0f;
  float total = 0.0f;
  for (int i = 0; i < bsdf.lobe_count; ++i) total += luminance(bsdf.lobes[i].albedo);
  if (total <= 0.0f) return 1.0f / float(bsdf.lobe_count);
  return luminance(bsdf.lobes[lobe].albedo) / total;
}

RGB bsdf_f(const BSDF& bsdf, const vec3& wo_world, const vec3& wi_world) {
  vec3 wo = bsdf.shading.to_local(wo_world), wi = bsdf.shading.to_local(wi_world);
  if (wo.z == 0.0f) return RGB(0.0f);
  RGB f(0.0f);
  for (int i = 0; i < bsdf.lobe_count; ++i) f += lobe_f(bsdf.lobes[i], wo, wi);
  return f;
}

float bsdf_lobe_pdf(const BSDF& bsdf, int lobe, const vec3& wo_world, const vec3& wi_world) {
  vec3 wo = bsdf.shading.to_local(wo_world), wi = bsdf.shading.to_local(wi_world);
  return lobe_pdf(bsdf.lobes[lobe], wo, wi);
}

float bsdf_pdf(const BSDF& bsdf, const vec3& wo_world, const vec3& wi_world) {
  vec3 wo = bsdf.shading.to_local(wo_world), wi = bsdf.shading.to_local(wi_world);
  if (wo.z == 0.0f) return 0.0f;
  float pdf = 0.0f;
  for (int i = 0; i < bsdf.lobe_count; ++i) pdf += lobe_selection_pmf(bsdf, i) * lobe_pdf(bsdf.lobes[i], wo, wi);
  return pdf;
}

std::optional<BSDFSample> bsdf_sample(const BSDF& bsdf, const vec3& wo_world, float u_lobe, vec2 u) {
  vec3 wo = bsdf.shading.to_local(wo_world);
  if (wo.z == 0.0f || bsdf.lobe_count == 0) return std::nullopt;
  int lobe = 0;
  for (float acc = 0.0f; lobe < bsdf.lobe_count - 1; ++lobe) {
    acc += lobe_selection_pmf(bsdf, lobe);
    if (u_lobe < acc) break;
  }
  const BxDFLobe& l = bsdf.lobes[lobe];
  vec3 wi;
  if (l.flags & kLobeDiffuse) {
    wi = sample_cosine_hemisphere(u);
    if (wo.z < 0.0f) wi.z = -wi.z;
  } else {
    return std::nullopt;
  }
  BSDFSample s;
  s.wi = bsdf.shading.from_local(wi);
  s.f = bsdf_f(bsdf, wo_world, s.wi);
  s.pdf = bsdf_pdf(bsdf, wo_world, s.wi);
  s.lobe = lobe;
  s.flags = l.flags;
  s.roughness = l.roughness;
  if (s.pdf == 0.0f || is_black(s.f)) return std::nullopt;
  return s;
}

RGB bsdf_albedo(const BSDF& bsdf) {
  RGB a(0.0f);
  for (int i = 0; i < bsdf.lobe_count; ++i) a += bsdf.lobes[i].albedo;
  return a;
}

bool bsdf_is_specular(const BSDF& bsdf) {
  for (int i = 0; i < bsdf.lobe_count; ++i)
    if (!(bsdf.lobes[i].flags & kLobeSpecular)) return false;
  return bsdf.lobe_count > 0;
}

}  // namespace theia
