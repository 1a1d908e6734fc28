// Path guiding end to end: the SD-tree trained from the radiance recorder
// leaves the image unbiased and deterministic.  (Whether it lowers the error
// is measured, not asserted: see guiding/README.md.)
#include "core/metrics.h"
#include "render_helpers.h"

#include <gtest/gtest.h>

using namespace theia;
using namespace theia::test;

namespace {

const std::string kCornell = std::string(THEIA_SCENES) + "/cornell-box/scene.pbrt";

RenderConfig guided_config(int spp, uint32_t seed = 0) {
  RenderConfig c = quick_config(spp);
  c.guiding.enabled = OnOffAuto::On;
  c.seed = seed;
  return c;
}

// Renders `c` (guided, 128 spp, leaves split at 1000 samples, 2 threads) on
// a 48 x 48 Cornell box and checks it
// against an unguided render of the same schedule (the same mean, within
// noise), and that 24 spp of it give the same image with 1 and 2 threads.
RenderResult render_unbiased_and_deterministic(RenderConfig c) {
  c.guiding.spatial_threshold = 1000.0;
  c.threads = 2;
  Scene scene = load_test_scene_file(kCornell);
  scene.film.width = scene.film.height = 48;
  RenderResult guided = render_scene(scene, c);
  RenderConfig unguided = quick_config(c.spp);
  unguided.schedule = "guiding";
  RenderResult plain = render_scene(scene, unguided);
  const RGB mg = image_mean(guided.image), mp = image_mean(plain.image);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(mg[k] / mp[k], 1.0, 0.01) << "channel " << k;
  EXPECT_LT(rel_mse(guided.image, plain.image), 0.05);
  RenderConfig one = c;
  one.threads = 1;
  one.spp = 24;
  RenderConfig two = one;
  two.threads = 2;
  EXPECT_LT(max_relative_difference(render_scene(scene, one).image, render_scene(scene, two).image), 1e-4);
  return guided;
}

}  // namespace

TEST(Guiding, CornellBoxMatchesPbrtReferenceWhenGuided) {
  Scene scene = load_test_scene_file(kCornell);
  RenderResult r = render_scene(scene, guided_config(256));
  ImageBuffer ref = read_image_file(std::string(THEIA_TEST_DATA) + "/cornell-box.exr");
  double rel = rel_mse(r.image, ref), dev = channel_mean_deviation(r.image, ref);
  std::printf("cornell-box 256 spp guided: relMSE %.5f, block relMSE %.2e, channel-mean deviation %.4f, %.2f s\n", rel,
              block_rel_mse(r.image, ref, 8), dev, r.log["time"]["render"].get<double>());
  EXPECT_LT(rel, 0.005);
  EXPECT_LT(dev, 0.02);
  EXPECT_EQ(r.log["dropped_samples"].get<uint64_t>(), 0u);
  // It did learn: the field split space and the log says what it holds.
  EXPECT_GT(r.log["guiding"]["spatial_leaves"].get<uint64_t>(), 1u);
  EXPECT_GT(r.log["memory"]["guiding"].get<uint64_t>(), 0u);
  EXPECT_EQ(r.log["options"]["schedule"].get<std::string>(), "guiding");
}

// A guided render weights its iterations by their inverse variance unless told
// otherwise or unless what it writes needs equal-weight sums; an unguided one
// keeps equal weights.  The log names the choice under the option's name.
TEST(Guiding, InverseVarianceIsTheDefaultCombinationOfAGuidedRender) {
  Scene scene = load_test_scene_file(kCornell);
  scene.film.width = scene.film.height = 16;
  auto combine = [&](const RenderConfig& c) {
    return render_scene(scene, c).log["options"]["combine"].get<std::string>();
  };
  EXPECT_EQ(combine(guided_config(12)), "inverse-variance");
  EXPECT_EQ(combine(quick_config(12)), "equal");
  RenderConfig told = guided_config(12);
  told.combine = "equal";
  EXPECT_EQ(combine(told), "equal");
  RenderConfig events = guided_config(12);
  events.aov_events = true;
  EXPECT_EQ(combine(events), "equal");
  RenderConfig debug = guided_config(12);
  debug.recorder.debug = true;
  EXPECT_EQ(combine(debug), "equal");
  // Asked for explicitly, the weighting still refuses the event layers.
  events.combine = "inverse-variance";
  EXPECT_THROW(render_scene(scene, events), std::exception);
}

