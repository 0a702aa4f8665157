// Particle catheter (Basdogan eq. 27–28, METHODS.md §2): the bending gradient against finite
// differences, the clamped chain against beam theory (small-deflection cantilever, axial bar,
// large-deflection elastica) through the offline Newton solve, the runtime integrator against
// that static solution (dynamic relaxation), energy decay, the stable-step budget, held
// particles, non-finite recovery, and zero heap use in the RT calls.
#include "trainer/model/catheter.hpp"

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/model_offline/catheter_static.hpp"

namespace trainer::model {
namespace {

using Vector3 = Eigen::Vector3d;

// Periods of the long runs (energy bound, no heap): 2,000 in sanitizer builds, where a step is
// ~20x slower and what is checked is memory and undefined behaviour, not the duration.
#if defined(TRAINER_SANITIZER_BUILD)
constexpr int kLongRunPeriods = 2000;
#else
constexpr int kLongRunPeriods = 10000;
#endif

// A polymer catheter: 2 mm outer diameter, E ≈ 50 MPa, ρ ≈ 1100 kg/m³, 0.3 m long.
constexpr double kLengthM = 0.3;
constexpr double kBendingStiffnessNm2 = 3.9e-5;  // E π r⁴ / 4
constexpr double kAxialStiffnessN = 157.0;       // E π r²
constexpr double kLinearDensityKgPerM = 3.5e-3;

CatheterParams polymer_catheter(std::uint32_t particles, float damping_n_s_per_m) {
  CatheterParams params;
  params.length_m = static_cast<float>(kLengthM);
  params.outer_radius_m = 1e-3F;
  params.bending_stiffness_n_m2 = static_cast<float>(kBendingStiffnessNm2);
  params.axial_stiffness_n = static_cast<float>(kAxialStiffnessN);
  params.linear_density_kg_per_m = static_cast<float>(kLinearDensityKgPerM);
  params.damping_n_s_per_m = damping_n_s_per_m;
  params.particle_count = particles;
  return params;
}

core::Arena make_arena() {
  auto arena = core::Arena::create(1 << 20);
  EXPECT_TRUE(arena.has_value());
  return std::move(arena).value();
}

Catheter make_catheter(core::Arena& arena, const CatheterParams& params, CatheterSetup setup = {}) {
  auto catheter = Catheter::create(params, setup, arena);
  EXPECT_TRUE(catheter.has_value()) << (catheter ? "" : catheter.error().message);
  return std::move(catheter).value();
}

offline::CatheterStaticResult solve_static(std::uint32_t particles, const Vector3& tip_force_n,
                                           std::uint32_t load_steps = 20) {
  offline::CatheterStaticInput input;
  input.length_m = kLengthM;
  input.bending_stiffness_n_m2 = kBendingStiffnessNm2;
  input.axial_stiffness_n = kAxialStiffnessN;
  input.particle_count = particles;
  input.tip_force_n = tip_force_n;
  input.load_steps = load_steps;
  auto result = offline::solve_catheter_static(input);
  EXPECT_TRUE(result.has_value()) << (result ? "" : result.error().message);
  return std::move(result).value();
}

TEST(CatheterForces, BendingAndAxialForcesAreTheExactEnergyGradient) {
  std::mt19937 random(7);
  std::uniform_real_distribution<double> jitter(-0.004, 0.004);
  constexpr std::uint32_t kCount = 7;
  ChainStiffness<double> stiffness;
  stiffness.axial_n_per_m = 50.0;
  stiffness.bending_n_m_per_rad = 0.02;
  stiffness.rest_length_m = 0.01;
  stiffness.root_tangent = Vector3(1.0, 0.2, -0.1).normalized();
  // Configurations from nearly straight (θ ~ 1e-5 rad, where a naive θ gradient divides 0/0)
  // to strongly bent (θ up to ~1 rad).
  for (double scale : {1e-5, 1e-2, 0.3, 1.0, 2.5}) {
    for (int trial = 0; trial < 4; ++trial) {
      stiffness.root_clamped = (trial % 2) == 0;
      std::vector<Vector3> positions(kCount);
      for (std::uint32_t i = 0; i < kCount; ++i) {
        positions[i] = Vector3(0.011 * i, 0.0, 0.0) +
                       scale * Vector3(jitter(random), jitter(random), jitter(random));
      }
      std::vector<Vector3> forces(kCount, Vector3::Zero());
      add_chain_forces<double>(positions, stiffness, forces);
      const double step_m = 1e-7;
      for (std::uint32_t i = 0; i < kCount; ++i) {
        for (int axis = 0; axis < 3; ++axis) {
          std::vector<Vector3> probe = positions;
          probe[i][axis] += step_m;
          const double plus = chain_energy<double>(probe, stiffness);
          probe[i][axis] -= 2.0 * step_m;
          const double minus = chain_energy<double>(probe, stiffness);
          const double expected_force = -(plus - minus) / (2.0 * step_m);
          EXPECT_NEAR(forces[i][axis], expected_force, 1e-6 * (1.0 + std::abs(expected_force)))
              << "scale " << scale << " trial " << trial << " particle " << i << " axis " << axis;
        }
      }
      // The float instance (run time) agrees with the double one to float precision.
      std::vector<Eigen::Vector3f> positions_float(kCount);
      std::vector<Eigen::Vector3f> forces_float(kCount, Eigen::Vector3f::Zero());
      for (std::uint32_t i = 0; i < kCount; ++i) positions_float[i] = positions[i].cast<float>();
      ChainStiffness<float> stiffness_float{50.0F, 0.02F, 0.01F, stiffness.root_clamped,
                                            stiffness.root_tangent.cast<float>()};
      add_chain_forces<float>(positions_float, stiffness_float, forces_float);
      for (std::uint32_t i = 0; i < kCount; ++i) {
        EXPECT_LT((forces_float[i].cast<double>() - forces[i]).norm(), 2e-3 * (1.0 + forces[i].norm()))
            << "scale " << scale << " particle " << i;
      }
    }
  }
}

// The run-time angle (catheter_angle: octant reduction and a minimax atan, no libm call)
// against std::atan2 in double, over [0, π] and at the small angles a nearly straight chain
// has: within 2 float ulp of π absolute, and 4e-7 relative below 0.1 rad. NaN propagates.
TEST(CatheterForces, FastAngleIsStdAtan2ToFloatPrecision) {
  double worst_absolute = 0.0;
  double worst_relative = 0.0;
  std::mt19937 random(3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int k = 0; k <= 200000; ++k) {
    // Uniform in angle, plus log-uniform small angles, at random magnitudes.
    const double angle = k % 2 == 0 ? std::numbers::pi * k / 200000.0 : std::pow(10.0, -8.0 + 7.0 * unit(random));
    const double scale = std::pow(10.0, -3.0 + 6.0 * unit(random));
    const auto sine = static_cast<float>(scale * std::sin(angle));
    const auto cosine = static_cast<float>(scale * std::cos(angle));
    const double exact = std::atan2(static_cast<double>(sine), static_cast<double>(cosine));
    const double fast = static_cast<double>(catheter_angle(sine, cosine));
    worst_absolute = std::max(worst_absolute, std::abs(fast - exact));
    if (exact > 0.0 && exact < 0.1) worst_relative = std::max(worst_relative, std::abs(fast - exact) / exact);
  }
  std::printf("catheter_angle vs atan2: worst absolute %.2e rad, worst relative below 0.1 rad %.2e\n",
              worst_absolute, worst_relative);
  EXPECT_LT(worst_absolute, 4.8e-7);  // 2 ulp of float(π)
  EXPECT_LT(worst_relative, 4e-7);
  EXPECT_EQ(catheter_angle(0.0F, 1.0F), 0.0F);
  EXPECT_NEAR(catheter_angle(0.0F, -1.0F), std::numbers::pi_v<float>, 3e-7F);
  EXPECT_NEAR(catheter_angle(1.0F, 0.0F), 0.5F * std::numbers::pi_v<float>, 2e-7F);
  EXPECT_EQ(catheter_angle(0.0F, 0.0F), 0.0F);
  EXPECT_TRUE(std::isnan(catheter_angle(std::numeric_limits<float>::quiet_NaN(), 1.0F)));
  EXPECT_TRUE(std::isnan(catheter_angle(1.0F, std::numeric_limits<float>::quiet_NaN())));
}

// A held segment (the forceps' jaws hold both its particles) clamps the chain: where the chain
// leaves it, the hinge is the clamped root's 2 k_b (hinge_stiffness). Checked three ways: the
// forces are the exact gradient of chain_energy with the same flags; a chain held at particles
// 0 and 1 gives its free particles exactly the forces of the chain from particle 1 on with a
// clamped root along the held segment, and a grasp in the middle does so on both sides (the
// back side as the reversed chain); a single held particle (a pin) and three held in a row add
// nothing.
TEST(CatheterForces, GraspHingesAreTheClampedRootsOnEitherSideOfAHeldSegment) {
  std::mt19937 random(11);
  std::uniform_real_distribution<double> jitter(-0.004, 0.004);
  constexpr std::uint32_t kCount = 9;
  ChainStiffness<double> stiffness;
  stiffness.axial_n_per_m = 50.0;
  stiffness.bending_n_m_per_rad = 0.02;
  stiffness.rest_length_m = 0.01;
  const auto flags = [](std::initializer_list<std::uint32_t> held) {
    std::vector<std::uint8_t> result(kCount, 0);
    for (const std::uint32_t i : held) result[i] = 1;
    return result;
  };
  const auto forces_of = [&](const std::vector<Vector3>& positions, const ChainStiffness<double>& chain,
                             const std::vector<std::uint8_t>& held) {
    std::vector<Vector3> forces(positions.size(), Vector3::Zero());
    add_chain_forces<double>(positions, chain, forces, held);
    return forces;
  };
  // The chain from `first` on (or, reversed, from `first` back to 0) with its root clamped
  // along the held segment that ends at `first`.
  const auto clamped_root_forces = [&](const std::vector<Vector3>& positions, std::uint32_t first,
                                       std::uint32_t other, bool reversed) {
    std::vector<Vector3> part;
    if (reversed) {
      for (std::uint32_t i = first + 1; i-- > 0;) part.push_back(positions[i]);
    } else {
      for (std::uint32_t i = first; i < kCount; ++i) part.push_back(positions[i]);
    }
    ChainStiffness<double> chain = stiffness;
    chain.root_clamped = true;
    chain.root_tangent = (positions[first] - positions[other]).normalized();
    return forces_of(part, chain, {});
  };
  for (double scale : {1e-2, 0.3, 1.0, 2.5}) {
    std::vector<Vector3> positions(kCount);
    for (std::uint32_t i = 0; i < kCount; ++i) {
      positions[i] = Vector3(0.011 * i, 0.0, 0.0) +
                     scale * Vector3(jitter(random), jitter(random), jitter(random));
    }
    for (const auto& held : {flags({0, 1}), flags({3, 4}), flags({7, 8}), flags({4}),
                             flags({2, 3, 4}), flags({0, 1, 5, 6})}) {
      const std::vector<Vector3> forces = forces_of(positions, stiffness, held);
      const double step_m = 1e-7;
      for (std::uint32_t i = 0; i < kCount; ++i) {
        for (int axis = 0; axis < 3; ++axis) {
          std::vector<Vector3> probe = positions;
          probe[i][axis] += step_m;
          const double plus = chain_energy<double>(probe, stiffness, held);
          probe[i][axis] -= 2.0 * step_m;
          const double minus = chain_energy<double>(probe, stiffness, held);
          const double expected_force = -(plus - minus) / (2.0 * step_m);
          EXPECT_NEAR(forces[i][axis], expected_force, 1e-6 * (1.0 + std::abs(expected_force)))
              << "scale " << scale << " particle " << i << " axis " << axis;
        }
      }
    }
    // Held 0 and 1: the free particles 2.. feel what a clamped root at particle 1 gives.
    {
      const std::vector<Vector3> grasped = forces_of(positions, stiffness, flags({0, 1}));
      const std::vector<Vector3> clamped = clamped_root_forces(positions, 1, 0, false);
      for (std::uint32_t i = 2; i < kCount; ++i) {
        EXPECT_LT((grasped[i] - clamped[i - 1]).norm(), 1e-12 * (1.0 + clamped[i - 1].norm()))
            << "scale " << scale << " particle " << i;
      }
    }
    // Held 3 and 4: towards the tip as a root clamped at 4, towards the start as one at 3.
    {
      const std::vector<Vector3> grasped = forces_of(positions, stiffness, flags({3, 4}));
      const std::vector<Vector3> front = clamped_root_forces(positions, 4, 3, false);
      for (std::uint32_t i = 5; i < kCount; ++i) {
        EXPECT_LT((grasped[i] - front[i - 4]).norm(), 1e-12 * (1.0 + front[i - 4].norm()))
            << "scale " << scale << " particle " << i;
      }
      const std::vector<Vector3> back = clamped_root_forces(positions, 3, 4, true);
      for (std::uint32_t i = 0; i < 3; ++i) {
        EXPECT_LT((grasped[i] - back[3 - i]).norm(), 1e-12 * (1.0 + back[3 - i].norm()))
            << "scale " << scale << " particle " << i;
      }
    }
    // A pin, or a run of three held particles, has no clamp hinge of its own.
    {
      const std::vector<Vector3> free = forces_of(positions, stiffness, {});
      const std::vector<Vector3> pinned = forces_of(positions, stiffness, flags({4}));
      for (std::uint32_t i = 0; i < kCount; ++i) EXPECT_EQ(pinned[i], free[i]) << i;
      const double plain = chain_energy<double>(positions, stiffness);
      EXPECT_EQ(chain_energy<double>(positions, stiffness, flags({4})), plain);
      // Three in a row: the middle hinge stays k_b (rigid anyway), the two ends get 2 k_b.
      const double theta_2 = segment_angle<double>(positions[2] - positions[1], positions[3] - positions[2]);
      const double theta_4 = segment_angle<double>(positions[4] - positions[3], positions[5] - positions[4]);
      EXPECT_NEAR(chain_energy<double>(positions, stiffness, flags({2, 3, 4})) - plain,
                  0.5 * stiffness.bending_n_m_per_rad * (theta_2 * theta_2 + theta_4 * theta_4),
                  1e-12 * (1.0 + plain));
    }
  }
}

// Small transverse tip load: the discrete chain against F L³/(3 EI). With the 2 k_b root hinge
// the chain's own linear answer is F L³/(3EI)·(1 + 1/(2n²)) (docs/catheter.md), so the error
// falls with N; the tolerance at N = 41 is the brief's 2 %, the measured error is far below.
TEST(CatheterStatic, SmallDeflectionCantileverConvergesToBeamTheory) {
  const double force_n = 1e-5;  // deflection ≈ 2.3 mm = 0.8 % of L: geometrically linear
  const double beam_m = force_n * kLengthM * kLengthM * kLengthM / (3.0 * kBendingStiffnessNm2);
  double previous_error = 1.0;
  for (std::uint32_t particles : {11U, 21U, 41U}) {
    const auto result = solve_static(particles, Vector3(0.0, force_n, 0.0), 1);
    const double error = std::abs(result.tip_displacement_m.y() - beam_m) / beam_m;
    std::printf("cantilever N = %u: tip deflection %.6e m, beam %.6e m, relative error %.3e, "
                "%u Newton iterations, residual %.2e N\n",
                particles, result.tip_displacement_m.y(), beam_m, error, result.iterations, result.residual_n);
    EXPECT_LT(error, previous_error) << "N = " << particles;
    previous_error = error;
    EXPECT_LT(result.residual_n, 1e-9 * kBendingStiffnessNm2 / (kLengthM * kLengthM) + 1e-12);
    EXPECT_NEAR(result.tip_displacement_m.z(), 0.0, 1e-12);
  }
  EXPECT_LT(previous_error, 0.02);
}

TEST(CatheterStatic, AxialTensionStretchesByFLOverEA) {
  const double force_n = 2.0;
  const auto result = solve_static(21, Vector3(force_n, 0.0, 0.0), 1);
  const double expected_m = force_n * kLengthM / kAxialStiffnessN;
  EXPECT_NEAR(result.tip_displacement_m.x(), expected_m, 1e-9 * expected_m + 1e-15);
  EXPECT_NEAR(result.tip_displacement_m.y(), 0.0, 1e-15);
}

// Large deflection, F L²/EI = 1: the inextensible elastica (Bisshopp & Drucker 1945) gives a
// tip deflection 0.3017 L — 9.5 % below the linear L/3 — and a tip rotation of about 0.46 rad
// (26°). EA ≫ F so stretching is negligible; the chain's own discretisation error is O(1/n²).
TEST(CatheterStatic, LargeDeflectionMatchesTheElastica) {
  const double force_n = kBendingStiffnessNm2 / (kLengthM * kLengthM);
  const auto result = solve_static(41, Vector3(0.0, force_n, 0.0), 40);
  const double deflection_ratio = result.tip_displacement_m.y() / kLengthM;
  std::printf("elastica F L²/EI = 1: tip deflection %.5f L (elastica 0.3017 L, linear 0.3333 L), "
              "shortening %.5f L, tip rotation %.4f rad, %u iterations\n",
              deflection_ratio, -result.tip_displacement_m.x() / kLengthM, result.tip_rotation_rad,
              result.iterations);
  EXPECT_NEAR(deflection_ratio, 0.3017, 0.003);
  EXPECT_LT(deflection_ratio, 1.0 / 3.0);
  EXPECT_GT(result.tip_rotation_rad, 0.40);
  EXPECT_LT(result.tip_rotation_rad, 0.52);
  EXPECT_LT(result.residual_n, 1e-9 * force_n + 1e-12);
}

TEST(CatheterStatic, RefusesBadInput) {
  offline::CatheterStaticInput input;
  input.length_m = kLengthM;
  input.bending_stiffness_n_m2 = kBendingStiffnessNm2;
  input.axial_stiffness_n = kAxialStiffnessN;
  input.particle_count = 2;
  auto result = offline::solve_catheter_static(input);
  ASSERT_FALSE(result.has_value());
  EXPECT_NE(result.error().message.find("particles = 2"), std::string::npos) << result.error().message;
  input.particle_count = 11;
  input.bending_stiffness_n_m2 = -1.0;
  EXPECT_FALSE(offline::solve_catheter_static(input).has_value());
}

// The runtime integrator with heavy damping (dynamic relaxation) settles where the Newton
// solve says: same chain, float vs double, so they agree to well below 1 %.
TEST(CatheterRuntime, DynamicRelaxationReachesTheStaticSolution) {
  constexpr std::uint32_t kParticles = 21;
  const double first_mode_rad_per_s =
      3.516 * std::sqrt(kBendingStiffnessNm2 / (kLinearDensityKgPerM * std::pow(kLengthM, 4.0)));
  const double mass_kg = kLinearDensityKgPerM * kLengthM / kParticles;
  core::Arena arena = make_arena();
  Catheter catheter = make_catheter(
      arena, polymer_catheter(kParticles, static_cast<float>(2.0 * mass_kg * first_mode_rad_per_s)));
  catheter.clamp_start(true);
  const Vector3 tip_force_n(0.0, 2e-3, 1e-3);  // F L²/EI ≈ 5: a large, out-of-plane deflection
  for (int period = 0; period < 6000; ++period) {
    catheter.clear_forces();
    ASSERT_TRUE(catheter.add_force(kParticles - 1, tip_force_n.cast<float>()).is_ok());
    ASSERT_TRUE(catheter.step(1e-3F).is_ok()) << "period " << period;
  }
  const auto reference = solve_static(kParticles, tip_force_n);
  const Vector3 runtime_tip = catheter.positions_m()[kParticles - 1].cast<double>();
  const double error = (runtime_tip - reference.tip_position_m).norm() / reference.tip_displacement_m.norm();
  std::printf("dynamic relaxation N = %u, %u substeps/ms: tip %.6f %.6f %.6f m, Newton %.6f %.6f %.6f m, "
              "error %.2e of the displacement\n",
              kParticles, catheter.substeps_per_period(), runtime_tip.x(), runtime_tip.y(), runtime_tip.z(),
              reference.tip_position_m.x(), reference.tip_position_m.y(), reference.tip_position_m.z(), error);
  EXPECT_LT(error, 2e-3);
  // Settled: what motion is left is float rounding ripple in the stiff axial springs.
  std::printf("settled kinetic energy %.2e J, elastic energy %.2e J\n", catheter.kinetic_energy_j(),
              catheter.potential_energy_j());
  EXPECT_LT(catheter.kinetic_energy_j(), 1e-4 * catheter.potential_energy_j());  // measured 3e-5
}

// Free vibration after the load is removed: only damping acts, so the total mechanical energy
// must not grow. Semi-implicit Euler conserves a shadow energy that differs from E by
// O(ω Δt) (measured worst rise 1.4e-4 of the initial energy in one period); the tolerance,
// 1e-3, is well below the decay over 2 s (a factor of ~1000).
TEST(CatheterRuntime, DampedFreeVibrationEnergyNeverIncreasesAndDecays) {
  core::Arena arena = make_arena();
  Catheter catheter = make_catheter(arena, polymer_catheter(21, 2e-4F));
  catheter.clamp_start(true);
  ASSERT_TRUE(catheter.add_force(20, Eigen::Vector3f(0.0F, 2e-3F, 0.0F)).is_ok());
  for (int period = 0; period < 3000; ++period) ASSERT_TRUE(catheter.step(1e-3F).is_ok());
  catheter.clear_forces();  // released: free vibration from the bent shape
  double energy = catheter.kinetic_energy_j() + catheter.potential_energy_j();
  const double initial = energy;
  double worst_rise = 0.0;
  for (int period = 0; period < 2000; ++period) {
    ASSERT_TRUE(catheter.step(1e-3F).is_ok());
    const double next = catheter.kinetic_energy_j() + catheter.potential_energy_j();
    worst_rise = std::max(worst_rise, (next - energy) / initial);
    energy = next;
  }
  std::printf("free vibration: energy %.4e J -> %.4e J in 2 s, worst rise per period %.2e of initial\n",
              initial, energy, worst_rise);
  EXPECT_LT(worst_rise, 1e-3);
  EXPECT_LT(energy, 1e-2 * initial);
}

TEST(CatheterRuntime, RefusesAPeriodBeyondTheSubstepBudget) {
  // The axial springs are implicit (no step limit); a stiff bending (EI) sets the substep.
  core::Arena arena = make_arena();
  CatheterParams stiff = polymer_catheter(41, 0.0F);
  stiff.bending_stiffness_n_m2 = 1.0F;  // a steel rod's EI on a light catheter
  stiff.axial_stiffness_n = 1e5F;       // steel-like EA: no longer limits the substep
  CatheterSetup setup;
  setup.max_substeps = 64;
  auto refused = Catheter::create(stiff, setup, arena);
  ASSERT_FALSE(refused.has_value());
  const std::string& message = refused.error().message;
  const double l0 = kLengthM / 40.0;
  const double mass = kLinearDensityKgPerM * kLengthM / 41.0;
  const double omega_squared = 20.0 * (1.0 / l0) / (mass * l0 * l0);
  // Largest substep 2/ω_r, ω_r² = ¼ ω² (catheter_stable_substep_s).
  const auto needed = static_cast<unsigned long>(std::ceil(1e-3 / (2.0 / std::sqrt(0.25 * omega_squared))));
  EXPECT_NE(message.find("needs " + std::to_string(needed) + " substeps"), std::string::npos) << message;
  EXPECT_NE(message.find("max_substeps = 64"), std::string::npos) << message;
  EXPECT_NE(message.find("EI = 1 N"), std::string::npos) << message;
  // The steel-like EA alone is accepted, at the substep of its bending.
  stiff.bending_stiffness_n_m2 = static_cast<float>(kBendingStiffnessNm2);
  auto accepted = Catheter::create(stiff, setup, arena);
  ASSERT_TRUE(accepted.has_value()) << accepted.error().message;
  EXPECT_LE(accepted->substeps_per_period(), 16U);

  // Within budget: 10,000 periods (sanitizers: 2,000) of an oscillating tip force stay finite
  // and bounded.
  Catheter catheter = make_catheter(arena, polymer_catheter(41, 1e-4F));
  EXPECT_LE(catheter.substeps_per_period(), 64U);
  catheter.clamp_start(true);
  double max_energy = 0.0;
  for (int period = 0; period < kLongRunPeriods; ++period) {
    catheter.clear_forces();
    const float phase = static_cast<float>(period) * 1e-3F * 2.0F * std::numbers::pi_v<float> * 3.0F;
    ASSERT_TRUE(catheter.add_force(40, Eigen::Vector3f(0.0F, 5e-3F * std::sin(phase), 0.0F)).is_ok());
    ASSERT_TRUE(catheter.step(1e-3F).is_ok()) << "period " << period;
    max_energy = std::max(max_energy, catheter.kinetic_energy_j() + catheter.potential_energy_j());
  }
  for (const auto& position : catheter.positions_m()) ASSERT_TRUE(position.allFinite());
  // The static work of the force amplitude, F²L³/(3EI)/2 ≈ 1.3e-5 J; resonance near 3 Hz could
  // amplify it, but nothing near the energy of a blow-up.
  std::printf("%d periods at %u substeps: max energy %.3e J\n", kLongRunPeriods, catheter.substeps_per_period(),
              max_energy);
  EXPECT_LT(max_energy, 1e-2);
  // A period the budget cannot cover is refused, state unchanged.
  const Eigen::Vector3f tip = catheter.positions_m()[40];
  EXPECT_EQ(catheter.step(1.0F).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(catheter.positions_m()[40], tip);
}

TEST(CatheterRuntime, HeldParticlesFollowTheirTargets) {
  core::Arena arena = make_arena();
  Catheter catheter = make_catheter(arena, polymer_catheter(21, 1e-3F));
  const Eigen::Vector3f jaw_m(0.15F, 0.01F, 0.0F);
  ASSERT_TRUE(catheter.hold(10, jaw_m).is_ok());
  for (int period = 0; period < 20; ++period) {
    const Eigen::Vector3f target = jaw_m + Eigen::Vector3f(0.0F, 1e-4F * static_cast<float>(period), 0.0F);
    const Eigen::Vector3f before = catheter.positions_m()[10];
    ASSERT_TRUE(catheter.hold(10, target).is_ok());
    ASSERT_TRUE(catheter.step(1e-3F).is_ok());
    EXPECT_EQ(catheter.positions_m()[10], target);
    // It moved there in a straight line over the period, with that velocity.
    EXPECT_LT((catheter.velocities_m_per_s()[10] - (target - before) / 1e-3F).norm(),
              1e-3F * (1.0F + ((target - before) / 1e-3F).norm()));
  }
  // The neighbours are pulled along by the springs.
  EXPECT_GT(catheter.positions_m()[9].y(), 0.0F);
  EXPECT_GT(catheter.positions_m()[11].y(), 0.0F);
  ASSERT_TRUE(catheter.release(10).is_ok());
  const Eigen::Vector3f held_at = catheter.positions_m()[10];
  for (int period = 0; period < 5; ++period) ASSERT_TRUE(catheter.step(1e-3F).is_ok());
  EXPECT_NE(catheter.positions_m()[10], held_at);
  EXPECT_EQ(catheter.hold(21, jaw_m).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(catheter.release(99).code(), core::StatusCode::invalid_argument);
}

TEST(CatheterRuntime, HoldForceIsWhatTheChainPullsWith) {
  // Particle 0 held, a steady axial pull of f on every other particle: at rest the pin must
  // balance the total, (N − 1) f, and the holder feels it along the pull.
  core::Arena arena = make_arena();
  Catheter catheter = make_catheter(arena, polymer_catheter(21, 1e-3F));
  ASSERT_TRUE(catheter.hold(0, catheter.positions_m()[0]).is_ok());
  const Eigen::Vector3f pull_n(2e-3F, 0.0F, 0.0F);
  for (int period = 0; period < 4000; ++period) {
    catheter.clear_forces();
    for (std::uint32_t i = 1; i < catheter.particle_count(); ++i) ASSERT_TRUE(catheter.add_force(i, pull_n).is_ok());
    ASSERT_TRUE(catheter.step(1e-3F).is_ok());
  }
  const Eigen::Vector3f expected = 20.0F * pull_n;
  EXPECT_LT((catheter.hold_forces_n()[0] - expected).norm(), 1e-2F * expected.norm());
  EXPECT_EQ(catheter.hold_forces_n()[1], Eigen::Vector3f::Zero());  // free particles: nothing
}

TEST(CatheterRuntime, ContactPlanesHoldTheChainAtForceOverStiffness) {
  // A free chain pressed onto a floor (normal +z) by f per particle rests at depth f/k, and
  // each plane reports the force it pushed with, equal and opposite to the press.
  core::Arena arena = make_arena();
  Catheter catheter = make_catheter(arena, polymer_catheter(21, 1e-3F));
  const float reach_m = 1e-3F;
  const float stiffness = 200.0F;
  const Eigen::Vector3f press_n(0.0F, 0.0F, -4e-3F);
  std::vector<ContactPlane> planes(catheter.particle_count());
  for (std::uint32_t i = 0; i < catheter.particle_count(); ++i) {
    planes[i].particle_a = planes[i].particle_b = i;
    planes[i].point_m = Eigen::Vector3f(catheter.positions_m()[i].x(), 0.0F, -reach_m);
    planes[i].normal = Eigen::Vector3f::UnitZ();
    planes[i].reach_m = reach_m;
    planes[i].stiffness_n_per_m = stiffness;
    planes[i].damping_n_s_per_m = 0.01F;
    planes[i].max_force_n = 1.0F;
  }
  ASSERT_TRUE(catheter.set_contact_planes(planes).is_ok());
  for (int period = 0; period < 3000; ++period) {
    catheter.clear_forces();
    for (std::uint32_t i = 0; i < catheter.particle_count(); ++i) ASSERT_TRUE(catheter.add_force(i, press_n).is_ok());
    ASSERT_TRUE(catheter.step(1e-3F).is_ok());
  }
  const float depth_m = -press_n.z() / stiffness;  // 20 µm
  for (std::uint32_t i = 0; i < catheter.particle_count(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_NEAR(catheter.positions_m()[i].z(), -depth_m, 0.02F * depth_m);
    EXPECT_LT((catheter.contact_plane_forces_n()[i] + press_n).norm(), 0.02F * press_n.norm());
  }
  // Lifted above reach, the planes push nothing.
  for (ContactPlane& plane : planes) plane.point_m.z() = -0.1F;
  ASSERT_TRUE(catheter.set_contact_planes(planes).is_ok());
  catheter.clear_forces();
  ASSERT_TRUE(catheter.step(1e-3F).is_ok());
  for (const Eigen::Vector3f& force : catheter.contact_plane_forces_n()) EXPECT_EQ(force, Eigen::Vector3f::Zero());
}

TEST(CatheterRuntime, ASegmentPlaneSplitsItsForceByTheWeight) {
  // One plane at w = 0.25 between particles 10 and 11: after one step from rest the plane's
  // impulse went 3/4 to particle 10 and 1/4 to 11 (their momenta, the only forces acting).
  core::Arena arena = make_arena();
  Catheter catheter = make_catheter(arena, polymer_catheter(21, 0.0F));
  ContactPlane plane;
  plane.particle_a = 10;
  plane.particle_b = 11;
  plane.weight_b = 0.25F;
  const Eigen::Vector3f point = 0.75F * catheter.positions_m()[10] + 0.25F * catheter.positions_m()[11];
  plane.point_m = point - Eigen::Vector3f(0.0F, 0.0F, 0.5e-3F);
  plane.normal = Eigen::Vector3f::UnitZ();
  plane.reach_m = 1e-3F;  // 0.5 mm deep at the start
  plane.stiffness_n_per_m = 50.0F;
  plane.max_force_n = 1.0F;
  ASSERT_TRUE(catheter.set_contact_planes(std::span(&plane, 1)).is_ok());
  ASSERT_TRUE(catheter.step(1e-4F).is_ok());
  const float mass = catheter.particle_mass_kg();
  const Eigen::Vector3f impulse = catheter.contact_plane_forces_n()[0] * 1e-4F;
  EXPECT_GT(impulse.z(), 0.0F);
  // The chain's springs pass some momentum on within the step; the split holds to a few %.
  float total_momentum = 0.0F;
  for (const Eigen::Vector3f& v : catheter.velocities_m_per_s()) total_momentum += mass * v.z();
  EXPECT_NEAR(total_momentum, impulse.z(), 1e-3F * impulse.z());
  EXPECT_NEAR(mass * catheter.velocities_m_per_s()[10].z() / impulse.z(), 0.75F, 0.05F);
  EXPECT_NEAR(mass * catheter.velocities_m_per_s()[11].z() / impulse.z(), 0.25F, 0.05F);
}

TEST(CatheterRuntime, ContactPlanesAreCheckedWhenSet) {
  core::Arena arena = make_arena();
  CatheterSetup setup;
  setup.max_contact_planes = 2;
  Catheter catheter = make_catheter(arena, polymer_catheter(21, 1e-3F), setup);
  ContactPlane good;
  good.reach_m = 1e-3F;
  good.stiffness_n_per_m = 10.0F;
  good.max_force_n = 1.0F;
  const auto refused = [&](ContactPlane bad) {
    const std::array<ContactPlane, 2> set{good, bad};
    const core::Status status = catheter.set_contact_planes(set);
    return !status.is_ok() && catheter.contact_plane_count() == 0;
  };
  ContactPlane bad = good;
  bad.particle_b = 21;
  EXPECT_TRUE(refused(bad));
  bad = good;
  bad.weight_b = 1.5F;
  EXPECT_TRUE(refused(bad));
  bad = good;
  bad.normal = Eigen::Vector3f(0.0F, 0.0F, 2.0F);
  EXPECT_TRUE(refused(bad));
  bad = good;
  bad.point_m.x() = std::numeric_limits<float>::quiet_NaN();
  EXPECT_TRUE(refused(bad));
  bad = good;
  bad.stiffness_n_per_m = 2.0F * catheter.max_contact_stiffness_n_per_m();
  EXPECT_TRUE(refused(bad));
  bad = good;
  bad.max_force_n = 0.0F;
  EXPECT_TRUE(refused(bad));
  const std::array<ContactPlane, 3> three{good, good, good};
  EXPECT_EQ(catheter.set_contact_planes(three).code(), core::StatusCode::capacity_exceeded);
  EXPECT_EQ(catheter.contact_plane_count(), 2U);
}

TEST(CatheterRuntime, AContactAtTheStiffnessLimitStaysBounded) {
  // Every particle hit by a plane at the largest accepted stiffness (1e5 m/h²), 1 mm deep, no
  // damping, each plane clamped below its start force: the kinetic energy must stay below the
  // initial contact energy. (An explicit clamped force on so stiff a plane for a whole 1 ms
  // substep flung the particles out at ~4e4 m/s before a clamped plane could turn back into an
  // implicit spring within the substep, Catheter::update_planes.)
  core::Arena arena = make_arena();
  Catheter catheter = make_catheter(arena, polymer_catheter(21, 0.0F));
  const float stiffness = catheter.max_contact_stiffness_n_per_m();
  std::vector<ContactPlane> planes(catheter.particle_count());
  for (std::uint32_t i = 0; i < catheter.particle_count(); ++i) {
    planes[i].particle_a = planes[i].particle_b = i;
    planes[i].point_m = catheter.positions_m()[i] - Eigen::Vector3f(0.0F, 0.0F, 1e-3F);
    planes[i].normal = Eigen::Vector3f::UnitZ();
    planes[i].reach_m = 2e-3F;
    planes[i].stiffness_n_per_m = stiffness;
    planes[i].max_force_n = 1e3F;
  }
  ASSERT_TRUE(catheter.set_contact_planes(planes).is_ok());
  const double initial_j = 21.0 * 0.5 * static_cast<double>(stiffness) * 1e-6;
  for (int period = 0; period < 200; ++period) {
    ASSERT_TRUE(catheter.step(1e-3F).is_ok());
    ASSERT_LT(catheter.kinetic_energy_j(), 1.3 * initial_j) << "period " << period;
  }
}

TEST(CatheterRuntime, NonFiniteInputOrStateIsRefusedAndTheStateKept) {
  core::Arena arena = make_arena();
  Catheter catheter = make_catheter(arena, polymer_catheter(21, 1e-4F));
  catheter.clamp_start(true);
  ASSERT_TRUE(catheter.add_force(20, Eigen::Vector3f(0.0F, 1e-3F, 0.0F)).is_ok());
  for (int period = 0; period < 10; ++period) ASSERT_TRUE(catheter.step(1e-3F).is_ok());
  const std::vector<Eigen::Vector3f> positions(catheter.positions_m().begin(), catheter.positions_m().end());
  const std::vector<Eigen::Vector3f> velocities(catheter.velocities_m_per_s().begin(),
                                                catheter.velocities_m_per_s().end());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(catheter.add_force(5, Eigen::Vector3f(nan, 0.0F, 0.0F)).code(), core::StatusCode::numeric_error);
  EXPECT_EQ(catheter.add_force(21, Eigen::Vector3f::Zero()).code(), core::StatusCode::invalid_argument);
  // An absurd but finite force overflows float within the step.
  ASSERT_TRUE(catheter.add_force(7, Eigen::Vector3f(3e38F, -3e38F, 3e38F)).is_ok());
  EXPECT_EQ(catheter.step(1e-3F).code(), core::StatusCode::numeric_error);
  for (std::size_t i = 0; i < positions.size(); ++i) {
    EXPECT_EQ(catheter.positions_m()[i], positions[i]) << i;
    EXPECT_EQ(catheter.velocities_m_per_s()[i], velocities[i]) << i;
  }
  // Removing the bad load lets the model continue.
  catheter.clear_forces();
  EXPECT_TRUE(catheter.step(1e-3F).is_ok());
}

TEST(CatheterRuntime, CreateRefusesBadParameters) {
  core::Arena arena = make_arena();
  CatheterParams params = polymer_catheter(2, 0.0F);
  auto refused = Catheter::create(params, {}, arena);
  ASSERT_FALSE(refused.has_value());
  EXPECT_NE(refused.error().message.find("particle_count = 2"), std::string::npos);
  params = polymer_catheter(300, 0.0F);
  EXPECT_FALSE(Catheter::create(params, {}, arena).has_value());
  params = polymer_catheter(21, 0.0F);
  params.bending_stiffness_n_m2 = -1.0F;
  refused = Catheter::create(params, {}, arena);
  ASSERT_FALSE(refused.has_value());
  EXPECT_NE(refused.error().message.find("EI"), std::string::npos);
  CatheterSetup setup;
  setup.direction = Eigen::Vector3f::Zero();
  EXPECT_FALSE(Catheter::create(polymer_catheter(21, 0.0F), setup, arena).has_value());
}

TEST(CatheterRuntime, RestShapeAndMassFollowTheMapping) {
  core::Arena arena = make_arena();
  CatheterSetup setup;
  setup.start_position_m = Eigen::Vector3f(0.01F, 0.02F, 0.03F);
  setup.direction = Eigen::Vector3f(0.0F, 0.0F, 2.0F);
  Catheter catheter = make_catheter(arena, polymer_catheter(31, 0.0F), setup);
  EXPECT_NEAR(catheter.stiffness().rest_length_m, kLengthM / 30.0, 1e-8);
  EXPECT_NEAR(catheter.stiffness().axial_n_per_m, kAxialStiffnessN * 30.0 / kLengthM, 1e-2);
  EXPECT_NEAR(catheter.stiffness().bending_n_m_per_rad, kBendingStiffnessNm2 * 30.0 / kLengthM, 1e-9);
  EXPECT_NEAR(catheter.particle_mass_kg(), kLinearDensityKgPerM * kLengthM / 31.0, 1e-10);
  EXPECT_LT((catheter.positions_m()[30] - Eigen::Vector3f(0.01F, 0.02F, 0.33F)).norm(), 1e-6F);
  // The straight rest shape is an equilibrium: no motion after many periods.
  for (int period = 0; period < 100; ++period) ASSERT_TRUE(catheter.step(1e-3F).is_ok());
  // Float rounding of the rest positions leaves sub-micrometre axial ripple, nothing more.
  for (std::uint32_t i = 0; i < 31; ++i) {
    const Eigen::Vector3f rest = setup.start_position_m + Eigen::Vector3f(0.0F, 0.0F, 0.01F * static_cast<float>(i));
    EXPECT_LT((catheter.positions_m()[i] - rest).norm(), 1e-6F) << i;
  }
  // substeps_for: exact multiples do not round up.
  EXPECT_EQ(Catheter::substeps_for(1e-3, 1e-4), 10U);
  EXPECT_EQ(Catheter::substeps_for(1e-3, 0.99e-4), 11U);
}

// 10,000 steps (sanitizers: 2,000).
TEST(CatheterRuntime, TenThousandStepsAllocateNothing) {
  ASSERT_TRUE(core::alloc::hooks_installed());
  core::Arena arena = make_arena();
  Catheter catheter = make_catheter(arena, polymer_catheter(41, 1e-4F));
  catheter.clamp_start(true);
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  bool all_ok = true;
  for (int period = 0; period < kLongRunPeriods; ++period) {
    catheter.clear_forces();
    all_ok = catheter.add_force(40, Eigen::Vector3f(0.0F, 1e-3F, 0.0F)).is_ok() && all_ok;
    all_ok = catheter.hold(20, catheter.positions_m()[20]).is_ok() && all_ok;
    all_ok = catheter.step(1e-3F).is_ok() && all_ok;
    (void)catheter.kinetic_energy_j();
    (void)catheter.potential_energy_j();
  }
  core::alloc::end_counting_this_thread();
  EXPECT_TRUE(all_ok);
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
}

}  // namespace
}  // namespace trainer::model
