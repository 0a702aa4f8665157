// Conversion between a joint's encoder counts / motor current and joint-side SI units.
// Encoders and motors sit on the motor shaft; a gear (and for the insertion axis a capstan
// of radius r) sits between motor and joint:
//   revolute:  joint angle [rad]   = counts / (counts_per_rev * gear_ratio) * 2π
//   prismatic: joint travel [m]    = counts / (counts_per_rev * gear_ratio) * 2π r
//   effort at joint (N·m or N)     = current * torque_constant * gear_ratio   (revolute)
//                                  = current * torque_constant * gear_ratio / r (prismatic)
// Directions (the device file's encoder_direction / motor_direction, default +1): an encoder
// wired the other way counts down when the joint moves in its positive direction (-1), a motor
// wired the other way turns the joint negative for a positive current (-1). position_from_counts
// and counts_from_position apply encoder_direction; motor_sign() is the factor a backend applies
// between joint-side effort and motor current or torque (effort_per_amp() stays positive).
// Every backend uses these, so simulation and hardware quantise and saturate the same way.
#pragma once

#include <cstdint>

#include "trainer/hal/device.hpp"

namespace trainer::hal {

struct JointScale {
  JointKind kind = JointKind::revolute;
  std::int32_t counts_per_rev = 4096;     // encoder counts per motor revolution (quadrature)
  double gear_ratio = 1.0;                // motor revolutions per joint revolution
  double capstan_radius_m = 0.0;          // prismatic joints only
  double torque_constant_nm_per_a = 0.0;  // motor torque per ampere
  double current_limit_a = 0.0;           // drive's continuous current limit
  std::int8_t encoder_direction = 1;      // +1 or -1
  std::int8_t motor_direction = 1;        // +1 or -1

  double encoder_sign() const noexcept { return encoder_direction < 0 ? -1.0 : 1.0; }
  double motor_sign() const noexcept { return motor_direction < 0 ? -1.0 : 1.0; }

  // Joint-side distance per encoder count: rad (revolute) or m (prismatic).
  double position_per_count() const noexcept;
  // Joint-side effort per ampere of motor current: N·m/A or N/A.
  double effort_per_amp() const noexcept;
  double max_effort() const noexcept { return effort_per_amp() * current_limit_a; }

  double position_from_counts(std::int64_t counts) const noexcept;
  // Nearest count to a joint position (what an ideal encoder reads).
  std::int64_t counts_from_position(double position) const noexcept;
  // Motor current (signed as the motor sees it, motor_direction applied) for a joint effort.
  double current_from_effort(double effort) const noexcept;
};

}  // namespace trainer::hal
