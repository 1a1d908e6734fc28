// The radiance recorder inside the wavefront, checked against the beauty pass
// with its own debug buffers (Hyperion course notes ch. 2, section 4.1).
#include "render_helpers.h"
#include "cachepoints/light_sampler.h"
#include "core/metrics.h"
#include "radiance_recorder/recorder.h"
#include "scene/accel.h"
#include "scene/camera.h"
#include "scene/filter.h"
#include "wavefront/engine.h"

#include <gtest/gtest.h>

#include <tbb/task_arena.h>

#include <memory>
#include <tuple>

using namespace theia;
using namespace theia::test;

namespace {

struct RecordedRender {
  ImageBuffer image;
  RecorderStats stats;
  std::vector<uint64_t> iteration_peaks;  // live vertices at their peak, per iteration
};

// Renders `iterations` iterations of `spp` samples each, with the recorder
// between begin/end_iteration as the scheduler will drive it.
// With a sink, the recorder makes training samples (and then records only
// the vertices that can train); `threads` > 0 runs the engine in an arena of
// that many threads.
RecordedRender render_recorded(const Scene& scene, const EngineOptions& opt, RecorderOptions ro, int iterations,
                               int spp, bool record = true, TrainingSampleSink* sink = nullptr, int threads = 0) {
  RenderableScene rs(scene);
  Film film(scene.film.width, scene.film.height);
  ro.width = scene.film.width;
  ro.height = scene.film.height;
  std::unique_ptr<RadianceRecorder> rec;
  if (record) rec = std::make_unique<RadianceRecorder>(ro, sink);
  WavefrontEngine engine(rs, film, opt, EngineHooks{.observer = rec.get()});
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  RecordedRender out;
  for (int it = 0; it < iterations; ++it) {
    if (rec) rec->begin_iteration();
    arena.execute([&] { engine.render(uint32_t(it * spp), uint32_t((it + 1) * spp)); });
    if (rec) {
      rec->end_iteration();
      rec->update_skip_rate();
      out.iteration_peaks.push_back(rec->stats().iteration_peak_live_vertices);
    }
  }
  if (rec) {
    if (ro.debug) film.layers.push_back({"recorder", rec->debug_primary()});
    if (ro.debug_bounce >= 0) film.layers.push_back({"bounce", rec->debug_bounce()});
    out.stats = rec->stats();
  }
  out.image = resolve_film(film);
  return out;
}

// The RGB of layer `name` (or the beauty for "") as an image of its own.
ImageBuffer layer(const ImageBuffer& img, const std::string& name) {
  ImageBuffer out(img.width, img.height, {"R", "G", "B"});
  for (int c = 0; c < 3; ++c) {
    std::string ch = name.empty() ? std::string(1, "RGB"[c]) : name + "." + "RGB"[c];
    int k = img.channel_index(ch);
    EXPECT_GE(k, 0) << ch;
    if (k < 0) continue;
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x) out.at(x, y, c) = img.data[img.offset(x, y, k)];
  }
  return out;
}

Scene cornell(int res) {
  Scene s = load_test_scene_file(std::string(THEIA_SCENES) + "/cornell-box/scene.pbrt");
  s.film.width = s.film.height = res;
  return s;
}

