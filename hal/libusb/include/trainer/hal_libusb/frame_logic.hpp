// UsbFrameLogic: everything the USB backend does per RT cycle that needs no USB — decoding the
// newest IN report, sequence bookkeeping (stale and missed frames, the device's acknowledgement
// of OUT reports and the round-trip latency), counts -> joint positions, efforts -> motor
// currents and the OUT report. UsbDevice owns one and feeds it the reports its libusb event
// thread exchanged; tests drive it with hand-made reports and no device at all.
//
// Definitions (docs/usb-host.md):
//  - stale cycle: a cycle in which no IN report newer (by sequence number) than the last one
//    used arrived, or the one that arrived did not decode; `stale_limit` stale cycles in a row
//    latch UsbFault::device_stopped (the device or the bus stopped delivering). The device
//    answers OUT reports, so a cycle before which no OUT report was published since the
//    restart (the first RT cycle after activate) expects nothing and is not stale; nor is a
//    cycle that comes less than half a period after the OUT report it waits for was
//    published (back-to-back cycles after an overrun: the answer is not due yet; counted as
//    not_due_cycles, the run of stale cycles neither grows nor resets).
//  - missed frame: an IN report the device numbered but the host never received (the gap in
//    the device's sequence minus the reports the event thread did receive). Reports received
//    but superseded before the RT cycle took them are counted apart (in_superseded): the
//    device reports faster than a slow (or slow-motion) loop reads.
//  - round trip: from the RT cycle publishing OUT report s (wall-clock CLOCK_MONOTONIC) to the
//    event thread receiving the first IN report with out_sequence_applied = s.
//
// RT methods are noexcept, allocation-free and never block; configure() is setup only.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "trainer/core/expected.hpp"
#include "trainer/hal/device.hpp"
#include "trainer/hal/joint_scale.hpp"
#include "trainer/core/histogram.hpp"
#include "trainer/hal_usbproto/protocol.hpp"

namespace trainer::hal::libusb {

namespace proto = trainer::hal::usbproto;

// An IN report as the event thread hands it over: raw bytes and when they arrived.
struct RawInReport {
  std::array<std::uint8_t, proto::kReportSize> bytes{};
  std::uint16_t length = 0;
  std::int64_t received_ns = 0;  // CLOCK_MONOTONIC (wall) when the transfer completed
  std::uint64_t index = 0;       // 1, 2, 3 ... per IN report received by the event thread
};

// An OUT report as the RT cycle hands it over.
struct RawOutReport {
  std::array<std::uint8_t, proto::kReportSize> bytes{};
  std::uint16_t sequence = 0;
  std::int64_t published_ns = 0;  // CLOCK_MONOTONIC (wall) when the RT cycle published it
};

// Why the device latched (bits; the first is kept).
enum class UsbFault : std::uint32_t {
  none = 0,
  device_lost = 1U << 0,        // unplugged: hotplug "left" or a transfer saw NO_DEVICE
  device_stopped = 1U << 1,     // stale_limit stale cycles in a row
  watchdog_tripped = 1U << 2,   // the device dropped the currents: OUT reports came too late
  device_fault = 1U << 3,       // the device reports a fault of its own
  channel_mismatch = 1U << 4,   // an IN report with another channel count than configured
  transfer_failed = 1U << 5,    // a transfer could not be resubmitted (other than NO_DEVICE)
};
const char* to_string(UsbFault fault) noexcept;

struct UsbFrameCounters {
  std::uint64_t cycles = 0;             // RT read cycles
  std::uint64_t in_reports_used = 0;    // fresh, decoded IN reports taken by the RT cycle
  std::uint64_t stale_frames = 0;       // stale cycles (see above)
  std::uint64_t not_due_cycles = 0;     // no new IN report, but none was due yet (see above)
  std::uint64_t missed_frames = 0;      // device sequence gaps not received (see above)
  std::uint64_t in_superseded = 0;      // received, overwritten before a cycle took them
  std::uint64_t bad_reports = 0;        // IN reports that did not decode
  std::uint64_t out_published = 0;
  std::uint64_t acks = 0;               // OUT reports acknowledged (round trips measured)
  std::uint64_t acks_unmatched = 0;     // acknowledged sequence not in the timestamp ring
  std::uint64_t watchdog_reports = 0;   // IN reports with the watchdog bit
  std::uint64_t current_limited_cycles = 0;  // device clipped a current
  std::uint64_t out_rejected_reports = 0;    // device says it refused an OUT report
  std::uint32_t stale_run = 0;          // current run of stale cycles
  std::uint32_t stale_run_max = 0;
  proto::DecodeStatus last_bad_status = proto::DecodeStatus::ok;
  std::uint16_t last_status = 0;        // status bits of the newest IN report
  std::uint16_t last_buttons = 0;
  std::uint32_t faults = 0;             // UsbFault bits
  UsbFault first_fault = UsbFault::none;
  std::uint64_t first_fault_cycle = 0;
};

class UsbFrameLogic {
 public:
  // Setup: one scale per channel (1..kMaxChannels), in the device file's channel order.
  // stale_limit >= 1.
  core::Expected<void> configure(std::span<const hal::JointScale> scales,
                                 std::uint32_t stale_limit);
  // Setup / activate: forget sequences, counters, faults and the histogram.
  void reset() noexcept;

