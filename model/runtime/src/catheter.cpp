// Particle catheter: creation from parameters or from an image's data (the derivation itself is
// catheter_chain.cpp), and the substep loop: linearly implicit axial springs and damping (a
// block-tridiagonal solve), explicit bending and contacts (Basdogan eq. 27–28). The force law
// is the shared template in catheter.hpp.
#include "trainer/model/catheter.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <tuple>
#include <utility>

#include "catheter_refusal.hpp"

namespace trainer::model {

using detail::catheter_positive_finite;
using detail::catheter_refusal;

core::Expected<Catheter> Catheter::create(const CatheterParams& params, const CatheterSetup& setup,
                                          core::Arena& arena) {
  auto chain = derive_catheter_chain(params);
  if (!chain) return std::move(chain).error();
  if (!setup.start_position_m.allFinite())
    return catheter_refusal("start_position_m is not finite");
  auto direction = catheter_rest_direction(setup.direction);
  if (!direction) return std::move(direction).error();
  auto catheter = allocate(params, chain.value(), direction.value(), setup.haptic_period_s,
                           setup.max_substeps, setup.max_contact_planes, arena);
  if (!catheter) return catheter;
  place_catheter_rest(setup.start_position_m, direction.value(), chain->rest_length_m,
                      catheter->rest_positions_);
  catheter->reset();
  return catheter;
}

core::Expected<Catheter> Catheter::create(const CatheterModelData& data, float haptic_period_s,
                                          std::uint32_t max_contact_planes, core::Arena& arena) {
  // The loader has checked every field of an image; these guard what create() relies on when
  // the data comes from elsewhere.
  const CatheterChain& chain = data.chain;
  if (chain.particle_count < 3 || chain.particle_count > kMaxParticles ||
      data.rest_positions_m.size() != 3 * std::size_t{chain.particle_count}) {
    return catheter_refusal("image data has " + std::to_string(chain.particle_count) +
                            " particles and " + std::to_string(data.rest_positions_m.size()) +
                            " rest coordinates: expected 3.." + std::to_string(kMaxParticles) +
                            " particles, 3 coordinates each");
  }
  if (!catheter_positive_finite(chain.particle_mass_kg) ||
      !catheter_positive_finite(chain.rest_length_m) ||
      !catheter_positive_finite(chain.stable_substep_s) || !std::isfinite(chain.axial_n_per_m) ||
      !std::isfinite(chain.bending_n_m_per_rad) || !(chain.damping_n_s_per_m >= 0.0F)) {
    return catheter_refusal(
        "image data: particle mass, segment and stable substep must be > 0, the spring "
        "constants finite and the damping >= 0");
  }
  auto catheter = allocate(data.params, chain, data.rest_direction, haptic_period_s,
                           data.max_substeps, max_contact_planes, arena);
  if (!catheter) return catheter;
  for (std::size_t i = 0; i < chain.particle_count; ++i) {
    catheter->rest_positions_[i] =
        Vec3(data.rest_positions_m[3 * i], data.rest_positions_m[3 * i + 1],
             data.rest_positions_m[3 * i + 2]);
  }
  catheter->reset();
  return catheter;
}

core::Expected<Catheter> Catheter::allocate(const CatheterParams& params,
                                            const CatheterChain& chain, const Vec3& rest_direction,
                                            float haptic_period_s, std::uint32_t max_substeps,
                                            std::uint32_t max_contact_planes, core::Arena& arena) {
  auto substeps = catheter_substeps_per_period(params, chain, haptic_period_s, max_substeps);
  if (!substeps) return std::move(substeps).error();
  Catheter catheter;
  catheter.count_ = chain.particle_count;
  catheter.mass_kg_ = chain.particle_mass_kg;
  catheter.damping_n_s_per_m_ = chain.damping_n_s_per_m;
  catheter.radius_m_ = chain.radius_m;
  catheter.stable_substep_s_ = chain.stable_substep_s;
  catheter.substeps_per_period_ = substeps.value();
  catheter.max_substeps_ = max_substeps;
  catheter.stiffness_.axial_n_per_m = chain.axial_n_per_m;
  catheter.stiffness_.bending_n_m_per_rad = chain.bending_n_m_per_rad;
  catheter.bending_omega_squared_ =
      20.0 * static_cast<double>(chain.bending_n_m_per_rad) /
      (static_cast<double>(chain.particle_mass_kg) * static_cast<double>(chain.rest_length_m) *
       static_cast<double>(chain.rest_length_m));
  catheter.stiffness_.rest_length_m = chain.rest_length_m;
  catheter.direction_ = rest_direction;
  catheter.stiffness_.root_tangent = rest_direction;

  const std::size_t n = chain.particle_count;
  auto take = [&](std::span<Vec3>& out, const char* what) -> core::Expected<void> {
    auto span = arena.allocate_array<Vec3>(n, what);
    if (!span) return std::move(span).error();
    out = span.value();
    return {};
  };
  for (auto [out, what] : {std::pair{&catheter.rest_positions_, "catheter rest positions"},
                           std::pair{&catheter.positions_, "catheter positions"},
                           std::pair{&catheter.velocities_, "catheter velocities"},
                           std::pair{&catheter.forces_, "catheter forces"},
                           std::pair{&catheter.external_n_, "catheter external forces"},
                           std::pair{&catheter.hold_targets_m_, "catheter hold targets"},
                           std::pair{&catheter.saved_positions_, "catheter saved positions"},
                           std::pair{&catheter.saved_velocities_, "catheter saved velocities"},
                           std::pair{&catheter.hold_forces_n_, "catheter hold forces"},
                           std::pair{&catheter.contact_n_, "catheter contact forces"}}) {
    auto taken = take(*out, what);
    if (!taken) return std::move(taken).error();
  }
  for (auto [out, count, what] :
       {std::tuple{&catheter.diagonal_, n, "catheter solve diagonal"},
        std::tuple{&catheter.band1_, n - 1, "catheter solve band"},
        std::tuple{&catheter.block_inverse_, n, "catheter solve blocks"},
        std::tuple{&catheter.lower_, n, "catheter solve factors"}}) {
    auto span = arena.allocate_array<Eigen::Matrix3d>(count, what);
    if (!span) return std::move(span).error();
    *out = span.value();
  }
  auto coupling = arena.allocate_array<SegmentCoupling>(n - 1, "catheter solve couplings");
  if (!coupling) return std::move(coupling).error();
  catheter.coupling_ = coupling.value();
  auto band2 = arena.allocate_array<double>(n - 2, "catheter solve second band");
  if (!band2) return std::move(band2).error();
  catheter.band2_ = band2.value();
  auto solution = arena.allocate_array<Eigen::Vector3d>(n, "catheter solve vector");
  if (!solution) return std::move(solution).error();
  catheter.solution_ = solution.value();
  auto units = arena.allocate_array<Vec3>(n - 1, "catheter segment units");
  if (!units) return std::move(units).error();
  catheter.segment_units_ = units.value();
  auto lengths = arena.allocate_array<float>(n - 1, "catheter segment lengths");
  if (!lengths) return std::move(lengths).error();
  catheter.segment_lengths_ = lengths.value();
  auto held = arena.allocate_array<std::uint8_t>(n, "catheter held flags");
  if (!held) return std::move(held).error();
  catheter.held_ = held.value();
  if (max_contact_planes > 0) {
    auto planes = arena.allocate_array<ContactPlane>(max_contact_planes, "catheter contact planes");
    if (!planes) return std::move(planes).error();
    catheter.planes_ = planes.value();
    auto plane_forces =
        arena.allocate_array<Vec3>(max_contact_planes, "catheter contact plane forces");
    if (!plane_forces) return std::move(plane_forces).error();
    catheter.plane_forces_n_ = plane_forces.value();
    auto gains = arena.allocate_array<float>(max_contact_planes, "catheter contact plane gains");
    if (!gains) return std::move(gains).error();
    catheter.plane_gain_ = gains.value();
    auto plane_force = arena.allocate_array<float>(max_contact_planes, "catheter contact plane force");
    if (!plane_force) return std::move(plane_force).error();
    catheter.plane_force_ = plane_force.value();
    for (auto [out, what] : {std::pair{&catheter.plane_spring_gain_, "catheter contact plane spring gains"},
                             std::pair{&catheter.plane_start_, "catheter contact plane start forces"}}) {
      auto span = arena.allocate_array<float>(max_contact_planes, what);
      if (!span) return std::move(span).error();
      *out = span.value();
    }
  }
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
  return contact_stiffness_limit_n_per_m(mass_kg_, stable_substep_s_);
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
  hold_targets_m_[0] = rest_positions_[0];
}

void Catheter::reset() noexcept {
  for (std::uint32_t i = 0; i < count_; ++i) {
    positions_[i] = rest_positions_[i];
    velocities_[i].setZero();
    external_n_[i].setZero();
    hold_targets_m_[i].setZero();
    held_[i] = 0;
    hold_forces_n_[i].setZero();
  }
  stiffness_.root_clamped = false;
  plane_count_ = 0;
}

void Catheter::explicit_forces(float dt_s, float fraction) noexcept {
  const std::span<Vec3> forces = forces_.first(count_);
  for (std::uint32_t i = 0; i < count_; ++i) forces[i] = external_n_[i];
  // Segments once: the axial forces at the current positions and the units bending needs.
  const float k_s = stiffness_.axial_n_per_m;
  const float l0 = stiffness_.rest_length_m;
  for (std::uint32_t s = 0; s + 1 < count_; ++s) {
    const Vec3 segment = positions_[s + 1] - positions_[s];
    const float length = segment.norm();
    segment_lengths_[s] = length;
    if (!(length > 0.0F)) {  // coincident particles: no defined direction, no force
      segment_units_[s].setZero();
      continue;
    }
    const Vec3 unit = segment / length;
    segment_units_[s] = unit;
    const Vec3 force = (k_s * (length - l0)) * unit;
    forces[s] += force;
    forces[s + 1] -= force;
  }
  Vec3 gradient_a;
  Vec3 gradient_b;
  const std::span<const std::uint8_t> held(held_.data(), count_);
  for (std::uint32_t i = 1; i + 1 < count_; ++i) {
    if (!(segment_lengths_[i - 1] > 0.0F) || !(segment_lengths_[i] > 0.0F)) continue;
    bending_gradient_of_units<float>(segment_units_[i - 1], segment_lengths_[i - 1], segment_units_[i],
                                     segment_lengths_[i], hinge_stiffness(stiffness_, held, i),
                                     gradient_a, gradient_b);
    forces[i - 1] += gradient_a;
    forces[i] -= gradient_a - gradient_b;
    forces[i + 1] -= gradient_b;
  }
  if (stiffness_.root_clamped && segment_lengths_[0] > 0.0F) {
    bending_gradient_of_units<float>(stiffness_.root_tangent, 1.0F, segment_units_[0], segment_lengths_[0],
                                     2.0F * stiffness_.bending_n_m_per_rad, gradient_a, gradient_b);
    forces[0] += gradient_b;
    forces[1] -= gradient_b;
  }
  // Contact planes: their force at the substep start, f = clamp(k depth − c (ẋ − v_s)·n, 0,
  // max), applied in the solve (assemble()). Active and unclamped at the start, a plane is
  // linearly implicit (its stiffness and damper in the matrix, gain h k + c); clamped
  // (pulling, or at max_force_n) it stays a constant explicit force. Planes between particles
  // that are not neighbours do not fit the band: explicit.
  if (explicit_path_) {  // the explicit-bending substep: planes explicit, as they always were
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
    return;
  }
  const float explicit_contact_stiffness = mass_kg_ / (dt_s * dt_s);
  for (std::size_t k = 0; k < plane_count_; ++k) {
    const ContactPlane& plane = planes_[k];
    const float w = plane.weight_b;
    const Vec3 point = (1.0F - w) * positions_[plane.particle_a] + w * positions_[plane.particle_b];
    const float depth = plane.reach_m - (point - plane.point_m).dot(plane.normal);
    plane_gain_[k] = 0.0F;
    plane_spring_gain_[k] = 0.0F;
    plane_force_[k] = 0.0F;
    if (!(depth > 0.0F)) continue;
    const Vec3 velocity = (1.0F - w) * velocities_[plane.particle_a] + w * velocities_[plane.particle_b];
    const float magnitude = plane.stiffness_n_per_m * depth -
                            plane.damping_n_s_per_m * (velocity - plane.surface_velocity_m_per_s).dot(plane.normal);
    plane_start_[k] = magnitude;
    const std::uint32_t apart = plane.particle_a > plane.particle_b ? plane.particle_a - plane.particle_b
                                                                    : plane.particle_b - plane.particle_a;
    // Only the stiffness beyond m/h² (what the explicit substep kept stable, ω h ≤ 1) goes
    // into the matrix, and with it the damper: a contact the substep resolves stays explicit
    // and keeps its restitution (implicit Euler would damp it by 1/(1 + ω²h²) per substep).
    const float implicit_stiffness = plane.stiffness_n_per_m - explicit_contact_stiffness;
    if (apart > 1 || !(implicit_stiffness > 0.0F)) {  // explicit for the whole substep
      plane_force_[k] = std::clamp(magnitude, 0.0F, plane.max_force_n);
      continue;
    }
    // Implicit-capable: off (pulling), at the clamp (explicit max_force_n), or a spring (in
    // the matrix), as at the substep start; the solve may move it (update_planes()).
    plane_spring_gain_[k] = dt_s * implicit_stiffness + plane.damping_n_s_per_m;
    if (!(magnitude > 0.0F)) continue;
    if (magnitude >= plane.max_force_n) {
      plane_force_[k] = plane.max_force_n;
    } else {
      plane_force_[k] = magnitude;
      plane_gain_[k] = plane_spring_gain_[k];
    }
  }
}

core::Status Catheter::step(float period_s) noexcept {
  if (!catheter_positive_finite(period_s)) {
    return {core::StatusCode::invalid_argument, "catheter: period must be > 0"};
  }
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
  // The explicit-bending substep while it resolves bending and every plane (ω h ≤ 1, the
  // integrator's stable step before the implicit bending): bit-identical to it there.
  double stiffest_plane = 0.0;
  for (std::size_t k = 0; k < plane_count_; ++k) {
    stiffest_plane = std::max(stiffest_plane, static_cast<double>(planes_[k].stiffness_n_per_m));
  }
  const double h = static_cast<double>(dt_s);
  explicit_path_ =
      h * h * (bending_omega_squared_ + stiffest_plane / static_cast<double>(mass_kg_)) <= 1.0;
  bool finite = true;
  for (std::uint64_t k = 0; k < substeps && finite; ++k) {
    const float hold_step = static_cast<float>(k + 1) * fraction;
    finite = explicit_path_ ? substep_tridiagonal(dt_s, fraction, hold_step)
                            : substep(dt_s, fraction, hold_step);
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
