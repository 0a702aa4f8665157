// Trocar kinematics against independent references: finite-difference Jacobians of forward()
// (positions of points on all three segments, and rotations of the segment bodies) and the
// virtual-work identity τ·q̇ = F·v + T·ω, which holds only if Jᵀ is the transpose of the true
// velocity map.
#include "trainer/kinematics/trocar_kinematics.hpp"

#include <algorithm>
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

// ---- Forces and torques anywhere on the three segments (ray-based rendering) ----

// Central differences of forward() in float. Step 4e-3 (rad or m): rounding of positions of
// magnitude ≤ 0.5 m is a few ulps ≈ 1e-7 m, i.e. ≈ 1.5e-5 after dividing by 2h; truncation is
// h²/6·|x‴| < 1e-6. Efforts are dotted with |F|, |T| ≤ √3, so 1e-4 bounds the error with
// margin while any wrong term (sign, missing axis, factor ½) is ≥ 1e-3 for these poses.
constexpr float kStep = 4e-3F;
constexpr float kEffortTolerance = 1e-4F;

JointVector stepped(const JointVector& q, const JointVector& direction, float step) {
  JointVector out = q;
  for (std::size_t j = 0; j < kJointCount; ++j) {
    out[j] += step * direction[j];
  }
  return out;
}

JointVector unit_rate(std::size_t joint) {
  JointVector rates{};
  rates[joint] = 1.0F;
  return rates;
}

// Point velocity for joint rates `rates`, by central differences of forward().
Vec3 numeric_velocity(const TrocarKinematics& kin, const JointVector& q,
                      const InstrumentPoint& point, const JointVector& rates) {
  const Vec3 plus = TrocarKinematics::position(kin.forward(stepped(q, rates, kStep)), point);
  const Vec3 minus = TrocarKinematics::position(kin.forward(stepped(q, rates, -kStep)), point);
  return (plus - minus) / (2.0F * kStep);
}

// Orthonormal frame fixed to the body of a segment, built from forward()'s outputs only:
// shaft (d̂, n, d̂ × n); jaw k (ŵ_k, b, ŵ_k × b) with the hinge axis b = d̂ × n.
Eigen::Matrix3f body_frame(const InstrumentPose& pose, Segment segment) {
  const Vec3 hinge_axis = pose.direction.cross(pose.opening_direction);
  Eigen::Matrix3f frame;
  if (segment == Segment::shaft) {
    frame.col(0) = pose.direction;
    frame.col(1) = pose.opening_direction;
  } else {
    frame.col(0) = pose.jaw_directions[segment == Segment::jaw0 ? 0U : 1U];
    frame.col(1) = hinge_axis;
  }
  frame.col(2) = frame.col(0).cross(frame.col(1));
  return frame;
}

// Angular velocity of the segment's body for joint rates `rates`: Ė Eᵀ = [ω]×.
Vec3 numeric_angular_velocity(const TrocarKinematics& kin, const JointVector& q,
                              Segment segment, const JointVector& rates) {
  const Eigen::Matrix3f plus = body_frame(kin.forward(stepped(q, rates, kStep)), segment);
  const Eigen::Matrix3f minus = body_frame(kin.forward(stepped(q, rates, -kStep)), segment);
  const Eigen::Matrix3f spin =
      (plus - minus) / (2.0F * kStep) * body_frame(kin.forward(q), segment).transpose();
  return 0.5F * Vec3(spin(2, 1) - spin(1, 2), spin(0, 2) - spin(2, 0), spin(1, 0) - spin(0, 1));
}

struct RandomCase {
  JointVector q{};
  InstrumentPoint point{};
  Vec3 force_n = Vec3::Zero();
  Vec3 torque_nm = Vec3::Zero();
};

RandomCase random_case(std::mt19937& rng, const TrocarGeometry& geometry) {
  std::uniform_real_distribution<float> unit(-1.0F, 1.0F);
  std::uniform_real_distribution<float> fraction(0.0F, 1.0F);
  RandomCase c;
  c.q = {0.6F * unit(rng), 0.6F * unit(rng), 0.05F + 0.15F * fraction(rng), 3.0F * unit(rng),
         1.0F * fraction(rng)};
  const auto segment = static_cast<int>(3.0F * fraction(rng));
  c.point.segment = segment == 0 ? Segment::shaft : (segment == 1 ? Segment::jaw0 : Segment::jaw1);
  const float length = c.point.segment == Segment::shaft
                           ? geometry.shaft_length_m - geometry.jaw_length_m
                           : geometry.jaw_length_m;
  c.point.along_m = length * fraction(rng);
  c.force_n = Vec3(unit(rng), unit(rng), unit(rng));
  c.torque_nm = Vec3(unit(rng), unit(rng), unit(rng));
  return c;
}

