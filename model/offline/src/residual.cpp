// Residual compliance and truncation error from exact static flexibility columns.
#include "trainer/model_offline/residual.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/SparseCholesky>

namespace trainer::model::offline {
namespace {

using SparseMatrix = Eigen::SparseMatrix<double>;

// Right-hand sides solved per back-substitution batch: bounds the dense block to
// free_count × kBlockColumns doubles while keeping the solves cache-friendly.
constexpr int kBlockColumns = 96;

core::Expected<void> check_inputs(const AssembledShell& shell, const ModalBasis& basis,
                                  std::span<const int> nodes, const char* what) {
  const int node_count = shell.dofs.node_count;
  const int free_count = shell.dofs.free_count();
  if (static_cast<int>(shell.dofs.free_index.size()) != kShellDofsPerNode * node_count ||
      shell.stiffness.rows() != free_count || shell.stiffness.cols() != free_count) {
    return core::make_error(std::string(what) +
                            ": the shell's DofMap and stiffness sizes disagree");
  }
  if (basis.node_count != node_count || basis.node_shapes.rows() != 3 * node_count ||
      basis.node_shapes.cols() != basis.omega_squared.size()) {
    return core::make_error(std::string(what) + ": modal basis is for " +
                            std::to_string(basis.node_count) + " nodes (" +
                            std::to_string(basis.node_shapes.rows()) + " × " +
                            std::to_string(basis.node_shapes.cols()) + " shapes, " +
                            std::to_string(basis.omega_squared.size()) +
                            " ω²), expected the shell's " + std::to_string(node_count) + " nodes");
  }
  if ((basis.omega_squared.array() <= 0.0).any()) {
    return core::make_error(std::string(what) + ": modal basis has a non-positive ω²");
  }
  std::vector<char> seen(static_cast<std::size_t>(node_count), 0);
  for (const int node : nodes) {
    if (node < 0 || node >= node_count) {
      return core::make_error(std::string(what) + ": node " + std::to_string(node) +
                              " out of range, expected 0.." + std::to_string(node_count - 1));
    }
    if (seen[static_cast<std::size_t>(node)]++ != 0) {
      return core::make_error(std::string(what) + ": node " + std::to_string(node) +
                              " listed twice");
    }
  }
  return {};
}

// Solves K X = E for a unit load on every translational dof of `nodes` (block by block) and
// hands each exact translational field (3n, zero at fixed dofs) to
// visit(list_index, axis, field). Loads on fixed dofs are skipped.
template <class Visit>
core::Expected<void> for_each_unit_load(const AssembledShell& shell, std::span<const int> nodes,
                                        const char* what, Visit&& visit) {
  Eigen::SimplicialLDLT<SparseMatrix> factorisation(shell.stiffness);
  if (factorisation.info() != Eigen::Success || (factorisation.vectorD().array() <= 0.0).any()) {
    return core::make_error(std::string(what) +
                            ": K is not positive definite (a free rigid-body motion or a dof "
                            "without stiffness)");
  }
  struct Load {
    int list_index;
    int axis;
    int free_dof;
  };
  std::vector<Load> loads;
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    for (int axis = 0; axis < 3; ++axis) {
      const int free_dof =
          shell.dofs.free_index[static_cast<std::size_t>(nodes[k] * kShellDofsPerNode + axis)];
      if (free_dof >= 0) loads.push_back({static_cast<int>(k), axis, free_dof});
    }
  }
  const int node_count = shell.dofs.node_count;
  const int free_count = shell.dofs.free_count();
  Eigen::VectorXd field(3 * node_count);
  for (std::size_t first = 0; first < loads.size(); first += kBlockColumns) {
    const std::size_t count = std::min<std::size_t>(kBlockColumns, loads.size() - first);
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(free_count, static_cast<Eigen::Index>(count));
    for (std::size_t c = 0; c < count; ++c) {
      rhs(loads[first + c].free_dof, static_cast<Eigen::Index>(c)) = 1.0;
    }
    const Eigen::MatrixXd solution = factorisation.solve(rhs);
    for (std::size_t c = 0; c < count; ++c) {
      field.setZero();
      for (int f = 0; f < free_count; ++f) {
        const int node_dof = shell.dofs.free_to_node_dof[static_cast<std::size_t>(f)];
        const int dof = node_dof % kShellDofsPerNode;
        if (dof < 3) {
          field[node_dof / kShellDofsPerNode * 3 + dof] = solution(f, static_cast<Eigen::Index>(c));
        }
      }
      visit(loads[first + c].list_index, loads[first + c].axis, field);
    }
  }
  return {};
}

}  // namespace

