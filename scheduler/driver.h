// The render as a series of iterations: the engine renders one, the image is
// folded in, the between-iteration tasks run (checkpoint last), and so on; a
// render resumes from a checkpoint and stops early on request.
#pragma once

#include "checkpoint/checkpoint.h"
#include "core/stop.h"
#include "scheduler/adaptive.h"
#include "scheduler/combine.h"
#include "scheduler/schedule.h"
#include "wavefront/engine.h"

#include <nlohmann/json.hpp>

#include <chrono>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace theia {

// Where and when checkpoints are written (flags --checkpoint-dir,
// --checkpoint-every-iteration, --checkpoint-first).  None of them changes
// the image, so a render may resume with others.
struct CheckpointOptions {
  std::string dir;               // empty: no checkpoints
  bool every_iteration = false;  // a checkpoint after every iteration instead of skipping
  int first = 4;                 // skipping: ideal checkpoints at cumulative spp first, 2 first, 4 first ... total
};

template <class V>
void declare_options(V& v, CheckpointOptions& o) {
  v.output("dir", o.dir, "Write checkpoints here; if it holds one, resume from it (exit code 75 when stopped)");
  v.output("every_iteration", o.every_iteration,
           "Checkpoint after every iteration instead of at FIRST, 2 FIRST, 4 FIRST ... spp (skipping)");
  v.output("first", o.first, "Cumulative spp of the first ideal checkpoint");
}

struct IterationConfig {
  ScheduleOptions schedule = regular_schedule();
  int total_spp = 16;
  Combination combination = Combination::Equal;
  uint32_t combine_window = 0;           // spp (ImageAccumulator::window)
  uint32_t seed = 0;
  CheckpointOptions checkpoint;          // none when checkpoint.dir is empty
  bool resume = false;                   // --resume: fail if there is nothing to resume
  uint64_t scene_hash = 0, options_hash = 0;
  std::vector<CheckpointParticipant> participants;
  // Adaptive sampling: iterations render its per-pixel ranges; it plans the next between iterations.
  AdaptiveSampler* adaptive = nullptr;
  // The engine's options.stop.  Raised by a signal handler: finish the paths
  // in flight, checkpoint, return interrupted.  Raised by the time limit:
  // finish them, keep every sample (the stopped iteration's too), return the
  // image; with checkpoints, the last one holds the finished render, so the
  // same command run again writes the same image and renders nothing.
  StopRequest* stop = nullptr;
  // > 0 (needs stop): raise stop with StopReason::TimeLimit this many
  // seconds after clock_start.  Not in the options fingerprint: it changes
  // where a render ends, not what any sample is.  The budget is this run's:
  // a resumed render gets it again.
  double time_limit = 0.0;
  std::chrono::steady_clock::time_point clock_start = std::chrono::steady_clock::now();
  // (iteration index, fraction of its camera samples generated, fraction of
  // the render's samples), from the engine's lanes, one call at a time.
  std::function<void(int, double, double)> progress;
  // Asked after each iteration's end hooks until it answers: options whose
  // schedule renders the rest of the samples from the next iteration on
  // (switch_schedule), or nothing to keep the schedule.  What learns between
  // iterations wants small iterations only while it learns.  The iteration
  // it switched at is checkpointed, so a resumed render renders the schedule
  // an uninterrupted one does.  Not asked with adaptive sampling (its
  // per-pixel plans follow the schedule it was built with).
  std::function<std::optional<ScheduleOptions>(const IterationInfo&)> switch_schedule;
  // Asked as each iteration is folded in: the first sample from which what
  // learns between iterations has stopped (a frozen guiding field), so that
  // inverse-variance weighting keeps every iteration from there in its window
  // (ImageAccumulator::fold); nothing while it still learns, or unset.
  std::function<std::optional<uint32_t>()> settled_from;
  // Called at every iteration boundary, after the iteration is folded in and
  // before the between-iteration tasks; what it returns is merged into that
  // iteration's log entry (the error against a reference image, --reference).
  // Unset: nothing is resolved or logged, so it costs nothing.
  std::function<nlohmann::json(const IterationInfo&, const ImageAccumulator&)> evaluate;
  // A split frame's part (--sample-range): samples [sample_begin, sample_end)
  // of every pixel, in the iterations of the whole frame's schedule clipped to
  // them (iteration_sizes); sample_end 0: the whole frame.
  uint32_t sample_begin = 0, sample_end = 0;
  // The part learns on its own (guiding, cache points' visibility): it renders
  // the schedule of a whole render of sample_end - sample_begin spp, so its
  // first iterations are small ones that train, whatever samples precede it.
  bool part_learns = false;
  bool keep_sums = false;  // IterationResult::sums (a part's mergeable film)
};

// The sizes of the iterations this config renders: the schedule for total_spp,
// clipped to the sample range when there is one (a part that learns: the
// schedule for the range's length).
std::vector<int> iteration_sizes(const IterationConfig& config);

struct IterationResult {
  ImageBuffer image;
  bool interrupted = false;        // stopped before the end; the state is in the checkpoint
  bool ended_by_time_limit = false; // the time limit ended it before its spp (the image holds every sample)
  uint32_t spp_min = 0, spp_max = 0; // colour samples per pixel in the image, counted from the sample ranges
  uint64_t dropped_samples = 0;    // non-finite samples dropped over every iteration
  std::vector<float> weight;       // per-pixel sum of filter weights over every iteration
  ImageBuffer sums;                // keep_sums: every film plane summed over the iterations (film_sums_image)
  nlohmann::json log;              // schedule, per-iteration times, checkpoint share of wall time
};

// The samples per pixel (smallest, largest) a checkpoint holds: what `theia
// farm status` reports for a render still under way.  Throws theia::Error
// when the checkpoint has no readable scheduler section.
std::pair<uint32_t, uint32_t> checkpoint_spp(const Checkpoint& c);

// `tasks` is copied: the driver adds its own checkpoint task to the copy.
// `film` must be the film the engine splats into; the engine's options.stop
// must be config.stop.  Throws theia::Error when a checkpoint cannot be
// resumed (different scene or options, none valid while --resume).
IterationResult render_iterations(WavefrontEngine& engine, Film& film, IterationTasks tasks,
                                  const IterationConfig& config);

}  // namespace theia
