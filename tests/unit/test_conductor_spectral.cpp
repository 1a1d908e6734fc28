// Conductors from spectral eta and k (scene/conductor_spectral.h): the RGB
// upsampling, the projection under D65, and the tabulated reflectance the
// renderer evaluates, against a per-wavelength Fresnel evaluation written here.
#include "core/color.h"
#include "scene/bxdfs.h"
#include "scene/conductor_spectral.h"
#include "scene/parser.h"
#include "scene/spectrum.h"

#include <gtest/gtest.h>

#include <complex>
#include <string>

using namespace theia;

namespace {

// The complex Fresnel reflectance of a conductor, unpolarised, in double
// precision (Born & Wolf; the test's own, not microfacet.h's).
double fresnel_conductor(double cos_i, double eta, double k) {
  using C = std::complex<double>;
  C n(eta, k);
  C cos_t = std::sqrt(C(1.0) - (1.0 - cos_i * cos_i) / (n * n));
  C rs = (cos_i - n * cos_t) / (cos_i + n * cos_t);
  C rp = (n * cos_i - cos_t) / (n * cos_i + cos_t);
  return 0.5 * (std::norm(rs) + std::norm(rp));
}

// What pbrt-v4's film records for the conductor under a white light: the
// per-wavelength reflectance projected to linear sRGB, as a working-space colour.
RGB spectral_reflectance(const SpectrumFn& eta, const SpectrumFn& k, double cos_i) {
  return srgb_to_working(reflectance_srgb_under_d65([&](double l) { return fresnel_conductor(cos_i, eta(l), k(l)); }));
}

const Material& only_material(const Scene& s) {
  EXPECT_FALSE(s.materials.empty());
  return s.materials.back();
}

Scene scene_with(const std::string& material) {
  return parse_scene_string("WorldBegin\nMaterial " + material + "\nShape \"sphere\"\n", "<test>", ".");
}

// The largest relative difference, per channel, between the renderer's Fresnel
// (the material's table through conductor_fresnel) and the spectral one, over
// cos theta in (0, 1].
RGB worst_relative_error(const Material& m, const SpectrumFn& eta, const SpectrumFn& k) {
  ConductorBxDF c;
  c.fresnel_table = m.conductor_fresnel.data();
  RGB worst(0.0f);
  for (int i = 1; i <= 200; ++i) {
    double cos_i = i / 200.0;
    RGB want = spectral_reflectance(eta, k, cos_i);
    RGB got = conductor_fresnel(float(cos_i), c);
    worst = glm::max(worst, glm::abs(got / want - RGB(1.0f)));
  }
  return worst;
}

SpectrumFn named(const char* name) {
  const NamedSpectrum* s = find_named_spectrum(name);
  EXPECT_NE(s, nullptr) << name;
  return [s](double l) { return double(spectrum_at(s->lambda, s->value, float(l))); };
}

}  // namespace

TEST(SpectrumUpsampling, UnboundedRgbRoundTripsThroughD65) {
  for (RGB c : {RGB(0.2f, 0.9f, 1.1f), RGB(3.9f, 2.4f, 1.6f), RGB(0.05f, 0.3f, 0.8f), RGB(1.0f, 0.02f, 0.4f)}) {
    SigmoidSpectrum s = rgb_unbounded_spectrum(c);
    EXPECT_FLOAT_EQ(float(s.scale), 2.0f * std::max({c.x, c.y, c.z}));
    RGB back = reflectance_srgb_under_d65(s);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(back[i], c[i], 1e-4f * s.scale) << i;
    for (int l = 360; l <= 830; l += 10) {
      EXPECT_GT(s(l), 0.0);
      EXPECT_LT(s(l), s.scale);
    }
  }
  SigmoidSpectrum grey = rgb_unbounded_spectrum(RGB(1.5f));
  for (int l = 360; l <= 830; l += 10) EXPECT_DOUBLE_EQ(grey(l), 1.5);
}

