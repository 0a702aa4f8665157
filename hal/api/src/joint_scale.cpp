#include "trainer/hal/joint_scale.hpp"

#include <cmath>
#include <numbers>

namespace trainer::hal {

const char* to_string(ReturnCode code) noexcept {
  switch (code) {
    case ReturnCode::ok: return "ok";
    case ReturnCode::error: return "error";
    case ReturnCode::deactivate: return "deactivate";
  }
  return "unknown";
}

const char* to_string(LifecycleState state) noexcept {
  switch (state) {
    case LifecycleState::unconfigured: return "unconfigured";
    case LifecycleState::inactive: return "inactive";
    case LifecycleState::active: return "active";
  }
  return "unknown";
}

double JointScale::position_per_count() const noexcept {
  const double per_motor_rev = 2.0 * std::numbers::pi / gear_ratio;
  const double joint_per_motor_rev =
      kind == JointKind::prismatic ? per_motor_rev * capstan_radius_m : per_motor_rev;
  return joint_per_motor_rev / static_cast<double>(counts_per_rev);
}

double JointScale::effort_per_amp() const noexcept {
  const double joint_torque = torque_constant_nm_per_a * gear_ratio;
  return kind == JointKind::prismatic ? joint_torque / capstan_radius_m : joint_torque;
}

double JointScale::position_from_counts(std::int64_t counts) const noexcept {
  return static_cast<double>(counts) * position_per_count() * encoder_sign();
}

std::int64_t JointScale::counts_from_position(double position) const noexcept {
  const std::int64_t counts = std::llround(position / position_per_count());
  return encoder_direction < 0 ? -counts : counts;
}

double JointScale::current_from_effort(double effort) const noexcept {
  return effort / effort_per_amp() * motor_sign();
}

}  // namespace trainer::hal
