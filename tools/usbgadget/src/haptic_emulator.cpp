#include "haptic_emulator.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace trainer::tools::usbgadget {

namespace up = hal::usbproto;

HapticEmulator::HapticEmulator(EmulatorParams params)
    : params_(std::move(params)), plant_(plant_clock_, params_.plant),
      watchdog_ms_(params_.watchdog_ms) {}

core::Expected<void> HapticEmulator::configure() {
  if (params_.watchdog_ms < up::kMinWatchdogMs || params_.watchdog_ms > up::kMaxWatchdogMs) {
    return core::make_error("watchdog " + std::to_string(params_.watchdog_ms) +
                            " ms: expected " + std::to_string(up::kMinWatchdogMs) + ".." +
                            std::to_string(up::kMaxWatchdogMs) + " ms");
  }
  const std::int64_t substep = params_.plant.plant_substep_ns;
  if (params_.frame_ns <= 0 || substep <= 0 || params_.frame_ns % substep != 0 ||
      params_.frame_ns / 1000 > std::numeric_limits<std::uint32_t>::max()) {
    return core::make_error("frame " + std::to_string(params_.frame_ns) +
                            " ns: expected a positive multiple of the plant sub-step (" +
                            std::to_string(substep) + " ns)");
  }
  if (auto configured = plant_.configure(); !configured) return configured;
  channel_count_ = plant_.channel_count();
  if (channel_count_ > up::kMaxChannels) {
    return core::make_error(std::to_string(channel_count_) +
                            " channels: the USB protocol carries at most 16 (3 instruments)");
  }
  double max_current_a = 0.0;
  for (const auto& instrument : params_.plant.instruments) {
    for (const auto& scale : instrument.scales) max_current_a = std::max(max_current_a, scale.current_limit_a);
  }
  max_current_ma_ = static_cast<std::uint16_t>(std::clamp(std::lround(max_current_a * 1e3), 0L, 65535L));
  watchdog_ms_ = params_.watchdog_ms;
  return {};
}

up::Identity HapticEmulator::identity() const noexcept {
  up::Identity identity;
  identity.protocol_version = up::kProtocolVersion;
  identity.firmware_version = kFirmwareVersion;
  identity.channel_count = static_cast<std::uint8_t>(channel_count_);
  identity.watchdog_ms = watchdog_ms();
  identity.frame_interval_us = static_cast<std::uint32_t>(params_.frame_ns / 1000);
  identity.max_current_ma = max_current_ma_;
  return identity;
}

bool HapticEmulator::set_watchdog_ms(std::uint16_t watchdog_ms) noexcept {
  if (watchdog_ms < up::kMinWatchdogMs || watchdog_ms > up::kMaxWatchdogMs) return false;
  pending_watchdog_ms_ = watchdog_ms;
  return true;
}

void HapticEmulator::note(std::int64_t t_ns, std::string kind, std::string detail) {
  events_.push_back({t_ns, std::move(kind), std::move(detail)});
}

std::vector<EmulatorEvent> HapticEmulator::take_events() {
  std::vector<EmulatorEvent> taken;
  taken.swap(events_);
  return taken;
}

void HapticEmulator::fill_in(up::InReport& in, std::uint16_t extra_status) {
  in = up::InReport{};
  in.sequence = ++in_sequence_;
  in.out_sequence_applied = out_sequence_applied_;
  in.device_time_us = static_cast<std::uint32_t>(
      static_cast<std::uint64_t>(plant_.simulated_time_ns() / 1000) & 0xFFFFFFFFU);
  std::uint16_t status = extra_status;
  if (tripped_) status |= up::kStatusWatchdogTripped;
  if (fault_) status |= up::kStatusFault;
  if (enabled_ && !tripped_ && !fault_) status |= up::kStatusEnabled;
  if (current_limited_) status |= up::kStatusCurrentLimited;
  if (rejected_since_in_) status |= up::kStatusOutRejected;
  in.status = status;
  in.buttons = static_cast<std::uint16_t>(buttons_ & 0xFFFFU);
  in.channel_count = static_cast<std::uint8_t>(channel_count_);
  for (std::size_t i = 0; i < channel_count_; ++i) in.counts[i] = up::wire_count(samples_[i].counts);
  rejected_since_in_ = false;
  ++stats_.in_produced;
}