TEST(SpectrumUpsampling, D65ProjectionKeepsGreysAndAgreesWithTheReflectanceConversion) {
  RGB white = reflectance_srgb_under_d65([](double) { return 1.0; });
  RGB grey = reflectance_srgb_under_d65([](double) { return 0.3; });
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(white[i], 1.0f, 1e-6f);
    EXPECT_NEAR(grey[i], 0.3f, 1e-6f);
  }
  // A smooth spectrum seen under D65 with the tabulated observer, and under an
  // equal-energy white with spectrum.h's fitted observer: close, not equal.
  const NamedSpectrum* cu = find_named_spectrum("metal-Cu-k");
  RGB a = reflectance_srgb_under_d65(named("metal-Cu-k"));
  RGB b = spectrum_to_rgb_reflectance(cu->lambda, cu->value);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(a[i] / b[i], 1.0f, 0.03f) << i;
}

TEST(SpectrumConductor, RgbEtaAndKMatchPerWavelengthFresnelWithinHalfAPercent) {
  Scene s = scene_with("\"conductor\" \"rgb eta\" [0.2 0.9 1.1] \"rgb k\" [3.9 2.4 1.6]");
  const Material& m = only_material(s);
  ASSERT_EQ(m.conductor_fresnel.size(), size_t(kConductorFresnelTableSize));
  SigmoidSpectrum eta = rgb_unbounded_spectrum(RGB(0.2f, 0.9f, 1.1f));
  SigmoidSpectrum k = rgb_unbounded_spectrum(RGB(3.9f, 2.4f, 1.6f));
  RGB err = worst_relative_error(m, eta, k);
  for (int i = 0; i < 3; ++i) EXPECT_LT(err[i], 0.005f) << "channel " << i;

  // Per-band Fresnel (what theia did before) misses red by several percent at
  // normal incidence: the comparison above can fail.
  ConductorBxDF per_band{{}, RGB(0.2f, 0.9f, 1.1f), RGB(3.9f, 2.4f, 1.6f)};
  RGB want = spectral_reflectance(eta, k, 1.0);
  EXPECT_GT(std::abs(conductor_fresnel(1.0f, per_band).x / want.x - 1.0f), 0.02f);
}

TEST(SpectrumConductor, NamedMetalsMatchPerWavelengthFresnelWithinHalfAPercent) {
  for (const char* metal : {"Cu", "Au", "Ag", "Al"}) {
    std::string e = std::string("metal-") + metal + "-eta", k = std::string("metal-") + metal + "-k";
    Scene s = scene_with("\"conductor\" \"spectrum eta\" \"" + e + "\" \"spectrum k\" \"" + k + "\"");
    const Material& m = only_material(s);
    ASSERT_EQ(m.conductor_fresnel.size(), size_t(kConductorFresnelTableSize)) << metal;
    RGB err = worst_relative_error(m, named(e.c_str()), named(k.c_str()));
    for (int i = 0; i < 3; ++i) EXPECT_LT(err[i], 0.005f) << metal << " channel " << i;
  }
  // No eta and k: pbrt-v4's default, copper.
  RGB err = worst_relative_error(only_material(scene_with("\"conductor\"")), named("metal-Cu-eta"), named("metal-Cu-k"));
  for (int i = 0; i < 3; ++i) EXPECT_LT(err[i], 0.005f) << i;
}

TEST(SpectrumConductor, CoatedConductorTableIsRelativeToTheCoat) {
  Scene s = scene_with(
      "\"coatedconductor\" \"float interface.eta\" [1.33] \"spectrum conductor.eta\" \"metal-Au-eta\" "
      "\"spectrum conductor.k\" \"metal-Au-k\"");
  const Material& m = only_material(s);
  ASSERT_EQ(m.conductor_fresnel.size(), size_t(kConductorFresnelTableSize));
  SpectrumFn eta = named("metal-Au-eta"), k = named("metal-Au-k");
  RGB err = worst_relative_error(m, [&](double l) { return eta(l) / 1.33; }, [&](double l) { return k(l) / 1.33; });
  for (int i = 0; i < 3; ++i) EXPECT_LT(err[i], 0.005f) << i;
}

