// The data one haptic cycle passes from stage to stage (shared/DESIGN.md "One cycle"): a plain
// struct, carved once at configure time and reused every cycle. Each field says which stage
// writes it; later stages only read it. Units are in the names (trainer frame, SI).
//
//   hal_read    → timing context, input conditions, encoder samples, actuator status, arming
//   kinematics  → per instrument: joints, pose, tip velocity; clears the contact outputs
//   models      → per instrument: forces from the soft-tissue models and catheters
//   forces      → actuator commands, telemetry staging
//   hal_write   → (HAL outputs)
//   publish     → faults_raised_at_publish (read by the next cycle's hal_read)
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "trainer/app/app_stats.hpp"
#include "trainer/app/telemetry.hpp"
#include "trainer/hal/device.hpp"
#include "trainer/kinematics/trocar_kinematics.hpp"
#include "trainer/loop/periodic_loop.hpp"
#include "trainer/model/forceps_catheter.hpp"
#include "trainer/model/segment_contact.hpp"
#include "trainer/safety/safety_supervisor.hpp"

namespace trainer::app {

// Point forces one instrument's shaft and jaws can take in one cycle: the catheters' (two
// per catheter contact), then each modal model's wall contacts. Beyond it a force is dropped
// and counted as a model step error.
inline constexpr std::size_t kMaxToolForces =
    2 * model::ForcepsCatheterContact::kMaxToolForces +
    kMaxSceneModels * model::SegmentSurfaceContact::kMaxSegments;

struct InstrumentFrame {
  // kinematics stage.
  kinematics::JointVector joint_position{};  // pitch rad, yaw rad, insertion m, roll rad, grip rad
  kinematics::InstrumentPose pose{};         // this cycle's shaft, hinge, jaws, tip
  Eigen::Vector3f tip_velocity_m_per_s = Eigen::Vector3f::Zero();
  Eigen::Vector3f previous_tip_m = Eigen::Vector3f::Zero();  // last cycle's tip
  bool has_previous_tip = false;
  // Model stages (cleared by the kinematics stage): the tip force of the soft-tissue models,
  // whether one holds the tip, the deepest displacement a contact imposes, and the ray-based
  // point forces on the shaft and jaws (duct walls, then catheters).
  Eigen::Vector3f model_force_n = Eigen::Vector3f::Zero();
  bool model_contact = false;
  float model_indentation_m = 0.0F;
  bool wall_segment_contact = false;  // the shaft or a jaw holds a duct's wall this cycle
  std::array<model::ToolForce, kMaxToolForces> tool_forces{};
  std::size_t tool_force_count = 0;
  bool catheter_contact = false;
  bool grasping = false;
  float squeeze_n = 0.0F;

  // Appends a point force; false (nothing added) when the capacity is full.
  bool add_tool_force(const model::ToolForce& force) noexcept {
    if (tool_force_count >= tool_forces.size()) return false;
    tool_forces[tool_force_count++] = force;
    return true;
  }
  std::span<const model::ToolForce> point_forces() const noexcept {
    return {tool_forces.data(), tool_force_count};
  }
};

struct CycleFrame {
  // hal_read: the loop's timing of this cycle, the safety inputs, what the HAL returned.
  loop::CycleTiming timing{};
  safety::InputConditions conditions{};
  bool encoders_ok = false;
  bool newly_armed = false;                       // the safety chain armed in this cycle's hal_read
  bool reset_requested = false;                   // hal_read took an explicit reset request
  std::span<hal::EncoderSample> encoder_samples;  // joint-side SI, per channel
  std::span<hal::ActuatorStatus> actuator_status;
  // kinematics and the model stages.
  std::span<InstrumentFrame> instruments;
  // forces: efforts per channel (hal_write sets enable and zeroes them unless armed) and what
  // the telemetry shows of each instrument.
  std::span<hal::ActuatorCommand> commands;
  std::span<InstrumentTelemetry> instrument_out;
  // publish: the supervisor's raised-fault total when this cycle published its state. Carried
  // to the next cycle: a reset is honoured only when no fault was raised since.
  std::uint64_t faults_raised_at_publish = 0;

  float dt_s() const noexcept { return static_cast<float>(timing.dt_s); }
};

}  // namespace trainer::app
