// Participating media end to end: a white furnace of an albedo-1 medium
// behind an interface sphere, a chromatic medium against three grey renders,
// determinism across threads and batch sizes, and the features that do not
// handle media switching themselves off.
#include "core/color.h"
#include "core/metrics.h"
#include "render_helpers.h"
#include "wavefront/engine.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

using namespace theia;
using namespace theia::test;

namespace {

// A sphere of radius 1 holding medium "m" behind the interface material,
// seen from 5 away in a constant environment of radiance 1.
std::string medium_sphere_scene(int resolution, const std::string& sigma_a, const std::string& sigma_s, float g,
                                int max_depth) {
  return "Film \"rgb\" \"integer xresolution\" [" + std::to_string(resolution) + "] \"integer yresolution\" [" +
         std::to_string(resolution) + "]\nIntegrator \"volpath\" \"integer maxdepth\" [" + std::to_string(max_depth) +
         "]\nLookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [30]\nWorldBegin\n"
         "LightSource \"infinite\" \"rgb L\" [1 1 1]\n"
         "MakeNamedMedium \"m\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [" + sigma_a + "] \"rgb sigma_s\" [" +
         sigma_s + "] \"float g\" " + std::to_string(g) +
         "\nMediumInterface \"m\" \"\"\nMaterial \"interface\"\nShape \"sphere\" \"float radius\" [1]\n";
}

}  // namespace

// Nothing absorbs: every path leaves the sphere eventually, so every pixel
// (inside the sphere's outline or not) is the environment's 1.  NEE from
// inside the medium reaches the light through the interface surface.
TEST(MediaFurnace, AlbedoOneMediumRendersToOne) {
  Scene scene = load_test_scene(medium_sphere_scene(24, "0 0 0", "3 3 3", 0.5f, 100000));
  RenderResult r = render_scene(scene, quick_config(64));
  RGB mean = image_mean(r.image);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], 1.0f, 0.01f) << "channel " << c;
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(pixel_channel(r.image, 12, 12, c), 1.0f, 0.1f) << "centre, channel " << c;
  EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
}

// Absorption makes the sphere darker than its background; a chromatic
// medium's channel c equals a grey medium's render with channel c's sigmas
// (spectral tracking under one majorant is unbiased per channel).  Channels
// are compared in the working space, where transport runs (the image is
// linear sRGB, a mix of them).
TEST(MediaChromatic, MatchesThreeGreyRenders) {
  const int res = 16, spp = 256;
  Scene chromatic = load_test_scene(medium_sphere_scene(res, "0.2 0.6 1.5", "2.0 1.0 0.3", 0.3f, 1000));
  const RGB c_mean = srgb_to_working(image_mean(render_scene(chromatic, quick_config(spp)).image));
  const Medium m = chromatic.media.at(0);
  ASSERT_GT(max_component(m.sigma_s) - std::min({m.sigma_s.x, m.sigma_s.y, m.sigma_s.z}), 0.5f);
  for (int c = 0; c < 3; ++c) {
    Scene grey = chromatic;
    grey.media[0].sigma_a = RGB(m.sigma_a[c]);
    grey.media[0].sigma_s = RGB(m.sigma_s[c]);
    RenderResult r = render_scene(grey, quick_config(spp));
    const float g_mean = image_mean(r.image)[c];
    EXPECT_LT(g_mean, 0.95f) << "the medium should absorb some light, channel " << c;
    EXPECT_NEAR(c_mean[c], g_mean, 0.01f * g_mean) << "channel " << c;
  }
}

TEST(MediaDeterminism, IndependentOfThreadsAndBatchSize) {
  Scene scene = load_test_scene(medium_sphere_scene(24, "0.1 0.2 0.3", "1 1 1", 0.3f, 64));
  RenderConfig a = quick_config(8), b = quick_config(8);
  a.threads = 1;
  a.batch_size = 1024;
  a.max_paths = 4096;
  b.threads = 2;
  RenderResult ra = render_scene(scene, a), rb = render_scene(scene, b);
  EXPECT_LT(max_relative_difference(ra.image, rb.image), 1e-4);
}

