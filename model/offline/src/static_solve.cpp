// Static solve of the free shell system with a sparse LDLᵀ factorisation.
#include "trainer/model_offline/static_solve.hpp"

#include <Eigen/SparseCholesky>

#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>

#include "trainer/model_offline/shell_assembly.hpp"

namespace trainer::model::offline {

struct ShellStaticSolver::Factorization {
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
};

ShellStaticSolver::ShellStaticSolver() = default;
ShellStaticSolver::ShellStaticSolver(ShellStaticSolver&&) noexcept = default;
ShellStaticSolver& ShellStaticSolver::operator=(ShellStaticSolver&&) noexcept = default;
ShellStaticSolver::~ShellStaticSolver() = default;

core::Expected<ShellStaticSolver> ShellStaticSolver::create(const AssembledShell& shell) {
  const auto free_count = shell.stiffness.rows();
  if (free_count == 0 || shell.stiffness.cols() != free_count ||
      free_count != shell.dofs.free_count()) {
    return core::make_error("static solve: the stiffness is " +
                            std::to_string(shell.stiffness.rows()) + " x " +
                            std::to_string(shell.stiffness.cols()) + " but the dof map has " +
                            std::to_string(shell.dofs.free_count()) +
                            " free dofs; expected a non-empty square system that matches");
  }
  ShellStaticSolver solver;
  solver.factorization_ = std::make_unique<Factorization>();
  solver.dofs_ = shell.dofs;
  const auto start = std::chrono::steady_clock::now();
  auto& ldlt = solver.factorization_->ldlt;
  ldlt.compute(shell.stiffness);
  solver.factorization_time_s_ =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  // D is in the fill-reducing order: permuted position of original dof j is P.indices()[j].
  const auto& permutation = ldlt.permutationP().indices();
  if (ldlt.info() != Eigen::Success) {
    // Eigen stops at the first zero pivot; the entries of D before it are valid.
    const Eigen::VectorXd partial_pivots = ldlt.vectorD();
    std::string where = "unknown dof";
    for (Eigen::Index k = 0; k < free_count; ++k) {
      if (partial_pivots(k) != 0.0 && std::isfinite(partial_pivots(k))) continue;
      for (Eigen::Index j = 0; j < free_count; ++j) {
        if (permutation(j) != k) continue;
        const int node_dof = shell.dofs.free_to_node_dof[static_cast<std::size_t>(j)];
        where = "node " + std::to_string(node_dof / kShellDofsPerNode) + " dof " +
                shell_dof_name(node_dof % kShellDofsPerNode);
      }
      break;
    }
    return core::make_error(
        "static solve: K is singular: the sparse LDL^T factorisation met a "
        "zero pivot at " +
        where + " (that dof has no stiffness once the others are eliminated)");
  }
  const Eigen::VectorXd pivots = ldlt.vectorD();
  const Eigen::VectorXd diagonal = shell.stiffness.diagonal();
  double smallest_pivot = std::numeric_limits<double>::infinity();
  double smallest_ratio = std::numeric_limits<double>::infinity();
  Eigen::Index worst = 0;
  for (Eigen::Index j = 0; j < free_count; ++j) {
    const double pivot = pivots(permutation(j));
    const double ratio = diagonal(j) > 0.0 ? pivot / diagonal(j) : -1.0;
    smallest_pivot = std::min(smallest_pivot, pivot);
    if (!(ratio >= smallest_ratio)) {
      smallest_ratio = ratio;
      worst = j;
    }
  }
  solver.smallest_pivot_ = smallest_pivot;
  solver.smallest_pivot_ratio_ = smallest_ratio;
  if (!std::isfinite(smallest_ratio) || smallest_ratio <= kSingularPivotRatio) {
    const int node_dof = shell.dofs.free_to_node_dof[static_cast<std::size_t>(worst)];
    std::ostringstream out;
    out << "static solve: K is not positive definite: the LDL^T pivot of node "
        << node_dof / kShellDofsPerNode << " dof " << shell_dof_name(node_dof % kShellDofsPerNode)
        << " is " << pivots(permutation(worst)) << " (" << smallest_ratio
        << " of its diagonal entry " << diagonal(worst) << "; expected > " << kSingularPivotRatio
        << ")";
    return core::make_error(out.str());
  }
  return solver;
}

core::Expected<StaticSolution> ShellStaticSolver::solve(const Eigen::VectorXd& nodal_loads) const {
  const auto expected_size = static_cast<Eigen::Index>(dofs_.free_index.size());
  if (nodal_loads.size() != expected_size) {
    return core::make_error("static solve: the load vector has " +
                            std::to_string(nodal_loads.size()) + " entries; expected " +
                            std::to_string(expected_size) + " (6 per node)");
  }
  if (!nodal_loads.allFinite()) {
    return core::make_error("static solve: the load vector has non-finite entries");
  }
  const int free_count = dofs_.free_count();
  Eigen::VectorXd free_loads(free_count);
  for (int i = 0; i < free_count; ++i) {
    free_loads(i) = nodal_loads(dofs_.free_to_node_dof[static_cast<std::size_t>(i)]);
  }
  const auto start = std::chrono::steady_clock::now();
  const Eigen::VectorXd free_displacements = factorization_->ldlt.solve(free_loads);
  StaticSolution solution;
  solution.solve_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (factorization_->ldlt.info() != Eigen::Success || !free_displacements.allFinite()) {
    return core::make_error("static solve: back-substitution failed or gave non-finite values");
  }
  solution.node_displacements.setZero(dofs_.node_count, kShellDofsPerNode);
  for (int i = 0; i < free_count; ++i) {
    const int node_dof = dofs_.free_to_node_dof[static_cast<std::size_t>(i)];
    solution.node_displacements(node_dof / kShellDofsPerNode, node_dof % kShellDofsPerNode) =
        free_displacements(i);
  }
  return solution;
}

core::Expected<StaticSolution> static_solve(const AssembledShell& shell,
                                            const Eigen::VectorXd& nodal_loads) {
  auto solver = ShellStaticSolver::create(shell);
  if (!solver) return solver.error();
  return solver->solve(nodal_loads);
}

}  // namespace trainer::model::offline