TEST(SpectrumConductor, GreyAndTexturedConstantsKeepPerBandFresnel) {
  // Constant spectra: per-band Fresnel is exact and images stay as they were.
  EXPECT_TRUE(only_material(scene_with("\"conductor\" \"rgb eta\" [1.5 1.5 1.5] \"rgb k\" [3 3 3]"))
                  .conductor_fresnel.empty());
  EXPECT_TRUE(only_material(scene_with("\"conductor\" \"rgb reflectance\" [0.9 0.6 0.3]")).conductor_fresnel.empty());
  Scene t = parse_scene_string(
      "WorldBegin\nTexture \"e\" \"spectrum\" \"constant\" \"rgb value\" [0.2 0.9 1.1]\n"
      "Material \"conductor\" \"texture eta\" \"e\" \"rgb k\" [3.9 2.4 1.6]\nShape \"sphere\"\n",
      "<test>", ".");
  EXPECT_TRUE(only_material(t).conductor_fresnel.empty());
}

TEST(SpectrumConductor, SpectraShorterThanTheVisibleRangeGiveAFiniteTable) {
  // Zero beyond 500-600 nm: eta = k = 0 there.
  Scene s = scene_with("\"conductor\" \"spectrum eta\" [500 0.5 600 1.0] \"spectrum k\" [500 3 600 2]");
  const Material& m = only_material(s);
  ASSERT_EQ(m.conductor_fresnel.size(), size_t(kConductorFresnelTableSize));
  for (const RGB& c : m.conductor_fresnel)
    for (int i = 0; i < 3; ++i) {
      EXPECT_TRUE(std::isfinite(c[i]));
      EXPECT_GE(c[i], 0.0f);
      EXPECT_LE(c[i], 1.0f);
    }
}

// Fits and Fresnel tables are kept by their exact arguments (core/memo.h): a
// second call returns the first's result bit for bit, and a call with other
// arguments in between is not served another's result.
TEST(SpectrumConductor, KeptFitsAndTablesBelongToTheirOwnArguments) {
  const RGB a(0.2f, 0.9f, 1.1f), b(0.21f, 0.9f, 1.1f);
  const SigmoidSpectrum fa = rgb_unbounded_spectrum(a), fb = rgb_unbounded_spectrum(b), fa2 = rgb_unbounded_spectrum(a);
  EXPECT_EQ(fa.c0, fa2.c0);
  EXPECT_EQ(fa.c1, fa2.c1);
  EXPECT_EQ(fa.c2, fa2.c2);
  EXPECT_NE(fa.c0, fb.c0);
  const RGB back = reflectance_srgb_under_d65(fb);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(back[i], b[i], 1e-4f * fb.scale) << i;

  const SpectrumFn eta = named("metal-Au-eta"), k1 = named("metal-Au-k");
  const SpectrumFn k2 = [&](double l) { return 0.5 * k1(l); };
  const std::vector<RGB> t1 = tabulate_conductor_fresnel(eta, k1), t2 = tabulate_conductor_fresnel(eta, k2),
                         t1_again = tabulate_conductor_fresnel(eta, k1);
  EXPECT_EQ(t1, t1_again);
  ASSERT_EQ(t2.size(), size_t(kConductorFresnelTableSize));
  // The half-k table is its own: it matches its spectral reflectance at normal incidence.
  const RGB want = spectral_reflectance(eta, k2, 1.0);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(t2.back()[i], want[i], 5e-3f * want[i]) << i;
    EXPECT_GT(std::abs(t1.back()[i] - t2.back()[i]), 0.01f) << i;
  }
}