// The caustic pass does not handle media: asked for, it is off and the log
// says why.  Guiding runs (its recorder records in-medium vertices).
TEST(MediaFeatures, GuidingRunsAndCausticsSwitchOff) {
  Scene scene = load_test_scene(medium_sphere_scene(8, "0.1 0.1 0.1", "1 1 1", 0.0f, 16));
  RenderConfig c = quick_config(4);
  c.guiding.enabled = OnOffAuto::On;
  RenderResult r = render_scene(scene, c);
  EXPECT_NE(r.log["caustics"]["off_because"].get<std::string>().find("participating media"), std::string::npos);
  EXPECT_GT(r.log["recorder"]["recorded_vertices"].get<uint64_t>(), 0u);
  EXPECT_EQ(r.log["options"]["guiding"].get<std::string>(), "on");
}

// The medium stage traces a ray past an interface itself, outside the
// batches: those traces count as continuation rays and enter the capture.
// Behind a clear medium's interface sphere nothing scatters or is shaded, so
// every traced ray that hits the sphere is followed by exactly one re-trace
// (a camera ray's crossing in, then its crossing out), and there are no others.
TEST(MediaRayCounts, ReTracesPastInterfacesAreCountedAndCaptured) {
  Scene scene = load_test_scene(medium_sphere_scene(16, "0 0 0", "0 0 0", 0.0f, 8));
  RenderableScene rs(scene);
  Film film(scene.film.width, scene.film.height);
  EngineOptions opt;
  std::vector<Ray> rays, shadow_rays;
  opt.capture_rays = &rays;
  opt.capture_shadow_rays = &shadow_rays;
  WavefrontEngine engine(rs, film, opt);
  engine.render(0, 4);
  const EngineStats& st = engine.stats();
  EXPECT_EQ(rays.size(), st.camera_rays + st.continuation_rays);
  EXPECT_EQ(shadow_rays.size(), st.shadow_rays);
  const uint64_t hitting = uint64_t(std::count_if(rays.begin(), rays.end(), [&](const Ray& r) {
    return rs.accel.intersect1(r).hit();
  }));
  EXPECT_GT(hitting, 0u);
  EXPECT_EQ(st.continuation_rays, hitting);
  EXPECT_EQ(st.total_rays(), rays.size() + shadow_rays.size());
}

// ---------------------------------------------------------------- guiding in media

namespace {

RenderConfig guided_config(int spp, uint32_t seed = 0) {
  RenderConfig c = quick_config(spp);
  c.guiding.enabled = OnOffAuto::On;
  c.seed = seed;
  return c;
}

Scene fog_cornell(int res) {
  Scene s = load_test_scene_file(std::string(THEIA_SCENES) + "/fog-cornell/scene.pbrt");
  s.film.width = s.film.height = res;
  return s;
}

}  // namespace

// Behind an interface sphere every vertex is a medium vertex: the field
// learns from in-medium samples alone and guides phase-function sampling,
// which changes every path (the image differs sample for sample) and keeps
// the furnace at 1.
TEST(MediaGuiding, FurnaceStaysOneWhenGuided) {
  Scene scene = load_test_scene(medium_sphere_scene(24, "0 0 0", "3 3 3", 0.5f, 100000));
  for (const char* sampling : {"ris", "mis"}) {
    RenderConfig c = guided_config(64);
    c.guiding.sampling = sampling;
    RenderResult r = render_scene(scene, c);
    RGB mean = image_mean(r.image);
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(mean[ch], 1.0f, 0.01f) << sampling << ", channel " << ch;
    EXPECT_GT(r.log["guiding"]["spatial_leaves"].get<uint64_t>(), 1u) << sampling;
    EXPECT_GT(r.log["recorder"]["samples"].get<uint64_t>(), 0u) << sampling;
    EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
    RenderConfig plain = quick_config(64);
    plain.schedule = "guiding";
    EXPECT_GT(max_relative_difference(r.image, render_scene(scene, plain).image), 1e-3) << sampling;
  }
}

