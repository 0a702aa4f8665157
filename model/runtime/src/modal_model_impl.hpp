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
#include <new>
#include <string>

namespace trainer::model {
namespace detail {

inline constexpr std::size_t kNotFound = static_cast<std::size_t>(-1);
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
  // Eigen's fixed-capacity LDLT declares a destructor, which create_object refuses; it owns
  // no resources (inline storage), so constructed in arena bytes and never destroyed.
  auto factorisation_bytes =
      arena.allocate_bytes(sizeof(FactorisationCache), alignof(FactorisationCache),
                           "modal model contact factorisations");
  if (!factorisation_bytes) {
    return core::make_error("modal model: arena exhausted: " +
                            factorisation_bytes.error().message);
  }
  model.factorisations_ = new (factorisation_bytes.value()) FactorisationCache();
  // Each LDLᵀ from a 1×1 identity: Eigen's default LDLT leaves its ComputationInfo
  // uninitialised (never read while the entry is empty, but not left indeterminate).
  for (Factorisation& entry : model.factorisations_->entries) {
    entry.ldlt.compute(ContactMatrix::Identity(1, 1));
    entry.count = 0;
    entry.last_use = 0;
  }
  model.factorisations_->clock = 0;
  model.factorisations_->computed = 0;
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

#include "modal_contact_solve.hpp"  // IWYU pragma: keep (BasicModalModel::solve_imposed)
#include "modal_shape_rows.hpp"  // IWYU pragma: keep (BasicModalModel::shape_rows)