std::vector<int> nodes_with_free_translation(const DofMap& dofs) {
  std::vector<int> nodes;
  for (int node = 0; node < dofs.node_count; ++node) {
    for (int axis = 0; axis < 3; ++axis) {
      if (dofs.free_index[static_cast<std::size_t>(node * kShellDofsPerNode + axis)] >= 0) {
        nodes.push_back(node);
        break;
      }
    }
  }
  return nodes;
}

core::Expected<ResidualCompliance> compute_residual_compliance(const AssembledShell& shell,
                                                               const ModalBasis& basis,
                                                               std::span<const int> nodes) {
  const char* what = "residual compliance";
  if (auto ok = check_inputs(shell, basis, nodes, what); !ok) return std::move(ok).error();
  const Eigen::Index rows = 3 * static_cast<Eigen::Index>(nodes.size());
  // Modal static flexibility at the nodes: Φ_s Ω⁻² Φ_sᵀ.
  Eigen::MatrixXd shapes_at_nodes(rows, basis.mode_count());
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    shapes_at_nodes.middleRows(3 * static_cast<Eigen::Index>(k), 3) =
        basis.node_shapes.middleRows(3 * nodes[k], 3);
  }
  const Eigen::MatrixXd scaled = shapes_at_nodes * basis.omega_squared.cwiseInverse().asDiagonal();
  ResidualCompliance result;
  result.nodes.assign(nodes.begin(), nodes.end());
  result.compliance = Eigen::MatrixXd::Zero(rows, rows);
  auto solved = for_each_unit_load(
      shell, nodes, what, [&](int list_index, int axis, const Eigen::VectorXd& field) {
        const Eigen::Index column = 3 * list_index + axis;
        for (std::size_t l = 0; l < nodes.size(); ++l) {
          result.compliance.block(3 * static_cast<Eigen::Index>(l), column, 3, 1) =
              field.segment(3 * nodes[l], 3);
        }
      });
  if (!solved) return std::move(solved).error();
  result.compliance.noalias() -= scaled * shapes_at_nodes.transpose();
  // Columns of fixed dofs stayed zero; symmetrise the round-off of the two triangles.
  result.compliance = 0.5 * (result.compliance + result.compliance.transpose()).eval();
  return result;
}

core::Expected<TruncationError> estimate_truncation_error(const AssembledShell& shell,
                                                          const ModalBasis& basis,
                                                          std::span<const int> nodes,
                                                          int mode_count) {
  const char* what = "truncation error";
  if (auto ok = check_inputs(shell, basis, nodes, what); !ok) return std::move(ok).error();
  if (mode_count < 0 || mode_count > basis.mode_count()) {
    return core::make_error("truncation error: mode_count = " + std::to_string(mode_count) +
                            ", expected 0 (all) .. " + std::to_string(basis.mode_count()));
  }
  const int r = mode_count == 0 ? basis.mode_count() : mode_count;
  const Eigen::MatrixXd shapes = basis.node_shapes.leftCols(r);
  const Eigen::VectorXd inverse_omega_squared = basis.omega_squared.head(r).cwiseInverse();
  TruncationError result;
  result.mode_count = r;
  double local_sum = 0.0;
  double field_sum = 0.0;
  auto solved = for_each_unit_load(
      shell, nodes, what, [&](int list_index, int axis, const Eigen::VectorXd& exact) {
        const int row = 3 * nodes[static_cast<std::size_t>(list_index)] + axis;
        const Eigen::VectorXd modal_coordinates =
            inverse_omega_squared.cwiseProduct(shapes.row(row).transpose());
        const Eigen::VectorXd modal = shapes * modal_coordinates;
        const Eigen::Index node_row = 3 * nodes[static_cast<std::size_t>(list_index)];
        const double local = (exact.segment(node_row, 3) - modal.segment(node_row, 3)).norm() /
                             exact.segment(node_row, 3).norm();
        const double field = (exact - modal).norm() / exact.norm();
        if (local > result.max_local_relative || result.load_cases == 0) {
          result.max_local_relative = local;
          result.worst_node = nodes[static_cast<std::size_t>(list_index)];
          result.worst_axis = axis;
        }
        result.max_field_relative = std::max(result.max_field_relative, field);
        local_sum += local;
        field_sum += field;
        ++result.load_cases;
      });
  if (!solved) return std::move(solved).error();
  if (result.load_cases > 0) {
    result.mean_local_relative = local_sum / result.load_cases;
    result.mean_field_relative = field_sum / result.load_cases;
  }
  return result;
}

}  // namespace trainer::model::offline
