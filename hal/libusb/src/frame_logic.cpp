#include "trainer/hal_libusb/frame_logic.hpp"

#include <algorithm>
#include <cmath>

namespace trainer::hal::libusb {

const char* to_string(UsbFault fault) noexcept {
  switch (fault) {
    case UsbFault::none: return "none";
    case UsbFault::device_lost: return "device_lost";
    case UsbFault::device_stopped: return "device_stopped";
    case UsbFault::watchdog_tripped: return "watchdog_tripped";
    case UsbFault::device_fault: return "device_fault";
    case UsbFault::channel_mismatch: return "channel_mismatch";
    case UsbFault::transfer_failed: return "transfer_failed";
  }
  return "unknown";
}

core::Expected<void> UsbFrameLogic::configure(std::span<const hal::JointScale> scales,
                                              std::uint32_t stale_limit) {
  if (scales.empty() || scales.size() > proto::kMaxChannels) {
    return core::make_error(std::to_string(scales.size()) + " channels, expected 1.." +
                            std::to_string(proto::kMaxChannels) + " (the protocol's limit)");
  }
  if (stale_limit < 1) return core::make_error("stale limit 0, expected at least 1 cycle");
  for (std::size_t i = 0; i < scales.size(); ++i) {
    const double per_amp = scales[i].effort_per_amp();
    const double per_count = scales[i].position_per_count();
    if (!(per_amp > 0.0) || !std::isfinite(per_amp) || !(per_count > 0.0) ||
        !std::isfinite(per_count) || !(scales[i].current_limit_a > 0.0)) {
      return core::make_error("channel " + std::to_string(i) +
                              ": the joint scale needs positive counts, gear, torque constant "
                              "and current limit");
    }
    Channel& channel = channels_[i];
    channel = Channel{};
    channel.scale = scales[i];
    // motor_direction -1: the current is sent negated, the reported one read back negated.
    channel.amps_per_effort = scales[i].motor_sign() / per_amp;
    channel.effort_per_ma = per_amp * 1e-3 * scales[i].motor_sign();
    const double limit_ma = std::floor(scales[i].current_limit_a * 1000.0);
    channel.limit_ma = static_cast<std::int16_t>(std::clamp(limit_ma, 1.0, 32767.0));
  }
  channel_count_ = scales.size();
  stale_limit_ = stale_limit;
  reset();
  return {};
}

void UsbFrameLogic::reset() noexcept {
  for (Channel& channel : channels_) {
    channel.counts = 0;
    channel.commanded_ma = 0;
    channel.enabled_command = false;
    channel.saturated = false;
  }
  has_report_ = false;
  watchdog_armed_ = false;
  awaiting_answer_ = true;
  last_report_ = proto::InReport{};
  last_index_ = 0;
  out_sequence_ = 0;
  last_ack_ = 0;
  ack_seen_ = false;
  sent_.fill(Sent{});
  counters_ = UsbFrameCounters{};
  round_trip_.reset();
}

void UsbFrameLogic::latch(UsbFault fault) noexcept {
  if (counters_.faults == 0) {
    counters_.first_fault = fault;
    counters_.first_fault_cycle = counters_.cycles;
  }
  counters_.faults |= static_cast<std::uint32_t>(fault);
}

void UsbFrameLogic::stale_cycle(bool answer_due) noexcept {
  if (!answer_due) {
    ++counters_.not_due_cycles;
    return;
  }
  ++counters_.stale_frames;
  ++counters_.stale_run;
  counters_.stale_run_max = std::max(counters_.stale_run_max, counters_.stale_run);
  if (counters_.stale_run >= stale_limit_) latch(UsbFault::device_stopped);
}

void UsbFrameLogic::on_cycle(const RawInReport* fresh, bool answer_due) noexcept {
  ++counters_.cycles;
  if (fresh == nullptr) {
    if (awaiting_answer_) stale_cycle(answer_due);
    return;
  }
  proto::InReport report;
  const proto::DecodeStatus status =
      proto::decode(std::span<const std::uint8_t>(fresh->bytes.data(), fresh->length), report);
  if (status != proto::DecodeStatus::ok) {
    ++counters_.bad_reports;
    counters_.last_bad_status = status;
    stale_cycle(true);
    return;
  }
  if (report.channel_count != channel_count_) {
    latch(UsbFault::channel_mismatch);
    stale_cycle(true);
    return;
  }
  // The same report again (or an older one): nothing new from the device this cycle.
  if (has_report_) {
    const std::uint16_t ahead = proto::sequence_distance(report.sequence, last_report_.sequence);
    if (ahead == 0 || ahead >= 0x8000U) {
      stale_cycle(answer_due);
      return;
    }
  }
  use_report(report, *fresh);
}

void UsbFrameLogic::use_report(const proto::InReport& report, const RawInReport& raw) noexcept {
  if (has_report_) {
    const std::uint64_t device_gap = proto::sequence_distance(report.sequence, last_report_.sequence);
    const std::uint64_t received_gap = raw.index > last_index_ ? raw.index - last_index_ : 1;
    counters_.in_superseded += received_gap - 1;
    if (device_gap > received_gap) counters_.missed_frames += device_gap - received_gap;
  }
  for (std::size_t i = 0; i < channel_count_; ++i) {
    Channel& channel = channels_[i];
    channel.counts = has_report_ ? proto::extend_count(channel.counts, report.counts[i])
                                 : std::int64_t{report.counts[i]};
  }
  // Round trip: the first IN report that acknowledges an OUT report we timestamped.
  const std::uint16_t applied = report.out_sequence_applied;
  if (counters_.out_published > 0 && (!ack_seen_ || applied != last_ack_) &&
      proto::sequence_distance(out_sequence_, applied) < kSentRing) {
    Sent& sent = sent_[applied % kSentRing];
    if (sent.valid && sent.sequence == applied) {
      round_trip_.record(raw.received_ns - sent.published_ns);
      ++counters_.acks;
      sent.valid = false;
    } else {
      ++counters_.acks_unmatched;
    }
    last_ack_ = applied;
    ack_seen_ = true;
  }
  if ((report.status & proto::kStatusWatchdogTripped) != 0U) {
    ++counters_.watchdog_reports;
    if (watchdog_armed_) latch(UsbFault::watchdog_tripped);
  }
  if ((report.status & proto::kStatusFault) != 0U && watchdog_armed_) {
    latch(UsbFault::device_fault);
  }
  if ((report.status & proto::kStatusCurrentLimited) != 0U) ++counters_.current_limited_cycles;
  if ((report.status & proto::kStatusOutRejected) != 0U) ++counters_.out_rejected_reports;
  counters_.last_status = report.status;
  counters_.last_buttons = report.buttons;
  counters_.stale_run = 0;
  ++counters_.in_reports_used;
  last_report_ = report;
  last_index_ = raw.index;
  has_report_ = true;
}

bool UsbFrameLogic::acknowledged(std::uint16_t sequence) const noexcept {
  if (!ack_seen_) return false;
  // applied is `sequence` or later (within half the sequence space).
  return proto::sequence_distance(last_ack_, sequence) < 0x8000U;
}

void UsbFrameLogic::fill_encoders(std::span<hal::EncoderSample> out) const noexcept {
  const std::size_t count = std::min(out.size(), channel_count_);
  for (std::size_t i = 0; i < count; ++i) {
    const Channel& channel = channels_[i];
    out[i].counts = channel.counts;
    out[i].position = static_cast<float>(channel.scale.position_from_counts(channel.counts));
    out[i].valid = has_report_ && !latched();
  }
}

std::int16_t UsbFrameLogic::current_ma(std::size_t channel, float effort,
                                       bool& saturated) const noexcept {
  const Channel& c = channels_[channel];
  const double ma = static_cast<double>(effort) * c.amps_per_effort * 1000.0;
  const auto limit = static_cast<double>(c.limit_ma);
  saturated = std::fabs(ma) > limit;
  return static_cast<std::int16_t>(std::lround(std::clamp(ma, -limit, limit)));
}

bool UsbFrameLogic::build_out(std::span<const hal::ActuatorCommand> commands, bool clear_watchdog,
                              std::int64_t now_ns, RawOutReport& out) noexcept {
  proto::OutReport report;
  report.sequence = ++out_sequence_;
  report.channel_count = static_cast<std::uint8_t>(channel_count_);
  bool all_finite = true;
  bool any_enable = false;
  for (std::size_t i = 0; i < channel_count_; ++i) {
    Channel& channel = channels_[i];
    const hal::ActuatorCommand command =
        i < commands.size() ? commands[i] : hal::ActuatorCommand{};
    const bool finite = std::isfinite(command.effort);
    all_finite = all_finite && finite;
    const bool enable = command.enable && finite && !latched() && !clear_watchdog;
    bool saturated = false;
    channel.commanded_ma = enable ? current_ma(i, command.effort, saturated) : std::int16_t{0};
    channel.enabled_command = enable;
    channel.saturated = saturated;
    report.current_ma[i] = channel.commanded_ma;
    any_enable = any_enable || enable;
  }
  if (clear_watchdog) {
    report.flags = proto::kOutFlagClearWatchdog;
  } else if (any_enable) {
    report.flags = proto::kOutFlagEnable;
  }
  (void)proto::encode(report, out.bytes);  // cannot fail: counts and flags are in range
  out.sequence = report.sequence;
  out.published_ns = now_ns;
  sent_[report.sequence % kSentRing] = Sent{report.sequence, now_ns, true};
  awaiting_answer_ = true;
  ++counters_.out_published;
  return all_finite;
}

void UsbFrameLogic::fill_status(std::span<hal::ActuatorStatus> out) const noexcept {
  const std::size_t count = std::min(out.size(), channel_count_);
  const bool device_enabled =
      has_report_ && (counters_.last_status & proto::kStatusEnabled) != 0U && !latched();
  const bool device_fault =
      (counters_.last_status & (proto::kStatusFault | proto::kStatusWatchdogTripped)) != 0U;
  for (std::size_t i = 0; i < count; ++i) {
    const Channel& channel = channels_[i];
    hal::ActuatorStatus& status = out[i];
    status.enabled = device_enabled && channel.enabled_command;
    status.applied_effort =
        status.enabled ? static_cast<float>(channel.commanded_ma * channel.effort_per_ma) : 0.0F;
    status.saturated = channel.saturated;
    status.fault = latched() || (watchdog_armed_ && device_fault);
  }
}

}  // namespace trainer::hal::libusb
