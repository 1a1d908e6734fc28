// Render farm on Slurm: a shot's frames as one job array (a task per frame),
// or each frame split into sample ranges (a job array per frame) and merged
// by a job that depends on it.  Every task renders with its own checkpoint
// directory; a task stopped by SIGTERM (preemption, Slurm's advance warning
// before its time limit, scancel) checkpoints, exits 75, and its batch
// wrapper requeues it, so it resumes where it stopped.
//
// The output directory is the farm's whole state:
//   farm.json            the plan (frames, parts, commands) and the job ids
//   jobs/*.sbatch        the batch scripts that were submitted
//   frames/NAME.exr      each frame (with NAME.png and NAME.json, the render's log)
//   parts/NAME.part-K.*  a split frame's parts (merged into frames/)
//   checkpoints/...      one checkpoint directory per task
//   logs/*.out           each task's output (appended across requeues): the
//                        wrapper's start/end lines, which status reads
#pragma once

#include "farm/part.h"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace theia {

// --render-options as the words a task's command line gets (split at spaces).
std::vector<std::string> split_words(const std::string& text);

// `theia farm submit`'s options.  One name each, flag --NAME (kebab-case).
struct FarmSubmitOptions {
  std::vector<std::string> scenes;    // scene files, in frame order
  std::string pattern;                // printf-style, e.g. shot/frame.%04d.pbrt (with frames)
  std::string frames;                 // A-B[:STEP] for the pattern
  std::string dir;                    // output directory
  int split = 1;                      // sample ranges per frame (> 1: split frames, needs spp)
  int spp = 0;                        // passed as --spp; 0: the scene's (not with split)
  std::string render_options;         // more `theia render` options, separated by spaces
  std::string partition;              // sbatch --partition (empty: the cluster's default)
  std::string time;                   // sbatch --time (empty: the partition's)
  int cpus_per_task = 1;              // sbatch --cpus-per-task, and theia's --threads
  std::string mem;                    // sbatch --mem (empty: the partition's)
  std::vector<std::string> sbatch_args;  // more sbatch options, verbatim (--sbatch-arg=--qos=low)
  int signal_seconds = 60;            // SIGTERM this long before the time limit (--signal=B:TERM@N)
  bool dry_run = false;               // print the batch scripts, submit nothing
  std::string theia;                  // the theia binary the tasks run (empty: this one)
};
void check(const FarmSubmitOptions& o);

// "%04d"-style pattern and A-B[:STEP] frame range to scene paths.
std::vector<std::string> expand_frame_pattern(const std::string& pattern, const std::string& frames);

// One Slurm job array: NAME, one command per task, and the sbatch options.
struct BatchJob {
  std::string name;
  std::vector<std::string> commands;  // shell command lines, one per array task
  std::string output;                 // sbatch --output (with %a)
  std::vector<std::string> sbatch;    // sbatch options
  bool requeue = true;                // wrap: exit 75 requeues the task
};
// The batch script: #SBATCH lines and the wrapper around the task's command.
std::string batch_script(const BatchJob& job);

// The plan: jobs and, per frame, where its outputs and logs go (farm.json).
struct FarmPlan {
  nlohmann::json manifest;
  std::vector<BatchJob> jobs;  // in submission order; a merge job follows its frame's parts
};
FarmPlan plan_farm(const FarmSubmitOptions& o);

int run_farm_submit(const FarmSubmitOptions& o);
// Per frame: done / running / requeued N / failed / pending, spp reached, time spent.
int run_farm_status(const std::string& dir);
// Checks every frame's output exists and is complete; lists what is not (exit 1).
int run_farm_collect(const std::string& dir);

}  // namespace theia
