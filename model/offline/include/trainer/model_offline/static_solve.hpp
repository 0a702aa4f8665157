// Linear static solve of the assembled shell: K_ff u_f = f_f with a sparse LDLᵀ
// (Eigen SimplicialLDLT) of the free system, displacements scattered back to every node
// (fixed dofs report 0). The factorisation can be kept and reused for many load vectors.
#pragma once

#include <memory>

#include <Eigen/Core>

#include "trainer/core/expected.hpp"
#include "trainer/model_offline/shell_model.hpp"

namespace trainer::model::offline {

struct StaticSolution {
  // One row per node: ux, uy, uz (m), rx, ry, rz (rad), global frame.
  Eigen::Matrix<double, Eigen::Dynamic, kShellDofsPerNode, Eigen::RowMajor> node_displacements;
  double solve_time_s = 0.0;  // back-substitution only (the factorisation is timed separately)
};

class ShellStaticSolver {
 public:
  // Factorises K. Fails when the matrix is not positive definite (a pivot ≤
  // kSingularPivotRatio × its diagonal entry), naming the node and dof of the bad pivot.
  static core::Expected<ShellStaticSolver> create(const AssembledShell& shell);

  // `nodal_loads`: 6 × node count entries (see loads.hpp); entries on fixed dofs are ignored.
  core::Expected<StaticSolution> solve(const Eigen::VectorXd& nodal_loads) const;

  double factorization_time_s() const { return factorization_time_s_; }
  // Smallest LDLᵀ pivot, and the smallest pivot divided by its own diagonal entry of K
  // (1 for a diagonal matrix, → 0 as K approaches singular).
  double smallest_pivot() const { return smallest_pivot_; }
  double smallest_pivot_ratio() const { return smallest_pivot_ratio_; }

  ShellStaticSolver(ShellStaticSolver&&) noexcept;
  ShellStaticSolver& operator=(ShellStaticSolver&&) noexcept;
  ~ShellStaticSolver();

 private:
  struct Factorization;
  ShellStaticSolver();
  std::unique_ptr<Factorization> factorization_;
  DofMap dofs_;
  double factorization_time_s_ = 0.0;
  double smallest_pivot_ = 0.0;
  double smallest_pivot_ratio_ = 0.0;
};

// One-shot convenience: create() then solve().
core::Expected<StaticSolution> static_solve(const AssembledShell& shell,
                                            const Eigen::VectorXd& nodal_loads);

}  // namespace trainer::model::offline
