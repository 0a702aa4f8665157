// Runtime modal model (NIRMS): the Newmark scheme against its closed forms (energy
// conservation, period elongation, damped decay, static limit), the float model against an
// independent double integration, displacement-driven contact with and without static
// correction, every refusal, and zero heap use in the RT calls.
#include "trainer/model/modal_model.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstring>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "synthetic_modal_model.hpp"
#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/arena.hpp"

namespace trainer::model {
namespace {

using SyntheticModel = SyntheticModalModel<float>;


ModalModel make_model(const SyntheticModel& synthetic, core::Arena& arena, ModalSettings settings) {
  auto model = ModalModel::create(synthetic.data(), arena, settings);
  if (!model) ADD_FAILURE() << model.error().message;
  return std::move(model).value();
}

// Energy norm of the single-dof oscillator: amplitude sqrt(x² + v²/ω²).
double amplitude(const ModalModel& model, double omega) {
  const double x = model.modal_displacement()[0];
  const double v = model.modal_velocity()[0];
  return std::sqrt(x * x + v * v / (omega * omega));
}

TEST(ModalNewmark, UndampedAmplitudeIsConserved) {
  // Average acceleration is the trapezoidal rule on (x, v): a Cayley transform, so it keeps
  // ω²x² + v² exactly once the acceleration is consistent (from the first step on).
  const double omega = 2.0 * std::numbers::pi * 40.0;
  const SyntheticModel synthetic = single_dof(static_cast<float>(omega), 0.0F);
  core::Arena arena = make_arena();
  ModalModel model = make_model(synthetic, arena, {1e-3F, 0, false});
  ASSERT_TRUE(model.add_node_force(0, Vec3(50.0F, 0, 0)).is_ok());  // one-step kick
  ASSERT_TRUE(model.step().is_ok());
  model.clear_forces();
  ASSERT_TRUE(model.step().is_ok());
  const double initial = amplitude(model, omega);
  ASSERT_GT(initial, 0.0);
  double worst_1000 = 0.0;
  double worst_all = 0.0;
  float peak_displacement = 0.0F;
  for (int step = 1; step <= 100000; ++step) {
    ASSERT_TRUE(model.step().is_ok());
    const double error = std::abs(amplitude(model, omega) - initial) / initial;
    if (step <= 1000) worst_1000 = std::max(worst_1000, error);
    worst_all = std::max(worst_all, error);
    peak_displacement = std::max(peak_displacement, std::abs(model.displacement(0).x()));
  }
  EXPECT_LT(worst_1000, 1e-5);  // the brief's bound; the double state does far better:
  EXPECT_LT(worst_all, 1e-7);   // 100 s of 1 kHz steps (measured 2.5e-8; a float state: ~1e-3)
  // The sampled peak never exceeds the amplitude and comes within the sampling phase error.
  EXPECT_LE(peak_displacement, initial * (1.0 + 1e-6));
  EXPECT_GT(peak_displacement, initial * 0.999);
}

TEST(ModalNewmark, PeriodElongationMatchesClosedForm) {
  // Trapezoidal rule: the discrete frequency obeys tan(ω̃Δt/2) = ωΔt/2, so
  // T̃/T = (ωΔt/2)/atan(ωΔt/2) (≈ 1 + (ωΔt)²/12, Bathe). Here ωΔt = 0.314: 0.82 % longer.
  const double dt = 1e-3;
  const double omega = 2.0 * std::numbers::pi * 50.0;
  const SyntheticModel synthetic = single_dof(static_cast<float>(omega), 0.0F);
  core::Arena arena = make_arena();
  ModalModel model = make_model(synthetic, arena, {static_cast<float>(dt), 0, false});
  ASSERT_TRUE(model.add_node_force(0, Vec3(1.0F, 0, 0)).is_ok());
  ASSERT_TRUE(model.step().is_ok());
  model.clear_forces();
  // Upward zero crossings of x, linearly interpolated.
  std::vector<double> crossings;
  double previous = model.modal_displacement()[0];
  for (int step = 2; step < 20000 && crossings.size() < 41; ++step) {
    ASSERT_TRUE(model.step().is_ok());
    const double x = model.modal_displacement()[0];
    if (previous < 0.0 && x >= 0.0) crossings.push_back((step - 1) + previous / (previous - x));
    previous = x;
  }
  ASSERT_EQ(crossings.size(), 41U);
  const double measured_period_s = (crossings.back() - crossings.front()) * dt / 40.0;
  const double exact_period_s = 2.0 * std::numbers::pi / omega;
  const double half = omega * dt / 2.0;
  const double predicted_period_s = exact_period_s * half / std::atan(half);
  EXPECT_NEAR(measured_period_s / predicted_period_s, 1.0, 2e-5);
  EXPECT_GT(measured_period_s / exact_period_s - 1.0, 5e-3);  // the elongation is real
}

TEST(ModalNewmark, DampedDecayRateMatchesAnalytic) {
  // ẍ + αẋ + ω²x = 0 with α = 2ζω. The scheme maps the continuous eigenvalue s to
  // z = (1 + sΔt/2)/(1 − sΔt/2); the modal amplitude c = l·(x, v), l the left eigenvector of
  // [[0, 1], [−ω², −α]] for s, decays exactly as |z|ⁿ, and |z| → e^{−ζωΔt} as Δt → 0.
  const double dt = 1e-3;
  const double omega = 2.0 * std::numbers::pi * 10.0;
  const double zeta = 0.05;
  const double alpha = 2.0 * zeta * omega;
  const SyntheticModel synthetic = single_dof(static_cast<float>(omega), static_cast<float>(alpha));
  core::Arena arena = make_arena();
  ModalModel model = make_model(synthetic, arena, {static_cast<float>(dt), 0, false});
  // The model stores α as float: use the stored value for the exact discrete prediction.
  const double alpha_stored = synthetic.modal_damping[0];
  const double omega_squared_stored = synthetic.omega_squared[0];
  const double dt_stored = static_cast<double>(static_cast<float>(dt));
  const std::complex<double> s(-alpha_stored / 2.0,
                               std::sqrt(omega_squared_stored - alpha_stored * alpha_stored / 4.0));
  const std::complex<double> z = (1.0 + s * dt_stored / 2.0) / (1.0 - s * dt_stored / 2.0);
  // Left eigenvector of [[0, 1], [−ω², −α]] for s: l = (s + α, 1), since s² + αs + ω² = 0.
  const auto modal_amplitude = [&]() {
    return std::abs((s + alpha_stored) * model.modal_displacement()[0] + model.modal_velocity()[0]);
  };
  ASSERT_TRUE(model.add_node_force(0, Vec3(1.0F, 0, 0)).is_ok());
  ASSERT_TRUE(model.step().is_ok());
  model.clear_forces();
  ASSERT_TRUE(model.step().is_ok());
  const double start = modal_amplitude();
  const int steps = 2000;  // 20 periods, amplitude down to e^{-2π} ≈ 0.2 %
  for (int step = 0; step < steps; ++step) ASSERT_TRUE(model.step().is_ok());
  const double measured_rate = -std::log(modal_amplitude() / start) / (steps * dt_stored);
  const double discrete_rate = -std::log(std::abs(z)) / dt_stored;
  EXPECT_NEAR(measured_rate / discrete_rate, 1.0, 1e-8);
  // Continuous decay rate ζω; the scheme's error is O((ωΔt)²) = O(4e-3).
  EXPECT_NEAR(measured_rate / (zeta * omega), 1.0, 4e-3);
}

TEST(ModalNewmark, StepResponseSettlesAtStaticDeflection) {
  const SyntheticModel synthetic = random_model(6, 5, false, 7);
  core::Arena arena = make_arena();
  ModalModel model = make_model(synthetic, arena, {1e-3F, 0, false});
  const Vec3 force(0.3F, -0.2F, 0.5F);
  ASSERT_TRUE(model.add_node_force(2, force).is_ok());
  for (int step = 0; step < 20000; ++step) ASSERT_TRUE(model.step().is_ok());
  // Static modal solution x_i = φ_iᵀF/ω_i², read back at node 4.
  for (int axis = 0; axis < 3; ++axis) {
    double expected = 0.0;
    for (std::uint32_t i = 0; i < synthetic.mode_count; ++i) {
      double modal_force = 0.0;
      for (int b = 0; b < 3; ++b) {
        modal_force +=
            static_cast<double>(synthetic.shape(2, b, i)) * static_cast<double>(force[b]);
      }
      expected += static_cast<double>(synthetic.shape(4, axis, i)) * modal_force /
                  static_cast<double>(synthetic.omega_squared[i]);
    }
    EXPECT_NEAR(model.displacement(4)[axis], expected, 1e-6 * std::abs(expected) + 1e-12);
  }
}

TEST(ModalModel, FloatModelMatchesDoubleIntegrationOfALoadHistory) {
  const SyntheticModel synthetic = random_model(30, 12, false, 11);
  core::Arena arena = make_arena();
  const double dt = 1e-3;
  ModalModel model = make_model(synthetic, arena, {static_cast<float>(dt), 0, false});
  DoubleReference reference(synthetic, static_cast<double>(static_cast<float>(dt)));
  std::mt19937 random(3);
  std::uniform_real_distribution<float> uniform(-1.0F, 1.0F);
  double worst = 0.0;
  double largest = 0.0;
  std::vector<std::pair<std::uint32_t, Vec3>> loads;
  for (int step = 0; step < 3000; ++step) {
    if (step % 50 == 0) {  // a new set of contacts every 50 ms, released after 2 s
      loads.clear();
      if (step < 2000) {
        for (std::uint32_t node : {3U, 17U, 29U}) {
          loads.emplace_back(node, Vec3(uniform(random), uniform(random), uniform(random)));
        }
      }
    }
    model.clear_forces();
    for (const auto& [node, force] : loads) ASSERT_TRUE(model.add_node_force(node, force).is_ok());
    ASSERT_TRUE(model.step().is_ok());
    reference.step(loads);
    for (std::uint32_t node = 0; node < synthetic.node_count; node += 7) {
      for (int axis = 0; axis < 3; ++axis) {
        const double expected = reference.displacement(node, axis);
        largest = std::max(largest, std::abs(expected));
        worst = std::max(worst, std::abs(double{model.displacement(node)[axis]} - expected));
      }
    }
  }
  ASSERT_GT(largest, 0.0);
  EXPECT_LT(worst / largest, 1e-5);
}

// reconstruct() is a float matrix–vector product (plus rows of R for the loads); displacement()
// sums each node in double: they agree to float rounding of the largest displacement, with and
// without static correction, with every stored mode or fewer (the per-node fallback: exact).
TEST(ModalModel, ReconstructEqualsPerNodeDisplacement) {
  const SyntheticModel synthetic = random_model(10, 6, true, 5);
  struct Case {
    std::uint32_t active_modes;
    bool static_correction;
  };
  for (const Case c : {Case{0, true}, Case{0, false}, Case{4, true}, Case{4, false}}) {
    SCOPED_TRACE(::testing::Message() << "active " << c.active_modes << " correction " << c.static_correction);
    core::Arena arena = make_arena();
    ModalModel model = make_model(synthetic, arena, {1e-3F, c.active_modes, c.static_correction});
    ASSERT_TRUE(model.add_node_force(1, Vec3(0.1F, 0.2F, -0.3F)).is_ok());
    ASSERT_TRUE(model.add_node_force(7, Vec3(-0.2F, 0.05F, 0.1F)).is_ok());
    for (int step = 0; step < 10; ++step) ASSERT_TRUE(model.step().is_ok());
    std::vector<float> field(3 * synthetic.node_count);
    ASSERT_TRUE(model.reconstruct(field).is_ok());
    float largest = 0.0F;
    for (std::uint32_t node = 0; node < synthetic.node_count; ++node) {
      largest = std::max(largest, model.displacement(node).cwiseAbs().maxCoeff());
    }
    ASSERT_GT(largest, 0.0F);
    for (std::uint32_t node = 0; node < synthetic.node_count; ++node) {
      for (int axis = 0; axis < 3; ++axis) {
        EXPECT_NEAR(field[3 * node + static_cast<std::uint32_t>(axis)], model.displacement(node)[axis],
                    1e-5F * largest);
      }
    }
    std::vector<float> too_short(3 * synthetic.node_count - 1);
    EXPECT_EQ(model.reconstruct(too_short).code(), core::StatusCode::invalid_argument);
  }
}

// reconstruct()'s Φ q is ModalModel::shape_rows (the kernel the lazy contact surface shares,
// issue 19): any subset of nodes, in any order, gets reconstruct()'s bits; and on a build whose
// packets are SSE's four floats it sums each row as Eigen 3.4's row-major GEMV did before
// (packets from zero, predux, the tail in order), so the field, the golden traces and the state
// hashes did not move. 13 and 40 modes: packets with and without a tail.
TEST(ModalModel, ShapeRowsIsReconstructsKernelAndKeepsTheGemvSums) {
  for (const std::uint32_t modes : {13U, 40U}) {
    SCOPED_TRACE(::testing::Message() << modes << " modes");
    const SyntheticModel synthetic = random_model(21, modes, false, 9);
    core::Arena arena = make_arena();
    ModalModel model = make_model(synthetic, arena, {1e-3F, 0, false});
    ASSERT_TRUE(model.add_node_force(3, Vec3(0.1F, -0.2F, 0.3F)).is_ok());
    for (int step = 0; step < 7; ++step) ASSERT_TRUE(model.step().is_ok());
    std::vector<float> field(3 * synthetic.node_count);
    ASSERT_TRUE(model.reconstruct(field).is_ok());
    std::vector<float> q(modes);
    for (std::size_t i = 0; i < modes; ++i) q[i] = static_cast<float>(model.modal_displacement()[i]);
    // A subset in a scrambled order, an odd count (pairs and a single).
    const std::vector<std::uint32_t> nodes = {17, 2, 9, 20, 0, 11, 5};
    std::vector<float> some(field.size(), -1.0F);
    model.shape_rows(nodes.data(), nodes.size(), q.data(), some.data());
    for (const std::uint32_t node : nodes) {
      for (std::size_t axis = 0; axis < 3; ++axis) {
        EXPECT_EQ(0, std::memcmp(&some[3 * node + axis], &field[3 * node + axis], sizeof(float))) << "node " << node;
      }
    }
    if (Eigen::internal::packet_traits<float>::size != 4) continue;  // the GEMV's sums differ on wider packets
    using RowMajor = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    const Eigen::Map<const RowMajor> shapes(synthetic.data().mode_shapes.data(),
                                            static_cast<Eigen::Index>(field.size()), static_cast<Eigen::Index>(modes));
    const Eigen::VectorXf gemv = shapes * Eigen::Map<const Eigen::VectorXf>(q.data(), static_cast<Eigen::Index>(modes));
    EXPECT_EQ(0, std::memcmp(gemv.data(), field.data(), field.size() * sizeof(float)));
  }
}

TEST(ModalModel, StaticCorrectionAddsResidualResponseOfTheSteppedForces) {
  const SyntheticModel synthetic = random_model(5, 4, true, 9);
  core::Arena arena = make_arena();
  ModalModel corrected = make_model(synthetic, arena, {1e-3F, 0, true});
  ModalModel plain = make_model(synthetic, arena, {1e-3F, 0, false});
  const Vec3 force_a(0.2F, 0.0F, -0.1F);
  const Vec3 force_b(-0.05F, 0.3F, 0.1F);
  for (ModalModel* model : {&corrected, &plain}) {
    ASSERT_TRUE(model->add_node_force(1, force_a).is_ok());
    ASSERT_TRUE(model->add_node_force(3, force_b).is_ok());
    ASSERT_TRUE(model->step().is_ok());
    model->clear_forces();  // the correction belongs to the forces of the last step
  }
  // What a host rebuilding the field from the telemetry stream reads: the last step's loads.
  ASSERT_EQ(corrected.stepped_load_count(), 2U);
  EXPECT_EQ(corrected.stepped_load_node(0), 1U);
  EXPECT_EQ(corrected.stepped_load_force(0), force_a);
  EXPECT_EQ(corrected.stepped_load_node(1), 3U);
  EXPECT_EQ(corrected.stepped_load_force(1), force_b);
  EXPECT_EQ(corrected.stepped_load_force(2), Vec3::Zero());
  const std::uint32_t rows = 3 * synthetic.node_count;
  for (std::uint32_t node = 0; node < synthetic.node_count; ++node) {
    for (std::uint32_t axis = 0; axis < 3; ++axis) {
      double expected = plain.displacement(node)[static_cast<int>(axis)];
      for (int b = 0; b < 3; ++b) {
        const auto column = static_cast<std::uint32_t>(b);
        expected +=
            double{synthetic.residual_compliance[(3 * node + axis) * rows + 3 * 1 + column]} *
            double{force_a[b]};
        expected +=
            double{synthetic.residual_compliance[(3 * node + axis) * rows + 3 * 3 + column]} *
            double{force_b[b]};
      }
      EXPECT_NEAR(corrected.displacement(node)[static_cast<int>(axis)], expected, 1e-9);
    }
  }
}

// Drives `targets` for several steps (moving targets) and checks each is reached.
void expect_targets_reached(ModalModel& model, std::vector<ImposedDisplacement> targets) {
  std::vector<Vec3> forces(targets.size());
  for (int step = 0; step < 200; ++step) {
    for (std::size_t k = 0; k < targets.size(); ++k) {
      // Press in over 100 steps, then hold: a tool tip pushing into the tissue.
      const float ramp = std::min(1.0F, static_cast<float>(step + 1) / 100.0F);
      targets[k].displacement_m = ramp * Vec3(1e-3F * static_cast<float>(k + 1), -5e-4F, 2e-4F);
    }
    model.clear_forces();
    const core::Status solved = model.solve_imposed(targets, forces);
    ASSERT_TRUE(solved.is_ok()) << solved.detail();
    ASSERT_TRUE(model.step().is_ok());
    for (const ImposedDisplacement& target : targets) {
      const Vec3 reached = model.displacement(target.node);
      EXPECT_LT((reached - target.displacement_m).norm(), 1e-5F * target.displacement_m.norm())
          << "node " << target.node << " step " << step;
    }
  }
}

TEST(ModalModel, SolveImposedReachesTargetsWithoutStaticCorrection) {
  const SyntheticModel synthetic = random_model(12, 10, false, 21);
  core::Arena arena = make_arena();
  ModalModel model = make_model(synthetic, arena, {1e-3F, 0, false});
  expect_targets_reached(model, {{2, Vec3::Zero()}, {7, Vec3::Zero()}});
}

TEST(ModalModel, SolveImposedReachesTargetsWithStaticCorrection) {
  // Few modes (3) for three contacts: only solvable because R adds the missing compliance.
  const SyntheticModel synthetic = random_model(12, 3, true, 22);
  core::Arena arena = make_arena();
  ModalModel model = make_model(synthetic, arena, {1e-3F, 0, true});
  expect_targets_reached(model, {{0, Vec3::Zero()}, {5, Vec3::Zero()}, {11, Vec3::Zero()}});
}

TEST(ModalModel, SolveImposedAccountsForForcesAlreadyApplied) {
  const SyntheticModel synthetic = random_model(8, 10, true, 23);
  core::Arena arena = make_arena();
  ModalModel model = make_model(synthetic, arena, {1e-3F, 0, true});
  ASSERT_TRUE(model.add_node_force(4, Vec3(0.5F, 0.5F, 0.0F)).is_ok());  // e.g. the catheter
  const std::vector<ImposedDisplacement> target{{1, Vec3(1e-3F, 0.0F, 0.0F)}};
  std::vector<Vec3> forces(1);
  ASSERT_TRUE(model.solve_imposed(target, forces).is_ok());
  EXPECT_EQ(model.applied_load_count(), 2U);
  ASSERT_TRUE(model.step().is_ok());
  EXPECT_LT((model.displacement(1) - target[0].displacement_m).norm(), 1e-8F);
}

TEST(ModalModel, SolveImposedRefusals) {
  SyntheticModel synthetic = random_model(12, 4, true, 31);
  // Node 11 is clamped: zero shape rows and zero residual compliance rows/columns.
  const std::uint32_t rows = 3 * synthetic.node_count;
  for (std::uint32_t row = 33; row < 36; ++row) {
    for (std::uint32_t i = 0; i < synthetic.mode_count; ++i)
      synthetic.mode_shapes[row * synthetic.mode_count + i] = 0.0F;
    for (std::uint32_t j = 0; j < rows; ++j) {
      synthetic.residual_compliance[row * rows + j] = 0.0F;
      synthetic.residual_compliance[j * rows + row] = 0.0F;
    }
  }
  core::Arena arena = make_arena();
  ModalModel plain = make_model(synthetic, arena, {1e-3F, 0, false});
  std::vector<Vec3> forces(9);
  const Vec3 d(1e-3F, 0, 0);
  std::vector<ImposedDisplacement> nine;
  for (std::uint32_t node = 0; node < 9; ++node) nine.push_back({node, d});
  EXPECT_EQ(plain.solve_imposed(nine, forces).code(), core::StatusCode::capacity_exceeded);
  const std::vector<ImposedDisplacement> two{{1, d}, {2, d}};
  EXPECT_EQ(plain.solve_imposed(two, std::span<Vec3>(forces).first(1)).code(),
            core::StatusCode::invalid_argument);
  EXPECT_EQ(plain.solve_imposed(two, forces).code(), core::StatusCode::invalid_argument)
      << "6 components, 4 modes, no static correction";
  const std::vector<ImposedDisplacement> repeated{{1, d}, {1, d}};
  EXPECT_EQ(plain.solve_imposed(repeated, forces).code(), core::StatusCode::invalid_argument);
  const std::vector<ImposedDisplacement> unknown{{12, d}};
  EXPECT_EQ(plain.solve_imposed(unknown, forces).code(), core::StatusCode::invalid_argument);
  const std::vector<ImposedDisplacement> nan{
      {1, Vec3(std::numeric_limits<float>::quiet_NaN(), 0, 0)}};
  EXPECT_EQ(plain.solve_imposed(nan, forces).code(), core::StatusCode::numeric_error);
  const std::vector<ImposedDisplacement> clamped{{11, d}};
  EXPECT_EQ(plain.solve_imposed(clamped, forces).code(), core::StatusCode::numeric_error);
  ModalModel corrected = make_model(synthetic, arena, {1e-3F, 0, true});
  EXPECT_EQ(corrected.solve_imposed(clamped, forces).code(), core::StatusCode::numeric_error);
  EXPECT_EQ(plain.applied_load_count(), 0U);
  EXPECT_EQ(corrected.applied_load_count(), 0U);

  // Static correction needs the contact to be a surface node.
  SyntheticModel partial = random_model(6, 4, false, 32);
  partial.surface_nodes = {0, 1, 2};
  partial.residual_compliance.assign(81, 0.0F);
  for (std::uint32_t i = 0; i < 9; ++i) partial.residual_compliance[i * 9 + i] = 1e-4F;
  ModalModel surface_only = make_model(partial, arena, {1e-3F, 0, true});
  const std::vector<ImposedDisplacement> inner{{4, d}};
  EXPECT_EQ(surface_only.solve_imposed(inner, forces).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(surface_only.add_node_force(4, d).code(), core::StatusCode::invalid_argument);
  EXPECT_TRUE(surface_only.add_node_force(2, d).is_ok());
}

TEST(ModalModel, ForceRefusalsApplyNothing) {
  const SyntheticModel synthetic = random_model(70, 3, false, 41);
  core::Arena arena = make_arena();
  ModalModel model = make_model(synthetic, arena, {1e-3F, 0, false});
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(model.add_node_force(0, Vec3(nan, 0, 0)).code(), core::StatusCode::numeric_error);
  EXPECT_EQ(model.add_node_force(0, Vec3(std::numeric_limits<float>::infinity(), 0, 0)).code(),
            core::StatusCode::numeric_error);
  EXPECT_EQ(model.add_node_force(70, Vec3(1, 0, 0)).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(model.applied_load_count(), 0U);
  ASSERT_TRUE(model.step().is_ok());
  EXPECT_EQ(model.displacement(0), Vec3::Zero());
  for (std::uint32_t node = 0; node < ModalModel::kMaxLoadedNodes; ++node) {
    ASSERT_TRUE(model.add_node_force(node, Vec3(0.01F, 0, 0)).is_ok());
  }
  ASSERT_TRUE(model.add_node_force(0, Vec3(0.01F, 0, 0)).is_ok()) << "same node accumulates";
  EXPECT_EQ(model.add_node_force(64, Vec3(0.01F, 0, 0)).code(),
            core::StatusCode::capacity_exceeded);
  EXPECT_EQ(model.applied_load_count(), ModalModel::kMaxLoadedNodes);
  EXPECT_EQ(model.displacement(70), Vec3::Zero()) << "unknown node reads as zero";
}

TEST(ModalModel, CreateRefusesBadData) {
  core::Arena arena = make_arena();
  const SyntheticModel good = random_model(4, 3, true, 51);
  ASSERT_TRUE(ModalModel::create(good.data(), arena, {1e-3F, 0, true}).has_value());
  const auto refused = [&](const SyntheticModel& model, ModalSettings settings,
                           const char* needle) {
    auto created = ModalModel::create(model.data(), arena, settings);
    ASSERT_FALSE(created.has_value()) << needle;
    EXPECT_NE(created.error().message.find(needle), std::string::npos) << created.error().message;
  };
  SyntheticModel bad = good;
  bad.mode_shapes.pop_back();
  refused(bad, {1e-3F, 0, false}, "mode_shapes has 35 values, expected 36");
  bad = good;
  bad.rest_positions.push_back(0.0F);
  refused(bad, {1e-3F, 0, false}, "rest_positions");
  bad = good;
  bad.omega_squared[1] = 0.0F;
  refused(bad, {1e-3F, 0, false}, "omega_squared[1]");
  bad = good;
  bad.modal_damping[2] = -1.0F;
  refused(bad, {1e-3F, 0, false}, "modal_damping[2]");
  bad = good;
  bad.mode_shapes[5] = std::numeric_limits<float>::quiet_NaN();
  refused(bad, {1e-3F, 0, false}, "non-finite");
  bad = good;
  bad.residual_compliance.pop_back();
  refused(bad, {1e-3F, 0, false}, "residual_compliance");
  bad = good;
  bad.residual_compliance.clear();
  refused(bad, {1e-3F, 0, true}, "static_correction is on");
  bad = good;
  bad.surface_nodes[2] = 4;
  refused(bad, {1e-3F, 0, false}, "surface_nodes[2] = 4");
  bad = good;
  bad.surface_nodes[2] = 1;
  refused(bad, {1e-3F, 0, false}, "listed twice");
  refused(good, {0.0F, 0, false}, "time_step_s");
  refused(good, {std::numeric_limits<float>::quiet_NaN(), 0, false}, "time_step_s");
  refused(good, {1e-3F, 4, false}, "active_modes = 4");
  bad = good;
  bad.node_count = 0;
  refused(bad, {1e-3F, 0, false}, "node_count = 0");
  auto tiny = core::Arena::create(256);
  ASSERT_TRUE(tiny.has_value());
  auto exhausted = ModalModel::create(good.data(), tiny.value(), {1e-3F, 0, false});
  ASSERT_FALSE(exhausted.has_value());
  EXPECT_NE(exhausted.error().message.find("arena exhausted"), std::string::npos)
      << exhausted.error().message;
}

TEST(ModalModel, ActiveModesUsesTheFirstModesOnly) {
  const SyntheticModel all = random_model(5, 6, false, 61);
  SyntheticModel first_two = all;  // the same model truncated to two stored modes
  first_two.mode_count = 2;
  first_two.mode_shapes.clear();
  for (std::uint32_t row = 0; row < 15; ++row) {
    for (std::uint32_t i = 0; i < 2; ++i)
      first_two.mode_shapes.push_back(all.mode_shapes[row * 6 + i]);
  }
  first_two.omega_squared.resize(2);
  first_two.modal_damping.resize(2);
  core::Arena arena = make_arena();
  ModalModel active = make_model(all, arena, {1e-3F, 2, false});
  ModalModel stored = make_model(first_two, arena, {1e-3F, 0, false});
  EXPECT_EQ(active.active_mode_count(), 2U);
  for (ModalModel* model : {&active, &stored}) {
    ASSERT_TRUE(model->add_node_force(3, Vec3(0.1F, 0.2F, 0.3F)).is_ok());
    for (int step = 0; step < 100; ++step) ASSERT_TRUE(model->step().is_ok());
  }
  EXPECT_EQ(active.displacement(1), stored.displacement(1));
}

TEST(ModalModel, NoHeapInTheRealTimeCalls) {
  ASSERT_TRUE(core::alloc::hooks_installed());
  const SyntheticModel synthetic = random_model(40, 20, true, 71);
  core::Arena arena = make_arena();
  ModalModel model = make_model(synthetic, arena, {1e-3F, 0, true});
  arena.seal();
  std::vector<float> field(3 * synthetic.node_count);
  // Target sets that change (nodes entering and leaving the contact cache, up to its eviction)
  // and releases (a re-solve of fewer targets), so every path of the solve runs counted.
  const std::vector<std::vector<std::uint32_t>> node_sets{
      {3, 9, 27}, {3, 9, 28}, {1, 2, 4, 5, 6, 7, 8, 10}, {11, 12, 13}};
  std::vector<ImposedDisplacement> targets;
  targets.reserve(8);
  std::vector<Vec3> forces(8);
  float checksum = 0.0F;
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (int step = 0; step < 5000; ++step) {
    model.clear_forces();
    targets.clear();
    for (const std::uint32_t node : node_sets[static_cast<std::size_t>(step / 7) % node_sets.size()])
      targets.push_back({node, Vec3(1e-3F * std::sin(0.01F * static_cast<float>(step)), 0, 0)});
    if (!model.add_node_force(30, Vec3(0.1F, 0, 0)).is_ok()) break;
    if (!model.solve_imposed(targets, forces).is_ok()) break;
    if (step % 5 == 0) {  // a release: the first target let go, the rest re-solved
      model.clear_forces();
      if (!model.solve_imposed(std::span(targets).subspan(1), forces).is_ok()) break;
    }
    if (!model.step().is_ok()) break;
    checksum += model.displacement(3).x();
    if (step % 33 == 0 && !model.reconstruct(field).is_ok()) break;
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
  EXPECT_TRUE(std::isfinite(checksum));
  EXPECT_GT(std::abs(checksum), 0.0F);
}

}  // namespace
}  // namespace trainer::model
