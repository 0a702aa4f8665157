// The device side of the USB haptic interface (docs/usb-protocol.md) without any USB: OUT
// report bytes in, IN reports out, the simulated bench's plant (hal::sim::SimDevice, the sim
// backend's plant) behind it and the device watchdog. tools/usbgadget moves the bytes over
// FunctionFS; the tests feed it directly.
//
// Per applied OUT report (the way simdrive's SimDriveBus handles a SYNC): the plant clock (a
// core::ManualClock) advances one frame_ns, the encoders are sampled (counts through
// JointScale's quantisation, sent modulo 2^24), then the report's currents are applied and held
// until the next report (zero-order hold). So plant time advances one frame per exchange
// whatever the speed of the two ends (an emulator, slow motion). The plant's script (the
// simulated hand) starts with the first OUT report.
//
// The watchdog runs on the caller's clock (`now_ns` arguments: CLOCK_MONOTONIC, or / N with
// --slow-motion N), never on plant time: armed by an applied report with enable, it trips when
// no report was applied for watchdog_ms; on_time() then returns the one IN report that tells
// the host. Not thread-safe: the program serialises calls with a mutex.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "trainer/core/clock.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/hal_sim/sim_device.hpp"
#include "trainer/hal_usbproto/protocol.hpp"

namespace trainer::tools::usbgadget {

inline constexpr std::uint16_t kFirmwareVersion = 0x0100;  // 1.0
inline constexpr std::uint16_t kDefaultWatchdogMs = 20;

struct EmulatorParams {
  hal::sim::SimDeviceParams plant;
  std::int64_t frame_ns = 1'000'000;  // plant time per exchange; a multiple of the plant sub-step
  std::uint16_t watchdog_ms = kDefaultWatchdogMs;  // kMinWatchdogMs .. kMaxWatchdogMs
};

struct EmulatorStats {
  std::uint64_t out_received = 0;
  std::uint64_t out_applied = 0;   // answered with an IN report
  std::uint64_t out_rejected = 0;  // refused by decode() or by channel count
  std::array<std::uint64_t, 7> rejected_by_status{};  // index = DecodeStatus
  std::uint64_t out_wrong_channel_count = 0;
  std::uint64_t in_produced = 0;
  std::uint64_t watchdog_trips = 0;
  std::uint64_t clears = 0;
  std::uint64_t current_limited_reports = 0;
};

// Something worth a line in the events file (non-RT: strings).
struct EmulatorEvent {
  std::int64_t t_ns = 0;  // caller's clock
  std::string kind;       // plant_started, enabled, disabled, watchdog_tripped, cleared, out_rejected
  std::string detail;
};

class HapticEmulator {
 public:
  explicit HapticEmulator(EmulatorParams params);

  // Configures the plant; refuses more than 16 channels, a frame that is not a positive
  // multiple of the plant sub-step, a watchdog outside its range. Errors name the value.
  core::Expected<void> configure();

  std::size_t channel_count() const noexcept { return channel_count_; }
  hal::usbproto::Identity identity() const noexcept;
  // SET_WATCHDOG: false (stall) outside kMinWatchdogMs .. kMaxWatchdogMs. The new value takes
  // effect with the next applied OUT report (docs/usb-protocol.md): a request that comes late
  // after the last report cannot trip the watchdog retroactively.
  bool set_watchdog_ms(std::uint16_t watchdog_ms) noexcept;
  // The watchdog set last (in force from the next applied OUT report after a SET_WATCHDOG).
  std::uint16_t watchdog_ms() const noexcept {
    return pending_watchdog_ms_ != 0 ? pending_watchdog_ms_ : watchdog_ms_;
  }

  // One OUT transfer's bytes received at `now_ns`. True when the device answers: `in` is the IN
  // report to send. False when the report was refused (counted, flagged in the next IN report).
  bool on_out_report(std::span<const std::uint8_t> bytes, std::int64_t now_ns,
                     hal::usbproto::InReport& in);
  // The watchdog at `now_ns`: true when it tripped now (`in` tells the host).
  bool on_time(std::int64_t now_ns, hal::usbproto::InReport& in);
  // When on_time() should next be called (INT64_MAX when the watchdog is not armed).
  std::int64_t next_deadline_ns() const noexcept;

  bool tripped() const noexcept { return tripped_; }
  bool enabled() const noexcept { return enabled_; }
  const EmulatorStats& stats() const noexcept { return stats_; }
  const hal::sim::SimDevice& plant() const noexcept { return plant_; }
  std::int64_t plant_time_ns() const noexcept { return plant_.simulated_time_ns(); }
  // Events since the last call.
  std::vector<EmulatorEvent> take_events();

 private:
  void fill_in(hal::usbproto::InReport& in, std::uint16_t extra_status);
  void apply_currents(const hal::usbproto::OutReport& out, bool apply);
  void note(std::int64_t t_ns, std::string kind, std::string detail = {});

  EmulatorParams params_;
  core::ManualClock plant_clock_;
  hal::sim::SimDevice plant_;
  std::size_t channel_count_ = 0;
  std::uint16_t max_current_ma_ = 0;
  std::uint16_t watchdog_ms_ = kDefaultWatchdogMs;  // in force
  std::uint16_t pending_watchdog_ms_ = 0;           // set, in force from the next report

  bool plant_started_ = false;
  bool armed_ = false;
  bool enabled_ = false;
  bool tripped_ = false;
  bool fault_ = false;
  bool rejected_since_in_ = false;
  bool current_limited_ = false;
  std::int64_t last_applied_ns_ = 0;
  std::uint16_t in_sequence_ = 0;
  std::uint16_t out_sequence_applied_ = 0;

  std::array<hal::EncoderSample, hal::sim::kMaxChannels> samples_{};
  std::array<hal::ActuatorCommand, hal::sim::kMaxChannels> commands_{};
  std::array<hal::ActuatorStatus, hal::sim::kMaxChannels> statuses_{};
  std::uint32_t buttons_ = 0;
  EmulatorStats stats_;
  std::vector<EmulatorEvent> events_;
};

}  // namespace trainer::tools::usbgadget
