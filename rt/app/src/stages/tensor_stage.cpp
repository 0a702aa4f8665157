#include "stages/tensor_stage.hpp"

#include <algorithm>

namespace trainer::app {

using Vec3 = Eigen::Vector3f;

void TensorStage::refresh_surface(TensorModelState& state) noexcept {
  ContactSurface& surface = state.surface;
  model::TensorModel& tensor = *state.model;
  surface.surface_ready = false;
  if (!surface.grid) return;
  if (tensor.contact_count() == 0) {
    if (!state.deformed_is_rest) {
      std::copy(surface.rest_positions.begin(), surface.rest_positions.end(),
                surface.deformed.begin());
    }
    state.deformed_is_rest = true;
  } else {
    tensor.update_field();
    const std::span<const float> field = tensor.displacements();
    for (std::size_t j = 0; j < state.response_nodes.size(); ++j) {
      const std::size_t base = 3 * static_cast<std::size_t>(state.response_nodes[j]);
      for (std::size_t axis = 0; axis < 3; ++axis) {
        surface.deformed[base + axis] = surface.rest_positions[base + axis] + field[3 * j + axis];
      }
    }
    state.deformed_is_rest = false;
  }
  (void)surface.refit_grid();
}

void TensorStage::gather_targets(TensorModelState& state, std::span<InstrumentFrame> instruments,
                                 Targets& out) noexcept {
  ContactSurface& surface = state.surface;
  const std::size_t capacity = state.model->max_contacts();
  for (std::size_t i = 0; i < instruments.size(); ++i) {
    if (!surface.contacts[i]) continue;
    InstrumentFrame& instrument = instruments[i];
    std::array<model::ImposedDisplacement, model::DisplacementContact::kMaxTargets> mine{};
    const std::size_t count = surface.tip_targets(i, instrument, mine, stats_->model_step_errors);
    bool shared = false;
    for (std::size_t k = 0; k < count; ++k) {
      for (std::size_t q = 0; q < out.count; ++q)
        shared = shared || out.contacts[q].node == mine[k].node;
    }
    if (shared || out.count + count > capacity) {
      surface.contacts[i]->release();
      continue;
    }
    for (std::size_t k = 0; k < count; ++k) {
      out.contacts[out.count] = model::TensorContact{mine[k].node, mine[k].displacement_m};
      out.owner[out.count++] = i;
      out.indentation_m = std::max(out.indentation_m, mine[k].displacement_m.norm());
      instrument.model_indentation_m =
          std::max(instrument.model_indentation_m, mine[k].displacement_m.norm());
    }
  }
}

void TensorStage::solve_contacts(std::size_t index, Targets& targets,
                                 std::span<InstrumentFrame> instruments) noexcept {
  TensorModelState& state = models_[index];
  model::TensorModel& tensor = *state.model;
  ContactSurface& surface = state.surface;
  TensorModelStats& model_stats = stats_->tensor_models[index];
  for (int attempt = 0; attempt < 2 && targets.count > 0; ++attempt) {
    if (!tensor.solve(std::span(targets.contacts.data(), targets.count)).is_ok()) {
      ++model_stats.refused_solves;
      ++stats_->model_step_errors;
      surface.release_all();
      targets.count = 0;
      return;
    }
    std::array<Vec3, kMaxInstruments> on_tissue{};
    for (Vec3& force : on_tissue) force.setZero();
    for (std::size_t k = 0; k < targets.count; ++k)
      on_tissue[targets.owner[k]] += tensor.contact_force(k);
    const bool released =
        surface.observe_tip_forces(std::span(on_tissue.data(), instruments.size()));
    if (released && attempt == 0) {
      std::size_t kept = 0;
      for (std::size_t k = 0; k < targets.count; ++k) {
        if (surface.contacts[targets.owner[k]]->in_contact()) {
          targets.contacts[kept] = targets.contacts[k];
          targets.owner[kept++] = targets.owner[k];
        }
      }
      targets.count = kept;
      continue;
    }
    bool holding = false;
    const Vec3 total = surface.apply_tip_reactions(on_tissue, instruments, holding);
    const float magnitude = total.norm();
    ++model_stats.loaded_cycles;
    model_stats.force_sum_n += static_cast<double>(magnitude);
    model_stats.peak_force_n = std::max(model_stats.peak_force_n, magnitude);
    model_stats.peak_contact_nodes =
        std::max(model_stats.peak_contact_nodes, static_cast<std::uint32_t>(targets.count));
    model_stats.peak_indentation_m =
        std::max(model_stats.peak_indentation_m, targets.indentation_m);
    return;
  }
}

void TensorStage::run_model(std::size_t index, CycleFrame& frame) noexcept {
  TensorModelState& state = models_[index];
  model::TensorModel& tensor = *state.model;
  ContactSurface& surface = state.surface;
  if (!surface.grid) return;  // no instrument touches it
  bool near = false;
  for (std::size_t i = 0; i < frame.instruments.size(); ++i) {
    if (!surface.contacts[i]) continue;
    near =
        near || surface.near(frame.instruments[i].pose.tip_m) || surface.contacts[i]->in_contact();
  }
  if (!near) {
    // Far from every tool: at rest, nothing to solve; the surface is rebuilt once on release.
    if (tensor.contact_count() > 0) (void)tensor.solve({});
    if (!state.deformed_is_rest || !surface.surface_ready) refresh_surface(state);
    state.was_in_contact.fill(false);
    return;
  }
  if (!surface.surface_ready) refresh_surface(state);
  if (!surface.surface_ready) {
    ++stats_->model_step_errors;
    return;
  }
  Targets targets{};
  gather_targets(state, frame.instruments, targets);
  solve_contacts(index, targets, frame.instruments);
  if (targets.count == 0 && tensor.contact_count() > 0) (void)tensor.solve({});
  TensorModelStats& model_stats = stats_->tensor_models[index];
  for (std::size_t i = 0; i < frame.instruments.size(); ++i) {
    const bool holding = surface.contacts[i] && surface.contacts[i]->in_contact();
    if (holding && !state.was_in_contact[i]) ++model_stats.contact_onsets;
    state.was_in_contact[i] = holding;
  }
  if (tensor.contact_count() > 0 || !state.deformed_is_rest) refresh_surface(state);
}

void TensorStage::run(CycleFrame& frame) noexcept {
  for (std::size_t t = 0; t < models_.size(); ++t) run_model(t, frame);
}

}  // namespace trainer::app
