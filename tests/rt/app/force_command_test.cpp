// The forces phase of one instrument (force_command.hpp) on hand-made cases: the efforts render
// exactly the force the safety chain allowed (also when the slew limit turns it), the actuators'
// effort limits scale the wrench joints together and clamp the grip on its own, and whatever
// the inputs, nothing beyond a limit or non-finite leaves. The random and hostile cases are in
// force_command_property_test.cpp.
#include "trainer/app/force_command.hpp"

#include <array>
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

namespace trainer::app {
namespace {

using Vec3 = Eigen::Vector3f;
using kinematics::JointVector;

constexpr float kDt = 1e-3F;

// The sim device's left instrument (config/devices/sim.toml): pivot at the origin, shaft down
// -z, 0.36 m shaft, 15 mm jaws; limits 1.35 N·m pitch/yaw, 62.5 N insertion, 0.48 N·m roll,
// 0.8 N·m grip.
kinematics::TrocarKinematics left_kinematics() {
  kinematics::TrocarGeometry geometry;
  geometry.pivot_m = Vec3::Zero();
  geometry.shaft_axis = Vec3(0, 0, -1);
  geometry.up_axis = Vec3(0, 1, 0);
  geometry.shaft_length_m = 0.36F;
  geometry.jaw_length_m = 0.015F;
  return kinematics::TrocarKinematics(geometry);
}
constexpr JointVector kLimits{1.35F, 1.35F, 62.5F, 0.48F, 0.8F};

safety::SafetySupervisor armed(float max_force_n = 8.0F, float rate_n_per_s = 4000.0F) {
  safety::SafetyLimits limits;
  limits.max_force_n = max_force_n;
  limits.max_force_rate_n_per_s = rate_n_per_s;
  limits.passivity_energy_bound_j = 0.0F;
  safety::SafetySupervisor supervisor(limits, 1);
  supervisor.request_reset();
  EXPECT_TRUE(supervisor.evaluate_inputs({}, 0));
  return supervisor;
}

// The joint efforts of `force` at the tip, computed directly (Jᵀ F).
JointVector tip_efforts(const kinematics::TrocarKinematics& kinematics,
                        const kinematics::InstrumentPose& pose, const Vec3& force) {
  JointVector efforts{};
  kinematics.add_point_force_efforts(
      pose, {kinematics::Segment::shaft, (pose.tip_m - pose.shaft_start_m).dot(pose.direction)},
      force, efforts);
  return efforts;
}

TEST(ForceCommand, EffortLimitIsTheDrivesLimitRoundedDown) {
  hal::JointScale scale;
  scale.kind = hal::JointKind::revolute;
  scale.gear_ratio = 15.0;
  scale.torque_constant_nm_per_a = 0.03;
  scale.current_limit_a = 3.0;
  const float limit = effort_limit(scale);
  EXPECT_LE(static_cast<double>(limit), scale.max_effort());
  EXPECT_NEAR(static_cast<double>(limit), 1.35, 1e-6);
  EXPECT_GT(static_cast<double>(std::nextafter(limit, 2.0F)), scale.max_effort());
}

TEST(ForceCommand, WithinLimitsTheEffortsAreJacobianTransposeOfTheForce) {
  const auto kinematics = left_kinematics();
  const auto pose = kinematics.forward({0.2F, -0.1F, 0.1F, 0.3F, 0.2F});
  auto supervisor = armed();
  const Vec3 force(1.0F, -2.0F, 0.5F);  // below the 4 N slew step: passes whole
  const ForceCommand command = command_instrument(supervisor, 0, kinematics, pose,
                                                  {force, {}, Vec3::Zero()}, kLimits, kDt, 1);
  EXPECT_FALSE(command.effort_limited);
  EXPECT_TRUE(command.force_n.isApprox(force, 1e-6F));
  const JointVector expected = tip_efforts(kinematics, pose, force);
  for (std::size_t j = 0; j < kinematics::kJointCount; ++j) {
    EXPECT_NEAR(command.efforts[j], expected[j], 1e-6F) << "joint " << j;
  }
}

TEST(ForceCommand, ALongLeverScalesTheWrenchJointsTogetherKeepingTheForcesDirection) {
  // 7.5 N across the shaft at 0.25 m of insertion needs 1.9 N·m of pitch: beyond its 1.35 N·m
  // (the force itself is within the 8 N limit).
  const auto kinematics = left_kinematics();
  const auto pose = kinematics.forward({0.0F, 0.0F, 0.25F, 0.0F, 0.0F});
  auto supervisor = armed(8.0F, 1e6F);
  const Vec3 requested(0.0F, 7.5F, -2.0F);
  const ForceCommand command = command_instrument(supervisor, 0, kinematics, pose,
                                                  {requested, {}, Vec3::Zero()}, kLimits, kDt, 1);
  EXPECT_TRUE(command.effort_limited);
  const JointVector unlimited = tip_efforts(kinematics, pose, requested);
  const float worst = std::fabs(unlimited[kinematics::kPitch]) / kLimits[kinematics::kPitch];
  ASSERT_GT(worst, 1.0F);
  // One factor for all: pitch at its limit, the rest in proportion, the force along `requested`.
  EXPECT_NEAR(std::fabs(command.efforts[kinematics::kPitch]), kLimits[kinematics::kPitch], 1e-5F);
  for (std::size_t j = 0; j < kinematics::kJointCount; ++j) {
    EXPECT_NEAR(command.efforts[j], unlimited[j] / worst, 1e-5F) << "joint " << j;
    EXPECT_LE(std::fabs(command.efforts[j]), kLimits[j]) << "joint " << j;
  }
  EXPECT_TRUE(command.force_n.isApprox(requested / worst, 1e-5F));
  // The chain's slew memory is the rendered force, not the one it allowed before the limits.
  auto slow = armed(8.0F, 1000.0F);  // 1 N per cycle
  ForceCommand first{};
  for (int i = 0; i < 20; ++i) {
    first = command_instrument(slow, 0, kinematics, pose, {requested, {}, Vec3::Zero()}, kLimits,
                               kDt, static_cast<std::uint64_t>(i));
  }
  const float rendered_n = first.force_n.norm();
  EXPECT_NEAR(rendered_n, requested.norm() / worst, 1e-4F);
  // The posture frees the actuators (insertion 0.05 m): the force rises 1 N per cycle from
  // what was rendered, not at once to what the chain had allowed.
  const auto near_pose = kinematics.forward({0.0F, 0.0F, 0.05F, 0.0F, 0.0F});
  const ForceCommand next = command_instrument(slow, 0, kinematics, near_pose,
                                               {requested, {}, Vec3::Zero()}, kLimits, kDt, 21);
  EXPECT_FALSE(next.effort_limited);
  EXPECT_NEAR(next.force_n.norm(), rendered_n + 1.0F, 1e-4F);
}

TEST(ForceCommand, ATurnUnderTheSlewLimitIsRenderedAsTheChainAllowedIt) {
  // +4 N along x held, then −4 N requested: the 1 N/cycle limit allows +3 N. The efforts must
  // render +3 N (what the telemetry reports), not 3 N along the request (−3 N).
  const auto kinematics = left_kinematics();
  const auto pose = kinematics.forward({0.1F, 0.2F, 0.1F, 0.0F, 0.0F});
  auto supervisor = armed(8.0F, 1000.0F);
  for (int i = 0; i < 10; ++i) {
    (void)command_instrument(supervisor, 0, kinematics, pose, {Vec3(4, 0, 0), {}, Vec3::Zero()},
                             kLimits, kDt, static_cast<std::uint64_t>(i));
  }
  // The turn arrives as a force on a jaw (a catheter), not at the tip.
  const std::array<model::ToolForce, 1> jaw{{{model::ToolSegment::jaw0, 0.01F, Vec3(-4, 0, 0)}}};
  const ForceCommand command = command_instrument(
      supervisor, 0, kinematics, pose, {Vec3::Zero(), jaw, Vec3::Zero()}, kLimits, kDt, 10);
  EXPECT_TRUE(command.force_n.isApprox(Vec3(3, 0, 0), 1e-5F));
  // τ_insertion = d̂·F for any point: it renders the reported +3 N.
  EXPECT_NEAR(command.efforts[kinematics::kInsertion], pose.direction.dot(Vec3(3, 0, 0)), 1e-5F);
  EXPECT_GT(command.efforts[kinematics::kInsertion] * pose.direction.x(), 0.0F);
}

TEST(ForceCommand, TheGripIsClampedOnItsOwn) {
  // A squeeze across the jaws adds nothing to the total but loads the grip beyond its limit.
  const auto kinematics = left_kinematics();
  const auto pose = kinematics.forward({0.0F, 0.0F, 0.1F, 0.0F, 0.3F});
  auto supervisor = armed();
  const Vec3 squeeze = 200.0F * pose.opening_direction;
  const std::array<model::ToolForce, 2> jaws{
      {{model::ToolSegment::jaw0, 0.015F, -squeeze}, {model::ToolSegment::jaw1, 0.015F, squeeze}}};
  const Vec3 tip(0.0F, 0.0F, 1.0F);
  const ForceCommand command = command_instrument(supervisor, 0, kinematics, pose,
                                                  {tip, jaws, Vec3::Zero()}, kLimits, kDt, 1);
  EXPECT_TRUE(command.effort_limited);
  EXPECT_NEAR(std::fabs(command.efforts[kinematics::kGrip]), kLimits[kinematics::kGrip], 1e-6F);
  // The tool's force is untouched by the grip's limit.
  EXPECT_TRUE(command.force_n.isApprox(tip, 1e-5F));
  EXPECT_NEAR(command.efforts[kinematics::kInsertion], pose.direction.dot(tip), 1e-4F);
}

TEST(ForceCommand, HugeCancellingForcesStayWithinTheLimits) {
  // 1e30 N at the tip, −1e30 N on the shaft: their total is zero, their moments are not.
  const auto kinematics = left_kinematics();
  const auto pose = kinematics.forward({0.3F, 0.0F, 0.2F, 0.0F, 0.0F});
  auto supervisor = armed();
  const Vec3 huge(1e30F, 0.0F, 0.0F);
  const std::array<model::ToolForce, 1> shaft{{{model::ToolSegment::shaft, 0.05F, -huge}}};
  const ForceCommand command = command_instrument(supervisor, 0, kinematics, pose,
                                                  {huge, shaft, Vec3::Zero()}, kLimits, kDt, 1);
  EXPECT_TRUE(supervisor.armed());
  for (std::size_t j = 0; j < kinematics::kJointCount; ++j) {
    EXPECT_TRUE(std::isfinite(command.efforts[j]));
    EXPECT_LE(std::fabs(command.efforts[j]), kLimits[j]) << "joint " << j;
  }
  EXPECT_TRUE(command.effort_limited);
}

TEST(ForceCommand, NonFiniteLatchesAndCommandsNothing) {
  const auto kinematics = left_kinematics();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  // A point off the instrument by NaN, with no force: its efforts are NaN all the same.
  auto supervisor = armed();
  const auto pose = kinematics.forward({0.1F, 0.1F, 0.1F, 0.0F, 0.0F});
  const std::array<model::ToolForce, 1> point{{{model::ToolSegment::jaw1, nan, Vec3::Zero()}}};
  ForceCommand command = command_instrument(supervisor, 0, kinematics, pose,
                                            {Vec3(0, 0, 1), point, Vec3::Zero()}, kLimits, kDt, 1);
  EXPECT_EQ(supervisor.first_fault(), safety::Fault::non_finite);
  EXPECT_TRUE(command.force_n.isZero(0.0F));
  for (const float effort : command.efforts) EXPECT_EQ(effort, 0.0F);
  // A NaN pose (a NaN joint reading) with no force at all.
  auto other = armed();
  const auto nan_pose = kinematics.forward({nan, 0.0F, 0.1F, 0.0F, 0.0F});
  command = command_instrument(other, 0, kinematics, nan_pose, {Vec3::Zero(), {}, Vec3::Zero()},
                               kLimits, kDt, 1);
  EXPECT_EQ(other.first_fault(), safety::Fault::non_finite);
  for (const float effort : command.efforts) EXPECT_EQ(effort, 0.0F);
}

}  // namespace
}  // namespace trainer::app
