#include "trainer/app/lazy_modal_surface.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "trainer/app/contact_surface.hpp"

namespace trainer::app {
namespace {

double lazy_surface_norm3(const float (&v)[3]) noexcept {
  const double x = v[0];
  const double y = v[1];
  const double z = v[2];
  return std::sqrt(x * x + y * y + z * z);
}

}  // namespace

void LazyModalSurface::finish_node(std::uint32_t node) noexcept {
  float* out = surface_->deformed.data() + 3 * static_cast<std::size_t>(node);
  const std::int32_t surface = surface_index_[node];
  if (full_residual_valid_) {
    if (surface >= 0) {
      for (std::size_t c = 0; c < 3; ++c) out[c] = out[c] + full_residual_[3 * static_cast<std::size_t>(surface) + c];
    }
  } else if (static_correction_ && surface >= 0 && load_count_ > 0) {
    // Σ_l R_{node,l} F_l summed as ModalModel::reconstruct does (element by element as its
    // axpy over the surface): loads in order, each load's axes in order, from zero (row block
    // l read at this node's columns).
    const std::size_t stride = 3 * static_cast<std::size_t>(surface_count_);
    if (static_cast<std::uint32_t>(surface) + 1 < surface_count_) {
      // Four lanes (the fourth reads the next node's x, discarded): per lane the same
      // multiply and add as the scalar sum below.
      Eigen::Array4f sum = Eigen::Array4f::Zero();
      for (std::size_t k = 0; k < load_count_; ++k) {
        const Load& load = loads_[k];
        if (load.surface_index < 0) continue;
        for (std::size_t axis = 0; axis < 3; ++axis) {
          const float* row = residual_.data() +
                             (3 * static_cast<std::size_t>(load.surface_index) + axis) * stride +
                             3 * static_cast<std::size_t>(surface);
          sum = sum + load.force_n[axis] * Eigen::Map<const Eigen::Array4f>(row);
        }
      }
      for (std::size_t c = 0; c < 3; ++c) out[c] = out[c] + sum[static_cast<Eigen::Index>(c)];
      for (std::size_t c = 0; c < 3; ++c) out[c] = out[c] + rest_[3 * static_cast<std::size_t>(node) + c];
      return;
    }
    float residual[3] = {0.0F, 0.0F, 0.0F};
    for (std::size_t k = 0; k < load_count_; ++k) {
      const Load& load = loads_[k];
      if (load.surface_index < 0) continue;
      for (std::size_t axis = 0; axis < 3; ++axis) {
        const float* row = residual_.data() +
                           (3 * static_cast<std::size_t>(load.surface_index) + axis) * stride +
                           3 * static_cast<std::size_t>(surface);
        for (std::size_t c = 0; c < 3; ++c) residual[c] = residual[c] + load.force_n[axis] * row[c];
      }
    }
    for (std::size_t c = 0; c < 3; ++c) out[c] = out[c] + residual[c];
  }
  for (std::size_t c = 0; c < 3; ++c) out[c] = out[c] + rest_[3 * static_cast<std::size_t>(node) + c];
}

void LazyModalSurface::mark_pending(std::uint32_t node, std::size_t& pending) noexcept {
  if (node >= node_count_ || stamp_[node] == step_) return;
  stamp_[node] = step_;
  pending_[pending++] = node;
}

void LazyModalSurface::compute_pending(std::size_t pending) noexcept {
  // The marked vertices in one kernel call, then their static correction and rest position.
  if (pending == 0) return;
  modal_->shape_rows(pending_.data(), pending, modes_.data(), surface_->deformed.data());
  for (std::size_t k = 0; k < pending; ++k) finish_node(pending_[k]);
  vertices_computed_ += pending;
}

void LazyModalSurface::compute_nodes(const std::uint32_t* nodes, std::size_t count) noexcept {
  std::size_t pending = 0;
  for (std::size_t k = 0; k < count; ++k) {
    const std::uint32_t node = nodes[k];
    mark_pending(node, pending);
  }
  compute_pending(pending);
}

void LazyModalSurface::reconstruct_node(std::uint32_t node, float* out) noexcept {
  // The test's view of the kernel: this step's value of a node, made current.
  compute_nodes(&node, 1);
  for (std::size_t c = 0; c < 3; ++c) out[c] = surface_->deformed[3 * static_cast<std::size_t>(node) + c];
}

double LazyModalSurface::state_magnitude(std::span<const float> modes, std::span<const Load> loads) const noexcept {
  // Each coordinate is a float sum of at most r + 3L + 4 terms whose magnitudes add up to at
  // most this; its rounding error is within γ_m of it.
  double modes_abs = 0.0;
  for (const float q : modes) modes_abs += std::abs(static_cast<double>(q));
  double forces_abs = 0.0;
  for (const Load& load : loads) {
    for (const float f : load.force_n) forces_abs += std::abs(static_cast<double>(f));
  }
  return max_rest_abs_ + max_shape_entry_ * modes_abs + max_residual_entry_ * forces_abs;
}

void LazyModalSurface::prepare_epoch(Epoch& epoch) noexcept {
  epoch.delta_step = step_;
  double squared = 0.0;
  for (std::size_t j = 0; j < active_modes_; ++j) {
    const double d = static_cast<double>(modes_[j]) - static_cast<double>(epoch.modes[j]);
    epoch.abs_dq[j] = std::abs(d);
    epoch.abs_dq_f[j] = float_up(std::abs(d));
    epoch.dq_f[j] = static_cast<float>(d);
    squared += d * d;
  }
  epoch.dq_norm = std::sqrt(squared);
  epoch.delta_count = 0;
  if (!static_correction_) return;
  for (std::size_t k = 0; k < load_count_; ++k) {
    const Load& load = loads_[k];
    if (load.surface_index < 0) continue;
    float delta[3] = {load.force_n[0], load.force_n[1], load.force_n[2]};
    // The loads keep their order from step to step mostly: the same slot first.
    std::size_t match = k < epoch.load_count && epoch.loads[k].node == load.node ? k : epoch.load_count;
    for (std::size_t j = 0; match == epoch.load_count && j < epoch.load_count; ++j) {
      if (epoch.loads[j].node == load.node) match = j;
    }
    if (match < epoch.load_count) {
      for (std::size_t c = 0; c < 3; ++c) delta[c] = load.force_n[c] - epoch.loads[match].force_n[c];
    }
    epoch.delta_index[epoch.delta_count] = load.surface_index;
    epoch.delta_norm[epoch.delta_count] = lazy_surface_norm3(delta) * (1.0 + 1e-6);  // float difference
    epoch.delta_norm_f[epoch.delta_count] = float_up(epoch.delta_norm[epoch.delta_count]);
    ++epoch.delta_count;
  }
  for (std::size_t j = 0; j < epoch.load_count; ++j) {
    const Load& load = epoch.loads[j];
    if (load.surface_index < 0) continue;
    bool present = j < load_count_ && loads_[j].node == load.node;
    for (std::size_t k = 0; k < load_count_ && !present; ++k) present = loads_[k].node == load.node;
    if (present) continue;
    epoch.delta_index[epoch.delta_count] = load.surface_index;
    epoch.delta_norm[epoch.delta_count] = lazy_surface_norm3(load.force_n);
    epoch.delta_norm_f[epoch.delta_count] = float_up(epoch.delta_norm[epoch.delta_count]);
    ++epoch.delta_count;
  }
}

void LazyModalSurface::epoch_cluster_pass(std::uint32_t index) noexcept {
  Epoch& epoch = epochs_[index];
  if (epoch.delta_step != step_) prepare_epoch(epoch);
  // Σ_j max|Φ_row,j| |Δq_j| and Σ_l max‖R_row,l‖ ‖ΔF_l‖ for eight clusters at a time (the
  // sums in registers), in float: each within (1 + (r + L + 1) u) of the exact sum of its
  // non-negative terms (every factor rounded up), hence the factor below.
  const double rounding = rounding_m(epoch);
  const double float_sum = 1.0 + static_cast<double>(active_modes_ + epoch.delta_count + 2) * 0x1p-23;
  const bool finite = std::isfinite(epoch.dq_norm);
  const std::size_t clusters = cluster_count();
  for (std::size_t base = 0; base < cluster_stride_; base += 8) {
    using Lanes = Eigen::Array4f;
    Lanes modes_low = Lanes::Zero();
    Lanes modes_high = Lanes::Zero();
    for (std::size_t j = 0; j < active_modes_; ++j) {
      const float d = epoch.abs_dq_f[j];
      const float* row = shape_max_t_.data() + j * cluster_stride_ + base;
      modes_low += Eigen::Map<const Lanes>(row) * d;
      modes_high += Eigen::Map<const Lanes>(row + 4) * d;
    }
    Lanes loads_low = Lanes::Zero();
    Lanes loads_high = Lanes::Zero();
    for (std::size_t i = 0; i < epoch.delta_count; ++i) {
      const float norm = epoch.delta_norm_f[i];
      const float* row = residual_max_t_.data() + static_cast<std::size_t>(epoch.delta_index[i]) * cluster_stride_ + base;
      loads_low += Eigen::Map<const Lanes>(row) * norm;
      loads_high += Eigen::Map<const Lanes>(row + 4) * norm;
    }
    float modes_sum[8];
    float loads_sum[8];
    Eigen::Map<Lanes>{modes_sum} = modes_low;
    Eigen::Map<Lanes>{modes_sum + 4} = modes_high;
    Eigen::Map<Lanes>{loads_sum} = loads_low;
    Eigen::Map<Lanes>{loads_sum + 4} = loads_high;
    for (std::size_t k = 0; k < 8 && base + k < clusters; ++k) {
      const std::size_t c = base + k;
      if (cluster_epoch_[c] != index) continue;
      mode_sum_[c] = static_cast<double>(modes_sum[k]) * float_sum;
      load_part_[c] = static_cast<double>(loads_sum[k]) * float_sum;
      const double modes = std::min(row_norm_max_[c] * epoch.dq_norm, mode_sum_[c]);
      bound_[c] = finite ? used_m_[c] + modes + load_part_[c] + rounding : std::numeric_limits<double>::quiet_NaN();
    }
  }
}

double LazyModalSurface::rounding_m(const Epoch& epoch) const noexcept {
  const double terms = static_cast<double>(active_modes_) +
                       3.0 * static_cast<double>(std::max(load_count_, epoch.load_count)) + 4.0;
  constexpr double kUnitRoundoff = 0x1p-24;
  return 2.0 * terms * kUnitRoundoff * (magnitude_ + epoch.magnitude);  // γ_m ≤ 2mu, twice
}

double LazyModalSurface::epoch_bound(const Epoch& epoch) const noexcept {
  // The pass's bound with the maxima over every cluster: a bound for each of its clusters.
  if (!std::isfinite(epoch.dq_norm)) return std::numeric_limits<double>::quiet_NaN();
  double per_mode = 0.0;
  for (std::size_t j = 0; j < active_modes_; ++j) per_mode += all_shape_max_[j] * epoch.abs_dq[j];
  double bound = std::min(all_row_norm_max_ * epoch.dq_norm, per_mode);
  for (std::size_t k = 0; k < epoch.delta_count; ++k) {
    bound += all_residual_max_[static_cast<std::size_t>(epoch.delta_index[k])] * epoch.delta_norm[k];
  }
  return epoch.max_used_m + bound + rounding_m(epoch);
}

std::uint32_t LazyModalSurface::take_snapshot_epoch() noexcept {
  // Epoch 0 is the last full refresh's (most clusters, far from any load, stay there); the
  // others are a ring of the states where clusters were checked.
  const auto ring = static_cast<std::uint32_t>(epochs_.size() - 1);
  const std::uint32_t slot = latest_epoch_ % ring + 1;
  Epoch& epoch = epochs_[slot];
  if (epoch.users > 0) {
    // Its clusters move to this state: their bound of this step bounds their distance now.
    for (std::size_t c = 0; c < cluster_count(); ++c) {
      if (cluster_epoch_[c] == slot) used_m_[c] = bound_[c];
    }
  }
  std::copy(modes_.begin(), modes_.end(), epoch.modes.begin());
  std::copy(loads_.begin(), loads_.begin() + static_cast<std::ptrdiff_t>(load_count_), epoch.loads.begin());
  epoch.load_count = load_count_;
  epoch.magnitude = magnitude_;
  epoch.delta_step = 0;
  latest_epoch_ = slot;
  return slot;
}

void LazyModalSurface::anchor(std::size_t cluster, std::uint32_t epoch, double deviation) noexcept {
  --epochs_[cluster_epoch_[cluster]].users;
  cluster_epoch_[cluster] = epoch;
  ++epochs_[epoch].users;
  used_m_[cluster] = deviation;
}

void LazyModalSurface::update_max_used() noexcept {
  for (Epoch& epoch : epochs_) epoch.max_used_m = 0.0;
  for (std::size_t c = 0; c < cluster_count(); ++c) {
    Epoch& epoch = epochs_[cluster_epoch_[c]];
    epoch.max_used_m = std::max(epoch.max_used_m, used_m_[c]);
  }
}

float LazyModalSurface::cluster_deviation(std::size_t cluster) const noexcept {
  // As TriangleBvh::refit compares: the largest |now − reference| over the coordinates, in float.
  const std::span<const float> reference = surface_->grid->reference_positions();
  float deviation = 0.0F;
  for (std::uint32_t k = cluster_start_[cluster]; k < cluster_start_[cluster + 1]; ++k) {
    const std::size_t base = 3 * static_cast<std::size_t>(cluster_nodes_[k]);
    for (std::size_t c = 0; c < 3; ++c) {
      const float d = std::abs(surface_->deformed[base + c] - reference[base + c]);
      if (!std::isfinite(d)) return std::numeric_limits<float>::quiet_NaN();
      deviation = std::max(deviation, d);
    }
  }
  return deviation;
}

bool LazyModalSurface::begin(ContactSurface& surface, const model::ModalModel& modal) noexcept {
  surface_ = &surface;
  modal_ = &modal;
  surface.lazy = this;
  ++step_;
  // The snapshot: q in float (as ModalModel::reconstruct rounds it) and the loads of the step.
  const std::span<const double> q = modal.modal_displacement();
  for (std::size_t i = 0; i < active_modes_ && i < q.size(); ++i) modes_[i] = static_cast<float>(q[i]);
  load_count_ = 0;
  if (static_correction_) {
    const std::size_t count = std::min(modal.stepped_load_count(), loads_.size());
    for (std::size_t k = 0; k < count; ++k) {
      Load& load = loads_[load_count_++];
      load.node = modal.stepped_load_node(k);
      load.surface_index = load.node < node_count_ ? surface_index_[load.node] : -1;
      const Eigen::Vector3f force = modal.stepped_load_force(k);
      for (int c = 0; c < 3; ++c) load.force_n[c] = force[c];
    }
  }
  const std::size_t clusters = cluster_count();
  if (lazy_allowed_ && reference_valid_ && surface.grid && surface.grid->ready()) {
    magnitude_ = state_magnitude(modes_, loads_.first(load_count_));
    budget_m_ = 0.999 * static_cast<double>(surface.grid_slack_m);
    // Each reference state's bound over all its clusters first (cheap); per cluster only
    // for the states where that is beyond the budget.
    bool all_within = true;
    for (Epoch& epoch : epochs_) {
      if (epoch.users == 0) continue;
      prepare_epoch(epoch);
      epoch.bound_m = epoch_bound(epoch);
      all_within = all_within && epoch.bound_m <= budget_m_;
    }
    // The last step computed every vertex (1 kHz held contact) and the common bound is beyond
    // the budget: most clusters would be checked again, so all of them are computed without
    // bounding them one by one first.
    bool all = !all_within && all_last_ && kAllAfterAll;
    std::size_t checked = 0;
    if (!all) {
      for (std::uint32_t e = 0; e < epochs_.size(); ++e) {
        // A state whose common bound is beyond the budget: its clusters one by one (in one pass).
        if (!(epochs_[e].bound_m <= budget_m_) && epochs_[e].users > 0) epoch_cluster_pass(e);
      }
      for (std::size_t c = 0; c < clusters; ++c) {
        const Epoch& epoch = epochs_[cluster_epoch_[c]];
        if (epoch.bound_m <= budget_m_) bound_[c] = epoch.bound_m;
        if (!(bound_[c] <= budget_m_)) {  // NaN too
          // Beyond the pass's bound: the tighter bound about the cluster's mean rows first.
          const double refined = refined_bound(c);
          if (refined <= budget_m_) {
            bound_[c] = std::min(bound_[c], refined);
            ++refined_clusters_;
            continue;
          }
          checked_[checked++] = static_cast<std::uint32_t>(c);
        }
      }
      // The clusters beyond the budget: their vertices exactly, compared as the refit compares
      // (the full path below does not compute them again).
      std::size_t checked_nodes = 0;
      for (std::size_t k = 0; k < checked; ++k) checked_nodes += cluster_start_[checked_[k] + 1] - cluster_start_[checked_[k]];
      // More than a fifth of the surface to check: all of it (a vertex checked alone sums its
      // static correction from scattered columns of R and costs ~3 times one of the fused
      // whole-surface pass; measured on cbd at 1 kHz, a fifth did slightly better than a third).
      all = 5 * checked_nodes > node_count_;
    }
    all_last_ = all;
    if (all) {
      // Every vertex the full path's way (contiguous rows, the static correction over the whole
      // surface at once), every cluster compared exactly; none beyond the slack → no refit (the
      // full path's refit would skip too) and this state is every cluster's reference with its
      // exact deviation, as after a full step that did not refit.
      compute_remaining();
      const bool none_beyond = all_cluster_deviations(surface.grid_slack_m);
      // This step's bound of each cluster: its exact deviation (rounded up: the float
      // difference may have rounded down); NaN when not finite.
      float within = 0.0F;
      for (std::size_t c = 0; c < clusters; ++c) {
        bound_[c] = static_cast<double>(std::nextafter(checked_deviation_[c], std::numeric_limits<float>::infinity()));
        within = std::max(within, checked_deviation_[c]);
      }
      if (none_beyond) {
        rebase_all();
        within_m_ = std::nextafter(within, std::numeric_limits<float>::infinity());
        ++checked_steps_;
        ++rebased_steps_;
        ++lazy_steps_;
        surface.surface_ready = true;
        return true;
      }
      all_last_ = false;
    } else {
      bool beyond = false;
      for (std::size_t k = 0; k < checked && !beyond; ++k) {
        const std::size_t c = checked_[k];
        compute_nodes(cluster_nodes_.data() + cluster_start_[c], cluster_start_[c + 1] - cluster_start_[c]);
        checked_deviation_[k] = cluster_deviation(c);
        beyond = !(checked_deviation_[k] <= surface.grid_slack_m);
      }
      if (!beyond) {
        if (checked > 0) {
          const std::uint32_t epoch = take_snapshot_epoch();
          for (std::size_t k = 0; k < checked; ++k) anchor(checked_[k], epoch, checked_deviation_[k]);
          update_max_used();
          ++checked_steps_;
        }
        // Every vertex is within this of the hierarchy's reference positions (per coordinate):
        // each cluster's bound, or a checked cluster's exact deviation; rounded up to float.
        // TriangleBvh::query_within / query_segment_within take the boxes as grown by it.
        double within = 0.0;
        for (std::size_t c = 0; c < clusters; ++c) {
          if (bound_[c] <= budget_m_) within = std::max(within, bound_[c]);
        }
        for (std::size_t k = 0; k < checked; ++k) within = std::max(within, static_cast<double>(checked_deviation_[k]));
        within_m_ = std::nextafter(static_cast<float>(within), std::numeric_limits<float>::infinity());
        ++lazy_steps_;
        surface.surface_ready = true;
        return true;
      }
    }
  }
  all_last_ = false;
  // The full path: every vertex, then the refit (which does the work only beyond the slack).
  ++full_steps_;
  within_m_ = -1.0F;  // unknown until the refit: the slack
  surface.surface_ready = false;
  if (lazy_allowed_) {
    compute_remaining();
  } else {
    full_failed_ = !modal.reconstruct(surface.deformed).is_ok();
    if (full_failed_) return false;
    for (std::size_t i = 0; i < surface.deformed.size(); ++i) surface.deformed[i] += surface.rest_positions[i];
    for (std::uint32_t node = 0; node < node_count_; ++node) stamp_[node] = step_;
  }
  full_failed_ = false;
  return false;
}

bool LazyModalSurface::finish_full(ContactSurface& surface) noexcept {
  reference_valid_ = false;
  if (full_failed_ || !surface.grid) return false;
  // The refit as the full path always did it: the work only when a coordinate moved beyond
  // the slack. Either way this state becomes every cluster's reference, with its distance
  // from the hierarchy's reference (0 after a refit that did the work).
  if (!surface.refit_grid()) return false;  // refused (non-finite): the hierarchy is empty
  within_m_ = surface.grid->last_deviation_m();  // these positions are the ones the refit saw
  if (!lazy_allowed_) return true;
  magnitude_ = state_magnitude(modes_, loads_.first(load_count_));
  restart_epochs();
  const bool refitted = surface.grid->last_deviation_m() == 0.0F;
  for (std::size_t c = 0; c < cluster_count(); ++c) {
    used_m_[c] = refitted ? 0.0 : static_cast<double>(cluster_deviation(c));
  }
  update_max_used();
  reference_valid_ = true;
  return true;
}

void LazyModalSurface::ensure_triangle(std::uint32_t triangle) noexcept {
  if (surface_ == nullptr) return;
  const std::size_t base = 3 * static_cast<std::size_t>(triangle);
  if (base + 2 >= surface_->triangles.size()) return;
  compute_nodes(surface_->triangles.data() + base, 3);
}

void LazyModalSurface::ensure_candidates(std::span<const std::uint32_t> ids) noexcept {
  if (surface_ == nullptr) return;
  // Every vertex of the candidates not yet current, then one kernel call over them.
  std::size_t pending = 0;
  for (const std::uint32_t id : ids) {
    const std::size_t base = 3 * static_cast<std::size_t>(id);
    if (base + 2 >= surface_->triangles.size()) continue;
    for (std::size_t c = 0; c < 3; ++c) {
      const std::uint32_t node = surface_->triangles[base + c];
      mark_pending(node, pending);
    }
  }
  compute_pending(pending);
}

core::Status LazyModalSurface::query(const model::Aabb& box, std::span<std::uint32_t> out_ids,
                                     std::size_t& out_count) noexcept {
  out_count = 0;
  if (surface_ == nullptr || !surface_->grid) return core::Status::ok();
  const core::Status status = surface_->grid->query_within(box, within_m_, out_ids, out_count);
  ensure_candidates(out_ids.first(std::min(out_count, out_ids.size())));
  return status;
}

core::Status LazyModalSurface::query_segment(const model::Vec3& p0, const model::Vec3& p1, float margin_m,
                                             std::span<std::uint32_t> out_ids,
                                             std::size_t& out_count) noexcept {
  out_count = 0;
  if (surface_ == nullptr || !surface_->grid) return core::Status::ok();
  // Boxes taken as grown by this step's bound on the motion instead of the slack (same
  // answer for every triangle within margin_m, fewer candidates and vertices to compute).
  const core::Status status =
      surface_->grid->query_segment_within(p0, p1, margin_m, within_m_, out_ids, out_count);
  ensure_candidates(out_ids.first(std::min(out_count, out_ids.size())));
  return status;
}

}  // namespace trainer::app
