// Cia402StateMachine: the slave side of the CiA 402 (IEC 61800-7-201) power state machine,
// transitions 0..16, for a torque-controlled (CST) haptic drive. Driven by the controlword
// (0x6040) and internal events (fault occurred, fault reaction done, connection lost); it
// tells the drive logic whether torque may be applied and how much of the commanded torque
// to apply, and produces the statusword (0x6041).
//
// Usage (simulated drive, once per cycle):
//   Cia402StateMachine power;                       // options = 0x605A/B/C/E defaults
//   if (overcurrent) power.raise_fault(0x2310, now_ns);
//   power.update(controlword, now_ns);
//   const double torque_nm = power.torque_output(target_torque_nm);  // 0 when disabled
//   od.set<std::uint16_t>(0x6041, 0, power.statusword());
//
// Stops, for a torque drive: "slow down on a ramp" means the torque is scaled from its
// value at the start of the stop to zero over the ramp time (slow_down_ramp_ns /
// quick_stop_ramp_ns); "slow down on current/voltage limit" has no meaning without a
// velocity loop and removes the torque at once (drive function stays enabled for options
// 7/8). Quick stop option 0x605A: 0 disable drive function (straight to switch on
// disabled), 1/2 ramp then switch on disabled, 3/4 zero torque then switch on disabled,
// 5/6 ramp then stay in quick stop active, 7/8 zero torque and stay; transition 16 back to
// operation enabled only for 5..8. Shutdown 0x605B and disable operation 0x605C: 0 disable
// the drive function at once, 1 slow-down ramp first (the state changes when the ramp
// ends; a new enable operation command during the ramp cancels it). Fault reaction 0x605E:
// 0 disable drive function (fault reaction completes at once), 1 slow-down ramp, 2 quick
// stop ramp, 3/4 zero torque; the reaction completes when the ramp ends or on
// fault_reaction_done(). Negative (manufacturer) option codes are refused.
//
// Controlword commands are decoded from bits 0..3 (cia402.hpp decode_controlword); bit 7
// is used only for its 0 -> 1 edge (fault reset, transition 15, refused while the drive
// logic reports the fault condition still present). Each update() takes at most one
// commanded transition, so "switch on + enable operation" (0x0F in ready to switch on) is
// 3 then 4 on the next cycle.
#pragma once

#include <cstdint>

#include "trainer/hal_canopen/cia402.hpp"

namespace trainer::hal::canopen {

struct Cia402Options {
  std::int16_t quick_stop_option = 2;         // 0x605A, 0..8
  std::int16_t shutdown_option = 0;           // 0x605B, 0..1
  std::int16_t disable_operation_option = 1;  // 0x605C, 0..1
  std::int16_t fault_reaction_option = 2;     // 0x605E, 0..4
  std::int16_t abort_connection_option = 1;   // 0x6007, 0..3 (connection_lost())
  std::int64_t slow_down_ramp_ns = 50'000'000;  // full torque -> 0
  std::int64_t quick_stop_ramp_ns = 10'000'000;
};
// Whether the option codes are in the ranges this machine implements (and ramps >= 0).
bool valid_options(const Cia402Options& options) noexcept;

class Cia402StateMachine {
 public:
  explicit Cia402StateMachine(const Cia402Options& options = {}) noexcept;

  // false (and nothing changed) unless valid_options(). The object dictionary's write
  // hook for 0x605A.. answers kAbortInvalidValue then.
  bool set_options(const Cia402Options& options) noexcept;
  const Cia402Options& options() const noexcept { return options_; }

  // Transition 0: back to not ready to switch on (power-on, NMT reset node).
  void reset() noexcept;
  // One cycle: automatic transitions (1, end of ramps) and at most one commanded one.
  void update(std::uint16_t controlword, std::int64_t now_ns) noexcept;
  // Transition 13 from any state but fault / fault reaction active; `error_code` goes to
  // 0x603F (the drive logic sends the EMCY).
  void raise_fault(std::uint16_t error_code, std::int64_t now_ns) noexcept;
  // Transition 14 now (the drive logic finished its own fault reaction).
  void fault_reaction_done() noexcept;
  // While true, fault reset is refused (the cause persists).
  void set_fault_present(bool present) noexcept { fault_present_ = present; }
  // Reaction to a lost master (heartbeat timeout, NMT stop) per 0x6007: 0 none, 1 fault
  // with `error_code`, 2 disable voltage, 3 quick stop.
  void connection_lost(std::uint16_t error_code, std::int64_t now_ns) noexcept;

  // Inputs for statusword bits not owned by the state machine.
  void set_voltage_present(bool present) noexcept { voltage_present_ = present; }
  void set_warning(bool warning) noexcept { warning_ = warning; }
  void set_remote(bool remote) noexcept { remote_ = remote; }
  void set_target_reached(bool reached) noexcept { target_reached_ = reached; }
  void set_internal_limit_active(bool active) noexcept { internal_limit_ = active; }

  PowerState state() const noexcept { return state_; }
  std::uint16_t statusword() const noexcept;
  std::uint16_t error_code() const noexcept { return error_code_; }  // 0x603F
  // The power stage drives the motor (torque may be non-zero): operation enabled, quick
  // stop active, fault reaction active with a ramp, and during a shutdown/disable ramp.
  bool drive_function_enabled() const noexcept;
  // The drive follows the commanded (target) torque: operation enabled, no stop ramp.
  bool torque_follows_command() const noexcept;
  // 1 while following the command; during a stop the fraction of the torque at the start
  // of the stop still applied (linear to 0); 0 when the drive function is disabled.
  double torque_scale() const noexcept { return drive_function_enabled() ? scale_ : 0.0; }
  // The torque to apply this cycle: `commanded` while following the command (it is
  // remembered), the remembered torque times torque_scale() during a stop, 0 otherwise.
  double torque_output(double commanded) noexcept;
  // Bit n set: transition n (0..16) was taken since the start of the last update() (events
  // between updates add theirs).
  std::uint32_t transitions() const noexcept { return transitions_; }

 private:
  enum class Stop : std::uint8_t { none, quick_stop, shutdown, disable_operation, fault_reaction };

  void enter(PowerState state, unsigned transition) noexcept;
  void start_stop(Stop stop, std::int64_t ramp_ns, std::int64_t now_ns) noexcept;
  void advance_ramp(std::int64_t now_ns) noexcept;
  void finish_stop() noexcept;
  void apply_command(Cia402Command command, std::int64_t now_ns) noexcept;
  void begin_quick_stop(std::int64_t now_ns) noexcept;

  Cia402Options options_;
  PowerState state_ = PowerState::not_ready_to_switch_on;
  Stop stop_ = Stop::none;
  std::int64_t ramp_start_ns_ = 0;
  std::int64_t ramp_ns_ = 0;
  double ramp_start_scale_ = 1.0;
  double scale_ = 0.0;
  double held_torque_ = 0.0;  // the last commanded torque, ramped down during a stop
  bool stop_finished_ = false;  // ramp reached zero (quick stop 5..8 holds there)
  std::uint16_t previous_controlword_ = 0;
  std::uint16_t error_code_ = 0;
  bool fault_present_ = false;
  bool voltage_present_ = true;
  bool warning_ = false;
  bool remote_ = true;
  bool target_reached_ = false;
  bool internal_limit_ = false;
  std::uint32_t transitions_ = 0;
};

}  // namespace trainer::hal::canopen
