#include "trainer/app/force_command.hpp"

#include <algorithm>
#include <cmath>

namespace trainer::app {

namespace {

kinematics::Segment kinematic_segment(model::ToolSegment segment) noexcept {
  switch (segment) {
    case model::ToolSegment::jaw0:
      return kinematics::Segment::jaw0;
    case model::ToolSegment::jaw1:
      return kinematics::Segment::jaw1;
    case model::ToolSegment::shaft:
      break;
  }
  return kinematics::Segment::shaft;
}

}  // namespace

ForceCommand command_instrument(safety::SafetySupervisor& safety, std::size_t instrument,
                                const kinematics::TrocarKinematics& kinematics,
                                const kinematics::InstrumentPose& pose,
                                const InstrumentForces& forces, float dt_s,
                                std::uint64_t cycle) noexcept {
  Eigen::Vector3f total = forces.tip_force_n;
  for (const model::ToolForce& point : forces.point_forces) total += point.force_n;

  ForceCommand command;
  command.force_n = safety.limit_force(instrument, total, dt_s, cycle);
  safety.observe_power(instrument, command.force_n, forces.tip_velocity_m_per_s, dt_s, cycle);
  const float total_norm = total.norm();
  const float scale =
      total_norm > 1e-9F ? std::min(1.0F, command.force_n.norm() / total_norm) : 1.0F;

  // The tip as a point on the shaft: its distance from the shaft's start.
  const kinematics::InstrumentPoint tip_point{kinematics::Segment::shaft,
                                              (pose.tip_m - pose.shaft_start_m).dot(pose.direction)};
  kinematics.add_point_force_efforts(pose, tip_point, scale * forces.tip_force_n, command.efforts);
  for (const model::ToolForce& point : forces.point_forces) {
    kinematics.add_point_force_efforts(
        pose, kinematics::InstrumentPoint{kinematic_segment(point.segment), point.along_m},
        scale * point.force_n, command.efforts);
  }
  for (const float effort : command.efforts) {
    if (!std::isfinite(effort)) safety.latch(safety::Fault::non_finite, cycle);
  }
  if (!safety.armed()) {
    command.force_n.setZero();
    command.efforts.fill(0.0F);
  }
  return command;
}

}  // namespace trainer::app
