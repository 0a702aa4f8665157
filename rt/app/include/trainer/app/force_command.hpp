// The forces phase of the haptic cycle for one instrument: from the forces the scene puts on it
// (the tip force of rigid objects and soft-tissue models, the ray-based point forces on its
// shaft and jaws) to the joint efforts its actuators are commanded. In order:
//   1. the exact Jᵀ of every point force (TrocarKinematics::add_point_force_efforts);
//   2. the safety chain on their total (SafetySupervisor::limit_force: finite check, magnitude
//      clamp, slew limit) and the passivity observer;
//   3. every point force scaled by the one factor the chain applied to the total, so the
//      efforts keep their proportions (equal and opposite jaw squeezes do not add to the total:
//      the catheter bounds them per jaw);
//   4. a non-finite effort latches non_finite; nothing but zero leaves unless the supervisor is
//      armed.
// HapticApp::render_instrument calls it every cycle; the property test
// (tests/rt/app/force_command_property_test.cpp) calls it with random and hostile inputs.
// RT path: noexcept, no heap.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "trainer/kinematics/trocar_kinematics.hpp"
#include "trainer/model/forceps_catheter.hpp"
#include "trainer/safety/safety_supervisor.hpp"

namespace trainer::app {

// What acts on one instrument this cycle (trainer frame, N; velocity in m/s).
struct InstrumentForces {
  Eigen::Vector3f tip_force_n = Eigen::Vector3f::Zero();  // at the closed-jaw tip
  std::span<const model::ToolForce> point_forces;  // on the shaft and jaws, at their points
  Eigen::Vector3f tip_velocity_m_per_s = Eigen::Vector3f::Zero();  // for the passivity observer
};

struct ForceCommand {
  // The total force after the safety chain: what the efforts render. Zero unless armed.
  Eigen::Vector3f force_n = Eigen::Vector3f::Zero();
  // Per joint (pitch, yaw, roll, grip N·m; insertion N). Zero unless armed.
  kinematics::JointVector efforts{};
};

// `pose` must come from kinematics.forward() this cycle; `instrument` indexes the supervisor's
// per-instrument state (slew, passivity).
ForceCommand command_instrument(safety::SafetySupervisor& safety, std::size_t instrument,
                                const kinematics::TrocarKinematics& kinematics,
                                const kinematics::InstrumentPose& pose,
                                const InstrumentForces& forces, float dt_s,
                                std::uint64_t cycle) noexcept;

}  // namespace trainer::app
