// Accuracy references for the duct dynamics (Basdogan Appendix B), offline, double precision:
//  * FullNewmark — DNIOS, direct Newmark integration of the full free-dof system
//    M ü + B u̇ + K u = F with B = α_M M + β_K K: K̂ = K + a0 M + a1 B is factorised once
//    (sparse LDLᵀ) and each step is one back-substitution, O(nnz(L)) — the paper's O(n²)
//    baseline;
//  * ModalNewmark — NIRMS in double over the first r modes of a ModalBasis, the reference the
//    float runtime model (trainer::model::ModalModel) is checked against.
//
// Both use the standard average-acceleration Newmark scheme (γ = 1/2, β = 1/4; Bathe's
// constants a0 = 4/Δt², a1 = 2/Δt, a2 = 4/Δt, a3 = 1, a4 = 1, a5 = 0), so with all modes and
// Rayleigh damping they integrate the same discrete system: Newmark is linear and commutes
// with the modal transformation. The zero rotational mass makes M singular but K̂ stays SPD;
// the massless rotations then satisfy their (static, damped) equilibrium K_rt u + K_rr θ +
// β_K (K_rt u̇ + K_rr θ̇) = 0 at every step, which from rest keeps θ = −K_rr⁻¹ K_rt u exactly,
// i.e. the same condensed system the modes describe.
//
// Load convention (both classes, and the runtime model): forces set before step() act at the
// end of that step (F_{n+1}); they stay applied until clear_forces(). Start at rest.
#pragma once

#include <map>
#include <memory>

#include <Eigen/Core>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "trainer/core/expected.hpp"
#include "trainer/model_offline/modal_analysis.hpp"
#include "trainer/model_offline/shell_model.hpp"

namespace trainer::model::offline {

class FullNewmark {
 public:
  // Refuses a non-positive or non-finite time step, negative damping, inconsistent shell
  // sizes, and a K̂ that is not positive definite.
  static core::Expected<FullNewmark> create(const AssembledShell& shell,
                                            const RayleighDamping& damping, double time_step_s);

  // Adds a force (N) on the translations of `node`; components on fixed dofs are dropped.
  core::Expected<void> add_node_force(int node, const Eigen::Vector3d& force_n);
  void clear_forces();
  void step();
  // One step in which `node`'s translation is imposed: the extra force on it (returned, N)
  // that makes its displacement at the end of the step equal `target_m`, given the forces
  // already applied — the reference for the runtime's displacement-driven contact
  // (ModalModel::solve_imposed). Newmark is linear in F_{n+1}: u_{n+1} = u_free + K̂⁻¹ E f with
  // E the node's three translational unit vectors, so one back-substitution for u_free plus the
  // node's three columns of K̂⁻¹ (solved once per node and kept). Refuses an unknown node, a
  // node with a fixed translation, and a non-finite target. The returned force is not kept
  // applied: the next step imposes again or runs free.
  core::Expected<Eigen::Vector3d> step_imposed(int node, const Eigen::Vector3d& target_m);
  void reset();  // back to rest, forces cleared

  Eigen::Vector3d displacement(int node) const;  // m; zero for fixed dofs and unknown nodes
  Eigen::VectorXd translational_field() const;   // 3n, m
  const Eigen::VectorXd& free_displacement() const { return displacement_; }
  double time_step_s() const { return time_step_s_; }
  int node_count() const { return dofs_.node_count; }

 private:
  FullNewmark() = default;

  DofMap dofs_;
  Eigen::SparseMatrix<double> stiffness_;
  Eigen::VectorXd mass_;
  RayleighDamping damping_;
  double time_step_s_ = 0.0;
  // K̂ = LDLᵀ; behind a pointer because Eigen's sparse solvers are not movable.
  std::unique_ptr<Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>> factorisation_;
  // The free-dof right-hand side of the next step for the applied forces and the state.
  Eigen::VectorXd step_rhs() const;
  // Commits u_{n+1} and updates velocity and acceleration.
  void advance(const Eigen::VectorXd& next);

  Eigen::VectorXd force_;
  // Per node used by step_imposed: K̂⁻¹ E (free × 3), solved on first use.
  std::map<int, Eigen::Matrix<double, Eigen::Dynamic, 3>> imposed_columns_;
  Eigen::VectorXd displacement_;
  Eigen::VectorXd velocity_;
  Eigen::VectorXd acceleration_;
};

class ModalNewmark {
 public:
  // `modal_damping`: α_i per mode (modal_damping()), at least `mode_count` entries.
  // mode_count 0 = every mode of the basis.
  static core::Expected<ModalNewmark> create(const ModalBasis& basis,
                                             const Eigen::VectorXd& modal_damping,
                                             double time_step_s, int mode_count = 0);

  core::Expected<void> add_node_force(int node, const Eigen::Vector3d& force_n);
  void clear_forces();
  void step();
  void reset();

  Eigen::Vector3d displacement(int node) const;  // m, Φ_node x
  Eigen::VectorXd translational_field() const;   // 3n, m
  const Eigen::VectorXd& modal_displacement() const { return x_; }
  int mode_count() const { return static_cast<int>(x_.size()); }

 private:
  ModalNewmark() = default;

  Eigen::MatrixXd shapes_;         // 3n × r
  Eigen::VectorXd omega_squared_;  // r
  Eigen::VectorXd a0_;             // (4 + 2 α Δt)/Δt²
  Eigen::VectorXd a2_;             // 4/Δt + α
  double time_step_s_ = 0.0;
  Eigen::VectorXd nodal_force_;  // 3n, N
  Eigen::VectorXd x_;
  Eigen::VectorXd v_;
  Eigen::VectorXd a_;
};

}  // namespace trainer::model::offline