// A floor lit by a real area light above; between them two virtual lights
// (emit, never block), one of them in view of the camera.
// The virtual quads are black: as ordinary surfaces they would only block.
Scene virtual_lights_scene(bool is_virtual = true) {
  std::string v = is_virtual ? "true" : "false";
  return load_test_scene(R"(
    Film "rgb" "integer xresolution" [20] "integer yresolution" [20]
    LookAt 0 3 -4  0 0 0  0 1 0
    Camera "perspective" "float fov" [45]
    WorldBegin
    Material "diffuse" "rgb reflectance" [0.7 0.7 0.7]
    Shape "bilinearmesh" "point3 P" [-3 0 -3  3 0 -3  -3 0 3  3 0 3]
    AttributeBegin
      AreaLightSource "diffuse" "rgb L" [6 6 6]
      Shape "bilinearmesh" "point3 P" [-0.5 3 -0.5  0.5 3 -0.5  -0.5 3 0.5  0.5 3 0.5]
    AttributeEnd
    AttributeBegin
      Material "diffuse" "rgb reflectance" [0 0 0]
      AreaLightSource "diffuse" "rgb L" [0.3 0.1 0.05] "bool twosided" true "bool virtual" )" + v + R"(
      Shape "bilinearmesh" "point3 P" [-1.5 1.5 -1.5  1.5 1.5 -1.5  -1.5 1.5 1.5  1.5 1.5 1.5]
    AttributeEnd
    AttributeBegin
      Material "diffuse" "rgb reflectance" [0 0 0]
      AreaLightSource "diffuse" "rgb L" [0.05 0.2 0.1] "bool twosided" true "bool virtual" )" + v + R"(
      Shape "bilinearmesh" "point3 P" [-1 0.8 -1  1 0.8 -1  -1 0.8 1  1 0.8 1]
    AttributeEnd
  )");
}

// A mirror ball (a delta lobe: its vertices cannot train) and a point light
// (NEE to it has no density) beside an area light over a diffuse floor.
Scene mirror_scene() {
  return load_test_scene(R"(
    Film "rgb" "integer xresolution" [24] "integer yresolution" [24]
    LookAt 0 2 -4  0 0.5 0  0 1 0
    Camera "perspective" "float fov" [45]
    WorldBegin
    LightSource "point" "point3 from" [1.5 2 -1] "rgb I" [3 3 3]
    Material "diffuse" "rgb reflectance" [0.6 0.6 0.6]
    Shape "bilinearmesh" "point3 P" [-3 0 -3  3 0 -3  -3 0 3  3 0 3]
    AttributeBegin
      AreaLightSource "diffuse" "rgb L" [5 5 5]
      Shape "bilinearmesh" "point3 P" [-0.5 3 -0.5  0.5 3 -0.5  -0.5 3 0.5  0.5 3 0.5]
    AttributeEnd
    AttributeBegin
      Material "conductor" "float roughness" [0]
      Translate 0 0.7 0
      Shape "sphere" "float radius" [0.7]
    AttributeEnd
  )");
}

bool same_sample(const TrainingSample& a, const TrainingSample& b) {
  return a.p == b.p && a.wi == b.wi && a.radiance == b.radiance && a.pdf == b.pdf &&
         a.roughness == b.roughness && a.pixel == b.pixel && a.sample == b.sample && a.depth == b.depth &&
         a.flags == b.flags && a.scattering_weight == b.scattering_weight && a.bsdf_ratio == b.bsdf_ratio &&
         a.guide_ratio == b.guide_ratio;
}

}  // namespace

// The sink gets the samples in (pixel, sample, depth, flags) order, the same
// samples bit for bit whatever the thread count, and none that cannot train;
// the vertices that cannot train still pass their light on, so the debug
// buffer still equals the beauty.
TEST(RecorderSamples, SortedIdenticalAcrossThreadCountsAndOnlyTrainable) {
  Scene scene = mirror_scene();
  EngineOptions opt;
  opt.batch_size = 2048;
  RecorderOptions ro;
  ro.debug = true;
  ro.vertex_budget = 0.0f;
  std::vector<std::vector<TrainingSample>> runs;
  for (int threads : {1, 2}) {
    StoringSampleSink sink;
    RecordedRender r = render_recorded(scene, opt, ro, 2, 4, true, &sink, threads);
    EXPECT_LT(max_relative_difference(layer(r.image, ""), layer(r.image, "recorder")), 1e-4) << threads;
    EXPECT_GT(r.stats.untrainable, 0u) << "the mirror and the point light make vertices that cannot train";
    EXPECT_GT(r.stats.untrainable_merged, 0u) << "NEE to the point light is merged into its parent";
    EXPECT_LT(r.stats.untrainable_merged, r.stats.untrainable) << "mirror vertices are kept (not merged)";
    EXPECT_EQ(r.stats.samples, sink.samples.size());
    EXPECT_GT(sink.samples.size(), 1000u);
    runs.push_back(std::move(sink.samples));
  }
  const std::vector<TrainingSample>& s = runs[0];
  size_t nee = 0;
  for (size_t i = 0; i < s.size(); ++i) {
    EXPECT_FALSE(s[i].flags & kVertexDelta) << "a sample without a density at " << i;
    nee += (s[i].flags & kVertexNEE) ? 1 : 0;
    if (i == 0) continue;
    // Each iteration's samples are sorted; the second's follow the first's.
    const TrainingSample &a = s[i - 1], &b = s[i];
    if (a.sample / 4 == b.sample / 4) {
      EXPECT_LT(std::tie(a.pixel, a.sample, a.depth, a.flags), std::tie(b.pixel, b.sample, b.depth, b.flags)) << i;
    }
  }
  EXPECT_GT(nee, 0u) << "NEE to the area light trains";
  ASSERT_EQ(runs[0].size(), runs[1].size());
  for (size_t i = 0; i < s.size(); ++i) ASSERT_TRUE(same_sample(runs[0][i], runs[1][i])) << "sample " << i;
}

