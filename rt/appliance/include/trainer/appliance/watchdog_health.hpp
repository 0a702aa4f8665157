// When the supervisor may tell systemd's watchdog that the trainer is alive (WATCHDOG=1). A
// ping says "the RT loop is healthy", so it is sent only when, since the previous ping,
//   * the loop's cycle counter advanced (the RT thread is still running cycles: a loop stuck in
//     a syscall, a dead RT thread or a supervisor that stopped seeing telemetry stops pinging),
//   * the loop has not latched an overrun-streak fault (it no longer keeps time; its outputs
//     are zero and will stay so: a restart is the only way back), and
//   * the run has not ended,
// and at most once per half the watchdog period (sd_watchdog_enabled's WATCHDOG_USEC / 2, as
// sd_watchdog_enabled(3) recommends). Other safety faults (e-stop, enable released, a drive
// fault) do not stop the pings: the loop still runs and holds the outputs at zero, and a
// watchdog restart would re-arm the chain the operator or the hardware just latched.
// Pure: the caller passes the time and what it saw of the loop. Supervisor thread only.
#pragma once

#include <cstdint>
#include <string_view>

namespace trainer::appliance {

struct LoopObservation {
  std::uint64_t cycle = 0;  // the newest telemetry snapshot's cycle counter
  bool loop_fault = false;  // an overrun-streak fault is latched
  bool finished = false;    // the RT loop has returned
};

enum class LoopHealth : std::uint8_t { healthy, not_started, stalled, faulted, finished };
std::string_view to_string(LoopHealth health) noexcept;

class WatchdogHealth {
 public:
  // watchdog_usec: systemd's WATCHDOG_USEC; 0 disables pinging.
  explicit WatchdogHealth(std::uint64_t watchdog_usec) noexcept;

  // Called on every supervisor tick; true when a WATCHDOG=1 is due now (it then counts as
  // sent). The health decision is made only when a ping is due, against the cycle counter at
  // the previous ping.
  bool should_ping(std::int64_t now_ns, const LoopObservation& loop) noexcept;

  // The health seen at the last due ping (healthy when it was sent).
  LoopHealth health() const noexcept { return health_; }
  std::int64_t ping_interval_ns() const noexcept { return interval_ns_; }
  std::uint64_t pings() const noexcept { return pings_; }

 private:
  std::int64_t interval_ns_ = 0;  // 0 = disabled
  bool pinged_ = false;
  std::int64_t last_ping_ns_ = 0;
  std::uint64_t cycle_at_last_ping_ = 0;
  std::uint64_t pings_ = 0;
  LoopHealth health_ = LoopHealth::not_started;
};

}  // namespace trainer::appliance
