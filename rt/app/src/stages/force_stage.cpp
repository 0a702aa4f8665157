#include "stages/force_stage.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "stages/vector_config.hpp"
#include "trainer/app/force_command.hpp"

namespace trainer::app {

using Vec3 = Eigen::Vector3f;
using kinematics::kJointCount;

core::Expected<ForceStage> ForceStage::create(const config::SceneConfig& scene,
                                              std::span<const InstrumentRig> rigs,
                                              safety::SafetySupervisor& safety, AppStats& stats,
                                              core::Arena& arena) {
  if (scene.objects.size() > kMaxObjects) {
    return core::make_error(scene.source_path.string() + ": at most " +
                            std::to_string(kMaxObjects) + " objects, the scene has " +
                            std::to_string(scene.objects.size()));
  }
  auto objects = arena.allocate_array<ObjectState>(scene.objects.size(), "rigid objects");
  if (!objects) return std::move(objects).error();
  for (std::size_t k = 0; k < scene.objects.size(); ++k) {
    const config::ObjectConfig& object = scene.objects[k];
    ObjectState& state = (*objects)[k];
    state.kind = object.kind;
    const model::PenaltyMaterial material{static_cast<float>(object.stiffness_n_per_m),
                                          static_cast<float>(object.damping_n_s_per_m)};
    if (object.kind == config::ObjectKind::plane) {
      state.plane = model::RigidPlane(to_vec3(object.point_m), to_vec3(object.normal), material);
    } else {
      state.sphere = model::RigidSphere(to_vec3(object.center_m),
                                        static_cast<float>(object.radius_m), material);
    }
    for (std::size_t instrument : object.touched_by) {
      state.touched_by_mask |= 1U << static_cast<unsigned>(instrument);
    }
  }
  auto was_in_contact = arena.allocate_array<bool>(rigs.size(), "instrument contact memory");
  if (!was_in_contact) return std::move(was_in_contact).error();
  return ForceStage(rigs, *objects, *was_in_contact, safety, stats);
}

void ForceStage::render_instrument(std::size_t index, CycleFrame& frame) noexcept {
  const InstrumentRig& rig = rigs_[index];
  const InstrumentFrame& state = frame.instruments[index];
  const kinematics::InstrumentPose& pose = state.pose;
  const Vec3& tip_velocity = state.tip_velocity_m_per_s;

  Vec3 requested = state.model_force_n;
  Vec3 object_force = Vec3::Zero();  // the rigid objects' share (telemetry contact point)
  bool object_contact = false;
  bool in_contact = state.model_contact;
  float depth = state.model_contact ? state.model_indentation_m : 0.0F;
  for (const ObjectState& object : objects_) {
    if ((object.touched_by_mask & (1U << static_cast<unsigned>(index))) == 0) continue;
    const model::PointContact contact = object.kind == config::ObjectKind::plane
                                            ? object.plane.contact(pose.tip_m, tip_velocity)
                                            : object.sphere.contact(pose.tip_m, tip_velocity);
    if (contact.in_contact) {
      in_contact = true;
      object_contact = true;
      depth = std::max(depth, contact.depth_m);
      requested += contact.force_n;
      object_force += contact.force_n;
    }
  }

  // The tip force (rigid objects, the ducts) plus the ray-based forces on the shaft and jaws
  // (walls, catheters) through the safety chain to joint efforts (force_command.hpp).
  in_contact = in_contact || state.catheter_contact;
  const InstrumentForces forces{requested, state.point_forces(), tip_velocity};
  const ForceCommand command =
      command_instrument(*safety_, index, rig.kinematics, pose, forces, rig.effort_limits,
                         frame.dt_s(), frame.timing.cycle_index);
  const Vec3& force = command.force_n;
  const kinematics::JointVector& efforts = command.efforts;
  if (command.effort_limited) ++stats_->effort_limited_cycles;
  for (std::size_t j = 0; j < kJointCount; ++j)
    frame.commands[rig.first_channel + j].effort = efforts[j];

  InstrumentStats& stats = stats_->instruments[index];
  if (state.wall_segment_contact) ++stats.wall_segment_contact_cycles;
  const float force_norm = force.norm();
  if (in_contact) {
    ++stats.contact_cycles;
    if (!was_in_contact_[index]) ++stats.contact_onsets;
    stats.force_sum_n += static_cast<double>(force_norm);
  }
  was_in_contact_[index] = in_contact;
  stats.peak_force_n = std::max(stats.peak_force_n, force_norm);
  stats.peak_depth_m = std::max(stats.peak_depth_m, depth);
  for (std::size_t j = 0; j < kJointCount; ++j) {
    stats.peak_joint_effort[j] = std::max(stats.peak_joint_effort[j], std::fabs(efforts[j]));
  }

  InstrumentTelemetry& out = frame.instrument_out[index];
  out.joints = state.joint_position;
  out.tip_m = {pose.tip_m.x(), pose.tip_m.y(), pose.tip_m.z()};
  out.force_n = {force.x(), force.y(), force.z()};
  out.joint_efforts = efforts;
  out.in_contact = in_contact;
  out.object_contact = object_contact;
  out.object_force_n = {object_force.x(), object_force.y(), object_force.z()};
}

void ForceStage::run(CycleFrame& frame) noexcept {
  for (std::size_t i = 0; i < rigs_.size(); ++i) render_instrument(i, frame);
}

}  // namespace trainer::app
