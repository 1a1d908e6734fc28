// Real scenes against pbrt-v4 (an independent, spectral renderer) at 256 spp.
//
// tests/data/NAME.exr is pbrt-v4's high-spp reference; kPbrt holds how close
// pbrt-v4's own 256-spp render comes to it (from the references' README).
// theia must reach: relMSE <= 2x pbrt's, 8x8-block relMSE <= max(3x pbrt's,
// 5e-4) (noise averages out there, bias does not), and every channel's mean
// within pbrt's deviation + 0.02 (+ 0.005 for the material sweep).  fog-cornell, dense-glass
// and smoke-grid are the participating-media scenes.  The Cornell box has its own test
// (test_cornell.cpp).  many-lights-city (20,000 one-sided quads, 40,000
// emitting triangles, mostly occluded) relies on cache points, which the
// default `auto` light sampler builds there.  veach-mis relies on the caustic pass (on by default): its tiny
// bright sphere seen in a near-mirror plate, on the diffuse back wall, is a
// caustic that camera paths alone find once in ~3000 samples at ~3000 times
// the pixel's value (9 of 12 seeds meet the bar without the pass, 12 of 12
// with it: tools/error_report.py seeds veach-mis [-- --caustics]).
#include "core/metrics.h"
#include "render_helpers.h"

#include <gtest/gtest.h>

using namespace theia;
using namespace theia::test;

namespace {

struct PbrtYardstick {
  const char* scene;
  double rel_mse, block_rel_mse, mean_deviation;
  double mean_slack = 0.02;  // allowed channel-mean deviation beyond pbrt's own
  bool pbrt_brighter = false;  // pbrt's reference carries its LayeredBxDF bias (below)
  // The default, "auto", is power but for many lights (cache points).
  // smoke-grid: a spot light beside a dim environment.  pbrt-v4's BVH light
  // sampler gives the environment half the samples, as "uniform" does;
  // "power" gives it ~80% (its power over the scene's bounding sphere), which
  // triples the relMSE (0.0034 against 0.00093).
  const char* light_sampler = "auto";
};

// The one-material scenes (scenes/material-sweep/README.md) isolate a BSDF
// each, so they can hold theia to pbrt's mean within 0.005.
constexpr double kSweepSlack = 0.005;
// Except where pbrt-v4's own layered f is wrong: a rough coat over a diffuse
// or rough conductor base, or a medium in the coat.  Against explicit geometry
// (tests/unit/test_layered_truth.cpp) theia's f is right and pbrt-v4's MIS
// weight for a base-sampled exit (scene/README.md) puts its f 4-13% high; with
// that one statement swapped into theia, these four scenes' mean deviations
// fall from 0.0052 / 0.0137 / 0.0062 / 0.0077 to 0.0026 / 0.0060 / 0.0018 /
// 0.0022 and their block relMSE by 4-12x.  So they keep the usual bar, and
// theia must be darker than pbrt-v4 overall, as that bias makes it.
constexpr double kPbrtLayeredBiasSlack = 0.02;

constexpr PbrtYardstick kPbrt[] = {
    {"living-room", 0.0055, 7.6e-5, 0.0003},
    {"many-lights-city", 0.051, 0.00055, 0.0021},
    {"material-testball", 0.0256, 0.00123, 0.0021},
    {"veach-ajar", 0.679, 0.0093, 0.0046},
    {"veach-mis", 0.0359, 0.00066, 0.0122},
    {"material-sweep/coatedconductor", 0.00063971, 7.11768e-06, 0.000201699, kPbrtLayeredBiasSlack, true},
    {"material-sweep/coateddiffuse-colour", 0.000554812, 1.34028e-05, 0.000414782, kPbrtLayeredBiasSlack, true},
    {"material-sweep/coateddiffuse-r0", 0.00116968, 1.97623e-05, 0.000676796, kSweepSlack},
    {"material-sweep/coateddiffuse-r01", 0.000607113, 1.07257e-05, 0.000535317, kPbrtLayeredBiasSlack, true},
    {"material-sweep/coateddiffuse-r03", 0.000525582, 8.08793e-06, 0.000127071, kPbrtLayeredBiasSlack, true},
    {"material-sweep/conductor-cu", 0.000290157, 5.28922e-06, 0.000411302, kSweepSlack},
    {"material-sweep/conductor-grey", 0.000287996, 6.45411e-06, 0.000728189, kSweepSlack},
    {"material-sweep/conductor-reflectance", 0.000244161, 4.09504e-06, 0.000335971, kSweepSlack},
    {"material-sweep/conductor-rgb-rough", 0.000238421, 3.42863e-06, 0.00048372, kSweepSlack},
    {"material-sweep/conductor-rgb-smooth", 0.00111984, 2.42346e-05, 0.000336585, kSweepSlack},
    {"material-sweep/dielectric-rough", 0.00724428, 6.51342e-05, 0.000676642, kSweepSlack},
    {"material-sweep/diffuse-colour", 0.000191741, 2.45521e-06, 0.000161531, kSweepSlack},
    {"material-sweep/diffusetransmission", 0.000457904, 7.54608e-06, 0.000542248, kSweepSlack},
    {"material-sweep/thindielectric", 0.0200866, 0.000219651, 0.00110136, kSweepSlack},
    // Material and texture features, one each (scenes/material-sweep/README.md).
    {"material-sweep/bump", 0.000349133, 5.28947e-06, 0.000460991, kSweepSlack},
    {"material-sweep/normalmap", 0.000333482, 6.46164e-06, 0.000566415, kSweepSlack},
    {"material-sweep/mix-constant", 0.000507187, 8.93222e-06, 0.000382151, kSweepSlack},
    {"material-sweep/mix-textured", 0.000460037, 7.30284e-06, 0.000242768, kSweepSlack},
    {"material-sweep/interface", 9.94021e-05, 1.45641e-06, 0.000255537, kSweepSlack},
    {"material-sweep/interface-in-dielectric", 0.00724433, 6.51296e-05, 0.000676642, kSweepSlack},
    {"material-sweep/hair", 0.00170425, 3.93130e-05, 0.00137279, kSweepSlack},
    // A floor 84 units deep for grazing footprints: "power" would give the sky
    // (its power over that bounding sphere) nearly every light sample, 20x the
    // relMSE; pbrt-v4's BVH sampler gives it half, as "uniform" does.
    {"material-sweep/texture-point", 0.000963397, 1.30504e-05, 0.000405696, kSweepSlack, false, "uniform"},
    {"material-sweep/texture-bilinear", 0.000652189, 1.18697e-05, 0.000593887, kSweepSlack, false, "uniform"},
    {"material-sweep/texture-trilinear", 0.000620583, 1.15955e-05, 0.000574513, kSweepSlack, false, "uniform"},
    {"material-sweep/texture-ewa", 0.000696180, 1.11333e-05, 0.000664161, kSweepSlack, false, "uniform"},
    {"fog-cornell", 0.010, 0.00016, 0.0015},
    {"dense-glass", 0.0063, 0.00010, 0.0013},
    {"smoke-grid", 0.00099, 1.9e-5, 0.00076, 0.02, false, "uniform"},
};

class Validation : public ::testing::TestWithParam<PbrtYardstick> {};

}  // namespace

