#include "trainer/hal_gpiod/gpio_device.hpp"

#include <utility>

namespace trainer::hal::gpiod {

const char* to_string(Bias bias) noexcept {
  switch (bias) {
    case Bias::as_is: return "as-is";
    case Bias::disable: return "disable";
    case Bias::pull_up: return "pull-up";
    case Bias::pull_down: return "pull-down";
  }
  return "unknown";
}

std::string describe_line(const LineParams& line) {
  std::string text = "chip '" + line.chip + "' line ";
  if (line.line_name.empty()) {
    text += std::to_string(line.offset);
  } else {
    text += "'" + line.line_name + "'";
  }
  return text;
}

GpioDevice::GpioDevice(GpioDeviceParams params)
    : GpioDevice(std::move(params), make_gpiod_line_io()) {}

GpioDevice::GpioDevice(GpioDeviceParams params, std::unique_ptr<LineIo> io)
    : params_(std::move(params)), io_(std::move(io)) {}

GpioDevice::~GpioDevice() {
  deactivate();
}

core::Expected<void> GpioDevice::check_params() const {
  const std::string device = params_.name + ": ";
  if (params_.lines.size() > kMaxLines) {
    return core::make_error(device + std::to_string(params_.lines.size()) +
                            " GPIO lines: at most " + std::to_string(kMaxLines));
  }
  if (params_.consumer.empty()) return core::make_error(device + "empty GPIO consumer name");
  for (std::size_t i = 0; i < params_.lines.size(); ++i) {
    const LineParams& line = params_.lines[i];
    if (line.bit < 0 || line.bit > 31) {
      return core::make_error(device + line.config_key + " (" + describe_line(line) + "): bit " +
                              std::to_string(line.bit) + " is not 0..31");
    }
    if (line.chip.empty() || (line.line_name.empty() && line.offset < 0)) {
      return core::make_error(device + line.config_key +
                              ": needs a chip and a line name or offset");
    }
    for (std::size_t k = 0; k < i; ++k) {
      const LineParams& other = params_.lines[k];
      if (other.direction == line.direction && other.bit == line.bit) {
        return core::make_error(device + line.config_key + " (" + describe_line(line) + "): bit " +
                                std::to_string(line.bit) + " is already " + other.config_key +
                                "'s");
      }
    }
  }
  return {};
}

core::Expected<void> GpioDevice::claim_lines() {
  if (claimed_) return {};
  if (auto claimed = io_->claim(params_.lines, params_.consumer); !claimed) {
    return core::make_error(params_.name + ": " + claimed.error().message);
  }
  claimed_ = true;
  out_levels_.fill(0);
  return {};
}

core::Expected<void> GpioDevice::configure() {
  if (state_ == LifecycleState::active) {
    return core::make_error(params_.name + ": configure() while active");
  }
  if (auto checked = check_params(); !checked) return checked;
  input_count_ = 0;
  output_count_ = 0;
  for (const LineParams& line : params_.lines) {
    if (line.direction == Direction::input) {
      ++input_count_;
    } else {
      ++output_count_;
    }
  }
  if (auto claimed = claim_lines(); !claimed) return claimed;
  state_ = LifecycleState::inactive;
  return {};
}

core::Expected<void> GpioDevice::activate() {
  if (state_ == LifecycleState::unconfigured) {
    return core::make_error(params_.name + ": activate() before configure()");
  }
  if (auto claimed = claim_lines(); !claimed) return claimed;
  // Events that arrived while inactive say nothing about this run: drop them, and with
  // them a stale "changed".
  for (std::size_t i = 0; i < params_.lines.size(); ++i) {
    if (params_.lines[i].direction != Direction::input) continue;
    bool active = false;
    bool changed = false;
    (void)io_->sample_input(i, active, changed);
  }
  state_ = LifecycleState::active;
  return {};
}

void GpioDevice::drive_outputs_inactive() noexcept {
  out_levels_.fill(0);
  if (output_count_ > 0) (void)io_->write_outputs(out_levels_);
}

void GpioDevice::deactivate() noexcept {
  if (claimed_) {
    drive_outputs_inactive();
    io_->release();
    claimed_ = false;
  }
  if (state_ == LifecycleState::active) state_ = LifecycleState::inactive;
}

ReturnCode GpioDevice::read_digital_inputs(std::uint32_t& levels) noexcept {
  levels = 0;
  if (!claimed_) {
    ++stats_.read_errors;
    return ReturnCode::error;
  }
  ++stats_.reads;
  ReturnCode result = ReturnCode::ok;
  for (std::size_t i = 0; i < params_.lines.size(); ++i) {
    const LineParams& line = params_.lines[i];
    if (line.direction != Direction::input) continue;
    bool active = false;
    bool changed = false;
    if (io_->sample_input(i, active, changed) != ReturnCode::ok) {
      result = ReturnCode::error;
      continue;
    }
    bool reported = active;
    if (changed) {
      const bool latch_level = line.latch == Latch::active;
      ++stats_.changed_reads[i];
      stats_.last_change_event_ns[i] = io_->oldest_event_ns(i);
      if (active != latch_level) ++stats_.pulses_latched[i];
      reported = latch_level;
    }
    if (reported) levels |= 1U << static_cast<unsigned>(line.bit);
  }
  if (result != ReturnCode::ok) ++stats_.read_errors;
  return result;
}

ReturnCode GpioDevice::write_digital_outputs(std::uint32_t levels) noexcept {
  if (!claimed_) {
    ++stats_.write_errors;
    return ReturnCode::error;
  }
  for (std::size_t i = 0; i < params_.lines.size(); ++i) {
    const LineParams& line = params_.lines[i];
    if (line.direction != Direction::output) continue;
    out_levels_[i] = static_cast<std::uint8_t>((levels >> static_cast<unsigned>(line.bit)) & 1U);
  }
  const ReturnCode written = io_->write_outputs(out_levels_);
  if (written != ReturnCode::ok) ++stats_.write_errors;
  return written;
}

}  // namespace trainer::hal::gpiod
