// --aov-events: the beauty split by each camera path's first scattering
// event (wavefront/film.h PathEvent).  The layers sum to the beauty (every
// splat, the shadow rays' and the caustic pass's included, lands in exactly
// one), a mirror's paths land in `specular` and a Lambertian's in `diffuse`,
// and guiding leaves each layer's mean where BSDF sampling puts it
// (seeds/000 ch. 1 section 6).  Resume and split-merge exactness are in
// test_resume.cpp and test_split.cpp.
#include "render_helpers.h"
#include "wavefront/film.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

using namespace theia;
using namespace theia::test;

namespace {

const char* const kLayers[] = {"emission", "diffuse", "glossy", "specular", "volume"};

// The value of channel NAME.{R,G,B}[c] at (x, y).
float layer(const ImageBuffer& img, const std::string& name, int x, int y, int c) {
  const int k = img.channel_index(name + "." + "RGB"[c]);
  EXPECT_GE(k, 0) << name;
  return k < 0 ? 0.0f : pixel_channel(img, x, y, k);
}

// Largest |sum of layers - beauty| over pixels and channels, relative to
// the larger of the beauty and the layers' absolute sum (floored).
double worst_layer_sum_error(const ImageBuffer& img) {
  double worst = 0.0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      for (int c = 0; c < 3; ++c) {
        double sum = 0.0, abs_sum = 0.0;
        for (const char* l : kLayers) {
          sum += layer(img, l, x, y, c);
          abs_sum += std::abs(layer(img, l, x, y, c));
        }
        const double beauty = pixel_channel(img, x, y, c);
        worst = std::max(worst, std::abs(sum - beauty) / std::max({std::abs(beauty), abs_sum, 1e-4}));
      }
  return worst;
}

// Mean of one layer channel over the image.
double layer_mean(const ImageBuffer& img, const std::string& name, int c) {
  double s = 0.0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) s += layer(img, name, x, y, c);
  return s / double(img.width * img.height);
}

RenderResult render_events(const Scene& scene, int spp, uint32_t seed = 0) {
  RenderConfig c = quick_config(spp);
  c.aov_events = true;
  c.seed = seed;
  return render_scene(scene, c);
}

Scene scene_file(const std::string& name, int width, int height) {
  Scene s = load_test_scene_file(std::string(THEIA_SCENES) + "/" + name + "/scene.pbrt");
  s.film.width = width;
  s.film.height = height;
  return s;
}

// A sphere of `material` in a white environment, filling most of the frame.
std::string sphere_in_environment(const std::string& material) {
  return R"(Film "rgb" "integer xresolution" [24] "integer yresolution" [24]
Integrator "volpath" "integer maxdepth" [8]
LookAt 0 0 -5  0 0 0  0 1 0
Camera "perspective" "float fov" [30]
WorldBegin
LightSource "infinite" "rgb L" [1 1 1]
Material )" + material + R"(
Shape "sphere" "float radius" [1]
)";
}

}  // namespace

// The scenes cover surface NEE and emission hits (cornell-box), a coated
// diffuse's specular and glossy events and an environment (material-testball),
// media (fog-cornell), and the caustic pass's splats (a mirror room).
TEST(AovEvents, LayersSumToTheBeauty) {
  struct Case {
    std::string name;
    Scene scene;
    int spp;
    const char* nonzero;  // a layer the scene must fill
  };
  std::vector<Case> cases;
  cases.push_back({"cornell-box", scene_file("cornell-box", 32, 32), 16, "diffuse"});
  cases.push_back({"material-testball", scene_file("material-testball", 48, 27), 16, "glossy"});
  cases.push_back({"fog-cornell", scene_file("fog-cornell", 24, 24), 8, "volume"});
  cases.push_back({"mirror room (caustic pass)", load_test_scene(mirror_room_scene(32, 24, 0.02f)), 16, "diffuse"});
  for (const Case& k : cases) {
    SCOPED_TRACE(k.name);
    RenderResult r = render_events(k.scene, k.spp);
    for (const char* l : kLayers) EXPECT_GE(r.image.channel_index(std::string(l) + ".R"), 0) << l;
    EXPECT_LT(worst_layer_sum_error(r.image), 1e-5);
    EXPECT_GT(layer_mean(r.image, k.nonzero, 1), 0.0);
    EXPECT_EQ(r.log["aov_event_layers"].size(), 5u);
    if (k.name.starts_with("mirror")) {
      EXPECT_GT(r.log["caustics"]["splats"].get<uint64_t>(), 0u) << r.log["caustics"];
    }
  }
}

