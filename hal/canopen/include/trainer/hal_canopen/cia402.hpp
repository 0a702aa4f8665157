// CiA 402 (IEC 61800-7-201) drive profile basics: object indices, modes of operation,
// statusword decoding into the power state, controlword commands, the master's
// "next controlword" helper, and torque unit conversion. The slave's state machine is in
// cia402_drive.hpp.
//
// Master, once per cycle for each drive:
//   const PowerState state = decode_statusword(statusword);          // from the TPDO
//   controlword = next_controlword(state, PowerTarget::operation_enabled, controlword);
//   target_torque = torque_to_permille(effort_nm / gear, rated_torque_mnm);   // 0x6071
//   ... RPDO {controlword, target_torque}
// next_controlword walks switch on disabled -> ready to switch on -> switched on ->
// operation enabled one transition per call, and clears a fault with a 0 -> 1 edge of bit 7
// spread over two calls (bit 7 low, then high; repeated while the fault stays).
#pragma once

#include <cstdint>

namespace trainer::hal::canopen {

// --- objects ---
inline constexpr std::uint16_t kObjectAbortConnectionOption = 0x6007;  // i16
inline constexpr std::uint16_t kObjectErrorCode = 0x603F;              // u16, last EMCY code
inline constexpr std::uint16_t kObjectControlword = 0x6040;            // u16
inline constexpr std::uint16_t kObjectStatusword = 0x6041;             // u16
inline constexpr std::uint16_t kObjectQuickStopOption = 0x605A;        // i16
inline constexpr std::uint16_t kObjectShutdownOption = 0x605B;         // i16
inline constexpr std::uint16_t kObjectDisableOperationOption = 0x605C;  // i16
inline constexpr std::uint16_t kObjectFaultReactionOption = 0x605E;    // i16
inline constexpr std::uint16_t kObjectModesOfOperation = 0x6060;       // i8
inline constexpr std::uint16_t kObjectModesOfOperationDisplay = 0x6061;  // i8
inline constexpr std::uint16_t kObjectPositionActual = 0x6064;         // i32, position units
inline constexpr std::uint16_t kObjectVelocityActual = 0x606C;         // i32, velocity units
inline constexpr std::uint16_t kObjectTargetTorque = 0x6071;           // i16, per mille of 0x6076
inline constexpr std::uint16_t kObjectMaxTorque = 0x6072;              // u16, per mille of 0x6076
inline constexpr std::uint16_t kObjectMotorRatedTorque = 0x6076;       // u32, mN·m
inline constexpr std::uint16_t kObjectTorqueActual = 0x6077;           // i16, per mille of 0x6076
inline constexpr std::uint16_t kObjectSupportedDriveModes = 0x6502;    // u32

// --- modes of operation (0x6060) ---
enum class OperationMode : std::int8_t {
  none = 0,
  profile_position = 1,           // PP
  velocity = 2,                   // VL
  profile_velocity = 3,           // PV
  profile_torque = 4,             // TQ
  homing = 6,                     // HM
  interpolated_position = 7,      // IP
  cyclic_synchronous_position = 8,  // CSP
  cyclic_synchronous_velocity = 9,  // CSV
  cyclic_synchronous_torque = 10,   // CST
};
const char* to_string(OperationMode mode) noexcept;
// The bit of a mode in 0x6502 (pp 0, vl 1, pv 2, tq 3, hm 5, ip 6, csp 7, csv 8, cst 9); 0
// for `none` and unknown values.
std::uint32_t supported_mode_bit(OperationMode mode) noexcept;

// --- statusword (0x6041) ---
inline constexpr std::uint16_t kStatusReadyToSwitchOn = 1U << 0;
inline constexpr std::uint16_t kStatusSwitchedOn = 1U << 1;
inline constexpr std::uint16_t kStatusOperationEnabled = 1U << 2;
inline constexpr std::uint16_t kStatusFault = 1U << 3;
inline constexpr std::uint16_t kStatusVoltageEnabled = 1U << 4;
inline constexpr std::uint16_t kStatusQuickStop = 1U << 5;  // active LOW: 0 = quick stop active
inline constexpr std::uint16_t kStatusSwitchOnDisabled = 1U << 6;
inline constexpr std::uint16_t kStatusWarning = 1U << 7;
inline constexpr std::uint16_t kStatusRemote = 1U << 9;
inline constexpr std::uint16_t kStatusTargetReached = 1U << 10;
inline constexpr std::uint16_t kStatusInternalLimitActive = 1U << 11;
// Cyclic synchronous modes: bit 12 = the drive follows the command value.
inline constexpr std::uint16_t kStatusDriveFollowsCommand = 1U << 12;

enum class PowerState : std::uint8_t {
  not_ready_to_switch_on,  // xxxx xxxx x0xx 0000 (mask 0x4F -> 0x00)
  switch_on_disabled,      // x1xx 0000 (0x4F -> 0x40)
  ready_to_switch_on,      // x01x 0001 (0x6F -> 0x21)
  switched_on,             // x01x 0011 (0x6F -> 0x23)
  operation_enabled,       // x01x 0111 (0x6F -> 0x27)
  quick_stop_active,       // x00x 0111 (0x6F -> 0x07)
  fault_reaction_active,   // x0xx 1111 (0x4F -> 0x0F)
  fault,                   // x0xx 1000 (0x4F -> 0x08)
  unknown,                 // any other pattern (not a CiA 402 state)
};
const char* to_string(PowerState state) noexcept;
PowerState decode_statusword(std::uint16_t statusword) noexcept;
// The state bits (0..3, 5, 6) of a state, e.g. 0x0027 for operation_enabled (0 for unknown).
std::uint16_t statusword_state_bits(PowerState state) noexcept;

// --- controlword (0x6040) ---
inline constexpr std::uint16_t kControlSwitchOn = 1U << 0;
inline constexpr std::uint16_t kControlEnableVoltage = 1U << 1;
inline constexpr std::uint16_t kControlQuickStop = 1U << 2;  // active LOW
inline constexpr std::uint16_t kControlEnableOperation = 1U << 3;
inline constexpr std::uint16_t kControlFaultReset = 1U << 7;  // rising edge
inline constexpr std::uint16_t kControlHalt = 1U << 8;

inline constexpr std::uint16_t kCommandShutdown = 0x0006;         // transitions 2, 6, 8
inline constexpr std::uint16_t kCommandSwitchOn = 0x0007;         // 3
inline constexpr std::uint16_t kCommandEnableOperation = 0x000F;  // 4, 16 (and 3+4)
inline constexpr std::uint16_t kCommandDisableVoltage = 0x0000;   // 7, 9, 10, 12
inline constexpr std::uint16_t kCommandQuickStop = 0x0002;        // 7, 10, 11
inline constexpr std::uint16_t kCommandDisableOperation = 0x0007;  // 5
inline constexpr std::uint16_t kCommandFaultReset = 0x0080;       // 15 (on the 0 -> 1 edge)

// The command a controlword carries (bit 7 edge not included: the caller tracks it).
enum class Cia402Command : std::uint8_t {
  disable_voltage,      // xxxx x0x (bit 1 = 0)
  quick_stop,           // bit 1 = 1, bit 2 = 0
  shutdown,             // bits 2,1,0 = 1,1,0
  switch_on,            // bits 3..0 = 0111 (= disable operation)
  enable_operation,     // bits 3..0 = 1111 (= switch on + enable operation)
};
Cia402Command decode_controlword(std::uint16_t controlword) noexcept;

enum class PowerTarget : std::uint8_t {
  operation_enabled,  // torque on
  disabled,           // switch on disabled: no torque, power stage off (disable voltage)
  quick_stop,         // quick stop command (the drive's 0x605A decides what follows)
};
const char* to_string(PowerTarget target) noexcept;

// The controlword to send this cycle to move a drive in `state` one step toward `target`.
// `previous_controlword` is the one sent last cycle (for the fault reset edge).
std::uint16_t next_controlword(PowerState state, PowerTarget target, std::uint16_t previous_controlword) noexcept;

// --- torque units (0x6071/0x6072/0x6077: per mille of 0x6076 motor rated torque in mN·m) ---
// Rounded to nearest and clamped to int16; 0 when rated torque is 0 or torque is not finite.
std::int16_t torque_to_permille(double torque_nm, std::uint32_t rated_torque_mnm) noexcept;
double torque_from_permille(std::int16_t permille, std::uint32_t rated_torque_mnm) noexcept;

}  // namespace trainer::hal::canopen
