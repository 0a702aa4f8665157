// Trocar kinematics against independent references: finite-difference Jacobians and the
// virtual-work identity τ·q̇ = F·v, which holds only if Jᵀ is the transpose of the true
// velocity map.
#include "trainer/kinematics/trocar_kinematics.hpp"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace trainer::kinematics {
namespace {

TrocarGeometry tilted_geometry() {
  TrocarGeometry g;
  g.pivot_m = Vec3(0.05F, -0.02F, 0.1F);
  g.shaft_axis = Vec3(0.0F, 0.3F, -1.0F).normalized();
  g.up_axis = Vec3(0.0F, 1.0F, 0.3F).normalized();  // orthogonal to the shaft axis
  g.shaft_length_m = 0.36F;
  g.jaw_length_m = 0.015F;
  return g;
}

TEST(TrocarKinematics, ZeroPoseLiesAlongShaftAxis) {
  const TrocarKinematics kin(tilted_geometry());
  const JointVector q{0.0F, 0.0F, 0.08F, 0.0F, 0.0F};
  const InstrumentPose pose = kin.forward(q);
  EXPECT_TRUE(pose.direction.isApprox(kin.geometry().shaft_axis, 1e-6F));
  EXPECT_TRUE(pose.tip_m.isApprox(kin.geometry().pivot_m + 0.08F * kin.geometry().shaft_axis, 1e-6F));
  EXPECT_NEAR((pose.tip_m - pose.hinge_m).norm(), 0.015F, 1e-6F);
  EXPECT_NEAR((pose.hinge_m - pose.shaft_start_m).norm(), 0.36F - 0.015F, 1e-5F);
  // Closed jaws end at the tip.
  EXPECT_TRUE(pose.jaw_tips_m[0].isApprox(pose.tip_m, 1e-5F));
  EXPECT_TRUE(pose.jaw_tips_m[1].isApprox(pose.tip_m, 1e-5F));
}

TEST(TrocarKinematics, PitchTiltsTowardUpAndYawTowardLateral) {
  const TrocarKinematics kin(tilted_geometry());
  const Vec3 s = kin.geometry().shaft_axis;
  const Vec3 u = kin.geometry().up_axis;
  const Vec3 l = u.cross(s);
  const float angle = 0.3F;
  const InstrumentPose pitched = kin.forward({angle, 0.0F, 0.1F, 0.0F, 0.0F});
  EXPECT_NEAR(pitched.direction.dot(u), std::sin(angle), 1e-6F);
  EXPECT_NEAR(pitched.direction.dot(s), std::cos(angle), 1e-6F);
  const InstrumentPose yawed = kin.forward({0.0F, angle, 0.1F, 0.0F, 0.0F});
  EXPECT_NEAR(yawed.direction.dot(l), std::sin(angle), 1e-6F);
  EXPECT_NEAR(yawed.direction.dot(u), 0.0F, 1e-6F);
}

TEST(TrocarKinematics, JacobianMatchesCentralDifferences) {
  const TrocarKinematics kin(tilted_geometry());
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> angle(-0.6F, 0.6F);
  std::uniform_real_distribution<float> depth(0.02F, 0.2F);
  for (int trial = 0; trial < 50; ++trial) {
    const JointVector q{angle(rng), angle(rng), depth(rng), angle(rng), 0.2F};
    const InstrumentPose pose = kin.forward(q);
    for (std::size_t j : {kPitch, kYaw, kInsertion}) {
      JointVector rates{};
      rates[j] = 1.0F;
      const Vec3 analytic = TrocarKinematics::point_velocity(pose, pose.insertion_m, rates);
      // Central difference in double-ish precision: step 1e-3 keeps float error ~1e-4.
      const float h = 1e-3F;
      JointVector plus = q;
      JointVector minus = q;
      plus[j] += h;
      minus[j] -= h;
      const Vec3 numeric = (kin.forward(plus).tip_m - kin.forward(minus).tip_m) / (2.0F * h);
      EXPECT_LT((analytic - numeric).norm(), 2e-3F * std::max(1.0F, numeric.norm()))
          << "joint " << j << " trial " << trial;
    }
  }
}

TEST(TrocarKinematics, TransposedJacobianConservesPower) {
  // For any force F at the tip and any joint rates q̇: Σ τ_j q̇_j = F · v_tip.
  const TrocarKinematics kin(tilted_geometry());
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.0F, 1.0F);
  for (int trial = 0; trial < 100; ++trial) {
    const JointVector q{0.5F * u(rng), 0.5F * u(rng), 0.1F + 0.05F * u(rng), u(rng), 0.3F};
    const InstrumentPose pose = kin.forward(q);
    const Vec3 force(u(rng), u(rng), u(rng));
    const JointVector rates{u(rng), u(rng), u(rng), 0.0F, 0.0F};
    JointVector efforts{};
    TrocarKinematics::add_joint_efforts(pose, pose.insertion_m, force, Vec3::Zero(), efforts);
    const float joint_power =
        efforts[kPitch] * rates[kPitch] + efforts[kYaw] * rates[kYaw] +
        efforts[kInsertion] * rates[kInsertion];
    const float tip_power =
        force.dot(TrocarKinematics::point_velocity(pose, pose.insertion_m, rates));
    EXPECT_NEAR(joint_power, tip_power, 1e-5F);
  }
}

