// What systemd hears from the trainer as a Type=notify service (docs/appliance.md), all from
// the supervisor thread, which calls observe() with each new telemetry snapshot and tick() on
// every pass (~30 Hz):
//   * READY=1 once the trainer is armed-ready: the RT thread has run at least one cycle (its RT
//     settings applied, the device active) and the safety chain is armed (the snapshot shows no
//     latched fault); with arm = false (--no-arm), once it runs. Until then, STATUS= says which
//     faults keep it from arming.
//   * WATCHDOG=1 while the loop is healthy (appliance::WatchdogHealth: its cycle counter
//     advanced since the last ping, no overrun-streak fault latched, the loop still running),
//     at WATCHDOG_USEC / 2; STATUS= on every change of that health.
//   * STOPPING=1 when the loop ends.
// Nothing is sent outside a unit (NOTIFY_SOCKET unset).
#pragma once

#include <cstdint>
#include <string>

#include "trainer/app/telemetry.hpp"
#include "trainer/appliance/service_notifier.hpp"
#include "trainer/appliance/watchdog_health.hpp"

namespace trainer::app {

class ServiceSupervision {
 public:
  ServiceSupervision(bool arm, std::string scene_name, std::int64_t period_ns);

  void observe(const TelemetrySnapshot& snapshot) noexcept;
  // now_ns: a monotonic time (the supervisor passes steady_clock's).
  void tick(bool finished, std::int64_t now_ns);
  void stopping(bool by_signal) const;

  bool ready_sent() const noexcept { return ready_; }
  const appliance::WatchdogHealth& watchdog() const noexcept { return watchdog_; }

 private:
  appliance::ServiceNotifier notifier_;
  appliance::WatchdogHealth watchdog_;
  bool arm_;
  std::string scene_name_;
  double rate_hz_;
  std::uint64_t cycle_ = 0;
  std::uint32_t latched_faults_ = 0;
  std::uint32_t waiting_faults_ = 0;
  bool ready_ = false;
  appliance::LoopHealth reported_health_ = appliance::LoopHealth::healthy;
};

}  // namespace trainer::app