// The camera sees the sphere or the environment: a mirror's paths are all
// `specular`, a Lambertian's all `diffuse`, a rough metal's all `glossy`;
// the environment seen directly is `emission`, and nothing else is filled.
TEST(AovEvents, MirrorPathsAreSpecularLambertianPathsDiffuse) {
  struct Case {
    std::string material;
    const char* layer;
  };
  const Case cases[] = {
      {R"("conductor" "float roughness" [0] "rgb eta" [0.2 0.9 1.1] "rgb k" [3.9 2.4 2.1])", "specular"},
      {R"("diffuse" "rgb reflectance" [0.5 0.5 0.5])", "diffuse"},
      {R"("conductor" "float roughness" [0.4] "rgb eta" [0.2 0.9 1.1] "rgb k" [3.9 2.4 2.1])", "glossy"}};
  for (const Case& k : cases) {
    SCOPED_TRACE(k.layer);
    RenderResult r = render_events(load_test_scene(sphere_in_environment(k.material)), 8);
    const ImageBuffer& img = r.image;
    int on_sphere = 0;
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x) {
        const bool hit = pixel_channel(img, x, y, 3) == 1.0f;  // every sample saw the sphere
        const bool miss = pixel_channel(img, x, y, 3) == 0.0f;
        on_sphere += hit;
        for (const char* l : kLayers)
          for (int c = 0; c < 3; ++c) {
            const float v = layer(img, l, x, y, c);
            if (l == std::string(k.layer)) {
              if (hit) { EXPECT_GT(v, 0.0f) << x << "," << y; }
              if (miss) { EXPECT_EQ(v, 0.0f) << x << "," << y; }
            } else if (l == std::string("emission")) {
              if (hit) { EXPECT_EQ(v, 0.0f) << x << "," << y; }
              if (miss) { EXPECT_NEAR(v, pixel_channel(img, x, y, c), 1e-6f) << x << "," << y; }
            } else {
              EXPECT_EQ(v, 0.0f) << l << " " << x << "," << y;
            }
          }
      }
    EXPECT_GT(on_sphere, 100);
  }
}

// A diffuse room lit by a small area light and an environment through its
// open side, with a rough metal sphere (glossy, guided) and a mirror sphere
// (specular, never guided) on its diffuse floor (guided).
std::string three_kinds_room() {
  return R"(Film "rgb" "integer xresolution" [48] "integer yresolution" [32]
Integrator "volpath" "integer maxdepth" [8]
LookAt 0 1.5 -6  0 0.8 0  0 1 0
Camera "perspective" "float fov" [45]
WorldBegin
LightSource "infinite" "rgb L" [0.3 0.3 0.35]
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [12 12 12]
  Material "diffuse" "rgb reflectance" [0 0 0]
  Shape "trianglemesh" "point3 P" [-0.5 2.99 -0.5  0.5 2.99 -0.5  0.5 2.99 0.5  -0.5 2.99 0.5] "integer indices" [0 1 2 0 2 3]
AttributeEnd
Material "diffuse" "rgb reflectance" [0.6 0.55 0.5]
Shape "trianglemesh" "point3 P" [-3 0 -8  3 0 -8  3 0 3  -3 0 3] "integer indices" [0 2 1 0 3 2]
Shape "trianglemesh" "point3 P" [-3 3 -8  3 3 -8  3 3 3  -3 3 3] "integer indices" [0 1 2 0 2 3]
Shape "trianglemesh" "point3 P" [-3 0 3  3 0 3  3 3 3  -3 3 3] "integer indices" [0 1 2 0 2 3]
Material "diffuse" "rgb reflectance" [0.6 0.2 0.2]
Shape "trianglemesh" "point3 P" [-3 0 -8  -3 0 3  -3 3 3  -3 3 -8] "integer indices" [0 1 2 0 2 3]
AttributeBegin
  Translate -0.9 0.7 0.5
  Material "conductor" "float roughness" [0.3] "bool remaproughness" false "rgb eta" [0.2 0.9 1.1] "rgb k" [3.9 2.4 2.1]
  Shape "sphere" "float radius" [0.7]
AttributeEnd
AttributeBegin
  Translate 0.9 0.7 0.2
  Material "conductor" "float roughness" [0] "rgb eta" [0.2 0.9 1.1] "rgb k" [3.9 2.4 2.1]
  Shape "sphere" "float radius" [0.7]
AttributeEnd
)";
}

