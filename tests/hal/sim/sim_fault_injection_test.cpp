// SimDevice fault injection, one test per fault: stuck encoder, read failures, late replies,
// e-stop and enable switch inputs, drive faults.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "sim_test_support.hpp"
#include "trainer/core/clock.hpp"
#include "trainer/hal_sim/sim_device.hpp"

namespace trainer::hal::sim {
namespace {

using test_support::bench_params;
using test_support::Commands;
using test_support::kMillisecondNs;
using test_support::Samples;
using test_support::Statuses;

class SimFaultInjection : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(device_.configure());
    ASSERT_TRUE(device_.activate());
  }
  ReturnCode step_and_read() {
    clock_.advance_ns(kMillisecondNs);
    return device_.read_encoders(samples_);
  }

  core::ManualClock clock_;
  SimDevice device_{clock_, bench_params({"left", "right"}, "builtin:sweep")};
  Samples samples_{};
};

TEST_F(SimFaultInjection, StuckEncoderFreezesItsCountsWhileThePlantMoves) {
  for (int cycle = 0; cycle < 1000; ++cycle) ASSERT_EQ(step_and_read(), ReturnCode::ok);
  const std::int64_t frozen_counts = samples_[kPitchJoint].counts;
  const std::int64_t yaw_counts_before = samples_[kYawJoint].counts;
  const double pitch_before = device_.true_position(kPitchJoint);
  ASSERT_TRUE(device_.inject_stuck_encoder(kPitchJoint, true));

  for (int cycle = 0; cycle < 1000; ++cycle) {
    ASSERT_EQ(step_and_read(), ReturnCode::ok);
    ASSERT_EQ(samples_[kPitchJoint].counts, frozen_counts);
    ASSERT_TRUE(samples_[kPitchJoint].valid) << "a stuck encoder looks healthy";
  }
  const JointScale& pitch_scale = device_.params().instruments[0].scales[kPitchJoint];
  const double moved = std::abs(device_.true_position(kPitchJoint) - pitch_before);
  EXPECT_GT(moved, 100.0 * pitch_scale.position_per_count()) << "the plant kept moving";
  EXPECT_NE(samples_[kYawJoint].counts, yaw_counts_before) << "other channels unaffected";

  ASSERT_TRUE(device_.inject_stuck_encoder(kPitchJoint, false));
  ASSERT_EQ(step_and_read(), ReturnCode::ok);
  EXPECT_EQ(samples_[kPitchJoint].counts,
            pitch_scale.counts_from_position(device_.true_position(kPitchJoint)));
  EXPECT_FALSE(device_.inject_stuck_encoder(kMaxChannels, true)) << "channel out of range";
}

TEST_F(SimFaultInjection, ReadFailuresFailExactlyTheRequestedNumberOfReads) {
  for (int cycle = 0; cycle < 1000; ++cycle) ASSERT_EQ(step_and_read(), ReturnCode::ok);
  const Samples last_good = samples_;
  device_.inject_read_failures(3);
  for (int failure = 0; failure < 3; ++failure) {
    ASSERT_EQ(step_and_read(), ReturnCode::error) << "read " << failure;
    for (std::size_t channel = 0; channel < device_.encoder_count(); ++channel) {
      EXPECT_FALSE(samples_[channel].valid);
      EXPECT_EQ(samples_[channel].counts, last_good[channel].counts) << "last good counts kept";
    }
  }
  ASSERT_EQ(step_and_read(), ReturnCode::ok);
  for (std::size_t channel = 0; channel < device_.encoder_count(); ++channel) {
    EXPECT_TRUE(samples_[channel].valid);
  }
  // The plant kept running through the failures: the fresh read reflects 4 ms of motion.
  EXPECT_NE(samples_[kPitchJoint].counts, last_good[kPitchJoint].counts);
}

TEST_F(SimFaultInjection, LateReplySleepsOnTheClockForTheRequestedReads) {
  constexpr std::int64_t kDelayNs = 300'000;
  device_.inject_late_reply(kDelayNs, 2);
  for (int late = 0; late < 2; ++late) {
    const std::int64_t before_ns = clock_.now_ns();
    ASSERT_EQ(device_.read_encoders(samples_), ReturnCode::ok);
    EXPECT_EQ(clock_.now_ns(), before_ns + kDelayNs) << "late reply " << late;
    // The answer describes the plant at reply time, not at request time.
    EXPECT_GT(device_.simulated_time_ns(), before_ns);
    EXPECT_LE(clock_.now_ns() - device_.simulated_time_ns(), device_.params().plant_substep_ns);
  }
  const std::int64_t before_ns = clock_.now_ns();
  ASSERT_EQ(device_.read_encoders(samples_), ReturnCode::ok);
  EXPECT_EQ(clock_.now_ns(), before_ns) << "only two replies were late";
}

