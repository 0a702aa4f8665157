// The catheter's substep (docs/catheter.md, "Integration and substep"): linearly implicit in
// the axial springs, the bending, the damping and the contact planes active at the substep
// start, with every force itself evaluated explicitly at the substep's positions:
//   m (v' − v) = h [F̂(p, v) − b v' − J (p' − p) − Σ c_k W_k n nᵀ Wᵀ (v' − v)],  p' = p + h v'
//   ⇒ A v' = m v + h F̂,   A = (m + h b) I + h² J + h Σ_k (h k̃_k + c_k) W_k n_k n_kᵀ W_kᵀ,
// J = H_axial (per segment k_s [g I + (1 − g) û ûᵀ], g = max(0, 1 − l0/l)) + K_b (the
// bending's Hessian at the straight chain, Σ_hinges k_i/l0² d dᵀ ⊗ I3 with d the second
// difference [1 −2 1], the clamped root's 2 k_b as [−1 1]). F̂ is every force at p (the exact
// nonlinear bending and axial forces, contacts, external) plus the contact dampers' c (n·v)
// moved to the right-hand side, so equilibria are those of the forces alone. k̃ = k − m/h² of a
// plane active and unclamped at the substep start (the rest of it explicit); planes switch
// between off, clamp and spring within the substep (update_planes). Block pentadiagonal and
// symmetric positive definite: block LDLᵀ in double, O(N), no heap. Runs when the period's
// substep does not resolve bending and contacts explicitly (Catheter::step).
#include <algorithm>
#include <cmath>

#include "catheter_advance.hpp"
#include "trainer/model/catheter.hpp"