// Training is deterministic (the recorder sorts its samples), so the guided
// image depends on the thread count only through summation order.
TEST(Guiding, ImageIndependentOfThreadCount) {
  Scene scene = load_test_scene_file(kCornell);
  scene.film.width = scene.film.height = 48;
  RenderConfig c1 = guided_config(24), c2 = guided_config(24);
  c1.threads = 1;
  c2.threads = 2;
  c1.batch_size = 2048;
  RenderResult a = render_scene(scene, c1), b = render_scene(scene, c2);
  EXPECT_LT(max_relative_difference(a.image, b.image), 1e-4);
}

// The field learns from the first --guiding-training-spp samples, then is
// frozen and the recorder detached: one update per training iteration, the
// recorder's paths are those of the training iterations alone, and the
// frozen field still guides (the image differs from an unguided one).
TEST(Guiding, FieldFrozenAfterTrainingSamples) {
  Scene scene = load_test_scene_file(kCornell);
  scene.film.width = scene.film.height = 32;
  RenderConfig c = guided_config(24);
  c.guiding.training_spp = 10;  // guiding schedule 1 x8, 2 | 4 8 2
  RenderResult r = render_scene(scene, c);
  EXPECT_EQ(r.log["guiding"]["updates"].get<int>(), 9);
  EXPECT_EQ(r.log["recorder"]["paths"].get<uint64_t>(), 10u * 32 * 32);
  EXPECT_GT(r.log["guiding"]["spatial_leaves"].get<uint64_t>(), 1u);
  RenderConfig every = c;
  every.guiding.training_spp = 0;
  RenderResult all = render_scene(scene, every);
  EXPECT_EQ(all.log["guiding"]["updates"].get<int>(), 12);
  EXPECT_EQ(all.log["recorder"]["paths"].get<uint64_t>(), 24u * 32 * 32);
  RenderConfig unguided = quick_config(24);
  unguided.schedule = "guiding";
  RenderResult plain = render_scene(scene, unguided);
  EXPECT_GT(max_relative_difference(r.image, plain.image), 1e-3);
  EXPECT_GT(max_relative_difference(r.image, all.image), 1e-3);
}

// Training iterations (the recorder attached) keep at most a quarter of the
// pool's paths in flight (EngineHooks::observed_pool_share); the iterations
// after training fill the whole pool again.  A pool of 102,400 paths (a
// sorted render's for 160 x 160 pixels: 4 per pixel), 25,600 while training.
TEST(Guiding, TrainingKeepsAQuarterOfThePoolInFlight) {
  Scene scene = load_test_scene_file(kCornell);
  scene.film.width = scene.film.height = 160;
  RenderConfig c = guided_config(16);
  c.threads = 1;
  c.max_paths = 102400;
  c.guiding.training_spp = 16;  // every iteration trains: 1 x8, 2, 4, 2
  RenderResult trained = render_scene(scene, c);
  ASSERT_EQ(trained.log["paths"]["pool"].get<size_t>(), 102400u);
  EXPECT_LE(trained.log["paths"]["peak_live"].get<size_t>(), 25600u);
  c.spp = 48;  // then 32 spp frozen, in iterations of 16 and more
  RenderResult after = render_scene(scene, c);
  EXPECT_GT(after.log["paths"]["peak_live"].get<size_t>(), 25600u);
}

// With --time-limit the field also stops learning once --guiding-training-share
// of the limit has passed.  A limit of 1000 s is never reached here: a share of
// 1e-9 (1 us, passed before the first iteration begins) means no training at
// all, a share of 1 leaves --guiding-training-spp in charge.  The log says
// what the field learned from.
TEST(Guiding, TrainingEndsAtItsShareOfTheTimeLimit) {
  Scene scene = load_test_scene_file(kCornell);
  scene.film.width = scene.film.height = 32;
  RenderConfig c = guided_config(24);
  c.guiding.training_spp = 10;  // guiding schedule 1 x8, 2 | 4 8 2
  c.time_limit = 1000.0;
  c.guiding.training_share = 1e-9f;
  RenderResult none = render_scene(scene, c);
  EXPECT_EQ(none.log["guiding"]["trained_spp"].get<int64_t>(), 0);
  EXPECT_EQ(none.log["guiding"]["updates"].get<int>(), 0);
  EXPECT_FALSE(none.log.contains("recorder") && none.log["recorder"]["paths"].get<uint64_t>() > 0);
  EXPECT_FALSE(none.log["scheduler"]["time_limit"]["reached"].get<bool>());
  c.guiding.training_share = 1.0f;
  RenderResult budget = render_scene(scene, c);
  EXPECT_EQ(budget.log["guiding"]["trained_spp"].get<int64_t>(), 10);
  EXPECT_EQ(budget.log["guiding"]["updates"].get<int>(), 9);
}

