// Static verification of the particle catheter (METHODS.md §2): the chain of the runtime model
// (the same force law, trainer::model::add_chain_forces, here in double) clamped at the origin
// along +x — particle 0 fixed, root hinge 2 k_b on the +x tangent — under a tip force of fixed
// global direction (not a follower load), solved to static equilibrium by load-stepped Newton
// on the total energy. Large deflections are included (geometrically exact chain). The
// tangent stiffness is the central finite difference of the analytic internal-force gradient;
// convergence is judged on the exact residual, so the approximation only affects the rate.
#pragma once

#include <cstdint>

#include <Eigen/Core>

#include "trainer/core/expected.hpp"

namespace trainer::model::offline {

struct CatheterStaticInput {
  double length_m = 0.0;
  double bending_stiffness_n_m2 = 0.0;  // EI
  double axial_stiffness_n = 0.0;       // EA
  std::uint32_t particle_count = 0;     // N, 3..trainer::model::Catheter::kMaxParticles
  Eigen::Vector3d tip_force_n = Eigen::Vector3d::Zero();
  std::uint32_t load_steps = 20;        // equal load increments, each solved by Newton
  std::uint32_t max_newton_iterations = 200;  // per load step
};

struct CatheterStaticResult {
  Eigen::Vector3d tip_position_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d tip_displacement_m = Eigen::Vector3d::Zero();  // from the straight rest shape
  Eigen::Matrix3Xd positions_m;  // every particle at equilibrium
  std::uint32_t iterations = 0;  // Newton iterations over all load steps
  double residual_n = 0.0;       // largest net-force component on a free particle (N)
  double tip_rotation_rad = 0.0;  // angle of the last segment from +x
};

// Fails (message names the input) for out-of-range inputs, or when a load step does not
// reach a residual of 1e-9 × max(|F|, EI/L²) + 64 ε EA within max_newton_iterations.
core::Expected<CatheterStaticResult> solve_catheter_static(const CatheterStaticInput& input);

}  // namespace trainer::model::offline