// Guided directions are labelled as BSDF sampling labels them: each layer's
// mean, and its blocks, agree between unguided and guided renders (RIS and
// one-sample MIS with a fixed and a learned share) within their noise.
TEST(AovEvents, GuidingKeepsEachLayersMean) {
  const Scene scene = load_test_scene(three_kinds_room());
  const int spp = 128;
  auto render = [&](const char* sampling) {
    RenderConfig c = quick_config(spp);
    c.aov_events = true;
    c.seed = 7;
    if (sampling) {
      c.guiding.enabled = OnOffAuto::On;
      c.guiding.sampling = sampling;
    }
    RenderResult r = render_scene(scene, c);
    if (sampling) {
      EXPECT_GT(r.log["guiding"]["spatial_leaves"].get<uint64_t>(), 1u);
    }
    return r.image;
  };
  const ImageBuffer plain = render(nullptr);
  for (const char* sampling : {"ris", "mis", "mis-learned"}) {
    SCOPED_TRACE(sampling);
    const ImageBuffer guided = render(sampling);
    for (const char* l : {"emission", "diffuse", "glossy", "specular"}) {
      SCOPED_TRACE(l);
      // Block means (8x8) of the layer: the z of their differences, and the
      // image mean's z from the blocks' standard errors.
      int worse = 0, blocks = 0;
      double chi2 = 0.0, diff = 0.0, var = 0.0, mean_plain = 0.0;
      for (int by = 0; by < 32; by += 8)
        for (int bx = 0; bx < 48; bx += 8)
          for (int c = 0; c < 3; ++c) {
            double sa = 0.0, sa2 = 0.0, sb = 0.0, sb2 = 0.0;
            for (int y = by; y < by + 8; ++y)
              for (int x = bx; x < bx + 8; ++x) {
                const double a = layer(plain, l, x, y, c), b = layer(guided, l, x, y, c);
                sa += a, sa2 += a * a, sb += b, sb2 += b * b;
              }
            const double ma = sa / 64, mb = sb / 64;
            const double va = std::max(0.0, sa2 / 64 - ma * ma) / 64, vb = std::max(0.0, sb2 / 64 - mb * mb) / 64;
            const double sigma = std::sqrt(va + vb) + 1e-4 * std::abs(ma) + 1e-7;
            const double z = (mb - ma) / sigma;
            chi2 += z * z;
            worse += std::abs(z) > 4.0;
            ++blocks;
            diff += mb - ma;
            var += va + vb;
            mean_plain += ma;
          }
      std::printf("%s %-8s mean unguided %.5f guided %.5f (z %.2f), block chi2/n %.2f\n", sampling, l,
                  mean_plain / blocks, (mean_plain + diff) / blocks, diff / std::sqrt(var), chi2 / blocks);
      EXPECT_GT(mean_plain, 0.0);
      EXPECT_EQ(worse, 0);
      EXPECT_LT(chi2 / blocks, 2.0);
      EXPECT_LT(std::abs(diff) / std::sqrt(var), 4.0);
    }
  }
}

TEST(AovEvents, OffByDefaultAndRefusedWithWeightedCombination) {
  RenderResult r = render_scene(load_test_scene(sphere_in_environment(R"("diffuse")")), quick_config(2));
  EXPECT_LT(r.image.channel_index("diffuse.R"), 0);
  EXPECT_FALSE(r.log.contains("aov_event_layers"));
  RenderConfig c = quick_config(2);
  c.aov_events = true;
  c.combine = "inverse-variance";
  try {
    check_config(c);
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("--aov-events"), std::string::npos) << e.what();
  }
}
