#include "trainer/kinematics/trocar_kinematics.hpp"

#include <cmath>

namespace trainer::kinematics {

TrocarKinematics::TrocarKinematics(const TrocarGeometry& geometry) noexcept
    : geometry_(geometry) {
  geometry_.shaft_axis.normalize();
  // Remove any component of up along the shaft so the frame is orthonormal.
  geometry_.up_axis -= geometry_.up_axis.dot(geometry_.shaft_axis) * geometry_.shaft_axis;
  geometry_.up_axis.normalize();
  lateral_axis_ = geometry_.up_axis.cross(geometry_.shaft_axis);
}

InstrumentPose TrocarKinematics::forward(const JointVector& joints) const noexcept {
  const Vec3& s = geometry_.shaft_axis;
  const Vec3& u = geometry_.up_axis;
  const Vec3& l = lateral_axis_;
  const float cos_pitch = std::cos(joints[kPitch]);
  const float sin_pitch = std::sin(joints[kPitch]);
  const float cos_yaw = std::cos(joints[kYaw]);
  const float sin_yaw = std::sin(joints[kYaw]);

  const Vec3 horizontal = cos_yaw * s + sin_yaw * l;  // unit, ⟂ u
  InstrumentPose pose;
  pose.direction = cos_pitch * horizontal + sin_pitch * u;
  pose.d_direction_d_pitch = -sin_pitch * horizontal + cos_pitch * u;
  pose.d_direction_d_yaw = cos_pitch * (-sin_yaw * s + cos_yaw * l);
  pose.insertion_m = joints[kInsertion];
  pose.tip_m = geometry_.pivot_m + joints[kInsertion] * pose.direction;
  pose.hinge_m = pose.tip_m - geometry_.jaw_length_m * pose.direction;
  pose.shaft_start_m =
      pose.hinge_m - (geometry_.shaft_length_m - geometry_.jaw_length_m) * pose.direction;

  // Opening direction: the pitch derivative is a unit vector ⟂ d̂ (the transported "up");
  // its partner completes the frame; roll turns the opening plane between them.
  const Vec3 up_transported = pose.d_direction_d_pitch;
  const Vec3 lateral_transported = up_transported.cross(pose.direction);
  const Vec3 opening = std::cos(joints[kRoll]) * up_transported +
                       std::sin(joints[kRoll]) * lateral_transported;
  const float half_grip = 0.5F * joints[kGrip];
  const Vec3 along = geometry_.jaw_length_m * std::cos(half_grip) * pose.direction;
  const Vec3 across = geometry_.jaw_length_m * std::sin(half_grip) * opening;
  pose.jaw_tips_m[0] = pose.hinge_m + along + across;
  pose.jaw_tips_m[1] = pose.hinge_m + along - across;
  return pose;
}

Vec3 TrocarKinematics::point_velocity(const InstrumentPose& pose, float distance_m,
                                      const JointVector& joint_rates) noexcept {
  return distance_m * (pose.d_direction_d_pitch * joint_rates[kPitch] +
                       pose.d_direction_d_yaw * joint_rates[kYaw]) +
         pose.direction * joint_rates[kInsertion];
}

void TrocarKinematics::add_joint_efforts(const InstrumentPose& pose, float distance_m,
                                         const Vec3& force_n, const Vec3& torque_nm,
                                         JointVector& efforts) noexcept {
  efforts[kPitch] += distance_m * pose.d_direction_d_pitch.dot(force_n);
  efforts[kYaw] += distance_m * pose.d_direction_d_yaw.dot(force_n);
  efforts[kInsertion] += pose.direction.dot(force_n);
  efforts[kRoll] += pose.direction.dot(torque_nm);
}

}  // namespace trainer::kinematics
