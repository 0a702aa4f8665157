// The particle catheter at run time (Basdogan §V-C-2, eq. 27–28; METHODS.md §2): N particles
// uniformly along the centreline joined by linear (axial) springs and torsional (bending)
// springs, viscous dissipation per particle, external forces, held particles (forceps jaws,
// introducer) and an optional clamped start. Integrated linearly implicitly (axial springs,
// bending through its Hessian at the straight chain, damping, the stiff part of the active
// contact planes), every force itself evaluated at the substep's positions (Basdogan eq. 27–28
// as an IMEX step), sub-stepped inside one haptic period at a step the model computes itself.
//
// Mapping of the beam to the chain (derivation in docs/catheter.md):
//   l0  = L/(N−1)            rest segment length (m)
//   m   = ρ_l L / N          every particle the same mass (kg): total mass exact, ends not halved
//   k_s = EA / l0            axial spring of one segment, a bar of length l0 (N/m)
//   k_b = EI / l0            torsional spring on the angle θ between neighbouring segments
//                            (N·m/rad): discrete elastica M = EI κ with κ ≈ θ / l0
//   E_b = ½ k_b θ², θ = atan2(|a×b|, a·b), differentiated exactly (bending_gradient()).
//   Clamped start: particle 0 held at its rest position and a root hinge of stiffness 2 k_b
//   between the clamp direction and the first segment — the half cell [0, l0/2] the interior
//   hinges do not cover. This makes the cantilever tip deflection F L³/(3EI)·(1 + 1/(2n²))
//   with n = N−1 segments (second order); fixing particles 0 and 1 instead gives
//   (1 − 3/(2n) + 1/(2n²)), −3.7 % at N = 41.
//   Grasp hinges: a held segment (both particles held: the forceps' jaws) clamps the chain the
//   same way, so a held particle where the chain leaves it gets 2 k_b (hinge_stiffness()).
//   Without them the grasp force converged at first order (44 % low at N = 11 in the cbd
//   insertion, docs/tradeoff-models.md); with them at second order.
//   Dissipation −b v with b in N·s/m per particle (not a damping ratio).
//
// Stability (docs/catheter.md, "Integration and substep"): each substep solves
// A v' = m v + h F̂(p, v), A = (m + h b) I + h² (H_axial + K_b) + h Σ (h k̃ + c) W n nᵀ Wᵀ
// (block pentadiagonal, 3×3 blocks, double): H_axial the axial Hessian (tension's transverse
// geometric stiffness k_s (1 − l0/l) included; compression's negative one stays explicit and
// grows without bound as a segment collapses: step() refuses a segment crushed below
// kMinSegmentRatio · l0), K_b = Σ k_i/l0² d dᵀ ⊗ I3 the bending's Hessian at the straight chain
// (d = [1 −2 1]; the clamped root's and grasp hinges' 2 k_b), and per contact plane active and
// unclamped at the substep start its stiffness beyond m/h² (k̃ = k − m/h²: a contact the
// substep resolves stays explicit and keeps its restitution) with its damper. For a linear
// system this dissipates whenever the matrix's stiffness is at least half the true one;
// the substep bounds the bending's nonlinear remainder: 2/ω_r, ω_r² = ¼ · 20 k_b/(m l0²)
// (catheter_stable_substep_s).
//
// Precision: float positions/velocities (SI), internal sums in float. Memory: every array is
// carved from a core::Arena at create(); after create() everything is noexcept, heap-free and
// lock-free. One thread (the haptic thread) owns the model.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <type_traits>

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross()

#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/core/status.hpp"
#include "trainer/model/catheter_chain.hpp"  // CatheterParams, CatheterChain, CatheterModelData

