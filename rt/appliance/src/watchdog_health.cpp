#include "trainer/appliance/watchdog_health.hpp"

namespace trainer::appliance {

std::string_view to_string(LoopHealth health) noexcept {
  switch (health) {
    case LoopHealth::healthy: return "healthy";
    case LoopHealth::not_started: return "not started";
    case LoopHealth::stalled: return "stalled (cycle counter did not advance)";
    case LoopHealth::faulted: return "overrun fault latched";
    case LoopHealth::finished: return "loop finished";
  }
  return "?";
}

WatchdogHealth::WatchdogHealth(std::uint64_t watchdog_usec) noexcept
    : interval_ns_(static_cast<std::int64_t>(watchdog_usec / 2) * 1000) {}

bool WatchdogHealth::should_ping(std::int64_t now_ns, const LoopObservation& loop) noexcept {
  if (interval_ns_ <= 0) return false;
  if (pinged_ && now_ns - last_ping_ns_ < interval_ns_) return false;
  if (loop.finished) {
    health_ = LoopHealth::finished;
  } else if (loop.loop_fault) {
    health_ = LoopHealth::faulted;
  } else if (loop.cycle == 0) {
    health_ = LoopHealth::not_started;
  } else if (pinged_ && loop.cycle <= cycle_at_last_ping_) {
    health_ = LoopHealth::stalled;
  } else {
    health_ = LoopHealth::healthy;
  }
  if (health_ != LoopHealth::healthy) return false;
  pinged_ = true;
  last_ping_ns_ = now_ns;
  cycle_at_last_ping_ = loop.cycle;
  ++pings_;
  return true;
}

}  // namespace trainer::appliance