TEST(RecorderDebug, PrimaryHitBufferEqualsBeautyOnCornellBox) {
  Scene scene = cornell(24);
  EngineOptions opt;
  opt.batch_size = 4096;
  RecorderOptions ro;
  ro.debug = true;
  RecordedRender r = render_recorded(scene, opt, ro, 1, 4);
  EXPECT_LT(max_relative_difference(layer(r.image, ""), layer(r.image, "recorder")), 1e-4);
  EXPECT_GT(image_mean(layer(r.image, "recorder")).x, 0.05f);
  EXPECT_EQ(r.stats.dropped, 0u);
  EXPECT_EQ(r.stats.skipped_paths, 0u);
}

TEST(RecorderDebug, VirtualLightsEmitWithoutOccluding) {
  EngineOptions opt;
  opt.batch_size = 4096;
  RecorderOptions ro;
  ro.debug = true;
  Scene scene = virtual_lights_scene();
  RecordedRender r = render_recorded(scene, opt, ro, 1, 16);
  ImageBuffer beauty = layer(r.image, "");
  EXPECT_LT(max_relative_difference(beauty, layer(r.image, "recorder")), 1e-4);

  // Dark quads: as virtual lights they do not block, so the floor is as lit as
  // with no quads at all; as ordinary (black) surfaces they shadow it.
  auto dark = [](Scene sc) {
    sc.lights[1].L = sc.lights[2].L = RGB(0.0f);
    return sc;
  };
  Scene none = dark(virtual_lights_scene());
  Scene blocking = dark(virtual_lights_scene(false));
  Scene empty = virtual_lights_scene();
  empty.top_level_shapes.resize(2);  // the floor and the real light only
  empty.lights.resize(1);
  RGB m_virtual = image_mean(beauty);
  RGB m_none = image_mean(layer(render_recorded(none, opt, ro, 1, 16, false).image, ""));
  RGB m_blocking = image_mean(layer(render_recorded(blocking, opt, ro, 1, 16, false).image, ""));
  RGB m_empty = image_mean(layer(render_recorded(empty, opt, ro, 1, 16, false).image, ""));
  for (int c = 0; c < 3; ++c) {
    EXPECT_GT(m_virtual[c], m_none[c] * 1.02f) << "virtual lights emit (channel " << c << ")";
    EXPECT_NEAR(m_none[c], m_empty[c], 0.03f * m_empty[c]) << "virtual lights do not occlude (channel " << c << ")";
    EXPECT_LT(m_blocking[c], m_empty[c] * 0.8f) << "the same quads as surfaces do (channel " << c << ")";
  }
}

