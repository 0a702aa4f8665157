// The offline → runtime modal chain: the float runtime model built from an offline basis
// against the double modal integration and against DNIOS, and displacement-driven contact
// against the exact static contact force from K.
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Dense>
#include <Eigen/SparseCholesky>

#include "modal_test_structures.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/model/modal_model.hpp"
#include "trainer/model_offline/dnios.hpp"
#include "trainer/model_offline/modal_analysis.hpp"
#include "trainer/model_offline/residual.hpp"

namespace trainer::model::offline {
namespace {

using testing::frame_tube;
using testing::RuntimeArrays;
using testing::to_runtime;

core::Arena make_arena() {
  auto arena = core::Arena::create(4 << 20);
  EXPECT_TRUE(arena.has_value());
  return std::move(arena).value();
}

ModalModel make_runtime(const RuntimeArrays& arrays, core::Arena& arena,
                        const ModalSettings& settings) {
  auto model = ModalModel::create(arrays.data(), arena, settings);
  if (!model) ADD_FAILURE() << model.error().message;
  return std::move(model).value();
}

// Contacts that come, move and go: (node, force N) per step.
std::vector<std::vector<std::pair<int, Eigen::Vector3d>>> load_history(int steps, int first_node,
                                                                       int last_node,
                                                                       unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  std::uniform_int_distribution<int> pick(first_node, last_node);
  std::vector<std::vector<std::pair<int, Eigen::Vector3d>>> history(
      static_cast<std::size_t>(steps));
  std::vector<std::pair<int, Eigen::Vector3d>> current;
  for (int step = 0; step < steps; ++step) {
    if (step % 25 == 0) {
      current.clear();
      const int contacts = step < 2 * steps / 3 ? 3 : 0;
      for (int c = 0; c < contacts; ++c) {
        current.emplace_back(pick(random), 0.01 * Eigen::Vector3d(uniform(random), uniform(random),
                                                                  uniform(random)));
      }
    }
    history[static_cast<std::size_t>(step)] = current;
  }
  return history;
}

template <class Reference>
double runtime_vs_reference(
    ModalModel& runtime, Reference& reference,
    const std::vector<std::vector<std::pair<int, Eigen::Vector3d>>>& history) {
  double worst = 0.0;
  double largest = 0.0;
  for (const auto& loads : history) {
    runtime.clear_forces();
    reference.clear_forces();
    for (const auto& [node, force] : loads) {
      const Vec3 force_f = force.template cast<float>();  // the runtime's force precision
      EXPECT_TRUE(runtime.add_node_force(static_cast<std::uint32_t>(node), force_f).is_ok());
      EXPECT_TRUE(reference.add_node_force(node, force_f.cast<double>()).has_value());
    }
    EXPECT_TRUE(runtime.step().is_ok());
    reference.step();
    for (int node = 0; node < static_cast<int>(runtime.node_count()); ++node) {
      const Eigen::Vector3d expected = reference.displacement(node);
      largest = std::max(largest, expected.cwiseAbs().maxCoeff());
      worst = std::max(
          worst, (runtime.displacement(static_cast<std::uint32_t>(node)).cast<double>() - expected)
                     .cwiseAbs()
                     .maxCoeff());
    }
  }
  EXPECT_GT(largest, 0.0);
  return worst / largest;
}

TEST(ModalRuntime, FloatModelMatchesTheDoubleModalIntegration) {
  const auto tube = frame_tube(10, 8, 0.05);
  auto basis = compute_modes(tube.shell, 20);
  ASSERT_TRUE(basis.has_value()) << basis.error().message;
  auto damping = modal_damping(basis->omega_squared, {0.02, {5.0, 1e-6}});
  ASSERT_TRUE(damping.has_value());
  const RuntimeArrays arrays = to_runtime(*basis, *damping, nullptr);
  // The reference integrates the float-rounded data the runtime sees, so the comparison
  // isolates the runtime's arithmetic (float shapes in, float displacements out).
  ModalBasis rounded = *basis;
  rounded.node_shapes = basis->node_shapes.cast<float>().cast<double>();
  rounded.omega_squared = basis->omega_squared.cast<float>().cast<double>();
  const Eigen::VectorXd rounded_damping = damping->cast<float>().cast<double>();
  const float dt = 1e-3F;
  auto reference = ModalNewmark::create(rounded, rounded_damping, static_cast<double>(dt));
  ASSERT_TRUE(reference.has_value()) << reference.error().message;
  core::Arena arena = make_arena();
  ModalModel runtime = make_runtime(arrays, arena, {dt, 0, false});
  const double error = runtime_vs_reference(runtime, *reference, load_history(1500, 8, 79, 5));
  std::printf("[ runtime vs double NIRMS ] r = 20: max relative history error %.2e\n", error);
  EXPECT_LT(error, 1e-5);
}

TEST(ModalRuntime, EveryModeTracksDnios) {
  const auto tube = frame_tube(4, 5, 0.05);  // 45 translational dofs
  ModalOptions options;
  options.method = ModalMethod::condensation;
  auto basis = compute_modes(tube.shell, 45, options);
  ASSERT_TRUE(basis.has_value()) << basis.error().message;
  const RayleighDamping rayleigh{20.0, 1e-5};
  auto damping = modal_damping(basis->omega_squared, {0.0, rayleigh});
  ASSERT_TRUE(damping.has_value());
  const float dt = 1e-3F;
  auto full = FullNewmark::create(tube.shell, rayleigh, static_cast<double>(dt));
  ASSERT_TRUE(full.has_value()) << full.error().message;
  const RuntimeArrays arrays = to_runtime(*basis, *damping, nullptr);
  core::Arena arena = make_arena();
  ModalModel runtime = make_runtime(arrays, arena, {dt, 0, false});
  // Float mode shapes and ω² (relative rounding 6e-8) bound the agreement (1.1e-7 measured).
  const double error = runtime_vs_reference(runtime, *full, load_history(600, 5, 19, 6));
  std::printf("[ runtime vs DNIOS ] every mode (45): max relative history error %.2e\n", error);
  EXPECT_LT(error, 1e-6);
}

// Exact static contact force for imposed displacements of `nodes`: F = [(K⁻¹)_KK]⁻¹ u*.
Eigen::VectorXd exact_contact_forces(const AssembledShell& shell, const std::vector<int>& nodes,
                                     const Eigen::VectorXd& imposed) {
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> solver(shell.stiffness);
  const auto rows = static_cast<Eigen::Index>(3 * nodes.size());
  Eigen::MatrixXd flexibility(rows, rows);
  for (Eigen::Index column = 0; column < rows; ++column) {
    Eigen::VectorXd unit = Eigen::VectorXd::Zero(shell.dofs.free_count());
    unit[shell.dofs.free_index[static_cast<std::size_t>(
        6 * nodes[static_cast<std::size_t>(column / 3)] + column % 3)]] = 1.0;
    const Eigen::VectorXd solution = solver.solve(unit);
    for (Eigen::Index row = 0; row < rows; ++row) {
      flexibility(row, column) = solution[shell.dofs.free_index[static_cast<std::size_t>(
          6 * nodes[static_cast<std::size_t>(row / 3)] + row % 3)]];
    }
  }
  return flexibility.ldlt().solve(imposed);
}

// Holds the contact nodes at `imposed` until the model settles; returns the last forces.
Eigen::VectorXd settle_imposed(ModalModel& model, const std::vector<int>& nodes,
                               const Eigen::VectorXd& imposed) {
  std::vector<ImposedDisplacement> targets;
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    targets.push_back({static_cast<std::uint32_t>(nodes[k]),
                       imposed.segment<3>(3 * static_cast<Eigen::Index>(k)).cast<float>()});
  }
  std::vector<Vec3> forces(nodes.size());
  for (int step = 0; step < 4000; ++step) {
    model.clear_forces();
    const core::Status solved = model.solve_imposed(targets, forces);
    EXPECT_TRUE(solved.is_ok()) << solved.detail();
    if (!solved) break;
    EXPECT_TRUE(model.step().is_ok());
  }
  for (const ImposedDisplacement& target : targets) {
    EXPECT_LT((model.displacement(target.node) - target.displacement_m).norm(),
              1e-5F * target.displacement_m.norm());
  }
  Eigen::VectorXd result(static_cast<Eigen::Index>(3 * nodes.size()));
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    result.segment<3>(3 * static_cast<Eigen::Index>(k)) = forces[k].cast<double>();
  }
  return result;
}

