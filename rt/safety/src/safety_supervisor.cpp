#include "trainer/safety/safety_supervisor.hpp"

#include <bit>
#include <cmath>

namespace trainer::safety {

const char* to_string(Fault fault) noexcept {
  switch (fault) {
    case Fault::none: return "none";
    case Fault::not_armed: return "not_armed";
    case Fault::non_finite: return "non_finite";
    case Fault::encoder_jump: return "encoder_jump";
    case Fault::overrun_streak: return "overrun_streak";
    case Fault::drive_fault: return "drive_fault";
    case Fault::device_lost: return "device_lost";
    case Fault::estop: return "estop";
    case Fault::passivity: return "passivity";
    case Fault::enable_released: return "enable_released";
    case Fault::shutdown: return "shutdown";
  }
  return "unknown";
}

SafetySupervisor::SafetySupervisor(const SafetyLimits& limits, std::size_t instrument_count) noexcept
    : limits_(limits),
      instrument_count_(instrument_count < kMaxInstruments ? instrument_count : kMaxInstruments) {
  for (auto& force : last_force_n_) force.setZero();
}

void SafetySupervisor::latch(Fault fault, std::uint64_t cycle) noexcept {
  const std::uint32_t b = bit(fault);
  if (b == 0) return;
  ++fault_counts_[static_cast<std::size_t>(std::countr_zero(b))];
  // The first fault after arming is the one that explains the stop.
  if (latched_ == 0) {
    first_fault_ = fault;
    first_fault_cycle_ = cycle;
  }
  latched_ |= b;
  for (auto& force : last_force_n_) force.setZero();
}

bool SafetySupervisor::evaluate_inputs(const InputConditions& inputs, std::uint64_t cycle) noexcept {
  if (inputs.estop_active && (latched_ & bit(Fault::estop)) == 0) latch(Fault::estop, cycle);
  if (inputs.drive_fault && (latched_ & bit(Fault::drive_fault)) == 0) {
    latch(Fault::drive_fault, cycle);
  }
  if (limits_.require_enable_input && !inputs.enable_held && armed()) {
    latch(Fault::enable_released, cycle);
  }
  if (reset_requested_) {
    reset_requested_ = false;
    const bool inputs_clear = !inputs.estop_active && !inputs.drive_fault &&
                              (!limits_.require_enable_input || inputs.enable_held);
    // A shutdown is final; nothing else survives an explicit reset once its cause is gone.
    if (inputs_clear && (latched_ & bit(Fault::shutdown)) == 0) {
      latched_ = 0;
      first_fault_ = Fault::none;
      for (auto& force : last_force_n_) force.setZero();
      for (auto& energy : delivered_energy_j_) energy = 0.0F;
      ++arm_count_;
    }
  }
  return armed();
}

void SafetySupervisor::check_joint_step(bool prismatic, float previous_position, float position,
                                        float dt_s, std::uint64_t cycle) noexcept {
  if (!std::isfinite(position)) {
    latch(Fault::non_finite, cycle);
    return;
  }
  const float limit =
      prismatic ? limits_.max_insertion_speed_m_per_s : limits_.max_joint_speed_rad_per_s;
  if (std::fabs(position - previous_position) > limit * dt_s) latch(Fault::encoder_jump, cycle);
}

Vec3 SafetySupervisor::limit_force(std::size_t instrument, const Vec3& requested_n, float dt_s,
                                   std::uint64_t cycle) noexcept {
  if (instrument >= instrument_count_) return Vec3::Zero();
  if (!requested_n.allFinite() || !std::isfinite(dt_s)) {
    latch(Fault::non_finite, cycle);
    return Vec3::Zero();
  }
  if (!armed()) return Vec3::Zero();

  // The magnitude in double: a finite float request beyond ~1.8e19 N overflows a float norm,
  // and the clamp would then scale it to zero instead of to max_force_n along its direction.
  Vec3 force = requested_n;
  const double magnitude = requested_n.cast<double>().norm();
  if (magnitude > static_cast<double>(limits_.max_force_n)) {
    force = (requested_n.cast<double>() * (static_cast<double>(limits_.max_force_n) / magnitude))
                .cast<float>();
    ++clamped_cycles_;
  }
  // Slew-limit rises and direction changes; a pure decrease toward zero is always allowed
  // (holding force up while the tool leaves a surface would inject energy). No time (dt ≤ 0)
  // allows no rise: a negative step would turn the limit around, past max_force_n.
  const Vec3& last = last_force_n_[instrument];
  const Vec3 step = force - last;
  const float max_step = dt_s > 0.0F ? limits_.max_force_rate_n_per_s * dt_s : 0.0F;
  const float step_norm = step.norm();
  const bool decreasing = force.squaredNorm() <= last.squaredNorm() && force.dot(last) >= 0.0F;
  if (step_norm > max_step && !decreasing) {
    force = last + step * (max_step / step_norm);
    ++slew_limited_cycles_;
  }
  last_force_n_[instrument] = force;
  return force;
}

void SafetySupervisor::reduce_last_force(std::size_t instrument, const Vec3& rendered_n) noexcept {
  if (instrument >= instrument_count_ || !armed() || !rendered_n.allFinite()) return;
  if (rendered_n.squaredNorm() <= last_force_n_[instrument].squaredNorm()) {
    last_force_n_[instrument] = rendered_n;
  }
}

void SafetySupervisor::observe_power(std::size_t instrument, const Vec3& force_n,
                                     const Vec3& velocity_m_per_s, float dt_s,
                                     std::uint64_t cycle) noexcept {
  if (instrument >= instrument_count_ || !armed()) return;
  const float power_w = force_n.dot(velocity_m_per_s);
  if (!std::isfinite(power_w) || !std::isfinite(dt_s)) {
    latch(Fault::non_finite, cycle);
    return;
  }
  if (!(dt_s > 0.0F)) return;  // no time, no work (a NaN here would disable the check for good)
  delivered_energy_j_[instrument] += power_w * dt_s;
  if (limits_.passivity_energy_bound_j > 0.0F &&
      delivered_energy_j_[instrument] > limits_.passivity_energy_bound_j) {
    latch(Fault::passivity, cycle);
  }
}

}  // namespace trainer::safety
