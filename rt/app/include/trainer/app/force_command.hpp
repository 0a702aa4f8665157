// The forces phase of the haptic cycle for one instrument: from the forces the scene puts on it
// (the tip force of rigid objects and soft-tissue models, the ray-based point forces on its
// shaft and jaws) to the joint efforts its actuators are commanded. In order:
//   1. the safety chain on their total (SafetySupervisor::limit_force: finite check, magnitude
//      clamp, slew limit);
//   2. the exact Jᵀ of every point force, each scaled by the one factor the chain applied to
//      the total, so the efforts keep their proportions (equal and opposite jaw squeezes do not
//      add to the total: the catheter bounds them per jaw); what the chain changed beyond a
//      common factor (the slew limit turning the force) is rendered at the tip, so the efforts
//      render exactly the force the chain allowed, never a turn it refused;
//   3. a non-finite effort latches non_finite;
//   4. the actuators' effort limits (the drives' current limits, effort_limit()): the wrench
//      joints (pitch, yaw, insertion, roll) are scaled down together by the one factor that
//      brings the worst of them to its limit, so the rendered force keeps its direction and the
//      chain sees the force actually rendered (its slew memory, the passivity observer); the
//      grip, an internal force of the jaws, is clamped on its own;
//   5. the passivity observer on the rendered force; nothing but zero leaves unless armed.
// Whatever the inputs (NaN, Inf, huge or cancelling forces, points off the instrument, a pose
// from joints outside their range), the efforts are finite and within the limits.
// The forces stage (rt/app/src/stages/force_stage.cpp) calls it every cycle;
// tests/rt/app/force_command_property_test.cpp checks it over 10^6 random and hostile cases. RT
// path: noexcept, no heap.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "trainer/hal/joint_scale.hpp"
#include "trainer/kinematics/trocar_kinematics.hpp"
#include "trainer/model/forceps_catheter.hpp"
#include "trainer/safety/safety_supervisor.hpp"

namespace trainer::app {

// What acts on one instrument this cycle (trainer frame, N; velocity in m/s).
struct InstrumentForces {
  Eigen::Vector3f tip_force_n = Eigen::Vector3f::Zero();  // at the closed-jaw tip
  std::span<const model::ToolForce> point_forces;         // on the shaft and jaws, at their points
  Eigen::Vector3f tip_velocity_m_per_s = Eigen::Vector3f::Zero();  // for the passivity observer
};

struct ForceCommand {
  // The total force the efforts render (after the safety chain and the effort limits). Zero
  // unless armed.
  Eigen::Vector3f force_n = Eigen::Vector3f::Zero();
  // Per joint (pitch, yaw, roll, grip N·m; insertion N), each within its effort limit. Zero
  // unless armed.
  kinematics::JointVector efforts{};
  bool effort_limited = false;  // the effort limits scaled the wrench or clamped the grip
};

// The largest float effort a joint's drive accepts: JointScale::max_effort() (current limit as a
// joint effort) rounded down, so a command at it is never above the configured limit.
float effort_limit(const hal::JointScale& scale) noexcept;

// The point of the instrument a model's point force acts at (forceps_catheter.hpp ToolForce:
// its segment and the distance along it), as the kinematics names it.
kinematics::InstrumentPoint tool_point(const model::ToolForce& force) noexcept;

// `pose` must come from kinematics.forward() this cycle; `instrument` indexes the supervisor's
// per-instrument state (slew, passivity); `effort_limits` are the instrument's effort_limit()s,
// each > 0.
ForceCommand command_instrument(safety::SafetySupervisor& safety, std::size_t instrument,
                                const kinematics::TrocarKinematics& kinematics,
                                const kinematics::InstrumentPose& pose,
                                const InstrumentForces& forces,
                                const kinematics::JointVector& effort_limits, float dt_s,
                                std::uint64_t cycle) noexcept;

}  // namespace trainer::app