// --guiding-auto judges in rounds (held-out iterations, without guide and
// recorder, against as many after them, guided without recording): a
// one-pair probe once the field has learned from a sixteenth of the training
// budget; if guiding came close to paying there, a one-pair recheck after an
// eighth more of training (skipped when training ends first) and a two-pair
// final round from where training ends.  Whichever way it goes (it is a
// measurement of time), the image stays unbiased.
TEST(Guiding, AutoJudgesInRoundsAndStaysUnbiased) {
  const std::vector<int> guiding_schedule{1, 1, 1, 1, 1, 1, 1, 1, 2, 4, 8, 16, 16, 16, 16, 16, 16, 16, 16, 16, 16, 16};
  EXPECT_EQ(guiding_holdout_iteration(guiding_schedule, 8), 9);  // 4 spp from 10 spp on
  EXPECT_EQ(guiding_holdout_iteration({16, 16, 32}, 8), 1);      // from 16 spp
  EXPECT_EQ(guiding_holdout_iteration({1, 1, 1, 1, 1, 1, 1, 1, 2, 4}, 8), -1);  // no successor
  EXPECT_EQ(guiding_holdout_iteration({8, 4, 1}, 8), -1);                       // successor of 1 spp
  EXPECT_EQ(guiding_holdout_iteration({8, 4, 4, 1}, 0, 2), -1);                 // two pairs need 4 iterations
  EXPECT_EQ(guiding_holdout_iteration({8, 4, 4, 2, 2}, 0, 2), 0);
  EXPECT_EQ(guiding_holdout_iteration({8, 4, 4, 2, 2}, 1, 2), 1);   // 4 4 held out, 2 2 judged
  EXPECT_EQ(guiding_holdout_iteration({8, 4, 4, 2, 2}, 9, 2), -1);  // from 12: too few left
  // Training 256 spp: the probe from 16 spp (iteration 11 starts at 22).
  EXPECT_EQ(guiding_probe_iteration(guiding_schedule, 256), 11);
  // The final round from where training ended, two pairs.
  std::vector<int> longer = guiding_schedule;
  longer.resize(40, 16);
  EXPECT_EQ(guiding_final_iteration(longer, 262, 262), 26);  // iteration 26 starts at 262
  EXPECT_EQ(guiding_final_iteration(guiding_schedule, 262, 262), -1);  // the schedule ends at 198 spp
  EXPECT_EQ(guiding_final_iteration(guiding_schedule, 118, 118), 17);  // training ended by the clock
  EXPECT_EQ(guiding_final_iteration(guiding_schedule, 118, 134), 18);  // planned later: from now on
  EXPECT_EQ(guiding_final_iteration(guiding_schedule, 182, 182), -1);  // 20, 21 are one pair only
  EXPECT_EQ(guiding_final_iteration(longer, -1, 54), 26);              // never-ending training: as 256
  // The recheck: 32 spp after the probe's pair (it ends at 54): iteration 15 starts at 86.
  EXPECT_EQ(guiding_recheck_iteration(guiding_schedule, 256), 15);
  EXPECT_EQ(guiding_recheck_iteration({1, 1, 1, 1, 1, 1, 1, 1, 2, 4}, 256), -1);  // no probe
  // A small budget: the probe from 8 spp, the recheck at least 16 spp after its pair (ends at 22).
  EXPECT_EQ(guiding_probe_iteration(guiding_schedule, 16), 9);
  EXPECT_EQ(guiding_recheck_iteration(guiding_schedule, 16), 12);
  EXPECT_EQ(guiding_probe_iteration(guiding_schedule, 0), 11);  // never-ending training: as 256

  Scene scene = load_test_scene_file(kCornell);
  RenderConfig c = quick_config(256);
  c.guiding.enabled = OnOffAuto::Auto;
  c.guiding.training_spp = 32;  // probe from 8 spp; training ends before the recheck; final round then
  RenderResult r = render_scene(scene, c);
  const nlohmann::json& a = r.log["guiding"]["auto"];
  std::printf("guiding-auto on cornell-box: %s\n", a.dump().c_str());
  EXPECT_EQ(r.log["options"]["guiding"].get<std::string>(), "auto");
  const std::vector<int> schedule = r.log["scheduler"]["schedule"].get<std::vector<int>>();
  EXPECT_EQ(a["probe"]["unguided_iteration"].get<int>(), guiding_probe_iteration(schedule, 32));
  EXPECT_TRUE(a["probe"]["measured"].get<bool>());
  EXPECT_EQ(a["probe"]["guided"]["iterations"].get<int>(), 1);
  EXPECT_GT(a["probe"]["unguided"]["variance"].get<double>(), 0.0);
  EXPECT_GE(a["probe"]["unguided"]["variance_full"].get<double>(), a["probe"]["unguided"]["variance"].get<double>());
  EXPECT_GT(a["probe"]["guided"]["cpu_seconds_per_spp"].get<double>(), 0.0);
  const std::string verdict = a["verdict"].get<std::string>();
  EXPECT_TRUE(verdict == "on" || verdict == "off") << verdict;
  // The final round is planned and measured exactly when the probe passed,
  // from where training ended (the first iteration from 32 spp), and then
  // replaces the recheck, which training's end came before.
  EXPECT_FALSE(a["recheck"]["measured"].get<bool>());
  const bool probe_passed = a["probe"]["pays"].get<bool>();
  if (probe_passed) {
    EXPECT_EQ(a["recheck"]["unguided_iteration"].get<int>(), -1);
  }
  EXPECT_EQ(a["final"]["measured"].get<bool>(), probe_passed);
  if (probe_passed) {
    const int64_t trained = r.log["guiding"]["trained_spp"].get<int64_t>();
    EXPECT_GE(trained, 32);
    EXPECT_EQ(a["final"]["unguided_iteration"].get<int>(), guiding_final_iteration(schedule, trained, int(trained)));
    EXPECT_EQ(a["final"]["guided"]["iterations"].get<int>(), 2);
    EXPECT_EQ(verdict == "on", a["final"]["pays"].get<bool>());
  } else {
    EXPECT_EQ(a["final"]["unguided_iteration"].get<int>(), -1);
    EXPECT_EQ(verdict, "off");
  }
  if (verdict == "on") {
    EXPECT_GT(a["final"]["efficiency_ratio"].get<double>(), 1.1);
    EXPECT_GT(a["final"]["efficiency_ratio_full"].get<double>(), 1.1);
  }
  ImageBuffer ref = read_image_file(std::string(THEIA_TEST_DATA) + "/cornell-box.exr");
  EXPECT_LT(rel_mse(r.image, ref), 0.005);
  EXPECT_LT(channel_mean_deviation(r.image, ref), 0.02);

  // Training 128 spp: the recheck (iteration 12, from 38 spp) comes before
  // training ends (134 spp), and each round is measured exactly when the one
  // before passed.
  scene.film.width = scene.film.height = 48;
  c = quick_config(224);
  c.guiding.enabled = OnOffAuto::Auto;
  c.guiding.training_spp = 128;
  const nlohmann::json b = render_scene(scene, c).log["guiding"]["auto"];
  std::printf("guiding-auto on cornell-box 48x48, training 128 spp: %s\n", b.dump().c_str());
  EXPECT_EQ(b["recheck"]["unguided_iteration"].get<int>(), 12);
  EXPECT_EQ(b["recheck"]["threshold"].get<double>(), kRecheckRule.threshold);
  EXPECT_EQ(b["recheck"]["measured"].get<bool>(), b["probe"]["pays"].get<bool>());
  const bool recheck_passed = b["recheck"]["pays"].get<bool>();
  EXPECT_EQ(b["final"]["measured"].get<bool>(), recheck_passed);
  if (recheck_passed) {
    EXPECT_EQ(b["final"]["unguided_iteration"].get<int>(), 18);  // from 134 spp
  }
  EXPECT_EQ(b["verdict"].get<std::string>(), recheck_passed && b["final"]["pays"].get<bool>() ? "on" : "off");
}

