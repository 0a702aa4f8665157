// The CiA 402 power state machine of a drive (IEC 61800-7-201, 6.2.1: states, transitions
// 0..16, option codes 0x605A..0x605E and 0x6007).
#include "trainer/hal_canopen/cia402_drive.hpp"

#include <algorithm>

namespace trainer::hal::canopen {

namespace {

bool quick_stop_stays_active(std::int16_t option) noexcept { return option >= 5 && option <= 8; }

}  // namespace

bool valid_options(const Cia402Options& options) noexcept {
  return options.quick_stop_option >= 0 && options.quick_stop_option <= 8 && options.shutdown_option >= 0 &&
         options.shutdown_option <= 1 && options.disable_operation_option >= 0 &&
         options.disable_operation_option <= 1 && options.fault_reaction_option >= 0 &&
         options.fault_reaction_option <= 4 && options.abort_connection_option >= 0 &&
         options.abort_connection_option <= 3 && options.slow_down_ramp_ns >= 0 && options.quick_stop_ramp_ns >= 0;
}

Cia402StateMachine::Cia402StateMachine(const Cia402Options& options) noexcept {
  if (valid_options(options)) options_ = options;
  reset();
}

bool Cia402StateMachine::set_options(const Cia402Options& options) noexcept {
  if (!valid_options(options)) return false;
  options_ = options;
  return true;
}

void Cia402StateMachine::reset() noexcept {
  transitions_ = 0;
  stop_ = Stop::none;
  stop_finished_ = false;
  previous_controlword_ = 0;
  error_code_ = 0;
  held_torque_ = 0.0;
  enter(PowerState::not_ready_to_switch_on, 0);
}

void Cia402StateMachine::enter(PowerState state, unsigned transition) noexcept {
  state_ = state;
  transitions_ |= 1U << transition;
  if (state == PowerState::operation_enabled) {
    scale_ = 1.0;
  } else if (state != PowerState::quick_stop_active && state != PowerState::fault_reaction_active) {
    scale_ = 0.0;  // drive function disabled
  }
}

void Cia402StateMachine::update(std::uint16_t controlword, std::int64_t now_ns) noexcept {
  transitions_ = 0;
  const bool reset_edge =
      (previous_controlword_ & kControlFaultReset) == 0 && (controlword & kControlFaultReset) != 0;
  previous_controlword_ = controlword;
  advance_ramp(now_ns);
  switch (state_) {
    case PowerState::not_ready_to_switch_on:
      enter(PowerState::switch_on_disabled, 1);  // initialisation and self-test done
      return;
    case PowerState::fault:
      if (reset_edge && !fault_present_) {
        error_code_ = 0;
        enter(PowerState::switch_on_disabled, 15);
      }
      return;
    case PowerState::fault_reaction_active:
    case PowerState::unknown: return;
    default: apply_command(decode_controlword(controlword), now_ns); return;
  }
}

void Cia402StateMachine::apply_command(Cia402Command command, std::int64_t now_ns) noexcept {
  switch (state_) {
    case PowerState::switch_on_disabled:
      if (command == Cia402Command::shutdown) enter(PowerState::ready_to_switch_on, 2);
      return;
    case PowerState::ready_to_switch_on:
      if (command == Cia402Command::switch_on || command == Cia402Command::enable_operation) {
        enter(PowerState::switched_on, 3);
      } else if (command == Cia402Command::disable_voltage || command == Cia402Command::quick_stop) {
        enter(PowerState::switch_on_disabled, 7);
      }
      return;
    case PowerState::switched_on:
      if (command == Cia402Command::enable_operation) {
        enter(PowerState::operation_enabled, 4);
      } else if (command == Cia402Command::shutdown) {
        enter(PowerState::ready_to_switch_on, 6);
      } else if (command == Cia402Command::disable_voltage || command == Cia402Command::quick_stop) {
        enter(PowerState::switch_on_disabled, 10);
      }
      return;
    case PowerState::operation_enabled:
      switch (command) {
        case Cia402Command::enable_operation:
          if (stop_ != Stop::none) {  // a shutdown / disable operation ramp is cancelled
            stop_ = Stop::none;
            scale_ = 1.0;
          }
          return;
        case Cia402Command::switch_on:  // disable operation, transition 5
          if (stop_ == Stop::disable_operation) return;
          if (options_.disable_operation_option == 0) {
            stop_ = Stop::none;
            enter(PowerState::switched_on, 5);
          } else {
            start_stop(Stop::disable_operation, options_.slow_down_ramp_ns, now_ns);
          }
          return;
        case Cia402Command::shutdown:  // transition 8
          if (stop_ == Stop::shutdown) return;
          if (options_.shutdown_option == 0) {
            stop_ = Stop::none;
            enter(PowerState::ready_to_switch_on, 8);
          } else {
            start_stop(Stop::shutdown, options_.slow_down_ramp_ns, now_ns);
          }
          return;
        case Cia402Command::disable_voltage:
          stop_ = Stop::none;
          enter(PowerState::switch_on_disabled, 9);
          return;
        case Cia402Command::quick_stop: begin_quick_stop(now_ns); return;
      }
      return;
    case PowerState::quick_stop_active:
      if (command == Cia402Command::disable_voltage) {
        stop_ = Stop::none;
        enter(PowerState::switch_on_disabled, 12);
      } else if (command == Cia402Command::enable_operation && quick_stop_stays_active(options_.quick_stop_option)) {
        stop_ = Stop::none;
        enter(PowerState::operation_enabled, 16);
      }
      return;
    default: return;
  }
}

void Cia402StateMachine::begin_quick_stop(std::int64_t now_ns) noexcept {
  stop_ = Stop::none;
  enter(PowerState::quick_stop_active, 11);
  switch (options_.quick_stop_option) {
    case 0:  // disable drive function: straight on to switch on disabled
      enter(PowerState::switch_on_disabled, 12);
      return;
    case 1:
    case 5: start_stop(Stop::quick_stop, options_.slow_down_ramp_ns, now_ns); return;
    case 2:
    case 6: start_stop(Stop::quick_stop, options_.quick_stop_ramp_ns, now_ns); return;
    default: start_stop(Stop::quick_stop, 0, now_ns); return;  // 3, 4, 7, 8: torque off at once
  }
}

void Cia402StateMachine::start_stop(Stop stop, std::int64_t ramp_ns, std::int64_t now_ns) noexcept {
  stop_ = stop;
  stop_finished_ = false;
  ramp_start_ns_ = now_ns;
  ramp_ns_ = ramp_ns;
  ramp_start_scale_ = scale_;
  advance_ramp(now_ns);
}

void Cia402StateMachine::advance_ramp(std::int64_t now_ns) noexcept {
  if (stop_ == Stop::none || stop_finished_) return;
  if (ramp_ns_ <= 0) {
    scale_ = 0.0;
  } else {
    const double elapsed = static_cast<double>(now_ns - ramp_start_ns_) / static_cast<double>(ramp_ns_);
    scale_ = ramp_start_scale_ * std::clamp(1.0 - elapsed, 0.0, 1.0);
  }
  if (scale_ <= 0.0) {
    scale_ = 0.0;
    finish_stop();
  }
}

void Cia402StateMachine::finish_stop() noexcept {
  stop_finished_ = true;
  const Stop stop = stop_;
  switch (stop) {
    case Stop::quick_stop:
      if (quick_stop_stays_active(options_.quick_stop_option)) return;  // hold zero torque
      stop_ = Stop::none;
      enter(PowerState::switch_on_disabled, 12);
      return;
    case Stop::shutdown:
      stop_ = Stop::none;
      enter(PowerState::ready_to_switch_on, 8);
      return;
    case Stop::disable_operation:
      stop_ = Stop::none;
      enter(PowerState::switched_on, 5);
      return;
    case Stop::fault_reaction:
      stop_ = Stop::none;
      enter(PowerState::fault, 14);
      return;
    case Stop::none: return;
  }
}

void Cia402StateMachine::raise_fault(std::uint16_t error_code, std::int64_t now_ns) noexcept {
  if (state_ == PowerState::fault || state_ == PowerState::fault_reaction_active) return;
  const bool was_enabled = drive_function_enabled();
  error_code_ = error_code;
  stop_ = Stop::none;
  enter(PowerState::fault_reaction_active, 13);
  if (!was_enabled) {
    fault_reaction_done();
    return;
  }
  switch (options_.fault_reaction_option) {
    case 0: fault_reaction_done(); return;
    case 1: start_stop(Stop::fault_reaction, options_.slow_down_ramp_ns, now_ns); return;
    case 2: start_stop(Stop::fault_reaction, options_.quick_stop_ramp_ns, now_ns); return;
    default: start_stop(Stop::fault_reaction, 0, now_ns); return;
  }
}

void Cia402StateMachine::fault_reaction_done() noexcept {
  if (state_ != PowerState::fault_reaction_active) return;
  stop_ = Stop::none;
  scale_ = 0.0;
  enter(PowerState::fault, 14);
}

void Cia402StateMachine::connection_lost(std::uint16_t error_code, std::int64_t now_ns) noexcept {
  if (state_ == PowerState::fault || state_ == PowerState::fault_reaction_active ||
      state_ == PowerState::not_ready_to_switch_on) {
    return;
  }
  switch (options_.abort_connection_option) {
    case 1: raise_fault(error_code, now_ns); return;
    case 2: apply_command(Cia402Command::disable_voltage, now_ns); return;
    case 3: apply_command(Cia402Command::quick_stop, now_ns); return;
    default: return;
  }
}

bool Cia402StateMachine::drive_function_enabled() const noexcept {
  switch (state_) {
    case PowerState::operation_enabled:
    case PowerState::quick_stop_active: return true;
    case PowerState::fault_reaction_active: return stop_ == Stop::fault_reaction && !stop_finished_;
    default: return false;
  }
}

bool Cia402StateMachine::torque_follows_command() const noexcept {
  return state_ == PowerState::operation_enabled && stop_ == Stop::none;
}

double Cia402StateMachine::torque_output(double commanded) noexcept {
  if (torque_follows_command()) {
    held_torque_ = commanded;
    return commanded;
  }
  return drive_function_enabled() ? held_torque_ * scale_ : 0.0;
}

std::uint16_t Cia402StateMachine::statusword() const noexcept {
  auto word = static_cast<std::uint16_t>(statusword_state_bits(state_));
  if (state_ != PowerState::quick_stop_active) word |= kStatusQuickStop;
  if (voltage_present_) word |= kStatusVoltageEnabled;
  if (warning_) word |= kStatusWarning;
  if (remote_) word |= kStatusRemote;
  if (target_reached_) word |= kStatusTargetReached;
  if (internal_limit_) word |= kStatusInternalLimitActive;
  if (torque_follows_command()) word |= kStatusDriveFollowsCommand;
  return word;
}

}  // namespace trainer::hal::canopen
