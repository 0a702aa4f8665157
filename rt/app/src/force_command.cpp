#include "trainer/app/force_command.hpp"

#include <algorithm>
#include <cmath>

namespace trainer::app {

namespace {

kinematics::Segment kinematic_segment(model::ToolSegment segment) noexcept {
  switch (segment) {
    case model::ToolSegment::jaw0: return kinematics::Segment::jaw0;
    case model::ToolSegment::jaw1: return kinematics::Segment::jaw1;
    case model::ToolSegment::shaft: break;
  }
  return kinematics::Segment::shaft;
}

// The joints whose efforts make the tool's wrench (the grip's is internal to the jaws).
constexpr std::size_t kWrenchJoints[] = {kinematics::kPitch, kinematics::kYaw,
                                         kinematics::kInsertion, kinematics::kRoll};

}  // namespace

kinematics::InstrumentPoint tool_point(const model::ToolForce& force) noexcept {
  return {kinematic_segment(force.segment), force.along_m};
}

float effort_limit(const hal::JointScale& scale) noexcept {
  const double limit = scale.max_effort();
  float rounded = static_cast<float>(limit);
  if (static_cast<double>(rounded) > limit) rounded = std::nextafter(rounded, 0.0F);
  return rounded;
}

ForceCommand command_instrument(safety::SafetySupervisor& safety, std::size_t instrument,
                                const kinematics::TrocarKinematics& kinematics,
                                const kinematics::InstrumentPose& pose,
                                const InstrumentForces& forces,
                                const kinematics::JointVector& effort_limits, float dt_s,
                                std::uint64_t cycle) noexcept {
  Eigen::Vector3f total = forces.tip_force_n;
  for (const model::ToolForce& point : forces.point_forces) total += point.force_n;

  ForceCommand command;
  command.force_n = safety.limit_force(instrument, total, dt_s, cycle);
  // In double: a float norm overflows beyond ~1.8e19 N and would put the whole command on
  // the tip instead of sharing it among the points in proportion.
  const double total_norm = total.cast<double>().norm();
  const float scale =
      total_norm > 1e-9
          ? static_cast<float>(std::min(1.0, command.force_n.cast<double>().norm() / total_norm))
          : 1.0F;

  // The tip as a point on the shaft: its distance from the shaft's start. It carries its own
  // force and whatever the chain changed beyond the common scale (zero unless the slew limit
  // turned the force), so the efforts' total is command.force_n.
  const kinematics::InstrumentPoint tip_point{
      kinematics::Segment::shaft, (pose.tip_m - pose.shaft_start_m).dot(pose.direction)};
  const Eigen::Vector3f tip_part = scale * forces.tip_force_n + (command.force_n - scale * total);
  kinematics.add_point_force_efforts(pose, tip_point, tip_part, command.efforts);
  for (const model::ToolForce& point : forces.point_forces) {
    kinematics.add_point_force_efforts(
        pose, kinematics::InstrumentPoint{kinematic_segment(point.segment), point.along_m},
        scale * point.force_n, command.efforts);
  }
  bool finite = true;
  for (const float effort : command.efforts) finite = finite && std::isfinite(effort);
  if (!finite) safety.latch(safety::Fault::non_finite, cycle);

  if (safety.armed()) {
    float worst_ratio = 1.0F;
    for (const std::size_t joint : kWrenchJoints) {
      worst_ratio = std::max(worst_ratio, std::fabs(command.efforts[joint]) / effort_limits[joint]);
    }
    if (worst_ratio > 1.0F) {
      const float factor = 1.0F / worst_ratio;
      for (const std::size_t joint : kWrenchJoints) command.efforts[joint] *= factor;
      command.force_n *= factor;
      safety.reduce_last_force(instrument, command.force_n);
      command.effort_limited = true;
    }
    // The scaled worst joint may sit one rounding above its limit, and the grip is on its own.
    for (std::size_t joint = 0; joint < kinematics::kJointCount; ++joint) {
      const float limit = effort_limits[joint];
      const float effort = command.efforts[joint];
      if (effort > limit || effort < -limit) {
        command.efforts[joint] = std::clamp(effort, -limit, limit);
        command.effort_limited = true;
      }
    }
  }
  safety.observe_power(instrument, command.force_n, forces.tip_velocity_m_per_s, dt_s, cycle);
  if (!safety.armed()) {
    command.force_n.setZero();
    command.efforts.fill(0.0F);
    command.effort_limited = false;
  }
  return command;
}

}  // namespace trainer::app