// Once --guiding-auto has decided for good and nothing is left to learn, the
// rest of the render goes on in the regular schedule's growing iterations
// (issue 12: guiding's 16-spp iterations cost ~12% more per sample than
// unguided's): "off" right after the probe's pair, "on" after the final
// round (training over).  The verdict is forced, so the iterations are known.
TEST(Guiding, AutoContinuesOnTheRegularScheduleOnceDecided) {
  Scene scene = load_test_scene_file(kCornell);
  scene.film.width = scene.film.height = 48;
  const std::vector<int> planned = make_schedule(guiding_schedule(), 256);
  auto render = [&](const std::string& verdict, int training_spp) {
    RenderConfig c = quick_config(256);
    c.guiding.enabled = OnOffAuto::Auto;
    c.guiding.training_spp = training_spp;
    c.guiding.test_verdict = verdict;
    return render_scene(scene, c);
  };
  // Off: the probe holds out iteration 11 (22 spp) against 12; from 13 (54 spp) on, regular.
  // (Training 255: a render of exactly its training budget would be off from the start.)
  RenderResult off = render("off", 255);
  EXPECT_EQ(off.log["guiding"]["auto"]["verdict"].get<std::string>(), "off");
  EXPECT_EQ(off.log["scheduler"]["schedule"].get<std::vector<int>>(), switch_schedule(planned, 13, regular_schedule()));
  EXPECT_EQ(off.log["scheduler"]["schedule_switch"]["at_iteration"].get<int>(), 13);
  EXPECT_EQ(off.log["scheduler"]["schedule_switch"]["at_spp"].get<int>(), 54);
  EXPECT_EQ(off.log["scheduler"]["spp_per_pixel"]["min"].get<int>(), 256);
  // On, training 32 spp: the final round holds out 12, 13 (from 38 spp)
  // against 14, 15; from 16 (102 spp) on, regular.
  RenderResult on = render("on", 32);
  EXPECT_EQ(on.log["guiding"]["auto"]["verdict"].get<std::string>(), "on");
  EXPECT_EQ(on.log["scheduler"]["schedule"].get<std::vector<int>>(), switch_schedule(planned, 16, regular_schedule()));
  EXPECT_EQ(on.log["scheduler"]["schedule_switch"]["at_iteration"].get<int>(), 16);
  // Training that never ends leaves guiding's schedule alone.
  RenderResult learning = render("on", 0);
  EXPECT_TRUE(learning.log["scheduler"]["schedule_switch"].is_null());
  // --guiding without auto switches once training is over: training 32 spp
  // ends as iteration 12 (38 spp) begins, so from 13 (54 spp) on, regular;
  // with --no-guiding-regular-after-training guiding's schedule to the end.
  RenderConfig guided = guided_config(256);
  guided.guiding.training_spp = 32;
  RenderResult switched = render_scene(scene, guided);
  EXPECT_EQ(switched.log["scheduler"]["schedule"].get<std::vector<int>>(),
            switch_schedule(planned, 13, regular_schedule()));
  EXPECT_EQ(switched.log["scheduler"]["schedule_switch"]["at_iteration"].get<int>(), 13);
  guided.guiding.regular_after_training = false;
  RenderResult plain = render_scene(scene, guided);
  EXPECT_EQ(plain.log["scheduler"]["schedule"].get<std::vector<int>>(), planned);
  EXPECT_TRUE(plain.log["scheduler"]["schedule_switch"].is_null());
  // The same image in expectation: mean channel values against the guided render's.
  for (const RenderResult* r : {&off, &on, &switched}) EXPECT_LT(channel_mean_deviation(r->image, plain.image), 0.02);
}

