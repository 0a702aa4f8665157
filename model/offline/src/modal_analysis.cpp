// Modal analysis: condensation (eq. 15–16, dense) and sparse shift-invert Lanczos (Spectra).
#include "trainer/model_offline/modal_analysis.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <numeric>
#include <string>

#include <Spectra/SymGEigsShiftSolver.h>
#include <Eigen/Dense>
#include <Eigen/SparseCholesky>

namespace trainer::model::offline {
namespace {

using SparseMatrix = Eigen::SparseMatrix<double>;

std::string describe_count(int value, const char* what) {
  return std::to_string(value) + " " + what;
}

// Checks the AssembledShell contract that modal analysis relies on.
core::Expected<void> check_shell(const AssembledShell& shell) {
  const DofMap& dofs = shell.dofs;
  const int free_count = dofs.free_count();
  if (dofs.node_count <= 0) return core::make_error("modal analysis: shell has no nodes");
  if (static_cast<int>(dofs.free_index.size()) != kShellDofsPerNode * dofs.node_count) {
    return core::make_error("modal analysis: DofMap.free_index has " +
                            std::to_string(dofs.free_index.size()) + " entries, expected 6 × " +
                            describe_count(dofs.node_count, "nodes"));
  }
  if (shell.stiffness.rows() != free_count || shell.stiffness.cols() != free_count) {
    return core::make_error(
        "modal analysis: stiffness is " + std::to_string(shell.stiffness.rows()) + " × " +
        std::to_string(shell.stiffness.cols()) + ", expected " + std::to_string(free_count) +
        " × " + std::to_string(free_count) + " (the free dofs)");
  }
  if (shell.lumped_mass.size() != free_count) {
    return core::make_error("modal analysis: lumped_mass has " +
                            std::to_string(shell.lumped_mass.size()) + " entries, expected " +
                            describe_count(free_count, "free dofs"));
  }
  for (int f = 0; f < free_count; ++f) {
    const int node_dof = dofs.free_to_node_dof[static_cast<std::size_t>(f)];
    if (node_dof < 0 || node_dof >= kShellDofsPerNode * dofs.node_count ||
        dofs.free_index[static_cast<std::size_t>(node_dof)] != f) {
      return core::make_error("modal analysis: DofMap is inconsistent at free dof " +
                              std::to_string(f));
    }
    const double mass = shell.lumped_mass[f];
    const bool translational = node_dof % kShellDofsPerNode < 3;
    if (translational && !(mass > 0.0 && std::isfinite(mass))) {
      return core::make_error("modal analysis: lumped mass of node " +
                              std::to_string(node_dof / kShellDofsPerNode) + " dof " +
                              std::to_string(node_dof % kShellDofsPerNode) + " is " +
                              std::to_string(mass) + " kg, expected > 0 on translations");
    }
    if (!translational && mass != 0.0) {
      return core::make_error(
          "modal analysis: lumped mass of node " + std::to_string(node_dof / kShellDofsPerNode) +
          " rotation dof " + std::to_string(node_dof % kShellDofsPerNode) + " is " +
          std::to_string(mass) + ", expected 0 (the modes are M-orthonormal over translations)");
    }
  }
  return {};
}

// Free dof → position in the translational block (≥ 0) or in the rotational block (−1 − pos).
std::vector<int> block_positions(const DofMap& dofs, int& translational_count,
                                 int& rotational_count) {
  std::vector<int> position(static_cast<std::size_t>(dofs.free_count()));
  translational_count = 0;
  rotational_count = 0;
  for (int f = 0; f < dofs.free_count(); ++f) {
    const int dof = dofs.free_to_node_dof[static_cast<std::size_t>(f)] % kShellDofsPerNode;
    position[static_cast<std::size_t>(f)] =
        dof < 3 ? translational_count++ : -1 - rotational_count++;
  }
  return position;
}

// Upper estimate of the spectrum, max over translational dofs of K_ii / M_ii (rad²/s²).
double spectrum_scale(const AssembledShell& shell) {
  double scale = 0.0;
  for (int f = 0; f < shell.dofs.free_count(); ++f) {
    if (shell.lumped_mass[f] > 0.0) {
      scale = std::max(scale, shell.stiffness.coeff(f, f) / shell.lumped_mass[f]);
    }
  }
  return scale;
}

// Eigenvalue refusal: a free rigid-body motion shows as ω² ≈ 0 (either sign, round-off of
// order 1e-16..1e-13 of the spectrum scale). The duct's lowest mode is 1e-5..3e-5 of it
// (measured for 10..40 rings of 16 segments), far above the 1e-11 threshold.
core::Expected<void> check_positive(const Eigen::VectorXd& omega_squared, double scale) {
  for (Eigen::Index i = 0; i < omega_squared.size(); ++i) {
    if (!(omega_squared[i] > 1e-11 * scale) || !std::isfinite(omega_squared[i])) {
      return core::make_error(
          "modal analysis: mode " + std::to_string(i + 1) +
          " has ω² = " + std::to_string(omega_squared[i]) +
          " rad²/s², expected > 0: the structure has a free rigid-body motion (fix more dofs)");
    }
  }
  return {};
}

// Deterministic sign: largest-magnitude entry positive.
void normalise_signs(Eigen::MatrixXd& shapes) {
  for (Eigen::Index mode = 0; mode < shapes.cols(); ++mode) {
    Eigen::Index largest = 0;
    shapes.col(mode).cwiseAbs().maxCoeff(&largest);
    if (shapes(largest, mode) < 0.0) shapes.col(mode) *= -1.0;
  }
}

ModalBasis make_basis(const TranslationalDofs& translations, int node_count,
                      const Eigen::MatrixXd& translational_shapes,
                      const Eigen::VectorXd& omega_squared, ModalMethod method) {
  ModalBasis basis;
  basis.node_count = node_count;
  basis.method = method;
  basis.omega_squared = omega_squared;
  basis.node_shapes = Eigen::MatrixXd::Zero(3 * node_count, translational_shapes.cols());
  for (std::size_t j = 0; j < translations.node_rows.size(); ++j) {
    basis.node_shapes.row(translations.node_rows[j]) =
        translational_shapes.row(static_cast<Eigen::Index>(j));
  }
  normalise_signs(basis.node_shapes);
  return basis;
}

core::Expected<ModalBasis> modes_by_condensation(const AssembledShell& shell, int mode_count) {
  int nt = 0;
  int nr = 0;
  const std::vector<int> position = block_positions(shell.dofs, nt, nr);
  // Split K into the translational/rotational blocks (eq. 15).
  std::vector<Eigen::Triplet<double>> tt;
  std::vector<Eigen::Triplet<double>> tr;
  std::vector<Eigen::Triplet<double>> rr;
  for (int col = 0; col < shell.stiffness.outerSize(); ++col) {
    for (SparseMatrix::InnerIterator it(shell.stiffness, col); it; ++it) {
      const int p_row = position[static_cast<std::size_t>(it.row())];
      const int p_col = position[static_cast<std::size_t>(it.col())];
      if (p_row >= 0 && p_col >= 0) {
        tt.emplace_back(p_row, p_col, it.value());
      } else if (p_row >= 0) {
        tr.emplace_back(p_row, -1 - p_col, it.value());
      } else if (p_col < 0) {
        rr.emplace_back(-1 - p_row, -1 - p_col, it.value());
      }
    }
  }
  Eigen::MatrixXd condensed = Eigen::MatrixXd::Zero(nt, nt);
  for (const auto& t : tt) condensed(t.row(), t.col()) += t.value();
  if (nr > 0) {
    SparseMatrix k_tr(nt, nr);
    SparseMatrix k_rr(nr, nr);
    k_tr.setFromTriplets(tr.begin(), tr.end());
    k_rr.setFromTriplets(rr.begin(), rr.end());
    Eigen::SimplicialLDLT<SparseMatrix> rotational(k_rr);
    if (rotational.info() != Eigen::Success || (rotational.vectorD().array() <= 0.0).any()) {
      return core::make_error(
          "modal analysis (condensation): the rotational stiffness block K_rr (" +
          std::to_string(nr) +
          " dofs) is not positive definite: a rotation without stiffness (drilling "
          "stiffness missing?)");
    }
    const Eigen::MatrixXd k_rt = Eigen::MatrixXd(k_tr.transpose());
    const Eigen::MatrixXd slaved = rotational.solve(k_rt);  // K_rr⁻¹ K_rt, eq. (16)
    condensed.noalias() -= k_tr * slaved;
  }
  condensed = 0.5 * (condensed + condensed.transpose()).eval();

  // Scale by M_t^-1/2 so the generalized problem becomes a standard symmetric one.
  Eigen::VectorXd inverse_root_mass(nt);
  for (int f = 0; f < shell.dofs.free_count(); ++f) {
    const int p = position[static_cast<std::size_t>(f)];
    if (p >= 0) inverse_root_mass[p] = 1.0 / std::sqrt(shell.lumped_mass[f]);
  }
  const Eigen::MatrixXd scaled =
      inverse_root_mass.asDiagonal() * condensed * inverse_root_mass.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(scaled);
  if (solver.info() != Eigen::Success) {
    return core::make_error(
        "modal analysis (condensation): dense eigensolver did not converge on " +
        describe_count(nt, "translational dofs"));
  }
  const Eigen::VectorXd omega_squared = solver.eigenvalues().head(mode_count);
  if (auto ok = check_positive(omega_squared, spectrum_scale(shell)); !ok) {
    return std::move(ok).error();
  }
  const Eigen::MatrixXd shapes =
      inverse_root_mass.asDiagonal() * solver.eigenvectors().leftCols(mode_count);
  return make_basis(translational_dofs(shell.dofs), shell.dofs.node_count, shapes, omega_squared,
                    ModalMethod::condensation);
}

// y = [(K − σM)⁻¹ [x; 0]]_t: the translational block of the shifted inverse of the full
// sparse system, which equals (K_c − σ M_t)⁻¹ x (Schur complement, zero rotational mass).
class TranslationalShiftInvert {
 public:
  using Scalar = double;

