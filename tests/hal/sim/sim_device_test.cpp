// SimDevice: parameter validation, lifecycle, encoder quantisation, plant dynamics (settling,
// static offset under motor effort, hard stops, determinism of the lazy sub-stepping),
// actuator clipping and rejection, digital outputs, and the no-heap guarantee of the RT calls.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "sim_test_support.hpp"
#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/clock.hpp"
#include "trainer/hal_sim/sim_device.hpp"

namespace trainer::hal::sim {
namespace {

using test_support::bench_params;
using test_support::Commands;
using test_support::csv_text;
using test_support::kMillisecondNs;
using test_support::kSecondNs;
using test_support::Samples;
using test_support::ScriptRow;
using test_support::Statuses;
using test_support::write_temp_csv;

// Steps a ManualClock in 1 ms cycles to `until_ns`, reading encoders each cycle like the loop.
void run_until(core::ManualClock& clock, SimDevice& device, std::int64_t until_ns) {
  Samples samples{};
  while (clock.now_ns() < until_ns) {
    clock.advance_ns(std::min(kMillisecondNs, until_ns - clock.now_ns()));
    ASSERT_EQ(device.read_encoders(samples), ReturnCode::ok);
  }
}

// Steps in 1 ms cycles, writing `commands` after every read (a loop with constant output).
void run_with_commands(core::ManualClock& clock, SimDevice& device, const Commands& commands,
                       std::int64_t until_ns) {
  Samples samples{};
  while (clock.now_ns() < until_ns) {
    clock.advance_ns(kMillisecondNs);
    ASSERT_EQ(device.read_encoders(samples), ReturnCode::ok);
    ASSERT_EQ(device.write_actuators(commands), ReturnCode::ok);
  }
}

std::string configure_error(SimDeviceParams params) {
  core::ManualClock clock;
  SimDevice device(clock, std::move(params));
  auto result = device.configure();
  return result ? std::string("(configured)") : result.error().message;
}

// --- Parameter validation -----------------------------------------------------------------

TEST(SimDeviceConfigure, AcceptsTheBenchAndExposesTheChannelLayout) {
  core::ManualClock clock;
  SimDevice device(clock, bench_params({"left", "right"}));
  ASSERT_TRUE(device.configure()) << "bench params must be valid";
  EXPECT_EQ(device.state(), LifecycleState::inactive);
  EXPECT_EQ(device.encoder_count(), 10U);
  EXPECT_EQ(device.actuator_count(), 10U);
  EXPECT_EQ(device.channel_name(0), "left.pitch");
  EXPECT_EQ(device.channel_name(7), "right.insertion");
  EXPECT_EQ(device.channel_name(9), "right.grip");
  EXPECT_EQ(device.name(), "test_bench");
  EXPECT_EQ(device.encoders(), static_cast<EncoderInterface*>(&device));
  EXPECT_EQ(device.actuators(), static_cast<ActuatorInterface*>(&device));
  EXPECT_EQ(device.digital_inputs(), static_cast<DigitalInputInterface*>(&device));
  EXPECT_EQ(device.digital_outputs(), static_cast<DigitalOutputInterface*>(&device));
}

TEST(SimDeviceConfigure, RefusesBadParametersWithMessagesNamingTheField) {
  struct Case {
    const char* what;
    void (*mutate)(SimDeviceParams&);
    const char* expected_fragment;
  };
  const std::vector<Case> cases = {
      {"no instruments", [](SimDeviceParams& p) { p.instruments.clear(); }, "0 instruments"},
      {"five instruments",
       [](SimDeviceParams& p) {
         while (p.instruments.size() < 5) p.instruments.push_back(p.instruments[0]);
         for (std::size_t i = 0; i < 5; ++i) p.instruments[i].name = std::to_string(i);
       },
       "5 instruments; expected 1..4"},
      {"duplicate name",
       [](SimDeviceParams& p) {
         p.instruments.push_back(p.instruments[0]);
       },
       "'left' is used twice"},
      {"empty instrument name", [](SimDeviceParams& p) { p.instruments[0].name.clear(); },
       "empty name"},
      {"empty device name", [](SimDeviceParams& p) { p.name.clear(); }, "name is empty"},
      {"insertion revolute",
       [](SimDeviceParams& p) { p.instruments[0].scales[kInsertionJoint].kind = JointKind::revolute; },
       "joint insertion: scale.kind is revolute; expected prismatic"},
      {"pitch prismatic",
       [](SimDeviceParams& p) { p.instruments[0].scales[kPitchJoint].kind = JointKind::prismatic; },
       "joint pitch: scale.kind is prismatic; expected revolute"},
      {"zero counts",
       [](SimDeviceParams& p) { p.instruments[0].scales[kYawJoint].counts_per_rev = 0; },
       "joint yaw: scale.counts_per_rev = 0"},
      {"negative gear",
       [](SimDeviceParams& p) { p.instruments[0].scales[kRollJoint].gear_ratio = -2.0; },
       "joint roll: scale.gear_ratio = -2"},
      {"zero capstan",
       [](SimDeviceParams& p) { p.instruments[0].scales[kInsertionJoint].capstan_radius_m = 0.0; },
       "scale.capstan_radius_m = 0"},
      {"zero torque constant",
       [](SimDeviceParams& p) { p.instruments[0].scales[kGripJoint].torque_constant_nm_per_a = 0.0; },
       "joint grip: scale.torque_constant_nm_per_a = 0"},
      {"negative current limit",
       [](SimDeviceParams& p) { p.instruments[0].scales[kGripJoint].current_limit_a = -1.0; },
       "scale.current_limit_a = -1"},
      {"zero inertia", [](SimDeviceParams& p) { p.instruments[0].plant[kPitchJoint].inertia = 0.0; },
       "plant.inertia = 0"},
      {"NaN stiffness",
       [](SimDeviceParams& p) {
         p.instruments[0].plant[kPitchJoint].hand_stiffness = std::numeric_limits<double>::quiet_NaN();
       },
       "plant.hand_stiffness = nan"},
      {"negative damping",
       [](SimDeviceParams& p) { p.instruments[0].plant[kYawJoint].hand_damping = -1.0; },
       "plant.hand_damping = -1"},
      {"inverted limits",
       [](SimDeviceParams& p) {
         p.instruments[0].plant[kRollJoint].min_position = 1.0;
         p.instruments[0].plant[kRollJoint].max_position = -1.0;
       },
       "expected finite min_position < max_position"},
      {"unstable plant",
       [](SimDeviceParams& p) { p.instruments[0].plant[kGripJoint].hand_stiffness = 1e6; },
       "too stiff for plant_substep_ns = 50000"},
      {"substep too small", [](SimDeviceParams& p) { p.plant_substep_ns = 10; },
       "plant_substep_ns = 10: expected 1000..1000000 ns"},
      {"substep too large", [](SimDeviceParams& p) { p.plant_substep_ns = 5'000'000; },
       "plant_substep_ns = 5000000"},
      {"estop bit out of range", [](SimDeviceParams& p) { p.digital.estop_input_bit = 8; },
       "digital.estop_input_bit = 8: expected -1 (not wired) or 0..7"},
      {"enable bit out of range", [](SimDeviceParams& p) { p.digital.enable_input_bit = -2; },
       "digital.enable_input_bit = -2"},
      {"same bit twice",
       [](SimDeviceParams& p) {
         p.digital.estop_input_bit = 3;
         p.digital.enable_input_bit = 3;
       },
       "both 3"},
      {"unknown builtin", [](SimDeviceParams& p) { p.script = "builtin:wave"; },
       "trainee script: unknown built-in script 'builtin:wave'"},
      {"missing script file", [](SimDeviceParams& p) { p.script = "/nonexistent/dir/x.csv"; },
       "cannot open trajectory file '/nonexistent/dir/x.csv'"},
  };
  for (const Case& test_case : cases) {
    SimDeviceParams params = bench_params({"left"});
    test_case.mutate(params);
    const std::string message = configure_error(params);
    EXPECT_NE(message.find(test_case.expected_fragment), std::string::npos)
        << test_case.what << ": got '" << message << "'";
    if (std::string(test_case.what) != "empty device name") {
      EXPECT_NE(message.find("sim device 'test_bench'"), std::string::npos) << message;
    }
  }
}

TEST(SimDeviceConfigure, RefusesScriptNamingAnInstrumentTheDeviceLacks) {
  const std::string path =
      write_temp_csv("unknown_instrument", csv_text({{0.0, "right", kNeutralPose}}));
  const std::string message = configure_error(bench_params({"left"}, path));
  EXPECT_NE(message.find(path + ":2: unknown instrument 'right'; the device has 'left'"),
            std::string::npos)
      << message;
}

// --- Lifecycle ----------------------------------------------------------------------------

TEST(SimDeviceLifecycle, CallsAreRefusedOutsideTheirStates) {
  core::ManualClock clock;
  SimDevice device(clock, bench_params({"left"}));
  Samples samples{};
  Commands commands{};
  Statuses statuses{};
  std::uint32_t levels = 0;
  EXPECT_EQ(device.state(), LifecycleState::unconfigured);
  EXPECT_EQ(device.encoder_count(), 0U);
  EXPECT_EQ(device.read_encoders(samples), ReturnCode::error);
  EXPECT_EQ(device.read_actuator_status(statuses), ReturnCode::error);
  EXPECT_EQ(device.read_digital_inputs(levels), ReturnCode::error);
  EXPECT_EQ(device.write_digital_outputs(1), ReturnCode::error);
  device.deactivate();  // safe in any state
  const auto early = device.activate();
  ASSERT_FALSE(early);
  EXPECT_NE(early.error().message.find("activate() before configure()"), std::string::npos);

  ASSERT_TRUE(device.configure());
  EXPECT_EQ(device.read_encoders(samples), ReturnCode::ok) << "encoders read while inactive";
  EXPECT_EQ(device.write_actuators(commands), ReturnCode::error) << "drives are off while inactive";
  ASSERT_TRUE(device.activate());
  EXPECT_EQ(device.state(), LifecycleState::active);
  EXPECT_FALSE(device.activate());
  const auto reconfigure = device.configure();
  ASSERT_FALSE(reconfigure);
  EXPECT_NE(reconfigure.error().message.find("deactivate() first"), std::string::npos);
  EXPECT_EQ(device.write_actuators(commands), ReturnCode::ok);
  EXPECT_EQ(device.write_actuators(std::span(commands).first(4)), ReturnCode::error)
      << "a span shorter than the channel count is refused";
  EXPECT_EQ(device.read_encoders(std::span(samples).first(4)), ReturnCode::error);
  device.deactivate();
  EXPECT_EQ(device.state(), LifecycleState::inactive);
  ASSERT_TRUE(device.configure()) << "reconfigure from inactive";
}

TEST(SimDeviceLifecycle, StartsAtTheScriptsInitialPoseAtRest) {
  const JointPose start = {0.1, -0.2, 0.08, 1.0, 0.5};
  const std::string path = write_temp_csv(
      "initial_pose", csv_text({{0.0, "left", start}, {1.0, "left", kNeutralPose}}));
  core::ManualClock clock(123 * kMillisecondNs);
  SimDevice device(clock, bench_params({"left"}, path));
  ASSERT_TRUE(device.configure());
  for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
    EXPECT_DOUBLE_EQ(device.true_position(joint), start[joint]) << kJointNames[joint];
    EXPECT_EQ(device.true_velocity(joint), 0.0);
  }
  // Script time is frozen until activate(): the hand keeps holding the initial pose.
  run_until(clock, device, clock.now_ns() + 500 * kMillisecondNs);
  EXPECT_EQ(device.script_time_s(), 0.0);
  EXPECT_NEAR(device.true_position(kPitchJoint), start[kPitchJoint], 1e-12);
  ASSERT_TRUE(device.activate());
  run_until(clock, device, clock.now_ns() + 250 * kMillisecondNs);
  EXPECT_NEAR(device.script_time_s(), 0.25, 1e-9);
  EXPECT_DOUBLE_EQ(device.script_duration_s(), 1.0);
}

// --- Encoders: quantisation ---------------------------------------------------------------

TEST(SimDeviceEncoders, ReportTheQuantisedTruePositionOfEveryChannel) {
  core::ManualClock clock;
  SimDevice device(clock, bench_params({"left", "right"}, "builtin:sweep"));
  ASSERT_TRUE(device.configure());
  ASSERT_TRUE(device.activate());
  Samples samples{};
  std::size_t moving_reads = 0;
  for (int cycle = 0; cycle < 10'000; ++cycle) {
    clock.advance_ns(kMillisecondNs);
    ASSERT_EQ(device.read_encoders(samples), ReturnCode::ok);
    for (std::size_t channel = 0; channel < device.encoder_count(); ++channel) {
      const JointScale& scale =
          device.params().instruments[channel / kJointsPerInstrument].scales[channel % kJointsPerInstrument];
      const double truth = device.true_position(channel);
      ASSERT_TRUE(samples[channel].valid);
      ASSERT_EQ(samples[channel].counts, scale.counts_from_position(truth)) << channel;
      ASSERT_EQ(samples[channel].position,
                static_cast<float>(scale.position_from_counts(samples[channel].counts)));
      // Rounding to the nearest count: within half a count (plus float rounding).
      ASSERT_LE(std::abs(static_cast<double>(samples[channel].position) - truth),
                0.5 * scale.position_per_count() + 1e-6 * std::abs(truth) + 1e-9)
          << channel;
    }
    if (std::abs(device.true_velocity(kPitchJoint)) > 1e-3) ++moving_reads;
  }
  EXPECT_GT(moving_reads, 5'000U) << "the sweep should keep the pitch joint moving";
}

TEST(SimDeviceEncoders, SettledPlantReadsEveryScriptedTargetWithinOneCount) {
  // 12 poses spread over each joint's range (not on count boundaries); each is reached in
  // 0.5 s and held 2 s, then read. With zero motor effort the hand spring settles the plant on
  // the target, so script -> plant -> counts -> position round-trips within one count.
  constexpr int kPoseCount = 12;
  const JointPose low = {-0.7, -0.7, 0.01, -3.0, 0.05};
  const JointPose high = {0.7, 0.7, 0.19, 3.0, 0.95};
  std::vector<ScriptRow> rows;
  std::vector<JointPose> poses;
  for (int k = 0; k < kPoseCount; ++k) {
    JointPose pose{};
    for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
      // Alternate ends so successive targets are far apart; irrational-ish offsets.
      const double fraction = std::fmod(0.137 + 0.618034 * k, 1.0);
      pose[joint] = low[joint] + fraction * (high[joint] - low[joint]);
    }
    poses.push_back(pose);
    const double arrive_s = 2.5 * k;
    rows.push_back({arrive_s, "left", pose});
    rows.push_back({arrive_s + 2.0, "left", pose});
  }
  core::ManualClock clock;
  SimDevice device(clock, bench_params({"left"}, write_temp_csv("round_trip", csv_text(rows))));
  ASSERT_TRUE(device.configure());
  ASSERT_TRUE(device.activate());
  Samples samples{};
  for (int k = 0; k < kPoseCount; ++k) {
    const std::int64_t read_at_ns =
        static_cast<std::int64_t>((2.5 * k + 2.0) * static_cast<double>(kSecondNs));
    run_until(clock, device, read_at_ns);
    ASSERT_EQ(device.read_encoders(samples), ReturnCode::ok);
    for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
      const double per_count = device.params().instruments[0].scales[joint].position_per_count();
      EXPECT_LE(std::abs(static_cast<double>(samples[joint].position) - poses[static_cast<std::size_t>(k)][joint]),
                per_count)
          << "pose " << k << " joint " << kJointNames[joint];
    }
  }
}