// The final round needs guiding to pay by both variance figures: a guided
// side with half the robust variance but fireflies (full variance 3x) does
// not pass, however cheap; the early rounds judge by the robust figure alone
// (one pair's full figure swings with a single firefly).  A figure that is
// unknown (0) does not count against guiding.
TEST(Guiding, AutoVerdictNeedsBothFiguresToPayInTheFinalRound) {
  GuidingVerdict::Round round;
  round.unguided_iteration = 5;
  round.length = 2;
  EXPECT_EQ(round.side_of(4), -1);
  EXPECT_EQ(round.side_of(6), 0);
  EXPECT_EQ(round.side_of(7), 1);
  EXPECT_EQ(round.side_of(9), -1);
  auto side = [](double variance, double full, double cpu_seconds) {
    GuidingVerdict::Side s;
    s.iterations = 2;
    s.spp = 32;
    s.variance = variance * 32.0;
    s.variance_full = full * 32.0;
    s.cpu_seconds = cpu_seconds;
    return s;
  };
  round.unguided = side(1.0, 1.5, 3.2);
  round.guided = side(0.5, 4.5, 3.2);
  EXPECT_TRUE(round.measured());
  EXPECT_DOUBLE_EQ(round.efficiency_ratio(false), 2.0);
  EXPECT_NEAR(round.efficiency_ratio(true), 1.0 / 3.0, 1e-12);
  EXPECT_FALSE(guiding_pays(round, kFinalRule));
  EXPECT_TRUE(guiding_pays(round, kProbeRule));  // robust alone
  EXPECT_TRUE(guiding_pays(round, kRecheckRule));
  round.guided = side(0.5, 0.75, 3.2);  // no fireflies
  EXPECT_TRUE(guiding_pays(round, kFinalRule));
  round.guided = side(0.5, 0.75, 6.4);  // twice the time per sample: no gain
  EXPECT_FALSE(guiding_pays(round, kFinalRule));
  EXPECT_FALSE(guiding_pays(round, kProbeRule));  // the probe asks for a clear gain early
  EXPECT_FALSE(guiding_pays(round, kRecheckRule));
  round.guided = side(0.5, 0.75, 4.0);  // 1.6
  EXPECT_TRUE(guiding_pays(round, kProbeRule));
  round.guided = side(0.5, 0.75, 5.0);  // 1.28: a rough break-even, whose training does not pay
  EXPECT_FALSE(guiding_pays(round, kProbeRule));
  EXPECT_TRUE(guiding_pays(round, kRecheckRule));
  round.guided = side(0.0, 0.0, 6.4);  // a noiseless image: nothing says it loses
  EXPECT_TRUE(guiding_pays(round, kFinalRule));
}

