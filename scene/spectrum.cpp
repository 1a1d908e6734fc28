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

// pbrt-v4's measured metal indices (src/pbrt/util/spectrum.cpp, Apache-2.0), all on
// one wavelength grid.
constexpr std::array<float, 56> kMetalLambda = {
    298.757f, 302.4f, 306.134f, 309.96f, 313.884f, 317.908f, 322.037f,
    326.274f, 330.624f, 335.092f, 339.683f, 344.4f, 349.251f, 354.241f,
    359.374f, 364.659f, 370.102f, 375.71f, 381.49f, 387.451f, 393.601f,
    399.949f, 406.505f, 413.281f, 420.285f, 427.532f, 435.032f, 442.801f,
    450.852f, 459.201f, 467.865f, 476.862f, 486.212f, 495.937f, 506.058f,
    516.601f, 527.592f, 539.062f, 551.041f, 563.564f, 576.671f, 590.401f,
    604.801f, 619.921f, 635.816f, 652.548f, 670.185f, 688.801f, 708.481f,
    729.319f, 751.419f, 774.901f, 799.898f, 826.561f, 855.063f, 885.601f,
};
constexpr std::array<float, 56> kMetalAgEta = {
    1.519f, 1.496f, 1.4325f, 1.323f, 1.14206f, 0.932f, 0.719062f,
    0.526f, 0.388125f, 0.294f, 0.253313f, 0.238f, 0.221438f, 0.209f,
    0.194813f, 0.186f, 0.192063f, 0.2f, 0.198063f, 0.192f, 0.182f,
    0.173f, 0.172625f, 0.173f, 0.166688f, 0.16f, 0.1585f, 0.157f,
    0.151063f, 0.144f, 0.137313f, 0.132f, 0.13025f, 0.13f, 0.129938f,
    0.13f, 0.130063f, 0.129f, 0.124375f, 0.12f, 0.119313f, 0.121f,
    0.1255f, 0.131f, 0.136125f, 0.14f, 0.140063f, 0.14f, 0.144313f,
    0.148f, 0.145875f, 0.143f, 0.142563f, 0.145f, 0.151938f, 0.163f,
};
constexpr std::array<float, 56> kMetalAgK = {
    1.08f, 0.882f, 0.761063f, 0.647f, 0.550875f, 0.504f, 0.554375f,
    0.663f, 0.818563f, 0.986f, 1.12069f, 1.24f, 1.34525f, 1.44f,
    1.53375f, 1.61f, 1.64187f, 1.67f, 1.735f, 1.81f, 1.87875f,
    1.95f, 2.02937f, 2.11f, 2.18625f, 2.26f, 2.32938f, 2.4f,
    2.47875f, 2.56f, 2.64f, 2.72f, 2.79813f, 2.88f, 2.97375f,
    3.07f, 3.15937f, 3.25f, 3.34813f, 3.45f, 3.55375f, 3.66f,
    3.76625f, 3.88f, 4.01063f, 4.15f, 4.29312f, 4.44f, 4.58625f,
    4.74f, 4.90813f, 5.09f, 5.28875f, 5.5f, 5.72062f, 5.95f,
};
constexpr std::array<float, 56> kMetalAlEta = {
    0.273375f, 0.28f, 0.286813f, 0.294f, 0.301875f, 0.31f, 0.317875f,
    0.326f, 0.33475f, 0.344f, 0.353813f, 0.364f, 0.374375f, 0.385f,
    0.39575f, 0.407f, 0.419125f, 0.432f, 0.445688f, 0.46f, 0.474688f,
    0.49f, 0.506188f, 0.523f, 0.540063f, 0.558f, 0.577313f, 0.598f,
    0.620313f, 0.644f, 0.668625f, 0.695f, 0.72375f, 0.755f, 0.789f,
    0.826f, 0.867f, 0.912f, 0.963f, 1.02f, 1.08f, 1.15f,
    1.22f, 1.3f, 1.39f, 1.49f, 1.6f, 1.74f, 1.91f,
    2.14f, 2.41f, 2.63f, 2.8f, 2.74f, 2.58f, 2.24f,
};
constexpr std::array<float, 56> kMetalAlK = {
    3.59375f, 3.64f, 3.68938f, 3.74f, 3.78938f, 3.84f, 3.89438f,
    3.95f, 4.005f, 4.06f, 4.11375f, 4.17f, 4.23375f, 4.3f,
    4.365f, 4.43f, 4.49375f, 4.56f, 4.63375f, 4.71f, 4.78437f,
    4.86f, 4.93813f, 5.02f, 5.10875f, 5.2f, 5.29f, 5.38f,
    5.48f, 5.58f, 5.69f, 5.8f, 5.915f, 6.03f, 6.15f,
    6.28f, 6.42f, 6.55f, 6.7f, 6.85f, 7.0f, 7.15f,
    7.31f, 7.48f, 7.65f, 7.82f, 8.01f, 8.21f, 8.39f,
    8.57f, 8.62f, 8.6f, 8.45f, 8.31f, 8.21f, 8.21f,
};
constexpr std::array<float, 56> kMetalAuEta = {
    1.795f, 1.812f, 1.82262f, 1.83f, 1.83712f, 1.84f, 1.83425f,
    1.824f, 1.812f, 1.798f, 1.782f, 1.766f, 1.7525f, 1.74f,
    1.72762f, 1.716f, 1.70588f, 1.696f, 1.68475f, 1.674f, 1.666f,
    1.658f, 1.64725f, 1.636f, 1.628f, 1.616f, 1.59625f, 1.562f,
    1.50212f, 1.426f, 1.34587f, 1.242f, 1.08675f, 0.916f, 0.7545f,
    0.608f, 0.49175f, 0.402f, 0.3455f, 0.306f, 0.267625f, 0.236f,
    0.212375f, 0.194f, 0.17775f, 0.166f, 0.161f, 0.16f, 0.160875f,
    0.164f, 0.1695f, 0.176f, 0.181375f, 0.188f, 0.198125f, 0.21f,
};
constexpr std::array<float, 56> kMetalAuK = {
    1.92037f, 1.92f, 1.91888f, 1.916f, 1.91138f, 1.904f, 1.89138f,
    1.878f, 1.86825f, 1.86f, 1.85175f, 1.846f, 1.84525f, 1.848f,
    1.85238f, 1.862f, 1.883f, 1.906f, 1.9225f, 1.936f, 1.94775f,
    1.956f, 1.95938f, 1.958f, 1.95138f, 1.94f, 1.9245f, 1.904f,
    1.87587f, 1.846f, 1.81462f, 1.796f, 1.79737f, 1.84f, 1.9565f,
    2.12f, 2.32625f, 2.54f, 2.73062f, 2.88f, 2.94062f, 2.97f,
    3.015f, 3.06f, 3.07f, 3.15f, 3.44581f, 3.8f, 4.08769f,
    4.357f, 4.61019f, 4.86f, 5.12581f, 5.39f, 5.63125f, 5.88f,
};
constexpr std::array<float, 56> kMetalCuEta = {
    1.40031f, 1.38f, 1.35844f, 1.34f, 1.32906f, 1.325f, 1.3325f,
    1.34f, 1.33438f, 1.325f, 1.31781f, 1.31f, 1.30031f, 1.29f,
    1.28156f, 1.27f, 1.24906f, 1.225f, 1.2f, 1.18f, 1.17437f,
    1.175f, 1.1775f, 1.18f, 1.17813f, 1.175f, 1.17281f, 1.17f,
    1.16531f, 1.16f, 1.15531f, 1.15f, 1.14281f, 1.135f, 1.13156f,
    1.12f, 1.09244f, 1.04f, 0.950375f, 0.826f, 0.645875f, 0.468f,
    0.35125f, 0.272f, 0.230813f, 0.214f, 0.20925f, 0.213f, 0.21625f,
    0.223f, 0.2365f, 0.25f, 0.254188f, 0.26f, 0.28f, 0.3f,
};
constexpr std::array<float, 56> kMetalCuK = {
    1.66213f, 1.687f, 1.70331f, 1.72f, 1.74456f, 1.77f, 1.79163f,
    1.81f, 1.82212f, 1.834f, 1.85175f, 1.872f, 1.89425f, 1.916f,
    1.93169f, 1.95f, 1.97244f, 2.015f, 2.12156f, 2.21f, 2.17719f,
    2.13f, 2.16006f, 2.21f, 2.24994f, 2.289f, 2.326f, 2.362f,
    2.39763f, 2.433f, 2.46919f, 2.504f, 2.53587f, 2.564f, 2.58962f,
    2.605f, 2.59556f, 2.583f, 2.5765f, 2.599f, 2.67806f, 2.809f,
    3.01075f, 3.24f, 3.45819f, 3.67f, 3.86313f, 4.05f, 4.23956f,
    4.43f, 4.61956f, 4.817f, 5.03413f, 5.26f, 5.48562f, 5.717f,
};