// --- Plant dynamics -----------------------------------------------------------------------

TEST(SimDevicePlant, StepInTheScriptConvergesToTheTarget) {
  const JointPose step = {0.3, -0.3, 0.1, 1.0, 0.6};
  const std::string path = write_temp_csv(
      "step", csv_text({{0.0, "left", kNeutralPose}, {1.0, "left", kNeutralPose},
                        {1.01, "left", step}}));
  core::ManualClock clock;
  SimDevice device(clock, bench_params({"left"}, path));
  ASSERT_TRUE(device.configure());
  ASSERT_TRUE(device.activate());
  run_until(clock, device, 1'015 * kMillisecondNs);
  for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
    // 5 ms after the step the inertia still lags well behind the hand.
    const double remaining = std::abs(device.true_position(joint) - step[joint]);
    EXPECT_GT(remaining, 0.3 * std::abs(step[joint] - kNeutralPose[joint])) << kJointNames[joint];
  }
  run_until(clock, device, 4 * kSecondNs);
  for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
    EXPECT_NEAR(device.true_position(joint), step[joint], 1e-6) << kJointNames[joint];
    EXPECT_NEAR(device.true_velocity(joint), 0.0, 1e-5) << kJointNames[joint];
  }
}

TEST(SimDevicePlant, ConstantMotorEffortGivesTheStaticOffsetEffortOverHandStiffness) {
  core::ManualClock clock;
  SimDevice device(clock, bench_params({"left"}));
  ASSERT_TRUE(device.configure());
  ASSERT_TRUE(device.activate());
  // Efforts inside every current limit; offsets stay inside every joint's range.
  const JointPose effort = {0.5, -1.0, 3.0, 0.04, 0.02};  // N·m, N·m, N, N·m, N·m
  Commands commands{};
  for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
    commands[joint] = {static_cast<float>(effort[joint]), true};
  }
  run_with_commands(clock, device, commands, 3 * kSecondNs);
  Samples samples{};
  ASSERT_EQ(device.read_encoders(samples), ReturnCode::ok);
  for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
    const double stiffness = device.params().instruments[0].plant[joint].hand_stiffness;
    const double expected_offset = static_cast<double>(static_cast<float>(effort[joint])) / stiffness;
    const double true_offset = device.true_position(joint) - kNeutralPose[joint];
    const double measured_offset = static_cast<double>(samples[joint].position) - kNeutralPose[joint];
    EXPECT_NEAR(true_offset, expected_offset, 0.01 * std::abs(expected_offset)) << kJointNames[joint];
    EXPECT_NEAR(measured_offset, expected_offset, 0.01 * std::abs(expected_offset))
        << kJointNames[joint];
    EXPECT_DOUBLE_EQ(device.applied_effort(joint), static_cast<double>(static_cast<float>(effort[joint])));
  }
}

