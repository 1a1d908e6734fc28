// pbrt-v4's HairBxDF (d'Eon et al. / Chiang et al. 2016 hair scattering), as
// plain data plus free functions; scene/bxdfs.cpp dispatches to them.
//
// The local frame is pbrt-v4's hair frame: x along the fibre (the curve's
// dpdu), z the surface normal, so sin(theta) = w.x and phi = atan2(w.z, w.y).
// h in [-1, 1] is the offset across the fibre where the ray hit it.
//
// Colours: sigma_a is an absorption coefficient per band (like a conductor's
// k), kept in the linear-sRGB bands the scene gives; f is a colour and joins
// the working space (core/color.h) only at the end, as conductor_fresnel does.
#pragma once

#include "core/math.h"

#include <optional>

namespace theia {

inline constexpr int kHairPMax = 3;

struct HairBxDF {
  float h = 0.0f, gamma_o = 0.0f, eta = 1.55f;
  RGB sigma_a{0.0f};  // sRGB bands
  float beta_m = 0.3f, beta_n = 0.3f;
  // Derived by make_hair_bxdf: longitudinal variances per lobe, the azimuthal
  // logistic scale, and the scale tilt's sin/cos of 2^k alpha.
  float v[kHairPMax + 1] = {};
  float s = 0.0f;
  float sin2k_alpha[3] = {}, cos2k_alpha[3] = {};
};

// alpha (the scales' tilt) is in degrees, as pbrt-v4's "alpha" parameter.
HairBxDF make_hair_bxdf(float h, float eta, RGB sigma_a, float beta_m, float beta_n, float alpha_degrees);

// pbrt-v4's SigmaAFromConcentration (sRGB bands) and SigmaAFromReflectance
// (reflectance and result in sRGB bands, per band).
RGB hair_sigma_a_from_concentration(float eumelanin, float pheomelanin);
RGB hair_sigma_a_from_reflectance(RGB c, float beta_n);
// The inverse of the above: the colour a sigma_a roughly looks like (sRGB bands).
RGB hair_reflectance_from_sigma_a(RGB sigma_a, float beta_n);

// f (without the cosine; like pbrt-v4 it divides by |wi.z| so that f |cos|
// is the hair's scattering function), pdf and sampling; the sample's f is
// in the working space like hair_f.
RGB hair_f(const HairBxDF& b, const vec3& wo, const vec3& wi);
float hair_pdf(const HairBxDF& b, const vec3& wo, const vec3& wi);
struct HairSample {
  vec3 wi{0.0f};
  RGB f{0.0f};
  float pdf = 0.0f;
};
std::optional<HairSample> hair_sample(const HairBxDF& b, const vec3& wo, float uc, vec2 u);
// pbrt-v4's A_p (per-lobe attenuations, sRGB bands) and their luminance-like
// sampling probabilities for an outgoing direction; exposed for tests.
void hair_ap(const HairBxDF& b, const vec3& wo, RGB ap[kHairPMax + 1]);
void hair_ap_pdf(const HairBxDF& b, float cos_theta_o, float ap_pdf[kHairPMax + 1]);

}  // namespace theia