  TranslationalShiftInvert(const AssembledShell& shell, const std::vector<int>& translational_free)
      : shell_(shell),
        translational_free_(translational_free),
        full_in_(Eigen::VectorXd::Zero(shell.dofs.free_count())) {}

  Eigen::Index rows() const { return static_cast<Eigen::Index>(translational_free_.size()); }
  Eigen::Index cols() const { return rows(); }

  void set_shift(double sigma) {
    SparseMatrix shifted = shell_.stiffness;
    for (Eigen::Index f = 0; f < shifted.rows(); ++f) {
      if (shell_.lumped_mass[f] != 0.0) shifted.coeffRef(f, f) -= sigma * shell_.lumped_mass[f];
    }
    factorisation_.compute(shifted);
    factorised_ =
        factorisation_.info() == Eigen::Success && (factorisation_.vectorD().array() > 0.0).all();
  }
  bool factorised() const { return factorised_; }

  void perform_op(const double* x_in, double* y_out) const {
    for (std::size_t j = 0; j < translational_free_.size(); ++j) {
      full_in_[translational_free_[j]] = x_in[j];
    }
    full_out_ = factorisation_.solve(full_in_);
    for (std::size_t j = 0; j < translational_free_.size(); ++j) {
      y_out[j] = full_out_[translational_free_[j]];
    }
  }

