// The trade study's double reference chain, its implicit substep: Catheter::substep (the
// pentadiagonal step with implicit bending and contacts, model/runtime/src/catheter_solve.cpp)
// line for line in double, for one wall normal and single-particle wall planes as the study
// sets them (docs/catheter.md, "Integration and substep"; docs/tradeoff-models.md).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "trainer/model/catheter.hpp"
#include "trainer/model_offline/catheter_tradeoff.hpp"

namespace trainer::model::offline::detail {

struct ReferenceChainState {
  const ChainStiffness<double>* stiffness = nullptr;
  double mass_kg = 0.0;
  double damping_n_s_per_m = 0.0;
  double radius_m = 0.0;
  CatheterWallContact contact;
  std::span<const std::size_t> wall_particles;
  std::span<const Eigen::Vector3d> wall_points_m;
  Eigen::Vector3d wall_normal = Eigen::Vector3d::UnitY();
  std::vector<Eigen::Vector3d>* positions = nullptr;
  std::vector<Eigen::Vector3d>* velocities = nullptr;
  std::span<const Eigen::Vector3d> external_n;
  std::span<const Eigen::Vector3d> targets_m;
  std::span<const Eigen::Vector3d> saved_positions_m;
  std::span<Eigen::Vector3d> hold_forces_n;
  std::span<const std::uint8_t> held;
};

// One implicit substep of dt_s (fraction of the period, hold_step how far through it ends).
void reference_implicit_substep(ReferenceChainState& state, double dt_s, double period_s,
                                double fraction, double hold_step);

}  // namespace trainer::model::offline::detail