TEST(ModalRuntime, StaticCorrectionGivesTheExactStaticContactForceWithFewModes) {
  const auto tube = frame_tube(10, 8, 0.05);
  auto basis = compute_modes(tube.shell, 5);
  ASSERT_TRUE(basis.has_value()) << basis.error().message;
  auto damping = modal_damping(basis->omega_squared, {0.5, {}});  // settle quickly
  ASSERT_TRUE(damping.has_value());
  const std::vector<int> surface = nodes_with_free_translation(tube.shell.dofs);
  auto residual = compute_residual_compliance(tube.shell, *basis, surface);
  ASSERT_TRUE(residual.has_value()) << residual.error().message;
  const RuntimeArrays arrays = to_runtime(*basis, *damping, &*residual);
  core::Arena arena = make_arena();

  for (const std::vector<int>& nodes : {std::vector<int>{60}, std::vector<int>{45, 74}}) {
    Eigen::VectorXd imposed(static_cast<Eigen::Index>(3 * nodes.size()));
    for (Eigen::Index i = 0; i < imposed.size(); ++i)
      imposed[i] = 1e-4 * std::cos(1.0 + 2.0 * static_cast<double>(i));
    const Eigen::VectorXd exact = exact_contact_forces(tube.shell, nodes, imposed);
    ModalModel corrected = make_runtime(arrays, arena, {1e-3F, 0, true});
    const Eigen::VectorXd with_correction = settle_imposed(corrected, nodes, imposed);
    EXPECT_LT((with_correction - exact).norm() / exact.norm(), 1e-4) << nodes.size() << " contacts";
    // Without it, 5 modes are far too stiff locally (the point of the correction).
    ModalModel plain = make_runtime(arrays, arena, {1e-3F, 0, false});
    if (3 * nodes.size() <= 5) {
      const Eigen::VectorXd without = settle_imposed(plain, nodes, imposed);
      EXPECT_GT((without - exact).norm() / exact.norm(), 0.1);
    }
  }
}

}  // namespace
}  // namespace trainer::model::offline
