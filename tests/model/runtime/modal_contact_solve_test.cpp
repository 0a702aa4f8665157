// The modal model's contact solve (solve_imposed) against references, on random target sets
// that change the way a haptic loop changes them: the same nodes held for several steps (the
// cached factorisation), one node swapped (a node entering the contact cache, another one
// evicted), a new patch, loads already applied (a catheter's wall reaction, on a contact node
// or beside it) and releases (clear_forces(), then a re-solve of a subset in the same step, as
// ModalStage::solve_contacts does for a contact that would pull the tissue).
//  - Against a dense reference written out here: the whole Φ, diag(1/k̂) and R in double, the
//    contact compliance Φ_K diag(1/k̂) Φ_Kᵀ + R_KK and the free response built from them, solved
//    by full-pivoting LU (another algorithm than the model's LDLᵀ). Agreement within the
//    rounding of the solve: relative to the largest force, 1e-9 for the double model and 1e-6
//    for the float model (its forces are returned rounded to float); measured 1.6e-13 and
//    5.5e-8 (2026-11-28, this dev VM).
//  - Against a cold solve: a second model driven in lockstep whose cache is flushed before
//    every solve (dummy solves on other nodes, which also push out its kept factorisations)
//    must give bit-identical forces and states: the cache, the factorisation reuse and the
//    re-solve after a release change no bit.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include <Eigen/LU>

#include "synthetic_modal_model.hpp"
#include "trainer/model/modal_model.hpp"

