#include "stages/catheter_stage.hpp"

#include "stages/cached_queries.hpp"

#include <algorithm>

namespace trainer::app {
namespace {

using Vec3 = Eigen::Vector3f;

// The instrument's segments as the catheter contact sees them.
model::ForcepsShape forceps_shape(const InstrumentFrame& instrument) noexcept {
  const kinematics::InstrumentPose& pose = instrument.pose;
  model::ForcepsShape shape;
  shape.shaft_start_m = pose.shaft_start_m;
  shape.hinge_m = pose.hinge_m;
  shape.jaw_tips_m = pose.jaw_tips_m;
  shape.direction = pose.direction;
  shape.opening_direction = pose.opening_direction;
  shape.grip_rad = instrument.joint_position[kinematics::kGrip];
  shape.velocity_m_per_s = instrument.tip_velocity_m_per_s;
  return shape;
}

}  // namespace

bool CatheterStage::add_wall_planes(std::size_t index, std::size_t& plane_count) noexcept {
  CatheterModelState& state = catheters_[index];
  const model::Catheter& catheter = *state.catheter;
  CatheterStats& stats = stats_->catheters[index];
  const std::span<const Vec3> positions = catheter.positions_m();
  const std::span<const Vec3> velocities = catheter.velocities_m_per_s();
  bool ok = true;
  for (std::size_t m = 0; m < walls_.size(); ++m) {
    state.wall_first_plane[m] = plane_count;
    state.wall_out[m] = model::ParticleContactOutput{};
    if (!state.walls[m]) continue;
    ContactSurface& wall = walls_[m].surface;
    if (!wall.surface_ready) continue;  // no particle near: nothing to find
    for (std::size_t i = 0; i < positions.size(); ++i) {
      state.model_frame_positions[i] = wall.transform.to_model(positions[i]);
      state.model_frame_velocities[i] = wall.transform.vector_to_model(velocities[i]);
    }
    const float detection_radius = catheter.radius_m() + kWallDetectionMarginM;
    // The hierarchy's root box holds every triangle box a query can return: the particles
    // outside it (most of the catheter) are not queried (docs/catheter.md, "Issue 19, round 2").
    const model::Aabb* bounds = wall.grid && wall.grid->ready() ? &wall.grid->bounds() : nullptr;
    CachedQueries queries(wall);  // each particle's candidates kept between cycles
    const core::Status found =
        state.walls[m]->compute(state.model_frame_positions.first(positions.size()),
                                state.model_frame_velocities.first(positions.size()),
                                detection_radius, wall.view(), {}, queries, state.wall_out[m],
                                bounds);
    if (!found.is_ok()) ok = false;
    stats.dropped_contacts += state.wall_out[m].dropped_count;
    const float reach = catheter.radius_m() + walls_[m].half_thickness_m;  // to the wall's surface
    for (const model::ParticleContactRecord& record : state.wall_out[m].contacts) {
      if (plane_count >= state.planes.size()) {
        ++stats.dropped_contacts;
        continue;
      }
      model::ContactPlane& plane = state.planes[plane_count++];
      plane.particle_a = plane.particle_b = record.particle;
      plane.weight_b = 0.0F;
      plane.point_m = wall.transform.to_world(record.point_m);
      plane.normal = wall.transform.vector_to_world(record.normal);
      plane.surface_velocity_m_per_s = Vec3::Zero();
      plane.reach_m = reach;
      plane.stiffness_n_per_m = state.contact.wall_stiffness_n_per_m;
      plane.damping_n_s_per_m = state.contact.wall_damping_n_s_per_m;
      plane.max_force_n = state.contact.max_contact_force_n;
    }
  }
  return ok;
}

bool CatheterStage::add_tool_planes(CatheterModelState& state,
                                    std::span<const InstrumentFrame> instruments,
                                    std::size_t& plane_count) noexcept {
  bool ok = true;
  for (std::size_t i = 0; i < instruments.size(); ++i) {
    state.tool_first_plane[i] = plane_count;
    state.tool_plane_count[i] = 0;
    if (!state.tools[i]) continue;
    std::size_t added = 0;
    const core::Status prepared = state.tools[i]->prepare(
        forceps_shape(instruments[i]), *state.catheter, state.planes.subspan(plane_count), added);
    if (!prepared.is_ok()) ok = false;
    state.tool_plane_count[i] = added;
    plane_count += added;
  }
  return ok;
}

void CatheterStage::return_wall_reactions(std::size_t index, std::size_t wall_plane_end) noexcept {
  CatheterModelState& state = catheters_[index];
  CatheterStats& stats = stats_->catheters[index];
  const std::span<const Vec3> plane_forces = state.catheter->contact_plane_forces_n();
  for (std::size_t m = 0; m < walls_.size(); ++m) {
    if (!state.walls[m]) continue;
    ModalModelState& wall = walls_[m];
    const std::span<const model::ParticleContactRecord> records = state.wall_out[m].contacts;
    Vec3 total = Vec3::Zero();
    std::uint32_t touching = 0;
    for (std::size_t k = 0; k < records.size(); ++k) {
      const std::size_t plane = state.wall_first_plane[m] + k;
      if (plane >= wall_plane_end || plane >= plane_forces.size()) break;
      const Vec3 on_wall = -wall.surface.transform.vector_to_model(plane_forces[plane]);
      if (on_wall.isZero(0.0F)) continue;
      ++touching;
      total += on_wall;
      for (std::size_t corner = 0; corner < 3; ++corner) {
        const float weight = records[k].barycentric[static_cast<Eigen::Index>(corner)];
        if (weight == 0.0F) continue;
        if (!wall.add_catheter_load(records[k].vertices[corner], weight * on_wall))
          ++stats.dropped_contacts;
      }
    }
    if (touching > 0) ++stats.wall_contact_cycles;
    ModalModelStats& wall_stats = stats_->modal_models[m];
    if (touching > 0) ++wall_stats.catheter_contact_cycles;
    wall_stats.peak_catheter_contacts = std::max(wall_stats.peak_catheter_contacts, touching);
    wall_stats.peak_catheter_force_n = std::max(wall_stats.peak_catheter_force_n, total.norm());
  }
}

bool CatheterStage::return_tool_forces(CatheterModelState& state,
                                       std::span<InstrumentFrame> instruments) noexcept {
  model::Catheter& catheter = *state.catheter;
  const std::span<const Vec3> plane_forces = catheter.contact_plane_forces_n();
  bool ok = true;
  for (std::size_t i = 0; i < instruments.size(); ++i) {
    if (!state.tools[i]) continue;
    InstrumentFrame& instrument = instruments[i];
    model::ForcepsCatheterContact& tool = *state.tools[i];
    const std::size_t first = state.tool_first_plane[i];
    const std::size_t count = state.tool_plane_count[i];
    const std::span<const Vec3> mine = first + count <= plane_forces.size()
                                           ? plane_forces.subspan(first, count)
                                           : std::span<const Vec3>{};
    if (!tool.collect(catheter, mine).is_ok()) ok = false;
    for (const model::ToolForce& force : tool.tool_forces()) {
      if (!instrument.add_tool_force(force)) {
        ok = false;
        break;
      }
      instrument.catheter_contact = true;
    }
    InstrumentStats& tool_stats = stats_->instruments[i];
    if (tool.grasping()) {
      instrument.grasping = true;
      instrument.squeeze_n = std::max(instrument.squeeze_n, tool.squeeze_force_n());
      ++tool_stats.grasping_cycles;
    }
    tool_stats.grasps = tool.grasp_count();
    tool_stats.slips = tool.slip_count();
    tool_stats.peak_squeeze_n = std::max(tool_stats.peak_squeeze_n, tool.squeeze_force_n());
    if (!tool.tool_forces().empty()) ++tool_stats.catheter_contact_cycles;
  }
  return ok;
}

void CatheterStage::track_insertion(std::size_t index) noexcept {
  const CatheterModelState& state = catheters_[index];
  CatheterStats& stats = stats_->catheters[index];
  if (!state.has_goal) return;
  float depth = 0.0F;
  for (const Vec3& p : state.catheter->positions_m()) {
    const Vec3 offset = p - state.goal_entry_m;
    const float along = offset.dot(state.goal_direction);
    const float radial = (offset - along * state.goal_direction).norm();
    if (along > depth && radial <= state.goal_radius_m) depth = along;
  }
  stats.insertion_depth_m = depth;
  stats.peak_insertion_depth_m = std::max(stats.peak_insertion_depth_m, depth);
  bool held = false;
  for (const auto& tool : state.tools) held = held || (tool && tool->grasping());
  if (held) stats.peak_held_depth_m = std::max(stats.peak_held_depth_m, depth);
  if (!stats.target_reached && depth >= state.goal_target_m) {
    stats.target_reached = true;
    stats.first_target_cycle = stats_->cycles;
  }
}

void CatheterStage::step_catheter(std::size_t index, CycleFrame& frame) noexcept {
  CatheterModelState& state = catheters_[index];
  model::Catheter& catheter = *state.catheter;
  std::size_t plane_count = 0;
  bool ok = add_wall_planes(index, plane_count);
  stats_->laps.lap(Substage::catheter_walls);
  const std::size_t wall_plane_end = plane_count;
  ok = add_tool_planes(state, frame.instruments, plane_count) && ok;
  stats_->laps.lap(Substage::catheter_tools);
  if (!catheter.set_contact_planes(state.planes.first(plane_count)).is_ok()) ok = false;
  catheter.clear_forces();
  if (state.has_gravity) {
    for (std::uint32_t p = 0; p < catheter.particle_count(); ++p) {
      ok = catheter.add_force(p, state.gravity_force_n).is_ok() && ok;
    }
  }
  ok = catheter.step(period_s_).is_ok() && ok;
  stats_->laps.lap(Substage::catheter_step);
  return_wall_reactions(index, wall_plane_end);
  ok = return_tool_forces(state, frame.instruments) && ok;
  track_insertion(index);
  stats_->laps.lap(Substage::catheter_reactions);
  if (!ok) ++stats_->model_step_errors;
}

void CatheterStage::run(CycleFrame& frame) noexcept {
  for (std::size_t c = 0; c < catheters_.size(); ++c) step_catheter(c, frame);
}

}  // namespace trainer::app
