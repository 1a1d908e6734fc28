#include "scene/conductor_spectral.h"

#include "core/color.h"
#include "core/memo.h"
#include "scene/microfacet.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>

namespace theia {

namespace {

// CIE 1931 2-degree colour-matching functions and CIE illuminant D65, the
// standard tables at 5 nm from 360 to 830 nm (the data of tools/spectral_gap.py).
constexpr double kCieX[95] = {
    0.0001299, 0.0002321, 0.0004149, 0.0007416, 0.001368, 0.002236, 0.004243, 0.00765, 0.01431, 0.02319,
    0.04351, 0.07763, 0.13438, 0.21477, 0.2839, 0.3285, 0.34828, 0.34806, 0.3362, 0.3187, 0.2908, 0.2511,
    0.19536, 0.1421, 0.09564, 0.05795001, 0.03201, 0.0147, 0.0049, 0.0024, 0.0093, 0.0291, 0.06327, 0.1096,
    0.1655, 0.2257499, 0.2904, 0.3597, 0.4334499, 0.5120501, 0.5945, 0.6784, 0.7621, 0.8425, 0.9163, 0.9786,
    1.0263, 1.0567, 1.0622, 1.0456, 1.0026, 0.9384, 0.8544499, 0.7514, 0.6424, 0.5419, 0.4479, 0.3608, 0.2835,
    0.2187, 0.1649, 0.1212, 0.0874, 0.0636, 0.04677, 0.0329, 0.0227, 0.01584, 0.01135916, 0.008110916,
    0.005790346, 0.004109457, 0.002899327, 0.00204919, 0.001439971, 0.0009999493, 0.0006900786, 0.0004760213,
    0.0003323011, 0.0002348261, 0.0001661505, 0.000117413, 8.307527e-05, 5.870652e-05, 4.150994e-05,
    2.935326e-05, 2.067383e-05, 1.455977e-05, 1.025398e-05, 7.221456e-06, 5.085868e-06, 3.581652e-06,
    2.522525e-06, 1.776509e-06, 1.251141e-06,
};
constexpr double kCieY[95] = {
    3.917e-06, 6.965e-06, 1.239e-05, 2.202e-05, 3.9e-05, 6.4e-05, 0.00012, 0.000217, 0.000396, 0.00064,
    0.00121, 0.00218, 0.004, 0.0073, 0.0116, 0.01684, 0.023, 0.0298, 0.038, 0.048, 0.06, 0.0739, 0.09098,
    0.1126, 0.13902, 0.1693, 0.20802, 0.2586, 0.323, 0.4073, 0.503, 0.6082, 0.71, 0.7932, 0.862, 0.9148501,
    0.954, 0.9803, 0.9949501, 1.0, 0.995, 0.9786, 0.952, 0.9154, 0.87, 0.8163, 0.757, 0.6949, 0.631, 0.5668,
    0.503, 0.4412, 0.381, 0.321, 0.265, 0.217, 0.175, 0.1382, 0.107, 0.0816, 0.061, 0.04458, 0.032, 0.0232,
    0.017, 0.01192, 0.00821, 0.005723, 0.004102, 0.002929, 0.002091, 0.001484, 0.001047, 0.00074, 0.00052,
    0.0003611, 0.0002492, 0.0001719, 0.00012, 8.48e-05, 6e-05, 4.24e-05, 3e-05, 2.12e-05, 1.499e-05, 1.06e-05,
    7.4657e-06, 5.2578e-06, 3.7029e-06, 2.6078e-06, 1.8366e-06, 1.2934e-06, 9.1093e-07, 6.4153e-07,
    4.5181e-07,
};
constexpr double kCieZ[95] = {
    0.0006061, 0.001086, 0.001946, 0.003486, 0.006450001, 0.01054999, 0.02005001, 0.03621, 0.06785001, 0.1102,
    0.2074, 0.3713, 0.6456, 1.0390501, 1.3856, 1.62296, 1.74706, 1.7826, 1.77211, 1.7441, 1.6692, 1.5281,
    1.28764, 1.0419, 0.8129501, 0.6162, 0.46518, 0.3533, 0.272, 0.2123, 0.1582, 0.1117, 0.07824999,
    0.05725001, 0.04216, 0.02984, 0.0203, 0.0134, 0.008749999, 0.005749999, 0.0039, 0.002749999, 0.0021,
    0.0018, 0.001650001, 0.0014, 0.0011, 0.001, 0.0008, 0.0006, 0.00034, 0.00024, 0.00019, 0.0001,
    4.999999e-05, 3e-05, 2e-05, 1e-05, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
    0.0, 0.0,
};
constexpr double kD65[95] = {
    46.6383, 49.3637, 52.0891, 51.0323, 49.9755, 52.3118, 54.6482, 68.7015, 82.7549, 87.1204, 91.486, 92.4589,
    93.4318, 90.057, 86.6823, 95.7736, 104.865, 110.936, 117.008, 117.41, 117.812, 116.336, 114.861, 115.392,
    115.923, 112.367, 108.811, 109.082, 109.354, 108.578, 107.802, 106.296, 104.79, 106.239, 107.689, 106.047,
    104.405, 104.225, 104.046, 102.023, 100.0, 98.1671, 96.3342, 96.0611, 95.788, 92.2368, 88.6856, 89.3459,
    90.0062, 89.8026, 89.5991, 88.6489, 87.6987, 85.4936, 83.2886, 83.4939, 83.6992, 81.863, 80.0268, 80.1207,
    80.2146, 81.2462, 82.2778, 80.281, 78.2842, 74.0027, 69.7213, 70.6652, 71.6091, 72.979, 74.349, 67.9765,
    61.604, 65.7448, 69.8856, 72.4863, 75.087, 69.3398, 63.5927, 55.0054, 46.4182, 56.6118, 66.8054, 65.0941,
    63.3828, 63.8434, 64.304, 61.8779, 59.4519, 55.7054, 51.959, 54.6998, 57.4406, 58.8765, 60.3125,
};

constexpr int kLambdaMin = 360, kLambdaMax = 830, kLambdaStep = 5;

// Linear interpolation in one of the 5 nm tables.
double table_at(const double (&t)[95], double lambda) {
  double x = std::clamp((lambda - kLambdaMin) / kLambdaStep, 0.0, 94.0);
  int i = std::min(int(x), 93);
  double f = x - i;
  return t[i] + f * (t[i + 1] - t[i]);
}

// XYZ -> linear sRGB, the sRGB colour space's matrix.
RGB xyz_to_srgb(const dvec3& c) {
  return RGB(float(3.2404542 * c.x - 1.5371385 * c.y - 0.4985314 * c.z),
             float(-0.9692660 * c.x + 1.8760108 * c.y + 0.0415560 * c.z),
             float(0.0556434 * c.x - 0.2040259 * c.y + 1.0572252 * c.z));
}

// The 5 nm tables interpolated at every nanometre, once: the sigmoid fit
// integrates thousands of spectra per colour (values as table_at gives them).
struct NanometreTables {
  static constexpr int kCount = kLambdaMax - kLambdaMin + 1;
  double d65[kCount];
  dvec3 xyz[kCount];
  NanometreTables() {
    for (int l = kLambdaMin; l <= kLambdaMax; ++l) {
      d65[l - kLambdaMin] = table_at(kD65, l);
      xyz[l - kLambdaMin] = dvec3(table_at(kCieX, l), table_at(kCieY, l), table_at(kCieZ, l));
    }
  }
};

// XYZ of r under D65, 1 nm trapezoid sums (pbrt-v4 integrates its 1 nm tables).
dvec3 xyz_under_d65(const SpectrumFn& r) {
  static const NanometreTables t;
  dvec3 sum(0.0);
  for (int l = kLambdaMin; l <= kLambdaMax; ++l) {
    double w = (l == kLambdaMin || l == kLambdaMax) ? 0.5 : 1.0;
    double e = w * t.d65[l - kLambdaMin] * r(l);
    sum += e * t.xyz[l - kLambdaMin];
  }
  return sum;
}

double sigmoid(double y) { return 0.5 + 0.5 * y / std::sqrt(1.0 + y * y); }

dvec3 sigmoid_colour(const std::array<double, 3>& c) {
  SigmoidSpectrum s{c[0], c[1], c[2], 1.0};
  return dvec3(reflectance_srgb_under_d65(s));
}

// Gauss-Newton for the sigmoid coefficients whose colour is `target` (each
// component in (0, 1)), walking from the grey of the same mean to the target
// so that saturated colours stay on the branch that grey starts (as pbrt-v4's
// table optimiser walks out from its centre).
std::array<double, 3> fit_sigmoid(const dvec3& target) {
  double grey = (target.x + target.y + target.z) / 3.0;
  std::array<double, 3> c = {0.0, 0.0, (grey - 0.5) / std::sqrt(grey * (1.0 - grey))};
  constexpr int kSteps = 16;
  for (int step = 1; step <= kSteps; ++step) {
    double t = double(step) / kSteps;
    dvec3 goal = (1.0 - t) * dvec3(grey) + t * target;
    for (int it = 0; it < 30; ++it) {
      dvec3 r = goal - sigmoid_colour(c);
      if (glm::dot(r, r) < 1e-14) break;
      glm::dmat3 J;
      for (int i = 0; i < 3; ++i) {
        std::array<double, 3> hi = c, lo = c;
        hi[i] += 1e-4;
        lo[i] -= 1e-4;
        J[i] = (sigmoid_colour(hi) - sigmoid_colour(lo)) / 2e-4;  // column i
      }
      if (std::abs(glm::determinant(J)) < 1e-300) break;
      dvec3 d = glm::inverse(J) * r;
      for (int i = 0; i < 3; ++i) c[i] += d[i];
    }
  }
  return c;
}

}  // namespace

double SigmoidSpectrum::operator()(double lambda_nm) const {
  double x = (lambda_nm - kLambdaMin) / double(kLambdaMax - kLambdaMin);
  return scale * sigmoid((c0 * x + c1) * x + c2);
}

SigmoidSpectrum rgb_unbounded_spectrum(const RGB& srgb) {
  double m = std::max({srgb.x, srgb.y, srgb.z});
  if (!(m > 0.0)) return {};
  double scale = 2.0 * m;
  dvec3 target = dvec3(srgb) / scale;
  if (srgb.x == srgb.y && srgb.y == srgb.z)  // grey: S(c2) = 1/2 exactly
    return {0.0, 0.0, 0.0, scale};
  // A zero component has no sigmoid (S > 0): take it a hair above zero.
  target = glm::max(target, dvec3(1e-6));
  // The fit integrates thousands of spectra (milliseconds); a scene repeats its
  // colours (every conductor of one metal), so fits are kept by the exact colour.
  static BoundedMemo<std::array<uint32_t, 3>, std::array<double, 3>> fits(4096);
  const std::array<uint32_t, 3> key = {std::bit_cast<uint32_t>(srgb.x), std::bit_cast<uint32_t>(srgb.y),
                                       std::bit_cast<uint32_t>(srgb.z)};
  std::array<double, 3> c = fits.get(key, [&] { return fit_sigmoid(target); });
  return {c[0], c[1], c[2], scale};
}

RGB reflectance_srgb_under_d65(const SpectrumFn& r) {
  static const RGB white = xyz_to_srgb(xyz_under_d65([](double) { return 1.0; }));
  return xyz_to_srgb(xyz_under_d65(r)) / white;
}

namespace {

std::vector<RGB> fresnel_table(const std::vector<float>& e, const std::vector<float>& kk) {
  std::vector<RGB> table(kConductorFresnelTableSize);
  for (int i = 0; i < kConductorFresnelTableSize; ++i) {
    double cos_i = double(i) / (kConductorFresnelTableSize - 1);
    RGB c = reflectance_srgb_under_d65([&](double l) {
      size_t j = size_t(std::clamp(int(std::lround(l)) - kLambdaMin, 0, kLambdaMax - kLambdaMin));
      // eta = k = 0 (a tabulated spectrum that stops short of the visible
      // range is 0 beyond it) has no Fresnel term: the limit of a vanishing
      // index, total reflection, rather than a NaN in every render.
      double f = double(fresnel_complex(float(cos_i), e[j], kk[j]));
      return std::isfinite(f) ? f : 1.0;
    });
    table[size_t(i)] = glm::clamp(srgb_to_working(c), RGB(0.0f), RGB(1.0f));
  }
  return table;
}

}  // namespace

std::vector<RGB> tabulate_conductor_fresnel(const SpectrumFn& eta, const SpectrumFn& k) {
  // Sample eta and k once on the 1 nm grid the projection sums over.
  std::vector<float> e, kk;
  for (int l = kLambdaMin; l <= kLambdaMax; ++l) {
    e.push_back(float(eta(l)));
    kk.push_back(float(k(l)));
  }
  // The table is a function of these samples alone (30,000 complex Fresnel
  // terms), and a scene's conductors share a few metals: kept by the samples'
  // bits (a NaN has no order).
  std::vector<uint32_t> key;
  for (const auto* v : {&e, &kk})
    for (float x : *v) key.push_back(std::bit_cast<uint32_t>(x));
  static BoundedMemo<std::vector<uint32_t>, std::vector<RGB>> tables(256);
  return tables.get(key, [&] { return fresnel_table(e, kk); });
}

RGB lookup_conductor_fresnel(const RGB* table, float cos_theta) {
  float x = std::clamp(cos_theta, 0.0f, 1.0f) * float(kConductorFresnelTableSize - 1);
  int i = std::min(int(x), kConductorFresnelTableSize - 2);
  float f = x - float(i);
  return table[i] + f * (table[i + 1] - table[i]);
}

}  // namespace theia
