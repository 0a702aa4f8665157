// CiA 402 (IEC 61800-7-201): statusword / controlword coding, the master's controlword
// sequencing, every numbered transition 0..16 of the drive's state machine, quick stop,
// shutdown, disable operation and fault reaction option codes, fault reset on the edge of
// bit 7, torque output during stops, and the master helper driving the drive.
#include <gtest/gtest.h>

#include <cmath>

#include "trainer/hal_canopen/cia402.hpp"
#include "trainer/hal_canopen/cia402_drive.hpp"

namespace trainer::hal::canopen {
namespace {

constexpr std::int64_t kDriveMs = 1'000'000;

bool took(const Cia402StateMachine& drive, unsigned transition) {
  return (drive.transitions() & (1U << transition)) != 0;
}

TEST(Cia402Coding, StatuswordDecode) {
  EXPECT_EQ(decode_statusword(0x0000), PowerState::not_ready_to_switch_on);
  EXPECT_EQ(decode_statusword(0x0040), PowerState::switch_on_disabled);
  EXPECT_EQ(decode_statusword(0x0060), PowerState::switch_on_disabled);  // bit 5 is x there
  EXPECT_EQ(decode_statusword(0x0021), PowerState::ready_to_switch_on);
  EXPECT_EQ(decode_statusword(0x0031), PowerState::ready_to_switch_on);  // + voltage enabled
  EXPECT_EQ(decode_statusword(0x0023), PowerState::switched_on);
  EXPECT_EQ(decode_statusword(0x0027), PowerState::operation_enabled);
  EXPECT_EQ(decode_statusword(0x1637), PowerState::operation_enabled);  // remote, target reached...
  EXPECT_EQ(decode_statusword(0x0007), PowerState::quick_stop_active);
  EXPECT_EQ(decode_statusword(0x000F), PowerState::fault_reaction_active);
  EXPECT_EQ(decode_statusword(0x002F), PowerState::fault_reaction_active);
  EXPECT_EQ(decode_statusword(0x0008), PowerState::fault);
  EXPECT_EQ(decode_statusword(0x0218), PowerState::fault);
  EXPECT_EQ(decode_statusword(0x0001), PowerState::unknown);  // ready without bit 5
  EXPECT_EQ(decode_statusword(0x0048), PowerState::unknown);
  for (PowerState state : {PowerState::not_ready_to_switch_on, PowerState::switch_on_disabled,
                           PowerState::ready_to_switch_on, PowerState::switched_on, PowerState::operation_enabled,
                           PowerState::quick_stop_active, PowerState::fault_reaction_active, PowerState::fault}) {
    EXPECT_EQ(decode_statusword(statusword_state_bits(state)), state) << to_string(state);
  }
}

TEST(Cia402Coding, ControlwordDecode) {
  EXPECT_EQ(decode_controlword(0x0006), Cia402Command::shutdown);
  EXPECT_EQ(decode_controlword(0x000E), Cia402Command::shutdown);  // bit 3 is x
  EXPECT_EQ(decode_controlword(0x0007), Cia402Command::switch_on);
  EXPECT_EQ(decode_controlword(0x000F), Cia402Command::enable_operation);
  EXPECT_EQ(decode_controlword(0x0000), Cia402Command::disable_voltage);
  EXPECT_EQ(decode_controlword(0x000D), Cia402Command::disable_voltage);  // bit 1 low wins
  EXPECT_EQ(decode_controlword(0x0002), Cia402Command::quick_stop);
  EXPECT_EQ(decode_controlword(0x000B), Cia402Command::quick_stop);
  EXPECT_EQ(decode_controlword(0x010F), Cia402Command::enable_operation);  // halt bit ignored here
}

TEST(Cia402Coding, MasterNextControlword) {
  const auto next = [](PowerState state, std::uint16_t previous = 0) {
    return next_controlword(state, PowerTarget::operation_enabled, previous);
  };
  EXPECT_EQ(next(PowerState::not_ready_to_switch_on), 0x0000);
  EXPECT_EQ(next(PowerState::switch_on_disabled), 0x0006);
  EXPECT_EQ(next(PowerState::ready_to_switch_on), 0x0007);
  EXPECT_EQ(next(PowerState::switched_on), 0x000F);
  EXPECT_EQ(next(PowerState::operation_enabled), 0x000F);
  EXPECT_EQ(next(PowerState::quick_stop_active), 0x000F);
  EXPECT_EQ(next(PowerState::fault_reaction_active), 0x0000);
  // Fault: the 0 -> 1 edge of bit 7 over two cycles.
  EXPECT_EQ(next(PowerState::fault, 0x000F), 0x0080);
  EXPECT_EQ(next(PowerState::fault, 0x0080), 0x0000);
  EXPECT_EQ(next(PowerState::fault, 0x0000), 0x0080);
  for (PowerState state : {PowerState::operation_enabled, PowerState::switched_on, PowerState::fault}) {
    EXPECT_EQ(next_controlword(state, PowerTarget::disabled, 0x0F), 0x0000);
    EXPECT_EQ(next_controlword(state, PowerTarget::quick_stop, 0x0F), 0x0002);
  }
}

TEST(Cia402Coding, TorqueUnitsAndModes) {
  // Rated 0.5 N·m = 500 mN·m: 0.1 N·m is 200 per mille.
  EXPECT_EQ(torque_to_permille(0.1, 500), 200);
  EXPECT_EQ(torque_to_permille(-0.1, 500), -200);
  EXPECT_EQ(torque_to_permille(0.10005, 500), 200);  // rounded
  EXPECT_EQ(torque_to_permille(1.0e6, 500), 32767);
  EXPECT_EQ(torque_to_permille(-1.0e6, 500), -32768);
  EXPECT_EQ(torque_to_permille(std::nan(""), 500), 0);
  EXPECT_EQ(torque_to_permille(1.0, 0), 0);
  EXPECT_DOUBLE_EQ(torque_from_permille(200, 500), 0.1);
  EXPECT_EQ(static_cast<int>(OperationMode::cyclic_synchronous_torque), 10);
  EXPECT_EQ(static_cast<int>(OperationMode::cyclic_synchronous_position), 8);
  EXPECT_EQ(static_cast<int>(OperationMode::cyclic_synchronous_velocity), 9);
  EXPECT_EQ(static_cast<int>(OperationMode::profile_position), 1);
  EXPECT_EQ(static_cast<int>(OperationMode::profile_velocity), 3);
  EXPECT_EQ(static_cast<int>(OperationMode::profile_torque), 4);
  EXPECT_EQ(static_cast<int>(OperationMode::homing), 6);
  EXPECT_EQ(supported_mode_bit(OperationMode::cyclic_synchronous_torque), 0x200U);
  EXPECT_EQ(supported_mode_bit(OperationMode::homing), 0x20U);
}

// Brings a fresh drive to operation enabled with the given options, at time 0.
Cia402StateMachine enabled_drive(const Cia402Options& options = {}) {
  Cia402StateMachine drive(options);
  drive.update(0x0000, 0);  // 1
  drive.update(0x0006, 0);  // 2
  drive.update(0x0007, 0);  // 3
  drive.update(0x000F, 0);  // 4
  EXPECT_EQ(drive.state(), PowerState::operation_enabled);
  return drive;
}

TEST(Cia402Drive, TransitionsZeroToFourAndStatusword) {
  Cia402StateMachine drive;
  EXPECT_TRUE(took(drive, 0));
  EXPECT_EQ(drive.state(), PowerState::not_ready_to_switch_on);
  EXPECT_EQ(drive.statusword() & 0x6F, 0x20);  // not ready; quick stop bit not active
  drive.update(0x0006, 0);
  EXPECT_TRUE(took(drive, 1));
  EXPECT_EQ(drive.state(), PowerState::switch_on_disabled);  // no command during transition 1
  drive.update(0x0007, 0);  // switch on: not a transition from switch on disabled
  EXPECT_EQ(drive.state(), PowerState::switch_on_disabled);
  EXPECT_EQ(drive.transitions(), 0U);
  drive.update(0x0006, 0);
  EXPECT_TRUE(took(drive, 2));
  EXPECT_EQ(drive.state(), PowerState::ready_to_switch_on);
  EXPECT_EQ(drive.statusword(), 0x0231);  // ready, voltage enabled, quick stop off, remote
  EXPECT_FALSE(drive.drive_function_enabled());
  drive.update(0x0007, 0);
  EXPECT_TRUE(took(drive, 3));
  EXPECT_EQ(drive.statusword(), 0x0233);
  EXPECT_FALSE(drive.drive_function_enabled());
  drive.update(0x000F, 0);
  EXPECT_TRUE(took(drive, 4));
  EXPECT_EQ(drive.state(), PowerState::operation_enabled);
  EXPECT_EQ(drive.statusword(), 0x1237);  // + drive follows the command
  EXPECT_TRUE(drive.drive_function_enabled());
  EXPECT_TRUE(drive.torque_follows_command());
  EXPECT_DOUBLE_EQ(drive.torque_output(0.3), 0.3);
  drive.set_warning(true);
  drive.set_target_reached(true);
  drive.set_internal_limit_active(true);
  drive.set_voltage_present(false);
  drive.set_remote(false);
  EXPECT_EQ(drive.statusword(), 0x1CA7);
}

TEST(Cia402Drive, SwitchOnPlusEnableOperationIsThreeThenFour) {
  Cia402StateMachine drive;
  drive.update(0, 0);
  drive.update(0x0006, 0);
  drive.update(0x000F, 0);
  EXPECT_TRUE(took(drive, 3));
  EXPECT_EQ(drive.state(), PowerState::switched_on);
  drive.update(0x000F, 0);
  EXPECT_TRUE(took(drive, 4));
  EXPECT_EQ(drive.state(), PowerState::operation_enabled);
}

TEST(Cia402Drive, TransitionsFiveToTen) {
  Cia402Options immediate;
  immediate.disable_operation_option = 0;
  immediate.shutdown_option = 0;
  Cia402StateMachine drive = enabled_drive(immediate);
  drive.update(0x0007, 0);  // disable operation
  EXPECT_TRUE(took(drive, 5));
  EXPECT_EQ(drive.state(), PowerState::switched_on);
  EXPECT_DOUBLE_EQ(drive.torque_output(0.3), 0.0);
  drive.update(0x0006, 0);
  EXPECT_TRUE(took(drive, 6));
  EXPECT_EQ(drive.state(), PowerState::ready_to_switch_on);
  drive.update(0x0000, 0);
  EXPECT_TRUE(took(drive, 7));
  EXPECT_EQ(drive.state(), PowerState::switch_on_disabled);
  drive.update(0x0006, 0);
  drive.update(0x0002, 0);  // quick stop also gives 7
  EXPECT_TRUE(took(drive, 7));

  drive = enabled_drive(immediate);
  drive.update(0x0006, 0);  // shutdown from operation enabled
  EXPECT_TRUE(took(drive, 8));
  EXPECT_EQ(drive.state(), PowerState::ready_to_switch_on);

  drive = enabled_drive(immediate);
  drive.update(0x0000, 0);
  EXPECT_TRUE(took(drive, 9));
  EXPECT_EQ(drive.state(), PowerState::switch_on_disabled);
  EXPECT_FALSE(drive.drive_function_enabled());

  for (std::uint16_t command : {std::uint16_t{0x0000}, std::uint16_t{0x0002}}) {
    Cia402StateMachine switched_on;
    switched_on.update(0, 0);
    switched_on.update(0x0006, 0);
    switched_on.update(0x0007, 0);
    switched_on.update(command, 0);
    EXPECT_TRUE(took(switched_on, 10)) << command;
    EXPECT_EQ(switched_on.state(), PowerState::switch_on_disabled);
  }
}

TEST(Cia402Drive, QuickStopOptionZeroDisablesAtOnce) {
  Cia402Options options;
  options.quick_stop_option = 0;
  Cia402StateMachine drive = enabled_drive(options);
  drive.update(0x0002, 0);
  EXPECT_TRUE(took(drive, 11));
  EXPECT_TRUE(took(drive, 12));
  EXPECT_EQ(drive.state(), PowerState::switch_on_disabled);
  EXPECT_DOUBLE_EQ(drive.torque_output(1.0), 0.0);
}

TEST(Cia402Drive, QuickStopOptionTwoRampsThenSwitchOnDisabled) {
  Cia402Options options;
  options.quick_stop_option = 2;
  options.quick_stop_ramp_ns = 10 * kDriveMs;
  Cia402StateMachine drive = enabled_drive(options);
  EXPECT_DOUBLE_EQ(drive.torque_output(0.4), 0.4);
  drive.update(0x0002, 100 * kDriveMs);
  EXPECT_TRUE(took(drive, 11));
  EXPECT_EQ(drive.state(), PowerState::quick_stop_active);
  EXPECT_EQ(drive.statusword() & 0x6F, 0x07);  // quick stop bit low
  EXPECT_TRUE(drive.drive_function_enabled());
  EXPECT_FALSE(drive.torque_follows_command());
  EXPECT_NEAR(drive.torque_output(0.9), 0.4, 1e-12);  // held, not the new command
  drive.update(0x0002, 104 * kDriveMs);
  EXPECT_NEAR(drive.torque_scale(), 0.6, 1e-9);
  EXPECT_NEAR(drive.torque_output(0.9), 0.24, 1e-9);
  drive.update(0x000F, 105 * kDriveMs);  // enable operation: no transition 16 for option 2
  EXPECT_EQ(drive.state(), PowerState::quick_stop_active);
  drive.update(0x0002, 110 * kDriveMs);
  EXPECT_TRUE(took(drive, 12));
  EXPECT_EQ(drive.state(), PowerState::switch_on_disabled);
  EXPECT_DOUBLE_EQ(drive.torque_output(0.9), 0.0);
}

TEST(Cia402Drive, QuickStopOptionSixStaysAndSixteenReturns) {
  Cia402Options options;
  options.quick_stop_option = 6;
  options.quick_stop_ramp_ns = 10 * kDriveMs;
  Cia402StateMachine drive = enabled_drive(options);
  drive.update(0x0002, 0);
  drive.update(0x0002, 20 * kDriveMs);
  EXPECT_EQ(drive.state(), PowerState::quick_stop_active);  // stays after the ramp
  EXPECT_TRUE(drive.drive_function_enabled());
  EXPECT_DOUBLE_EQ(drive.torque_scale(), 0.0);
  drive.update(0x000F, 30 * kDriveMs);
  EXPECT_TRUE(took(drive, 16));
  EXPECT_EQ(drive.state(), PowerState::operation_enabled);
  EXPECT_DOUBLE_EQ(drive.torque_output(0.2), 0.2);
  // Disable voltage from quick stop active is 12 at once.
  drive.update(0x0002, 40 * kDriveMs);
  drive.update(0x0000, 41 * kDriveMs);
  EXPECT_TRUE(took(drive, 12));
  EXPECT_EQ(drive.state(), PowerState::switch_on_disabled);
}

TEST(Cia402Drive, TransitionSixteenOnlyForOptionsFiveToEight) {
  for (std::int16_t option = 0; option <= 8; ++option) {
    Cia402Options options;
    options.quick_stop_option = option;
    options.slow_down_ramp_ns = 10 * kDriveMs;
    options.quick_stop_ramp_ns = 10 * kDriveMs;
    Cia402StateMachine drive = enabled_drive(options);
    drive.update(0x0002, 0);
    drive.update(0x0002, 5 * kDriveMs);  // mid-ramp for 1, 2, 5, 6
    drive.update(0x000F, 6 * kDriveMs);
    const bool returns = option >= 5;
    EXPECT_EQ(took(drive, 16), returns) << option;
    EXPECT_EQ(drive.state(), returns ? PowerState::operation_enabled
                             : (option == 0 || option >= 3) ? PowerState::switch_on_disabled
                                                            : PowerState::quick_stop_active)
        << option;
  }
}

TEST(Cia402Drive, QuickStopOptionsOneThreeSevenAndInvalidOnes) {
  Cia402Options slow;
  slow.quick_stop_option = 1;  // slow-down ramp, then switch on disabled
  slow.slow_down_ramp_ns = 40 * kDriveMs;
  Cia402StateMachine drive = enabled_drive(slow);
  drive.update(0x0002, 0);
  drive.update(0x0002, 20 * kDriveMs);
  EXPECT_NEAR(drive.torque_scale(), 0.5, 1e-9);
  drive.update(0x0002, 40 * kDriveMs);
  EXPECT_EQ(drive.state(), PowerState::switch_on_disabled);

  Cia402Options current_limit;
  current_limit.quick_stop_option = 3;  // no ramp for a torque drive
  drive = enabled_drive(current_limit);
  drive.update(0x0002, 0);
  EXPECT_TRUE(took(drive, 11));
  EXPECT_TRUE(took(drive, 12));

  Cia402Options hold;
  hold.quick_stop_option = 7;
  drive = enabled_drive(hold);
  drive.update(0x0002, 0);
  EXPECT_EQ(drive.state(), PowerState::quick_stop_active);
  EXPECT_DOUBLE_EQ(drive.torque_scale(), 0.0);

  Cia402Options invalid;
  invalid.quick_stop_option = 9;
  EXPECT_FALSE(valid_options(invalid));
  EXPECT_FALSE(drive.set_options(invalid));
  invalid.quick_stop_option = -1;  // manufacturer specific: not implemented
  EXPECT_FALSE(drive.set_options(invalid));
  EXPECT_EQ(drive.options().quick_stop_option, 7);
  Cia402StateMachine defaults(invalid);  // falls back to the defaults
  EXPECT_EQ(defaults.options().quick_stop_option, 2);
}

TEST(Cia402Drive, ShutdownAndDisableOperationRamps) {
  Cia402Options options;
  options.shutdown_option = 1;
  options.disable_operation_option = 1;
  options.slow_down_ramp_ns = 20 * kDriveMs;
  Cia402StateMachine drive = enabled_drive(options);
  drive.torque_output(0.5);
  drive.update(0x0006, 0);  // shutdown: ramp first, state unchanged meanwhile
  EXPECT_EQ(drive.state(), PowerState::operation_enabled);
  EXPECT_FALSE(drive.torque_follows_command());
  EXPECT_EQ(drive.transitions(), 0U);
  drive.update(0x0006, 10 * kDriveMs);
  EXPECT_NEAR(drive.torque_output(0.0), 0.25, 1e-9);
  drive.update(0x000F, 12 * kDriveMs);  // enable operation cancels the ramp
  EXPECT_TRUE(drive.torque_follows_command());
  EXPECT_DOUBLE_EQ(drive.torque_scale(), 1.0);
  drive.update(0x0007, 20 * kDriveMs);  // disable operation: ramp, then 5
  drive.update(0x0007, 30 * kDriveMs);
  EXPECT_EQ(drive.state(), PowerState::operation_enabled);
  drive.update(0x0007, 40 * kDriveMs);
  EXPECT_TRUE(took(drive, 5));
  EXPECT_EQ(drive.state(), PowerState::switched_on);
  drive.update(0x000F, 41 * kDriveMs);
  drive.update(0x0006, 50 * kDriveMs);
  drive.update(0x0006, 70 * kDriveMs);
  EXPECT_TRUE(took(drive, 8));
  EXPECT_EQ(drive.state(), PowerState::ready_to_switch_on);
}

TEST(Cia402Drive, FaultReactionAndFaultResetEdge) {
  Cia402Options options;
  options.fault_reaction_option = 2;  // quick stop ramp
  options.quick_stop_ramp_ns = 10 * kDriveMs;
  Cia402StateMachine drive = enabled_drive(options);
  drive.torque_output(0.8);
  drive.raise_fault(0x2310, 0);
  EXPECT_TRUE(took(drive, 13));
  EXPECT_EQ(drive.state(), PowerState::fault_reaction_active);
  EXPECT_EQ(drive.statusword() & 0x4F, 0x0F);
  EXPECT_EQ(drive.error_code(), 0x2310);
  EXPECT_TRUE(drive.drive_function_enabled());
  drive.update(0x000F, 5 * kDriveMs);
  EXPECT_NEAR(drive.torque_output(0.8), 0.4, 1e-9);
  drive.raise_fault(0x4210, 6 * kDriveMs);  // a second fault during the reaction changes nothing
  EXPECT_EQ(drive.error_code(), 0x2310);
  drive.update(0x000F, 10 * kDriveMs);
  EXPECT_TRUE(took(drive, 14));
  EXPECT_EQ(drive.state(), PowerState::fault);
  EXPECT_EQ(drive.statusword() & 0x4F, 0x08);
  EXPECT_DOUBLE_EQ(drive.torque_output(0.8), 0.0);
  // Bit 7 held high is no edge; commands are ignored in fault.
  drive.update(0x0080, 11 * kDriveMs);
  EXPECT_TRUE(took(drive, 15));  // 0x000F -> 0x0080: that is an edge
  EXPECT_EQ(drive.state(), PowerState::switch_on_disabled);
  EXPECT_EQ(drive.error_code(), 0);

  drive = enabled_drive(options);
  drive.set_fault_present(true);
  drive.raise_fault(0x3210, 0);
  drive.fault_reaction_done();  // the drive logic ends its reaction early
  EXPECT_TRUE(took(drive, 14));
  drive.update(0x0080, 1 * kDriveMs);  // edge, but the cause persists
  EXPECT_EQ(drive.state(), PowerState::fault);
  drive.set_fault_present(false);
  drive.update(0x0080, 2 * kDriveMs);  // still high: no new edge
  EXPECT_EQ(drive.state(), PowerState::fault);
  drive.update(0x0006, 3 * kDriveMs);  // shutdown is ignored in fault
  EXPECT_EQ(drive.state(), PowerState::fault);
  drive.update(0x0086, 4 * kDriveMs);  // edge
  EXPECT_TRUE(took(drive, 15));
  EXPECT_EQ(drive.state(), PowerState::switch_on_disabled);
}

TEST(Cia402Drive, FaultWithoutDriveFunctionAndReset) {
  Cia402StateMachine drive;
  drive.update(0, 0);
  drive.raise_fault(0x5530, 0);  // in switch on disabled: reaction completes at once
  EXPECT_TRUE(took(drive, 13));
  EXPECT_TRUE(took(drive, 14));
  EXPECT_EQ(drive.state(), PowerState::fault);
  drive.reset();  // transition 0 (NMT reset node)
  EXPECT_TRUE(took(drive, 0));
  EXPECT_EQ(drive.state(), PowerState::not_ready_to_switch_on);
  EXPECT_EQ(drive.error_code(), 0);
}

TEST(Cia402Drive, ConnectionLostFollowsAbortConnectionOption) {
  Cia402Options fault;
  fault.abort_connection_option = 1;
  fault.fault_reaction_option = 0;
  Cia402StateMachine drive = enabled_drive(fault);
  drive.connection_lost(0x8130, 0);
  EXPECT_EQ(drive.state(), PowerState::fault);
  EXPECT_EQ(drive.error_code(), 0x8130);

  Cia402Options disable;
  disable.abort_connection_option = 2;
  drive = enabled_drive(disable);
  drive.connection_lost(0x8130, 0);
  EXPECT_TRUE(took(drive, 9));
  EXPECT_EQ(drive.state(), PowerState::switch_on_disabled);
  drive.update(0x000F, 1 * kDriveMs);  // the master's old command does not re-enable it
  EXPECT_EQ(drive.state(), PowerState::switch_on_disabled);

  Cia402Options quick;
  quick.abort_connection_option = 3;
  drive = enabled_drive(quick);
  drive.connection_lost(0x8130, 0);
  EXPECT_TRUE(took(drive, 11));

  Cia402Options nothing;
  nothing.abort_connection_option = 0;
  drive = enabled_drive(nothing);
  drive.connection_lost(0x8130, 0);
  EXPECT_EQ(drive.state(), PowerState::operation_enabled);
}

TEST(Cia402Drive, MasterHelperDrivesTheDriveThroughFaults) {
  Cia402StateMachine drive;
  std::uint16_t controlword = 0;
  std::int64_t now = 0;
  auto run_until = [&](PowerTarget target, PowerState wanted) {
    for (int cycle = 0; cycle < 20; ++cycle) {
      controlword = next_controlword(decode_statusword(drive.statusword()), target, controlword);
      drive.update(controlword, now);
      now += kDriveMs;
      if (drive.state() == wanted) return cycle + 1;
    }
    return -1;
  };
  EXPECT_EQ(run_until(PowerTarget::operation_enabled, PowerState::operation_enabled), 4);  // 1, 2, 3, 4
  drive.raise_fault(0x7305, now);
  EXPECT_GT(run_until(PowerTarget::operation_enabled, PowerState::fault), 0);
  EXPECT_GT(run_until(PowerTarget::operation_enabled, PowerState::operation_enabled), 0);
  EXPECT_TRUE(drive.torque_follows_command());
  EXPECT_GT(run_until(PowerTarget::quick_stop, PowerState::switch_on_disabled), 0);  // option 2
  EXPECT_GT(run_until(PowerTarget::operation_enabled, PowerState::operation_enabled), 0);
  EXPECT_GT(run_until(PowerTarget::disabled, PowerState::switch_on_disabled), 0);
}

}  // namespace
}  // namespace trainer::hal::canopen