 private:
  const AssembledShell& shell_;
  const std::vector<int>& translational_free_;
  Eigen::SimplicialLDLT<SparseMatrix> factorisation_;
  bool factorised_ = false;
  mutable Eigen::VectorXd full_in_;  // rotational entries stay zero
  mutable Eigen::VectorXd full_out_;
};

// y = M_t x (diagonal).
class TranslationalMass {
 public:
  using Scalar = double;
  explicit TranslationalMass(Eigen::VectorXd mass) : mass_(std::move(mass)) {}
  Eigen::Index rows() const { return mass_.size(); }
  Eigen::Index cols() const { return mass_.size(); }
  void perform_op(const double* x_in, double* y_out) const {
    for (Eigen::Index i = 0; i < mass_.size(); ++i) y_out[i] = mass_[i] * x_in[i];
  }

 private:
  Eigen::VectorXd mass_;
};

core::Expected<ModalBasis> modes_by_shift_invert(const AssembledShell& shell, int mode_count,
                                                 const ModalOptions& options) {
  const TranslationalDofs translations = translational_dofs(shell.dofs);
  const int nt = static_cast<int>(translations.free_indices.size());
  if (mode_count >= nt) {
    return core::make_error(
        "modal analysis (shift_invert): " + describe_count(mode_count, "modes") + " requested of " +
        describe_count(nt, "translational dofs") +
        "; Lanczos needs fewer modes than dofs, use the condensation method");
  }
  Eigen::VectorXd mass(nt);
  double stiffness_over_mass_sum = 0.0;
  for (int j = 0; j < nt; ++j) {
    const int f = translations.free_indices[static_cast<std::size_t>(j)];
    mass[j] = shell.lumped_mass[f];
    stiffness_over_mass_sum += shell.stiffness.coeff(f, f) / mass[j];
  }
  double sigma = options.shift_rad2_per_s2;
  if (std::isnan(sigma)) sigma = -1e-6 * stiffness_over_mass_sum / nt;
  if (!std::isfinite(sigma)) {
    return core::make_error(
        "modal analysis (shift_invert): shift must be finite or NaN (automatic)");
  }
  int subspace = options.lanczos_vectors;
  if (subspace == 0) subspace = std::max(2 * mode_count + 1, mode_count + 20);
  subspace = std::min(subspace, nt);
  if (subspace <= mode_count) {
    return core::make_error("modal analysis (shift_invert): lanczos_vectors = " +
                            std::to_string(options.lanczos_vectors) + ", expected > mode count " +
                            std::to_string(mode_count));
  }

  TranslationalShiftInvert op(shell, translations.free_indices);
  TranslationalMass mass_op(mass);
  using Solver = Spectra::SymGEigsShiftSolver<TranslationalShiftInvert, TranslationalMass,
                                              Spectra::GEigsMode::ShiftInvert>;
  Eigen::VectorXd omega_squared;
  Eigen::MatrixXd shapes;
  try {
    Solver solver(op, mass_op, mode_count, subspace, sigma);
    if (!op.factorised()) {
      return core::make_error(
          "modal analysis (shift_invert): K − σM (σ = " + std::to_string(sigma) +
          " rad²/s²) is not positive definite: a free rigid-body motion or a "
          "dof without stiffness; fix more dofs");
    }
    solver.init();
    solver.compute(Spectra::SortRule::LargestMagn, options.max_restarts, options.tolerance,
                   Spectra::SortRule::SmallestAlge);
    if (solver.info() != Spectra::CompInfo::Successful) {
      return core::make_error("modal analysis (shift_invert): Lanczos did not converge to " +
                              describe_count(mode_count, "modes") + " in " +
                              std::to_string(options.max_restarts) + " restarts (subspace " +
                              std::to_string(subspace) + ", tolerance " +
                              std::to_string(options.tolerance) + ")");
    }
    omega_squared = solver.eigenvalues();
    shapes = solver.eigenvectors();
  } catch (const std::exception& error) {
    return core::make_error(std::string("modal analysis (shift_invert): Spectra failed: ") +
                            error.what());
  }
  // Re-normalise in M (the Lanczos basis is M-orthonormal to round-off; make it exact).
  for (Eigen::Index mode = 0; mode < shapes.cols(); ++mode) {
    const double norm = std::sqrt(shapes.col(mode).dot(mass.asDiagonal() * shapes.col(mode)));
    shapes.col(mode) /= norm;
  }
  if (auto ok = check_positive(omega_squared, spectrum_scale(shell)); !ok) {
    return std::move(ok).error();
  }
  return make_basis(translations, shell.dofs.node_count, shapes, omega_squared,
                    ModalMethod::shift_invert);
}

}  // namespace

const char* to_string(ModalMethod method) noexcept {
  switch (method) {
    case ModalMethod::condensation: return "condensation";
    case ModalMethod::shift_invert: return "shift_invert";
  }
  return "unknown";
}

TranslationalDofs translational_dofs(const DofMap& dofs) {
  TranslationalDofs result;
  for (int f = 0; f < dofs.free_count(); ++f) {
    const int node_dof = dofs.free_to_node_dof[static_cast<std::size_t>(f)];
    const int dof = node_dof % kShellDofsPerNode;
    if (dof < 3) {
      result.free_indices.push_back(f);
      result.node_rows.push_back(node_dof / kShellDofsPerNode * 3 + dof);
    }
  }
  return result;
}

core::Expected<ModalBasis> compute_modes(const AssembledShell& shell, int mode_count,
                                         const ModalOptions& options) {
  if (auto ok = check_shell(shell); !ok) return std::move(ok).error();
  const int nt = static_cast<int>(translational_dofs(shell.dofs).free_indices.size());
  if (mode_count <= 0 || mode_count > nt) {
    return core::make_error("modal analysis: mode_count = " + std::to_string(mode_count) +
                            ", expected 1.." + std::to_string(nt) +
                            " (the translational free dofs)");
  }
  switch (options.method) {
    case ModalMethod::condensation: return modes_by_condensation(shell, mode_count);
    case ModalMethod::shift_invert: return modes_by_shift_invert(shell, mode_count, options);
  }
  return core::make_error("modal analysis: unknown method");
}

core::Expected<Eigen::VectorXd> modal_damping(const Eigen::VectorXd& omega_squared,
                                              const DampingModel& damping) {
  const auto valid = [](double value) { return std::isfinite(value) && value >= 0.0; };
  if (!valid(damping.damping_ratio) || !valid(damping.rayleigh.mass_proportional_per_s) ||
      !valid(damping.rayleigh.stiffness_proportional_s)) {
    return core::make_error(
        "modal damping: ζ = " + std::to_string(damping.damping_ratio) +
        ", α_M = " + std::to_string(damping.rayleigh.mass_proportional_per_s) +
        " 1/s, β_K = " + std::to_string(damping.rayleigh.stiffness_proportional_s) +
        " s: expected finite values ≥ 0");
  }
  Eigen::VectorXd alpha(omega_squared.size());
  for (Eigen::Index i = 0; i < omega_squared.size(); ++i) {
    if (!(omega_squared[i] > 0.0) || !std::isfinite(omega_squared[i])) {
      return core::make_error("modal damping: ω² of mode " + std::to_string(i + 1) + " is " +
                              std::to_string(omega_squared[i]) + ", expected > 0");
    }
    alpha[i] = 2.0 * damping.damping_ratio * std::sqrt(omega_squared[i]) +
               damping.rayleigh.mass_proportional_per_s +
               damping.rayleigh.stiffness_proportional_s * omega_squared[i];
  }
  return alpha;
}

}  // namespace trainer::model::offline
