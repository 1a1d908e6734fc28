// Stopping a render early: one request for every cause, and the cause.
//
// The engine asks only whether to stop (it then generates no more camera
// rays and finishes the paths in flight); the scheduler decides from the
// reason what the stop means.  A signal (a farm taking the machine back)
// checkpoints and exits 75 to be resumed; a time limit (--time-limit) is
// the render's normal end and writes the image.  The first reason raised
// wins, so a signal during a time-limited render's last paths still finishes
// the image, and a time limit after a signal still checkpoints.
//
// A signal must end the render within seconds however long the paths are
// (a farm kills the job soon after): the engine drops paths still in flight
// a grace time after it (EngineOptions::abandon_after_seconds), and the
// scheduler then writes nothing for that iteration, so the resume continues
// from the newest checkpoint and gives the uninterrupted image.  A time
// limit keeps every sample instead, so it always waits for them.
#pragma once

#include <atomic>
#include <cstdint>

namespace theia {

enum class StopReason : uint8_t { None, Signal, TimeLimit };

class StopRequest {
 public:
  // Lock-free, so a signal handler may call it.
  void raise(StopReason reason) noexcept {
    uint8_t none = uint8_t(StopReason::None);
    reason_.compare_exchange_strong(none, uint8_t(reason));
  }
  bool raised() const noexcept { return reason_.load(std::memory_order_relaxed) != uint8_t(StopReason::None); }
  StopReason reason() const noexcept { return StopReason(reason_.load()); }
  // Tests only: run again with the same request.
  void clear() noexcept { reason_.store(uint8_t(StopReason::None)); }

 private:
  static_assert(std::atomic<uint8_t>::is_always_lock_free);
  std::atomic<uint8_t> reason_{uint8_t(StopReason::None)};
};

}  // namespace theia
