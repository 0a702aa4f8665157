// The catheter's substep while the period's substep resolves the bending and the contacts
// explicitly (docs/catheter.md, "Integration and substep": h² (20 k_b/(m l0²) + k_max/m) ≤ 1,
// the cbd catheter at 10 kHz): linearly implicit axial springs and damping only (a
// block-tridiagonal solve), bending and contact planes explicit (Basdogan eq. 27–28). This is
// the integrator of before the implicit bending, unchanged operation for operation, so such
// runs are bit-identical to it.
#include <algorithm>
#include <cmath>

#include "catheter_advance.hpp"
#include "trainer/model/catheter.hpp"

namespace trainer::model {

void Catheter::solve_tridiagonal(float dt_s, float period_fraction) noexcept {
  // Linearly implicit Euler for the axial springs and the damping, explicit for the rest:
  //   m (v' − v) = h [F(p) − b v' − H (p' − p)],  p' = p + h v'
  //   ⇒ ((m + h b) I + h² H) v' = m v + h F(p),
  // H the axial springs' Hessian, per segment k_s [g I + (1 − g) û ûᵀ] with
  // g = max(0, 1 − l0/l) (tension's geometric stiffness; compression's negative one stays in
  // the explicit force). SPD, block tridiagonal: block Thomas (LDLᵀ) elimination in double.
  const double h = static_cast<double>(dt_s);
  const double h2k = h * h * static_cast<double>(stiffness_.axial_n_per_m);
  const double l0 = static_cast<double>(stiffness_.rest_length_m);
  const double mass = static_cast<double>(mass_kg_);
  const double diagonal = mass + h * static_cast<double>(damping_n_s_per_m_);
  for (std::uint32_t s = 0; s + 1 < count_; ++s) {
    SegmentCoupling& coupling = coupling_[s];
    const double length = static_cast<double>(segment_lengths_[s]);
    if (!(length > 0.0)) {
      coupling = SegmentCoupling{};
      continue;
    }
    const double g = std::clamp(1.0 - l0 / length, 0.0, 1.0);
    coupling.unit = segment_units_[s].cast<double>();
    coupling.isotropic = h2k * g;
    coupling.along = h2k * (1.0 - g);
  }
  // Forward elimination (block LDLᵀ): D'_i = D_i − C D'_{i−1}⁻¹ C, r'_i = r_i − C D'_{i−1}⁻¹ r'_{i−1}
  // with C = −(a I + b û ûᵀ) symmetric, so with w = D'⁻¹ û:
  //   C D'⁻¹ C = a² D'⁻¹ + a b (w ûᵀ + û wᵀ) + b² (û·w) û ûᵀ,   C D'⁻¹ r' = −(a y + b (û·y) û), y = D'⁻¹ r'.
  // A held particle's velocity is known (its hold path): its row is the identity, and its
  // couplings move to the free neighbours' right-hand sides.
  const float dt_over_period = dt_s / period_fraction;  // the step's period
  const auto hold_velocity = [&](std::uint32_t i) {
    return Eigen::Vector3d(((hold_targets_m_[i] - saved_positions_[i]) / dt_over_period).cast<double>());
  };
  for (std::uint32_t i = 0; i < count_; ++i) {
    if (held_[i] != 0) {
      solution_[i] = hold_velocity(i);
      block_inverse_[i].setIdentity();
      continue;
    }
    Eigen::Matrix3d block = Eigen::Matrix3d::Identity() * diagonal;
    Eigen::Vector3d rhs = mass * velocities_[i].cast<double>() + h * forces_[i].cast<double>();
    const auto add_segment = [&block](const SegmentCoupling& c) {
      block.diagonal().array() += c.isotropic;
      block.noalias() += c.along * (c.unit * c.unit.transpose());
    };
    if (i > 0) add_segment(coupling_[i - 1]);  // the segments at i
    if (i + 1 < count_) add_segment(coupling_[i]);
    if (i > 0) {
      const SegmentCoupling& c = coupling_[i - 1];
      if (held_[i - 1] != 0) {
        rhs += c.times(solution_[i - 1]);  // −C v_held
      } else {
        const Eigen::Matrix3d& previous = block_inverse_[i - 1];
        const Eigen::Vector3d w = previous * c.unit;
        const Eigen::Vector3d y = previous * solution_[i - 1];
        block.noalias() -= (c.along * c.along * c.unit.dot(w)) * (c.unit * c.unit.transpose());
        if (c.isotropic != 0.0) {
          block.noalias() -= (c.isotropic * c.isotropic) * previous;
          block.noalias() -= (c.isotropic * c.along) * (w * c.unit.transpose() + c.unit * w.transpose());
        }
        rhs += c.times(y);
      }
    }
    if (i + 1 < count_ && held_[i + 1] != 0) rhs += coupling_[i].times(hold_velocity(i + 1));
    block_inverse_[i] = block.inverse();
    solution_[i] = rhs;
  }
  // Back substitution: v_i = D'_i⁻¹ (r'_i − C_i v_{i+1}), free neighbours only.
  for (std::uint32_t k = count_; k-- > 0;) {
    if (held_[k] != 0) continue;
    if (k + 1 < count_ && held_[k + 1] == 0) solution_[k] += coupling_[k].times(solution_[k + 1]);
    solution_[k] = block_inverse_[k] * solution_[k];
  }
}

bool Catheter::substep_tridiagonal(float dt_s, float fraction, float hold_step) noexcept {
  explicit_forces(dt_s, fraction);
  solve_tridiagonal(dt_s, fraction);
  const double h = static_cast<double>(dt_s);
  return advance(dt_s, fraction, hold_step, [&](std::uint32_t i) {
    // The pin balances every force on the particle over the substep, the implicit ones at
    // their end-of-substep values: F(p) − b v' − h Σ_s H_s (v'_i − v'_j). The holder feels it.
    Eigen::Vector3d force = forces_[i].cast<double>() - static_cast<double>(damping_n_s_per_m_) * solution_[i];
    if (i > 0) force -= coupling_[i - 1].times(solution_[i] - solution_[i - 1]) / h;
    if (i + 1 < count_) force -= coupling_[i].times(solution_[i] - solution_[i + 1]) / h;
    return force;
  });
}

}  // namespace trainer::model