// One-sample MIS with the selection probability learned per leaf (seeds/001
// 10.5): the share is fixed within an iteration, so every iteration is an
// unbiased MIS estimator; it is learned deterministically (the same image
// with 1 and 2 threads); and it did learn (leaves moved away from their start
// of 0.5, differently).
TEST(Guiding, LearnedSelectionIsUnbiasedDeterministicAndLearns) {
  RenderConfig c = guided_config(128);
  c.guiding.sampling = "mis-learned";
  RenderResult learned = render_unbiased_and_deterministic(c);
  const nlohmann::json& sel = learned.log["guiding"]["selection"];
  std::printf("learned selection over %llu leaves: mean %.3f, min %.3f, max %.3f\n",
              (unsigned long long)learned.log["guiding"]["spatial_leaves"].get<uint64_t>(), sel["mean"].get<double>(),
              sel["min"].get<double>(), sel["max"].get<double>());
  EXPECT_GT(learned.log["guiding"]["spatial_leaves"].get<uint64_t>(), 4u);
  EXPECT_LT(sel["min"].get<double>(), sel["max"].get<double>() - 0.05);
  EXPECT_GT(std::abs(sel["mean"].get<double>() - 0.5), 0.02);
  // One-sample MIS draws guide directions into the surface (counted; the paths end there).
  EXPECT_GT(learned.log["guiding"]["draw_failures"].get<uint64_t>(), 0u);
}

// --guiding-selection-max: the engine takes at most the cap of a leaf's
// learned share; still unbiased and deterministic, and the log counts the
// leaves it cuts.  A cap below where learning starts changes every guided vertex.
TEST(Guiding, SelectionCapIsUnbiasedDeterministicAndApplies) {
  RenderConfig c = guided_config(128);
  c.guiding.sampling = "mis-learned";
  c.guiding.selection_max = 0.3f;
  RenderResult capped = render_unbiased_and_deterministic(c);
  const nlohmann::json& sel = capped.log["guiding"]["selection"];
  EXPECT_FLOAT_EQ(sel["cap"].get<float>(), 0.3f);
  EXPECT_GT(sel["capped_leaves"].get<uint64_t>(), 0u);
  EXPECT_EQ(capped.log["options"]["guiding_selection_max"].get<float>(), 0.3f);

  Scene scene = load_test_scene_file(kCornell);
  scene.film.width = scene.film.height = 24;
  RenderConfig a = guided_config(24);
  a.guiding.spatial_threshold = 1000.0;
  a.guiding.selection_max = 1.0f;
  a.threads = 1;
  RenderConfig b = a;
  b.guiding.selection_max = 0.3f;
  EXPECT_GT(max_relative_difference(render_scene(scene, a).image, render_scene(scene, b).image), 1e-3);
  // An uncapped render says so.
  RenderResult plain = render_scene(scene, a);
  EXPECT_EQ(plain.log["guiding"]["selection"]["capped_leaves"].get<uint64_t>(), 0u);
}