namespace trainer::model {

// Rest placement and the cycle budget.
struct CatheterSetup {
  Eigen::Vector3f start_position_m = Eigen::Vector3f::Zero();  // particle 0
  Eigen::Vector3f direction = Eigen::Vector3f::UnitX();         // rest tangent, normalised here
  float haptic_period_s = 1e-3F;
  std::uint32_t max_substeps = 64;  // most substeps one haptic period may cost
  std::uint32_t max_contact_planes = 64;  // contact planes one step may take (set_contact_planes)
};

// One unilateral contact held for one step(), evaluated at every substep (linearly implicit in
// its stiffness beyond m/h² while active and unclamped at the substep start; collision detection
// runs once per period). The catheter's material point x = (1 − w) p_a + w p_b (w = weight_b; a point on
// the segment between two particles, or a particle itself with w = 0) must stay at least
// reach_m from the plane through point_m with unit normal `normal` on its positive side:
//   depth = reach_m − (x − point_m)·normal,
//   f = k·depth − b·((ẋ − surface_velocity)·normal), clipped to [0, max_force_n], f = 0 when
//   depth ≤ 0; the force f·normal goes (1 − w) to particle a and w to particle b.
// The plane is the contact's tangent plane at detection time (a duct wall, a jaw's surface);
// it does not move during the step (its velocity only enters the damper).
struct ContactPlane {
  std::uint32_t particle_a = 0;
  std::uint32_t particle_b = 0;
  float weight_b = 0.0F;  // [0, 1]
  Eigen::Vector3f point_m = Eigen::Vector3f::Zero();
  Eigen::Vector3f normal = Eigen::Vector3f::UnitZ();  // unit, towards the catheter
  Eigen::Vector3f surface_velocity_m_per_s = Eigen::Vector3f::Zero();
  float reach_m = 0.0F;            // ≥ 0: the two radii (catheter + surface half-thickness/tool)
  float stiffness_n_per_m = 0.0F;  // > 0, ≤ Catheter::max_contact_stiffness_n_per_m()
  float damping_n_s_per_m = 0.0F;  // ≥ 0
  float max_force_n = 0.0F;        // > 0
};

// Spring constants of the chain, in the precision of the caller (float at run time, double in
// the offline static check, both through the same code below).
template <class Scalar>
struct ChainStiffness {
  Scalar axial_n_per_m = 0;          // k_s
  Scalar bending_n_m_per_rad = 0;    // k_b
  Scalar rest_length_m = 0;          // l0
  bool root_clamped = false;         // root hinge 2 k_b against root_tangent at particle 0
  Eigen::Matrix<Scalar, 3, 1> root_tangent = Eigen::Matrix<Scalar, 3, 1>::UnitX();  // unit
};

// atan2(sine, cosine) for sine ≥ 0 (an angle in [0, π]) in float without the libm call, which
// was ~60 % of the catheter's cost: the octant is reduced to |t| ≤ tan(π/8) and atan(t) is the
// classic degree-9 odd minimax polynomial (Cephes' atanf), within 2 float ulp of std::atan2 over
// [0, π] (CatheterForces.FastAngleIsStdAtan2ToFloatPrecision measures it). NaN in, NaN out.
inline float catheter_angle(float sine, float cosine) noexcept {
  constexpr float kPi = 3.14159265358979F;
  const float magnitude = std::fabs(cosine);
  // First octant pair: t = min/max in [0, 1], angle = atan(t) or π/2 − atan(t).
  const bool swapped = sine > magnitude;
  const float numerator = swapped ? magnitude : sine;
  const float denominator = swapped ? sine : magnitude;
  float t = denominator > 0.0F ? numerator / denominator : 0.0F;
  float offset = 0.0F;
  if (t > 0.4142135623730950F) {  // tan(π/8): atan(t) = π/4 + atan((t − 1)/(t + 1))
    t = (t - 1.0F) / (t + 1.0F);
    offset = 0.25F * kPi;
  }
  const float z = t * t;
  const float atan_t =
      offset + ((((8.05374449538e-2F * z - 1.38776856032e-1F) * z + 1.99777106478e-1F) * z -
                 3.33329491539e-1F) * z * t + t);
  const float first = swapped ? 0.5F * kPi - atan_t : atan_t;
  const float angle = cosine < 0.0F ? kPi - first : first;
  return (sine != sine || cosine != cosine) ? sine + cosine : angle;  // NaN propagates
}

// Angle (rad, 0..π) between segments a and b: std::atan2 in double (the offline static check),
// catheter_angle() in float (run time).
template <class Scalar>
Scalar segment_angle(const Eigen::Matrix<Scalar, 3, 1>& a, const Eigen::Matrix<Scalar, 3, 1>& b) noexcept {
  if constexpr (std::is_same_v<Scalar, float>) {
    return catheter_angle(a.cross(b).norm(), a.dot(b));
  } else {
    return std::atan2(a.cross(b).norm(), a.dot(b));
  }
}

// Gradient of E = ½ k θ² with respect to the segment vectors a and b. With â, b̂ unit:
//   ∂θ/∂a = −(b̂ − cosθ â) / (|a| sinθ),  ∂θ/∂b = −(â − cosθ b̂) / (|b| sinθ),
// so ∂E/∂a = −k (θ/sinθ)(b̂ − cosθ â)/|a|. θ/sinθ is smooth at θ = 0 (→ 1, series used below
// 1e-4 rad), so the straight chain is not a singular direction. Near θ = π (a segment folded
// back on its neighbour, unphysical) the factor is capped. Zero-length segments give zero.
// The same from the unit segments and their lengths (> 0), for callers that have them.
template <class Scalar>
void bending_gradient_of_units(const Eigen::Matrix<Scalar, 3, 1>& unit_a, Scalar length_a,
                               const Eigen::Matrix<Scalar, 3, 1>& unit_b, Scalar length_b,
                               Scalar stiffness, Eigen::Matrix<Scalar, 3, 1>& gradient_a,
                               Eigen::Matrix<Scalar, 3, 1>& gradient_b) noexcept {
  const Scalar sine = unit_a.cross(unit_b).norm();
  const Scalar cosine = unit_a.dot(unit_b);
  Scalar theta;
  if constexpr (std::is_same_v<Scalar, float>) {
    theta = catheter_angle(sine, cosine);
  } else {
    theta = std::atan2(sine, cosine);
  }
  Scalar theta_over_sine = Scalar(1) + theta * theta / Scalar(6);
  if (theta > Scalar(1e-4)) {
    constexpr Scalar kMaxFactor = Scalar(1e4);
    theta_over_sine = sine > theta / kMaxFactor ? theta / sine : kMaxFactor;
  }
  const Scalar scale = -stiffness * theta_over_sine;
  gradient_a = scale * (unit_b - cosine * unit_a) / length_a;
  gradient_b = scale * (unit_a - cosine * unit_b) / length_b;
}

template <class Scalar>
void bending_gradient(const Eigen::Matrix<Scalar, 3, 1>& a, const Eigen::Matrix<Scalar, 3, 1>& b,
                      Scalar stiffness, Eigen::Matrix<Scalar, 3, 1>& gradient_a,
                      Eigen::Matrix<Scalar, 3, 1>& gradient_b) noexcept {
  const Scalar length_a = a.norm();
  const Scalar length_b = b.norm();
  if (!(length_a > Scalar(0)) || !(length_b > Scalar(0))) {
    gradient_a.setZero();
    gradient_b.setZero();
    return;
  }
  bending_gradient_of_units<Scalar>(Eigen::Matrix<Scalar, 3, 1>(a / length_a), length_a,
                                    Eigen::Matrix<Scalar, 3, 1>(b / length_b), length_b, stiffness,
                                    gradient_a, gradient_b);
}

// Stiffness of the hinge at interior particle i. A held segment (both its particles held, as
// the forceps' jaws hold one) is a short clamp: at a held particle where the chain leaves the
// clamp (one neighbouring segment held, the other free) the hinge spans half a cell, like the
// clamped root's, and gets 2 k_b (docs/catheter.md). `held` is empty (nothing held) or has a
// flag per particle.
template <class Scalar>
Scalar hinge_stiffness(const ChainStiffness<Scalar>& stiffness, std::span<const std::uint8_t> held,
                       std::size_t i) noexcept {
  if (!held.empty() && held[i] != 0 && (held[i - 1] != 0) != (held[i + 1] != 0)) {
    return Scalar(2) * stiffness.bending_n_m_per_rad;
  }
  return stiffness.bending_n_m_per_rad;
}

// Adds the internal forces of the chain (eq. 27: axial k_s (l − l0), bending from ½ k_b θ²,
// minus the energy gradient) to `forces_n`. positions and forces have the same size; `held`
// (empty, or a flag per particle) gives the grasp hinges (hinge_stiffness).
template <class Scalar>
void add_chain_forces(std::span<const Eigen::Matrix<Scalar, 3, 1>> positions_m,
                      const ChainStiffness<Scalar>& stiffness,
                      std::span<Eigen::Matrix<Scalar, 3, 1>> forces_n,
                      std::span<const std::uint8_t> held = {}) noexcept {
  using Vector = Eigen::Matrix<Scalar, 3, 1>;
  const std::size_t count = positions_m.size();
  for (std::size_t i = 0; i + 1 < count; ++i) {
    const Vector segment = positions_m[i + 1] - positions_m[i];
    const Scalar length = segment.norm();
    if (!(length > Scalar(0))) continue;  // coincident particles: no defined direction
    const Vector force = stiffness.axial_n_per_m * (length - stiffness.rest_length_m) / length * segment;
    forces_n[i] += force;
    forces_n[i + 1] -= force;
  }
  Vector gradient_a;
  Vector gradient_b;
  for (std::size_t i = 1; i + 1 < count; ++i) {
    bending_gradient<Scalar>(positions_m[i] - positions_m[i - 1], positions_m[i + 1] - positions_m[i],
                             hinge_stiffness(stiffness, held, i), gradient_a, gradient_b);
    forces_n[i - 1] += gradient_a;
    forces_n[i] -= gradient_a - gradient_b;
    forces_n[i + 1] -= gradient_b;
  }
  if (stiffness.root_clamped && count >= 2) {
    bending_gradient<Scalar>(stiffness.root_tangent, positions_m[1] - positions_m[0],
                             Scalar(2) * stiffness.bending_n_m_per_rad, gradient_a, gradient_b);
    forces_n[0] += gradient_b;
    forces_n[1] -= gradient_b;
  }
}

// Elastic energy (J) of the chain: Σ ½ k_s (l − l0)² + Σ ½ k_b,i θ_i² (+ ½ (2 k_b) θ_root²),
// k_b,i from hinge_stiffness.
template <class Scalar>
Scalar chain_energy(std::span<const Eigen::Matrix<Scalar, 3, 1>> positions_m,
                    const ChainStiffness<Scalar>& stiffness,
                    std::span<const std::uint8_t> held = {}) noexcept {
  const std::size_t count = positions_m.size();
  Scalar energy = 0;
  for (std::size_t i = 0; i + 1 < count; ++i) {
    const Scalar stretch = (positions_m[i + 1] - positions_m[i]).norm() - stiffness.rest_length_m;
    energy += Scalar(0.5) * stiffness.axial_n_per_m * stretch * stretch;
  }
  for (std::size_t i = 1; i + 1 < count; ++i) {
    const Scalar theta =
        segment_angle<Scalar>(positions_m[i] - positions_m[i - 1], positions_m[i + 1] - positions_m[i]);
    energy += Scalar(0.5) * hinge_stiffness(stiffness, held, i) * theta * theta;
  }
  if (stiffness.root_clamped && count >= 2) {
    const Scalar theta = segment_angle<Scalar>(stiffness.root_tangent, positions_m[1] - positions_m[0]);
    energy += stiffness.bending_n_m_per_rad * theta * theta;  // ½ (2 k_b) θ²
  }
  return energy;
}

class Catheter {
 public:
  using Vec3 = Eigen::Vector3f;
  static constexpr std::uint32_t kMaxParticles = kMaxCatheterParticles;

