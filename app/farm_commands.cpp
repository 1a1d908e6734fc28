#include "app/farm_commands.h"

#include "app/render_command.h"
#include "farm/part.h"

namespace theia {

FarmCommands::FarmCommands(CLI::App& app) {
  merge_ = app.add_subcommand("merge", "Add the parts of a split frame (render --sample-range) into its image");
  merge_->add_option("parts", merge_parts_, "The parts' .exr files (each with its .json log beside it)")->required();
  merge_->add_option("-o,--output", merge_output_, "Output .exr (with .png and .json beside it)")->required();
  merge_->add_option("--log", merge_log_, "JSON log file (default: OUTPUT with .json)");

  CLI::App* farm = app.add_subcommand("farm", "Render a shot on a Slurm cluster");
  farm->require_subcommand(1);
  FarmSubmitOptions& o = submit_options_;
  submit_ = farm->add_subcommand("submit", "Submit a shot's frames as Slurm job arrays");
  submit_->add_option("scenes", o.scenes, "Scene files, one per frame (or --pattern with --frames)");
  submit_->add_option("--pattern", o.pattern, "Scene file pattern with the frame number as %d or %0Nd");
  submit_->add_option("--frames", o.frames, "Frame numbers for --pattern: A-B or A-B:STEP");
  submit_->add_option("-d,--dir", o.dir, "Output directory: frames, parts, checkpoints, logs, farm.json")->required();
  submit_->add_option("--split", o.split, "Split every frame into this many sample ranges, merged by a dependent job")
      ->capture_default_str();
  submit_->add_option("--spp", o.spp, "Samples per pixel (needed with --split; default: the scene's)");
  submit_->add_option("--render-options", o.render_options, "More `theia render` options, separated by spaces");
  submit_->add_option("--partition", o.partition, "Slurm partition (default: the cluster's)");
  submit_->add_option("--time", o.time, "Time limit of each task (sbatch --time)");
  submit_->add_option("--cpus-per-task", o.cpus_per_task, "CPUs of each task (and its render's --threads)")
      ->capture_default_str();
  submit_->add_option("--mem", o.mem, "Memory of each task (sbatch --mem)");
  submit_->add_option("--sbatch-arg", o.sbatch_args, "More sbatch options, verbatim (repeat: --sbatch-arg=--qos=low)");
  submit_->add_option("--signal-seconds", o.signal_seconds,
                      "SIGTERM this many seconds before the time limit: the render checkpoints and is requeued")
      ->capture_default_str();
  submit_->add_flag("--dry-run", o.dry_run, "Print the batch scripts; submit nothing");
  submit_->add_option("--theia", o.theia, "The theia binary the tasks run (default: this one)");

  status_ = farm->add_subcommand("status", "Per frame: done, running, requeued, failed; spp reached; time spent");
  status_->add_option("dir", farm_dir_, "The farm's output directory")->required();
  collect_ = farm->add_subcommand("collect", "Check every frame's output is there and complete; list what is not");
  collect_->add_option("dir", farm_dir_, "The farm's output directory")->required();
}

bool FarmCommands::parsed() const {
  return merge_->parsed() || submit_->parsed() || status_->parsed() || collect_->parsed();
}

int FarmCommands::run() const {
  if (merge_->parsed()) return run_merge(merge_parts_, merge_output_, merge_log_);
  if (submit_->parsed()) {
    // A typo in the render's options fails here, not in every task on the farm.
    check_render_words(split_words(submit_options_.render_options), "farm submit --render-options");
    return run_farm_submit(submit_options_);
  }
  if (status_->parsed()) return run_farm_status(farm_dir_);
  return run_farm_collect(farm_dir_);
}

}  // namespace theia
