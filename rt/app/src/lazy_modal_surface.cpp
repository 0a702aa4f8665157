#include "trainer/app/lazy_modal_surface.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "trainer/app/contact_surface.hpp"

namespace trainer::app {
namespace {

// Φ_node q for the three rows of a node (row-major, `stride` floats apart), each row summed
// exactly as Eigen 3.4's row-major GEMV sums a row in its multi-row loops (the path
// ModalModel::reconstruct takes): Eigen's own packets, pmadd over whole packets, predux, then
// the tail in order, added to a zeroed result. Inlined into both the lazy and the full path.
inline void lazy_surface_node_dot(const float* rows, std::size_t stride, const float* q,
                                  std::size_t n, float* out) noexcept {
  using Packet = Eigen::internal::packet_traits<float>::type;
  constexpr std::size_t kSize = static_cast<std::size_t>(Eigen::internal::packet_traits<float>::size);
  const float* row0 = rows;
  const float* row1 = rows + stride;
  const float* row2 = rows + 2 * stride;
  Packet c0 = Eigen::internal::pset1<Packet>(0.0F);
  Packet c1 = c0;
  Packet c2 = c0;
  std::size_t j = 0;
  for (; j + kSize <= n; j += kSize) {
    const Packet b = Eigen::internal::ploadu<Packet>(q + j);
    c0 = Eigen::internal::pmadd(Eigen::internal::ploadu<Packet>(row0 + j), b, c0);
    c1 = Eigen::internal::pmadd(Eigen::internal::ploadu<Packet>(row1 + j), b, c1);
    c2 = Eigen::internal::pmadd(Eigen::internal::ploadu<Packet>(row2 + j), b, c2);
  }
  float cc0 = Eigen::internal::predux(c0);
  float cc1 = Eigen::internal::predux(c1);
  float cc2 = Eigen::internal::predux(c2);
  for (; j < n; ++j) {
    cc0 += row0[j] * q[j];
    cc1 += row1[j] * q[j];
    cc2 += row2[j] * q[j];
  }
  out[0] = 0.0F + cc0;  // the GEMV adds into a zeroed result: −0 becomes +0 as there
  out[1] = 0.0F + cc1;
  out[2] = 0.0F + cc2;
}

double lazy_surface_norm3(const float (&v)[3]) noexcept {
  const double x = v[0];
  const double y = v[1];
  const double z = v[2];
  return std::sqrt(x * x + y * y + z * z);
}

}  // namespace

core::Expected<LazyModalSurface> LazyModalSurface::create(const model::ModalModelData& data,
                                                          const model::ModalModel& modal,
                                                          core::Arena& arena) {
  LazyModalSurface lazy;
  lazy.rest_ = data.rest_positions;
  lazy.mode_shapes_ = data.mode_shapes;
  lazy.node_count_ = data.node_count;
  lazy.stored_modes_ = data.mode_count;
  lazy.active_modes_ = modal.active_mode_count();
  lazy.static_correction_ = modal.static_correction();
  lazy.surface_count_ = static_cast<std::uint32_t>(data.surface_nodes.size());
  if (lazy.static_correction_) lazy.residual_ = data.residual_compliance;
  lazy.lazy_allowed_ = !(lazy.static_correction_ && lazy.active_modes_ < lazy.stored_modes_);
  const std::size_t n = data.node_count;
  const std::size_t r = lazy.stored_modes_;
  if (data.rest_positions.size() != 3 * n || data.mode_shapes.size() != 3 * n * r ||
      lazy.active_modes_ > r) {
    return core::make_error("lazy modal surface: model data sizes disagree");
  }
  auto index = arena.allocate_array<std::int32_t>(n, "lazy surface: surface index");
  if (!index) return std::move(index).error();
  std::fill(index->begin(), index->end(), -1);
  for (std::size_t k = 0; k < data.surface_nodes.size(); ++k) {
    if (data.surface_nodes[k] >= n) return core::make_error("lazy modal surface: surface node out of range");
    (*index)[data.surface_nodes[k]] = static_cast<std::int32_t>(k);
  }
  lazy.surface_index_ = index.value();

  auto column_norms = arena.allocate_array<double>(std::max<std::size_t>(r, 1), "lazy surface: mode maxima");
  if (!column_norms) return std::move(column_norms).error();
  std::fill(column_norms->begin(), column_norms->end(), 0.0);
  lazy.mode_column_max_ = column_norms.value();
  for (std::size_t node = 0; node < n; ++node) {
    for (std::size_t i = 0; i < lazy.active_modes_; ++i) {
      double column = 0.0;
      for (std::size_t axis = 0; axis < 3; ++axis) {
        const double value = data.mode_shapes[(3 * node + axis) * r + i];
        column += value * value;
      }
      lazy.mode_column_max_[i] = std::max(lazy.mode_column_max_[i], std::sqrt(column));
    }
    double squared = 0.0;
    for (std::size_t axis = 0; axis < 3; ++axis) {
      const float* row = data.mode_shapes.data() + (3 * node + axis) * r;
      for (std::size_t i = 0; i < lazy.active_modes_; ++i) {
        const double value = row[i];
        squared += value * value;
        lazy.max_shape_entry_ = std::max(lazy.max_shape_entry_, std::abs(value));
      }
      lazy.max_rest_abs_ =
          std::max(lazy.max_rest_abs_, std::abs(static_cast<double>(data.rest_positions[3 * node + axis])));
    }
    lazy.max_shape_norm_ = std::max(lazy.max_shape_norm_, std::sqrt(squared));
  }

  const std::size_t s = lazy.surface_count_;
  auto column_max = arena.allocate_array<double>(std::max<std::size_t>(s, 1), "lazy surface: residual maxima");
  if (!column_max) return std::move(column_max).error();
  std::fill(column_max->begin(), column_max->end(), 0.0);
  if (lazy.static_correction_) {
    if (lazy.residual_.size() != 9 * s * s) {
      return core::make_error("lazy modal surface: residual compliance is not 3s x 3s");
    }
    const std::size_t stride = 3 * s;
    for (std::size_t k = 0; k < s; ++k) {
      for (std::size_t l = 0; l < s; ++l) {
        double squared = 0.0;
        for (std::size_t a = 0; a < 3; ++a) {
          for (std::size_t b = 0; b < 3; ++b) {
            const double value = lazy.residual_[(3 * k + a) * stride + 3 * l + b];
            squared += value * value;
            lazy.max_residual_entry_ = std::max(lazy.max_residual_entry_, std::abs(value));
          }
        }
        (*column_max)[l] = std::max((*column_max)[l], std::sqrt(squared));
      }
    }
  }
  lazy.residual_column_max_ = column_max.value();

  const std::size_t modes = std::max<std::size_t>(lazy.active_modes_, 1);
  auto modes_now = arena.allocate_array<float>(modes, "lazy surface: modes");
  auto modes_ref = arena.allocate_array<float>(modes, "lazy surface: reference modes");
  auto loads_now = arena.allocate_array<Load>(model::ModalModel::kMaxLoadedNodes, "lazy surface: loads");
  auto loads_ref =
      arena.allocate_array<Load>(model::ModalModel::kMaxLoadedNodes, "lazy surface: reference loads");
  auto stamps = arena.allocate_array<std::uint64_t>(std::max<std::size_t>(n, 1), "lazy surface: stamps");
  auto full_residual =
      arena.allocate_array<float>(std::max<std::size_t>(3 * s, 1), "lazy surface: residual scratch");
  if (!full_residual) return std::move(full_residual).error();
  lazy.full_residual_ = full_residual.value();
  if (!modes_now) return std::move(modes_now).error();
  if (!modes_ref) return std::move(modes_ref).error();
  if (!loads_now) return std::move(loads_now).error();
  if (!loads_ref) return std::move(loads_ref).error();
  if (!stamps) return std::move(stamps).error();
  lazy.modes_ = modes_now.value();
  lazy.reference_modes_ = modes_ref.value();
  lazy.loads_ = loads_now.value();
  lazy.reference_loads_ = loads_ref.value();
  lazy.stamp_ = stamps.value();
  std::fill(lazy.modes_.begin(), lazy.modes_.end(), 0.0F);
  std::fill(lazy.reference_modes_.begin(), lazy.reference_modes_.end(), 0.0F);
  std::fill(lazy.stamp_.begin(), lazy.stamp_.end(), std::uint64_t{0});
  return lazy;
}

void LazyModalSurface::reconstruct_node(std::uint32_t node, float* out) const noexcept {
  const std::size_t base = 3 * static_cast<std::size_t>(node);
  float u[3];
  lazy_surface_node_dot(mode_shapes_.data() + base * stored_modes_, stored_modes_, modes_.data(),
                        active_modes_, u);
  const std::int32_t surface = surface_index_[node];
  if (full_residual_valid_) {
    if (surface >= 0) {
      for (std::size_t c = 0; c < 3; ++c) u[c] = u[c] + full_residual_[3 * static_cast<std::size_t>(surface) + c];
    }
  } else if (static_correction_ && surface >= 0 && load_count_ > 0) {
    // Σ_l R_{node,l} F_l summed as ModalModel::reconstruct does: loads in order, each load's
    // axes in order, from zero (R symmetric: row block l read at this node's columns).
    const std::size_t stride = 3 * static_cast<std::size_t>(surface_count_);
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
    for (std::size_t c = 0; c < 3; ++c) u[c] = u[c] + residual[c];
  }
  for (std::size_t c = 0; c < 3; ++c) out[c] = u[c] + rest_[base + c];
}

double LazyModalSurface::motion_bound() const noexcept {
  // ‖Φ_i Δq‖ ≤ ‖Φ_i‖_F ‖Δq‖₂ and ≤ Σ_j ‖φ_ij‖ |Δq_j|: the smaller of the two maxima.
  double squared = 0.0;
  double per_mode = 0.0;
  for (std::size_t i = 0; i < active_modes_; ++i) {
    const double d = static_cast<double>(modes_[i]) - static_cast<double>(reference_modes_[i]);
    squared += d * d;
    per_mode += mode_column_max_[i] * std::abs(d);
  }
  double bound = std::min(max_shape_norm_ * std::sqrt(squared), per_mode);
  if (std::isnan(squared) || std::isnan(per_mode)) return std::numeric_limits<double>::quiet_NaN();
  if (!static_correction_) return bound;
  // Σ over the nodes loaded now or at the reference of max_k ‖R_kl‖ ‖ΔF_l‖.
  for (std::size_t k = 0; k < load_count_; ++k) {
    const Load& load = loads_[k];
    if (load.surface_index < 0) continue;
    float delta[3] = {load.force_n[0], load.force_n[1], load.force_n[2]};
    for (std::size_t j = 0; j < reference_load_count_; ++j) {
      if (reference_loads_[j].node != load.node) continue;
      for (std::size_t c = 0; c < 3; ++c) delta[c] = load.force_n[c] - reference_loads_[j].force_n[c];
      break;
    }
    bound += residual_column_max_[static_cast<std::size_t>(load.surface_index)] *
             lazy_surface_norm3(delta) * (1.0 + 1e-6);  // the float difference's rounding
  }
  for (std::size_t j = 0; j < reference_load_count_; ++j) {
    const Load& load = reference_loads_[j];
    if (load.surface_index < 0) continue;
    bool present = false;
    for (std::size_t k = 0; k < load_count_ && !present; ++k) present = loads_[k].node == load.node;
    if (present) continue;
    bound += residual_column_max_[static_cast<std::size_t>(load.surface_index)] *
             lazy_surface_norm3(load.force_n);
  }
  return bound;
}

double LazyModalSurface::rounding_margin() const noexcept {
  // Each coordinate is a float sum of at most r + 3L + 2 terms whose magnitudes are bounded by
  // the sums below; its rounding error is within γ_m (m terms) of that magnitude, once for the
  // positions of the reference and once for these.
  double magnitude = max_rest_abs_;
  double modes_abs = 0.0;
  for (std::size_t i = 0; i < active_modes_; ++i) {
    modes_abs += std::max(std::abs(static_cast<double>(modes_[i])),
                          std::abs(static_cast<double>(reference_modes_[i])));
  }
  magnitude += max_shape_entry_ * modes_abs;
  double forces_abs = 0.0;
  for (std::size_t k = 0; k < load_count_; ++k) {
    for (const float f : loads_[k].force_n) forces_abs += std::abs(static_cast<double>(f));
  }
  for (std::size_t k = 0; k < reference_load_count_; ++k) {
    for (const float f : reference_loads_[k].force_n) forces_abs += std::abs(static_cast<double>(f));
  }
  magnitude += max_residual_entry_ * forces_abs;
  const double terms = static_cast<double>(active_modes_) +
                       3.0 * static_cast<double>(std::max(load_count_, reference_load_count_)) + 4.0;
  constexpr double kUnitRoundoff = 0x1p-24;
  return 2.0 * 2.0 * terms * kUnitRoundoff * magnitude;  // γ_m ≤ 2 m u here, twice
}

bool LazyModalSurface::begin(ContactSurface& surface, const model::ModalModel& modal) noexcept {
  surface_ = &surface;
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
  if (lazy_allowed_ && reference_valid_) {
    const double bound = motion_bound();
    const double rounding = rounding_margin();
    const double budget = 0.999 * static_cast<double>(surface.grid_slack_m) - used_slack_m_ - rounding;
    last_bound_m_ = bound;
    last_budget_m_ = budget;
    if (bound <= budget) {  // false for a non-finite bound: the full path refuses it
      // Every vertex is within this of the hierarchy's reference (rounded up to float).
      within_m_ = std::nextafter(static_cast<float>(used_slack_m_ + bound + rounding), INFINITY);
      ++lazy_steps_;
      surface.surface_ready = true;
      return true;
    }
  }
  // The full path: every vertex, then the refit (which may still find nothing beyond slack).
  ++full_steps_;
  within_m_ = -1.0F;
  surface.surface_ready = false;
  if (lazy_allowed_) {
    // Σ_l R_{k,l} F_l for every surface node at once (element by element in the same order as
    // reconstruct_node's per-node sum, so the values are the same), then every node.
    if (static_correction_ && load_count_ > 0) {
      const std::size_t stride = 3 * static_cast<std::size_t>(surface_count_);
      std::fill(full_residual_.begin(), full_residual_.end(), 0.0F);
      for (std::size_t k = 0; k < load_count_; ++k) {
        const Load& load = loads_[k];
        if (load.surface_index < 0) continue;
        for (std::size_t axis = 0; axis < 3; ++axis) {
          const float* row =
              residual_.data() + (3 * static_cast<std::size_t>(load.surface_index) + axis) * stride;
          // Element by element as reconstruct_node's sum (and ModalModel::reconstruct's axpy).
          Eigen::Map<Eigen::VectorXf>(full_residual_.data(), static_cast<Eigen::Index>(stride)) +=
              load.force_n[axis] * Eigen::Map<const Eigen::VectorXf>(row, static_cast<Eigen::Index>(stride));
        }
      }
      full_residual_valid_ = true;
    }
    for (std::uint32_t node = 0; node < node_count_; ++node) {
      reconstruct_node(node, surface.deformed.data() + 3 * static_cast<std::size_t>(node));
      stamp_[node] = step_;
    }
    full_residual_valid_ = false;
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
  // the slack. Either way these positions become the bound's reference, with the slack the
  // hierarchy has left for them (slack − their distance from its own reference).
  if (!surface.refit_grid()) return false;  // refused (non-finite): the hierarchy is empty
  used_slack_m_ = static_cast<double>(surface.grid->last_deviation_m());
  within_m_ = surface.grid->last_deviation_m();  // these positions are the ones the refit saw
  std::copy(modes_.begin(), modes_.end(), reference_modes_.begin());
  std::copy(loads_.begin(), loads_.begin() + static_cast<std::ptrdiff_t>(load_count_),
            reference_loads_.begin());
  reference_load_count_ = load_count_;
  reference_valid_ = lazy_allowed_;
  return true;
}

void LazyModalSurface::ensure_vertex(std::uint32_t node) noexcept {
  if (node >= node_count_ || stamp_[node] == step_) return;
  reconstruct_node(node, surface_->deformed.data() + 3 * static_cast<std::size_t>(node));
  stamp_[node] = step_;
  ++vertices_computed_;
}

void LazyModalSurface::ensure_triangle(std::uint32_t triangle) noexcept {
  if (surface_ == nullptr) return;
  const std::size_t base = 3 * static_cast<std::size_t>(triangle);
  if (base + 2 >= surface_->triangles.size()) return;
  for (std::size_t c = 0; c < 3; ++c) ensure_vertex(surface_->triangles[base + c]);
}

void LazyModalSurface::ensure_candidates(std::span<const std::uint32_t> ids) noexcept {
  for (const std::uint32_t id : ids) ensure_triangle(id);
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
  const core::Status status = surface_->grid->query_segment_within(p0, p1, margin_m, within_m_, out_ids, out_count);
  ensure_candidates(out_ids.first(std::min(out_count, out_ids.size())));
  return status;
}

}  // namespace trainer::app
