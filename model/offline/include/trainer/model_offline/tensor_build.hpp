// Precomputation of Cotin's tensor model (METHODS.md §3, Cotin et al. 1999 §5.1): for every
// contact node k, impose a unit displacement along each axis with every other node free
// (except the fixed ones), store the displacement tensor T(n, k) of every stored node n and
// the force tensor F(k) — then the float32 image the runtime TensorModel superposes.
//
// Method: one sparse Cholesky factorisation of K_ff (TetStaticSolver) reused for all right-hand
// sides. Unit forces at k's three dofs give the compliance columns C(:, k); imposing a unit
// displacement at k takes the force F(k) = C(k, k)⁻¹ (Cotin's Lagrange multipliers, in closed
// form) and moves node n by T(n, k) = C(n, k) F(k). The paper's conjugate gradient took hours;
// this takes seconds (docs/performance.md).
//
// solve_imposed_displacements() is the independent reference the tests and `modelc accuracy`
// use: it partitions the free dofs into imposed and unknown ones and solves K_uu u_u =
// −K_uc u_c directly, with its own factorisation.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "trainer/core/expected.hpp"
#include "trainer/model/image_format.hpp"
#include "trainer/model_offline/gmsh_reader.hpp"
#include "trainer/model_offline/tet_elasticity.hpp"

namespace trainer::model::offline {

struct TensorPrecomputeOptions {
  std::vector<int> contact_nodes;   // strictly increasing; each with all three axes free
  std::vector<int> response_nodes;  // strictly increasing; must contain every contact node
  int contacts_per_block = 128;     // contacts solved per block of right-hand sides (memory)
};

struct TensorPrecompute {
  std::vector<std::uint32_t> contact_nodes;
  std::vector<std::uint32_t> response_nodes;
  std::vector<float> displacement_tensors;  // (s·r) × 9, the image layout (image_format.hpp)
  std::vector<double> force_tensors;        // s × 9, symmetric, N/m
  double solve_time_s = 0.0;                // the back-substitutions and tensor products
  // Largest |T(k, k) − I| entry over the contacts before rounding to float: how well the
  // factorisation reproduces the constraint (≈ machine precision × condition number).
  double self_tensor_error = 0.0;
};

core::Expected<TensorPrecompute> precompute_tensors(const AssembledTet& assembled,
                                                    const TetStaticSolver& solver,
                                                    const TensorPrecomputeOptions& options);

// Nodes fixed on at least one axis (the image's fixed_nodes), strictly increasing.
std::vector<int> partly_fixed_nodes(const TetDofMap& dofs);

// Everything a tet_tensor image records besides the tensors.
struct TensorImageInputs {
  const TetMesh* mesh = nullptr;
  Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor> boundary_triangles;  // outward
  TetMaterial material;
  std::vector<int> fixed_nodes;  // strictly increasing
  double time_step_s = 0.0;      // the haptic period it is prepared for (metadata)
};

// Serialises (and checks with the runtime parser) a tet_tensor image, or writes it atomically.
core::Expected<std::vector<std::byte>> serialize_tensor_image(const TensorImageInputs& inputs,
                                                              const TensorPrecompute& tensors);
core::Expected<void> write_tensor_image(const std::filesystem::path& path,
                                        const TensorImageInputs& inputs,
                                        const TensorPrecompute& tensors);

struct ImposedDisplacementSolution {
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> node_displacements;  // n × 3, m
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> contact_forces;      // m × 3, N
};

// Direct reference: the nodes `imposed_nodes` (distinct, all axes free) are moved by
// `imposed_displacements` (one row each), every other free dof is in equilibrium.
// contact_forces(i) is the force on the tissue at imposed node i (K u at its dofs).
core::Expected<ImposedDisplacementSolution> solve_imposed_displacements(
    const AssembledTet& assembled, std::span<const int> imposed_nodes,
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>&
        imposed_displacements);

// How closely the float32 runtime model reproduces the direct solve on a built image: one
// contact at the softest contact node (smallest trace of F(k), where a press deforms most), then
// the 2 and the `max_contacts` contact nodes nearest it pressed together (a jaw-sized patch),
// each pressed by 2 % of the mesh's bounding-box diagonal towards its centroid. Errors are
// relative to the largest displacement / contact force of the direct solution.
struct TensorAgreement {
  int contact_count = 0;
  double displacement_error = 0.0;  // max over nodes and axes
  double force_error = 0.0;         // max over contacts of |Δf|
  double direct_solve_s = 0.0;      // the reference's own factorisation and solve
  double tensor_solve_us = 0.0;     // TensorModel::solve + update_field, one call
};
core::Expected<std::vector<TensorAgreement>> measure_tensor_agreement(
    const TetMesh& mesh, const AssembledTet& assembled, std::span<const std::byte> image_bytes,
    std::uint32_t max_contacts);

}  // namespace trainer::model::offline
