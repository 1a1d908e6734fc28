// A progress bar with rate and ETA for a terminal; silent when disabled.
#pragma once

#include <chrono>
#include <cstdint>

namespace theia {

class ProgressBar {
 public:
  explicit ProgressBar(bool enabled);
  void update(double fraction, uint64_t rays);
  void finish();

 private:
  bool enabled_;
  bool drawn_ = false;
  std::chrono::steady_clock::time_point start_, last_;
};

}  // namespace theia
