// Modal analysis of an assembled shell (METHODS.md §1 steps 5–7, Basdogan eq. 15–22): the r
// lowest modes of K φ = ω² M φ with the lumped mass (zero on rotations), mapped back to
// per-node translations, and the modal damping that both the reduced model (NIRMS) and the
// full-system reference (DNIOS, dnios.hpp) integrate. Offline, double precision.
//
// Two solvers give the same modes (tested to agree):
//  * condensation: static (Guyan) condensation of the rotations, eq. (15–16),
//    K_c = K_tt − K_tr K_rr⁻¹ K_rt, dense over the translational free dofs, then the dense
//    symmetric eigenproblem of M_t^-1/2 K_c M_t^-1/2. O(n_t³) time, O(n_t²) memory.
//  * shift_invert: Lanczos (Spectra) on the uncondensed sparse problem. With zero rotational
//    mass the rotations are slaved to the translations, so the operator (K − σM)⁻¹ M acts only
//    through the translational block; the iteration runs on the translational dofs with the
//    sparse factorisation of the full K − σM (whose translational block of the inverse is
//    exactly (K_c − σ M_t)⁻¹ by the Schur complement), so M_t is positive definite as Spectra
//    requires and no condensed matrix is ever formed.
// Measured on the default duct size (20 rings × 16 segments, modal_analysis_test log line),
// shift_invert is the faster at equal result; it is the default.
#pragma once

#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "trainer/core/expected.hpp"
#include "trainer/model_offline/shell_model.hpp"

namespace trainer::model::offline {

enum class ModalMethod : std::uint8_t {
  condensation,  // eq. (15–16) then dense eigensolver; can return every mode
  shift_invert,  // sparse Lanczos shift-invert; needs mode_count < translational free dofs
};

const char* to_string(ModalMethod method) noexcept;

struct ModalOptions {
  ModalMethod method = ModalMethod::shift_invert;
  // Shift σ (rad²/s²) for shift_invert. NaN = automatic: a small negative value
  // (−1e-6 × the mean translational K_ii/M_ii), so K − σM stays positive definite and the
  // modes nearest σ are the lowest ones.
  double shift_rad2_per_s2 = std::numeric_limits<double>::quiet_NaN();
  int max_restarts = 1000;   // Lanczos restarts before "did not converge"
  double tolerance = 1e-12;  // Spectra's relative Ritz residual tolerance
  // Lanczos subspace size; 0 = automatic (max(2r + 1, r + 20), capped at n_t).
  int lanczos_vectors = 0;
};

// Translational free dofs: the free dofs that are ux, uy or uz of some node, in free order.
struct TranslationalDofs {
  std::vector<int> free_indices;  // free dof index of each translational free dof
  std::vector<int> node_rows;     // node*3 + axis for each (row in ModalBasis::node_shapes)
};
TranslationalDofs translational_dofs(const DofMap& dofs);

// r modes, ascending in ω², M-orthonormal over the translational dofs (Φᵀ M Φ = I), so the
// mode shapes carry units of kg^-1/2 and the modal coordinates kg^1/2·m. Sign convention:
// the largest-magnitude entry of each mode is positive (ties: the first one).
struct ModalBasis {
  int node_count = 0;
  Eigen::MatrixXd node_shapes;    // 3n × r, row node*3 + axis; zero rows at fixed dofs
  Eigen::VectorXd omega_squared;  // r, rad²/s², ascending, > 0
  ModalMethod method = ModalMethod::shift_invert;  // which solver produced it
  int mode_count() const { return static_cast<int>(omega_squared.size()); }
};

// Refuses (message says why): inconsistent shell sizes, non-zero rotational mass or
// non-positive translational mass, mode_count ≤ 0 or > translational free dofs
// (shift_invert: ≥), a factorisation failure, Lanczos non-convergence, and a non-positive
// ω² (a free rigid-body motion: fix more dofs).
core::Expected<ModalBasis> compute_modes(const AssembledShell& shell, int mode_count,
                                         const ModalOptions& options = {});

// Damping of each mode as the coefficient α_i of ẋ_i in ẍ_i + α_i ẋ_i + ω_i² x_i = f_i
// (1/s). Sources add: a modal damping ratio ζ (α_i = 2 ζ ω_i, Basdogan eq. 20) and Rayleigh
// damping B = α_M M + β_K K, whose modal image is α_i = α_M + β_K ω_i² because Φᵀ M Φ = I and
// Φᵀ K Φ = Ω². The full-system reference (FullNewmark) integrates B = α_M M + β_K K, so
// NIRMS and DNIOS integrate the same damped system only when ζ = 0 (a ζ that is not of
// Rayleigh form has no sparse full-system B); use the Rayleigh terms for comparisons.
struct RayleighDamping {
  double mass_proportional_per_s = 0.0;   // α_M, 1/s
  double stiffness_proportional_s = 0.0;  // β_K, s
};
struct DampingModel {
  double damping_ratio = 0.0;  // ζ, dimensionless, same for every mode
  RayleighDamping rayleigh;
};
// Refuses negative or non-finite coefficients and non-positive ω².
core::Expected<Eigen::VectorXd> modal_damping(const Eigen::VectorXd& omega_squared,
                                              const DampingModel& damping);

}  // namespace trainer::model::offline
