// The safety chain's contract: starts faulted, arms only on an explicit reset with clear
// inputs, zeroes force in the same call a fault appears, never re-arms by itself.
#include "trainer/safety/safety_supervisor.hpp"

#include <limits>

#include <gtest/gtest.h>

namespace trainer::safety {
namespace {

SafetyLimits test_limits() {
  SafetyLimits limits;
  limits.max_force_n = 5.0F;
  limits.max_force_rate_n_per_s = 1000.0F;  // 1 N per 1 ms cycle
  limits.max_joint_speed_rad_per_s = 10.0F;
  limits.max_insertion_speed_m_per_s = 0.5F;
  limits.passivity_energy_bound_j = 0.1F;
  return limits;
}

constexpr float kDt = 1e-3F;

SafetySupervisor armed_supervisor(SafetyLimits limits = test_limits()) {
  SafetySupervisor s(limits, 2);
  s.request_reset();
  EXPECT_TRUE(s.evaluate_inputs({}, 0));
  return s;
}

TEST(SafetySupervisor, StartsFaultedAndCommandsNoForce) {
  SafetySupervisor s(test_limits(), 1);
  EXPECT_FALSE(s.armed());
  EXPECT_EQ(s.first_fault(), Fault::not_armed);
  EXPECT_EQ(s.limit_force(0, Vec3(1, 0, 0), kDt, 0), Vec3::Zero());
  EXPECT_FALSE(s.evaluate_inputs({}, 1));  // no reset requested: stays faulted
}

TEST(SafetySupervisor, ResetArmsOnlyWithClearInputs) {
  SafetySupervisor s(test_limits(), 1);
  s.request_reset();
  EXPECT_FALSE(s.evaluate_inputs({.estop_active = true}, 1));
  EXPECT_TRUE(s.latched_faults() & bit(Fault::estop));
  // The request was consumed; releasing the e-stop alone does not arm.
  EXPECT_FALSE(s.evaluate_inputs({}, 2));
  s.request_reset();
  EXPECT_TRUE(s.evaluate_inputs({}, 3));
  EXPECT_EQ(s.arm_count(), 1U);
}

TEST(SafetySupervisor, EstopZeroesForceAndLatches) {
  SafetySupervisor s = armed_supervisor();
  EXPECT_NE(s.limit_force(0, Vec3(0.5F, 0, 0), kDt, 1), Vec3::Zero());
  s.evaluate_inputs({.estop_active = true}, 2);
  EXPECT_EQ(s.limit_force(0, Vec3(0.5F, 0, 0), kDt, 2), Vec3::Zero());
  EXPECT_EQ(s.first_fault(), Fault::estop);
  EXPECT_EQ(s.first_fault_cycle(), 2U);
  s.evaluate_inputs({}, 3);  // released: still latched
  EXPECT_FALSE(s.armed());
}

TEST(SafetySupervisor, DriveFaultAndEnableRelease) {
  SafetySupervisor drive = armed_supervisor();
  drive.evaluate_inputs({.drive_fault = true}, 5);
  EXPECT_EQ(drive.first_fault(), Fault::drive_fault);

  SafetyLimits limits = test_limits();
  limits.require_enable_input = true;
  SafetySupervisor s(limits, 1);
  s.request_reset();
  EXPECT_FALSE(s.evaluate_inputs({.enable_held = false}, 1));
  s.request_reset();
  EXPECT_TRUE(s.evaluate_inputs({.enable_held = true}, 2));
  s.evaluate_inputs({.enable_held = false}, 3);
  EXPECT_EQ(s.first_fault(), Fault::enable_released);
}

TEST(SafetySupervisor, NonFiniteForceLatchesAndReturnsZero) {
  SafetySupervisor s = armed_supervisor();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(s.limit_force(0, Vec3(nan, 0, 0), kDt, 9), Vec3::Zero());
  EXPECT_EQ(s.first_fault(), Fault::non_finite);
  EXPECT_EQ(s.limit_force(0, Vec3(0.1F, 0, 0), kDt, 10), Vec3::Zero());
  // NaN is latched even while unarmed: nothing is lost.
  SafetySupervisor unarmed(test_limits(), 1);
  (void)unarmed.limit_force(0, Vec3(std::numeric_limits<float>::infinity(), 0, 0), kDt, 1);
  EXPECT_TRUE(unarmed.latched_faults() & bit(Fault::non_finite));
}

TEST(SafetySupervisor, ClampsMagnitudeAndLimitsRise) {
  SafetySupervisor s = armed_supervisor();
  // Rise limited to 1 N per cycle.
  Vec3 f = s.limit_force(0, Vec3(0, 0, 100.0F), kDt, 1);
  EXPECT_NEAR(f.z(), 1.0F, 1e-5F);
  for (int i = 0; i < 10; ++i) f = s.limit_force(0, Vec3(0, 0, 100.0F), kDt, 2);
  EXPECT_NEAR(f.norm(), 5.0F, 1e-5F);  // clamped to max_force_n
  EXPECT_GT(s.clamped_cycles(), 0U);
  EXPECT_GT(s.slew_limited_cycles(), 0U);
  // A drop to zero is never delayed.
  EXPECT_EQ(s.limit_force(0, Vec3::Zero(), kDt, 3), Vec3::Zero());
  // A reversal is slew limited.
  for (int i = 0; i < 10; ++i) f = s.limit_force(0, Vec3(0, 0, 4.0F), kDt, 4);
  f = s.limit_force(0, Vec3(0, 0, -4.0F), kDt, 5);
  EXPECT_NEAR(f.z(), 3.0F, 1e-5F);
  // Instruments are limited independently.
  EXPECT_NEAR(s.limit_force(1, Vec3(0, 1.0F, 0), kDt, 6).y(), 1.0F, 1e-6F);
}

TEST(SafetySupervisor, HugeFiniteForcesAreClampedAlongTheirDirection) {
  // A finite request too large for a float norm (|F|² overflows beyond ~1.8e19 N) still ends as
  // max_force_n along its own direction, not as zero (the direction is what the user feels).
  for (const Vec3& requested : {Vec3(3e38F, -3e38F, 3e38F), Vec3(1e20F, 0.0F, 0.0F),
                                Vec3(0.0F, 2e19F, 2e19F), Vec3(0.0F, 0.0F, 1e3F)}) {
    SafetySupervisor s = armed_supervisor();
    Vec3 f = Vec3::Zero();
    for (int i = 0; i < 10; ++i) f = s.limit_force(0, requested, kDt, static_cast<std::uint64_t>(i));
    EXPECT_TRUE(s.armed());
    EXPECT_NEAR(f.norm(), 5.0F, 1e-5F) << requested.transpose();
    EXPECT_NEAR(f.normalized().dot(requested.cast<double>().normalized().cast<float>()), 1.0F, 1e-6F)
        << requested.transpose();
  }
}

TEST(SafetySupervisor, NonPositiveOrNonFiniteTimeStepsNeverRaiseTheForce) {
  // A negative dt used to turn the slew limit around: each cycle stepped |rate·dt| away from
  // the request, past max_force_n (−4, −8, −12 N … for a 5 N request at 1 N per cycle).
  SafetySupervisor s = armed_supervisor();
  for (int i = 0; i < 20; ++i) {
    const Vec3 f = s.limit_force(0, Vec3(5.0F, 0.0F, 0.0F), -4e-3F, static_cast<std::uint64_t>(i));
    EXPECT_EQ(f, Vec3::Zero()) << "cycle " << i;
  }
  // dt = 0: nothing may rise in no time.
  EXPECT_EQ(s.limit_force(0, Vec3(5.0F, 0.0F, 0.0F), 0.0F, 30), Vec3::Zero());
  // A proper dt then rises at the slew rate again.
  EXPECT_NEAR(s.limit_force(0, Vec3(5.0F, 0.0F, 0.0F), kDt, 31).x(), 1.0F, 1e-6F);
  // A non-finite dt is a non-finite number: latched, zero force; and the passivity observer
  // never integrates it (its energy would stay NaN and the check silently off).
  EXPECT_EQ(s.limit_force(0, Vec3(5.0F, 0.0F, 0.0F), std::numeric_limits<float>::quiet_NaN(), 32),
            Vec3::Zero());
  EXPECT_EQ(s.first_fault(), Fault::non_finite);
  SafetySupervisor observer = armed_supervisor();
  observer.observe_power(0, Vec3(1.0F, 0.0F, 0.0F), Vec3(1.0F, 0.0F, 0.0F),
                         std::numeric_limits<float>::infinity(), 1);
  EXPECT_EQ(observer.first_fault(), Fault::non_finite);
  SafetySupervisor negative = armed_supervisor();
  negative.observe_power(0, Vec3(1.0F, 0.0F, 0.0F), Vec3(-1.0F, 0.0F, 0.0F), -1.0F, 1);
  EXPECT_EQ(negative.delivered_energy_j(0), 0.0F);  // nothing integrated over negative time
  EXPECT_TRUE(negative.armed());
}

TEST(SafetySupervisor, ReduceLastForceStartsTheNextSlewFromTheRenderedForce) {
  SafetySupervisor s = armed_supervisor();
  Vec3 f = Vec3::Zero();
  for (int i = 0; i < 10; ++i) f = s.limit_force(0, Vec3(0, 0, 4.0F), kDt, 1);
  ASSERT_NEAR(f.z(), 4.0F, 1e-6F);
  // The actuators rendered only 1 N of the 4 N allowed: the next rise starts from 1 N.
  s.reduce_last_force(0, Vec3(0, 0, 1.0F));
  EXPECT_NEAR(s.limit_force(0, Vec3(0, 0, 4.0F), kDt, 2).z(), 2.0F, 1e-5F);
  // Never a raise, nothing non-finite, nothing while faulted.
  s.reduce_last_force(0, Vec3(0, 0, 3.0F));
  EXPECT_NEAR(s.limit_force(0, Vec3(0, 0, 4.0F), kDt, 3).z(), 3.0F, 1e-5F);
  s.reduce_last_force(0, Vec3(std::numeric_limits<float>::quiet_NaN(), 0, 0));
  EXPECT_TRUE(s.armed());
  EXPECT_NEAR(s.limit_force(0, Vec3(0, 0, 4.0F), kDt, 4).z(), 4.0F, 1e-5F);
  s.latch(Fault::estop, 5);
  s.reduce_last_force(0, Vec3(0, 0, 1.0F));
  s.request_reset();
  ASSERT_TRUE(s.evaluate_inputs({}, 6));
  EXPECT_NEAR(s.limit_force(0, Vec3(0, 0, 4.0F), kDt, 6).z(), 1.0F, 1e-5F);  // from zero
}

TEST(SafetySupervisor, EncoderJumpLatches) {
  SafetySupervisor s = armed_supervisor();
  s.check_joint_step(false, 0.0F, 0.009F, kDt, 1);  // 9 rad/s < 10
  s.check_joint_step(true, 0.1F, 0.1004F, kDt, 1);  // 0.4 m/s < 0.5
  EXPECT_TRUE(s.armed());
  s.check_joint_step(true, 0.1F, 0.1006F, kDt, 2);
  EXPECT_EQ(s.first_fault(), Fault::encoder_jump);
  SafetySupervisor t = armed_supervisor();
  t.check_joint_step(false, 0.0F, std::numeric_limits<float>::quiet_NaN(), kDt, 3);
  EXPECT_EQ(t.first_fault(), Fault::non_finite);
}

TEST(SafetySupervisor, PassivityObserverCatchesActiveEnvironment) {
  // A passive spring: pushing in and releasing returns at most what was stored.
  SafetySupervisor passive = armed_supervisor();
  const float k = 400.0F;
  for (int i = 0; i < 2000; ++i) {
    const float t = static_cast<float>(i) * kDt;
    const float x = 0.01F * std::sin(3.14159265F * t);  // in then out over 1 s
    const float v = 0.01F * 3.14159265F * std::cos(3.14159265F * t);
    const Vec3 force(x > 0.0F ? -k * x : 0.0F, 0, 0);
    passive.observe_power(0, force, Vec3(v, 0, 0), kDt, static_cast<std::uint64_t>(i));
  }
  EXPECT_TRUE(passive.armed());
  EXPECT_LT(passive.delivered_energy_j(0), 0.01F);

  // An active environment pushing along the motion delivers energy: latched.
  SafetySupervisor active = armed_supervisor();
  for (int i = 0; i < 2000 && active.armed(); ++i) {
    active.observe_power(0, Vec3(2.0F, 0, 0), Vec3(0.1F, 0, 0), kDt, static_cast<std::uint64_t>(i));
  }
  EXPECT_EQ(active.first_fault(), Fault::passivity);
  // 0.2 W for 0.1 J: latched at cycle 500 (+ rounding).
  EXPECT_NEAR(static_cast<double>(active.first_fault_cycle()), 500.0, 2.0);
}

TEST(SafetySupervisor, ShutdownIsFinal) {
  SafetySupervisor s = armed_supervisor();
  s.latch(Fault::shutdown, 7);
  s.request_reset();
  EXPECT_FALSE(s.evaluate_inputs({}, 8));
}

TEST(SafetySupervisor, CountsEveryRaise) {
  SafetySupervisor s = armed_supervisor();
  s.latch(Fault::encoder_jump, 1);
  s.latch(Fault::encoder_jump, 2);
  s.latch(Fault::passivity, 3);
  EXPECT_EQ(s.fault_counts()[2], 2U);  // encoder_jump is bit 2
  EXPECT_EQ(s.fault_counts()[7], 1U);  // passivity is bit 7
  EXPECT_EQ(s.first_fault(), Fault::encoder_jump);
  EXPECT_EQ(s.first_fault_cycle(), 1U);
}

}  // namespace
}  // namespace trainer::safety