// --guiding-roulette-floor: adjoint-driven roulette's least survival at a
// guided vertex.  Any floor leaves the mean alone; a higher one keeps more
// paths alive (here 1: guided vertices never end a path by roulette).
TEST(Guiding, RouletteFloorIsUnbiasedAndApplies) {
  RenderConfig c = guided_config(128);
  c.guiding.roulette_floor = 0.05f;
  RenderResult low = render_unbiased_and_deterministic(c);
  EXPECT_EQ(low.log["options"]["guiding_roulette_floor"].get<float>(), 0.05f);
  c.guiding.roulette_floor = 1.0f;
  RenderResult high = render_unbiased_and_deterministic(c);
  EXPECT_GT(high.log["paths"]["average_length"].get<double>(), low.log["paths"]["average_length"].get<double>() * 1.01);
}

// --guiding-field vmm: the mixture field guides without bias, trains the same
// whatever the thread count (its checkpoint: test_resume.cpp; its saved field:
// test_field_e2e.cpp).
TEST(Guiding, VMMFieldIsUnbiasedAndDeterministic) {
  RenderConfig c = guided_config(128);
  c.guiding.field = "vmm";
  RenderResult vmm = render_unbiased_and_deterministic(c);
  EXPECT_EQ(vmm.log["dropped_samples"].get<uint64_t>(), 0u);
  EXPECT_EQ(vmm.log["guiding"]["field"].get<std::string>(), "vmm");
  EXPECT_EQ(vmm.log["guiding"]["vmm"]["regions"].get<uint64_t>(), vmm.log["guiding"]["spatial_leaves"].get<uint64_t>());
  EXPECT_GT(vmm.log["guiding"]["spatial_leaves"].get<uint64_t>(), 4u);
  // The log says how many lobes carry the fitted regions' mixtures, and how concentrated they are.
  const nlohmann::json& m = vmm.log["guiding"]["vmm"];
  EXPECT_GT(m["fitted_regions"].get<uint64_t>(), 4u);
  EXPECT_GE(m["active_lobes"]["min"].get<int>(), 1);
  EXPECT_LE(m["active_lobes"]["max"].get<int>(), kVMMLobes);
  EXPECT_GT(m["kappa"]["max"].get<double>(), m["kappa"]["mean"].get<double>());

  Scene scene = load_test_scene_file(kCornell);
  RenderConfig bad = guided_config(4);
  bad.guiding.field = "quadtree";
  try {
    render_scene(scene, bad);
    ADD_FAILURE() << "--guiding-field quadtree was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("expected sdtree or vmm"), std::string::npos) << e.what();
  }
}

// --guiding-auto where the render ends within training: the probe's
// training alone would cost more than guiding could win back, so it is off
// from the first sample, renders as --no-guiding does and says why (also at
// exactly the training budget: no sample would follow training).
TEST(Guiding, AutoIsOffForARenderShorterThanTraining) {
  Scene scene = load_test_scene_file(kCornell);
  scene.film.width = scene.film.height = 24;
  RenderConfig c = quick_config(64);
  c.guiding.enabled = OnOffAuto::Auto;
  c.threads = 1;  // the same summation order as the plain render's
  const RenderResult r = render_scene(scene, c);
  EXPECT_EQ(r.log["options"]["guiding"].get<std::string>(), "off");
  EXPECT_EQ(r.log["guiding"]["auto"]["verdict"].get<std::string>(), "off");
  EXPECT_EQ(r.log["guiding"]["auto"]["why"].get<std::string>(), "the render's 64 spp leave none after training's 256");
  RenderConfig plain = quick_config(64);
  plain.guiding.enabled = OnOffAuto::Off;
  plain.threads = 1;
  EXPECT_EQ(test::max_relative_difference(r.image, render_scene(scene, plain).image), 0.0);
  c.guiding.training_spp = 64;
  EXPECT_EQ(render_scene(scene, c).log["options"]["guiding"].get<std::string>(), "off");
  // Training shorter than the render: auto judges.
  c.guiding.training_spp = 32;
  EXPECT_EQ(render_scene(scene, c).log["options"]["guiding"].get<std::string>(), "auto");
}