TEST(SimDevicePlant, JointLimitsAreHardStops) {
  // The hand pulls pitch, yaw, insertion and grip beyond their stops; roll is pushed beyond
  // its stop by the motor (target 3.0 rad + 0.058 N·m / 0.2 N·m/rad = 3.29 rad > 3.2 rad).
  const JointPose beyond = {1.0, -1.0, 0.25, 3.0, -0.2};
  const std::string path = write_temp_csv(
      "limits", csv_text({{0.0, "left", kNeutralPose}, {1.0, "left", beyond}}));
  core::ManualClock clock;
  SimDevice device(clock, bench_params({"left"}, path));
  ASSERT_TRUE(device.configure());
  ASSERT_TRUE(device.activate());
  Commands commands{};
  commands[kRollJoint] = {1.0F, true};  // clipped to the 0.058 N·m limit
  Samples samples{};
  const JointPlantParams* plants = device.params().instruments[0].plant.data();
  while (clock.now_ns() < 3 * kSecondNs) {
    clock.advance_ns(kMillisecondNs);
    ASSERT_EQ(device.read_encoders(samples), ReturnCode::ok);
    ASSERT_EQ(device.write_actuators(commands), ReturnCode::ok);
    for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
      ASSERT_GE(device.true_position(joint), plants[joint].min_position) << kJointNames[joint];
      ASSERT_LE(device.true_position(joint), plants[joint].max_position) << kJointNames[joint];
    }
  }
  EXPECT_EQ(device.true_position(kPitchJoint), plants[kPitchJoint].max_position);
  EXPECT_EQ(device.true_position(kYawJoint), plants[kYawJoint].min_position);
  EXPECT_EQ(device.true_position(kInsertionJoint), plants[kInsertionJoint].max_position);
  EXPECT_EQ(device.true_position(kRollJoint), plants[kRollJoint].max_position);
  EXPECT_EQ(device.true_position(kGripJoint), plants[kGripJoint].min_position);
  for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
    EXPECT_EQ(device.true_velocity(joint), 0.0) << kJointNames[joint] << " rests on its stop";
  }
  // Leaving the stop is free: bring the roll motor to zero and the hand target (3.0 rad) pulls
  // the joint off the 3.2 rad stop.
  commands[kRollJoint] = {0.0F, true};
  run_with_commands(clock, device, commands, 6 * kSecondNs);
  EXPECT_NEAR(device.true_position(kRollJoint), 3.0, 1e-6);
}

