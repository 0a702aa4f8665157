// The CAN part's small CANopen master (tools/hil, not the RT path): SYNC, RPDO1 and the master's
// heartbeat every period, TPDO1 and EMCY decoded with their arrival times, per drive, with the
// trainer's PDO layout (hal/socketcan pdo_layout()) and the CiA 402 controlword walk of
// hal/canopen. Unlike the trainer's CanopenDevice it can stop its heartbeat on purpose, keeps
// every time stamp and blocks between SYNCs. Times are bench times: CLOCK_MONOTONIC divided by
// the slow-motion factor, the time line simdrive --slow-motion runs on.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "trainer/core/clock.hpp"
#include "trainer/hal/joint_scale.hpp"
#include "trainer/hal_socketcan/can_transport.hpp"

namespace trainer::hil::can {

struct MasterDrive {
  std::uint8_t node = 0;
  std::string who;  // "node 2 (left.yaw)"
  hal::JointScale scale;
  // Commands (RPDO1): walk toward Operation enabled when `enable`, else toward Switch on
  // disabled; the torque is sent only in Operation enabled.
  bool enable = false;
  std::int16_t target_permille = 0;
  std::uint16_t controlword = 0;
  // Latest TPDO1.
  bool tpdo_seen = false;
  std::uint16_t statusword = 0;
  std::int32_t position = 0;
  std::int16_t torque_permille = 0;
  std::int64_t tpdo_ns = 0;
  bool answered_last_sync = false;
  // First EMCY since clear_events().
  std::optional<std::uint16_t> emcy_code;
  std::int64_t emcy_ns = 0;
  bool booted = false;  // a boot-up message came since clear_events()
};

struct BusRecord {
  std::vector<double> sync_interval_error_ns;  // |interval - period| between SYNCs sent
  std::vector<double> round_trip_ns;           // SYNC sent -> TPDO1 received, every drive
  std::uint64_t syncs = 0;
  std::uint64_t missing_tpdos = 0;  // a drive's TPDO1 not in before the next SYNC
};

class Master {
 public:
  Master(hal::socketcan::CanTransport& bus, std::int64_t slow_motion, std::int64_t period_ns,
         std::uint8_t master_node, std::int64_t heartbeat_ns);
  ~Master();
  Master(const Master&) = delete;
  Master& operator=(const Master&) = delete;

  std::vector<MasterDrive> drives;
  bool heartbeat_on = true;
  bool record = false;
  BusRecord recorded;

  std::int64_t now_ns() noexcept { return clock_.now_ns(); }
  std::int64_t period_ns() const noexcept { return period_ns_; }
  std::int64_t last_heartbeat_ns() const noexcept { return last_heartbeat_ns_; }
  // One period: RPDO1 of every drive, SYNC, the heartbeat when due, then frames until the
  // period ends. Throws Interrupted on SIGINT/SIGTERM (the caller's guard removes the torque).
  void cycle();
  void cycles(std::int64_t count) {
    for (std::int64_t i = 0; i < count; ++i) cycle();
  }
  // Cycles until `done` or `timeout_ns` (bench time); false on timeout.
  template <class Done>
  bool cycle_until(Done&& done, std::int64_t timeout_ns) {
    const std::int64_t deadline = now_ns() + timeout_ns;
    while (now_ns() < deadline) {
      cycle();
      if (done()) return true;
    }
    return false;
  }
  void clear_events() noexcept;
  // Torque off at once, whatever the state: RPDO1 disable voltage + zero torque, a SYNC, NMT
  // enter pre-operational, to every drive. Never throws, never blocks.
  void torque_off() noexcept;

 private:
  void handle(const can_frame& frame) noexcept;

  hal::socketcan::CanTransport& bus_;
  core::SlowMotionClock clock_;
  std::int64_t slow_motion_;
  std::int64_t period_ns_;
  std::uint8_t master_node_;
  std::int64_t heartbeat_ns_;
  std::int64_t next_ns_ = 0;
  std::int64_t next_heartbeat_ns_ = 0;
  std::int64_t last_heartbeat_ns_ = 0;
  std::int64_t last_sync_ns_ = 0;
  bool started_ = false;
};

// Operation enabled per the statusword.
bool operation_enabled(std::uint16_t statusword) noexcept;

// Nearest-rank percentile of `values` (sorted copy); 0 when empty.
double percentile(std::vector<double> values, double p);

}  // namespace trainer::hil::can
