// DNIOS (full-system Newmark) against the static solution, and the modal integration
// (NIRMS, double) against DNIOS: identical with every mode, converging as modes are added.
#include "trainer/model_offline/dnios.hpp"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/SparseCholesky>

#include "modal_test_structures.hpp"

namespace trainer::model::offline {
namespace {

using testing::frame_tube;

constexpr RayleighDamping kRayleigh{20.0, 1e-5};  // α_M 1/s, β_K s

// A load history: contacts appear, move and leave (forces on two nodes, then one, then none).
struct LoadStep {
  std::vector<std::pair<int, Eigen::Vector3d>> loads;
};
std::vector<LoadStep> load_history(int steps, int node_count, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  std::uniform_int_distribution<int> pick(node_count / 3, node_count - 1);
  std::vector<LoadStep> history(static_cast<std::size_t>(steps));
  std::vector<std::pair<int, Eigen::Vector3d>> current;
  for (int step = 0; step < steps; ++step) {
    if (step % 40 == 0) {
      current.clear();
      const int contacts = step < steps / 2 ? 2 : (step < 3 * steps / 4 ? 1 : 0);
      for (int c = 0; c < contacts; ++c) {
        current.emplace_back(pick(random), 0.01 * Eigen::Vector3d(uniform(random), uniform(random),
                                                                  uniform(random)));
      }
    }
    history[static_cast<std::size_t>(step)].loads = current;
  }
  return history;
}

// Runs any integrator with add_node_force/clear_forces/step/translational_field through a
// load history; returns the field after every step (3n × steps).
template <class Integrator>
Eigen::MatrixXd run(Integrator& integrator, const std::vector<LoadStep>& history) {
  Eigen::MatrixXd fields;
  int column = 0;
  for (const LoadStep& step : history) {
    integrator.clear_forces();
    for (const auto& [node, force] : step.loads) {
      EXPECT_TRUE(integrator.add_node_force(node, force).has_value());
    }
    integrator.step();
    const Eigen::VectorXd field = integrator.translational_field();
    if (fields.size() == 0) fields.resize(field.size(), static_cast<Eigen::Index>(history.size()));
    fields.col(column++) = field;
  }
  return fields;
}

double relative_history_error(const Eigen::MatrixXd& history, const Eigen::MatrixXd& reference) {
  return (history - reference).cwiseAbs().maxCoeff() / reference.cwiseAbs().maxCoeff();
}

TEST(Dnios, SettlesAtTheStaticSolution) {
  const auto tube = frame_tube(6, 6, 0.05);
  auto full = FullNewmark::create(tube.shell, {200.0, 0.0}, 1e-3);
  ASSERT_TRUE(full.has_value()) << full.error().message;
  const Eigen::Vector3d force(0.0, 0.02, -0.01);
  ASSERT_TRUE(full->add_node_force(33, force).has_value());
  ASSERT_TRUE(full->add_node_force(3, force).has_value()) << "fixed node: silently dropped";
  for (int step = 0; step < 3000; ++step) full->step();
  Eigen::VectorXd free_force = Eigen::VectorXd::Zero(tube.shell.dofs.free_count());
  for (int axis = 0; axis < 3; ++axis) {
    free_force[tube.shell.dofs.free_index[static_cast<std::size_t>(6 * 33 + axis)]] = force[axis];
  }
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> solver(tube.shell.stiffness);
  const Eigen::VectorXd exact = solver.solve(free_force);
  EXPECT_LT((full->free_displacement() - exact).norm() / exact.norm(), 1e-8);
  EXPECT_EQ(full->displacement(3), Eigen::Vector3d::Zero());
  EXPECT_GT(full->displacement(33).norm(), 0.0);
}

TEST(Dnios, ModalWithEveryModeEqualsTheFullIntegration) {
  // 15 free nodes, 45 translational dofs: r = 45 is the whole (condensed) system.
  const auto tube = frame_tube(4, 5, 0.05);
  const double dt = 1e-3;
  ModalOptions options;
  options.method = ModalMethod::condensation;
  auto basis = compute_modes(tube.shell, 45, options);
  ASSERT_TRUE(basis.has_value()) << basis.error().message;
  auto damping = modal_damping(basis->omega_squared, {0.0, kRayleigh});
  ASSERT_TRUE(damping.has_value());
  auto full = FullNewmark::create(tube.shell, kRayleigh, dt);
  ASSERT_TRUE(full.has_value()) << full.error().message;
  auto modal = ModalNewmark::create(*basis, *damping, dt);
  ASSERT_TRUE(modal.has_value()) << modal.error().message;
  const auto history = load_history(400, 20, 3);
  const Eigen::MatrixXd reference = run(*full, history);
  const Eigen::MatrixXd nirms = run(*modal, history);
  EXPECT_LT(relative_history_error(nirms, reference), 1e-9);
}

TEST(Dnios, ModalConvergesToTheFullIntegrationAsModesAreAdded) {
  const auto tube = frame_tube(8, 6, 0.05);  // 42 free nodes, 126 translational dofs
  const double dt = 1e-3;
  ModalOptions options;
  options.method = ModalMethod::condensation;
  auto basis = compute_modes(tube.shell, 126, options);
  ASSERT_TRUE(basis.has_value()) << basis.error().message;
  auto damping = modal_damping(basis->omega_squared, {0.0, kRayleigh});
  ASSERT_TRUE(damping.has_value());
  auto full = FullNewmark::create(tube.shell, kRayleigh, dt);
  ASSERT_TRUE(full.has_value()) << full.error().message;
  const auto history = load_history(400, 48, 4);
  const Eigen::MatrixXd reference = run(*full, history);
  double previous = 1e300;
  for (int r : {2, 5, 10, 20, 40, 80, 126}) {
    auto modal = ModalNewmark::create(*basis, *damping, dt, r);
    ASSERT_TRUE(modal.has_value()) << modal.error().message;
    const double error = relative_history_error(run(*modal, history), reference);
    std::printf("[ modal vs DNIOS ] r = %3d: max relative history error %.3e\n", r, error);
    EXPECT_LT(error, previous) << "r = " << r;
    previous = error;
  }
  EXPECT_LT(previous, 1e-9);
}

TEST(Dnios, Refusals) {
  const auto tube = frame_tube(4, 5, 0.05);
  EXPECT_FALSE(FullNewmark::create(tube.shell, kRayleigh, 0.0).has_value());
  EXPECT_FALSE(FullNewmark::create(tube.shell, kRayleigh, std::nan("")).has_value());
  EXPECT_FALSE(FullNewmark::create(tube.shell, {-1.0, 0.0}, 1e-3).has_value());
  AssembledShell broken = tube.shell;
  broken.lumped_mass.conservativeResize(3);
  auto refused = FullNewmark::create(broken, kRayleigh, 1e-3);
  ASSERT_FALSE(refused.has_value());
  EXPECT_NE(refused.error().message.find("lumped mass (3)"), std::string::npos)
      << refused.error().message;
  auto full = FullNewmark::create(tube.shell, kRayleigh, 1e-3);
  ASSERT_TRUE(full.has_value());
  EXPECT_FALSE(full->add_node_force(20, Eigen::Vector3d::Zero()).has_value());
  EXPECT_FALSE(full->add_node_force(5, Eigen::Vector3d(std::nan(""), 0, 0)).has_value());

  auto basis = compute_modes(tube.shell, 5);
  ASSERT_TRUE(basis.has_value());
  const Eigen::VectorXd damping = Eigen::VectorXd::Zero(5);
  EXPECT_FALSE(ModalNewmark::create(*basis, damping, 1e-3, 6).has_value());
  EXPECT_FALSE(ModalNewmark::create(*basis, Eigen::VectorXd::Zero(4), 1e-3).has_value());
  EXPECT_FALSE(ModalNewmark::create(*basis, -Eigen::VectorXd::Ones(5), 1e-3).has_value());
  EXPECT_FALSE(ModalNewmark::create(*basis, damping, -1e-3).has_value());
}

}  // namespace
}  // namespace trainer::model::offline
