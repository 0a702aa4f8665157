#include "trainer/core/clock.hpp"

#include <cerrno>
#include <ctime>

namespace trainer::core {

namespace {
constexpr std::int64_t kNanosecondsPerSecond = 1'000'000'000;
}

std::int64_t MonotonicClock::now_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * kNanosecondsPerSecond + ts.tv_nsec;
}

void MonotonicClock::sleep_until_ns(std::int64_t deadline_ns) noexcept {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(deadline_ns / kNanosecondsPerSecond);
  ts.tv_nsec = static_cast<long>(deadline_ns % kNanosecondsPerSecond);
  // clock_nanosleep returns the error number directly; EINTR means a signal arrived
  // before the deadline, so sleep again towards the same absolute deadline.
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

std::int64_t SlowMotionClock::now_ns() noexcept { return wall_.now_ns() / factor_; }

void SlowMotionClock::sleep_until_ns(std::int64_t deadline_ns) noexcept {
  wall_.sleep_until_ns(deadline_ns * factor_);
}

}  // namespace trainer::core
