// LazyModalSurface's whole-surface steps and its bound about the clusters' mean rows (issue 19,
// round 4; docs/collision.md "Round 4"): every vertex in one fused pass, every cluster compared
// exactly, the state rebased; the per-cluster pass is in lazy_modal_surface.cpp.
#include <algorithm>
#include <cmath>
#include <limits>

#include "trainer/app/contact_surface.hpp"
#include "trainer/app/lazy_modal_surface.hpp"

namespace trainer::app {

void LazyModalSurface::keep_warm(ContactSurface& surface) noexcept {
  const std::size_t lines = shapes_.size_bytes() / 64;
  const auto* base = reinterpret_cast<const char*>(shapes_.data());
  for (std::size_t k = 0; k < kWarmShapeLines && lines > 0; ++k) {
    __builtin_prefetch(base + 64 * warm_line_, 0, 2);
    warm_line_ = warm_line_ + 1 < lines ? warm_line_ + 1 : 0;
  }
  if (surface.grid) surface.grid->keep_warm(kWarmGridLines);
}

void LazyModalSurface::compute_all_fused() noexcept {
  // Every node in order, the surface nodes one run (node surface_first_node_ + k is surface
  // node k; the duct: nodes 16..335): Φ q by the model's kernel, then per coordinate the static
  // correction Σ_l R F summed from zero load by load, axis by axis (in registers, 32
  // coordinates at a time), + that, + rest: the float operations of the per-node path
  // (finish_node) and of the whole-surface axpys, in the same order, in one pass over the array
  // instead of one per load and axis. Off the surface: + rest.
  modal_->shape_rows(nullptr, node_count_, modes_.data(), surface_->deformed.data());
  const std::size_t size = 3 * static_cast<std::size_t>(node_count_);
  float* out = surface_->deformed.data();
  const float* rest = rest_.data();
  std::size_t terms = 0;
  const bool correction = static_correction_ && load_count_ > 0;
  if (correction) {
    const std::size_t stride = 3 * static_cast<std::size_t>(surface_count_);
    for (std::size_t k = 0; k < load_count_; ++k) {
      const Load& load = loads_[k];
      if (load.surface_index < 0) continue;
      for (std::size_t axis = 0; axis < 3; ++axis) {
        load_rows_[terms] = residual_.data() + (3 * static_cast<std::size_t>(load.surface_index) + axis) * stride;
        load_forces_[terms] = load.force_n[axis];
        ++terms;
      }
    }
  }
  const auto add_rest = [&](std::size_t from, std::size_t to) {
    if (to <= from) return;
    Eigen::Map<Eigen::ArrayXf>(out + from, static_cast<Eigen::Index>(to - from)) +=
        Eigen::Map<const Eigen::ArrayXf>(rest + from, static_cast<Eigen::Index>(to - from));
  };
  if (!correction) {
    add_rest(0, size);
    return;
  }
  const std::size_t first = 3 * static_cast<std::size_t>(surface_first_node_);
  const std::size_t last = first + 3 * static_cast<std::size_t>(surface_count_);
  add_rest(0, first);
  std::size_t i = first;
  // Eight packets (32 coordinates) at a time: eight independent sums, so the adds' latency is
  // hidden (each coordinate's own sum is the same, term by term from zero, as below).
  for (; i + 32 <= last; i += 32) {
    using Packet = Eigen::Array4f;
    Packet sum[8];
    for (Packet& packet : sum) packet = Packet::Zero();
    for (std::size_t t = 0; t < terms; ++t) {
      const float force = load_forces_[t];
      const float* row = load_rows_[t] + (i - first);
      for (std::size_t p = 0; p < 8; ++p) sum[p] = sum[p] + force * Eigen::Map<const Packet>(row + 4 * p);
    }
    for (std::size_t p = 0; p < 8; ++p) {
      Eigen::Map<Packet> value(out + i + 4 * p);
      value = (value + sum[p]) + Eigen::Map<const Packet>(rest + i + 4 * p);
    }
  }
  for (; i + 4 <= last; i += 4) {
    Eigen::Array4f sum = Eigen::Array4f::Zero();
    for (std::size_t t = 0; t < terms; ++t) {
      sum = sum + load_forces_[t] * Eigen::Map<const Eigen::Array4f>(load_rows_[t] + (i - first));
    }
    Eigen::Map<Eigen::Array4f> value(out + i);
    value = (value + sum) + Eigen::Map<const Eigen::Array4f>(rest + i);
  }
  for (; i < last; ++i) {
    float sum = 0.0F;
    for (std::size_t t = 0; t < terms; ++t) sum = sum + load_forces_[t] * load_rows_[t][i - first];
    out[i] = (out[i] + sum) + rest[i];
  }
  add_rest(last, size);
}

void LazyModalSurface::compute_remaining() noexcept {
  // Every vertex not computed yet this step (a check may have computed some).
  std::size_t pending = 0;
  for (std::uint32_t node = 0; node < node_count_; ++node) {
    if (stamp_[node] == step_) continue;
    stamp_[node] = step_;
    pending_[pending++] = node;
  }
  if (pending == 0) return;
  if (surface_run_ || !static_correction_) {
    // The fused pass over every vertex, the ones a check computed too: each gets the same bits
    // again (same kernel, same operations in the same order as finish_node), and one fused pass
    // costs less than the per-node path over the rest (which sums R's rows into full_residual_
    // first, then adds it node by node; on the cbd duct's full steps 5-41 of 336 vertices had
    // been computed by a check).
    compute_all_fused();
    return;
  }
  // With most of the surface to do, Σ_l R_{k,l} F_l for every surface node at once
  // (element by element in the same order as finish_node's per-node sum, so the values are
  // the same).
  if (static_correction_ && load_count_ > 0 && 2 * pending > node_count_) {
    const std::size_t stride = 3 * static_cast<std::size_t>(surface_count_);
    std::fill(full_residual_.begin(), full_residual_.end(), 0.0F);
    for (std::size_t k = 0; k < load_count_; ++k) {
      const Load& load = loads_[k];
      if (load.surface_index < 0) continue;
      for (std::size_t axis = 0; axis < 3; ++axis) {
        const float* row =
            residual_.data() + (3 * static_cast<std::size_t>(load.surface_index) + axis) * stride;
        // Element by element as finish_node's sum (and ModalModel::reconstruct's axpy).
        Eigen::Map<Eigen::VectorXf>(full_residual_.data(), static_cast<Eigen::Index>(stride)) +=
            load.force_n[axis] * Eigen::Map<const Eigen::VectorXf>(row, static_cast<Eigen::Index>(stride));
      }
    }
    full_residual_valid_ = true;
  }
  modal_->shape_rows(pending == node_count_ ? nullptr : pending_.data(), pending, modes_.data(),
                     surface_->deformed.data());
  for (std::size_t k = 0; k < pending; ++k) finish_node(pending_[k]);
  full_residual_valid_ = false;
}

bool LazyModalSurface::all_cluster_deviations(float slack_m) noexcept {
  const auto size = static_cast<Eigen::Index>(3 * static_cast<std::size_t>(node_count_));
  Eigen::Map<Eigen::ArrayXf> deviation(coordinate_deviation_.data(), size);
  deviation = (Eigen::Map<const Eigen::ArrayXf>(surface_->deformed.data(), size) -
               Eigen::Map<const Eigen::ArrayXf>(surface_->grid->reference_positions().data(), size))
                  .abs();
  // Not finite (a NaN or infinite coordinate, or deviations so large their sum overflows): the
  // full path, whose refit refuses it or refits. (allFinite() is a scalar loop; the sum is
  // vectorized.)
  if (!std::isfinite(deviation.sum())) {
    std::fill(checked_deviation_.begin(), checked_deviation_.begin() + static_cast<std::ptrdiff_t>(cluster_count()),
              std::numeric_limits<float>::quiet_NaN());
    return false;
  }
  bool within = true;
  for (std::size_t c = 0; c < cluster_count(); ++c) {
    float worst = 0.0F;
    for (std::uint32_t k = cluster_start_[c]; k < cluster_start_[c + 1]; ++k) {
      const float* d = coordinate_deviation_.data() + 3 * static_cast<std::size_t>(cluster_nodes_[k]);
      worst = std::max(worst, std::max(d[0], std::max(d[1], d[2])));
    }
    checked_deviation_[c] = worst;
    within = within && worst <= slack_m;
  }
  return within;
}

void LazyModalSurface::restart_epochs() noexcept {
  for (Epoch& epoch : epochs_) epoch.users = 0;
  latest_epoch_ = 0;
  Epoch& epoch = epochs_[0];
  std::copy(modes_.begin(), modes_.end(), epoch.modes.begin());
  std::copy(loads_.begin(), loads_.begin() + static_cast<std::ptrdiff_t>(load_count_), epoch.loads.begin());
  epoch.load_count = load_count_;
  epoch.magnitude = magnitude_;
  epoch.delta_step = 0;
  epoch.users = static_cast<std::uint32_t>(cluster_count());
  std::fill(cluster_epoch_.begin(), cluster_epoch_.begin() + static_cast<std::ptrdiff_t>(cluster_count()), 0U);
}

void LazyModalSurface::rebase_all() noexcept {
  restart_epochs();
  for (std::size_t c = 0; c < cluster_count(); ++c) used_m_[c] = static_cast<double>(checked_deviation_[c]);
  update_max_used();
}

double LazyModalSurface::refined_bound(std::size_t cluster) const noexcept {
  const Epoch& epoch = epochs_[cluster_epoch_[cluster]];
  if (!std::isfinite(epoch.dq_norm)) return std::numeric_limits<double>::quiet_NaN();
  // A row of the cluster: Φ_row Δq = Φ̄ Δq + (Φ_row − Φ̄) Δq. Φ̄ Δq in float with Δq rounded
  // to float: within 2^-24 Σ|Φ̄_j||Δq_j| of Φ̄ Δq for the rounding of Δq, and γ_{r+1} of the
  // same sum for the dot's own roundings; |Φ̄_j| ≤ max_row |Φ_row,j|, so mode_sum_ bounds
  // that sum (it is a covered float sum of the same terms, each rounded up).
  const auto active = static_cast<Eigen::Index>(active_modes_);
  const Eigen::Map<const Eigen::VectorXf> dq(epoch.dq_f.data(), active);
  const float* centre = centre_rows_.data() + 3 * cluster * active_modes_;
  double largest = 0.0;
  for (std::size_t axis = 0; axis < 3; ++axis) {
    const float dot = Eigen::Map<const Eigen::VectorXf>(centre + axis * active_modes_, active).dot(dq);
    largest = std::max(largest, std::abs(static_cast<double>(dot)));
  }
  const double dot_rounding = static_cast<double>(2 * active_modes_ + 6) * 0x1p-24 * mode_sum_[cluster];
  // The spread: Σ_j max|Φ_row,j − Φ̄_j| |Δq_j| in float (every factor rounded up, the sum's
  // rounding covered as in the pass), or the norms' product.
  float spread_sum = 0.0F;
  for (std::size_t j = 0; j < active_modes_; ++j) {
    spread_sum += spread_max_t_[j * cluster_stride_ + cluster] * epoch.abs_dq_f[j];
  }
  const double float_sum = 1.0 + static_cast<double>(active_modes_ + 2) * 0x1p-23;
  const double spread = std::min(spread_norm_max_[cluster] * epoch.dq_norm * (1.0 + 1e-12),
                                 static_cast<double>(spread_sum) * float_sum);
  return used_m_[cluster] + largest + dot_rounding + spread + load_part_[cluster] + rounding_m(epoch);
}

}  // namespace trainer::app