TEST(RecorderDebug, SkippingIsNoisierButConverges) {
  Scene scene = cornell(16);
  EngineOptions opt;
  opt.batch_size = 4096;
  RecorderOptions ro;
  ro.debug = true;
  ro.vertex_budget = 2.0f;            // path skipping from the second iteration on
  ro.vertex_skip_probability = 0.5f;  // and vertex skipping throughout
  auto error_at = [&](int iterations, RecorderStats* st) {
    RecordedRender r = render_recorded(scene, opt, ro, iterations, 2);
    if (st) *st = r.stats;
    return rel_mse(layer(r.image, "recorder"), layer(r.image, ""));
  };
  RecorderStats st;
  double e_few = error_at(2, nullptr), e_many = error_at(16, &st);
  EXPECT_GT(st.path_skip_rate, 0.2) << "the budget must have engaged path skipping";
  EXPECT_GT(st.skipped_vertices, 0u);
  EXPECT_GT(e_few, 1e-4) << "with skipping the debug image is not the beauty sample for sample";
  EXPECT_LT(e_many, 0.35 * e_few) << "relMSE " << e_few << " at 4 spp, " << e_many << " at 32 spp";
}

TEST(RecorderDebug, NthBounceBufferEqualsThroughputResetImage) {
  Scene scene = cornell(16);
  EngineOptions opt;
  opt.batch_size = 4096;
  // Russian roulette decides on the throughput, which the reset image changes:
  // without it both renders make the same decisions sample for sample.
  opt.rr_min_depth = 1000;
  for (int bounce : {0, 1, 2}) {
    RecorderOptions ro;
    ro.debug_bounce = bounce;
    RecordedRender r = render_recorded(scene, opt, ro, 1, 4);
    EngineOptions reset = opt;
    reset.throughput_reset_bounce = bounce;
    ImageBuffer reference = layer(render_recorded(scene, reset, ro, 1, 4, false).image, "");
    EXPECT_LT(max_relative_difference(layer(r.image, "bounce"), reference), 1e-4) << "bounce " << bounce;
    EXPECT_GT(image_mean(reference).x, 0.01f);
  }
  // With vertex skipping: noisier, converging.
  RecorderOptions ro;
  ro.debug_bounce = 1;
  ro.vertex_skip_probability = 0.5f;
  EngineOptions reset = opt;
  reset.throughput_reset_bounce = 1;
  auto error_at = [&](int spp) {
    RecordedRender r = render_recorded(scene, opt, ro, 1, spp);
    ImageBuffer reference = layer(render_recorded(scene, reset, ro, 1, spp, false).image, "");
    return rel_mse(layer(r.image, "bounce"), reference);
  };
  double e_few = error_at(4), e_many = error_at(32);
  EXPECT_LT(e_many, 0.35 * e_few) << "relMSE " << e_few << " at 4 spp, " << e_many << " at 32 spp";
}

// With the budget, the live vertices at the peak depend on the pool size and
// the budget, not on how long paths are.
TEST(RecorderMemory, PeakDoesNotGrowWithPathLength) {
  Scene scene = cornell(16);
  EngineOptions opt;
  opt.batch_size = 1024;
  opt.max_paths = 2048;
  opt.rr_min_depth = 1000;
  auto peak = [&](int max_depth, float budget) {
    EngineOptions o = opt;
    o.max_depth = max_depth;
    RecorderOptions ro;
    ro.vertex_budget = budget;
    RecordedRender r = render_recorded(scene, o, ro, 3, 1);
    return double(r.iteration_peaks.back());
  };
  double short_budget = peak(4, 4.0f), long_budget = peak(32, 4.0f);
  double short_free = peak(4, 0.0f), long_free = peak(32, 0.0f);
  EXPECT_GT(long_free, 1.5 * short_free) << "without a budget, longer paths hold more vertices";
  EXPECT_LT(long_budget, 1.25 * short_budget) << short_budget << " vs " << long_budget;
}

