// CiA 402 statusword / controlword coding (IEC 61800-7-201, 6.2 "device control") and the
// master's controlword sequencing.
#include "trainer/hal_canopen/cia402.hpp"

#include <cmath>
#include <limits>

namespace trainer::hal::canopen {

namespace {

constexpr std::uint16_t kMaskShort = 0x004F;  // bits 0..3, 6
constexpr std::uint16_t kMaskLong = 0x006F;   // bits 0..3, 5, 6

}  // namespace

PowerState decode_statusword(std::uint16_t statusword) noexcept {
  switch (statusword & kMaskShort) {
    case 0x0000: return PowerState::not_ready_to_switch_on;
    case 0x0040: return PowerState::switch_on_disabled;
    case 0x000F: return PowerState::fault_reaction_active;
    case 0x0008: return PowerState::fault;
    default: break;
  }
  switch (statusword & kMaskLong) {
    case 0x0021: return PowerState::ready_to_switch_on;
    case 0x0023: return PowerState::switched_on;
    case 0x0027: return PowerState::operation_enabled;
    case 0x0007: return PowerState::quick_stop_active;
    default: return PowerState::unknown;
  }
}

std::uint16_t statusword_state_bits(PowerState state) noexcept {
  switch (state) {
    case PowerState::not_ready_to_switch_on: return 0x0000;
    case PowerState::switch_on_disabled: return 0x0040;
    case PowerState::ready_to_switch_on: return 0x0021;
    case PowerState::switched_on: return 0x0023;
    case PowerState::operation_enabled: return 0x0027;
    case PowerState::quick_stop_active: return 0x0007;
    case PowerState::fault_reaction_active: return 0x000F;
    case PowerState::fault: return 0x0008;
    case PowerState::unknown: return 0;
  }
  return 0;
}

Cia402Command decode_controlword(std::uint16_t controlword) noexcept {
  if ((controlword & kControlEnableVoltage) == 0) return Cia402Command::disable_voltage;
  if ((controlword & kControlQuickStop) == 0) return Cia402Command::quick_stop;
  if ((controlword & kControlSwitchOn) == 0) return Cia402Command::shutdown;
  if ((controlword & kControlEnableOperation) == 0) return Cia402Command::switch_on;
  return Cia402Command::enable_operation;
}

std::uint16_t next_controlword(PowerState state, PowerTarget target, std::uint16_t previous_controlword) noexcept {
  if (target == PowerTarget::disabled) return kCommandDisableVoltage;
  if (target == PowerTarget::quick_stop) return kCommandQuickStop;
  switch (state) {
    case PowerState::switch_on_disabled: return kCommandShutdown;
    case PowerState::ready_to_switch_on: return kCommandSwitchOn;
    case PowerState::switched_on:
    case PowerState::operation_enabled:
    case PowerState::quick_stop_active:  // transition 16 where the drive's 0x605A allows it
      return kCommandEnableOperation;
    case PowerState::fault:
      // Fault reset acts on the rising edge of bit 7: low one cycle, high the next.
      return (previous_controlword & kControlFaultReset) != 0 ? kCommandDisableVoltage : kCommandFaultReset;
    case PowerState::not_ready_to_switch_on:  // the drive accepts no command yet
    case PowerState::fault_reaction_active:   // wait for the reaction; keep bit 7 low
    case PowerState::unknown: return kCommandDisableVoltage;
  }
  return kCommandDisableVoltage;
}

std::int16_t torque_to_permille(double torque_nm, std::uint32_t rated_torque_mnm) noexcept {
  if (rated_torque_mnm == 0 || !std::isfinite(torque_nm)) return 0;
  // per mille = torque / rated * 1000, rated in mN·m: torque_nm * 1e6 / rated_mnm.
  const double permille = std::round(torque_nm * 1.0e6 / static_cast<double>(rated_torque_mnm));
  if (permille >= std::numeric_limits<std::int16_t>::max()) return std::numeric_limits<std::int16_t>::max();
  if (permille <= std::numeric_limits<std::int16_t>::min()) return std::numeric_limits<std::int16_t>::min();
  return static_cast<std::int16_t>(permille);
}

double torque_from_permille(std::int16_t permille, std::uint32_t rated_torque_mnm) noexcept {
  return static_cast<double>(permille) * static_cast<double>(rated_torque_mnm) * 1.0e-6;
}

std::uint32_t supported_mode_bit(OperationMode mode) noexcept {
  switch (mode) {
    case OperationMode::profile_position: return 1U << 0;
    case OperationMode::velocity: return 1U << 1;
    case OperationMode::profile_velocity: return 1U << 2;
    case OperationMode::profile_torque: return 1U << 3;
    case OperationMode::homing: return 1U << 5;
    case OperationMode::interpolated_position: return 1U << 6;
    case OperationMode::cyclic_synchronous_position: return 1U << 7;
    case OperationMode::cyclic_synchronous_velocity: return 1U << 8;
    case OperationMode::cyclic_synchronous_torque: return 1U << 9;
    case OperationMode::none: return 0;
  }
  return 0;
}

const char* to_string(OperationMode mode) noexcept {
  switch (mode) {
    case OperationMode::none: return "no mode";
    case OperationMode::profile_position: return "profile position (PP)";
    case OperationMode::velocity: return "velocity (VL)";
    case OperationMode::profile_velocity: return "profile velocity (PV)";
    case OperationMode::profile_torque: return "profile torque (TQ)";
    case OperationMode::homing: return "homing (HM)";
    case OperationMode::interpolated_position: return "interpolated position (IP)";
    case OperationMode::cyclic_synchronous_position: return "cyclic synchronous position (CSP)";
    case OperationMode::cyclic_synchronous_velocity: return "cyclic synchronous velocity (CSV)";
    case OperationMode::cyclic_synchronous_torque: return "cyclic synchronous torque (CST)";
  }
  return "unknown mode";
}

const char* to_string(PowerState state) noexcept {
  switch (state) {
    case PowerState::not_ready_to_switch_on: return "not ready to switch on";
    case PowerState::switch_on_disabled: return "switch on disabled";
    case PowerState::ready_to_switch_on: return "ready to switch on";
    case PowerState::switched_on: return "switched on";
    case PowerState::operation_enabled: return "operation enabled";
    case PowerState::quick_stop_active: return "quick stop active";
    case PowerState::fault_reaction_active: return "fault reaction active";
    case PowerState::fault: return "fault";
    case PowerState::unknown: return "unknown";
  }
  return "?";
}

const char* to_string(PowerTarget target) noexcept {
  switch (target) {
    case PowerTarget::operation_enabled: return "operation enabled";
    case PowerTarget::disabled: return "disabled";
    case PowerTarget::quick_stop: return "quick stop";
  }
  return "?";
}

}  // namespace trainer::hal::canopen
