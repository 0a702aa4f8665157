// The simulated drives' events log: what happened on which node and when, for tests and for the
// program's --events file (one JSON object per line, docs/simdrive.md "Events log").
//
// Recording (SimDriveBus::poll, RT-style: noexcept, no heap): EventLog::push() copies a small
// plain record into a ring sized at setup; when the ring is full the OLDEST record is kept and
// the new one dropped and counted (a log that overwrote its start would lose the boot and the
// first fault, which tests measure from). Reading (the program's main loop, tests): pop() or
// snapshot(), then to_json() (allocates).
//
// Times are the `now_ns` the bus was polled with: CLOCK_MONOTONIC in the program, whatever the
// test passes in tests. Not thread-safe: record and read from the thread that polls the bus.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace trainer::hal::simdrive {

enum class EventKind : std::uint8_t {
  boot,                        // boot-up message queued (power-on, NMT reset, reboot)
  nmt_state,                   // a = from, b = to (canopen::NmtState values)
  power_state,                 // a = from, b = to (canopen::PowerState values), cause
  master_heartbeat_seen,       // a = producer node, b = consumer time ms: monitoring starts
  master_heartbeat_lost,       // a = producer node, b = consumer time ms
  master_heartbeat_recovered,  // a = producer node
  rpdo_deadline_expired,       // a = RPDO number, b = event timer ms
  torque_removed,              // the drive function went off; cause
  torque_enabled,              // the drive function went on (operation enabled); cause
  abort_connection,            // a = 0x6007 option applied, cause
  fault_injected,              // text = the fault spec
  fault_cleared,               // text = which fault ran out or was cleared
  emcy_sent,                   // a = error code, b = error register; text "suppressed" when
                               // the node could not send it (silent, stopped, bus-off)
  plant_started,               // the first NMT start: the plant's script time begins
};
const char* to_string(EventKind kind) noexcept;

inline constexpr std::size_t kEventTextBytes = 56;

struct DriveEvent {
  std::int64_t t_ns = 0;
  std::uint64_t sync = 0;  // SYNCs the bus had received when it happened
  std::uint8_t node = 0;   // node id, 0 = the bus as a whole
  EventKind kind = EventKind::boot;
  std::uint32_t a = 0;
  std::uint32_t b = 0;
  const char* cause = nullptr;               // static text or null
  std::array<char, kEventTextBytes> text{};  // NUL-terminated, may be empty
};

// One JSON object (no trailing newline), e.g.
//   {"t_ns":1234,"sync":10,"node":3,"event":"power_state","from":"switched on",
//    "to":"operation enabled","cause":"controlword (RPDO)"}
std::string to_json(const DriveEvent& event);

class EventLog {
 public:
  // Setup: room for `capacity` records (at least 1).
  explicit EventLog(std::size_t capacity = 4096);

  // False (and counted in dropped()) when full.
  bool push(const DriveEvent& event) noexcept;
  // Oldest first; false when empty.
  bool pop(DriveEvent& out) noexcept;
  std::size_t size() const noexcept { return count_; }
  std::size_t capacity() const noexcept { return ring_.size(); }
  std::uint64_t dropped() const noexcept { return dropped_; }
  std::uint64_t recorded() const noexcept { return recorded_; }
  // Copies of the waiting records, oldest first (allocates; tests and reports).
  std::vector<DriveEvent> snapshot() const;
  void clear() noexcept { head_ = count_ = 0; }

 private:
  std::vector<DriveEvent> ring_;
  std::size_t head_ = 0;
  std::size_t count_ = 0;
  std::uint64_t dropped_ = 0;
  std::uint64_t recorded_ = 0;
};

}  // namespace trainer::hal::simdrive