TEST_F(SimFaultInjection, EstopAndEnableSwitchDriveTheirInputBits) {
  std::uint32_t levels = 0xFFFF'FFFFU;
  ASSERT_EQ(device_.read_digital_inputs(levels), ReturnCode::ok);
  EXPECT_EQ(levels, 0b10U) << "default: e-stop released (bit 0 low), enable held (bit 1 high)";
  device_.set_estop(true);
  ASSERT_EQ(device_.read_digital_inputs(levels), ReturnCode::ok);
  EXPECT_EQ(levels, 0b11U);
  device_.set_enable_switch(false);
  ASSERT_EQ(device_.read_digital_inputs(levels), ReturnCode::ok);
  EXPECT_EQ(levels, 0b01U);
  device_.set_estop(false);
  ASSERT_EQ(device_.read_digital_inputs(levels), ReturnCode::ok);
  EXPECT_EQ(levels, 0U);
}

TEST(SimDigitalMap, BitsFollowTheMapAndUnwiredSwitchesReadLow) {
  core::ManualClock clock;
  SimDeviceParams params = bench_params({"left"});
  params.digital.estop_input_bit = 5;
  params.digital.enable_input_bit = -1;
  SimDevice device(clock, params);
  ASSERT_TRUE(device.configure());
  std::uint32_t levels = 0;
  ASSERT_EQ(device.read_digital_inputs(levels), ReturnCode::ok);
  EXPECT_EQ(levels, 0U) << "enable switch not wired";
  device.set_estop(true);
  ASSERT_EQ(device.read_digital_inputs(levels), ReturnCode::ok);
  EXPECT_EQ(levels, 1U << 5);
}

TEST_F(SimFaultInjection, DriveFaultRemovesTorqueAndAsksTheControllerToDeactivate) {
  constexpr std::size_t kFaulted = 5 + kInsertionJoint;  // right.insertion
  Commands commands{};
  for (std::size_t channel = 0; channel < device_.actuator_count(); ++channel) {
    commands[channel] = {0.01F, true};
  }
  ASSERT_EQ(step_and_read(), ReturnCode::ok);
  ASSERT_EQ(device_.write_actuators(commands), ReturnCode::ok);
  ASSERT_TRUE(device_.inject_drive_fault(kFaulted, true));

  EXPECT_EQ(device_.write_actuators(commands), ReturnCode::deactivate);
  Statuses statuses{};
  EXPECT_EQ(device_.read_actuator_status(statuses), ReturnCode::deactivate);
  for (std::size_t channel = 0; channel < device_.actuator_count(); ++channel) {
    if (channel == kFaulted) {
      EXPECT_TRUE(statuses[channel].fault);
      EXPECT_FALSE(statuses[channel].enabled);
      EXPECT_EQ(statuses[channel].applied_effort, 0.0F);
      EXPECT_EQ(device_.applied_effort(channel), 0.0);
    } else {
      EXPECT_FALSE(statuses[channel].fault) << channel;
      EXPECT_FLOAT_EQ(statuses[channel].applied_effort, 0.01F) << channel;
    }
  }
  EXPECT_EQ(step_and_read(), ReturnCode::ok) << "encoders keep working";

  // The drive refuses to enable while faulted; clearing the fault lets it.
  device_.deactivate();
  const auto refused = device_.activate();
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("channel 7 (right.insertion) reports a fault"),
            std::string::npos)
      << refused.error().message;
  ASSERT_TRUE(device_.inject_drive_fault(kFaulted, false));
  ASSERT_TRUE(device_.activate());
  EXPECT_EQ(device_.write_actuators(commands), ReturnCode::ok);
  EXPECT_EQ(device_.read_actuator_status(statuses), ReturnCode::ok);
  EXPECT_FALSE(statuses[kFaulted].fault);
  EXPECT_FALSE(device_.inject_drive_fault(kMaxChannels, true)) << "channel out of range";
}

}  // namespace
}  // namespace trainer::hal::sim
