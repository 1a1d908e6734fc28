// Render iterations: how many samples per pixel each one renders, after which
// ones a checkpoint is written, and what runs between them.
//
// Between iterations no ray is in flight, so subsystems update their data
// structures there without locks (seeds/000 section 5.2.1).  The order of those
// updates is fixed by BetweenIterationSlot, not by who registered first, so a
// render is the same whatever order the subsystems were set up in.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace theia {

// Iteration sizes in spp: `first` repeated `repeat` times, then each iteration
// `growth` times the previous one, capped at `max`; the last one shortened to
// hit the total.  The command line's --iteration-first, --iteration-repeat,
// --iteration-growth and --iteration-max override these fields by name.
struct ScheduleOptions {
  int first = 16;
  int repeat = 2;
  double growth = 2.0;
  int max = 256;
};

// Hyperion's batch schedule: 16 16 32 64 128 256 256 ...
inline ScheduleOptions regular_schedule() { return {16, 2, 2.0, 256}; }
// For path guiding: small iterations early (frequent updates), a smaller cap
// (bounded recorder memory): 1 x8, 2 4 8 16 16 ...
inline ScheduleOptions guiding_schedule() { return {1, 8, 2.0, 16}; }

// Iteration sizes summing to exactly total_spp.  Throws theia::Error on
// options that cannot make progress (non-positive sizes, growth < 1).
std::vector<int> make_schedule(const ScheduleOptions& options, int total_spp);

// A split frame's part: the iterations of `sizes` intersected with samples
// [begin, end) (the empty intersections left out), so a part renders the
// iterations a whole render has there, cut at the range's ends.
std::vector<int> clip_schedule(const std::vector<int>& sizes, int begin, int end);

// `sizes` from iteration `at` on replaced by `options`' schedule: the
// iterations a render of the same total has there on it (clipped where `at`
// begins; a clipped first one smaller than options.first joins the next), so
// a render that stops learning continues on the sizes it would have had on
// that schedule from the start.  `at` past the end: `sizes` unchanged.
std::vector<int> switch_schedule(const std::vector<int>& sizes, int at, const ScheduleOptions& options);

// A time limit's last iteration: iteration `at` cut to the samples per pixel
// `seconds_left` fits at `seconds_per_spp` (at least 1), the rest of its
// samples an iteration after it, so the total stays.  Unchanged when it fits.
std::vector<int> fit_iteration(const std::vector<int>& sizes, int at, double seconds_left, double seconds_per_spp);

// Running totals of a schedule: cumulative[i] = sizes[0] + ... + sizes[i].
std::vector<int> cumulative_spp(const std::vector<int>& sizes);

// Checkpoint skipping (seeds/000 section 5.2.2).  Checkpoints are ideally
// written at cumulative spp first_ideal, 2 first_ideal, 4 first_ideal, ...,
// total; for each ideal count the iteration with the largest cumulative spp
// not above it is chosen.  Returns one flag per iteration.  `every_iteration`
// turns skipping off (a checkpoint after every iteration).
std::vector<bool> checkpoint_iterations(const std::vector<int>& cumulative, int first_ideal = 4,
                                        bool every_iteration = false);

// One iteration as the between-iteration tasks see it.
struct IterationInfo {
  int index = 0;            // 0-based
  int count = 0;            // iterations in the schedule
  uint32_t spp_begin = 0;   // samples [spp_begin, spp_end) of every pixel
  uint32_t spp_end = 0;
  // Set for the end-of-iteration tasks: the iteration's wall and CPU
  // seconds (the render alone; CPU: every thread of the process, which
  // another process on the machine does not inflate) and, when a task asked
  // for it (IterationTasks::measure_variance), its per-sample relative
  // variance, robust and full (combine.h: relative_variance; < 0: unknown,
  // as for 1-spp iterations): what efficiency estimates need.
  double seconds = 0.0;
  double cpu_seconds = 0.0;
  double sample_variance = -1.0;
  double sample_variance_full = -1.0;
  // Seconds since the render clock started (IterationConfig::clock_start),
  // at the iteration's start: what a time-limited render plans by.
  double elapsed_seconds = 0.0;
  bool last() const { return index + 1 == count; }
};

// The fixed order of the work between iterations.  Checkpoint comes last so a
// checkpoint holds the state after every update: a resume continues with the
// next iteration and never replays an update (whose inputs, e.g. the
// recorder's training samples, are gone by then).  Add a slot here to add a task.
enum class BetweenIterationSlot {
  GuidingUpdate,
  CachePointUpdate,
  AdaptiveSamplerUpdate,
  RecorderSkipRateUpdate,
  ScheduleSwitch,
  Checkpoint,
  Count
};
inline constexpr const char* kSlotNames[] = {"guiding_update", "cache_point_update", "adaptive_sampler_update",
                                             "recorder_skip_rate_update", "schedule_switch", "checkpoint"};
static_assert(sizeof(kSlotNames) / sizeof(kSlotNames[0]) == size_t(BetweenIterationSlot::Count));

// What runs around and between iterations.  A subsystem registers itself with
// one line: tasks.add(BetweenIterationSlot::GuidingUpdate, [&](auto& it) { ... }).
// The radiance recorder hooks begin_iteration()/end_iteration() in with
// on_begin/on_end.
class IterationTasks {
 public:
  using Task = std::function<void(const IterationInfo&)>;
  void add(BetweenIterationSlot slot, Task task);
  void on_begin(Task hook) { begin_hooks_.push_back(std::move(hook)); }
  void on_end(Task hook) { end_hooks_.push_back(std::move(hook)); }
  // A task reads IterationInfo::sample_variance (a pass over the film, paid only then).
  void measure_variance() { measure_variance_ = true; }
  bool measures_variance() const { return measure_variance_; }

  void begin_iteration(const IterationInfo& it) const;
  // end hooks, then every slot in order; each slot's wall time is added to
  // seconds(), the end hooks' to end_hook_seconds().
  void end_iteration(const IterationInfo& it);
  double seconds(BetweenIterationSlot slot) const { return seconds_[size_t(slot)]; }
  double end_hook_seconds() const { return end_hook_seconds_; }

 private:
  std::vector<Task> slots_[size_t(BetweenIterationSlot::Count)];
  double seconds_[size_t(BetweenIterationSlot::Count)] = {};
  double end_hook_seconds_ = 0.0;
  std::vector<Task> begin_hooks_, end_hooks_;
  bool measure_variance_ = false;
};

}  // namespace theia
