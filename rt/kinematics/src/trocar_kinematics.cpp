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
  // d̂ × it completes the frame, so roll turns the opening plane right-handed about +d̂ and
  // the roll effort of a torque T is +d̂·T (add_joint_efforts relies on this).
  const Vec3 up_transported = pose.d_direction_d_pitch;
  const Vec3 lateral_transported = pose.direction.cross(up_transported);
  pose.opening_direction = std::cos(joints[kRoll]) * up_transported +
                           std::sin(joints[kRoll]) * lateral_transported;
  const float half_grip = 0.5F * joints[kGrip];
  const Vec3 along = std::cos(half_grip) * pose.direction;
  const Vec3 across = std::sin(half_grip) * pose.opening_direction;
  pose.jaw_directions[0] = along + across;
  pose.jaw_directions[1] = along - across;
  pose.jaw_tips_m[0] = pose.hinge_m + geometry_.jaw_length_m * pose.jaw_directions[0];
  pose.jaw_tips_m[1] = pose.hinge_m + geometry_.jaw_length_m * pose.jaw_directions[1];
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

Vec3 TrocarKinematics::position(const InstrumentPose& pose,
                                const InstrumentPoint& point) noexcept {
  switch (point.segment) {
    case Segment::jaw0:
      return pose.hinge_m + point.along_m * pose.jaw_directions[0];
    case Segment::jaw1:
      return pose.hinge_m + point.along_m * pose.jaw_directions[1];
    case Segment::shaft:
      break;
  }
  return pose.shaft_start_m + point.along_m * pose.direction;
}

namespace {

// +1 for jaw 0 (opens toward +n), −1 for jaw 1, 0 for the shaft (no grip motion).
float grip_sign(Segment segment) noexcept {
  switch (segment) {
    case Segment::jaw0:
      return 1.0F;
    case Segment::jaw1:
      return -1.0F;
    case Segment::shaft:
      break;
  }
  return 0.0F;
}

}  // namespace

void TrocarKinematics::add_point_force_efforts(const InstrumentPose& pose,
                                               const InstrumentPoint& point, const Vec3& force_n,
                                               JointVector& efforts) const noexcept {
  // Pitch, yaw and roll rotate the whole instrument about axes through the pivot, so
  // ∂x/∂q = ω_q × (x − pivot) and (ω_q × r)·F = ω_q·(r × F).
  const Vec3 arm_m = position(pose, point) - geometry_.pivot_m;
  const Vec3 moment_nm = arm_m.cross(force_n);
  const Vec3 pitch_axis = pose.direction.cross(pose.d_direction_d_pitch);
  efforts[kPitch] += pitch_axis.dot(moment_nm);
  efforts[kYaw] += geometry_.up_axis.dot(moment_nm);
  efforts[kInsertion] += pose.direction.dot(force_n);
  const float sign = grip_sign(point.segment);
  if (sign == 0.0F) {
    return;  // Shaft points lie on the roll axis and do not move with grip.
  }
  efforts[kRoll] += pose.direction.dot(moment_nm);
  // Jaw k turns about the hinge axis b = d̂ × n at ±ġ/2: ∂x/∂g = a·(±½ b) × ŵ_k.
  const Vec3 hinge_axis = pose.direction.cross(pose.opening_direction);
  const std::size_t jaw = point.segment == Segment::jaw0 ? 0U : 1U;
  const Vec3 d_position_d_grip =
      (0.5F * sign * point.along_m) * hinge_axis.cross(pose.jaw_directions[jaw]);
  efforts[kGrip] += d_position_d_grip.dot(force_n);
}

void TrocarKinematics::add_wrench_efforts(const InstrumentPose& pose,
                                          const InstrumentPoint& point, const Vec3& force_n,
                                          const Vec3& torque_nm,
                                          JointVector& efforts) const noexcept {
  add_point_force_efforts(pose, point, force_n, efforts);
  const Vec3 pitch_axis = pose.direction.cross(pose.d_direction_d_pitch);
  efforts[kPitch] += pitch_axis.dot(torque_nm);
  efforts[kYaw] += geometry_.up_axis.dot(torque_nm);
  efforts[kRoll] += pose.direction.dot(torque_nm);  // the shaft body rolls too
  const float sign = grip_sign(point.segment);
  if (sign != 0.0F) {
    const Vec3 hinge_axis = pose.direction.cross(pose.opening_direction);
    efforts[kGrip] += 0.5F * sign * hinge_axis.dot(torque_nm);
  }
}

}  // namespace trainer::kinematics