void HapticEmulator::apply_currents(const up::OutReport& out, bool apply) {
  const auto& instruments = params_.plant.instruments;
  for (std::size_t i = 0; i < channel_count_; ++i) {
    const hal::JointScale& scale =
        instruments[i / hal::sim::kJointsPerInstrument].scales[i % hal::sim::kJointsPerInstrument];
    const double current_a = apply ? static_cast<double>(out.current_ma[i]) * 1e-3 : 0.0;
    commands_[i] = {static_cast<float>(current_a * scale.effort_per_amp()), apply};
  }
  if (plant_.state() != hal::LifecycleState::active) return;
  (void)plant_.write_actuators(std::span(commands_.data(), channel_count_));
  (void)plant_.read_actuator_status(std::span(statuses_.data(), channel_count_));
  current_limited_ = false;
  for (std::size_t i = 0; i < channel_count_; ++i) {
    current_limited_ = current_limited_ || statuses_[i].saturated;
    if (statuses_[i].fault && !fault_) {
      fault_ = true;
      enabled_ = false;
    }
  }
}

bool HapticEmulator::on_out_report(std::span<const std::uint8_t> bytes, std::int64_t now_ns,
                                   up::InReport& in) {
  ++stats_.out_received;
  up::OutReport out;
  const up::DecodeStatus status = up::decode(bytes, out);
  if (status != up::DecodeStatus::ok || out.channel_count != channel_count_) {
    ++stats_.out_rejected;
    rejected_since_in_ = true;
    if (status != up::DecodeStatus::ok) {
      ++stats_.rejected_by_status[static_cast<std::size_t>(status)];
      if (stats_.out_rejected <= 10) note(now_ns, "out_rejected", up::to_string(status));
    } else {
      ++stats_.out_wrong_channel_count;
      if (stats_.out_rejected <= 10) {
        note(now_ns, "out_rejected",
             "channel_count " + std::to_string(out.channel_count) + ", device has " +
                 std::to_string(channel_count_));
      }
    }
    return false;
  }
  if (!plant_started_) {
    if (plant_.activate()) {
      plant_started_ = true;
      note(now_ns, "plant_started", "first OUT report");
    } else {
      note(now_ns, "plant_error", "plant did not activate");
    }
  }

  // The latch and the enable state this report leaves.
  bool apply = false;
  if (tripped_ || fault_) {
    if ((out.flags & up::kOutFlagClearWatchdog) != 0) {
      tripped_ = false;
      fault_ = false;
      armed_ = false;
      ++stats_.clears;
      note(now_ns, "cleared", "OUT sequence " + std::to_string(out.sequence));
    }
    enabled_ = false;
  } else {
    const bool enable = (out.flags & up::kOutFlagEnable) != 0;
    if (enable != enabled_) note(now_ns, enable ? "enabled" : "disabled", "OUT sequence " + std::to_string(out.sequence));
    enabled_ = enable;
    armed_ = enable;
    apply = enable;
  }

  // The plant, as at a SYNC: time, sample, then the new command (held until the next report).
  plant_clock_.advance_ns(params_.frame_ns);
  (void)plant_.read_encoders(std::span(samples_.data(), channel_count_));
  (void)plant_.read_digital_inputs(buttons_);
  apply_currents(out, apply);
  if (current_limited_) ++stats_.current_limited_reports;

  last_applied_ns_ = now_ns;
  if (pending_watchdog_ms_ != 0) {
    watchdog_ms_ = pending_watchdog_ms_;
    pending_watchdog_ms_ = 0;
  }
  out_sequence_applied_ = out.sequence;
  ++stats_.out_applied;
  fill_in(in, 0);
  return true;
}

bool HapticEmulator::on_time(std::int64_t now_ns, up::InReport& in) {
  if (!armed_ || tripped_) return false;
  if (now_ns - last_applied_ns_ <= static_cast<std::int64_t>(watchdog_ms_) * 1'000'000) return false;
  tripped_ = true;
  enabled_ = false;
  ++stats_.watchdog_trips;
  up::OutReport zero;
  apply_currents(zero, false);
  note(now_ns, "watchdog_tripped",
       "no OUT report for " + std::to_string((now_ns - last_applied_ns_) / 1'000'000) +
           " ms (watchdog " + std::to_string(watchdog_ms_) + " ms)");
  fill_in(in, up::kStatusNoNewOut);
  return true;
}

std::int64_t HapticEmulator::next_deadline_ns() const noexcept {
  if (!armed_ || tripped_) return std::numeric_limits<std::int64_t>::max();
  return last_applied_ns_ + static_cast<std::int64_t>(watchdog_ms_) * 1'000'000 + 1;
}

}  // namespace trainer::tools::usbgadget
