// Modal analysis on the real shell (assemble_shell on the duct tube): both solvers agree, and
// their time on the default duct size decides the default method (logged, not asserted);
// the static correction restores the exact static response on the shell as well.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/SparseCholesky>

#include "modal_test_structures.hpp"
#include "trainer/model_offline/mesh_generators.hpp"
#include "trainer/model_offline/modal_analysis.hpp"
#include "trainer/model_offline/residual.hpp"
#include "trainer/model_offline/shell_assembly.hpp"

namespace trainer::model::offline {
namespace {

using testing::node_row_mass;
using testing::shape_mismatch;

// The paper's duct: ~9 mm diameter, a soft wall 1 mm thick, clamped at x = 0.
AssembledShell duct(int rings, int segments) {
  auto mesh = make_tube(4.5e-3, 40e-3, rings, segments);
  EXPECT_TRUE(mesh.has_value()) << mesh.error().message;
  const ShellMaterial material{1e6, 0.45, 1e-3, 1050.0};
  const std::vector<DofFix> fixes{{"clamped", {kUx, kUy, kUz, kRx, kRy, kRz}}};
  auto shell = assemble_shell(*mesh, material, BendingElement::dkt, fixes);
  EXPECT_TRUE(shell.has_value()) << shell.error().message;
  return std::move(shell).value();
}

// Median wall time of `runs` calls, in milliseconds.
template <class Work>
double median_ms(int runs, Work&& work) {
  std::vector<double> times;
  for (int run = 0; run < runs; ++run) {
    const auto start = std::chrono::steady_clock::now();
    work();
    times.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
            .count());
  }
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

TEST(ModalShell, MethodsAgreeOnTheDefaultDuctAndTheFasterIsTheDefault) {
  const AssembledShell shell = duct(21, 16);  // 20 free rings × 16 = 320 free nodes, 336 in all
  ASSERT_EQ(shell.dofs.node_count, 336);
  const int r = 20;
  ModalOptions condensation;
  condensation.method = ModalMethod::condensation;
  ModalOptions shift_invert;
  shift_invert.method = ModalMethod::shift_invert;
  // r + 2 modes so that a repeated pair at the end is seen whole by the shape comparison.
  auto condensed = compute_modes(shell, r + 2, condensation);
  auto lanczos = compute_modes(shell, r + 2, shift_invert);
  ASSERT_TRUE(condensed.has_value()) << condensed.error().message;
  ASSERT_TRUE(lanczos.has_value()) << lanczos.error().message;
  double worst_eigenvalue = 0.0;
  for (int i = 0; i < r; ++i) {
    EXPECT_NEAR(lanczos->omega_squared[i] / condensed->omega_squared[i], 1.0, 1e-8) << "mode " << i;
    worst_eigenvalue = std::max(
        worst_eigenvalue, std::abs(lanczos->omega_squared[i] / condensed->omega_squared[i] - 1.0));
  }
  int compared = 0;
  const double mismatch =
      shape_mismatch(*condensed, *lanczos, node_row_mass(shell), r, false, &compared);
  EXPECT_LT(mismatch, 1e-6);
  EXPECT_GE(compared, r);
  std::printf(
      "[ modal agreement ] duct, r = %d: eigenvalues within %.1e relative, shapes within %.1e "
      "(repeated pairs compared as subspaces)\n",
      r, worst_eigenvalue, mismatch);

  const double condensation_ms = median_ms(3, [&] { (void)compute_modes(shell, r, condensation); });
  const double shift_invert_ms = median_ms(3, [&] { (void)compute_modes(shell, r, shift_invert); });
  std::printf(
      "[ modal timing ] duct %d nodes (%d translational dofs), r = %d: condensation %.1f ms, "
      "shift_invert %.1f ms (median of 3), shift_invert %.1fx faster\n",
      shell.dofs.node_count, 3 * 320, r, condensation_ms, shift_invert_ms,
      condensation_ms / shift_invert_ms);
  std::printf("[ modal timing ] f1 = %.2f Hz, f%d = %.2f Hz\n",
              std::sqrt(condensed->omega_squared[0]) / (2.0 * std::numbers::pi), r,
              std::sqrt(condensed->omega_squared[r - 1]) / (2.0 * std::numbers::pi));
  EXPECT_EQ(ModalOptions{}.method, ModalMethod::shift_invert);
}

TEST(ModalShell, StaticCorrectionIsExactOnTheShell) {
  const AssembledShell shell = duct(11, 12);
  auto basis = compute_modes(shell, 8);
  ASSERT_TRUE(basis.has_value()) << basis.error().message;
  const std::vector<int> surface = nodes_with_free_translation(shell.dofs);
  auto residual = compute_residual_compliance(shell, *basis, surface);
  ASSERT_TRUE(residual.has_value()) << residual.error().message;
  // A force pair at two surface nodes.
  Eigen::VectorXd free_force = Eigen::VectorXd::Zero(shell.dofs.free_count());
  Eigen::VectorXd nodal_force = Eigen::VectorXd::Zero(3 * shell.dofs.node_count);
  Eigen::VectorXd surface_force =
      Eigen::VectorXd::Zero(3 * static_cast<Eigen::Index>(surface.size()));
  const std::pair<std::size_t, Eigen::Vector3d> loads[] = {{70, {0.0, 0.01, -0.02}},
                                                           {101, {0.005, 0.0, 0.01}}};
  for (const auto& [k, force] : loads) {
    for (int axis = 0; axis < 3; ++axis) {
      free_force[shell.dofs.free_index[static_cast<std::size_t>(6 * surface[k] + axis)]] +=
          force[axis];
    }
    nodal_force.segment<3>(3 * surface[k]) += force;
    surface_force.segment<3>(3 * static_cast<Eigen::Index>(k)) += force;
  }
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> solver(shell.stiffness);
  const Eigen::VectorXd exact = solver.solve(free_force);
  const Eigen::VectorXd modal =
      basis->node_shapes * basis->omega_squared.cwiseInverse().cwiseProduct(
                               basis->node_shapes.transpose() * nodal_force);
  const Eigen::VectorXd corrected_surface = residual->compliance * surface_force;
  double worst = 0.0;
  double largest = 0.0;
  for (std::size_t k = 0; k < surface.size(); ++k) {
    for (int axis = 0; axis < 3; ++axis) {
      const double expected =
          exact[shell.dofs.free_index[static_cast<std::size_t>(6 * surface[k] + axis)]];
      const double corrected =
          modal[3 * surface[k] + axis] + corrected_surface[3 * static_cast<Eigen::Index>(k) + axis];
      largest = std::max(largest, std::abs(expected));
      worst = std::max(worst, std::abs(corrected - expected));
    }
  }
  EXPECT_LT(worst / largest, 1e-8);
  auto truncation = estimate_truncation_error(shell, *basis, surface);
  ASSERT_TRUE(truncation.has_value()) << truncation.error().message;
  std::printf(
      "[ truncation ] shell %d nodes, r = 8: local max %.3f mean %.3f, field max %.3f mean %.3f\n",
      shell.dofs.node_count, truncation->max_local_relative, truncation->mean_local_relative,
      truncation->max_field_relative, truncation->mean_field_relative);
  EXPECT_GT(truncation->mean_local_relative, 0.0);
}

}  // namespace
}  // namespace trainer::model::offline