namespace trainer::model {

void Catheter::assemble(float dt_s, float period_fraction) noexcept {
  const double h = static_cast<double>(dt_s);
  const double h2k = h * h * static_cast<double>(stiffness_.axial_n_per_m);
  const double l0 = static_cast<double>(stiffness_.rest_length_m);
  const double mass_diagonal = static_cast<double>(mass_kg_) + h * static_cast<double>(damping_n_s_per_m_);
  const std::uint32_t n = count_;
  // Scalar parts first (the damped mass and the bending stencil), then the 3×3 ones.
  double scalar_diagonal[kMaxParticles];
  double scalar_band1[kMaxParticles];
  for (std::uint32_t i = 0; i < n; ++i) {
    scalar_diagonal[i] = mass_diagonal;
    scalar_band1[i] = 0.0;
    if (i + 2 < n) band2_[i] = 0.0;
  }
  const double h2_over_l02 = h * h / (l0 * l0);
  const std::span<const std::uint8_t> held(held_.data(), n);
  for (std::uint32_t i = 1; i + 1 < n; ++i) {
    const double c = h2_over_l02 * static_cast<double>(hinge_stiffness(stiffness_, held, i));
    scalar_diagonal[i - 1] += c;
    scalar_diagonal[i] += 4.0 * c;
    scalar_diagonal[i + 1] += c;
    scalar_band1[i - 1] -= 2.0 * c;
    scalar_band1[i] -= 2.0 * c;
    band2_[i - 1] += c;
  }
  if (stiffness_.root_clamped) {
    const double c = h2_over_l02 * 2.0 * static_cast<double>(stiffness_.bending_n_m_per_rad);
    scalar_diagonal[0] += c;
    scalar_diagonal[1] += c;
    scalar_band1[0] -= c;
  }
  for (std::uint32_t i = 0; i < n; ++i) diagonal_[i] = Eigen::Matrix3d::Identity() * scalar_diagonal[i];
  for (std::uint32_t s = 0; s + 1 < n; ++s) {
    Eigen::Matrix3d& band = band1_[s];
    band = Eigen::Matrix3d::Identity() * scalar_band1[s];
    // Axial: h² H_s = a I + b û ûᵀ on both diagonals, minus it off the diagonal.
    const double length = static_cast<double>(segment_lengths_[s]);
    if (!(length > 0.0)) continue;
    const double g = std::clamp(1.0 - l0 / length, 0.0, 1.0);
    const Eigen::Vector3d unit = segment_units_[s].cast<double>();
    Eigen::Matrix3d block = (h2k * (1.0 - g)) * (unit * unit.transpose());
    block.diagonal().array() += h2k * g;
    diagonal_[s] += block;
    diagonal_[s + 1] += block;
    band -= block;
  }
  // Contact planes: explicit ones their force, implicit ones h (h k + c) W n nᵀ Wᵀ in the
  // matrix and their start force plus the damper's c (n·ẋ) on the right-hand side.
  for (std::uint32_t i = 0; i < n; ++i) contact_n_[i].setZero();
  for (std::size_t k = 0; k < plane_count_; ++k) {
    const ContactPlane& plane = planes_[k];
    const float gain = plane_gain_[k];
    const float w = plane.weight_b;
    float magnitude = plane_force_[k];
    if (gain != 0.0F) {
      magnitude += plane.damping_n_s_per_m *
                   ((1.0F - w) * velocities_[plane.particle_a] + w * velocities_[plane.particle_b]).dot(plane.normal);
    }
    if (magnitude != 0.0F) {
      contact_n_[plane.particle_a] += ((1.0F - w) * magnitude) * plane.normal;
      if (w != 0.0F) contact_n_[plane.particle_b] += (w * magnitude) * plane.normal;
    }
    if (gain == 0.0F) continue;
    const Eigen::Vector3d normal = plane.normal.cast<double>();
    const Eigen::Matrix3d outer = (h * static_cast<double>(gain)) * (normal * normal.transpose());
    if (plane.particle_a == plane.particle_b) {
      diagonal_[plane.particle_a] += outer;
      continue;
    }
    const double wa = 1.0 - static_cast<double>(w);
    const double wb = static_cast<double>(w);
    diagonal_[plane.particle_a] += (wa * wa) * outer;
    diagonal_[plane.particle_b] += (wb * wb) * outer;
    band1_[std::min(plane.particle_a, plane.particle_b)] += (wa * wb) * outer;
  }
  // Right-hand side m v + h F̂; a held particle's row is its hold velocity.
  const double mass = static_cast<double>(mass_kg_);
  const float step_period = dt_s / period_fraction;
  for (std::uint32_t i = 0; i < n; ++i) {
    if (held_[i] != 0) {
      solution_[i] = ((hold_targets_m_[i] - saved_positions_[i]) / step_period).cast<double>();
    } else {
      solution_[i] = mass * velocities_[i].cast<double>() + h * (forces_[i] + contact_n_[i]).cast<double>();
    }
  }
}

void Catheter::factor_and_solve() noexcept {
  // Block LDLᵀ of the pentadiagonal matrix with held rows and columns replaced by the
  // identity (their couplings moved to the free neighbours' right-hand sides first):
  //   L_{i,i−2} = α_i D_{i−2}⁻¹ (α_i = A_{i,i−2} scalar),
  //   G_i = A_{i,i−1} − L_{i,i−2} G_{i−1}ᵀ,  L_{i,i−1} = G_i D_{i−1}⁻¹,
  //   D_i = A_ii − α_i² D_{i−2}⁻¹ − L_{i,i−1} G_iᵀ,
  //   y_i = r_i − L_{i,i−2} y_{i−2} − L_{i,i−1} y_{i−1};  x_i = D_i⁻¹ y_i − L_{i+1,i}ᵀ x_{i+1} − L_{i+2,i}ᵀ x_{i+2}.
  const std::uint32_t n = count_;
  for (std::uint32_t i = 0; i < n; ++i) {
    if (held_[i] == 0) continue;
    const Eigen::Vector3d v = solution_[i];
    if (i >= 1 && held_[i - 1] == 0) solution_[i - 1] -= band1_[i - 1] * v;
    if (i + 1 < n && held_[i + 1] == 0) solution_[i + 1] -= band1_[i] * v;
    if (i >= 2 && held_[i - 2] == 0) solution_[i - 2] -= band2_[i - 2] * v;
    if (i + 2 < n && held_[i + 2] == 0) solution_[i + 2] -= band2_[i] * v;
  }
  Eigen::Matrix3d previous_g = Eigen::Matrix3d::Zero();  // G_{i−1}
  for (std::uint32_t i = 0; i < n; ++i) {
    if (held_[i] != 0) {
      block_inverse_[i].setIdentity();
      lower_[i].setZero();
      previous_g.setZero();
      continue;
    }
    Eigen::Matrix3d d = diagonal_[i];
    Eigen::Vector3d y = solution_[i];
    Eigen::Matrix3d g = Eigen::Matrix3d::Zero();
    bool has_second = false;
    double alpha = 0.0;
    if (i >= 2 && held_[i - 2] == 0 && band2_[i - 2] != 0.0) {
      has_second = true;
      alpha = band2_[i - 2];
      const Eigen::Matrix3d& inverse2 = block_inverse_[i - 2];
      d.noalias() -= (alpha * alpha) * inverse2;
      y.noalias() -= alpha * (inverse2 * solution_[i - 2]);
    }
    if (i >= 1 && held_[i - 1] == 0) {
      g = band1_[i - 1];
      if (has_second) g.noalias() -= alpha * (block_inverse_[i - 2] * previous_g.transpose());
      const Eigen::Matrix3d l = g * block_inverse_[i - 1];
      d.noalias() -= l * g.transpose();
      y.noalias() -= l * solution_[i - 1];
      lower_[i] = l;
    } else {
      lower_[i].setZero();
    }
    previous_g = g;
    block_inverse_[i] = d.inverse();
    solution_[i] = y;
  }
  for (std::uint32_t k = n; k-- > 0;) {
    if (held_[k] != 0) continue;
    Eigen::Vector3d x = block_inverse_[k] * solution_[k];
    if (k + 1 < n && held_[k + 1] == 0) x.noalias() -= lower_[k + 1].transpose() * solution_[k + 1];
    if (k + 2 < n && held_[k + 2] == 0 && band2_[k] != 0.0) {
      x.noalias() -= band2_[k] * (block_inverse_[k] * solution_[k + 2]);  // L_{k+2,k}ᵀ, D⁻¹ symmetric
    }
    solution_[k] = x;
  }
}

namespace {

// The force of an implicit plane at the substep end: f + c n·ẋ − (h k + c) n·ẋ'.
float implicit_plane_force(const ContactPlane& plane, float start_force, float gain,
                           const Eigen::Vector3f& old_velocity, const Eigen::Vector3d& new_velocity) noexcept {
  return start_force + plane.damping_n_s_per_m * old_velocity.dot(plane.normal) -
         gain * static_cast<float>(new_velocity.dot(plane.normal.cast<double>()));
}

}  // namespace

bool Catheter::update_planes() noexcept {
  bool changed = false;
  for (std::size_t k = 0; k < plane_count_; ++k) {
    const float spring_gain = plane_spring_gain_[k];
    if (spring_gain == 0.0F) continue;  // explicit for the whole substep
    const ContactPlane& plane = planes_[k];
    const bool spring = plane_gain_[k] != 0.0F;
    const bool clamped = !spring && plane_force_[k] == plane.max_force_n;
    if (!spring && !clamped) continue;  // off stays off within the substep
    const double w = static_cast<double>(plane.weight_b);
    const float f = implicit_plane_force(
        plane, plane_start_[k], spring_gain,
        (1.0F - plane.weight_b) * velocities_[plane.particle_a] + plane.weight_b * velocities_[plane.particle_b],
        (1.0 - w) * solution_[plane.particle_a] + w * solution_[plane.particle_b]);
    if (spring && f > plane.max_force_n) {
      plane_gain_[k] = 0.0F;
      plane_force_[k] = plane.max_force_n;
      changed = true;
    } else if (spring && f < 0.0F) {
      plane_gain_[k] = 0.0F;
      plane_force_[k] = 0.0F;
      changed = true;
    } else if (clamped && f < plane.max_force_n) {
      plane_gain_[k] = spring_gain;
      plane_force_[k] = plane_start_[k];
      changed = true;
    }
  }
  return changed;
}

bool Catheter::substep(float dt_s, float fraction, float hold_step) noexcept {
  explicit_forces(dt_s, fraction);
  // At most kPlanePasses solves, each further one after planes changed state.
  constexpr int kPlanePasses = 6;
  for (int pass = 0;; ++pass) {
    assemble(dt_s, fraction);
    factor_and_solve();
    if (pass + 1 == kPlanePasses || !update_planes()) break;
  }
  const double h = static_cast<double>(dt_s);
  const double mass = static_cast<double>(mass_kg_);
  for (std::size_t k = 0; k < plane_count_; ++k) {
    const ContactPlane& plane = planes_[k];
    float f = plane_force_[k];
    if (plane_gain_[k] != 0.0F) {
      const double w = static_cast<double>(plane.weight_b);
      f = implicit_plane_force(
          plane, f, plane_gain_[k],
          (1.0F - plane.weight_b) * velocities_[plane.particle_a] + plane.weight_b * velocities_[plane.particle_b],
          (1.0 - w) * solution_[plane.particle_a] + w * solution_[plane.particle_b]);
    }
    plane_forces_n_[k] += (fraction * f) * plane.normal;
  }
  return advance(dt_s, fraction, hold_step, [&](std::uint32_t i) {
    // The pin balances every force on the particle over the substep, the implicit ones at
    // their end-of-substep values: F̂_i − ((A − m I) v')_i / h. The holder feels it.
    Eigen::Vector3d implicit = diagonal_[i] * solution_[i] - mass * solution_[i];
    if (i >= 1) implicit.noalias() += band1_[i - 1] * solution_[i - 1];
    if (i + 1 < count_) implicit.noalias() += band1_[i] * solution_[i + 1];
    if (i >= 2) implicit += band2_[i - 2] * solution_[i - 2];
    if (i + 2 < count_) implicit += band2_[i] * solution_[i + 2];
    return Eigen::Vector3d((forces_[i] + contact_n_[i]).cast<double>() - implicit / h);
  });
}

}  // namespace trainer::model