TEST(TrocarKinematics, ForceAlongShaftLoadsOnlyInsertion) {
  const TrocarKinematics kin(tilted_geometry());
  const InstrumentPose pose = kin.forward({0.2F, -0.1F, 0.1F, 0.0F, 0.0F});
  JointVector efforts{};
  TrocarKinematics::add_joint_efforts(pose, pose.insertion_m, -2.0F * pose.direction,
                                      Vec3::Zero(), efforts);
  EXPECT_NEAR(efforts[kInsertion], -2.0F, 1e-6F);
  EXPECT_NEAR(efforts[kPitch], 0.0F, 1e-6F);
  EXPECT_NEAR(efforts[kYaw], 0.0F, 1e-6F);
  // Torque about the shaft goes to roll only.
  JointVector roll{};
  TrocarKinematics::add_joint_efforts(pose, pose.insertion_m, Vec3::Zero(),
                                      0.01F * pose.direction, roll);
  EXPECT_NEAR(roll[kRoll], 0.01F, 1e-7F);
}

TEST(TrocarKinematics, JawsOpenSymmetricallyByGripAngle) {
  const TrocarKinematics kin(tilted_geometry());
  for (float roll : {0.0F, 0.7F, -2.0F}) {
    const float grip = 0.5F;
    const InstrumentPose pose = kin.forward({0.1F, 0.2F, 0.1F, roll, grip});
    const Vec3 a = pose.jaw_tips_m[0] - pose.hinge_m;
    const Vec3 b = pose.jaw_tips_m[1] - pose.hinge_m;
    EXPECT_NEAR(a.norm(), 0.015F, 1e-6F);
    EXPECT_NEAR(b.norm(), 0.015F, 1e-6F);
    EXPECT_NEAR(std::acos(a.normalized().dot(b.normalized())), grip, 1e-3F);
    EXPECT_NEAR(a.dot(pose.direction), b.dot(pose.direction), 1e-7F);
  }
  // Roll turns the opening plane about the shaft: the opening directions at two rolls differ
  // by the roll angle.
  const InstrumentPose r0 = kin.forward({0.1F, 0.2F, 0.1F, 0.0F, 0.5F});
  const InstrumentPose r1 = kin.forward({0.1F, 0.2F, 0.1F, 0.4F, 0.5F});
  const Vec3 open0 = (r0.jaw_tips_m[0] - r0.jaw_tips_m[1]).normalized();
  const Vec3 open1 = (r1.jaw_tips_m[0] - r1.jaw_tips_m[1]).normalized();
  EXPECT_NEAR(std::acos(open0.dot(open1)), 0.4F, 1e-3F);
}

}  // namespace
}  // namespace trainer::kinematics