  // Setup path: validates every parameter, computes the spring constants and the stable
  // substep (derive_catheter_chain), refuses a catheter whose haptic period needs more than
  // setup.max_substeps substeps (the error names the parameters and the required count), and
  // carves the state from `arena`. Rest shape: straight from start_position_m along direction
  // (place_catheter_rest).
  static core::Expected<Catheter> create(const CatheterParams& params, const CatheterSetup& setup,
                                         core::Arena& arena);
  // The same from a catheter image's data (catheter_model_data(), catheter_image.hpp): the
  // chain constants, stable substep, budget, rest positions and rest direction as modelc
  // stored them, nothing recomputed. The substep count of haptic_period_s (a scene setting, not
  // in the image) is computed here and refused beyond data.max_substeps, as above. A catheter
  // created from the image of a definition behaves bit for bit like one created from the same
  // definition's parameters. hold_start, gravity and contact settings are the caller's.
  static core::Expected<Catheter> create(const CatheterModelData& data, float haptic_period_s,
                                         std::uint32_t max_contact_planes, core::Arena& arena);

  // ---- RT path: noexcept, no heap ----

  // Adds force_n (N) on particle i until clear_forces(). Refuses an unknown particle
  // (invalid_argument) and a non-finite force (numeric_error); nothing applied then.
  core::Status add_force(std::uint32_t particle, const Vec3& force_n) noexcept;
  void clear_forces() noexcept;