TEST(TrocarKinematics, PointPositionsSpanTheThreeSegments) {
  const TrocarKinematics kin(tilted_geometry());
  const InstrumentPose pose = kin.forward({0.2F, -0.3F, 0.12F, 1.1F, 0.7F});
  const float shaft_span = 0.36F - 0.015F;
  EXPECT_LT((TrocarKinematics::position(pose, {Segment::shaft, 0.0F}) - pose.shaft_start_m).norm(),
            1e-7F);
  EXPECT_LT((TrocarKinematics::position(pose, {Segment::shaft, shaft_span}) - pose.hinge_m).norm(),
            1e-6F);
  EXPECT_LT((TrocarKinematics::position(pose, {Segment::jaw0, 0.015F}) - pose.jaw_tips_m[0]).norm(),
            1e-7F);
  EXPECT_LT((TrocarKinematics::position(pose, {Segment::jaw1, 0.015F}) - pose.jaw_tips_m[1]).norm(),
            1e-7F);
  EXPECT_LT((TrocarKinematics::position(pose, {Segment::jaw1, 0.0F}) - pose.hinge_m).norm(), 1e-7F);
}

TEST(TrocarKinematics, PointForceEffortsMatchCentralDifferencesOnAllJoints) {
  const TrocarGeometry geometry = tilted_geometry();
  const TrocarKinematics kin(geometry);
  std::mt19937 rng(23);
  int jaw_cases = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const RandomCase c = random_case(rng, geometry);
    jaw_cases += c.point.segment == Segment::shaft ? 0 : 1;
    JointVector efforts{};
    kin.add_point_force_efforts(kin.forward(c.q), c.point, c.force_n, efforts);
    for (std::size_t j = 0; j < kJointCount; ++j) {
      const float numeric = numeric_velocity(kin, c.q, c.point, unit_rate(j)).dot(c.force_n);
      EXPECT_NEAR(efforts[j], numeric, kEffortTolerance)
          << "joint " << j << " segment " << static_cast<int>(c.point.segment) << " trial "
          << trial;
    }
  }
  EXPECT_GT(jaw_cases, 150);  // both jaws well represented
}

TEST(TrocarKinematics, WrenchTorqueMapsThroughTheBodyRotation) {
  const TrocarGeometry geometry = tilted_geometry();
  const TrocarKinematics kin(geometry);
  std::mt19937 rng(29);
  for (int trial = 0; trial < 300; ++trial) {
    const RandomCase c = random_case(rng, geometry);
    JointVector efforts{};
    kin.add_wrench_efforts(kin.forward(c.q), c.point, Vec3::Zero(), c.torque_nm, efforts);
    for (std::size_t j = 0; j < kJointCount; ++j) {
      const float numeric =
          numeric_angular_velocity(kin, c.q, c.point.segment, unit_rate(j)).dot(c.torque_nm);
      EXPECT_NEAR(efforts[j], numeric, kEffortTolerance)
          << "joint " << j << " segment " << static_cast<int>(c.point.segment) << " trial "
          << trial;
    }
  }
}

TEST(TrocarKinematics, WrenchEffortsConservePowerForRandomRates) {
  // Σ τ_j q̇_j = F · ẋ + T · ω with ẋ and ω from finite differences along q̇ (all five joints
  // moving at once), so cross-couplings between joints are covered too.
  const TrocarGeometry geometry = tilted_geometry();
  const TrocarKinematics kin(geometry);
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> unit(-1.0F, 1.0F);
  for (int trial = 0; trial < 200; ++trial) {
    const RandomCase c = random_case(rng, geometry);
    const JointVector rates{unit(rng), unit(rng), 0.1F * unit(rng), unit(rng), unit(rng)};
    JointVector efforts{};
    kin.add_wrench_efforts(kin.forward(c.q), c.point, c.force_n, c.torque_nm, efforts);
    float joint_power = 0.0F;
    for (std::size_t j = 0; j < kJointCount; ++j) {
      joint_power += efforts[j] * rates[j];
    }
    const float body_power =
        c.force_n.dot(numeric_velocity(kin, c.q, c.point, rates)) +
        c.torque_nm.dot(numeric_angular_velocity(kin, c.q, c.point.segment, rates));
    EXPECT_NEAR(joint_power, body_power, 3.0F * kEffortTolerance) << "trial " << trial;
  }
}

