// What a particle catheter is made of: its physical parameters (CatheterParams), the chain
// constants derived from them in the precision the runtime keeps (CatheterChain), its straight
// rest placement, and what a catheter image holds (CatheterModelData, read by
// catheter_model_data() in catheter_image.hpp). derive_catheter_chain() and
// place_catheter_rest() are the one derivation that Catheter::create(params, setup) and
// modelc's image writer share, so a catheter created from its image rounds every constant
// exactly like one created from its parameters. Mapping and stable step: docs/catheter.md.
#pragma once

#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "trainer/core/expected.hpp"

namespace trainer::model {

// Physical description of the catheter (SI).
struct CatheterParams {
  float length_m = 0.0F;
  float outer_radius_m = 0.0F;           // sphere of influence per particle (contact)
  float bending_stiffness_n_m2 = 0.0F;   // EI
  float axial_stiffness_n = 0.0F;        // EA
  float linear_density_kg_per_m = 0.0F;  // ρ_l
  float damping_n_s_per_m = 0.0F;        // b per particle, ≥ 0
  std::uint32_t particle_count = 0;      // N, 3..kMaxCatheterParticles
  // The stiffest contact spring (N/m, ≥ 0) the substep must keep stable: a definition's
  // max(wall, tool) stiffness (modelc, catheter_model_data()); 0 = the chain alone. Contacts are
  // linearly implicit: it no longer enters the substep (catheter_stable_substep_s).
  float contact_stiffness_n_per_m = 0.0F;
};

// The share of the bending's spectral bound 20 k_b/(m l0²) taken for the explicit remainder
// (the nonlinear bending beyond its constant Jacobian) in catheter_stable_substep_s
// (docs/catheter.md, "Integration and substep").
inline constexpr double kCatheterRemainderShare = 0.25;
// The stiffest implicit contact, as h² k / m at the stored substep (docs/catheter.md).
inline constexpr float kCatheterContactStiffnessRatio = 1e5F;
// Most particles a chain may have (Catheter::kMaxParticles).
inline constexpr std::uint32_t kMaxCatheterParticles = 256;
// Largest substep budget an image may name (the definition's max_substeps range, docs/config.md).
inline constexpr std::uint32_t kMaxCatheterSubsteps = 10000;

// The chain's constants as the runtime stores them (float).
struct CatheterChain {
  std::uint32_t particle_count = 0;  // N
  float rest_length_m = 0.0F;        // l0 = L / (N − 1)
  float particle_mass_kg = 0.0F;     // m = ρ_l L / N
  float axial_n_per_m = 0.0F;        // k_s = EA / l0
  float bending_n_m_per_rad = 0.0F;  // k_b = EI / l0
  float radius_m = 0.0F;             // outer radius
  float damping_n_s_per_m = 0.0F;    // b per particle
  float stable_substep_s = 0.0F;     // catheter_stable_substep_s() of the double constants
};

// The largest substep of the catheter's integrator for these constants (docs/catheter.md,
// "Integration and substep"). The axial springs, the bending (its Hessian at the straight
// chain), the damping and the active contact planes are linearly implicit; what stays explicit
// is the bending's nonlinear remainder, bounded as a share of the bending's spectral bound:
// 2/ω_r with ω_r² = kCatheterRemainderShare · 20 k_b/(m l0²). The contact stiffness no longer
// enters (kept in the signature for the image's record checks). Positive finite arguments.
double catheter_stable_substep_s(double mass_kg, double bending_n_m_per_rad, double rest_length_m,
                                 double contact_stiffness_n_per_m) noexcept;

// Validates `params` (each refusal names the parameter: "catheter: particle_count = 2:
// expected 3..256") and derives the chain: the constants in double, each rounded once to float.
core::Expected<CatheterChain> derive_catheter_chain(const CatheterParams& params);

// ceil(period / substep) for a positive substep, at least 1; exact multiples do not round up.
// A count beyond 2^64 - 1 (or a NaN ratio) saturates at UINT64_MAX.
std::uint64_t catheter_substeps_for(double period_s, double substep_s) noexcept;

// The substeps one haptic period costs at the chain's stored (float) substep — the value
// Catheter::step() divides by, so the count here is the count at run time. Refuses a
// non-positive period, a zero budget, and a count beyond max_substeps (the message names EA,
// EI, the particle mass, the segment, the damping, the count and the budget, and the remedies).
core::Expected<std::uint32_t> catheter_substeps_per_period(const CatheterParams& params,
                                                           const CatheterChain& chain,
                                                           float haptic_period_s,
                                                           std::uint32_t max_substeps);

// The unit rest tangent: direction / |direction| in float. Refuses a zero or non-finite vector.
core::Expected<Eigen::Vector3f> catheter_rest_direction(const Eigen::Vector3f& direction);

// The straight rest shape: particle i at start_m + (i · l0) · unit_direction, in float, for
// every i < positions_m.size().
void place_catheter_rest(const Eigen::Vector3f& start_m, const Eigen::Vector3f& unit_direction,
                         float rest_length_m, std::span<Eigen::Vector3f> positions_m) noexcept;

// The stiffest contact accepted: kCatheterContactStiffnessRatio · m / Δt_sub². Contacts are
// linearly implicit (no stability limit of their own); the bound keeps h² k / m within 1e5
// (measured stable to 4.4e5: 1e7 N/m on the cbd chain at 1 ms, docs/catheter.md).
inline float contact_stiffness_limit_n_per_m(float particle_mass_kg, float substep_s) noexcept {
  return kCatheterContactStiffnessRatio * particle_mass_kg / (substep_s * substep_s);
}

// The contact stiffness a definition's substep keeps stable: its stiffer contact (wall or tool,
// CatheterParams::contact_stiffness_n_per_m). The grasp squeeze is not a spring on the chain
// (the jaws hold the grasped particles), so it does not enter.
inline float catheter_contact_stiffness(float wall_stiffness_n_per_m,
                                        float tool_stiffness_n_per_m) noexcept {
  return wall_stiffness_n_per_m > tool_stiffness_n_per_m ? wall_stiffness_n_per_m
                                                         : tool_stiffness_n_per_m;
}

// A catheter definition's [contact] as the trainer applies it (float; docs/config.md).
struct CatheterContactSettings {
  float wall_stiffness_n_per_m = 0.0F;  // particle sphere vs duct wall, ≤ the stiffness limit
  float wall_damping_n_s_per_m = 0.0F;
  float tool_stiffness_n_per_m = 0.0F;   // vs shaft and jaw capsules, ≤ the stiffness limit
  float grasp_stiffness_n_per_m = 0.0F;  // jaw squeeze per metre past touching
  float grasp_friction = 0.0F;           // slip beyond this × the squeeze
  float max_contact_force_n = 0.0F;      // per contact, and per jaw when grasping
};

// A catheter image's content: views into the loaded image (rest positions) and copies of its
// parameter record. Only the chain, the budget, the rest shape and direction build the
// Catheter; hold_start, gravity and contact are for the trainer that steps it.
struct CatheterModelData {
  CatheterParams params;  // what the chain was derived from (messages)
  CatheterChain chain;
  std::uint32_t max_substeps = 0;                             // budget of one haptic period
  std::span<const float> rest_positions_m;                    // N × 3, row-major, trainer frame
  Eigen::Vector3f rest_direction = Eigen::Vector3f::UnitX();  // unit; the clamped root's tangent
  bool hold_start = false;  // apply Catheter::clamp_start(true) after create
  Eigen::Vector3f gravity_m_per_s2 = Eigen::Vector3f::Zero();
  CatheterContactSettings contact;
};

}  // namespace trainer::model
