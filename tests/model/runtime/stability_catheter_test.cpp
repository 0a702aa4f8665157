// Stability of the particle catheter at the extremes (docs/stability.md): stiffness-to-mass
// ratios from a 1 N to a 10 MN axial stiffness (the configuration's bound) and heavy damping,
// each run at exactly its substep budget (accepted, stable) and refused one substep below it
// with a message naming the need; a catheter accepted at its budget must then step; contact
// planes at the largest accepted stiffness driven through the whole catheter.
//
// Energy. Every part of the chain is integrated linearly implicitly (docs/catheter.md,
// "Integration and substep"): m(v' − v) = −h K x − h² K̃ v' − h b v' with K̃ the Jacobian the
// solve uses (the axial Hessian, the bending's at the straight chain, the active contacts).
// For a linear system the mechanical energy H = T + V then changes per substep by
//   ΔH = −½ m|v' − v|² − ½ h² v'ᵀK v' − h² v'ᵀ(K̃ − K) v' − h b |v'|²,
// never positive while K̃ ≥ K/2 (the straight chain: K̃ = K across, K̃ > K along). What is
// left is the bending's nonlinear remainder (a bent hinge's Hessian departs from the straight
// one's), bounded by the substep (catheter_stable_substep_s) — so what never grows from one
// substep to the next, undriven, is H itself, up to float rounding. The rounding is the
// positions' (p += h v in float): each substep moves every particle by up to ε|p| off its
// exact update, which changes V by up to |∇V_i|·ε|p_i|. The tolerance per substep is
// 4 Σ_i |F_i| ε ‖p_i‖ (F_i the chain force, ε = FLT_EPSILON).
#include <gtest/gtest.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "trainer/core/arena.hpp"
#include "trainer/model/catheter.hpp"

