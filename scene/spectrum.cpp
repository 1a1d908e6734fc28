#include "scene/spectrum.h"

#include <array>

namespace theia {

namespace {

// The visible range pbrt-v4 integrates over, sampled every nanometre: the
// fit's lobes are far wider than that, so a Riemann sum is exact enough.
constexpr int kLambdaMin = 360;
constexpr int kLambdaMax = 830;

float piecewise_gaussian(float x, float mu, float sigma_lo, float sigma_hi) {
  float t = (x - mu) / (x < mu ? sigma_lo : sigma_hi);
  return std::exp(-0.5f * t * t);
}

template <typename F>
vec3 integrate_xyz(F&& spectrum) {
  dvec3 sum(0.0);
  for (int l = kLambdaMin; l <= kLambdaMax; ++l) {
    float s = spectrum(float(l));
    sum += dvec3(cie_xyz_cmf(float(l))) * double(s);
  }
  return vec3(sum);
}

float cie_y_integral() {
  static const float y = integrate_xyz([](float) { return 1.0f; }).y;
  return y;
}

// Linear interpolation in an ascending table; zero outside it.
float eval_piecewise(std::span<const float> lambda, std::span<const float> value, float l) {
  if (lambda.empty() || l < lambda.front() || l > lambda.back()) return 0.0f;
  auto it = std::upper_bound(lambda.begin(), lambda.end(), l);
  if (it == lambda.end()) return value.back();
  size_t i = size_t(it - lambda.begin());
  if (i == 0) return value.front();
  float t = (l - lambda[i - 1]) / (lambda[i] - lambda[i - 1]);
  return value[i - 1] + t * (value[i] - value[i - 1]);
}

double planck(double lambda_nm, double t) {
  constexpr double c = 299792458.0, h = 6.62606957e-34, kb = 1.3806488e-23;
  double l = lambda_nm * 1e-9;
  return (2.0 * h * c * c) / (std::pow(l, 5.0) * (std::exp((h * c) / (l * kb * t)) - 1.0));
}

RGB normalised_illuminant(const vec3& xyz) {
  if (!(xyz.y > 0.0f)) return RGB(0.0f);
  return xyz_to_linear_srgb(xyz / xyz.y);
}

// Named-spectrum table: extend here.  CIE illuminant A is by definition a
// Planckian radiator at 2856 K.
const std::array<NamedSpectrum, 1> kNamedSpectra = {{
    {"stdillum-A", {}, {}, 2856.0f},
}};

}  // namespace

vec3 cie_xyz_cmf(float l) {
  float x = 1.056f * piecewise_gaussian(l, 599.8f, 37.9f, 31.0f) + 0.362f * piecewise_gaussian(l, 442.0f, 16.0f, 26.7f) -
            0.065f * piecewise_gaussian(l, 501.1f, 20.4f, 26.2f);
  float y = 0.821f * piecewise_gaussian(l, 568.8f, 46.9f, 40.5f) + 0.286f * piecewise_gaussian(l, 530.9f, 16.3f, 31.1f);
  float z = 1.217f * piecewise_gaussian(l, 437.0f, 11.8f, 36.0f) + 0.681f * piecewise_gaussian(l, 459.0f, 26.0f, 13.8f);
  return {x, y, z};
}

RGB xyz_to_linear_srgb(const vec3& c) {
  return {3.2404542f * c.x - 1.5371385f * c.y - 0.4985314f * c.z,
          -0.9692660f * c.x + 1.8760108f * c.y + 0.0415560f * c.z,
          0.0556434f * c.x - 0.2040259f * c.y + 1.0572252f * c.z};
}

RGB blackbody_rgb(float temperature_k) {
  if (!(temperature_k > 0.0f)) return RGB(0.0f);
  double t = temperature_k;
  return normalised_illuminant(integrate_xyz([t](float l) { return float(planck(l, t)); }));
}

RGB spectrum_to_rgb_illuminant(std::span<const float> lambda, std::span<const float> value) {
  return normalised_illuminant(integrate_xyz([&](float l) { return eval_piecewise(lambda, value, l); }));
}

RGB spectrum_to_rgb_reflectance(std::span<const float> lambda, std::span<const float> value) {
  float y_white = cie_y_integral();
  static const RGB white = xyz_to_linear_srgb(integrate_xyz([](float) { return 1.0f; }) / cie_y_integral());
  vec3 xyz = integrate_xyz([&](float l) { return eval_piecewise(lambda, value, l); }) / y_white;
  return xyz_to_linear_srgb(xyz) / white;
}

const NamedSpectrum* find_named_spectrum(std::string_view name) {
  for (const NamedSpectrum& s : kNamedSpectra)
    if (s.name == name) return &s;
  return nullptr;
}

RGB named_spectrum_rgb(const NamedSpectrum& s, bool illuminant) {
  if (s.blackbody_k > 0.0f) {
    RGB c = blackbody_rgb(s.blackbody_k);
    // As a reflectance a Planckian has no natural scale; use its chromaticity.
    return illuminant ? c : c / std::max(max_component(c), 1e-6f);
  }
  return illuminant ? spectrum_to_rgb_illuminant(s.lambda, s.value) : spectrum_to_rgb_reflectance(s.lambda, s.value);
}

}  // namespace theia
