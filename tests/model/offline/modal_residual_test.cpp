// Residual compliance: r modes + R restore the exact static response K⁻¹F at the chosen
// nodes; R is symmetric PSD and vanishes with every mode; the truncation error estimate
// falls as modes are added; refusals.
#include "trainer/model_offline/residual.hpp"

#include <random>

#include <gtest/gtest.h>
#include <Eigen/Dense>
#include <Eigen/SparseCholesky>

#include "modal_test_structures.hpp"

namespace trainer::model::offline {
namespace {

using testing::frame_tube;

// Exact static translations (3n) for nodal forces (3n), by an independent sparse solve.
Eigen::VectorXd exact_static(const AssembledShell& shell, const Eigen::VectorXd& nodal_force) {
  Eigen::VectorXd free_force = Eigen::VectorXd::Zero(shell.dofs.free_count());
  for (int f = 0; f < shell.dofs.free_count(); ++f) {
    const int node_dof = shell.dofs.free_to_node_dof[static_cast<std::size_t>(f)];
    if (node_dof % 6 < 3) free_force[f] = nodal_force[node_dof / 6 * 3 + node_dof % 6];
  }
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> solver(shell.stiffness);
  const Eigen::VectorXd free_displacement = solver.solve(free_force);
  Eigen::VectorXd result = Eigen::VectorXd::Zero(nodal_force.size());
  for (int f = 0; f < shell.dofs.free_count(); ++f) {
    const int node_dof = shell.dofs.free_to_node_dof[static_cast<std::size_t>(f)];
    if (node_dof % 6 < 3) result[node_dof / 6 * 3 + node_dof % 6] = free_displacement[f];
  }
  return result;
}

class ResidualByModeCount : public ::testing::TestWithParam<int> {};

TEST_P(ResidualByModeCount, ModesPlusResidualGiveTheExactStaticResponse) {
  const int r = GetParam();
  const auto tube = frame_tube(10, 8, 0.05);
  auto basis = compute_modes(tube.shell, r);
  ASSERT_TRUE(basis.has_value()) << basis.error().message;
  const std::vector<int> surface = nodes_with_free_translation(tube.shell.dofs);
  ASSERT_EQ(surface.size(), 72U);  // rings 1..9
  auto residual = compute_residual_compliance(tube.shell, *basis, surface);
  ASSERT_TRUE(residual.has_value()) << residual.error().message;
  ASSERT_EQ(residual->compliance.rows(), 3 * 72);

  std::mt19937 random(static_cast<unsigned>(r));
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  for (int trial = 0; trial < 5; ++trial) {
    // Forces at 1 to 5 random surface nodes.
    Eigen::VectorXd nodal_force = Eigen::VectorXd::Zero(3 * tube.shell.dofs.node_count);
    Eigen::VectorXd surface_force = Eigen::VectorXd::Zero(3 * 72);
    for (int load = 0; load <= trial; ++load) {
      const auto k = static_cast<std::size_t>(std::uniform_int_distribution<int>(0, 71)(random));
      const Eigen::Vector3d force(uniform(random), uniform(random), uniform(random));
      nodal_force.segment<3>(3 * surface[k]) += force;
      surface_force.segment<3>(3 * static_cast<Eigen::Index>(k)) += force;
    }
    const Eigen::VectorXd exact = exact_static(tube.shell, nodal_force);
    const Eigen::VectorXd modal_coordinates = basis->omega_squared.cwiseInverse().cwiseProduct(
        basis->node_shapes.transpose() * nodal_force);
    const Eigen::VectorXd modal = basis->node_shapes * modal_coordinates;
    const Eigen::VectorXd correction = residual->compliance * surface_force;
    double worst = 0.0;
    double largest = 0.0;
    double modal_only_worst = 0.0;
    for (std::size_t k = 0; k < surface.size(); ++k) {
      const Eigen::Vector3d expected = exact.segment<3>(3 * surface[k]);
      const Eigen::Vector3d corrected = modal.segment<3>(3 * surface[k]) +
                                        correction.segment<3>(3 * static_cast<Eigen::Index>(k));
      largest = std::max(largest, expected.norm());
      worst = std::max(worst, (corrected - expected).norm());
      modal_only_worst =
          std::max(modal_only_worst, (modal.segment<3>(3 * surface[k]) - expected).norm());
    }
    EXPECT_LT(worst / largest, 1e-8) << "r = " << r << " trial " << trial;
    EXPECT_GT(modal_only_worst / largest, 1e-3) << "the correction is doing real work";
  }
  // Symmetric positive semi-definite (the discarded modes' flexibility).
  const Eigen::MatrixXd& compliance = residual->compliance;
  EXPECT_LT((compliance - compliance.transpose()).cwiseAbs().maxCoeff(),
            1e-15 * compliance.cwiseAbs().maxCoeff());
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(compliance);
  EXPECT_GT(eigen.eigenvalues().minCoeff(), -1e-10 * eigen.eigenvalues().maxCoeff());
}

INSTANTIATE_TEST_SUITE_P(Residual, ResidualByModeCount, ::testing::Values(5, 20));

TEST(Residual, VanishesWithEveryModeAndCoversFixedNodes) {
  const auto tube = frame_tube(4, 5, 0.05);  // 15 free nodes, 45 translational dofs
  ModalOptions options;
  options.method = ModalMethod::condensation;
  auto basis = compute_modes(tube.shell, 45, options);
  ASSERT_TRUE(basis.has_value()) << basis.error().message;
  // Include a clamped node (0): its rows and columns are zero.
  const std::vector<int> nodes{0, 5, 9, 19};
  auto residual = compute_residual_compliance(tube.shell, *basis, nodes);
  ASSERT_TRUE(residual.has_value()) << residual.error().message;
  auto few = compute_modes(tube.shell, 3, options);
  ASSERT_TRUE(few.has_value());
  auto reference = compute_residual_compliance(tube.shell, *few, nodes);
  ASSERT_TRUE(reference.has_value());
  EXPECT_LT(residual->compliance.cwiseAbs().maxCoeff(),
            1e-9 * reference->compliance.cwiseAbs().maxCoeff());
  EXPECT_EQ(reference->compliance.topRows(3).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(reference->compliance.leftCols(3).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT(reference->compliance.bottomRightCorner(3, 3).cwiseAbs().maxCoeff(), 0.0);
}

TEST(TruncationError, FallsWithModesAndVanishesWithAll) {
  const auto tube = frame_tube(6, 6, 0.05);  // 30 free nodes, 90 translational dofs
  ModalOptions options;
  options.method = ModalMethod::condensation;
  auto basis = compute_modes(tube.shell, 90, options);
  ASSERT_TRUE(basis.has_value()) << basis.error().message;
  const std::vector<int> nodes = nodes_with_free_translation(tube.shell.dofs);
  double previous_max = 2.0;
  double previous_mean = 2.0;
  for (int r : {2, 5, 10, 20, 40}) {
    auto error = estimate_truncation_error(tube.shell, *basis, nodes, r);
    ASSERT_TRUE(error.has_value()) << error.error().message;
    EXPECT_EQ(error->mode_count, r);
    EXPECT_EQ(error->load_cases, 90);
    EXPECT_LE(error->max_local_relative, previous_max + 1e-12);
    EXPECT_LT(error->mean_local_relative, previous_mean);
    EXPECT_LE(error->mean_local_relative, error->max_local_relative);
    EXPECT_LE(error->mean_field_relative, error->max_field_relative);
    EXPECT_GE(error->worst_node, 6);
    EXPECT_GE(error->worst_axis, 0);
    previous_max = error->max_local_relative;
    previous_mean = error->mean_local_relative;
  }
  EXPECT_GT(previous_mean, 1e-4) << "40 of 90 modes still miss local flexibility";
  auto all = estimate_truncation_error(tube.shell, *basis, nodes);
  ASSERT_TRUE(all.has_value());
  EXPECT_EQ(all->mode_count, 90);
  EXPECT_LT(all->max_local_relative, 1e-9);
  EXPECT_LT(all->max_field_relative, 1e-9);
}

TEST(Residual, Refusals) {
  const auto tube = frame_tube(4, 5, 0.05);
  auto basis = compute_modes(tube.shell, 5);
  ASSERT_TRUE(basis.has_value());
  const auto refused = [](const core::Expected<ResidualCompliance>& result, const char* needle) {
    ASSERT_FALSE(result.has_value()) << needle;
    EXPECT_NE(result.error().message.find(needle), std::string::npos) << result.error().message;
  };
  refused(compute_residual_compliance(tube.shell, *basis, std::vector<int>{3, 20}),
          "node 20 out of range, expected 0..19");
  refused(compute_residual_compliance(tube.shell, *basis, std::vector<int>{3, 7, 3}),
          "node 3 listed twice");
  const auto other = frame_tube(5, 5, 0.05);
  auto other_basis = compute_modes(other.shell, 5);
  ASSERT_TRUE(other_basis.has_value());
  refused(compute_residual_compliance(tube.shell, *other_basis, std::vector<int>{3}),
          "modal basis is for 25 nodes");
  auto error = estimate_truncation_error(tube.shell, *basis, std::vector<int>{3}, 6);
  ASSERT_FALSE(error.has_value());
  EXPECT_NE(error.error().message.find("mode_count = 6"), std::string::npos)
      << error.error().message;
}

}  // namespace
}  // namespace trainer::model::offline