TEST(SimDevicePlant, LazySubsteppingIsIndependentOfTheReadPattern) {
  // Two identical devices, read at different rates: wherever both have advanced to the same
  // instant their states are bit-identical, because the plant only moves in whole sub-steps
  // from its activation time and carries the remainder.
  core::ManualClock clock_a;
  core::ManualClock clock_b;
  SimDevice device_a(clock_a, bench_params({"left"}, "builtin:sweep"));
  SimDevice device_b(clock_b, bench_params({"left"}, "builtin:sweep"));
  ASSERT_TRUE(device_a.configure() && device_a.activate());
  ASSERT_TRUE(device_b.configure() && device_b.activate());
  Samples samples{};
  for (int block = 1; block <= 400; ++block) {
    const std::int64_t target_ns = block * 3 * kMillisecondNs;
    while (clock_a.now_ns() < target_ns) {
      clock_a.advance_ns(kMillisecondNs);
      ASSERT_EQ(device_a.read_encoders(samples), ReturnCode::ok);
    }
    while (clock_b.now_ns() < target_ns) {
      clock_b.advance_ns(std::min<std::int64_t>(370'000, target_ns - clock_b.now_ns()));
      ASSERT_EQ(device_b.read_encoders(samples), ReturnCode::ok);
    }
    ASSERT_EQ(device_a.simulated_time_ns(), device_b.simulated_time_ns());
    for (std::size_t channel = 0; channel < device_a.channel_count(); ++channel) {
      ASSERT_EQ(device_a.true_position(channel), device_b.true_position(channel)) << channel;
      ASSERT_EQ(device_a.true_velocity(channel), device_b.true_velocity(channel)) << channel;
    }
  }
  // The remainder is carried, not dropped: 50 reads of 1/50 of a sub-step advance one sub-step.
  core::ManualClock clock_c;
  SimDevice device_c(clock_c, bench_params({"left"}));
  ASSERT_TRUE(device_c.configure() && device_c.activate());
  const std::int64_t substep_ns = device_c.params().plant_substep_ns;
  for (int i = 0; i < 50; ++i) {
    clock_c.advance_ns(substep_ns / 50);
    ASSERT_EQ(device_c.read_encoders(samples), ReturnCode::ok);
  }
  EXPECT_EQ(device_c.simulated_time_ns(), substep_ns);
}

// --- Actuators ----------------------------------------------------------------------------

TEST(SimDeviceActuators, EffortIsClippedAtTheCurrentLimitAndFlaggedSaturated) {
  core::ManualClock clock;
  SimDevice device(clock, bench_params({"left"}));
  ASSERT_TRUE(device.configure() && device.activate());
  const auto& scales = device.params().instruments[0].scales;
  Commands commands{};
  commands[kPitchJoint] = {10.0F, true};
  commands[kYawJoint] = {-10.0F, true};
  commands[kInsertionJoint] = {2.5F, true};
  commands[kRollJoint] = {-0.05F, true};
  commands[kGripJoint] = {100.0F, false};  // saturated but disabled: nothing applied
  ASSERT_EQ(device.write_actuators(commands), ReturnCode::ok);
  Statuses statuses{};
  ASSERT_EQ(device.read_actuator_status(statuses), ReturnCode::ok);

  const double pitch_max = scales[kPitchJoint].max_effort();
  EXPECT_NEAR(pitch_max, 0.0302 * 20.0 * 2.0, 1e-12);
  EXPECT_FLOAT_EQ(statuses[kPitchJoint].applied_effort, static_cast<float>(pitch_max));
  EXPECT_TRUE(statuses[kPitchJoint].saturated);
  EXPECT_TRUE(statuses[kPitchJoint].enabled);
  EXPECT_FLOAT_EQ(statuses[kYawJoint].applied_effort, static_cast<float>(-pitch_max));
  EXPECT_TRUE(statuses[kYawJoint].saturated);
  EXPECT_FLOAT_EQ(statuses[kInsertionJoint].applied_effort, 2.5F);
  EXPECT_FALSE(statuses[kInsertionJoint].saturated);
  EXPECT_FLOAT_EQ(statuses[kRollJoint].applied_effort, -0.05F);
  EXPECT_FALSE(statuses[kRollJoint].saturated);
  EXPECT_EQ(statuses[kGripJoint].applied_effort, 0.0F);
  EXPECT_FALSE(statuses[kGripJoint].enabled);
  EXPECT_TRUE(statuses[kGripJoint].saturated);
  for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
    EXPECT_FALSE(statuses[joint].fault);
    EXPECT_FLOAT_EQ(static_cast<float>(device.applied_effort(joint)), statuses[joint].applied_effort);
  }
}

TEST(SimDeviceActuators, NonFiniteEffortIsRejectedAsAFaultAndNotApplied) {
  core::ManualClock clock;
  SimDevice device(clock, bench_params({"left"}));
  ASSERT_TRUE(device.configure() && device.activate());
  Commands commands{};
  commands[kPitchJoint] = {std::numeric_limits<float>::quiet_NaN(), true};
  commands[kYawJoint] = {std::numeric_limits<float>::infinity(), true};
  commands[kInsertionJoint] = {1.0F, true};
  EXPECT_EQ(device.write_actuators(commands), ReturnCode::error);
  Statuses statuses{};
  ASSERT_EQ(device.read_actuator_status(statuses), ReturnCode::ok);
  for (const std::size_t joint : {kPitchJoint, kYawJoint}) {
    EXPECT_TRUE(statuses[joint].fault) << kJointNames[joint];
    EXPECT_FALSE(statuses[joint].enabled);
    EXPECT_EQ(statuses[joint].applied_effort, 0.0F);
    EXPECT_EQ(device.applied_effort(joint), 0.0);
  }
  EXPECT_FALSE(statuses[kInsertionJoint].fault);
  EXPECT_FLOAT_EQ(statuses[kInsertionJoint].applied_effort, 1.0F);

  // Nothing pushes pitch: it stays on the hand target while insertion is offset by 1 N.
  Samples samples{};
  for (int cycle = 0; cycle < 2000; ++cycle) {
    clock.advance_ns(kMillisecondNs);
    ASSERT_EQ(device.read_encoders(samples), ReturnCode::ok);
  }
  EXPECT_NEAR(device.true_position(kPitchJoint), 0.0, 1e-12);
  EXPECT_NEAR(device.true_position(kInsertionJoint), 0.05 + 1.0 / 200.0, 1e-6);

  // The next finite command clears the rejection.
  commands[kPitchJoint] = {0.2F, true};
  commands[kYawJoint] = {0.0F, true};
  EXPECT_EQ(device.write_actuators(commands), ReturnCode::ok);
  ASSERT_EQ(device.read_actuator_status(statuses), ReturnCode::ok);
  EXPECT_FALSE(statuses[kPitchJoint].fault);
  EXPECT_FLOAT_EQ(statuses[kPitchJoint].applied_effort, 0.2F);
}

TEST(SimDeviceActuators, DeactivateZeroesEffortsAndOutputs) {
  core::ManualClock clock;
  SimDevice device(clock, bench_params({"left", "right"}));
  ASSERT_TRUE(device.configure() && device.activate());
  Commands commands{};
  for (std::size_t channel = 0; channel < device.actuator_count(); ++channel) {
    commands[channel] = {0.01F, true};
  }
  commands[kPitchJoint] = {0.8F, true};
  run_with_commands(clock, device, commands, 2 * kSecondNs);
  ASSERT_EQ(device.write_digital_outputs(0b101U), ReturnCode::ok);
  EXPECT_NEAR(device.true_position(kPitchJoint), 0.4, 1e-4) << "pushed by 0.8 N·m";

  device.deactivate();
  EXPECT_EQ(device.state(), LifecycleState::inactive);
  EXPECT_EQ(device.digital_output_levels(), 0U);
  Statuses statuses{};
  ASSERT_EQ(device.read_actuator_status(statuses), ReturnCode::ok);
  for (std::size_t channel = 0; channel < device.actuator_count(); ++channel) {
    EXPECT_EQ(statuses[channel].applied_effort, 0.0F) << channel;
    EXPECT_FALSE(statuses[channel].enabled) << channel;
    EXPECT_EQ(device.applied_effort(channel), 0.0);
  }
  EXPECT_EQ(device.write_actuators(commands), ReturnCode::error) << "inactive: drives are off";
  // With no motor effort the hand brings pitch back to its target.
  run_until(clock, device, 5 * kSecondNs);
  EXPECT_NEAR(device.true_position(kPitchJoint), 0.0, 1e-6);
}

// --- Digital lines ------------------------------------------------------------------------

TEST(SimDeviceDigital, OutputsAreStoredAndOutOfRangeBitsRefused) {
  core::ManualClock clock;
  SimDevice device(clock, bench_params({"left"}));
  ASSERT_TRUE(device.configure());
  EXPECT_EQ(device.digital_output_count(), 8U);
  EXPECT_EQ(device.digital_input_count(), 8U);
  EXPECT_EQ(device.write_digital_outputs(0b1000'0001U), ReturnCode::ok);
  EXPECT_EQ(device.digital_output_levels(), 0b1000'0001U);
  EXPECT_EQ(device.write_digital_outputs(1U << 8), ReturnCode::error);
  EXPECT_EQ(device.digital_output_levels(), 0b1000'0001U) << "a refused write stores nothing";
}

// --- No heap on the RT path ---------------------------------------------------------------

TEST(SimDeviceRealTime, TenThousandCyclesAllocateNothing) {
  if (!core::alloc::hooks_installed()) GTEST_SKIP() << "allocation hooks not linked";
  core::ManualClock clock;
  SimDevice device(clock, bench_params({"a", "b", "c", "d"}, "builtin:sweep"));
  ASSERT_TRUE(device.configure() && device.activate());
  Samples samples{};
  Commands commands{};
  Statuses statuses{};
  std::uint32_t levels = 0;
  int failures = 0;

  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (int cycle = 0; cycle < 10'000; ++cycle) {
    clock.advance_ns(kMillisecondNs);
    if (cycle % 1000 == 500) {
      device.inject_read_failures(2);
      device.inject_late_reply(100'000, 1);
      (void)device.inject_stuck_encoder(static_cast<std::size_t>(cycle / 1000), cycle % 2000 == 500);
    }
    if (device.read_encoders(samples) != ReturnCode::ok) ++failures;
    for (std::size_t channel = 0; channel < kMaxChannels; ++channel) {
      commands[channel] = {std::sin(static_cast<float>(cycle) * 0.01F) * 0.05F, true};
    }
    if (device.write_actuators(commands) != ReturnCode::ok) ++failures;
    if (device.read_actuator_status(statuses) != ReturnCode::ok) ++failures;
    if (device.read_digital_inputs(levels) != ReturnCode::ok) ++failures;
    if (device.write_digital_outputs(levels & 0x3U) != ReturnCode::ok) ++failures;
  }
  core::alloc::end_counting_this_thread();
  const std::uint64_t after = core::alloc::counted_allocations();

  EXPECT_EQ(after, before) << "RT calls allocated " << (after - before) << " times";
  EXPECT_EQ(failures, 20) << "only the 10 x 2 injected read failures may fail";
  EXPECT_GT(device.script_time_s(), 9.9);
}

}  // namespace
}  // namespace trainer::hal::sim