// Through the command-line path: the scheduler runs several iterations (16 +
// 16 spp) with the recorder's begin/end hooks and its skip-rate task, and the
// debug layer, resolved against the combined film, still equals the beauty.
TEST(RecorderDebug, PrimaryHitBufferEqualsBeautyAcrossSchedulerIterations) {
  Scene scene = cornell(24);
  RenderConfig c = quick_config(32);
  c.recorder.debug = true;
  c.recorder.vertex_budget = 0.0f;  // no path skipping: the buffers must agree exactly
  RenderResult r = render_scene(scene, c);
  ASSERT_EQ(r.log["scheduler"]["iterations"].size(), 2u);
  EXPECT_LT(max_relative_difference(layer(r.image, ""), layer(r.image, "recorder")), 1e-4);
  EXPECT_EQ(r.log["recorder"]["skipped_paths"].get<uint64_t>(), 0u);
}

// ---------------------------------------------------------------- media

namespace {

Scene media_scene(const std::string& name, int res, int max_depth = -1) {
  Scene s = load_test_scene_file(std::string(THEIA_SCENES) + "/" + name + "/scene.pbrt");
  s.film.width = s.film.height = res;
  if (max_depth >= 0) s.settings.max_depth = max_depth;
  return s;
}

EngineOptions media_options(const Scene& scene) {
  EngineOptions opt;
  opt.batch_size = 4096;
  opt.max_depth = scene.settings.max_depth;
  return opt;
}

}  // namespace

// In-medium vertices (seeds/000 ch. 2 section 3.4.2): scattering and NEE
// from inside a medium create vertices, a medium's emission and the
// transmittance-weighted light beyond reach the vertex whose ray it is, so
// the primary-hit buffer still equals the beauty: fog-cornell (the camera in
// a fog), the same fog glowing, and dense-glass (hundreds of scattering
// events behind glass).
TEST(RecorderDebug, PrimaryHitBufferEqualsBeautyInMedia) {
  for (const char* name : {"fog-cornell", "glowing fog-cornell", "dense-glass"}) {
    const bool glow = std::string(name).rfind("glowing ", 0) == 0;
    Scene scene = media_scene(glow ? "fog-cornell" : name, 20);
    if (glow) scene.media[0].Le = RGB(0.4f, 0.2f, 0.1f);
    RecorderOptions ro;
    ro.debug = true;
    ro.vertex_budget = 0.0f;
    RecordedRender r = render_recorded(scene, media_options(scene), ro, 1, 4);
    EXPECT_LT(max_relative_difference(layer(r.image, ""), layer(r.image, "recorder")), 1e-4) << name;
    // Recording changes nothing the paths do (wavefront/media.cpp: one compiled
    // medium stage), only the film's summation order.
    const ImageBuffer plain = layer(render_recorded(scene, media_options(scene), ro, 1, 4, false).image, "");
    EXPECT_LT(max_relative_difference(layer(r.image, ""), plain), 1e-5) << name;
    EXPECT_GT(image_mean(layer(r.image, "recorder")).x, 0.01f) << name;
    EXPECT_EQ(r.stats.dropped, 0u) << name;
    EXPECT_GT(r.stats.recorded, 0u) << name;
  }
}

// The N-th bounce buffer divides out the prefix throughput and multiplies
// the local factor: at medium vertices that is phase / pdf (1 for
// Henyey-Greenstein), so it equals the throughput-reset image there too
// (roulette off: it decides on the throughput the reset changes).
TEST(RecorderDebug, NthBounceBufferEqualsThroughputResetImageInFog) {
  Scene scene = media_scene("fog-cornell", 16, 8);
  EngineOptions opt = media_options(scene);
  opt.rr_min_depth = 1000;
  for (int bounce : {0, 1, 3}) {
    RecorderOptions ro;
    ro.debug_bounce = bounce;
    ro.vertex_budget = 0.0f;
    RecordedRender r = render_recorded(scene, opt, ro, 1, 4);
    EngineOptions reset = opt;
    reset.throughput_reset_bounce = bounce;
    ImageBuffer reference = layer(render_recorded(scene, reset, ro, 1, 4, false).image, "");
    EXPECT_LT(max_relative_difference(layer(r.image, "bounce"), reference), 1e-4) << "bounce " << bounce;
    EXPECT_GT(image_mean(reference).x, 0.01f) << "bounce " << bounce;
  }
}

