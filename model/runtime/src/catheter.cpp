// Particle catheter: parameter validation, stable substep, and the semi-implicit Euler loop
// (Basdogan eq. 27–28). The force law itself is the shared template in catheter.hpp.
#include "trainer/model/catheter.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

namespace trainer::model {
namespace {

bool positive_finite(float value) noexcept { return std::isfinite(value) && value > 0.0F; }

std::string number(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", value);
  return text;
}

}  // namespace

std::uint64_t Catheter::substeps_for(double period_s, double substep_s) noexcept {
  const double ratio = std::ceil(period_s / substep_s - 1e-9);  // exact multiples stay exact
  return ratio < 1.0 ? 1U : static_cast<std::uint64_t>(ratio);
}

core::Expected<Catheter> Catheter::create(const CatheterParams& params, const CatheterSetup& setup,
                                          core::Arena& arena) {
  const auto refuse = [](const std::string& what) {
    return core::make_error("catheter: " + what);
  };
  if (params.particle_count < 3 || params.particle_count > kMaxParticles) {
    return refuse("particle_count = " + std::to_string(params.particle_count) + ": expected 3.." +
                  std::to_string(kMaxParticles));
  }
  if (!positive_finite(params.length_m)) return refuse("length_m = " + number(params.length_m) + ": expected > 0");
  if (!positive_finite(params.outer_radius_m)) {
    return refuse("outer_radius_m = " + number(params.outer_radius_m) + ": expected > 0");
  }
  if (!positive_finite(params.bending_stiffness_n_m2)) {
    return refuse("bending_stiffness_n_m2 (EI) = " + number(params.bending_stiffness_n_m2) + ": expected > 0");
  }
  if (!positive_finite(params.axial_stiffness_n)) {
    return refuse("axial_stiffness_n (EA) = " + number(params.axial_stiffness_n) + ": expected > 0");
  }
  if (!positive_finite(params.linear_density_kg_per_m)) {
    return refuse("linear_density_kg_per_m = " + number(params.linear_density_kg_per_m) + ": expected > 0");
  }
  if (!std::isfinite(params.damping_n_s_per_m) || params.damping_n_s_per_m < 0.0F) {
    return refuse("damping_n_s_per_m = " + number(params.damping_n_s_per_m) + ": expected >= 0");
  }
  if (!positive_finite(setup.haptic_period_s)) {
    return refuse("haptic_period_s = " + number(setup.haptic_period_s) + ": expected > 0");
  }
  if (setup.max_substeps == 0) return refuse("max_substeps = 0: expected >= 1");
  if (!setup.start_position_m.allFinite()) return refuse("start_position_m is not finite");
  const float direction_norm = setup.direction.norm();
  if (!positive_finite(direction_norm)) return refuse("direction: expected a finite non-zero vector");

  Catheter catheter;
  catheter.count_ = params.particle_count;
  const double count = static_cast<double>(params.particle_count);
  const double rest_length_m = static_cast<double>(params.length_m) / (count - 1.0);
  const double mass_kg = static_cast<double>(params.linear_density_kg_per_m) *
                         static_cast<double>(params.length_m) / count;
  const double axial_n_per_m = static_cast<double>(params.axial_stiffness_n) / rest_length_m;
  const double bending_n_m = static_cast<double>(params.bending_stiffness_n_m2) / rest_length_m;
  const double omega_max_squared =
      4.0 * axial_n_per_m / mass_kg + 20.0 * bending_n_m / (mass_kg * rest_length_m * rest_length_m);
  double substep_s = 0.5 * 2.0 / std::sqrt(omega_max_squared);
  if (params.damping_n_s_per_m > 0.0F) {
    substep_s = std::min(substep_s, mass_kg / static_cast<double>(params.damping_n_s_per_m));
  }
  // step() divides the period by the stored float substep, so count with that same value: the
  // double one can round to a float a few ulp smaller, and a period within rounding of a
  // multiple of it would then need one substep more at run time than counted here (a catheter
  // accepted at exactly max_substeps would refuse every step).
  const float stored_substep_s = static_cast<float>(substep_s);
  const std::uint64_t needed = substeps_for(static_cast<double>(setup.haptic_period_s),
                                            static_cast<double>(stored_substep_s));
  if (needed > setup.max_substeps) {
    return refuse("a haptic period of " + number(setup.haptic_period_s) + " s needs " +
                  std::to_string(needed) + " substeps of at most " + number(substep_s) +
                  " s (stable step from EA = " + number(params.axial_stiffness_n) +
                  " N, EI = " + number(params.bending_stiffness_n_m2) + " N·m², particle mass " +
                  number(mass_kg) + " kg, segment " + number(rest_length_m) + " m, damping " +
                  number(params.damping_n_s_per_m) + " N·s/m) but max_substeps = " +
                  std::to_string(setup.max_substeps) +
                  ": raise max_substeps, use fewer particles, a softer EA, or a shorter period");
  }
  catheter.mass_kg_ = static_cast<float>(mass_kg);
  catheter.damping_n_s_per_m_ = params.damping_n_s_per_m;
  catheter.radius_m_ = params.outer_radius_m;
  catheter.stable_substep_s_ = stored_substep_s;
  catheter.substeps_per_period_ = static_cast<std::uint32_t>(needed);
  catheter.max_substeps_ = setup.max_substeps;
  catheter.stiffness_.axial_n_per_m = static_cast<float>(axial_n_per_m);
  catheter.stiffness_.bending_n_m_per_rad = static_cast<float>(bending_n_m);
  catheter.stiffness_.rest_length_m = static_cast<float>(rest_length_m);
  catheter.start_m_ = setup.start_position_m;
  catheter.direction_ = setup.direction / direction_norm;
  catheter.stiffness_.root_tangent = catheter.direction_;

  const std::size_t n = params.particle_count;
  auto take = [&](std::span<Vec3>& out, const char* what) -> core::Expected<void> {
    auto span = arena.allocate_array<Vec3>(n, what);
    if (!span) return std::move(span).error();
    out = span.value();
    return {};
  };
  for (auto [out, what] : {std::pair{&catheter.positions_, "catheter positions"},
                           std::pair{&catheter.velocities_, "catheter velocities"},
                           std::pair{&catheter.forces_, "catheter forces"},
                           std::pair{&catheter.external_n_, "catheter external forces"},
                           std::pair{&catheter.hold_targets_m_, "catheter hold targets"},
                           std::pair{&catheter.saved_positions_, "catheter saved positions"},
                           std::pair{&catheter.saved_velocities_, "catheter saved velocities"},
                           std::pair{&catheter.hold_forces_n_, "catheter hold forces"}}) {
    auto taken = take(*out, what);
    if (!taken) return std::move(taken).error();
  }
  auto held = arena.allocate_array<std::uint8_t>(n, "catheter held flags");
  if (!held) return std::move(held).error();
  catheter.held_ = held.value();
  if (setup.max_contact_planes > 0) {
    auto planes = arena.allocate_array<ContactPlane>(setup.max_contact_planes, "catheter contact planes");
    if (!planes) return std::move(planes).error();
    catheter.planes_ = planes.value();
    auto plane_forces = arena.allocate_array<Vec3>(setup.max_contact_planes, "catheter contact plane forces");
    if (!plane_forces) return std::move(plane_forces).error();
    catheter.plane_forces_n_ = plane_forces.value();
  }
  catheter.reset();
  return catheter;
}

core::Status Catheter::add_force(std::uint32_t particle, const Vec3& force_n) noexcept {
  if (particle >= count_) return {core::StatusCode::invalid_argument, "catheter: unknown particle"};
  if (!force_n.allFinite()) return {core::StatusCode::numeric_error, "catheter: non-finite force"};
  external_n_[particle] += force_n;
  return core::Status::ok();
}

void Catheter::clear_forces() noexcept {
  for (Vec3& force : external_n_) force.setZero();
}

core::Status Catheter::hold(std::uint32_t particle, const Vec3& position_m) noexcept {
  if (particle >= count_) return {core::StatusCode::invalid_argument, "catheter: unknown particle"};
  if (!position_m.allFinite()) return {core::StatusCode::numeric_error, "catheter: non-finite hold target"};
  held_[particle] = 1;
  hold_targets_m_[particle] = position_m;
  return core::Status::ok();
}

core::Status Catheter::release(std::uint32_t particle) noexcept {
  if (particle >= count_) return {core::StatusCode::invalid_argument, "catheter: unknown particle"};
  held_[particle] = 0;
  return core::Status::ok();
}

float Catheter::max_contact_stiffness_n_per_m() const noexcept {
  const float substep_s = stable_substep_s_;
  return mass_kg_ / (substep_s * substep_s);
}

core::Status Catheter::set_contact_planes(std::span<const ContactPlane> planes) noexcept {
  plane_count_ = 0;
  const float stiffness_limit = max_contact_stiffness_n_per_m();
  for (const ContactPlane& plane : planes) {
    if (plane.particle_a >= count_ || plane.particle_b >= count_ || !(plane.weight_b >= 0.0F) ||
        !(plane.weight_b <= 1.0F)) {
      return {core::StatusCode::invalid_argument, "catheter: contact plane names an unknown particle or weight"};
    }
    if (!plane.point_m.allFinite() || !plane.normal.allFinite() ||
        !plane.surface_velocity_m_per_s.allFinite() || !std::isfinite(plane.reach_m) ||
        !std::isfinite(plane.stiffness_n_per_m) || !std::isfinite(plane.damping_n_s_per_m) ||
        !std::isfinite(plane.max_force_n)) {
      return {core::StatusCode::numeric_error, "catheter: non-finite contact plane"};
    }
    if (std::fabs(plane.normal.norm() - 1.0F) > 1e-3F || plane.reach_m < 0.0F ||
        !(plane.stiffness_n_per_m > 0.0F) || plane.stiffness_n_per_m > stiffness_limit ||
        plane.damping_n_s_per_m < 0.0F || !(plane.max_force_n > 0.0F)) {
      return {core::StatusCode::invalid_argument,
              "catheter: contact plane normal not unit, negative reach/damping, or stiffness out of (0, limit]"};
    }
  }
  const std::size_t kept = std::min(planes.size(), planes_.size());
  std::copy_n(planes.begin(), kept, planes_.begin());
  plane_count_ = kept;
  for (std::size_t k = 0; k < kept; ++k) plane_forces_n_[k].setZero();
  if (kept < planes.size()) {
    return {core::StatusCode::capacity_exceeded, "catheter: more contact planes than max_contact_planes"};
  }
  return core::Status::ok();
}

void Catheter::clamp_start(bool clamped) noexcept {
  stiffness_.root_clamped = clamped;
  held_[0] = clamped ? 1 : 0;
  hold_targets_m_[0] = start_m_;
}

void Catheter::reset() noexcept {
  for (std::uint32_t i = 0; i < count_; ++i) {
    positions_[i] = start_m_ + (static_cast<float>(i) * stiffness_.rest_length_m) * direction_;
    velocities_[i].setZero();
    external_n_[i].setZero();
    hold_targets_m_[i].setZero();
    held_[i] = 0;
    hold_forces_n_[i].setZero();
  }
  stiffness_.root_clamped = false;
  plane_count_ = 0;
}

bool Catheter::substep(float dt_s, float fraction, float hold_step) noexcept {
  const std::span<Vec3> forces = forces_.first(count_);
  for (std::uint32_t i = 0; i < count_; ++i) forces[i] = external_n_[i] - damping_n_s_per_m_ * velocities_[i];
  add_chain_forces<float>(std::span<const Vec3>(positions_.data(), count_), stiffness_, forces,
                          std::span<const std::uint8_t>(held_.data(), count_));
  for (std::size_t k = 0; k < plane_count_; ++k) {
    const ContactPlane& plane = planes_[k];
    const float w = plane.weight_b;
    const Vec3 point = (1.0F - w) * positions_[plane.particle_a] + w * positions_[plane.particle_b];
    const float depth = plane.reach_m - (point - plane.point_m).dot(plane.normal);
    if (!(depth > 0.0F)) continue;
    const Vec3 velocity = (1.0F - w) * velocities_[plane.particle_a] + w * velocities_[plane.particle_b];
    float magnitude = plane.stiffness_n_per_m * depth -
                      plane.damping_n_s_per_m * (velocity - plane.surface_velocity_m_per_s).dot(plane.normal);
    magnitude = std::clamp(magnitude, 0.0F, plane.max_force_n);
    const Vec3 force = magnitude * plane.normal;
    forces[plane.particle_a] += (1.0F - w) * force;
    if (w != 0.0F) forces[plane.particle_b] += w * force;
    plane_forces_n_[k] += fraction * force;
  }
  const float dt_over_mass = dt_s / mass_kg_;
  bool finite = true;
  for (std::uint32_t i = 0; i < count_; ++i) {
    if (held_[i] != 0) {
      // The pin balances every force on the particle: the holder feels them.
      hold_forces_n_[i] += fraction * forces[i];
      const Vec3 start = saved_positions_[i];
      positions_[i] = hold_step >= 1.0F ? hold_targets_m_[i] : Vec3(start + hold_step * (hold_targets_m_[i] - start));
      velocities_[i] = (hold_targets_m_[i] - start) / (dt_s / fraction);
      continue;
    }
    velocities_[i] += dt_over_mass * forces[i];  // eq. 28: v_{t+Δt} = v_t + Δt a_t
    positions_[i] += dt_s * velocities_[i];      //          p_{t+Δt} = p_t + Δt v_{t+Δt}
    finite = finite && positions_[i].allFinite() && velocities_[i].allFinite();
  }
  return finite;
}

core::Status Catheter::step(float period_s) noexcept {
  if (!positive_finite(period_s)) return {core::StatusCode::invalid_argument, "catheter: period must be > 0"};
  const std::uint64_t substeps =
      substeps_for(static_cast<double>(period_s), static_cast<double>(stable_substep_s_));
  if (substeps > max_substeps_) {
    return {core::StatusCode::invalid_argument, "catheter: period needs more substeps than max_substeps"};
  }
  std::copy_n(positions_.begin(), count_, saved_positions_.begin());
  std::copy_n(velocities_.begin(), count_, saved_velocities_.begin());
  for (std::uint32_t i = 0; i < count_; ++i) hold_forces_n_[i].setZero();
  for (std::size_t k = 0; k < plane_count_; ++k) plane_forces_n_[k].setZero();
  const float dt_s = period_s / static_cast<float>(substeps);
  const float fraction = 1.0F / static_cast<float>(substeps);
  bool finite = true;
  for (std::uint64_t k = 0; k < substeps && finite; ++k) {
    finite = substep(dt_s, fraction, static_cast<float>(k + 1) * fraction);
  }
  if (!finite) {
    restore_saved_state();
    return {core::StatusCode::numeric_error, "catheter: state became non-finite; restored the last good state"};
  }
  if (crushed()) {
    restore_saved_state();
    return {core::StatusCode::numeric_error,
            "catheter: a segment was crushed below 10 % of its rest length; restored the last good state"};
  }
  return core::Status::ok();
}

void Catheter::restore_saved_state() noexcept {
  std::copy_n(saved_positions_.begin(), count_, positions_.begin());
  std::copy_n(saved_velocities_.begin(), count_, velocities_.begin());
  for (std::uint32_t i = 0; i < count_; ++i) hold_forces_n_[i].setZero();
  for (std::size_t k = 0; k < plane_count_; ++k) plane_forces_n_[k].setZero();
}

bool Catheter::crushed() const noexcept {
  const float shortest = kMinSegmentRatio * stiffness_.rest_length_m;
  for (std::uint32_t i = 0; i + 1 < count_; ++i) {
    if ((positions_[i + 1] - positions_[i]).squaredNorm() < shortest * shortest) return true;
  }
  return false;
}

double Catheter::kinetic_energy_j() const noexcept {
  double energy = 0.0;
  for (std::uint32_t i = 0; i < count_; ++i) {
    energy += 0.5 * static_cast<double>(mass_kg_) * static_cast<double>(velocities_[i].squaredNorm());
  }
  return energy;
}

double Catheter::potential_energy_j() const noexcept {
  // Evaluated in double from the float state so energy-monotonicity tests see the dynamics,
  // not the rounding of a float sum.
  ChainStiffness<double> stiffness;
  stiffness.axial_n_per_m = static_cast<double>(stiffness_.axial_n_per_m);
  stiffness.bending_n_m_per_rad = static_cast<double>(stiffness_.bending_n_m_per_rad);
  stiffness.rest_length_m = static_cast<double>(stiffness_.rest_length_m);
  stiffness.root_clamped = stiffness_.root_clamped;
  stiffness.root_tangent = stiffness_.root_tangent.cast<double>();
  double energy = 0.0;
  for (std::uint32_t i = 0; i + 1 < count_; ++i) {
    const double stretch = (positions_[i + 1] - positions_[i]).cast<double>().norm() - stiffness.rest_length_m;
    energy += 0.5 * stiffness.axial_n_per_m * stretch * stretch;
  }
  for (std::uint32_t i = 1; i + 1 < count_; ++i) {
    const double theta = segment_angle<double>((positions_[i] - positions_[i - 1]).cast<double>(),
                                               (positions_[i + 1] - positions_[i]).cast<double>());
    energy += 0.5 * hinge_stiffness<double>(stiffness, std::span<const std::uint8_t>(held_.data(), count_), i) *
              theta * theta;
  }
  if (stiffness.root_clamped) {
    const double theta = segment_angle<double>(stiffness.root_tangent, (positions_[1] - positions_[0]).cast<double>());
    energy += stiffness.bending_n_m_per_rad * theta * theta;
  }
  return energy;
}

}  // namespace trainer::model
