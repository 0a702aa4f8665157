// StopSignals: pthread_sigmask on construction/destruction, sigtimedwait to collect.
#include "trainer/loop/stop_signals.hpp"

#include <pthread.h>

#include <cerrno>
#include <ctime>

namespace trainer::loop {

namespace {

constexpr std::int64_t kNanosecondsPerSecond = 1'000'000'000;

std::int64_t monotonic_now_ns() noexcept {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<std::int64_t>(now.tv_sec) * kNanosecondsPerSecond + now.tv_nsec;
}

}  // namespace

StopSignals::StopSignals() {
  sigemptyset(&stop_set_);
  sigaddset(&stop_set_, SIGINT);
  sigaddset(&stop_set_, SIGTERM);
  // Cannot fail with a valid `how` and set.
  pthread_sigmask(SIG_BLOCK, &stop_set_, &previous_mask_);
}

StopSignals::~StopSignals() {
  pthread_sigmask(SIG_SETMASK, &previous_mask_, nullptr);
}

int StopSignals::wait_for(std::int64_t timeout_ns) noexcept {
  if (timeout_ns < 0) timeout_ns = 0;
  const std::int64_t deadline_ns = monotonic_now_ns() + timeout_ns;
  std::int64_t remaining_ns = timeout_ns;
  for (;;) {
    timespec timeout{};
    timeout.tv_sec = static_cast<time_t>(remaining_ns / kNanosecondsPerSecond);
    timeout.tv_nsec = static_cast<long>(remaining_ns % kNanosecondsPerSecond);
    const int signal_number = sigtimedwait(&stop_set_, nullptr, &timeout);
    if (signal_number > 0) return signal_number;
    if (errno != EINTR) return 0;  // EAGAIN: timed out
    remaining_ns = deadline_ns - monotonic_now_ns();
    if (remaining_ns < 0) remaining_ns = 0;
  }
}

}  // namespace trainer::loop