namespace trainer::model {
namespace {

using Vector3 = Eigen::Vector3d;

constexpr float kLengthM = 0.3F;
constexpr std::uint32_t kParticles = 21;
constexpr float kPeriodS = 1e-3F;
#if defined(TRAINER_SANITIZER_BUILD)
constexpr int kFreeSubsteps = 300;      // the sanitizer build checks the same cases, shorter
constexpr int kDeadLoadPeriods = 400;
#else
constexpr int kFreeSubsteps = 1500;
constexpr int kDeadLoadPeriods = 1000;
#endif

CatheterParams catheter_params(float axial_stiffness_n, float linear_density_kg_per_m,
                               float damping_n_s_per_m) {
  CatheterParams params;
  params.length_m = kLengthM;
  params.outer_radius_m = 1e-3F;
  params.bending_stiffness_n_m2 = 3.9e-5F;
  params.axial_stiffness_n = axial_stiffness_n;
  params.linear_density_kg_per_m = linear_density_kg_per_m;
  params.damping_n_s_per_m = damping_n_s_per_m;
  params.particle_count = kParticles;
  return params;
}

// Shadow energy H̃ and the rounding tolerance of one substep, in double from the float state.
struct EnergyState {
  double mechanical_j = 0.0;  // H = T + V
  double shadow_j = 0.0;      // H̃ = H (the former explicit bending's shadow term is gone)
  double rounding_j = 0.0;    // 4 Σ |F_i| ε ‖p_i‖_∞
};

EnergyState energy_state(const Catheter& catheter) {
  const auto positions = catheter.positions_m();
  const auto velocities = catheter.velocities_m_per_s();
  std::vector<Vector3> p(positions.size());
  std::vector<Vector3> forces(positions.size(), Vector3::Zero());
  for (std::size_t i = 0; i < p.size(); ++i) p[i] = positions[i].cast<double>();
  const ChainStiffness<float>& stiffness = catheter.stiffness();
  ChainStiffness<double> chain;
  chain.axial_n_per_m = static_cast<double>(stiffness.axial_n_per_m);
  chain.bending_n_m_per_rad = static_cast<double>(stiffness.bending_n_m_per_rad);
  chain.rest_length_m = static_cast<double>(stiffness.rest_length_m);
  chain.root_clamped = stiffness.root_clamped;
  chain.root_tangent = stiffness.root_tangent.cast<double>();
  add_chain_forces<double>(std::span<const Vector3>(p), chain, std::span<Vector3>(forces));
  EnergyState state;
  state.mechanical_j = catheter.kinetic_energy_j() + catheter.potential_energy_j();
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (i == 0 && stiffness.root_clamped) continue;  // held: its velocity is the holder's
    state.rounding_j += 4.0 * forces[i].norm() * static_cast<double>(FLT_EPSILON) *
                        p[i].cwiseAbs().maxCoeff();
  }
  state.shadow_j = state.mechanical_j;  // nothing explicit left to shadow (see the top)
  return state;
}

struct FreeRun {
  bool finite = true;
  double released_j = 0.0;       // H after release
  double final_j = 0.0;          // H at the end
  double released_shadow_j = 0.0;  // H̃ after release
  double final_shadow_j = 0.0;     // H̃ at the end
  double worst_shadow_rise = 0.0;  // max over substeps of ΔH̃ / rounding tolerance
  double worst_mechanical_rise = 0.0;  // max over substeps of ΔH / H at release
};

// Clamped at the root, the tip pushed sideways and along the axis for `load_periods`, then
// released and stepped one substep at a time (step(substep) takes exactly one) for `substeps`.
FreeRun bend_and_release(Catheter& catheter, float tip_force_n, int load_periods, int substeps) {
  FreeRun run;
  catheter.clamp_start(true);
  EXPECT_TRUE(catheter.add_force(kParticles - 1, Eigen::Vector3f(0.5F * tip_force_n, tip_force_n, 0.0F))
                  .is_ok());
  for (int period = 0; period < load_periods; ++period) {
    EXPECT_TRUE(catheter.step(kPeriodS).is_ok());
  }
  catheter.clear_forces();
  const float substep = catheter.stable_substep_s();
  EXPECT_TRUE(catheter.step(substep).is_ok());  // the force's last substep
  EnergyState state = energy_state(catheter);
  run.released_j = state.mechanical_j;
  run.released_shadow_j = state.shadow_j;
  for (int k = 0; k < substeps; ++k) {
    EXPECT_TRUE(catheter.step(substep).is_ok());
    for (const auto& position : catheter.positions_m()) run.finite = run.finite && position.allFinite();
    for (const auto& velocity : catheter.velocities_m_per_s()) run.finite = run.finite && velocity.allFinite();
    const EnergyState next = energy_state(catheter);
    run.worst_shadow_rise =
        std::max(run.worst_shadow_rise, (next.shadow_j - state.shadow_j) / state.rounding_j);
    run.worst_mechanical_rise = std::max(
        run.worst_mechanical_rise, (next.mechanical_j - state.mechanical_j) / run.released_j);
    state = next;
  }
  run.final_j = state.mechanical_j;
  run.final_shadow_j = state.shadow_j;
  return run;
}

// Substeps one period needs, from a catheter created with a budget that cannot bind.
std::uint32_t needed_substeps(const CatheterParams& params, float period_s = kPeriodS) {
  core::Arena arena = core::Arena::create(1 << 16).value();
  CatheterSetup setup;
  setup.haptic_period_s = period_s;
  setup.max_substeps = 1U << 30;
  setup.max_contact_planes = 0;
  auto catheter = Catheter::create(params, setup, arena);
  EXPECT_TRUE(catheter) << catheter.error().message;
  return catheter ? catheter->substeps_per_period() : 0;
}

TEST(CatheterStability, StiffnessToMassRatiosUpToTheSubstepBudget) {
  // EA from 1 N to 1e7 N (the configuration's bound) on a light (3.5 g/m) and a heavy
  // (100 g/m) catheter: ω_max² ≈ 4 EA/(l0 m) spans 12 decades. Each is created with exactly the
  // substeps it needs as its budget (accepted, and its released, damped vibration checked
  // substep by substep) and with one fewer (refused, the message naming the need).
  struct Case {
    float axial_stiffness_n;
    float linear_density_kg_per_m;
  };
  for (const Case c : {Case{1.0F, 3.5e-3F}, Case{157.0F, 3.5e-3F}, Case{1e4F, 3.5e-3F},
                       Case{1e6F, 3.5e-3F}, Case{1e7F, 3.5e-3F}, Case{1e7F, 0.1F}}) {
    SCOPED_TRACE(testing::Message() << "EA " << c.axial_stiffness_n << " N, rho "
                                    << c.linear_density_kg_per_m << " kg/m");
    // Damping b = 0.02 m ω_max (2 % of critical for the stiffest axial mode, which the release
    // rings most): well inside the substep's own m/b limit.
    const float mass = c.linear_density_kg_per_m * kLengthM / static_cast<float>(kParticles);
    CatheterParams params = catheter_params(c.axial_stiffness_n, c.linear_density_kg_per_m, 0.0F);
    {
      core::Arena probe_arena = core::Arena::create(1 << 16).value();
      CatheterSetup probe;
      probe.max_substeps = 1U << 30;
      probe.max_contact_planes = 0;
      const float substep = Catheter::create(params, probe, probe_arena)->stable_substep_s();
      params.damping_n_s_per_m = 0.02F * mass / substep;
    }
    const std::uint32_t needed = needed_substeps(params);
    ASSERT_GE(needed, 1U);
    core::Arena arena = core::Arena::create(1 << 16).value();
    CatheterSetup setup;
    setup.max_contact_planes = 0;
    if (needed > 1) {
      setup.max_substeps = needed - 1;
      auto refused = Catheter::create(params, setup, arena);
      ASSERT_FALSE(refused);
      const std::string& message = refused.error().message;
      EXPECT_NE(message.find("needs " + std::to_string(needed) + " substeps"), std::string::npos)
          << message;
      EXPECT_NE(message.find("max_substeps = " + std::to_string(needed - 1)), std::string::npos)
          << message;
    }
    setup.max_substeps = needed;
    auto accepted = Catheter::create(params, setup, arena);
    ASSERT_TRUE(accepted) << accepted.error().message;
    EXPECT_EQ(accepted->substeps_per_period(), needed);
    // Load for 5 periods, then 1500 substeps free (hundreds of periods of the stiffest mode).
    const int substeps = kFreeSubsteps;
    const FreeRun run = bend_and_release(*accepted, 1e-3F, 5, substeps);
    std::printf("EA %7.0e N rho %6.4f kg/m: %5u substeps of %.3e s per ms (w_max^2 %.2e); released "
                "H %.3e -> %.3e J, H~ %.3e -> %.3e J over %d substeps; "
                "worst rise of H %.1e of H0, of H~ %.2f of the rounding tolerance\n",
                static_cast<double>(c.axial_stiffness_n),
                static_cast<double>(c.linear_density_kg_per_m), needed,
                static_cast<double>(accepted->stable_substep_s()),
                1.0 / std::pow(static_cast<double>(accepted->stable_substep_s()), 2.0),
                run.released_j, run.final_j, run.released_shadow_j, run.final_shadow_j, substeps,
                run.worst_mechanical_rise, run.worst_shadow_rise);
    EXPECT_TRUE(run.finite);
    EXPECT_LE(run.worst_shadow_rise, 1.0);
    // Over the whole run H̃ stays near where it was released: float rounding heats the stiff
    // axial springs a little every substep, in a window (0.2 ms at EA = 1e7 N) where the
    // damping removes little. Measured at EA = 1e7 N: +20 % over 1500 substeps in the release
    // build (the explicit chain before: +8 %, +29 % over 300 under ASan+UBSan); an instability
    // would grow by orders of magnitude.
    EXPECT_LT(run.final_shadow_j, 1.5 * run.released_shadow_j);
    // And a whole period at the budget runs.
    EXPECT_TRUE(accepted->step(kPeriodS).is_ok());
  }
}

TEST(CatheterStability, AcceptedAtExactlyItsBudgetAlwaysSteps) {
  // For EI at the edge of every budget from 8 to 80 substeps (±20 float steps of EI around the
  // value where period / substep is an integer; the explicit bending sets the substep), a
  // catheter create() accepts must step: create() and step() count substeps from the same
  // stored float substep. (They did not: counting from the double substep accepted, e.g.,
  // EA = 743.3208 N at 63 substeps when the axial springs set the substep, whose float substep
  // needs 64, and every step() was refused.)
  CatheterParams params = catheter_params(157.0F, 3.5e-3F, 0.0F);
  const double rest_length = static_cast<double>(kLengthM) / (kParticles - 1);
  const double mass = static_cast<double>(params.linear_density_kg_per_m) *
                      static_cast<double>(kLengthM) / kParticles;
  int accepted_count = 0;
  for (std::uint32_t budget = 8; budget <= 80; ++budget) {
    // substep = 2/sqrt(¼ ω²) = 4/ω with ω² = 20 (EI / l0) / (m l0²)
    const double omega = 4.0 * budget / static_cast<double>(kPeriodS);
    float bending = static_cast<float>(omega * omega * mass * rest_length * rest_length * rest_length / 20.0);
    for (int k = 0; k < 20; ++k) bending = std::nextafter(bending, 0.0F);
    for (int k = 0; k < 40; ++k, bending = std::nextafter(bending, FLT_MAX)) {
      params.bending_stiffness_n_m2 = bending;
      core::Arena arena = core::Arena::create(1 << 14).value();
      CatheterSetup setup;
      setup.max_substeps = budget;
      setup.max_contact_planes = 0;
      auto catheter = Catheter::create(params, setup, arena);
      if (!catheter) continue;
      ++accepted_count;
      ASSERT_TRUE(catheter->step(kPeriodS).is_ok())
          << "EI " << bending << " N m2 accepted at " << catheter->substeps_per_period() << " of "
          << budget << " substeps but step() refused the period";
    }
  }
  EXPECT_GT(accepted_count, 73 * 15);  // both sides of every edge were probed
  EXPECT_LT(accepted_count, 73 * 25);
}

TEST(CatheterStability, HeavyDampingUpToTheSubstepBudget) {
  // Damping is implicit and does not limit the substep: from the default 5e-4 N·s/m to
  // 100 N·s/m (the configuration allows 1000) the count is the undamped chain's. At a 20 ms
  // period (several substeps), one substep short is refused with a message that names the
  // damping; at the budget accepted and dissipative.
  const std::uint32_t undamped = needed_substeps(catheter_params(157.0F, 3.5e-3F, 0.0F), 20e-3F);
  ASSERT_GT(undamped, 1U);
  for (const float damping : {5e-4F, 1.0F, 10.0F, 100.0F}) {
    SCOPED_TRACE(damping);
    const CatheterParams params = catheter_params(157.0F, 3.5e-3F, damping);
    const std::uint32_t needed = needed_substeps(params);
    EXPECT_EQ(needed_substeps(params, 20e-3F), undamped);
    core::Arena arena = core::Arena::create(1 << 16).value();
    CatheterSetup setup;
    setup.max_contact_planes = 0;
    setup.haptic_period_s = 20e-3F;
    setup.max_substeps = undamped - 1;
    auto refused = Catheter::create(params, setup, arena);
    ASSERT_FALSE(refused);
    char named[64];
    std::snprintf(named, sizeof named, "damping %.6g N", static_cast<double>(damping));
    EXPECT_NE(refused.error().message.find(named), std::string::npos) << refused.error().message;
    setup.haptic_period_s = kPeriodS;
    setup.max_substeps = needed;
    auto accepted = Catheter::create(params, setup, arena);
    ASSERT_TRUE(accepted) << accepted.error().message;
    const FreeRun run = bend_and_release(*accepted, 1e-3F, 5, kFreeSubsteps);
    std::printf("damping %6.0e N s/m: %5u substeps per ms; released H %.3e -> %.3e J; worst rise "
                "of H~ %.2f of the rounding tolerance\n",
                static_cast<double>(damping), needed, run.released_j, run.final_j,
                run.worst_shadow_rise);
    EXPECT_TRUE(run.finite);
    EXPECT_LE(run.worst_shadow_rise, 1.0);
    EXPECT_LT(run.final_shadow_j, run.released_shadow_j);
  }
}

TEST(CatheterStability, ContactPlanesAtTheStiffnessLimitThroughTheWholeCatheter) {
  // The catheter clamped at its root, every particle against a plane at the largest accepted
  // stiffness, the plane moved from touching to the whole catheter length deep (0.3 m: far
  // past max_force_n / stiffness), undamped and damped contacts. Every plane force stays within
  // max_force_n, the state finite and the chain intact: the 20 planes' 0.4 N each pull the root
  // segment with 8 N, a static strain of 8/157 = 5 %; the plane's jumps in depth are sudden
  // loads (measured peak strain 16 %), and no segment strays beyond 25 %.
  for (const float damping_n_s_per_m : {0.0F, 0.05F}) {
    core::Arena arena = core::Arena::create(1 << 16).value();
    CatheterSetup setup;
    setup.max_contact_planes = kParticles;
    auto catheter = Catheter::create(catheter_params(157.0F, 3.5e-3F, 5e-4F), setup, arena);
    ASSERT_TRUE(catheter) << catheter.error().message;
    catheter->clamp_start(true);
    const float stiffness = catheter->max_contact_stiffness_n_per_m();
    const float rest_length = catheter->stiffness().rest_length_m;
    constexpr float kMaxForceN = 0.4F;
    float peak_n = 0.0F;
    float worst_strain = 0.0F;
    for (const float depth_m : {1e-4F, 1e-3F, 1e-2F, 0.1F, kLengthM}) {
      std::vector<ContactPlane> planes(kParticles);
      for (std::uint32_t i = 0; i < kParticles; ++i) {
        planes[i].particle_a = planes[i].particle_b = i;
        // The rest line is z = 0: a plane through z = depth − reach puts every particle
        // `depth` too deep.
        planes[i].point_m = Eigen::Vector3f(0.0F, 0.0F, depth_m - 1e-3F);
        planes[i].normal = Eigen::Vector3f::UnitZ();
        planes[i].reach_m = 1e-3F;
        planes[i].stiffness_n_per_m = stiffness;
        planes[i].damping_n_s_per_m = damping_n_s_per_m;
        planes[i].max_force_n = kMaxForceN;
      }
      ASSERT_TRUE(catheter->set_contact_planes(planes).is_ok());
      for (int period = 0; period < 50; ++period) {
        ASSERT_TRUE(catheter->step(kPeriodS).is_ok()) << "depth " << depth_m << " period " << period;
        for (const Eigen::Vector3f& force : catheter->contact_plane_forces_n()) {
          ASSERT_TRUE(force.allFinite());
          ASSERT_LE(force.norm(), kMaxForceN * (1.0F + 1e-6F));
          peak_n = std::max(peak_n, force.norm());
        }
        const auto positions = catheter->positions_m();
        for (std::size_t i = 0; i + 1 < positions.size(); ++i) {
          ASSERT_TRUE(positions[i + 1].allFinite());
          worst_strain = std::max(
              worst_strain, std::abs((positions[i + 1] - positions[i]).norm() / rest_length - 1.0F));
        }
      }
    }
    std::printf("planes at k = %.3g N/m (the limit), damping %.2f N s/m, up to 0.3 m deep: peak "
                "plane force %.3f N, worst segment strain %.2e\n",
                static_cast<double>(stiffness), static_cast<double>(damping_n_s_per_m),
                static_cast<double>(peak_n), static_cast<double>(worst_strain));
    EXPECT_GT(peak_n, 0.99F * kMaxForceN);  // the cap was reached, and held
    EXPECT_LT(worst_strain, 0.25F);
  }
}

TEST(CatheterStability, DeadTipLoadsFromTwentyTimesEaInTensionToCrushing) {
  // The clamped polymer catheter (EA 157 N) under a constant tip load with a small sideways
  // part, for 1 s (0.4 s in the sanitizer build). Tension of any size is stable: the geometric stiffness of a stretched
  // segment is T/l = k_s (1 − l0/l) < k_s, inside the substep's bound however far it stretches
  // (20 EA stretches it 20-fold and it settles). Compression folds the catheter back on itself;
  // up to 0.5 EA (78 N) it flips over and settles. (With explicit axial springs the fold
  // crushed segments from ~0.2 EA and the chain pumped energy — measured without the guard:
  // kinetic energy 2e3 J, segments stretched 23-fold; the linearly implicit axial springs
  // dissipate instead, and 0.2 and 0.5 EA settle.) From ~1 EA the load itself crushes a
  // segment: step() refuses a step that leaves a segment shorter than a tenth of its rest
  // length, restoring the state, and says so. The
  // work the load can do is W = |F| (L + L (1 + |F|/EA)) (the tip swings over and the chain
  // stretches); the peak kinetic energy stays below 1.5 W (measured up to 1.36 W at 1 EA,
  // where the pumping had reached 14 W).
  struct Case {
    float load_over_ea;  // along +x (tension) when positive
    bool refused;
  };
  for (const Case c : {Case{20.0F, false}, Case{1.0F, false}, Case{-0.01F, false},
                       Case{-0.1F, false}, Case{-0.2F, false}, Case{-0.5F, false}, Case{-1.0F, true},
                       Case{-2.0F, true}}) {
    SCOPED_TRACE(c.load_over_ea);
    core::Arena arena = core::Arena::create(1 << 16).value();
    CatheterSetup setup;
    setup.max_contact_planes = 0;
    auto catheter = Catheter::create(catheter_params(157.0F, 3.5e-3F, 5e-4F), setup, arena);
    ASSERT_TRUE(catheter) << catheter.error().message;
    catheter->clamp_start(true);
    const float load_n = c.load_over_ea * 157.0F;
    ASSERT_TRUE(catheter->add_force(kParticles - 1, Eigen::Vector3f(load_n, 1e-3F, 0.0F)).is_ok());
    int refusals = 0;
    double peak_kinetic_j = 0.0;
    std::string message;
    for (int period = 0; period < kDeadLoadPeriods; ++period) {
      const std::vector<Eigen::Vector3f> before(catheter->positions_m().begin(),
                                                catheter->positions_m().end());
      const core::Status status = catheter->step(kPeriodS);
      if (!status.is_ok()) {
        ++refusals;
        message = status.detail();
        ASSERT_EQ(status.code(), core::StatusCode::numeric_error);
        for (std::size_t i = 0; i < before.size(); ++i) {
          ASSERT_EQ(catheter->positions_m()[i], before[i]) << "a refused step changed the state";
        }
      }
      for (const auto& position : catheter->positions_m()) ASSERT_TRUE(position.allFinite());
      peak_kinetic_j = std::max(peak_kinetic_j, catheter->kinetic_energy_j());
    }
    std::printf("tip load %7.2f EA (%8.2f N): %4d of %d periods refused, peak kinetic energy "
                "%.3e J, at the end %.3e J%s%s\n",
                static_cast<double>(c.load_over_ea), static_cast<double>(load_n), refusals,
                kDeadLoadPeriods, peak_kinetic_j, catheter->kinetic_energy_j(), message.empty() ? "" : ": ",
                message.c_str());
    if (c.refused) {
      EXPECT_GT(refusals, 0);
      EXPECT_NE(message.find("crushed below 10 % of its rest length"), std::string::npos) << message;
      const double load = std::abs(static_cast<double>(load_n));
      const double length = static_cast<double>(kLengthM);
      EXPECT_LT(peak_kinetic_j, 1.5 * load * (length + length * (1.0 + load / 157.0)));
    } else {
      EXPECT_EQ(refusals, 0);
      // Settling at the damping's rate: the kinetic energy decays as e^(−b t/m) (b/m = 10/s).
      const double rate_per_s = 5e-4 / static_cast<double>(catheter->particle_mass_kg());
      const double decay = std::exp(-rate_per_s * kDeadLoadPeriods * static_cast<double>(kPeriodS));
      EXPECT_LT(catheter->kinetic_energy_j(), 10.0 * decay * peak_kinetic_j);
    }
  }
}

}  // namespace
}  // namespace trainer::model
