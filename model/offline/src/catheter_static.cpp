// Load-stepped Newton for the clamped catheter chain (see catheter_static.hpp).
#include "trainer/model_offline/catheter_static.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "trainer/model/catheter.hpp"

namespace trainer::model::offline {
namespace {

using Vector3 = Eigen::Vector3d;

// Net force on every particle (internal + tip load), free particles 1..N−1 stacked.
class ClampedChain {
 public:
  ClampedChain(const ChainStiffness<double>& stiffness, std::uint32_t count)
      : stiffness_(stiffness), positions_(count), forces_(count) {}

  // Residual r = −(internal + external) forces on the free particles = ∇(total energy).
  Eigen::VectorXd gradient(const Eigen::VectorXd& free_positions, const Vector3& tip_force_n) {
    scatter(free_positions);
    for (Vector3& force : forces_) force.setZero();
    add_chain_forces<double>(std::span<const Vector3>(positions_), stiffness_, std::span<Vector3>(forces_));
    forces_.back() += tip_force_n;
    Eigen::VectorXd result(free_positions.size());
    for (std::size_t i = 1; i < positions_.size(); ++i) result.segment<3>(static_cast<Eigen::Index>(3 * (i - 1))) = -forces_[i];
    return result;
  }

  void scatter(const Eigen::VectorXd& free_positions) {
    positions_[0].setZero();
    for (std::size_t i = 1; i < positions_.size(); ++i) {
      positions_[i] = free_positions.segment<3>(static_cast<Eigen::Index>(3 * (i - 1)));
    }
  }
  const std::vector<Vector3>& positions() const { return positions_; }

  // Total potential energy (J): elastic energy minus the work of the fixed-direction tip load.
  double energy(const Eigen::VectorXd& free_positions, const Vector3& tip_force_n) {
    scatter(free_positions);
    return chain_energy<double>(std::span<const Vector3>(positions_), stiffness_) -
           tip_force_n.dot(positions_.back());
  }

 private:
  ChainStiffness<double> stiffness_;
  std::vector<Vector3> positions_;
  std::vector<Vector3> forces_;
};

}  // namespace

core::Expected<CatheterStaticResult> solve_catheter_static(const CatheterStaticInput& input) {
  const auto refuse = [](const std::string& what) { return core::make_error("catheter static: " + what); };
  if (!(std::isfinite(input.length_m) && input.length_m > 0.0)) return refuse("length must be > 0 m");
  if (!(std::isfinite(input.bending_stiffness_n_m2) && input.bending_stiffness_n_m2 > 0.0)) {
    return refuse("EI must be > 0 N·m²");
  }
  if (!(std::isfinite(input.axial_stiffness_n) && input.axial_stiffness_n > 0.0)) return refuse("EA must be > 0 N");
  if (input.particle_count < 3 || input.particle_count > Catheter::kMaxParticles) {
    return refuse("particles = " + std::to_string(input.particle_count) + ": expected 3.." +
                  std::to_string(Catheter::kMaxParticles));
  }
  if (!input.tip_force_n.allFinite()) return refuse("tip force is not finite");
  if (input.load_steps == 0 || input.max_newton_iterations == 0) {
    return refuse("load_steps and max_newton_iterations must be >= 1");
  }

  const std::uint32_t count = input.particle_count;
  const double rest_length_m = input.length_m / static_cast<double>(count - 1);
  ChainStiffness<double> stiffness;
  stiffness.axial_n_per_m = input.axial_stiffness_n / rest_length_m;
  stiffness.bending_n_m_per_rad = input.bending_stiffness_n_m2 / rest_length_m;
  stiffness.rest_length_m = rest_length_m;
  stiffness.root_clamped = true;
  stiffness.root_tangent = Vector3::UnitX();
  ClampedChain chain(stiffness, count);

  const Eigen::Index dofs = 3 * static_cast<Eigen::Index>(count - 1);
  Eigen::VectorXd free_positions(dofs);
  for (std::uint32_t i = 1; i < count; ++i) {
    free_positions.segment<3>(3 * static_cast<Eigen::Index>(i - 1)) = Vector3(rest_length_m * i, 0.0, 0.0);
  }
  // 1e-9 of the load scale, but not below the rounding of the axial spring forces (a few
  // ulps of EA), which no iteration can remove.
  const double tolerance_n =
      1e-9 * std::max(input.tip_force_n.norm(),
                      input.bending_stiffness_n_m2 / (input.length_m * input.length_m)) +
      64.0 * std::numeric_limits<double>::epsilon() * input.axial_stiffness_n;
  const double difference_step_m = 1e-6 * rest_length_m;

  CatheterStaticResult result;
  Eigen::MatrixXd tangent(dofs, dofs);
  for (std::uint32_t load_step = 1; load_step <= input.load_steps; ++load_step) {
    const Vector3 force_n = input.tip_force_n * (static_cast<double>(load_step) / input.load_steps);
    Eigen::VectorXd residual = chain.gradient(free_positions, force_n);
    std::uint32_t iteration = 0;
    while (residual.lpNorm<Eigen::Infinity>() > tolerance_n) {
      if (iteration++ == input.max_newton_iterations) {
        return refuse("Newton did not converge in load step " + std::to_string(load_step) + " of " +
                      std::to_string(input.load_steps) + " (residual " +
                      std::to_string(residual.lpNorm<Eigen::Infinity>()) + " N after " +
                      std::to_string(input.max_newton_iterations) +
                      " iterations): raise load_steps for a larger deflection");
      }
      for (Eigen::Index j = 0; j < dofs; ++j) {
        Eigen::VectorXd probe = free_positions;
        probe[j] += difference_step_m;
        const Eigen::VectorXd plus = chain.gradient(probe, force_n);
        probe[j] -= 2.0 * difference_step_m;
        tangent.col(j) = (plus - chain.gradient(probe, force_n)) / (2.0 * difference_step_m);
      }
      const Eigen::MatrixXd symmetric = 0.5 * (tangent + tangent.transpose());
      Eigen::VectorXd delta = symmetric.ldlt().solve(-residual);
      if (!delta.allFinite()) delta = symmetric.partialPivLu().solve(-residual);
      // Backtracking: a linearised step rotates segments along tangents and so stretches them,
      // which the stiff axial springs punish; accept the step once it lowers the total energy
      // or the residual (near equilibrium the energy change drowns in rounding, the residual
      // does not).
      const double energy = chain.energy(free_positions, force_n);
      double fraction = 1.0;
      Eigen::VectorXd trial = free_positions + delta;
      Eigen::VectorXd trial_residual = chain.gradient(trial, force_n);
      for (int halving = 0; halving < 30 && !(chain.energy(trial, force_n) < energy) &&
                            !(trial_residual.norm() < residual.norm());
           ++halving) {
        fraction *= 0.5;
        trial = free_positions + fraction * delta;
        trial_residual = chain.gradient(trial, force_n);
      }
      free_positions = trial;
      residual = trial_residual;
      ++result.iterations;
    }
    result.residual_n = residual.lpNorm<Eigen::Infinity>();
  }
  chain.scatter(free_positions);
  const std::vector<Vector3>& positions = chain.positions();
  result.positions_m.resize(3, count);
  for (std::uint32_t i = 0; i < count; ++i) result.positions_m.col(i) = positions[i];
  result.tip_position_m = positions.back();
  result.tip_displacement_m = positions.back() - Vector3(input.length_m, 0.0, 0.0);
  result.tip_rotation_rad = segment_angle<double>(Vector3::UnitX(), positions[count - 1] - positions[count - 2]);
  return result;
}

}  // namespace trainer::model::offline