// fog-cornell guided against unguided at equal spp: the channel means agree,
// and the 8x8-block error between them is what two unbiased renders show:
// the sum of their variances, each estimated from two seeds of its own
// (guiding in fog is noisier than unguided, so the unguided pair alone is
// not the yardstick; a bias adds to the error and to neither pair).
TEST(MediaGuiding, FogCornellAgreesWithUnguided) {
  Scene scene = fog_cornell(32);
  RenderConfig unguided = quick_config(256), other_seed = quick_config(256);
  unguided.schedule = other_seed.schedule = "guiding";
  other_seed.seed = 1;
  RenderConfig guided_other = guided_config(256);
  guided_other.seed = 1;
  const ImageBuffer a = render_scene(scene, unguided).image, b = render_scene(scene, other_seed).image;
  const ImageBuffer guided = render_scene(scene, guided_config(256)).image;
  const ImageBuffer guided_b = render_scene(scene, guided_other).image;
  const RGB ma = image_mean(a), mg = image_mean(guided);
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(mg[ch], ma[ch], 0.015f * ma[ch]) << "channel " << ch;
  const double noise_unguided = block_rel_mse(b, a, 8), noise_guided = block_rel_mse(guided_b, guided, 8);
  const double expected = 0.5 * (noise_unguided + noise_guided), err = block_rel_mse(guided, a, 8);
  std::printf("fog-cornell 32x32 256 spp: block relMSE guided vs unguided %.3g; seed pairs: unguided %.3g, guided %.3g\n",
              err, noise_unguided, noise_guided);
  EXPECT_LT(err, 3.0 * expected) << "guided vs unguided " << err << ", expected from the seed pairs " << expected;
}

// Training from in-medium samples is as deterministic as from surface ones:
// one thread and small batches, or two, make the same image.
TEST(MediaGuiding, ImageIndependentOfThreadCount) {
  const Scene scene = fog_cornell(24);
  std::vector<ImageBuffer> images;
  for (int threads : {1, 2}) {
    RenderConfig c = guided_config(24);
    c.threads = threads;
    if (threads == 1) c.batch_size = 2048;
    images.push_back(render_scene(scene, c).image);
  }
  EXPECT_LT(max_relative_difference(images[0], images[1]), 1e-4);
}

// ---------------------------------------------------------------- extreme cases

namespace {

// The camera inside an unbounded emissive medium of albedo a (nothing else in
// the scene).  A path's k-th segment is reached with throughput a^k and
// gathers (1 - a) Le on average; pbrt-v4 gathers emission below the depth
// limit D only, so L = Le (1 - a^D) exactly.
std::string emissive_fog_scene(float sigma_a, float sigma_s, int max_depth) {
  return "Film \"rgb\" \"integer xresolution\" [8] \"integer yresolution\" [8]\n"
         "Integrator \"volpath\" \"integer maxdepth\" [" + std::to_string(max_depth) + "]\n"
         "MakeNamedMedium \"glow\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [" + std::to_string(sigma_a) + " " +
         std::to_string(sigma_a) + " " + std::to_string(sigma_a) + "] \"rgb sigma_s\" [" + std::to_string(sigma_s) +
         " " + std::to_string(sigma_s) + " " + std::to_string(sigma_s) +
         "] \"rgb Le\" [1 1 1] \"float g\" 0.9\nMediumInterface \"\" \"glow\"\n"
         "Camera \"perspective\"\nWorldBegin\n";
}

struct PixelStats {
  double mean = 0.0, sd_of_mean = 0.0;  // over the pixels' red channel
};
PixelStats emissive_fog(float sigma_a, float sigma_s, int max_depth, int resolution, int spp) {
  Scene scene = load_test_scene(emissive_fog_scene(sigma_a, sigma_s, max_depth));
  scene.film.width = scene.film.height = resolution;
  RenderResult r = render_scene(scene, quick_config(spp));
  EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
  double sum = 0.0, sum2 = 0.0;
  const int n = resolution * resolution;
  for (int y = 0; y < resolution; ++y)
    for (int x = 0; x < resolution; ++x) {
      const double v = pixel_channel(r.image, x, y, 0);
      sum += v, sum2 += v * v;
    }
  PixelStats s;
  s.mean = sum / n;
  s.sd_of_mean = std::sqrt(std::max(0.0, sum2 / n - s.mean * s.mean) / n);
  return s;
}

}  // namespace