  // Pins particle i at position_m (velocity zero) at every substep until release(i).
  core::Status hold(std::uint32_t particle, const Vec3& position_m) noexcept;
  core::Status release(std::uint32_t particle) noexcept;
  // Clamped start: particle 0 at its rest position, root hinge along the rest direction.
  void clamp_start(bool clamped) noexcept;
  // A held particle moves in a straight line from where it is at the start of step() to its
  // target, reaching it at the last substep, with the matching velocity (a jaw carrying the
  // catheter drags it smoothly instead of jumping it once per period). hold_forces_n()[i] is
  // the mean force the catheter put on the holder of particle i over the last step() (the
  // chain, external and damping forces the pin balanced): what the jaws feel. Zero if free.
  std::span<const Vec3> hold_forces_n() const noexcept { return {hold_forces_n_.data(), count_}; }

  // Replaces the contact planes used by the following step() calls (they persist until set
  // again; an empty span removes them). Refuses the whole set (nothing replaced, the old set
  // cleared) when a plane names an unknown particle, has a weight outside [0, 1], a
  // non-finite or non-unit normal (|n| off 1 by > 1e-3), a non-finite value, a negative
  // reach/damping, a non-positive max force, or a stiffness beyond
  // max_contact_stiffness_n_per_m() (invalid_argument / numeric_error); more planes than
  // max_contact_planes keeps the first ones and returns capacity_exceeded.
  core::Status set_contact_planes(std::span<const ContactPlane> planes) noexcept;
  std::size_t contact_plane_count() const noexcept { return plane_count_; }
  std::size_t max_contact_planes() const noexcept { return planes_.size(); }  // setup.max_contact_planes
  // Mean force (N) each plane put on the catheter over the last step(), in set order.
  std::span<const Vec3> contact_plane_forces_n() const noexcept {
    return {plane_forces_n_.data(), plane_count_};
  }
  // The stiffest contact accepted: 1e5 m / Δt_sub² (contacts are linearly implicit;
  // contact_stiffness_limit_n_per_m).
  float max_contact_stiffness_n_per_m() const noexcept;