TEST_P(Validation, MatchesPbrtReferenceAt256spp) {
  const PbrtYardstick& y = GetParam();
  Scene scene = load_test_scene_file(std::string(THEIA_SCENES) + "/" + y.scene + "/scene.pbrt");
  RenderConfig config = quick_config(256);
  config.light_sampler = y.light_sampler;
  RenderResult r = render_scene(scene, config);
  ImageBuffer ref = read_image_file(std::string(THEIA_TEST_DATA) + "/" + y.scene + ".exr");
  ErrorMetrics m = compute_error_metrics(r.image, ref);
  std::printf("%s 256 spp: relMSE %.5f (pbrt %.5f), block relMSE %.2e (pbrt %.2e), mean deviation %.4f (pbrt %.4f), %.1f s\n",
              y.scene, m.rel_mse, y.rel_mse, m.block_rel_mse, y.block_rel_mse, m.channel_mean_deviation,
              y.mean_deviation, r.log["time"]["render"].get<double>());
  EXPECT_LE(m.rel_mse, 2.0 * y.rel_mse);
  EXPECT_LE(m.block_rel_mse, std::max(3.0 * y.block_rel_mse, 5e-4));
  EXPECT_LE(m.channel_mean_deviation, y.mean_deviation + y.mean_slack);
  EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
  if (y.pbrt_brighter) {
    // Summed over R, G, B, theia is darker by more than pbrt's own 256-spp deviation.
    auto rgb_sum = [](const ImageBuffer& im) {
      double sum = 0.0;
      for (int c : im.rgb_channel_indices())
        for (size_t i = 0; i < im.pixel_count(); ++i) sum += im.data[i * im.channels.size() + size_t(c)];
      return sum / double(im.pixel_count());
    };
    double ratio = rgb_sum(r.image) / rgb_sum(ref);
    std::printf("  theia / pbrt over R + G + B: %.4f\n", ratio);
    EXPECT_LT(ratio, 1.0 - y.mean_deviation);
  }
}

INSTANTIATE_TEST_SUITE_P(Scenes, Validation, ::testing::ValuesIn(kPbrt),
                         [](const ::testing::TestParamInfo<PbrtYardstick>& info) {
                           std::string n = info.param.scene;
                           for (char& c : n)
                             if (c == '-' || c == '/') c = '_';
                           return n;
                         });
