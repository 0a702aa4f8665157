// Private to model/runtime: the member definitions of BasicModalModel<Scalar> (setup checks,
// Newmark per mode, contact solve, reconstruction), included by the two files that instantiate
// it: modal_model.cpp (float, model images) and modal_model_double.cpp (double, offline
// precision measurements). One instantiation per translation unit keeps the compiler's inlining
// choices for the float model what they were when it was the only one (GCC 12, -O3: the float
// step, add_node_force, displacement and reconstruct compile to the same instructions as the
// non-template model did; with both instantiations in one file, two Eigen reductions also
// moved out of line in the float solve_imposed).
#pragma once

#include "trainer/model/modal_model.hpp"

#include <cmath>
#include <limits>
#include <string>

#include <Eigen/Cholesky>

namespace trainer::model {
namespace detail {

inline constexpr std::size_t kNotFound = static_cast<std::size_t>(-1);
inline constexpr int kMaxContactRows = 3 * static_cast<int>(BasicModalModel<float>::kMaxContacts);
// A contact compliance whose smallest LDLᵀ pivot is below this fraction of the largest is
// treated as singular: with float data (relative error ~1e-7), below ~1e-8 the solved forces
// would be rounding noise (e.g. a fixed node, or nearly dependent shape rows). The double model
// keeps the same bound so that both precisions accept and refuse the same contact sets (a
// comparison of the two then times and measures the same work).
inline constexpr double kMinPivotRatio = 1e-8;
inline constexpr std::uint32_t kNoSlot = static_cast<std::uint32_t>(-1);

using ContactVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxContactRows, 1>;

template <typename Scalar>
bool all_finite(std::span<const Scalar> values) noexcept {
  for (const Scalar value : values) {
    if (!std::isfinite(value)) return false;
  }
  return true;
}

inline std::string size_error(const char* what, std::size_t actual, std::size_t expected,
                              const std::string& expected_from) {
  return std::string("modal model: ") + what + " has " + std::to_string(actual) +
         " values, expected " + std::to_string(expected) + " (" + expected_from + ")";
}

template <class T>
core::Expected<std::span<T>> carve(core::Arena& arena, std::size_t count, std::string_view what) {
  auto span = arena.allocate_array<T>(count, what);
  if (!span) {
    return core::make_error("modal model: arena exhausted: " + span.error().message);
  }
  return span.value();
}

}  // namespace detail

template <typename Scalar>
core::Expected<BasicModalModel<Scalar>> BasicModalModel<Scalar>::create(
    const BasicModalModelData<Scalar>& data, core::Arena& arena,
    const BasicModalSettings<Scalar>& settings) {
  const std::size_t n = data.node_count;
  const std::size_t r = data.mode_count;
  if (n == 0 || r == 0) {
    return core::make_error("modal model: node_count = " + std::to_string(n) +
                            ", mode_count = " + std::to_string(r) + ": expected both ≥ 1");
  }
  const std::string sizes = std::to_string(n) + " nodes, " + std::to_string(r) + " modes";
  if (data.rest_positions.size() != 3 * n) {
    return core::make_error(detail::size_error("rest_positions", data.rest_positions.size(), 3 * n,
                                               "3 × node_count, " + sizes));
  }
  if (data.mode_shapes.size() != 3 * n * r) {
    return core::make_error(detail::size_error("mode_shapes", data.mode_shapes.size(), 3 * n * r,
                                               "3 × node_count × mode_count, " + sizes));
  }
  if (data.omega_squared.size() != r) {
    return core::make_error(
        detail::size_error("omega_squared", data.omega_squared.size(), r, "mode_count, " + sizes));
  }
  if (data.modal_damping.size() != r) {
    return core::make_error(
        detail::size_error("modal_damping", data.modal_damping.size(), r, "mode_count, " + sizes));
  }
  if (!detail::all_finite(data.rest_positions) || !detail::all_finite(data.mode_shapes) ||
      !detail::all_finite(data.residual_compliance)) {
    return core::make_error(
        "modal model: rest_positions, mode_shapes or residual_compliance has a non-finite value");
  }
  for (std::size_t i = 0; i < r; ++i) {
    if (!(data.omega_squared[i] > Scalar{0}) || !std::isfinite(data.omega_squared[i])) {
      return core::make_error("modal model: omega_squared[" + std::to_string(i) +
                              "] = " + std::to_string(data.omega_squared[i]) +
                              " rad²/s², expected finite > 0");
    }
    if (!(data.modal_damping[i] >= Scalar{0}) || !std::isfinite(data.modal_damping[i])) {
      return core::make_error("modal model: modal_damping[" + std::to_string(i) + "] = " +
                              std::to_string(data.modal_damping[i]) + " 1/s, expected finite ≥ 0");
    }
  }
  const std::size_t s = data.surface_nodes.size();
  if (!data.residual_compliance.empty() && data.residual_compliance.size() != 9 * s * s) {
    return core::make_error(detail::size_error(
        "residual_compliance", data.residual_compliance.size(), 9 * s * s,
        "(3 × surface node count)², " + std::to_string(s) + " surface nodes; or empty"));
  }
  if (settings.static_correction && (s == 0 || data.residual_compliance.empty())) {
    return core::make_error(
        "modal model: static_correction is on but the model has no residual compliance (" +
        std::to_string(s) + " surface nodes, " + std::to_string(data.residual_compliance.size()) +
        " compliance values)");
  }
  if (!(settings.time_step_s > Scalar{0}) || !std::isfinite(settings.time_step_s)) {
    return core::make_error("modal model: time_step_s = " + std::to_string(settings.time_step_s) +
                            ", expected finite > 0");
  }
  if (settings.active_modes > r) {
    return core::make_error("modal model: active_modes = " + std::to_string(settings.active_modes) +
                            ", expected 0 (all) .. " + std::to_string(r) + " stored modes");
  }

  BasicModalModel model;
  model.node_count_ = data.node_count;
  model.stored_modes_ = data.mode_count;
  model.active_modes_ = settings.active_modes == 0 ? data.mode_count : settings.active_modes;
  model.surface_count_ = static_cast<std::uint32_t>(s);
  model.time_step_s_ = settings.time_step_s;
  model.static_correction_ = settings.static_correction;
  model.rest_positions_ = data.rest_positions;
  model.mode_shapes_ = data.mode_shapes;
  model.residual_compliance_ = data.residual_compliance;

  auto surface_index = detail::carve<std::int32_t>(arena, n, "modal model surface index");
  if (!surface_index) return std::move(surface_index).error();
  for (auto& index : surface_index.value()) index = -1;
  for (std::size_t k = 0; k < s; ++k) {
    const std::uint32_t node = data.surface_nodes[k];
    if (node >= n) {
      return core::make_error("modal model: surface_nodes[" + std::to_string(k) +
                              "] = " + std::to_string(node) + ", expected < node_count " +
                              std::to_string(n));
    }
    if (surface_index.value()[node] >= 0) {
      return core::make_error(
          "modal model: surface node " + std::to_string(node) + " listed twice (surface_nodes[" +
          std::to_string(surface_index.value()[node]) + "] and [" + std::to_string(k) + "])");
    }
    surface_index.value()[node] = static_cast<std::int32_t>(k);
  }
  model.surface_index_ = surface_index.value();

  const std::size_t active = model.active_modes_;
  std::span<double>* per_mode[] = {&model.omega_squared_,
                                   &model.a0_,
                                   &model.a2_,
                                   &model.inverse_k_hat_,
                                   &model.x_,
                                   &model.v_,
                                   &model.a_,
                                   &model.modal_force_,
                                   &model.predicted_};
  for (std::span<double>* target : per_mode) {
    auto span = detail::carve<double>(arena, active, "modal model per-mode state");
    if (!span) return std::move(span).error();
    *target = span.value();
  }
  if (model.static_correction_) {
    const std::size_t inactive = model.stored_modes_ - active;
    auto inverse = detail::carve<double>(arena, inactive, "modal model inactive-mode flexibility");
    if (!inverse) return std::move(inverse).error();
    model.inactive_inverse_omega_squared_ = inverse.value();
    for (std::size_t j = 0; j < inactive; ++j) {
      const auto omega_squared = static_cast<double>(data.omega_squared[active + j]);
      if (!(omega_squared > 0.0)) {
        return core::make_error(
            "modal model: omega_squared[" + std::to_string(active + j) +
            "] = " + std::to_string(omega_squared) +
            ", expected > 0 (a free rigid-body mode has no static flexibility)");
      }
      model.inactive_inverse_omega_squared_[j] = 1.0 / omega_squared;
    }
  }
  auto modes_scalar = detail::carve<Scalar>(arena, active, "modal model reconstruct scratch");
  if (!modes_scalar) return std::move(modes_scalar).error();
  model.reconstruct_modes_ = modes_scalar.value();
  if (model.static_correction_) {
    auto residual = detail::carve<Scalar>(arena, 3 * static_cast<std::size_t>(model.surface_count_),
                                          "modal model reconstruct residual scratch");
    if (!residual) return std::move(residual).error();
    model.reconstruct_residual_ = residual.value();
  }
  auto pending = detail::carve<NodeLoad>(arena, kMaxLoadedNodes, "modal model pending loads");
  if (!pending) return std::move(pending).error();
  model.pending_loads_ = pending.value();
  auto stepped = detail::carve<NodeLoad>(arena, kMaxLoadedNodes, "modal model stepped loads");
  if (!stepped) return std::move(stepped).error();
  model.stepped_loads_ = stepped.value();
  auto cache = arena.create_object<ContactCache>("modal model contact cache");
  if (!cache) return core::make_error("modal model: arena exhausted: " + cache.error().message);
  model.contact_cache_ = cache.value();
  model.contact_cache_->slot_count = 0;
  model.residual_symmetric_ = true;
  const std::size_t residual_rows = 3 * s;
  for (std::size_t row = 0;
       row < residual_rows && !data.residual_compliance.empty() && model.residual_symmetric_;
       ++row) {
    for (std::size_t column = row + 1; column < residual_rows; ++column) {
      if (data.residual_compliance[row * residual_rows + column] !=
          data.residual_compliance[column * residual_rows + row]) {
        model.residual_symmetric_ = false;
        break;
      }
    }
  }

  // Newmark constants per mode (METHODS.md §1, Appendix B corrected), in double.
  const double dt = settings.time_step_s;
  for (std::size_t i = 0; i < active; ++i) {
    const double alpha = data.modal_damping[i];
    model.omega_squared_[i] = data.omega_squared[i];
    model.a0_[i] = (4.0 + 2.0 * alpha * dt) / (dt * dt);
    model.a2_[i] = 4.0 / dt + alpha;
    model.inverse_k_hat_[i] = 1.0 / (model.omega_squared_[i] + model.a0_[i]);
  }
  model.reset();
  return model;
}

template <typename Scalar>
void BasicModalModel<Scalar>::reset() noexcept {
  for (std::size_t i = 0; i < active_modes_; ++i) {
    x_[i] = 0.0;
    v_[i] = 0.0;
    a_[i] = 0.0;
  }
  pending_count_ = 0;
  stepped_count_ = 0;
  projected_count_ = 0;
  ++state_epoch_;  // the free responses cached by the contact solve belong to the old state
}

template <typename Scalar>
std::size_t BasicModalModel<Scalar>::find_pending(std::uint32_t node) const noexcept {
  for (std::size_t l = 0; l < pending_count_; ++l) {
    if (pending_loads_[l].node == node) return l;
  }
  return detail::kNotFound;
}

template <typename Scalar>
core::Status BasicModalModel<Scalar>::add_node_force(std::uint32_t node,
                                                     const Vector3& force_n) noexcept {
  return add_force(node, force_n.template cast<double>());
}

template <typename Scalar>
core::Status BasicModalModel<Scalar>::add_force(std::uint32_t node,
                                                const Eigen::Vector3d& force_n) noexcept {
  if (node >= node_count_) return {core::StatusCode::invalid_argument, "modal model: unknown node"};
  if (!force_n.allFinite())
    return {core::StatusCode::numeric_error, "modal model: non-finite force"};
  const std::int32_t surface = surface_index_[node];
  if (static_correction_ && surface < 0) {
    return {core::StatusCode::invalid_argument,
            "modal model: force on a non-surface node with static correction on"};
  }
  std::size_t slot = find_pending(node);
  if (slot == detail::kNotFound) {
    if (pending_count_ == kMaxLoadedNodes) {
      return {core::StatusCode::capacity_exceeded, "modal model: too many loaded nodes"};
    }
    slot = pending_count_++;
    pending_loads_[slot] = NodeLoad{node, surface, {0.0, 0.0, 0.0}};
  } else if (slot < projected_count_) {
    projected_count_ = 0;  // a projected load changes: project them all again, in order
  }
  for (int axis = 0; axis < 3; ++axis) pending_loads_[slot].force_n[axis] += force_n[axis];
  return core::Status::ok();
}

template <typename Scalar>
void BasicModalModel<Scalar>::clear_forces() noexcept {
  pending_count_ = 0;
  projected_count_ = 0;
}

template <typename Scalar>
void BasicModalModel<Scalar>::project_pending_forces() noexcept {
  const std::size_t r = active_modes_;
  if (projected_count_ == 0) {
    for (std::size_t i = 0; i < r; ++i) modal_force_[i] = 0.0;
  }
  for (std::size_t l = projected_count_; l < pending_count_; ++l) {
    const NodeLoad& load = pending_loads_[l];
    for (int axis = 0; axis < 3; ++axis) {
      const double force = load.force_n[axis];
      if (force == 0.0) continue;
      const Scalar* row = shape_row(load.node, axis);
      for (std::size_t i = 0; i < r; ++i) modal_force_[i] += static_cast<double>(row[i]) * force;
    }
  }
  projected_count_ = pending_count_;
}

// Average-acceleration Newmark (γ = 1/2, β = 1/4) for ẍ + α ẋ + ω² x = f, per mode:
//   x⁺ = x + Δt v + Δt²/4 (a + a⁺)  ⇒  a⁺ = 4/Δt² (x⁺ − x) − 4/Δt v − a
//   v⁺ = v + Δt/2 (a + a⁺)          ⇒  v⁺ = 2/Δt (x⁺ − x) − v
// Equilibrium at the end of the step, a⁺ + α v⁺ + ω² x⁺ = f⁺, with both substituted:
//   (ω² + 4/Δt² + 2α/Δt) x⁺ = f⁺ + (4/Δt² + 2α/Δt) x + (4/Δt + α) v + a,
// i.e. k̂ = ω² + a0 with a0 = (4 + 2αΔt)/Δt², a2 = 4/Δt + α, f̂ = f⁺ + a0 x + a2 v + a and
// x⁺ = f̂/k̂ — the corrected Appendix B of METHODS.md §1 (the runtime test checks this
// scheme's period elongation and energy conservation against the closed forms).
template <typename Scalar>
core::Status BasicModalModel<Scalar>::step() noexcept {
  project_pending_forces();
  const double dt = time_step_s_;
  const double four_over_dt_squared = 4.0 / (dt * dt);
  const double four_over_dt = 4.0 / dt;
  const double half_dt = 0.5 * dt;
  bool finite = true;
  for (std::size_t i = 0; i < active_modes_; ++i) {
    const double effective_force = modal_force_[i] + a0_[i] * x_[i] + a2_[i] * v_[i] + a_[i];
    const double next = effective_force * inverse_k_hat_[i];
    const double next_acceleration =
        four_over_dt_squared * (next - x_[i]) - four_over_dt * v_[i] - a_[i];
    v_[i] += half_dt * (a_[i] + next_acceleration);
    a_[i] = next_acceleration;
    x_[i] = next;
    finite = finite && std::isfinite(next) && std::isfinite(v_[i]);
  }
  if (!finite) {
    reset();
    return {core::StatusCode::numeric_error, "modal model: state became non-finite; reset to rest"};
  }
  for (std::size_t l = 0; l < pending_count_; ++l) stepped_loads_[l] = pending_loads_[l];
  stepped_count_ = pending_count_;
  ++state_epoch_;
  return core::Status::ok();
}

template <typename Scalar>
const Scalar* BasicModalModel<Scalar>::compliance_block(
    std::int32_t row_surface, std::int32_t column_surface) const noexcept {
  const std::size_t stride = 3 * static_cast<std::size_t>(surface_count_);
  return residual_compliance_.data() + 3 * static_cast<std::size_t>(row_surface) * stride +
         3 * static_cast<std::size_t>(column_surface);
}

template <typename Scalar>
double BasicModalModel<Scalar>::residual_entry(std::uint32_t node_k, int axis_k,
                                               std::uint32_t node_l, int axis_l) const noexcept {
  const std::size_t stride = 3 * static_cast<std::size_t>(surface_count_);
  double value = static_cast<double>(compliance_block(
      surface_index_[node_k], surface_index_[node_l])[static_cast<std::size_t>(axis_k) * stride +
                                                      static_cast<std::size_t>(axis_l)]);
  const Scalar* shape_k = shape_row(node_k, axis_k);
  const Scalar* shape_l = shape_row(node_l, axis_l);
  for (std::size_t j = 0; j < inactive_inverse_omega_squared_.size(); ++j) {
    const std::size_t i = active_modes_ + j;
    value += static_cast<double>(shape_k[i]) * static_cast<double>(shape_l[i]) *
             inactive_inverse_omega_squared_[j];
  }
  return value;
}

template <typename Scalar>
Eigen::Vector3d BasicModalModel<Scalar>::static_response(
    std::uint32_t node, std::span<const NodeLoad> loads) const noexcept {
  Eigen::Vector3d response = Eigen::Vector3d::Zero();
  if (!static_correction_ || surface_index_[node] < 0) return response;
  for (const NodeLoad& load : loads) {
    if (load.surface_index < 0) continue;
    for (int row = 0; row < 3; ++row) {
      for (int column = 0; column < 3; ++column) {
        response[row] += residual_entry(node, row, load.node, column) * load.force_n[column];
      }
    }
  }
  return response;
}

template <typename Scalar>
typename BasicModalModel<Scalar>::Vector3 BasicModalModel<Scalar>::displacement(
    std::uint32_t node) const noexcept {
  if (node >= node_count_) return Vector3::Zero();
  Eigen::Vector3d result = static_response(node, {stepped_loads_.data(), stepped_count_});
  for (int axis = 0; axis < 3; ++axis) {
    const Scalar* row = shape_row(node, axis);
    double sum = 0.0;
    for (std::size_t i = 0; i < active_modes_; ++i) sum += static_cast<double>(row[i]) * x_[i];
    result[axis] += sum;
  }
  return result.cast<Scalar>();
}

template <typename Scalar>
typename BasicModalModel<Scalar>::Vector3 BasicModalModel<Scalar>::rest_position(
    std::uint32_t node) const noexcept {
  if (node >= node_count_) return Vector3::Zero();
  const std::size_t base = 3 * static_cast<std::size_t>(node);
  return {rest_positions_[base], rest_positions_[base + 1], rest_positions_[base + 2]};
}

// The nine sums run side by side over the modes (nine independent dependency chains instead of
// one at a time: the sums are latency-bound), each in its own mode order, so every entry is
// the same sequence of roundings as a sum computed alone.
template <typename Scalar>
void BasicModalModel<Scalar>::modal_compliance_block(std::uint32_t node_a, std::uint32_t node_b,
                                                     double (&block)[3][3]) const noexcept {
  const Scalar* a0 = shape_row(node_a, 0);
  const Scalar* a1 = shape_row(node_a, 1);
  const Scalar* a2 = shape_row(node_a, 2);
  const Scalar* b0 = shape_row(node_b, 0);
  const Scalar* b1 = shape_row(node_b, 1);
  const Scalar* b2 = shape_row(node_b, 2);
  double s00 = 0.0, s01 = 0.0, s02 = 0.0, s10 = 0.0, s11 = 0.0, s12 = 0.0, s20 = 0.0, s21 = 0.0,
         s22 = 0.0;
  for (std::size_t i = 0; i < active_modes_; ++i) {
    const double k = inverse_k_hat_[i];
    const auto x0 = static_cast<double>(a0[i]);
    const auto x1 = static_cast<double>(a1[i]);
    const auto x2 = static_cast<double>(a2[i]);
    const auto y0 = static_cast<double>(b0[i]);
    const auto y1 = static_cast<double>(b1[i]);
    const auto y2 = static_cast<double>(b2[i]);
    s00 += x0 * y0 * k;
    s01 += x0 * y1 * k;
    s02 += x0 * y2 * k;
    s10 += x1 * y0 * k;
    s11 += x1 * y1 * k;
    s12 += x1 * y2 * k;
    s20 += x2 * y0 * k;
    s21 += x2 * y1 * k;
    s22 += x2 * y2 * k;
  }
  block[0][0] = s00;
  block[0][1] = s01;
  block[0][2] = s02;
  block[1][0] = s10;
  block[1][1] = s11;
  block[1][2] = s12;
  block[2][0] = s20;
  block[2][1] = s21;
  block[2][2] = s22;
}

// The blocks of two cached nodes (a ≠ b: both orientations; a = b: the diagonal block, its
// upper triangle computed and mirrored, as a solve from scratch does).
template <typename Scalar>
void BasicModalModel<Scalar>::fill_cache_blocks(std::uint32_t slot_a,
                                                std::uint32_t slot_b) noexcept {
  ContactCache& cache = *contact_cache_;
  const std::uint32_t node_a = cache.nodes[slot_a];
  const std::uint32_t node_b = cache.nodes[slot_b];
  const auto entry = [&cache](std::uint32_t slot_row, int axis_row, std::uint32_t slot_column,
                              int axis_column) -> double& {
    return cache.compliance[(3 * static_cast<std::size_t>(slot_row) +
                             static_cast<std::size_t>(axis_row)) *
                                kContactRows +
                            3 * static_cast<std::size_t>(slot_column) +
                            static_cast<std::size_t>(axis_column)];
  };
  double block[3][3];
  modal_compliance_block(node_a, node_b, block);
  for (int axis_a = 0; axis_a < 3; ++axis_a) {
    for (int axis_b = (slot_a == slot_b ? axis_a : 0); axis_b < 3; ++axis_b) {
      const double modal = block[axis_a][axis_b];
      double value = modal;
      if (static_correction_) value += residual_entry(node_a, axis_a, node_b, axis_b);
      entry(slot_a, axis_a, slot_b, axis_b) = value;
      if (slot_a == slot_b) {
        entry(slot_b, axis_b, slot_a, axis_a) = value;
        continue;
      }
      // The transposed entry: the same modal sum (products commute, summed in the same
      // order); the residual compliance read in its own orientation, as a solve with node b
      // first reads it.
      double transposed = modal;
      if (static_correction_) {
        transposed = residual_symmetric_ ? value
                                         : transposed + residual_entry(node_b, axis_b, node_a, axis_a);
      }
      entry(slot_b, axis_b, slot_a, axis_a) = transposed;
    }
  }
  cache.pair_valid[slot_a * kMaxContacts + slot_b] = true;
  cache.pair_valid[slot_b * kMaxContacts + slot_a] = true;
}

template <typename Scalar>
void BasicModalModel<Scalar>::gather_contact_slots(
    std::span<const BasicImposedDisplacement<Scalar>> targets,
    std::span<std::uint32_t> slot_of) noexcept {
  ContactCache& cache = *contact_cache_;
  bool used[kMaxContacts] = {};
  for (std::size_t k = 0; k < targets.size(); ++k) {
    slot_of[k] = detail::kNoSlot;
    for (std::uint32_t slot = 0; slot < cache.slot_count; ++slot) {
      if (cache.nodes[slot] == targets[k].node) {
        slot_of[k] = slot;
        used[slot] = true;
        break;
      }
    }
  }
  for (std::size_t k = 0; k < targets.size(); ++k) {
    if (slot_of[k] != detail::kNoSlot) continue;
    // A free slot, else one no target uses (there is one: at most kMaxContacts targets, and
    // this one is not cached).
    std::uint32_t slot = 0;
    if (cache.slot_count < kMaxContacts) {
      slot = cache.slot_count++;
    } else {
      while (used[slot]) ++slot;
    }
    used[slot] = true;
    cache.nodes[slot] = targets[k].node;
    cache.response_epoch[slot] = 0;
    for (std::size_t other = 0; other < kMaxContacts; ++other) {
      cache.pair_valid[slot * kMaxContacts + other] = false;
      cache.pair_valid[other * kMaxContacts + slot] = false;
    }
    slot_of[k] = slot;
  }
  // Only the blocks this solve needs (pairs of its targets) are computed.
  for (std::size_t k = 0; k < targets.size(); ++k) {
    for (std::size_t l = k; l < targets.size(); ++l) {
      if (!cache.pair_valid[slot_of[k] * kMaxContacts + slot_of[l]])
        fill_cache_blocks(slot_of[k], slot_of[l]);
    }
  }
}

template <typename Scalar>
core::Status BasicModalModel<Scalar>::solve_imposed(
    std::span<const BasicImposedDisplacement<Scalar>> targets,
    std::span<Vector3> forces_out) noexcept {
  const std::size_t c = targets.size();
  if (c == 0) return core::Status::ok();
  if (c > kMaxContacts) {
    return {core::StatusCode::capacity_exceeded,
            "modal model: more imposed displacements than kMaxContacts"};
  }
  if (forces_out.size() < c) {
    return {core::StatusCode::invalid_argument, "modal model: forces_out shorter than targets"};
  }
  std::size_t new_nodes = 0;
  for (std::size_t k = 0; k < c; ++k) {
    const std::uint32_t node = targets[k].node;
    if (node >= node_count_)
      return {core::StatusCode::invalid_argument, "modal model: unknown contact node"};
    if (!targets[k].displacement_m.allFinite()) {
      return {core::StatusCode::numeric_error, "modal model: non-finite imposed displacement"};
    }
    if (static_correction_ && surface_index_[node] < 0) {
      return {core::StatusCode::invalid_argument,
              "modal model: contact on a non-surface node with static correction on"};
    }
    for (std::size_t l = 0; l < k; ++l) {
      if (targets[l].node == node) {
        return {core::StatusCode::invalid_argument, "modal model: contact node imposed twice"};
      }
    }
    if (find_pending(node) == detail::kNotFound) ++new_nodes;
  }
  if (pending_count_ + new_nodes > kMaxLoadedNodes) {
    return {core::StatusCode::capacity_exceeded, "modal model: too many loaded nodes"};
  }
  if (!static_correction_ && active_modes_ < 3 * c) {
    return {core::StatusCode::invalid_argument,
            "modal model: fewer active modes than imposed components (enable static correction)"};
  }

  // Next-step modal displacement without the new forces: x⁺₀ = (Φᵀ F + a0 x + a2 v + a)/k̂,
  // needed only for a node whose free response this step is not cached yet.
  project_pending_forces();
  std::array<std::uint32_t, kMaxContacts> slot_of{};
  gather_contact_slots(targets, slot_of);
  ContactCache& cache = *contact_cache_;
  // A free response is cached only when no load is applied (the usual case at the first solve
  // of a step, and after a release's clear_forces()): with loads, it depends on them.
  const bool unloaded = pending_count_ == 0;
  bool predicted_ready = false;
  const std::span<const NodeLoad> pending{pending_loads_.data(), pending_count_};
  const auto rows = static_cast<Eigen::Index>(3 * c);
  detail::ContactVector rhs(rows);
  for (std::size_t k = 0; k < c; ++k) {
    const std::uint32_t node_k = targets[k].node;
    const std::uint32_t slot = slot_of[k];
    double* free_response = cache.free_response + 3 * static_cast<std::size_t>(slot);
    if (!unloaded || cache.response_epoch[slot] != state_epoch_) {
      if (!predicted_ready) {
        for (std::size_t i = 0; i < active_modes_; ++i) {
          predicted_[i] =
              (modal_force_[i] + a0_[i] * x_[i] + a2_[i] * v_[i] + a_[i]) * inverse_k_hat_[i];
        }
        predicted_ready = true;
      }
      // Three sums side by side, each in mode order (as one computed alone).
      const Scalar* shape_x = shape_row(node_k, 0);
      const Scalar* shape_y = shape_row(node_k, 1);
      const Scalar* shape_z = shape_row(node_k, 2);
      double sum_x = 0.0, sum_y = 0.0, sum_z = 0.0;
      for (std::size_t i = 0; i < active_modes_; ++i) {
        sum_x += static_cast<double>(shape_x[i]) * predicted_[i];
        sum_y += static_cast<double>(shape_y[i]) * predicted_[i];
        sum_z += static_cast<double>(shape_z[i]) * predicted_[i];
      }
      free_response[0] = sum_x;
      free_response[1] = sum_y;
      free_response[2] = sum_z;
      cache.response_epoch[slot] = unloaded ? state_epoch_ : 0;
    }
    const Eigen::Vector3d static_part = static_response(node_k, pending);
    for (int axis_k = 0; axis_k < 3; ++axis_k) {
      const Eigen::Index row = static_cast<Eigen::Index>(3 * k) + axis_k;
      rhs[row] = static_cast<double>(targets[k].displacement_m[axis_k]) - free_response[axis_k] -
                 static_part[axis_k];
    }
  }
  // The same target nodes in the same order as the last accepted solve: the same matrix, so
  // its factorisation stands. Otherwise the upper triangle of Φ_K diag(1/k̂) Φ_Kᵀ + R_KK is
  // gathered from the cache (row node first, as a cold solve computes it), mirrored below.
  bool same_nodes = factorised_count_ == c;
  for (std::size_t k = 0; same_nodes && k < c; ++k)
    same_nodes = factorised_nodes_[k] == targets[k].node;
  if (!same_nodes) {
    factorised_count_ = 0;
    ContactMatrix compliance(rows, rows);
    for (std::size_t k = 0; k < c; ++k) {
      const std::size_t cache_row = 3 * static_cast<std::size_t>(slot_of[k]);
      for (int axis_k = 0; axis_k < 3; ++axis_k) {
        const Eigen::Index row = static_cast<Eigen::Index>(3 * k) + axis_k;
        const double* cached =
            cache.compliance + (cache_row + static_cast<std::size_t>(axis_k)) * kContactRows;
        for (std::size_t l = k; l < c; ++l) {
          const std::size_t cache_column = 3 * static_cast<std::size_t>(slot_of[l]);
          for (int axis_l = (l == k ? axis_k : 0); axis_l < 3; ++axis_l) {
            const Eigen::Index column = static_cast<Eigen::Index>(3 * l) + axis_l;
            const double value = cached[cache_column + static_cast<std::size_t>(axis_l)];
            compliance(row, column) = value;
            compliance(column, row) = value;
          }
        }
      }
    }
    factorisation_.compute(compliance);
    const detail::ContactVector pivots = factorisation_.vectorD();
    if (factorisation_.info() != Eigen::Success ||
        !(pivots.minCoeff() > detail::kMinPivotRatio * pivots.maxCoeff())) {
      return {core::StatusCode::numeric_error,
              "modal model: contact compliance singular (fixed node or dependent contacts)"};
    }
    for (std::size_t k = 0; k < c; ++k) factorised_nodes_[k] = targets[k].node;
    factorised_count_ = c;
  }
  const detail::ContactVector forces = factorisation_.solve(rhs);
  // Forces are returned as Scalar: one that would overflow it is refused like a non-finite one.
  constexpr double kScalarMax = static_cast<double>(std::numeric_limits<Scalar>::max());
  for (Eigen::Index j = 0; j < rows; ++j) {
    if (!std::isfinite(forces[j]) || std::abs(forces[j]) > kScalarMax) {
      return {core::StatusCode::numeric_error, "modal model: non-finite contact force"};
    }
  }
  for (std::size_t k = 0; k < c; ++k) {
    const Eigen::Vector3d force = forces.segment<3>(static_cast<Eigen::Index>(3 * k));
    forces_out[k] = force.cast<Scalar>();
    // Cannot fail: node, finiteness, surface membership and capacity were checked above.
    (void)add_force(targets[k].node, force);
  }
  return core::Status::ok();
}

template <typename Scalar>
core::Status BasicModalModel<Scalar>::reconstruct(std::span<Scalar> out_3n) const noexcept {
  if (out_3n.size() < 3 * static_cast<std::size_t>(node_count_)) {
    return {core::StatusCode::invalid_argument, "modal model: reconstruct output shorter than 3n"};
  }
  if (static_correction_ && active_modes_ < stored_modes_ && stepped_count_ > 0) {
    // The inactive modes' static flexibility couples every loaded node with every node through
    // the stored shapes: rare (a model run below its stored mode count), done per node.
    for (std::uint32_t node = 0; node < node_count_; ++node) {
      const Vector3 u = displacement(node);
      for (int axis = 0; axis < 3; ++axis)
        out_3n[3 * static_cast<std::size_t>(node) + static_cast<std::size_t>(axis)] = u[axis];
    }
    return core::Status::ok();
  }
  using Vector = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;
  for (std::size_t i = 0; i < active_modes_; ++i)
    reconstruct_modes_[i] = static_cast<Scalar>(x_[i]);
  // Φ q by the kernel the lazy contact surface shares (modal_shape_rows.hpp).
  shape_rows(nullptr, node_count_, reconstruct_modes_.data(), out_3n.data());
  if (!static_correction_ || stepped_count_ == 0) return core::Status::ok();
  // Σ_l R_{k,l} F_l for every surface node k: R symmetric, so column block l is the transpose
  // of row block l — three contiguous rows of length 3s per loaded node.
  const std::size_t stride = 3 * static_cast<std::size_t>(surface_count_);
  Eigen::Map<Vector> residual(reconstruct_residual_.data(), static_cast<Eigen::Index>(stride));
  residual.setZero();
  for (std::size_t k = 0; k < stepped_count_; ++k) {
    const NodeLoad& load = stepped_loads_[k];
    if (load.surface_index < 0) continue;
    for (std::size_t axis = 0; axis < 3; ++axis) {
      const Scalar* row = residual_compliance_.data() +
                          (3 * static_cast<std::size_t>(load.surface_index) + axis) * stride;
      residual += static_cast<Scalar>(load.force_n[axis]) *
                  Eigen::Map<const Vector>(row, static_cast<Eigen::Index>(stride));
    }
  }
  for (std::uint32_t node = 0; node < node_count_; ++node) {
    const std::int32_t surface = surface_index_[node];
    if (surface < 0) continue;
    for (std::size_t axis = 0; axis < 3; ++axis) {
      out_3n[3 * static_cast<std::size_t>(node) + axis] +=
          reconstruct_residual_[3 * static_cast<std::size_t>(surface) + axis];
    }
  }
  return core::Status::ok();
}

}  // namespace trainer::model

#include "modal_shape_rows.hpp"  // IWYU pragma: keep (BasicModalModel::shape_rows)
