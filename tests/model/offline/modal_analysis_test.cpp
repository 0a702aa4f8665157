// Modal analysis: both solvers against analytic eigenvalues, against each other on a space
// frame with the shell's dof layout, M-orthonormality and order, modal damping, refusals.
#include "trainer/model_offline/modal_analysis.hpp"

#include <chrono>
#include <cmath>
#include <limits>

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include "modal_test_structures.hpp"

namespace trainer::model::offline {
namespace {

using testing::coupled_chain;
using testing::frame_tube;
using testing::node_row_mass;
using testing::shape_mismatch;

ModalOptions with_method(ModalMethod method) {
  ModalOptions options;
  options.method = method;
  return options;
}

class BothMethods : public ::testing::TestWithParam<ModalMethod> {};

TEST_P(BothMethods, CoupledChainMatchesAnalyticEigenvalues) {
  // 12 free nodes × 3 axes = 36 translational dofs, 36 coupled rotational dofs.
  const auto chain = coupled_chain(12, 0.02, Eigen::Vector3d(100.0, 230.0, 410.0), 5);
  const int r = 20;
  auto basis = compute_modes(chain.shell, r, with_method(GetParam()));
  ASSERT_TRUE(basis.has_value()) << basis.error().message;
  ASSERT_EQ(basis->mode_count(), r);
  for (int i = 0; i < r; ++i) {
    EXPECT_NEAR(basis->omega_squared[i] / chain.analytic_omega_squared[static_cast<std::size_t>(i)],
                1.0, 1e-10)
        << "mode " << i;
  }
}

TEST_P(BothMethods, ModesAreMassOrthonormalAscendingAndZeroAtTheClamp) {
  const auto tube = frame_tube(8, 6, 0.05);
  auto basis = compute_modes(tube.shell, 15, with_method(GetParam()));
  ASSERT_TRUE(basis.has_value()) << basis.error().message;
  const Eigen::VectorXd mass = node_row_mass(tube.shell);
  const Eigen::MatrixXd gram =
      basis->node_shapes.transpose() * mass.asDiagonal() * basis->node_shapes;
  EXPECT_LT((gram - Eigen::MatrixXd::Identity(15, 15)).cwiseAbs().maxCoeff(), 1e-10);
  for (int i = 1; i < 15; ++i) EXPECT_LT(basis->omega_squared[i - 1], basis->omega_squared[i]);
  EXPECT_GT(basis->omega_squared[0], 0.0);
  EXPECT_EQ(basis->node_shapes.topRows(3 * 6).cwiseAbs().maxCoeff(), 0.0) << "ring 0 is clamped";
  EXPECT_EQ(basis->method, GetParam());
  // Sign convention: largest-magnitude entry positive.
  for (int i = 0; i < 15; ++i) {
    Eigen::Index largest = 0;
    basis->node_shapes.col(i).cwiseAbs().maxCoeff(&largest);
    EXPECT_GT(basis->node_shapes(largest, i), 0.0);
  }
}

INSTANTIATE_TEST_SUITE_P(ModalAnalysis, BothMethods,
                         ::testing::Values(ModalMethod::condensation, ModalMethod::shift_invert),
                         [](const auto& param_info) {
                           return std::string(to_string(param_info.param));
                         });

TEST(ModalAnalysis, MethodsAgreeOnASpaceFrame) {
  // Jittered so no two eigenvalues coincide: every mode is compared up to sign.
  const auto tube = frame_tube(10, 8, 0.05);
  const int r = 30;  // one more is computed so a cluster at the end is seen whole
  auto condensed = compute_modes(tube.shell, r + 1, with_method(ModalMethod::condensation));
  auto lanczos = compute_modes(tube.shell, r + 1, with_method(ModalMethod::shift_invert));
  ASSERT_TRUE(condensed.has_value()) << condensed.error().message;
  ASSERT_TRUE(lanczos.has_value()) << lanczos.error().message;
  for (int i = 0; i < r; ++i) {
    EXPECT_NEAR(lanczos->omega_squared[i] / condensed->omega_squared[i], 1.0, 1e-8) << "mode " << i;
  }
  int compared = 0;
  EXPECT_LT(shape_mismatch(*condensed, *lanczos, node_row_mass(tube.shell), r, false, &compared),
            1e-6);
  EXPECT_GE(compared, r);
}

TEST(ModalAnalysis, MethodsAgreeOnASymmetricFrameWithRepeatedEigenvalues) {
  // Without jitter the tube has pairs of equal bending frequencies: within a pair any
  // rotation of the two shapes is a valid answer, so the pair's subspaces are compared.
  const auto tube = frame_tube(10, 8, 0.0);
  const int r = 24;
  auto condensed = compute_modes(tube.shell, r + 2, with_method(ModalMethod::condensation));
  auto lanczos = compute_modes(tube.shell, r + 2, with_method(ModalMethod::shift_invert));
  ASSERT_TRUE(condensed.has_value()) << condensed.error().message;
  ASSERT_TRUE(lanczos.has_value()) << lanczos.error().message;
  EXPECT_NEAR(condensed->omega_squared[1] / condensed->omega_squared[0], 1.0, 1e-9)
      << "the symmetric frame has a repeated first bending mode";
  for (int i = 0; i < r; ++i) {
    EXPECT_NEAR(lanczos->omega_squared[i] / condensed->omega_squared[i], 1.0, 1e-8) << "mode " << i;
  }
  int compared = 0;
  EXPECT_LT(shape_mismatch(*condensed, *lanczos, node_row_mass(tube.shell), r, false, &compared),
            1e-6);
  EXPECT_GE(compared, r);
}

TEST(ModalAnalysis, CondensationReturnsEveryMode) {
  const auto chain = coupled_chain(4, 0.02, Eigen::Vector3d(100.0, 230.0, 410.0), 6);
  auto basis = compute_modes(chain.shell, 12, with_method(ModalMethod::condensation));
  ASSERT_TRUE(basis.has_value()) << basis.error().message;
  for (int i = 0; i < 12; ++i) {
    EXPECT_NEAR(basis->omega_squared[i] / chain.analytic_omega_squared[static_cast<std::size_t>(i)],
                1.0, 1e-10);
  }
}

void expect_refused(const AssembledShell& shell, int r, ModalOptions options, const char* needle) {
  auto basis = compute_modes(shell, r, options);
  ASSERT_FALSE(basis.has_value()) << needle;
  EXPECT_NE(basis.error().message.find(needle), std::string::npos) << basis.error().message;
}

TEST(ModalAnalysis, Refusals) {
  const auto chain = coupled_chain(4, 0.02, Eigen::Vector3d(100.0, 230.0, 410.0), 7);
  for (ModalMethod method : {ModalMethod::condensation, ModalMethod::shift_invert}) {
    expect_refused(chain.shell, 0, with_method(method), "mode_count = 0, expected 1..12");
    expect_refused(chain.shell, -3, with_method(method), "mode_count = -3");
    expect_refused(chain.shell, 13, with_method(method), "mode_count = 13, expected 1..12");
  }
  expect_refused(chain.shell, 12, with_method(ModalMethod::shift_invert),
                 "use the condensation method");

  AssembledShell rotating = chain.shell;
  rotating.lumped_mass[3] = 1e-6;  // node 1, rx
  expect_refused(rotating, 2, {}, "rotation dof 3 is 0.000001, expected 0");
  AssembledShell massless = chain.shell;
  massless.lumped_mass[7] = 0.0;  // node 2, uy
  expect_refused(massless, 2, {}, "node 2 dof 1 is 0.000000 kg, expected > 0");
  AssembledShell wrong_size = chain.shell;
  wrong_size.lumped_mass.conservativeResize(5);
  expect_refused(wrong_size, 2, {}, "lumped_mass has 5 entries");

  // Nothing clamped: the frame floats freely (six rigid-body modes).
  const auto free_tube = frame_tube(4, 5, 0.05, 1, false);
  expect_refused(free_tube.shell, 3, with_method(ModalMethod::condensation),
                 "free rigid-body motion");
  expect_refused(free_tube.shell, 3, with_method(ModalMethod::shift_invert),
                 "free rigid-body motion");
}

TEST(ModalAnalysis, RefusesNonConvergence) {
  const auto tube = frame_tube(12, 8, 0.05);
  ModalOptions options = with_method(ModalMethod::shift_invert);
  options.max_restarts = 1;
  options.lanczos_vectors = 11;
  expect_refused(tube.shell, 10, options, "Lanczos did not converge to 10 modes in 1 restarts");
  options.lanczos_vectors = 10;
  expect_refused(tube.shell, 10, options, "lanczos_vectors = 10, expected > mode count 10");
}

TEST(ModalDamping, RatioAndRayleighAdd) {
  const Eigen::VectorXd omega_squared = Eigen::Vector3d(100.0, 400.0, 1e4);
  DampingModel damping;
  damping.damping_ratio = 0.05;
  damping.rayleigh = {2.0, 1e-4};
  auto alpha = modal_damping(omega_squared, damping);
  ASSERT_TRUE(alpha.has_value()) << alpha.error().message;
  for (int i = 0; i < 3; ++i) {
    const double omega = std::sqrt(omega_squared[i]);
    EXPECT_DOUBLE_EQ((*alpha)[i], 2.0 * 0.05 * omega + 2.0 + 1e-4 * omega_squared[i]);
  }
  damping.rayleigh.stiffness_proportional_s = -1.0;
  EXPECT_FALSE(modal_damping(omega_squared, damping).has_value());
  damping.rayleigh.stiffness_proportional_s = 0.0;
  damping.damping_ratio = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(modal_damping(omega_squared, damping).has_value());
  damping.damping_ratio = 0.0;
  auto refused = modal_damping(Eigen::Vector2d(1.0, 0.0), damping);
  ASSERT_FALSE(refused.has_value());
  EXPECT_NE(refused.error().message.find("mode 2"), std::string::npos) << refused.error().message;
}

}  // namespace
}  // namespace trainer::model::offline
