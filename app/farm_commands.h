// `theia merge` and `theia farm submit|status|collect`: their flags; the
// work is farm/'s (part.h: split frames, slurm.h: the Slurm farm).
#pragma once

#include "farm/slurm.h"

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace theia {

class FarmCommands {
 public:
  explicit FarmCommands(CLI::App& app);
  bool parsed() const;
  int run() const;  // the parsed one's exit code; throws theia::Error

 private:
  CLI::App *merge_ = nullptr, *submit_ = nullptr, *status_ = nullptr, *collect_ = nullptr;
  std::vector<std::string> merge_parts_;
  std::string merge_output_, merge_log_;
  FarmSubmitOptions submit_options_;
  std::string farm_dir_;
};

}  // namespace theia
