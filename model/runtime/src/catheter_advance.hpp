// Private to model/runtime: the end of a catheter substep shared by both solves
// (catheter_solve.cpp, catheter_tridiagonal.cpp): pins and free particles moved.
#pragma once

#include "trainer/model/catheter.hpp"

namespace trainer::model {

template <class HoldForce>
bool Catheter::advance(float dt_s, float fraction, float hold_step, HoldForce&& hold_force) noexcept {
  bool finite = true;
  for (std::uint32_t i = 0; i < count_; ++i) {
    if (held_[i] != 0) {
      const Eigen::Vector3d force = hold_force(i);
      hold_forces_n_[i] += fraction * force.cast<float>();
      const Vec3 start = saved_positions_[i];
      positions_[i] = hold_step >= 1.0F ? hold_targets_m_[i] : Vec3(start + hold_step * (hold_targets_m_[i] - start));
      velocities_[i] = (hold_targets_m_[i] - start) / (dt_s / fraction);
      continue;
    }
    velocities_[i] = solution_[i].cast<float>();  // v_{t+Δt} from the implicit solve
    positions_[i] += dt_s * velocities_[i];       // p_{t+Δt} = p_t + Δt v_{t+Δt}
    finite = finite && positions_[i].allFinite() && velocities_[i].allFinite();
  }
  return finite;
}

}  // namespace trainer::model
