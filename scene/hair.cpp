#include "scene/hair.h"

#include "core/color.h"
#include "scene/microfacet.h"

namespace theia {

namespace {

float safe_asin(float x) { return std::asin(std::clamp(x, -1.0f, 1.0f)); }

// Modified Bessel function of the first kind, order 0 (series), and its log
// for large arguments where the series overflows.
float bessel_i0(float x) {
  float val = 0.0f, x2i = 1.0f;
  int64_t ifact = 1;
  int i4 = 1;
  for (int i = 0; i < 10; ++i) {
    if (i > 1) ifact *= i;
    val += x2i / (float(i4) * sqr(float(ifact)));
    x2i *= x * x;
    i4 *= 4;
  }
  return val;
}
float log_bessel_i0(float x) {
  if (x > 12.0f) return x + 0.5f * (-std::log(2.0f * kPi) + std::log(1.0f / x) + 1.0f / (8.0f * x));
  return std::log(bessel_i0(x));
}

// Longitudinal scattering (d'Eon et al.); the log form keeps small variances finite.
float mp(float cos_i, float cos_o, float sin_i, float sin_o, float v) {
  float a = cos_i * cos_o / v, b = sin_i * sin_o / v;
  if (v <= 0.1f) return std::exp(log_bessel_i0(a) - b - 1.0f / v + 0.6931f + std::log(1.0f / (2.0f * v)));
  return std::exp(-b) * bessel_i0(a) / (std::sinh(1.0f / v) * 2.0f * v);
}

float logistic(float x, float s) {
  x = std::abs(x);
  return std::exp(-x / s) / (s * sqr(1.0f + std::exp(-x / s)));
}
float logistic_cdf(float x, float s) { return 1.0f / (1.0f + std::exp(-x / s)); }
float trimmed_logistic(float x, float s, float a, float b) {
  return logistic(x, s) / (logistic_cdf(b, s) - logistic_cdf(a, s));
}
float sample_trimmed_logistic(float u, float s, float a, float b) {
  float k = logistic_cdf(b, s) - logistic_cdf(a, s);
  float x = -s * std::log(1.0f / (u * k + logistic_cdf(a, s)) - 1.0f);
  return std::clamp(x, a, b);
}

// Azimuthal deflection of lobe p (exit angle relative to entry).
float phi_of(int p, float gamma_o, float gamma_t) { return 2.0f * p * gamma_t - 2.0f * gamma_o + p * kPi; }

float np(float phi, int p, float s, float gamma_o, float gamma_t) {
  float dphi = phi - phi_of(p, gamma_o, gamma_t);
  while (dphi > kPi) dphi -= 2.0f * kPi;
  while (dphi < -kPi) dphi += 2.0f * kPi;
  return trimmed_logistic(dphi, s, -kPi, kPi);
}

// The scales tilt each lobe's cone: R by -2 alpha, TT by alpha, TRT by 4 alpha.
void tilt(const HairBxDF& b, int p, float sin_o, float cos_o, float* sin_p, float* cos_p) {
  switch (p) {
    case 0:
      *sin_p = sin_o * b.cos2k_alpha[1] - cos_o * b.sin2k_alpha[1];
      *cos_p = cos_o * b.cos2k_alpha[1] + sin_o * b.sin2k_alpha[1];
      break;
    case 1:
      *sin_p = sin_o * b.cos2k_alpha[0] + cos_o * b.sin2k_alpha[0];
      *cos_p = cos_o * b.cos2k_alpha[0] - sin_o * b.sin2k_alpha[0];
      break;
    case 2:
      *sin_p = sin_o * b.cos2k_alpha[2] + cos_o * b.sin2k_alpha[2];
      *cos_p = cos_o * b.cos2k_alpha[2] - sin_o * b.sin2k_alpha[2];
      break;
    default: *sin_p = sin_o, *cos_p = cos_o;
  }
  *cos_p = std::abs(*cos_p);  // the tilt can rotate past the pole
}

// Angles of the ray refracted into the fibre, from wo's.
struct Refracted {
  float cos_theta_t, gamma_t;
  RGB T;  // transmittance of one pass through the fibre
};
Refracted refracted(const HairBxDF& b, float sin_o, float cos_o) {
  float sin_t = sin_o / b.eta, cos_t = safe_sqrt(1.0f - sqr(sin_t));
  float etap = safe_sqrt(sqr(b.eta) - sqr(sin_o)) / cos_o;
  float sin_gamma_t = b.h / etap, cos_gamma_t = safe_sqrt(1.0f - sqr(sin_gamma_t));
  Refracted r;
  r.cos_theta_t = cos_t;
  r.gamma_t = safe_asin(sin_gamma_t);
  r.T = glm::exp(-b.sigma_a * (2.0f * cos_gamma_t / cos_t));
  return r;
}

void ap_terms(float cos_o, float eta, float h, RGB T, RGB ap[kHairPMax + 1]) {
  float cos_gamma_o = safe_sqrt(1.0f - h * h);
  float f = fresnel_dielectric(cos_o * cos_gamma_o, eta);
  ap[0] = RGB(f);
  ap[1] = sqr(1.0f - f) * T;
  for (int p = 2; p < kHairPMax; ++p) ap[p] = ap[p - 1] * T * f;
  // The geometric series of all higher orders.
  ap[kHairPMax] = RGB(0.0f);
  for (int c = 0; c < 3; ++c)
    if (1.0f - T[c] * f != 0.0f) ap[kHairPMax][c] = ap[kHairPMax - 1][c] * f * T[c] / (1.0f - T[c] * f);
}

float average(RGB c) { return (c.x + c.y + c.z) / 3.0f; }

}  // namespace

HairBxDF make_hair_bxdf(float h, float eta, RGB sigma_a, float beta_m, float beta_n, float alpha_degrees) {
  HairBxDF b;
  b.h = std::clamp(h, -1.0f, 1.0f);
  b.gamma_o = safe_asin(b.h);
  b.eta = eta;
  b.sigma_a = glm::max(sigma_a, RGB(0.0f));
  b.beta_m = std::clamp(beta_m, 0.0f, 1.0f);
  b.beta_n = std::clamp(beta_n, 0.0f, 1.0f);
  // Fits of d'Eon et al. / Chiang et al. mapping roughness to variance and scale.
  float bm = b.beta_m, bn = b.beta_n;
  b.v[0] = sqr(0.726f * bm + 0.812f * sqr(bm) + 3.7f * std::pow(bm, 20.0f));
  b.v[1] = 0.25f * b.v[0];
  b.v[2] = 4.0f * b.v[0];
  for (int p = 3; p <= kHairPMax; ++p) b.v[p] = b.v[2];
  const float sqrt_pi_over_8 = 0.626657069f;
  b.s = sqrt_pi_over_8 * (0.265f * bn + 1.194f * sqr(bn) + 5.372f * std::pow(bn, 22.0f));
  b.sin2k_alpha[0] = std::sin(radians(alpha_degrees));
  b.cos2k_alpha[0] = safe_sqrt(1.0f - sqr(b.sin2k_alpha[0]));
  for (int i = 1; i < 3; ++i) {
    b.sin2k_alpha[i] = 2.0f * b.cos2k_alpha[i - 1] * b.sin2k_alpha[i - 1];
    b.cos2k_alpha[i] = sqr(b.cos2k_alpha[i - 1]) - sqr(b.sin2k_alpha[i - 1]);
  }
  return b;
}

RGB hair_sigma_a_from_concentration(float eumelanin, float pheomelanin) {
  return eumelanin * RGB(0.419f, 0.697f, 1.37f) + pheomelanin * RGB(0.187f, 0.4f, 1.05f);
}

// Chiang et al.'s fit of the absorption that gives a colour after multiple scattering.
static float reflectance_fit(float bn) {
  return 5.969f - 0.215f * bn + 2.532f * sqr(bn) - 10.73f * bn * bn * bn + 5.574f * sqr(sqr(bn)) +
         0.245f * std::pow(bn, 5.0f);
}
RGB hair_sigma_a_from_reflectance(RGB c, float beta_n) {
  RGB sa;
  for (int i = 0; i < 3; ++i) sa[i] = sqr(std::log(std::max(c[i], 1e-6f)) / reflectance_fit(beta_n));
  return sa;
}
RGB hair_reflectance_from_sigma_a(RGB sigma_a, float beta_n) {
  return glm::exp(-glm::sqrt(glm::max(sigma_a, RGB(0.0f))) * reflectance_fit(beta_n));
}

void hair_ap(const HairBxDF& b, const vec3& wo, RGB ap[kHairPMax + 1]) {
  float sin_o = wo.x, cos_o = safe_sqrt(1.0f - sqr(sin_o));
  ap_terms(cos_o, b.eta, b.h, refracted(b, sin_o, cos_o).T, ap);
}

void hair_ap_pdf(const HairBxDF& b, float cos_theta_o, float ap_pdf[kHairPMax + 1]) {
  RGB ap[kHairPMax + 1];
  hair_ap(b, vec3(safe_sqrt(1.0f - sqr(cos_theta_o)), cos_theta_o, 0.0f), ap);
  float sum = 0.0f;
  for (const RGB& a : ap) sum += average(a);
  for (int p = 0; p <= kHairPMax; ++p) ap_pdf[p] = sum > 0.0f ? average(ap[p]) / sum : 0.0f;
}

RGB hair_f(const HairBxDF& b, const vec3& wo, const vec3& wi) {
  float sin_o = wo.x, cos_o = safe_sqrt(1.0f - sqr(sin_o)), phi_o = std::atan2(wo.z, wo.y);
  float sin_i = wi.x, cos_i = safe_sqrt(1.0f - sqr(sin_i)), phi_i = std::atan2(wi.z, wi.y);
  if (cos_o == 0.0f) return RGB(0.0f);
  Refracted r = refracted(b, sin_o, cos_o);
  RGB ap[kHairPMax + 1];
  ap_terms(cos_o, b.eta, b.h, r.T, ap);
  float phi = phi_i - phi_o;
  RGB sum(0.0f);
  for (int p = 0; p < kHairPMax; ++p) {
    float sin_p, cos_p;
    tilt(b, p, sin_o, cos_o, &sin_p, &cos_p);
    sum += mp(cos_i, cos_p, sin_i, sin_p, b.v[p]) * ap[p] * np(phi, p, b.s, b.gamma_o, r.gamma_t);
  }
  sum += mp(cos_i, cos_o, sin_i, sin_o, b.v[kHairPMax]) * ap[kHairPMax] * kInv2Pi;
  if (std::abs(wi.z) > 0.0f) sum /= std::abs(wi.z);
  RGB f = srgb_to_working(sum);
  return is_finite(f) ? f : RGB(0.0f);
}

float hair_pdf(const HairBxDF& b, const vec3& wo, const vec3& wi) {
  float sin_o = wo.x, cos_o = safe_sqrt(1.0f - sqr(sin_o)), phi_o = std::atan2(wo.z, wo.y);
  float sin_i = wi.x, cos_i = safe_sqrt(1.0f - sqr(sin_i)), phi_i = std::atan2(wi.z, wi.y);
  if (cos_o == 0.0f) return 0.0f;
  float gamma_t = refracted(b, sin_o, cos_o).gamma_t;
  float ap_pdf[kHairPMax + 1];
  hair_ap_pdf(b, cos_o, ap_pdf);
  float phi = phi_i - phi_o, pdf = 0.0f;
  for (int p = 0; p < kHairPMax; ++p) {
    float sin_p, cos_p;
    tilt(b, p, sin_o, cos_o, &sin_p, &cos_p);
    pdf += mp(cos_i, cos_p, sin_i, sin_p, b.v[p]) * ap_pdf[p] * np(phi, p, b.s, b.gamma_o, gamma_t);
  }
  pdf += mp(cos_i, cos_o, sin_i, sin_o, b.v[kHairPMax]) * ap_pdf[kHairPMax] * kInv2Pi;
  return std::isfinite(pdf) ? pdf : 0.0f;
}

std::optional<HairSample> hair_sample(const HairBxDF& b, const vec3& wo, float uc, vec2 u) {
  float sin_o = wo.x, cos_o = safe_sqrt(1.0f - sqr(sin_o)), phi_o = std::atan2(wo.z, wo.y);
  if (cos_o == 0.0f) return std::nullopt;
  // Choose a lobe by its A_p, then reuse uc (rescaled) for the azimuth.
  float ap_pdf[kHairPMax + 1];
  hair_ap_pdf(b, cos_o, ap_pdf);
  int p = 0;
  for (; p < kHairPMax; ++p) {
    if (uc < ap_pdf[p]) break;
    uc -= ap_pdf[p];
  }
  uc = std::min(ap_pdf[p] > 0.0f ? uc / ap_pdf[p] : 0.0f, 0x1.fffffep-1f);
  float sin_p, cos_p;
  tilt(b, p, sin_o, cos_o, &sin_p, &cos_p);
  // Sample M_p for theta_i.
  float v = b.v[p];
  float cos_theta = 1.0f + v * std::log(std::max(u[0], 1e-5f) + (1.0f - u[0]) * std::exp(-2.0f / v));
  float sin_theta = safe_sqrt(1.0f - sqr(cos_theta));
  float cos_phi = std::cos(2.0f * kPi * u[1]);
  float sin_i = -cos_theta * sin_p + sin_theta * cos_phi * cos_p;
  float cos_i = safe_sqrt(1.0f - sqr(sin_i));
  // Sample N_p for the azimuth.
  float gamma_t = refracted(b, sin_o, cos_o).gamma_t;
  float dphi = p < kHairPMax ? phi_of(p, b.gamma_o, gamma_t) + sample_trimmed_logistic(uc, b.s, -kPi, kPi)
                             : 2.0f * kPi * uc;
  float phi_i = phi_o + dphi;
  HairSample s;
  s.wi = vec3(sin_i, cos_i * std::cos(phi_i), cos_i * std::sin(phi_i));
  s.pdf = hair_pdf(b, wo, s.wi);
  s.f = hair_f(b, wo, s.wi);
  if (!(s.pdf > 0.0f) || !std::isfinite(s.wi.x + s.wi.y + s.wi.z)) return std::nullopt;
  return s;
}

}  // namespace theia