  // Advances by period_s in ceil(period_s / stable_substep_s()) equal substeps (linearly
  // implicit; a plane whose end-of-substep force leaves [0, max_force_n] is made explicit at
  // the bound and the substep solved again, at most 4 solves, the last with every plane explicit).
  // Refuses (state unchanged) a non-positive/non-finite period or one needing more substeps
  // than the budget (invalid_argument). If any position or velocity becomes non-finite, or a
  // segment ends shorter than kMinSegmentRatio of its rest length (crushed: a compression of
  // 90 %, beyond the model — see below), the state returns to the one before this call and
  // numeric_error is returned; the caller's loads decide whether the next step goes on.
  core::Status step(float period_s) noexcept;

  // A segment compressed below this fraction of l0 ends step() with numeric_error. Measured
  // (tests/model/runtime/stability_catheter_test.cpp, docs/stability.md): a clamped polymer
  // catheter (EA 157 N) under a dead compressive tip load up to 0.5 EA folds over and settles;
  // at 1 and 2 EA the load crushes a segment and the step is refused (peak kinetic energy
  // within 1.5× the load's work). With the explicit axial springs the fold crushed segments from
  // ~0.2 EA and the chain pumped energy (kinetic energy to 2e3 J, segments stretched 23-fold,
  // never non-finite); refusing at 0.1 l0 stopped that. Reaching it statically takes a
  // compression of 0.9 EA.
  static constexpr float kMinSegmentRatio = 0.1F;