TEST(TrocarKinematics, EqualAndOppositeClosingForcesLoadOnlyTheGrip) {
  const TrocarKinematics kin(tilted_geometry());
  const float grip = 0.6F;
  const float along = 0.01F;
  const float squeeze_n = 3.0F;
  for (float roll : {0.0F, 0.9F, -2.5F}) {
    const InstrumentPose pose = kin.forward({0.25F, -0.15F, 0.1F, roll, grip});
    // Each jaw pushed toward the other, perpendicular to the shaft (n is jaw 0's side).
    JointVector on_jaw0{};
    JointVector on_jaw1{};
    kin.add_point_force_efforts(pose, {Segment::jaw0, along}, -squeeze_n * pose.opening_direction,
                                on_jaw0);
    kin.add_point_force_efforts(pose, {Segment::jaw1, along}, squeeze_n * pose.opening_direction,
                                on_jaw1);
    // Closing → negative grip effort, the same from both jaws: −a·F·cos(g/2)/2 each.
    const float expected_grip = -0.5F * along * squeeze_n * std::cos(0.5F * grip);
    EXPECT_NEAR(on_jaw0[kGrip], expected_grip, 1e-6F);
    EXPECT_NEAR(on_jaw1[kGrip], expected_grip, 1e-6F);
    for (std::size_t j : {kPitch, kYaw, kInsertion, kRoll}) {
      EXPECT_NEAR(on_jaw0[j] + on_jaw1[j], 0.0F, 1e-6F) << "joint " << j << " roll " << roll;
    }
    // An opening force reverses the sign.
    JointVector opening{};
    kin.add_point_force_efforts(pose, {Segment::jaw0, along}, squeeze_n * pose.opening_direction,
                                opening);
    EXPECT_NEAR(opening[kGrip], -expected_grip, 1e-6F);
  }
}

TEST(TrocarKinematics, ShaftPointAgreesWithTheAxisDistanceMapping) {
  // add_joint_efforts takes the distance beyond the pivot; the shaft start is at d − L from it.
  const TrocarKinematics kin(tilted_geometry());
  std::mt19937 rng(37);
  std::uniform_real_distribution<float> unit(-1.0F, 1.0F);
  for (int trial = 0; trial < 50; ++trial) {
    const JointVector q{0.5F * unit(rng), 0.5F * unit(rng), 0.12F + 0.05F * unit(rng),
                        3.0F * unit(rng), 0.5F + 0.4F * unit(rng)};
    const InstrumentPose pose = kin.forward(q);
    const InstrumentPoint point{Segment::shaft, 0.17F + 0.17F * unit(rng)};
    const float distance_m = q[kInsertion] - 0.36F + point.along_m;
    const Vec3 force(unit(rng), unit(rng), unit(rng));
    const Vec3 axial_torque = 0.02F * unit(rng) * pose.direction;
    JointVector by_distance{};
    JointVector by_point{};
    TrocarKinematics::add_joint_efforts(pose, distance_m, force, axial_torque, by_distance);
    kin.add_wrench_efforts(pose, point, force, axial_torque, by_point);
    for (std::size_t j : {kPitch, kInsertion, kRoll, kGrip}) {
      EXPECT_NEAR(by_point[j], by_distance[j], 1e-6F) << "joint " << j << " trial " << trial;
    }
    // Yaw turns the instrument about u, which has a component sinθ along d̂: an axial torque
    // does work under yaw too. add_joint_efforts leaves that term out; the exact map has it.
    EXPECT_NEAR(by_point[kYaw] - by_distance[kYaw], kin.geometry().up_axis.dot(axial_torque),
                1e-6F)
        << "trial " << trial;
    EXPECT_EQ(by_point[kGrip], 0.0F);
  }
}

}  // namespace
}  // namespace trainer::kinematics