// Bounded memory in a dense medium (seeds/000 ch. 2 sections 3.4.4, 5.1):
// dense-glass with ten times its scattering, isotropic and without
// absorption (sigma_t 200 in a sphere of radius 0.5: a walk takes thousands
// of scattering events to leave it) holds every path's chain
// of vertices until the path ends; skipping in-medium vertices or merging
// close ones into their parent shrinks the peak, and since the camera's
// vertices are on the glass (not in the medium) the primary buffer still
// equals the beauty: merged light reaches the nearest recorded ancestor.
TEST(RecorderMemory, DenseMediumSkippingBoundsThePeak) {
  Scene scene = media_scene("dense-glass", 16, 20000);
  scene.media[0].sigma_s *= 10.0f;
  scene.media[0].sigma_a = RGB(0.0f);
  scene.media[0].g = 0.0f;
  EngineOptions opt = media_options(scene);
  auto run = [&](float medium_skip, float min_distance) {
    RecorderOptions ro;
    ro.debug = true;
    ro.vertex_budget = 0.0f;
    ro.medium_skip_probability = medium_skip;
    ro.min_distance = min_distance;
    RecordedRender r = render_recorded(scene, opt, ro, 1, 1);
    EXPECT_LT(max_relative_difference(layer(r.image, ""), layer(r.image, "recorder")), 1e-4)
        << "skip " << medium_skip << ", distance " << min_distance;
    return r.stats;
  };
  const RecorderStats all = run(0.0f, 0.0f), skipped = run(0.9f, 0.0f), merged = run(0.0f, 0.05f);
  // Measured: 181 vertex events per path, a peak of 13,118 live vertices for 256 paths; with
  // skipping 1,364, with the minimum distance 276.
  EXPECT_GT(double(all.vertex_events) / double(all.paths), 100.0) << "paths scatter hundreds of times";
  EXPECT_GT(all.peak_live_vertices, 10000u);
  EXPECT_LT(double(skipped.peak_live_vertices), 0.2 * double(all.peak_live_vertices));
  EXPECT_LT(double(merged.peak_live_vertices), 0.2 * double(all.peak_live_vertices));
  EXPECT_GT(merged.merged_vertices, all.recorded / 2);
}

// With the camera in the fog, depth-0 vertices are skipped too: the primary
// buffer is then noisier than the beauty (its splats weighted by 1 / keep
// probability) but converges to it.
TEST(RecorderDebug, MediumSkippingIsNoisierButConvergesInFog) {
  Scene scene = media_scene("fog-cornell", 16, 8);
  RecorderOptions ro;
  ro.debug = true;
  ro.vertex_budget = 0.0f;
  ro.medium_skip_probability = 0.5f;
  auto error_at = [&](int spp, RecorderStats* st) {
    RecordedRender r = render_recorded(scene, media_options(scene), ro, 1, spp);
    if (st) *st = r.stats;
    return rel_mse(layer(r.image, "recorder"), layer(r.image, ""));
  };
  RecorderStats st;
  const double e_few = error_at(4, nullptr), e_many = error_at(32, &st);
  EXPECT_GT(st.skipped_vertices, 0u);
  EXPECT_GT(e_few, 1e-4) << "skipped depth-0 vertices make the buffer differ sample for sample";
  EXPECT_LT(e_many, 0.35 * e_few) << "relMSE " << e_few << " at 4 spp, " << e_many << " at 32 spp";
}

// Each skip probability is a probability below 1 (1 would record nothing),
// refused with the flag's name.
TEST(RecorderOptionsCheck, SkipProbabilitiesAreBelowOne) {
  for (float p : {1.0f, -0.1f, std::nanf("")}) {
    RenderConfig c = quick_config(1);
    c.recorder.medium_skip_probability = p;
    try {
      check_config(c);
      ADD_FAILURE() << "accepted " << p;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("--recorder-medium-skip-probability"), std::string::npos) << e.what();
    }
  }
}