  void reset() noexcept;  // rest shape, zero velocity, forces and holds cleared, clamp off

  std::span<const Vec3> rest_positions_m() const noexcept {
    return {rest_positions_.data(), count_};
  }
  const Vec3& rest_direction() const noexcept { return direction_; }  // unit
  std::uint32_t max_substeps() const noexcept { return max_substeps_; }

  std::span<const Vec3> positions_m() const noexcept { return {positions_.data(), count_}; }
  std::span<const Vec3> velocities_m_per_s() const noexcept { return {velocities_.data(), count_}; }
  double kinetic_energy_j() const noexcept;
  double potential_energy_j() const noexcept;  // elastic (springs + bending), external work excluded
  float stable_substep_s() const noexcept { return stable_substep_s_; }
  std::uint32_t substeps_per_period() const noexcept { return substeps_per_period_; }
  std::uint32_t particle_count() const noexcept { return count_; }
  float particle_mass_kg() const noexcept { return mass_kg_; }
  float radius_m() const noexcept { return radius_m_; }
  const ChainStiffness<float>& stiffness() const noexcept { return stiffness_; }

  // ceil(period / substep) for a positive substep (exposed for tests and config checks).
  static std::uint64_t substeps_for(double period_s, double substep_s) noexcept {
    return catheter_substeps_for(period_s, substep_s);
  }

 private:
  Catheter() = default;
  // What both create()s share: counts the substeps of the period (refusing beyond the budget)
  // and carves every array from the arena. The rest positions are left for the caller to fill
  // before reset().
  static core::Expected<Catheter> allocate(const CatheterParams& params,
                                           const CatheterChain& chain, const Vec3& rest_direction,
                                           float haptic_period_s, std::uint32_t max_substeps,
                                           std::uint32_t max_contact_planes, core::Arena& arena);
  // false if the state became non-finite. `fraction` is this substep's share of the step
  // (averaging), `hold_step` how far through the step it ends (hold interpolation, 0..1].
  bool substep(float dt_s, float fraction, float hold_step) noexcept;
  // The same while the substep resolves bending and contacts explicitly (explicit_path_):
  // implicit axial springs and damping only, a block-tridiagonal solve (catheter_tridiagonal.cpp).
  bool substep_tridiagonal(float dt_s, float fraction, float hold_step) noexcept;
  void solve_tridiagonal(float dt_s, float period_fraction) noexcept;
  // After either solve: a held particle's pin force (hold_force(i), double) averaged into
  // hold_forces_n_ and the particle moved along its hold path; a free one takes v' (solution_)
  // and moves by h v'. false if a free particle became non-finite (catheter_advance.hpp).
  template <class HoldForce>
  bool advance(float dt_s, float fraction, float hold_step, HoldForce&& hold_force) noexcept;
  // The substep's explicit forces into forces_: external, axial at the current positions,
  // bending, contact planes; and the segments' unit vectors and lengths (segment_units_).
  // Marks the planes active and unclamped at the substep start for the implicit solve
  // (plane_gain_ = h k + c).
  void explicit_forces(float dt_s, float fraction) noexcept;
  // The linearly implicit velocity update (catheter_solve.cpp): assembles
  // (m + h b) I + h² (H_axial + K_bending) + h Σ (h k + c) W n nᵀ Wᵀ (block pentadiagonal,
  // 3×3 blocks, held particles eliminated) and solves it for the new velocities into solution_
  // (docs/catheter.md, "Integration and substep").
  void assemble(float dt_s, float period_fraction) noexcept;
  void factor_and_solve() noexcept;
  // After a solve, each implicit-capable plane takes the state its end-of-substep spring force
  // f_end = f + c n·ẋ − (h k̃ + c) n·ẋ' says: a spring above max_force_n goes to the clamp
  // (explicit max), below 0 off; a clamped one whose f_end is below the clamp becomes a
  // spring. True if any changed (the substep is solved again).
  bool update_planes() noexcept;
  // Back to the state at the start of step(), with no hold or contact forces reported.
  void restore_saved_state() noexcept;
  bool crushed() const noexcept;  // some segment shorter than kMinSegmentRatio · l0