  std::size_t channel_count() const noexcept { return channel_count_; }

  // RT, once per cycle before anything else: `fresh` is the newest IN report if one arrived
  // since the previous cycle, else nullptr. `answer_due`: at least half a period passed since
  // the last OUT report was published (the caller's cycle clock).
  void on_cycle(const RawInReport* fresh, bool answer_due = true) noexcept;
  // RT: positions of the newest report (valid = a report was ever received and no fault).
  void fill_encoders(std::span<hal::EncoderSample> out) const noexcept;
  // RT: the next OUT report into `out` (sequence, currents clipped to the limits, enable when
  // any command enables and no fault is latched), with its publication time.
  // clear_watchdog: send the watchdog-clear flag instead of currents (activate only).
  // Returns false when a command was not finite (that channel is sent as 0 mA).
  bool build_out(std::span<const hal::ActuatorCommand> commands, bool clear_watchdog,
                 std::int64_t now_ns, RawOutReport& out) noexcept;
  // RT: per channel what was commanded and what the device says.
  void fill_status(std::span<hal::ActuatorStatus> out) const noexcept;

  // activate(), after its setup exchanges: the RT cycles count from 0 and the round-trip
  // histogram holds the RT cycles' exchanges only (the setup exchanges went through
  // on_cycle() too; the first one includes the device starting its plant).
  void restart_cycle_count() noexcept {
    counters_.cycles = 0;
    counters_.stale_run = 0;
    round_trip_.reset();
    awaiting_answer_ = false;
  }
  void latch(UsbFault fault) noexcept;
  bool latched() const noexcept { return counters_.faults != 0; }
  bool has_report() const noexcept { return has_report_; }
  // The newest decoded IN report (valid when has_report()).
  const proto::InReport& last_report() const noexcept { return last_report_; }
  std::uint16_t last_out_sequence() const noexcept { return out_sequence_; }
  // Whether the device has applied OUT report `sequence` or a later one.
  bool acknowledged(std::uint16_t sequence) const noexcept;

  const UsbFrameCounters& counters() const noexcept { return counters_; }
  const core::LatencyHistogram& round_trip() const noexcept { return round_trip_; }
  // Watchdog bits are a fault only once the device was seen enabled without them (a trip
  // reported at start is what activate() clears).
  void arm_watchdog_check(bool armed) noexcept { watchdog_armed_ = armed; }

  // mA the command `effort` asks of `channel`, clipped to the current limit; `saturated` set
  // when clipped. Public for tests.
  std::int16_t current_ma(std::size_t channel, float effort, bool& saturated) const noexcept;

 private:
  struct Channel {
    hal::JointScale scale;
    double amps_per_effort = 0.0;
    double effort_per_ma = 0.0;
    std::int16_t limit_ma = 0;
    std::int64_t counts = 0;       // unwrapped from the 24-bit wire value
    std::int16_t commanded_ma = 0;
    bool enabled_command = false;
    bool saturated = false;
  };
  static constexpr std::size_t kSentRing = 256;
  struct Sent {
    std::uint16_t sequence = 0;
    std::int64_t published_ns = 0;
    bool valid = false;
  };

  void use_report(const proto::InReport& report, const RawInReport& raw) noexcept;
  void stale_cycle(bool answer_due) noexcept;

  std::array<Channel, proto::kMaxChannels> channels_{};
  std::size_t channel_count_ = 0;
  std::uint32_t stale_limit_ = 2;
  bool has_report_ = false;
  bool watchdog_armed_ = false;
  bool awaiting_answer_ = true;  // an OUT report was published since restart_cycle_count()
  proto::InReport last_report_{};
  std::uint64_t last_index_ = 0;
  std::uint16_t out_sequence_ = 0;
  std::uint16_t last_ack_ = 0;
  bool ack_seen_ = false;
  std::array<Sent, kSentRing> sent_{};
  UsbFrameCounters counters_{};
  core::LatencyHistogram round_trip_{};
};

}  // namespace trainer::hal::libusb
