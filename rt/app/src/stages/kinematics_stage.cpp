#include "stages/kinematics_stage.hpp"

#include <cmath>
#include <numbers>

namespace trainer::app {

using kinematics::kJointCount;

core::Expected<KinematicsStage> KinematicsStage::create(std::span<const InstrumentRig> rigs,
                                                        safety::SafetySupervisor& safety,
                                                        AppStats& stats, core::Arena& arena) {
  auto joints = arena.allocate_array<JointState>(rigs.size(), "instrument joint state");
  if (!joints) return std::move(joints).error();
  return KinematicsStage(rigs, *joints, safety, stats);
}

void KinematicsStage::sense_joints(std::size_t index, const CycleFrame& frame) noexcept {
  const InstrumentRig& rig = rigs_[index];
  JointState& state = joints_[index];
  const loop::CycleTiming& timing = frame.timing;
  const auto dt = static_cast<float>(timing.dt_s);
  const auto alpha = static_cast<float>(
      timing.dt_s / (timing.dt_s + 1.0 / (2.0 * std::numbers::pi * kVelocityCutoffHz)));

  bool all_valid = true;
  kinematics::JointVector position{};
  for (std::size_t j = 0; j < kJointCount; ++j) {
    const hal::EncoderSample& sample = frame.encoder_samples[rig.first_channel + j];
    all_valid = all_valid && sample.valid;
    position[j] = sample.position;  // joint-side SI, converted by the backend (HAL contract)
  }
  if (!all_valid) {
    ++stats_->invalid_encoder_cycles;
    position = state.position;  // hold the last good reading; the error streak guards this
  } else if (state.has_position) {
    for (std::size_t j = 0; j < kJointCount; ++j) {
      safety_->check_joint_step(rig.kinds[j] == hal::JointKind::prismatic, state.position[j],
                                position[j], dt, timing.cycle_index);
      const float raw_rate = (position[j] - state.position[j]) / dt;
      state.velocity[j] += alpha * (raw_rate - state.velocity[j]);
    }
  } else {
    // The first reading has no previous one to check a step against; its numbers still must
    // be finite (a NaN roll or grip would otherwise pass unseen while no jaw force uses it).
    for (const float value : position) {
      if (!std::isfinite(value)) safety_->latch(safety::Fault::non_finite, timing.cycle_index);
    }
  }
  if (all_valid) {
    state.position = position;
    state.has_position = true;
  }
}

void KinematicsStage::run(CycleFrame& frame) noexcept {
  for (std::size_t i = 0; i < rigs_.size(); ++i) {
    if (frame.newly_armed) joints_[i].velocity.fill(0.0F);
    sense_joints(i, frame);
    const JointState& joints = joints_[i];
    InstrumentFrame& out = frame.instruments[i];
    // out.pose still holds last cycle's pose: only this stage writes it.
    if (joints.has_position) {
      out.previous_tip_m = out.pose.tip_m;
      out.has_previous_tip = true;
    }
    out.joint_position = joints.position;
    out.pose = rigs_[i].kinematics.forward(joints.position);
    out.tip_velocity_m_per_s = kinematics::TrocarKinematics::point_velocity(
        out.pose, out.pose.insertion_m, joints.velocity);
    // What the model stages accumulate this cycle starts from nothing.
    out.model_force_n.setZero();
    out.model_contact = false;
    out.model_indentation_m = 0.0F;
    out.wall_segment_contact = false;
    out.tool_force_count = 0;
    out.catheter_contact = false;
    out.grasping = false;
    out.squeeze_n = 0.0F;
  }
}

}  // namespace trainer::app
