// Residual (static-correction) compliance and the modal truncation error, both from the exact
// static flexibility of the shell (METHODS.md §1 "static correction"). Offline, double.
//
// Truncating the modal basis to r modes keeps the dynamics of the lowest modes but loses the
// static flexibility of the rest: a tool pressing on one node feels the modal compliance
// Φ Ω⁻² Φᵀ instead of the exact K⁻¹. The residual compliance R = K⁻¹ − Φ Ω⁻² Φᵀ, restricted
// to the translations of the nodes a tool may touch, restores the exact static response:
// u = Φ x_static + R F = K⁻¹ F for forces at those nodes. The exact columns of K⁻¹ come from
// one sparse LDLᵀ factorisation of K and 3s right-hand sides solved in blocks.
#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "trainer/core/expected.hpp"
#include "trainer/model_offline/modal_analysis.hpp"
#include "trainer/model_offline/shell_model.hpp"

namespace trainer::model::offline {

struct ResidualCompliance {
  std::vector<int> nodes;      // s node indices, in the order of the blocks of `compliance`
  Eigen::MatrixXd compliance;  // 3s × 3s, m/N, symmetric positive semi-definite;
                               // block (k, l) = response at nodes[k] to a force at nodes[l]
};

// R for the given nodes (each once; fixed nodes give zero rows). Refuses a basis that does not
// match the shell, unknown or repeated nodes, and a K that is not positive definite.
core::Expected<ResidualCompliance> compute_residual_compliance(const AssembledShell& shell,
                                                               const ModalBasis& basis,
                                                               std::span<const int> nodes);

// Every node that has at least one free translational dof (the tube's surface nodes).
std::vector<int> nodes_with_free_translation(const DofMap& dofs);

// Static error of the first `mode_count` modes (0 = all of the basis) for a unit force on each
// free translational dof of the given nodes: the modal static response Φ Ω⁻² Φᵀ e against the
// exact K⁻¹ e. "local" compares the displacement of the loaded node (what the tool feels),
// "field" the whole translational displacement field (2-norm). Relative errors.
struct TruncationError {
  int mode_count = 0;
  int load_cases = 0;
  double max_local_relative = 0.0;
  double mean_local_relative = 0.0;
  double max_field_relative = 0.0;
  double mean_field_relative = 0.0;
  int worst_node = -1;  // node of the worst local error
  int worst_axis = -1;  // 0..2
};
core::Expected<TruncationError> estimate_truncation_error(const AssembledShell& shell,
                                                          const ModalBasis& basis,
                                                          std::span<const int> nodes,
                                                          int mode_count = 0);

}  // namespace trainer::model::offline