namespace trainer::model {
namespace {

struct ReferenceLoad {
  std::uint32_t node;
  Eigen::Vector3d force_n;
};

// The dense reference of the next step's contact forces, from the model's state and the loads
// the test applied.
template <typename Scalar>
Eigen::VectorXd reference_forces(const SyntheticModalModel<Scalar>& synthetic,
                                 const BasicModalModel<Scalar>& model, bool static_correction,
                                 const std::vector<BasicImposedDisplacement<Scalar>>& targets,
                                 const std::vector<ReferenceLoad>& loads) {
  const auto n = static_cast<Eigen::Index>(3 * synthetic.node_count);
  const auto r = static_cast<Eigen::Index>(synthetic.mode_count);
  Eigen::MatrixXd shapes(n, r);
  for (Eigen::Index row = 0; row < n; ++row)
    for (Eigen::Index i = 0; i < r; ++i)
      shapes(row, i) = static_cast<double>(synthetic.mode_shapes[static_cast<std::size_t>(row * r + i)]);
  Eigen::MatrixXd residual = Eigen::MatrixXd::Zero(n, n);
  if (static_correction) {
    for (Eigen::Index row = 0; row < n; ++row)
      for (Eigen::Index column = 0; column < n; ++column)
        residual(row, column) = static_cast<double>(
            synthetic.residual_compliance[static_cast<std::size_t>(row * n + column)]);
  }
  const double dt = static_cast<double>(model.time_step_s());
  Eigen::VectorXd inverse_k_hat(r);
  Eigen::VectorXd free_modal(r);
  Eigen::VectorXd load(n);
  load.setZero();
  for (const ReferenceLoad& applied : loads) load.segment<3>(3 * applied.node) += applied.force_n;
  const Eigen::VectorXd modal_force = shapes.transpose() * load;
  for (Eigen::Index i = 0; i < r; ++i) {
    const double alpha = static_cast<double>(synthetic.modal_damping[static_cast<std::size_t>(i)]);
    const double a0 = (4.0 + 2.0 * alpha * dt) / (dt * dt);
    const double a2 = 4.0 / dt + alpha;
    inverse_k_hat[i] =
        1.0 / (static_cast<double>(synthetic.omega_squared[static_cast<std::size_t>(i)]) + a0);
    const auto mode = static_cast<std::size_t>(i);
    free_modal[i] = (modal_force[i] + a0 * model.modal_displacement()[mode] +
                     a2 * model.modal_velocity()[mode] + model.modal_acceleration()[mode]) *
                    inverse_k_hat[i];
  }
  const Eigen::VectorXd free_field = shapes * free_modal + residual * load;
  const auto c = static_cast<Eigen::Index>(targets.size());
  Eigen::MatrixXd gathered(3 * c, r);
  Eigen::MatrixXd residual_kk(3 * c, 3 * c);
  Eigen::VectorXd rhs(3 * c);
  for (Eigen::Index k = 0; k < c; ++k) {
    const auto node_k = static_cast<Eigen::Index>(targets[static_cast<std::size_t>(k)].node);
    gathered.middleRows<3>(3 * k) = shapes.middleRows<3>(3 * node_k);
    rhs.segment<3>(3 * k) =
        targets[static_cast<std::size_t>(k)].displacement_m.template cast<double>() -
        free_field.segment<3>(3 * node_k);
    for (Eigen::Index l = 0; l < c; ++l) {
      const auto node_l = static_cast<Eigen::Index>(targets[static_cast<std::size_t>(l)].node);
      residual_kk.block<3, 3>(3 * k, 3 * l) = residual.block<3, 3>(3 * node_k, 3 * node_l);
    }
  }
  const Eigen::MatrixXd compliance =
      gathered * inverse_k_hat.asDiagonal() * gathered.transpose() + residual_kk;
  return compliance.fullPivLu().solve(rhs);
}

// Applies the same calls to `warm` (used as the loop uses it) and to `cold` (its contact cache
// flushed before each solve by a solve on `flush` nodes), checks both against the dense
// reference and against each other. Returns the largest relative difference from the reference.
template <typename Scalar>
double run_random_contact_sequence(const SyntheticModalModel<Scalar>& synthetic,
                                   bool static_correction, unsigned seed, int steps) {
  using Model = BasicModalModel<Scalar>;
  using Target = BasicImposedDisplacement<Scalar>;
  using Vector3 = typename Model::Vector3;
  core::Arena arena = make_arena();
  const BasicModalSettings<Scalar> settings{static_cast<Scalar>(1e-3), 0, static_correction};
  auto warm_created = Model::create(synthetic.data(), arena, settings);
  auto cold_created = Model::create(synthetic.data(), arena, settings);
  EXPECT_TRUE(warm_created && cold_created);
  Model warm = std::move(warm_created).value();
  Model cold = std::move(cold_created).value();
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const auto nodes = synthetic.node_count;
  const std::size_t max_contacts =
      static_correction ? Model::kMaxContacts
                        : std::min<std::size_t>(Model::kMaxContacts, synthetic.mode_count / 3);
  std::vector<std::uint32_t> order(nodes);
  for (std::uint32_t node = 0; node < nodes; ++node) order[node] = node;
  std::vector<Target> targets;
  double worst = 0.0;
  std::size_t releases = 0;
  std::size_t reuses = 0;

  // One solve on both models; `loads` are the forces applied before it.
  const auto solve_both = [&](const std::vector<Target>& solved,
                              const std::vector<ReferenceLoad>& loads) {
    // Flush the cold model's cache: a solve on Model::kMaxContacts nodes outside `solved`
    // takes every slot; its forces are cleared and the loads applied again.
    std::vector<Target> flush;
    for (std::uint32_t node = nodes; node-- > 0 && flush.size() < max_contacts;) {
      const bool in_solved = std::any_of(solved.begin(), solved.end(),
                                         [node](const Target& t) { return t.node == node; });
      if (!in_solved) flush.push_back(Target{node, Vector3::Constant(static_cast<Scalar>(1e-5))});
    }
    // kFactorisations distinct node lists (prefixes of `flush`) push every kept factorisation
    // out: the cold model factorises `solved` again.
    ASSERT_GE(flush.size(), Model::kFactorisations);
    for (std::size_t list = 0; list < Model::kFactorisations; ++list) {
      const std::vector<Target> prefix(flush.begin(),
                                       flush.end() - static_cast<std::ptrdiff_t>(list));
      std::vector<Vector3> flush_forces(prefix.size());
      const core::Status flushed = cold.solve_imposed(prefix, flush_forces);
      EXPECT_TRUE(flushed.is_ok()) << flushed.detail();
    }
    cold.clear_forces();
    for (const ReferenceLoad& load : loads)
      EXPECT_TRUE(cold.add_node_force(load.node, load.force_n.template cast<Scalar>()).is_ok());

    const Eigen::VectorXd expected =
        reference_forces(synthetic, warm, static_correction, solved, loads);
    std::vector<Vector3> warm_forces(solved.size());
    std::vector<Vector3> cold_forces(solved.size());
    const core::Status warm_status = warm.solve_imposed(solved, warm_forces);
    const std::uint64_t cold_factorised = cold.contact_factorisations();
    const core::Status cold_status = cold.solve_imposed(solved, cold_forces);
    EXPECT_EQ(cold.contact_factorisations(), cold_factorised + 1) << "the cold solve factorises";
    EXPECT_TRUE(warm_status.is_ok()) << warm_status.detail();
    EXPECT_TRUE(cold_status.is_ok()) << cold_status.detail();
    const double scale = expected.cwiseAbs().maxCoeff();
    for (std::size_t k = 0; k < solved.size(); ++k) {
      EXPECT_EQ(warm_forces[k], cold_forces[k]) << "target " << k << " node " << solved[k].node;
      for (int axis = 0; axis < 3; ++axis) {
        const double difference = std::abs(static_cast<double>(warm_forces[k][axis]) -
                                           expected[static_cast<Eigen::Index>(3 * k) + axis]);
        worst = std::max(worst, difference / scale);
      }
    }
  };

  for (int step = 0; step < steps; ++step) {
    // Random targets jumping every step over ill-conditioned random patches pump the state up
    // (10^30 within a few hundred float steps): back to rest now and then, which also runs the
    // solve right after a reset.
    if (step % 20 == 0) {
      warm.reset();
      cold.reset();
    }
    const double change = unit(random);
    if (targets.empty() || change < 0.2) {  // a new patch
      std::shuffle(order.begin(), order.end(), random);
      const auto count = 1 + static_cast<std::size_t>(unit(random) * static_cast<double>(max_contacts));
      targets.clear();
      for (std::size_t k = 0; k < std::min(count, max_contacts); ++k)
        targets.push_back(Target{order[k], Vector3::Zero()});
    } else if (change < 0.4) {  // one node swapped for one outside the set
      std::uint32_t node = 0;
      do {
        node = static_cast<std::uint32_t>(unit(random) * nodes) % nodes;
      } while (std::any_of(targets.begin(), targets.end(),
                           [node](const Target& t) { return t.node == node; }));
      targets[static_cast<std::size_t>(unit(random) * static_cast<double>(targets.size())) %
              targets.size()]
          .node = node;
    } else {
      ++reuses;  // the same nodes: a held contact
    }
    for (Target& target : targets) {
      for (int axis = 0; axis < 3; ++axis)
        target.displacement_m[axis] = static_cast<Scalar>(2e-4 * (unit(random) - 0.5));
    }
    std::vector<ReferenceLoad> loads;
    if (unit(random) < 0.3) {  // a catheter's reaction, on a contact node every other time
      const std::uint32_t node = unit(random) < 0.5
                                     ? targets.front().node
                                     : static_cast<std::uint32_t>(unit(random) * nodes) % nodes;
      loads.push_back({node, Eigen::Vector3d(0.05, -0.02, 0.01)});
    }
    warm.clear_forces();
    cold.clear_forces();
    for (const ReferenceLoad& load : loads)
      EXPECT_TRUE(warm.add_node_force(load.node, load.force_n.template cast<Scalar>()).is_ok());
    solve_both(targets, loads);
    if (targets.size() > 1 && unit(random) < 0.3) {  // a release: the rest re-solved
      ++releases;
      warm.clear_forces();
      cold.clear_forces();
      std::vector<Target> kept;
      for (const Target& target : targets)
        if (kept.empty() || unit(random) < 0.6) kept.push_back(target);
      solve_both(kept, {});
    }
    EXPECT_TRUE(warm.step().is_ok());
    EXPECT_TRUE(cold.step().is_ok());
    for (std::size_t i = 0; i < warm.active_mode_count(); ++i)
      EXPECT_EQ(warm.modal_displacement()[i], cold.modal_displacement()[i]) << "step " << step;
    if (::testing::Test::HasFailure()) break;
  }
  EXPECT_GT(releases, static_cast<std::size_t>(steps / 10));
  EXPECT_GT(reuses, static_cast<std::size_t>(steps / 4));
  return worst;
}

// A held contact that releases in every step, as in the cbd session (two of three held-contact
// cycles at 10 kHz): the full list, then the kept rows, step after step. Both lists keep their
// factorisation (with one kept, both were factorised again in every step), and the forces are
// those of a model that factorises every solve (its kept lists pushed out before each).
TEST(ModalContactSolve, HeldContactWithReleasesFactorisesEachListOnce) {
  using Target = ImposedDisplacement;
  const auto synthetic = random_model<float>(30, 6, true, 106);
  core::Arena arena = make_arena();
  const ModalSettings settings{1e-3F, 0, true};
  auto held_created = ModalModel::create(synthetic.data(), arena, settings);
  auto cold_created = ModalModel::create(synthetic.data(), arena, settings);
  ASSERT_TRUE(held_created && cold_created);
  ModalModel held = std::move(held_created).value();
  ModalModel cold = std::move(cold_created).value();
  std::mt19937 random(12);
  std::uniform_real_distribution<float> unit(-1e-4F, 1e-4F);
  const auto solve = [&](const std::vector<Target>& targets) {
    for (std::size_t list = 0; list < ModalModel::kFactorisations; ++list) {
      const std::vector<Target> flush(1, Target{static_cast<std::uint32_t>(20 + list),
                                                ModalModel::Vector3::Constant(1e-5F)});
      std::vector<ModalModel::Vector3> flush_forces(1);
      ASSERT_TRUE(cold.solve_imposed(flush, flush_forces).is_ok());
    }
    cold.clear_forces();
    std::vector<ModalModel::Vector3> held_forces(targets.size());
    std::vector<ModalModel::Vector3> cold_forces(targets.size());
    ASSERT_TRUE(held.solve_imposed(targets, held_forces).is_ok());
    ASSERT_TRUE(cold.solve_imposed(targets, cold_forces).is_ok());
    for (std::size_t k = 0; k < targets.size(); ++k) EXPECT_EQ(held_forces[k], cold_forces[k]);
  };
  constexpr int kSteps = 20;
  for (int step = 0; step < kSteps; ++step) {
    std::vector<Target> targets;
    for (const std::uint32_t node : {3U, 7U}) {
      targets.push_back(Target{node, ModalModel::Vector3(unit(random), unit(random), unit(random))});
    }
    held.clear_forces();
    cold.clear_forces();
    solve(targets);
    held.clear_forces();  // the second node lets go: the first one re-solved
    cold.clear_forces();
    targets.pop_back();
    solve(targets);
    ASSERT_TRUE(held.step().is_ok());
    ASSERT_TRUE(cold.step().is_ok());
  }
  EXPECT_EQ(held.contact_factorisations(), 2U);
  EXPECT_EQ(cold.contact_factorisations(), static_cast<std::uint64_t>(2 * kSteps * 5));
  for (std::size_t i = 0; i < held.active_mode_count(); ++i)
    EXPECT_EQ(held.modal_displacement()[i], cold.modal_displacement()[i]);
}

TEST(ModalContactSolve, DoubleModelMatchesDenseReferenceAndColdSolves) {
  const auto corrected = random_model<double>(30, 6, true, 101);
  const double worst_corrected = run_random_contact_sequence(corrected, true, 7, 300);
  EXPECT_LT(worst_corrected, 1e-9);
  const auto plain = random_model<double>(30, 40, false, 102);
  const double worst_plain = run_random_contact_sequence(plain, false, 8, 300);
  EXPECT_LT(worst_plain, 1e-9);
  std::printf("[ measured ] double model vs dense reference, worst relative difference: static "
              "correction %.2e, modes only %.2e\n", worst_corrected, worst_plain);
}

TEST(ModalContactSolve, FloatModelMatchesDenseReferenceAndColdSolves) {
  const auto corrected = random_model<float>(30, 6, true, 103);
  const double worst_corrected = run_random_contact_sequence(corrected, true, 9, 300);
  EXPECT_LT(worst_corrected, 1e-6);
  const auto plain = random_model<float>(30, 40, false, 104);
  const double worst_plain = run_random_contact_sequence(plain, false, 10, 300);
  EXPECT_LT(worst_plain, 1e-6);
  // A residual compliance not symmetric to the bit (one entry one ulp off): the solve then
  // reads both orientations of every block (the symmetric one reads one).
  auto asymmetric = random_model<float>(30, 6, true, 105);
  const std::size_t rows = 3 * asymmetric.node_count;
  asymmetric.residual_compliance[1 * rows + 2] = std::nextafter(
      asymmetric.residual_compliance[1 * rows + 2], std::numeric_limits<float>::infinity());
  EXPECT_LT(run_random_contact_sequence(asymmetric, true, 11, 300), 1e-6);
  std::printf("[ measured ] float model vs dense reference, worst relative difference: static "
              "correction %.2e, modes only %.2e\n", worst_corrected, worst_plain);
}

}  // namespace
}  // namespace trainer::model
