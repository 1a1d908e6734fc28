// Costs made visible: wall time per named phase and process memory.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <string>

namespace theia {

// Seconds spent per phase.  Phases are entered from the single thread that
// drives the engine (each phase is parallel inside), so no locking is needed.
template <typename PhaseEnum, size_t N>
struct PhaseTimes {
  std::array<double, N> seconds{};
  double& operator[](PhaseEnum p) { return seconds[size_t(p)]; }
  double operator[](PhaseEnum p) const { return seconds[size_t(p)]; }
};

class ScopedTimer {
 public:
  explicit ScopedTimer(double& accumulator) : acc_(accumulator), start_(std::chrono::steady_clock::now()) {}
  ~ScopedTimer() { acc_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count(); }
  ScopedTimer(const ScopedTimer&) = delete;
  ScopedTimer& operator=(const ScopedTimer&) = delete;

 private:
  double& acc_;
  std::chrono::steady_clock::time_point start_;
};

inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// CPU seconds (user + system, every thread) this process has used so far:
// on a shared machine the CPU time of a piece of work varies far less than
// its wall time, which grows with whatever else the cores run.
double process_cpu_seconds();

// Peak and current resident set size of this process, from /proc/self/status.
size_t peak_rss_bytes();
size_t current_rss_bytes();

std::string format_bytes(size_t bytes);

}  // namespace theia