  std::uint32_t count_ = 0;
  bool explicit_path_ = false;  // this step's substeps: h² (ω_b² + k_max/m) ≤ 1 (see step())
  double bending_omega_squared_ = 0.0;  // ω_b² = 20 k_b/(m l0²)
  float mass_kg_ = 0.0F;
  float damping_n_s_per_m_ = 0.0F;
  float radius_m_ = 0.0F;
  float stable_substep_s_ = 0.0F;
  std::uint32_t substeps_per_period_ = 0;
  std::uint32_t max_substeps_ = 0;
  ChainStiffness<float> stiffness_{};
  Vec3 direction_ = Vec3::UnitX();  // unit rest tangent (the clamped root's)

  std::span<Vec3> rest_positions_;   // the rest shape reset() returns to; [0] is the clamp point
  std::span<Vec3> positions_;
  std::span<Vec3> velocities_;
  std::span<Vec3> forces_;           // scratch per substep
  std::span<Vec3> external_n_;
  std::span<Vec3> hold_targets_m_;
  std::span<std::uint8_t> held_;     // 1 = pinned
  std::span<Vec3> saved_positions_;  // last good state (start of step())
  std::span<Vec3> saved_velocities_;
  std::span<Vec3> hold_forces_n_;    // mean over the last step, per particle
  // Scratch of the implicit solve (double: the axial blocks h² k_s reach 1e6 m at the stiffest
  // accepted EA, and float would lose the transverse directions to rounding). The matrix
  // (docs/catheter.md, "Integration and substep") is block pentadiagonal: diagonal blocks,
  // first off-diagonal blocks (symmetric 3×3: axial, bending, contact) and a scalar second
  // off-diagonal (bending only, times I). Factored by block LDLᵀ into D⁻¹ and L_{i,i−1}; the
  // second-band factor α D⁻¹ is recomputed where needed.
  std::span<Eigen::Matrix3d> diagonal_;       // N: A_ii (kept for the holders' forces)
  std::span<Eigen::Matrix3d> band1_;          // N − 1: A_{s,s+1} = A_{s+1,s}
  std::span<double> band2_;                   // N − 2: A_{s,s+2} = band2_[s] · I
  std::span<Eigen::Matrix3d> block_inverse_;  // N: D_i⁻¹
  std::span<Eigen::Matrix3d> lower_;          // N: L_{i,i−1}
  std::span<Eigen::Vector3d> solution_;       // N: right-hand side, then the new velocities
  // h² H_s of segment s = isotropic·I + along·û ûᵀ (the off-diagonal block is −that), for the
  // block-tridiagonal solve of the explicit-bending substep (catheter_tridiagonal.cpp).
  struct SegmentCoupling {
    Eigen::Vector3d unit = Eigen::Vector3d::Zero();
    double isotropic = 0.0;
    double along = 0.0;
    Eigen::Vector3d times(const Eigen::Vector3d& v) const noexcept {
      return isotropic * v + (along * unit.dot(v)) * unit;
    }
  };
  std::span<SegmentCoupling> coupling_;       // N − 1
  std::span<float> plane_gain_;               // per plane: h k̃ + c while implicit, else 0
  std::span<float> plane_force_;              // per plane: the force applied explicitly, or a
                                              // spring's start force (N)
  std::span<float> plane_spring_gain_;        // per plane: h k̃ + c if it may be implicit, else 0
  std::span<float> plane_start_;              // per plane: k depth − c ẋ_rel·n at the start (N)
  std::span<Vec3> contact_n_;                 // N: the planes' right-hand-side forces
  std::span<Vec3> segment_units_;             // N − 1: unit segment vectors of the substep
  std::span<float> segment_lengths_;          // N − 1
  std::span<ContactPlane> planes_;   // max_contact_planes
  std::span<Vec3> plane_forces_n_;   // mean over the last step, per plane
  std::size_t plane_count_ = 0;
};

}  // namespace trainer::model
