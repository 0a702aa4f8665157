#include "stages/modal_stage.hpp"

#include <algorithm>

namespace trainer::app {

using Vec3 = Eigen::Vector3f;

Vec3 ModalStage::apply_catheter_loads(ModalModelState& state) noexcept {
  model::ModalModel& modal = *state.model;
  Vec3 total = Vec3::Zero();
  for (std::size_t k = 0; k < state.catheter_load_count; ++k) {
    const model::NodeForce& load = state.catheter_loads[k];
    if (!modal.add_node_force(load.node, load.force_n).is_ok()) {
      ++stats_->model_step_errors;
    } else {
      total += load.force_n;
    }
  }
  state.catheter_load_count = 0;
  return total;
}

bool ModalStage::anything_near(const ModalModelState& state,
                               std::span<const InstrumentFrame> instruments) const noexcept {
  const ContactSurface& surface = state.surface;
  for (std::size_t i = 0; i < instruments.size(); ++i) {
    if (!surface.contacts[i]) continue;
    if (surface.near(instruments[i].pose.tip_m) || surface.near(instruments[i].pose.hinge_m) ||
        surface.contacts[i]->in_contact() ||
        (state.segments[i] && state.segments[i]->contact_count() > 0)) {
      return true;
    }
  }
  if (!surface.grid) return false;
  for (const CatheterModelState& catheter : catheters_) {
    for (const Vec3& particle : catheter.catheter->positions_m()) {
      if (surface.near(particle)) return true;
    }
  }
  return false;
}

Vec3 ModalStage::apply_reactions(const ModalModelState& state, const ModalTargets& targets,
                                 std::span<const Vec3> on_tissue,
                                 std::span<InstrumentFrame> instruments,
                                 bool& tool_touching) noexcept {
  const ContactSurface& surface = state.surface;
  Vec3 total = surface.apply_tip_reactions(on_tissue, instruments, tool_touching);
  // Shaft and jaws: the opposite of what imposing their wall points took, at the contact
  // point on the segment (ray-based: the Jacobian there gives the torques).
  for (std::size_t s = 0; s < targets.segment_count; ++s) {
    const SegmentTarget& target = targets.segments[s];
    if (!target.active) continue;
    InstrumentFrame& instrument = instruments[target.instrument];
    if (!instrument.add_tool_force(
            model::ToolForce{target.segment, target.along_m,
                             -surface.transform.vector_to_world(target.on_tissue_n)})) {
      ++stats_->model_step_errors;
      continue;
    }
    instrument.model_contact = true;
    instrument.wall_segment_contact = true;
    instrument.model_indentation_m = std::max(instrument.model_indentation_m, target.depth_m);
    total += target.on_tissue_n;
    tool_touching = true;
  }
  return total;
}

Vec3 ModalStage::solve_contacts(ModalModelState& state, ModalTargets& targets,
                                std::span<InstrumentFrame> instruments,
                                bool& tool_touching) noexcept {
  model::ModalModel& modal = *state.model;
  ContactSurface& surface = state.surface;
  // Solve; a contact that would pull the tissue is released and the rest re-solved.
  for (int attempt = 0; attempt < 2 && targets.count > 0; ++attempt) {
    std::array<Vec3, model::ModalModel::kMaxContacts> forces{};
    if (!modal
             .solve_imposed(std::span(targets.targets.data(), targets.count),
                            std::span(forces.data(), targets.count))
             .is_ok()) {
      ++stats_->model_step_errors;
      modal.clear_forces();
      surface.release_all();
      targets.count = 0;
      break;
    }
    std::array<Vec3, kMaxInstruments> on_tissue{};
    for (Vec3& force : on_tissue) force.setZero();
    for (std::size_t s = 0; s < targets.segment_count; ++s)
      targets.segments[s].on_tissue_n.setZero();
    for (std::size_t k = 0; k < targets.count; ++k) {
      if (targets.segment_of[k] < 0) {
        on_tissue[targets.owner[k]] += forces[k];
      } else {
        targets.segments[static_cast<std::size_t>(targets.segment_of[k])].on_tissue_n += forces[k];
      }
    }
    bool released = surface.observe_tip_forces(std::span(on_tissue.data(), instruments.size()));
    // A shaft or jaw holding the wall where it would have to pull it (the tool moving away
    // faster than the wall follows) lets go, as a tip contact does.
    for (std::size_t s = 0; s < targets.segment_count; ++s) {
      SegmentTarget& target = targets.segments[s];
      if (target.active && target.on_tissue_n.dot(target.normal) > 0.0F) {
        target.active = false;
        released = true;
      }
    }
    if (released && attempt == 0) {
      modal.clear_forces();
      targets.keep_holding(surface);
      continue;
    }
    return apply_reactions(state, targets, on_tissue, instruments, tool_touching);
  }
  return Vec3::Zero();
}

void ModalStage::refresh_surface(ModalModelState& state) noexcept {
  ContactSurface& surface = state.surface;
  surface.surface_ready = false;
  if (!surface.grid) return;
  if (state.lazy) {
    // Lazy: only the vertices the queries return are computed (in the collision sub-stage);
    // the whole surface and the refit only when the motion bound exceeds the slack.
    state.lazy->keep_warm(surface);
    const bool lazy = state.lazy->begin(surface, *state.model);
    stats_->laps.lap(Substage::modal_reconstruct);
    if (!lazy) (void)state.lazy->finish_full(surface);
    stats_->laps.lap(Substage::modal_refit);
    return;
  }
  if (!state.model->reconstruct(surface.deformed).is_ok()) return;
  for (std::size_t i = 0; i < surface.deformed.size(); ++i)
    surface.deformed[i] += surface.rest_positions[i];
  stats_->laps.lap(Substage::modal_reconstruct);
  (void)surface.refit_grid();
  stats_->laps.lap(Substage::modal_refit);
}

void ModalStage::run_model(std::size_t index, CycleFrame& frame) noexcept {
  ModalModelState& state = models_[index];
  model::ModalModel& modal = *state.model;
  ModalModelStats& model_stats = stats_->modal_models[index];
  modal.clear_forces();
  const Vec3 catheter_total = apply_catheter_loads(state);  // from the catheters' last step
  Vec3 tool_total = Vec3::Zero();
  bool tool_touching = false;
  const bool near = anything_near(state, frame.instruments);
  stats_->laps.lap(Substage::modal_near);
  if (near && !state.surface.surface_ready) refresh_surface(state);
  if (near && state.surface.surface_ready) {
    ModalTargets targets{};
    gather_tip_targets(state, frame.instruments, targets, stats_->model_step_errors);
    gather_segment_targets(state, frame.instruments, targets, stats_->model_step_errors);
    stats_->laps.lap(Substage::modal_collision);
    tool_total = solve_contacts(state, targets, frame.instruments, tool_touching);
    stats_->laps.lap(Substage::modal_solve);
  }
  const Vec3 total = tool_total + catheter_total;
  if (tool_touching) ++model_stats.tool_contact_cycles;
  if (!total.isZero(0.0F) || tool_touching) {
    const float magnitude = total.norm();
    ++model_stats.loaded_cycles;
    model_stats.force_sum_n += static_cast<double>(magnitude);
    model_stats.peak_force_n = std::max(model_stats.peak_force_n, magnitude);
  }
  if (!modal.step().is_ok()) ++stats_->model_step_errors;
  stats_->laps.lap(Substage::modal_step);
  if (near) {
    refresh_surface(state);
  } else {
    state.surface.surface_ready = false;  // stale: rebuilt when a tool comes near
  }
}

void ModalStage::run(CycleFrame& frame) noexcept {
  for (std::size_t m = 0; m < models_.size(); ++m) run_model(m, frame);
}

}  // namespace trainer::app
