// StopSignals: SIGINT/SIGTERM handled without asynchronous handlers. Construct it in the main
// thread before any other thread exists: it blocks both signals, every thread created later
// inherits the mask, so the signals stay pending until the supervisor collects them with
// wait_for (sigtimedwait) and sets the loop's stop flag. Nothing runs in signal context.
#pragma once

#include <signal.h>

#include <cstdint>

namespace trainer::loop {

class StopSignals {
 public:
  // Blocks SIGINT and SIGTERM in the calling thread (pthread_sigmask).
  StopSignals();
  // Restores the calling thread's previous mask. A stop signal still pending then is
  // delivered with its default action (the process ends), as if it had never been blocked.
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

  // Waits up to `timeout_ns` (<= 0: just polls) for SIGINT or SIGTERM directed at this thread
  // or the process, and consumes it. Returns the signal number, or 0 on timeout. Call it from
  // a thread that has the signals blocked (the constructing thread or one created after).
  // Waits are resumed with the remaining time when another signal's handler interrupts them.
  int wait_for(std::int64_t timeout_ns) noexcept;

 private:
  sigset_t stop_set_{};
  sigset_t previous_mask_{};
};

}  // namespace trainer::loop
