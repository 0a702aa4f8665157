// DNIOS (full-system Newmark) and the double-precision NIRMS reference.
#include "trainer/model_offline/dnios.hpp"

#include <cmath>
#include <string>

#include <Eigen/Cholesky>

namespace trainer::model::offline {
namespace {

core::Expected<void> check_time_step(double time_step_s, const char* what) {
  if (!(time_step_s > 0.0) || !std::isfinite(time_step_s)) {
    return core::make_error(std::string(what) + ": time step " + std::to_string(time_step_s) +
                            " s, expected a finite value > 0");
  }
  return {};
}

core::Expected<void> check_force(int node, int node_count, const Eigen::Vector3d& force_n,
                                 const char* what) {
  if (node < 0 || node >= node_count) {
    return core::make_error(std::string(what) + ": node " + std::to_string(node) +
                            " out of range, expected 0.." + std::to_string(node_count - 1));
  }
  if (!force_n.allFinite()) {
    return core::make_error(std::string(what) + ": non-finite force on node " +
                            std::to_string(node));
  }
  return {};
}

}  // namespace

core::Expected<FullNewmark> FullNewmark::create(const AssembledShell& shell,
                                                const RayleighDamping& damping,
                                                double time_step_s) {
  const char* what = "DNIOS";
  if (auto ok = check_time_step(time_step_s, what); !ok) return std::move(ok).error();
  if (!(damping.mass_proportional_per_s >= 0.0) || !(damping.stiffness_proportional_s >= 0.0) ||
      !std::isfinite(damping.mass_proportional_per_s) ||
      !std::isfinite(damping.stiffness_proportional_s)) {
    return core::make_error(
        "DNIOS: Rayleigh damping α_M = " + std::to_string(damping.mass_proportional_per_s) +
        " 1/s, β_K = " + std::to_string(damping.stiffness_proportional_s) +
        " s: expected finite values ≥ 0");
  }
  const int free_count = shell.dofs.free_count();
  if (shell.stiffness.rows() != free_count || shell.stiffness.cols() != free_count ||
      shell.lumped_mass.size() != free_count ||
      static_cast<int>(shell.dofs.free_index.size()) != kShellDofsPerNode * shell.dofs.node_count) {
    return core::make_error("DNIOS: the shell's stiffness (" +
                            std::to_string(shell.stiffness.rows()) + " × " +
                            std::to_string(shell.stiffness.cols()) + "), lumped mass (" +
                            std::to_string(shell.lumped_mass.size()) + ") and DofMap (" +
                            std::to_string(free_count) + " free dofs) disagree");
  }
  FullNewmark model;
  model.dofs_ = shell.dofs;
  model.stiffness_ = shell.stiffness;
  model.mass_ = shell.lumped_mass;
  model.damping_ = damping;
  model.time_step_s_ = time_step_s;
  // K̂ = K + a0 M + a1 (α_M M + β_K K) = (1 + a1 β_K) K + (a0 + a1 α_M) M.
  const double a0 = 4.0 / (time_step_s * time_step_s);
  const double a1 = 2.0 / time_step_s;
  Eigen::SparseMatrix<double> effective =
      (1.0 + a1 * damping.stiffness_proportional_s) * shell.stiffness;
  for (int f = 0; f < free_count; ++f) {
    effective.coeffRef(f, f) += (a0 + a1 * damping.mass_proportional_per_s) * shell.lumped_mass[f];
  }
  model.factorisation_ =
      std::make_unique<Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>>(effective);
  if (model.factorisation_->info() != Eigen::Success ||
      (model.factorisation_->vectorD().array() <= 0.0).any()) {
    return core::make_error("DNIOS: K̂ = K + a0 M + a1 B is not positive definite (" +
                            std::to_string(free_count) +
                            " free dofs): a dof without stiffness or mass");
  }
  model.reset();
  return model;
}

core::Expected<void> FullNewmark::add_node_force(int node, const Eigen::Vector3d& force_n) {
  if (auto ok = check_force(node, dofs_.node_count, force_n, "DNIOS"); !ok) return ok;
  for (int axis = 0; axis < 3; ++axis) {
    const int free_dof =
        dofs_.free_index[static_cast<std::size_t>(node * kShellDofsPerNode + axis)];
    if (free_dof >= 0) force_[free_dof] += force_n[axis];
  }
  return {};
}

void FullNewmark::clear_forces() {
  force_.setZero();
}

void FullNewmark::reset() {
  const int free_count = dofs_.free_count();
  force_ = Eigen::VectorXd::Zero(free_count);
  displacement_ = Eigen::VectorXd::Zero(free_count);
  velocity_ = Eigen::VectorXd::Zero(free_count);
  acceleration_ = Eigen::VectorXd::Zero(free_count);
}

Eigen::VectorXd FullNewmark::step_rhs() const {
  // Standard average-acceleration Newmark (Bathe, γ = 1/2, β = 1/4):
  //   F̂ = F_{n+1} + M (a0 u + a2 v + a) + B (a1 u + v),  K̂ u_{n+1} = F̂,
  //   a_{n+1} = a0 (u_{n+1} − u) − a2 v − a,  v_{n+1} = v + Δt/2 (a + a_{n+1}).
  const double dt = time_step_s_;
  const double a0 = 4.0 / (dt * dt);
  const double a1 = 2.0 / dt;
  const double a2 = 4.0 / dt;
  const Eigen::VectorXd damped = a1 * displacement_ + velocity_;
  Eigen::VectorXd rhs = force_;
  rhs += mass_.cwiseProduct(a0 * displacement_ + a2 * velocity_ + acceleration_ +
                            damping_.mass_proportional_per_s * damped);
  if (damping_.stiffness_proportional_s != 0.0) {
    rhs += damping_.stiffness_proportional_s * (stiffness_ * damped);
  }
  return rhs;
}

void FullNewmark::advance(const Eigen::VectorXd& next) {
  const double dt = time_step_s_;
  const double a0 = 4.0 / (dt * dt);
  const double a2 = 4.0 / dt;
  const Eigen::VectorXd next_acceleration =
      a0 * (next - displacement_) - a2 * velocity_ - acceleration_;
  velocity_ += 0.5 * dt * (acceleration_ + next_acceleration);
  acceleration_ = next_acceleration;
  displacement_ = next;
}

void FullNewmark::step() {
  advance(factorisation_->solve(step_rhs()));
}

core::Expected<Eigen::Vector3d> FullNewmark::step_imposed(int node,
                                                          const Eigen::Vector3d& target_m) {
  if (auto ok = check_force(node, dofs_.node_count, target_m, "DNIOS imposed displacement"); !ok) {
    return std::move(ok).error();
  }
  int free_dofs[3];
  for (int axis = 0; axis < 3; ++axis) {
    free_dofs[axis] = dofs_.free_index[static_cast<std::size_t>(node * kShellDofsPerNode + axis)];
    if (free_dofs[axis] < 0) {
      return core::make_error("DNIOS imposed displacement: node " + std::to_string(node) +
                              " has a fixed translation, expected a free node");
    }
  }
  auto columns = imposed_columns_.find(node);
  if (columns == imposed_columns_.end()) {
    Eigen::Matrix<double, Eigen::Dynamic, 3> unit =
        Eigen::Matrix<double, Eigen::Dynamic, 3>::Zero(dofs_.free_count(), 3);
    for (int axis = 0; axis < 3; ++axis) unit(free_dofs[axis], axis) = 1.0;
    columns = imposed_columns_.emplace(node, factorisation_->solve(unit)).first;
  }
  const Eigen::VectorXd free = factorisation_->solve(step_rhs());
  Eigen::Matrix3d compliance;
  Eigen::Vector3d free_node;
  for (int axis = 0; axis < 3; ++axis) {
    compliance.row(axis) = columns->second.row(free_dofs[axis]);
    free_node[axis] = free[free_dofs[axis]];
  }
  const Eigen::Vector3d force = compliance.ldlt().solve(target_m - free_node);
  advance(free + columns->second * force);
  return force;
}

Eigen::Vector3d FullNewmark::displacement(int node) const {
  Eigen::Vector3d result = Eigen::Vector3d::Zero();
  if (node < 0 || node >= dofs_.node_count) return result;
  for (int axis = 0; axis < 3; ++axis) {
    const int free_dof =
        dofs_.free_index[static_cast<std::size_t>(node * kShellDofsPerNode + axis)];
    if (free_dof >= 0) result[axis] = displacement_[free_dof];
  }
  return result;
}

Eigen::VectorXd FullNewmark::translational_field() const {
  Eigen::VectorXd field(3 * dofs_.node_count);
  for (int node = 0; node < dofs_.node_count; ++node)
    field.segment<3>(3 * node) = displacement(node);
  return field;
}

core::Expected<ModalNewmark> ModalNewmark::create(const ModalBasis& basis,
                                                  const Eigen::VectorXd& modal_damping,
                                                  double time_step_s, int mode_count) {
  const char* what = "modal Newmark reference";
  if (auto ok = check_time_step(time_step_s, what); !ok) return std::move(ok).error();
  const int r = mode_count == 0 ? basis.mode_count() : mode_count;
  if (r <= 0 || r > basis.mode_count() || basis.node_shapes.cols() != basis.mode_count() ||
      basis.node_shapes.rows() != 3 * basis.node_count) {
    return core::make_error("modal Newmark reference: mode_count = " + std::to_string(mode_count) +
                            ", expected 0 (all) .. " + std::to_string(basis.mode_count()) +
                            " of a consistent basis");
  }
  if (modal_damping.size() < r || !modal_damping.head(r).allFinite() ||
      (modal_damping.head(r).array() < 0.0).any()) {
    return core::make_error("modal Newmark reference: modal_damping has " +
                            std::to_string(modal_damping.size()) + " entries, expected ≥ " +
                            std::to_string(r) + " finite values ≥ 0");
  }
  ModalNewmark model;
  model.time_step_s_ = time_step_s;
  model.shapes_ = basis.node_shapes.leftCols(r);
  model.omega_squared_ = basis.omega_squared.head(r);
  const double dt = time_step_s;
  // Per-mode constants of METHODS.md §1 (Appendix B, NIRMS).
  model.a0_ = (4.0 + 2.0 * dt * modal_damping.head(r).array()) / (dt * dt);
  model.a2_ = 4.0 / dt + modal_damping.head(r).array();
  model.nodal_force_ = Eigen::VectorXd::Zero(3 * basis.node_count);
  model.reset();
  return model;
}

core::Expected<void> ModalNewmark::add_node_force(int node, const Eigen::Vector3d& force_n) {
  const int node_count = static_cast<int>(shapes_.rows() / 3);
  if (auto ok = check_force(node, node_count, force_n, "modal Newmark reference"); !ok) return ok;
  nodal_force_.segment<3>(3 * node) += force_n;
  return {};
}

void ModalNewmark::clear_forces() {
  nodal_force_.setZero();
}

void ModalNewmark::reset() {
  const Eigen::Index r = omega_squared_.size();
  nodal_force_.setZero();
  x_ = Eigen::VectorXd::Zero(r);
  v_ = Eigen::VectorXd::Zero(r);
  a_ = Eigen::VectorXd::Zero(r);
}

void ModalNewmark::step() {
  const double dt = time_step_s_;
  const Eigen::VectorXd modal_force = shapes_.transpose() * nodal_force_;
  const Eigen::ArrayXd effective_force =
      modal_force.array() + a0_.array() * x_.array() + a2_.array() * v_.array() + a_.array();
  const Eigen::ArrayXd next = effective_force / (omega_squared_.array() + a0_.array());
  const Eigen::ArrayXd next_acceleration =
      4.0 / (dt * dt) * (next - x_.array()) - 4.0 / dt * v_.array() - a_.array();
  v_.array() += 0.5 * dt * (a_.array() + next_acceleration);
  a_ = next_acceleration.matrix();
  x_ = next.matrix();
}

Eigen::Vector3d ModalNewmark::displacement(int node) const {
  if (node < 0 || 3 * node >= shapes_.rows()) return Eigen::Vector3d::Zero();
  return shapes_.middleRows(3 * node, 3) * x_;
}

Eigen::VectorXd ModalNewmark::translational_field() const {
  return shapes_ * x_;
}

}  // namespace trainer::model::offline