// Glass indices (pbrt-v4's tables, from refractiveindex.info, CC0).  theia
// uses one index per dielectric, taken at 550 nm, so only the two samples
// around 550 nm are kept; "glass-F5/F10/F11" are Schott SF5/SF10/SF11.
constexpr std::array<float, 2> kGlassBK7Lambda = {542.0f, 564.0f}, kGlassBK7Eta = {1.5189334783f, 1.5178426479f};
constexpr std::array<float, 2> kGlassBAF10Lambda = {543.0f, 565.0f}, kGlassBAF10Eta = {1.6736474832f, 1.6717737893f};
constexpr std::array<float, 2> kGlassFK51ALambda = {533.0f, 555.0f}, kGlassFK51AEta = {1.4884310526f, 1.4876086240f};
constexpr std::array<float, 2> kGlassLASF9Lambda = {540.0f, 561.0f}, kGlassLASF9Eta = {1.8574834752f, 1.8539661699f};
constexpr std::array<float, 2> kGlassF5Lambda = {540.0f, 561.0f}, kGlassF5Eta = {1.6784090060f, 1.6756360974f};
constexpr std::array<float, 2> kGlassF10Lambda = {549.0f, 570.0f}, kGlassF10Eta = {1.7337260730f, 1.7305324563f};
constexpr std::array<float, 2> kGlassF11Lambda = {540.0f, 561.0f}, kGlassF11Eta = {1.7930548641f, 1.7889903664f};