TEST(ExtremeMedia, EmissiveFogCountsDepthAsPbrt) {
  // a = 0.5, D = 3: 1 - 1/8.
  PixelStats s = emissive_fog(0.5f, 0.5f, 3, 8, 64);
  EXPECT_NEAR(s.mean, 0.875, 4.5 * s.sd_of_mean + 1e-4);
}

// Albedo 0.999: about a thousand scattering events per path.  At depth
// 1000 the limit shows (1 - 0.999^1000 = 0.632); at depth 10000 the paths
// end by absorption first (1 - 4.5e-5), with throughput products that stay 1.
TEST(ExtremeMedia, AlbedoPoint999AgainstClosedForm) {
  for (int depth : {1000, 10000}) {
    PixelStats s = emissive_fog(0.001f, 0.999f, depth, 16, 16);
    const double expected = 1.0 - std::pow(0.999, double(depth));
    EXPECT_NEAR(s.mean, expected, 4.5 * s.sd_of_mean) << "depth " << depth;
    EXPECT_LT(s.sd_of_mean, 0.03) << "depth " << depth;
  }
}

// Coefficients from 1e-6 to 1e4 behind the interface sphere, g = +-0.999:
// finite images, nothing dropped; the thinnest medium is the environment's 1.
TEST(ExtremeMedia, SigmaRangeAndExtremeG) {
  for (const char* sigma : {"0 0 0", "1e-6 1e-6 1e-6", "1e4 1e4 1e4"}) {
    for (float g : {-0.999f, 0.999f}) {
      Scene scene = load_test_scene(medium_sphere_scene(8, "0 0 0", sigma, g, 64));
      RenderResult r = render_scene(scene, quick_config(4));
      EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u) << sigma << " g " << g;
      const RGB mean = image_mean(r.image);
      EXPECT_TRUE(std::isfinite(mean.x) && std::isfinite(mean.y) && std::isfinite(mean.z));
      if (std::string(sigma) != "1e4 1e4 1e4") {
        EXPECT_NEAR(mean.x, 1.0f, 1e-3f) << sigma << " g " << g;
      }
    }
  }
}

// The same absorbing medium sphere at scales 1e-4 and 1e5 (coefficients
// divided by the scale, so optical depths are unchanged) renders the image
// it renders at scale 1: ray offsets and tracking distances hold at both ends.
TEST(ExtremeMedia, HugeAndTinySceneScales) {
  auto mean_at = [](double k) {
    auto num = [](double v) { return fmt::format("{:.9g}", v); };
    const std::string sa = num(0.5 / k), ss = num(2.0 / k);
    Scene scene = load_test_scene(
        "Film \"rgb\" \"integer xresolution\" [16] \"integer yresolution\" [16]\n"
        "Integrator \"volpath\" \"integer maxdepth\" [200]\n"
        "LookAt 0 0 " + num(-5 * k) + "  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [30]\nWorldBegin\n"
        "LightSource \"infinite\" \"rgb L\" [1 1 1]\n"
        "MakeNamedMedium \"m\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [" + sa + " " + sa + " " + sa +
        "] \"rgb sigma_s\" [" + ss + " " + ss + " " + ss + "] \"float g\" 0.3\n"
        "MediumInterface \"m\" \"\"\nMaterial \"interface\"\nShape \"sphere\" \"float radius\" [" + num(k) + "]\n");
    RenderResult r = render_scene(scene, quick_config(64));
    EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u) << "scale " << k;
    return image_mean(r.image).x;
  };
  const float unit = mean_at(1.0);
  EXPECT_LT(unit, 0.9f) << "the sphere should absorb";
  for (double k : {1e-4, 1e5}) EXPECT_NEAR(mean_at(k), unit, 0.01f) << "scale " << k;
}