// Named-spectrum table: extend here.  CIE illuminant A is by definition a
// Planckian radiator at 2856 K.
const std::array<NamedSpectrum, 16> kNamedSpectra = {{
    {"stdillum-A", {}, {}, 2856.0f},
    {"metal-Ag-eta", kMetalLambda, kMetalAgEta},
    {"metal-Ag-k", kMetalLambda, kMetalAgK},
    {"metal-Al-eta", kMetalLambda, kMetalAlEta},
    {"metal-Al-k", kMetalLambda, kMetalAlK},
    {"metal-Au-eta", kMetalLambda, kMetalAuEta},
    {"metal-Au-k", kMetalLambda, kMetalAuK},
    {"metal-Cu-eta", kMetalLambda, kMetalCuEta},
    {"metal-Cu-k", kMetalLambda, kMetalCuK},
    {"glass-BK7", kGlassBK7Lambda, kGlassBK7Eta},
    {"glass-BAF10", kGlassBAF10Lambda, kGlassBAF10Eta},
    {"glass-FK51A", kGlassFK51ALambda, kGlassFK51AEta},
    {"glass-LASF9", kGlassLASF9Lambda, kGlassLASF9Eta},
    {"glass-F5", kGlassF5Lambda, kGlassF5Eta},
    {"glass-F10", kGlassF10Lambda, kGlassF10Eta},
    {"glass-F11", kGlassF11Lambda, kGlassF11Eta},
}};

}  // namespace

namespace {

vec3 cie_xyz_cmf_fit(float l) {
  float x = 1.056f * piecewise_gaussian(l, 599.8f, 37.9f, 31.0f) + 0.362f * piecewise_gaussian(l, 442.0f, 16.0f, 26.7f) -
            0.065f * piecewise_gaussian(l, 501.1f, 20.4f, 26.2f);
  float y = 0.821f * piecewise_gaussian(l, 568.8f, 46.9f, 40.5f) + 0.286f * piecewise_gaussian(l, 530.9f, 16.3f, 31.1f);
  float z = 1.217f * piecewise_gaussian(l, 437.0f, 11.8f, 36.0f) + 0.681f * piecewise_gaussian(l, 459.0f, 26.0f, 13.8f);
  return {x, y, z};
}

}  // namespace

vec3 cie_xyz_cmf(float l) {
  // The whole nanometres every integral here sums over, evaluated once (seven
  // exponentials each; a blackbody medium's table took a quarter million).
  static const auto table = [] {
    std::array<vec3, kLambdaMax - kLambdaMin + 1> t;
    for (int i = kLambdaMin; i <= kLambdaMax; ++i) t[size_t(i - kLambdaMin)] = cie_xyz_cmf_fit(float(i));
    return t;
  }();
  if (l >= float(kLambdaMin) && l <= float(kLambdaMax) && l == std::floor(l)) return table[size_t(int(l) - kLambdaMin)];
  return cie_xyz_cmf_fit(l);
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

float spectrum_at(std::span<const float> lambda, std::span<const float> value, float lambda_nm) {
  return eval_piecewise(lambda, value, lambda_nm);
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
