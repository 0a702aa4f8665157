// Safety chain of the haptic cycle (DESIGN.md "Safety chain").
//
// The supervisor starts faulted (not_armed); only an explicit reset arms it, and only when no
// input condition is active (e-stop released, enable switch held if required, no drive
// fault). Any fault zeroes force in the same cycle and latches until the next explicit reset:
// recovering communication or releasing the e-stop never re-arms by itself. Every latched
// fault is kept as a bit, with the first fault's code and cycle, so none is lost even if the
// log ring drops the message.
//
// On every cycle, a tool force passes through: finite check → magnitude clamp → slew limit →
// passivity observer. RT methods are noexcept and allocate nothing.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include <Eigen/Core>

namespace trainer::safety {

using Vec3 = Eigen::Vector3f;

enum class Fault : std::uint32_t {
  none = 0,
  not_armed = 1U << 0,        // initial state, cleared only by reset()
  non_finite = 1U << 1,       // NaN/Inf in a force, torque or position
  encoder_jump = 1U << 2,     // joint moved faster than physics allows between two reads
  overrun_streak = 1U << 3,   // too many consecutive late cycles
  drive_fault = 1U << 4,      // an actuator reports a fault or went to its safe state
  device_lost = 1U << 5,      // read/write errors beyond the tolerated streak
  estop = 1U << 6,            // e-stop input active
  passivity = 1U << 7,        // the virtual environment produced more energy than the bound
  enable_released = 1U << 8,  // deadman/enable switch released while armed
  shutdown = 1U << 9,         // controller is shutting down
};
constexpr std::size_t kFaultKinds = 10;
const char* to_string(Fault fault) noexcept;
constexpr std::uint32_t bit(Fault fault) noexcept { return static_cast<std::uint32_t>(fault); }

struct SafetyLimits {
  float max_force_n = 5.0F;                 // per instrument tip force magnitude
  float max_force_rate_n_per_s = 2000.0F;   // slew limit on the commanded force
  float max_joint_speed_rad_per_s = 20.0F;  // encoder-jump threshold, revolute joints
  float max_insertion_speed_m_per_s = 1.0F; // encoder-jump threshold, insertion
  float passivity_energy_bound_j = 0.5F;    // 0 disables the passivity check
  bool require_enable_input = false;
};

struct InputConditions {
  bool estop_active = false;
  bool enable_held = true;
  bool drive_fault = false;
};

class SafetySupervisor {
 public:
  static constexpr std::size_t kMaxInstruments = 4;

  SafetySupervisor() = default;
  SafetySupervisor(const SafetyLimits& limits, std::size_t instrument_count) noexcept;

  // Asks to arm; honoured at the next evaluate_inputs() if no input condition is active.
  void request_reset() noexcept { reset_requested_ = true; }

  // Once per cycle, before forces: latches e-stop / enable / drive faults, then processes a
  // pending reset. Returns true when armed.
  bool evaluate_inputs(const InputConditions& inputs, std::uint64_t cycle) noexcept;

  // Latches a fault (first one recorded with its cycle).
  void latch(Fault fault, std::uint64_t cycle) noexcept;

  // Checks a joint displacement over dt against the speed limits; latches encoder_jump.
  void check_joint_step(bool prismatic, float previous_position, float position, float dt_s,
                        std::uint64_t cycle) noexcept;

  // Turns a requested tool force into the force that may be commanded this cycle: at most
  // max_force_n along the request's direction (any finite magnitude), rising by at most
  // max_force_rate_n_per_s · dt_s (no rise when dt_s ≤ 0). Zero when not armed; latches
  // non_finite on a NaN/Inf force or dt_s.
  Vec3 limit_force(std::size_t instrument, const Vec3& requested_n, float dt_s,
                   std::uint64_t cycle) noexcept;

  // The force actually rendered this cycle when the actuators' effort limits scaled down what
  // limit_force() allowed: the next cycle's slew limit starts from it, so the rendered force
  // never rises faster than the limit when the posture frees the actuators again. Only a
  // finite force no larger than the one limit_force() returned is taken, and only while armed.
  void reduce_last_force(std::size_t instrument, const Vec3& rendered_n) noexcept;

  // Energy observer (Hannaford & Ryu): integrates the power the rendered force delivers to the
  // tool, W += F·v dt. A passive environment cannot deliver more than it absorbed, so W above
  // the bound latches a passivity fault. Resets on arming. A non-finite power or dt_s latches
  // non_finite; dt_s ≤ 0 integrates nothing.
  void observe_power(std::size_t instrument, const Vec3& force_n, const Vec3& velocity_m_per_s,
                     float dt_s, std::uint64_t cycle) noexcept;

  bool armed() const noexcept { return latched_ == 0; }
  std::uint32_t latched_faults() const noexcept { return latched_; }
  Fault first_fault() const noexcept { return first_fault_; }
  std::uint64_t first_fault_cycle() const noexcept { return first_fault_cycle_; }
  // How many times each fault kind was raised (bit index → count), including repeats.
  const std::array<std::uint64_t, kFaultKinds>& fault_counts() const noexcept {
    return fault_counts_;
  }
  // Every raise of every kind, repeats included: the sum of fault_counts().
  std::uint64_t raised_fault_total() const noexcept {
    std::uint64_t total = 0;
    for (const std::uint64_t count : fault_counts_) total += count;
    return total;
  }
  std::uint64_t clamped_cycles() const noexcept { return clamped_cycles_; }
  std::uint64_t slew_limited_cycles() const noexcept { return slew_limited_cycles_; }
  std::uint32_t arm_count() const noexcept { return arm_count_; }
  float delivered_energy_j(std::size_t instrument) const noexcept {
    return delivered_energy_j_[instrument];
  }
  const SafetyLimits& limits() const noexcept { return limits_; }

 private:
  SafetyLimits limits_{};
  std::size_t instrument_count_ = 0;
  std::uint32_t latched_ = bit(Fault::not_armed);
  Fault first_fault_ = Fault::not_armed;
  std::uint64_t first_fault_cycle_ = 0;
  std::array<std::uint64_t, kFaultKinds> fault_counts_{};
  std::array<Vec3, kMaxInstruments> last_force_n_{};
  std::array<float, kMaxInstruments> delivered_energy_j_{};
  std::uint64_t clamped_cycles_ = 0;
  std::uint64_t slew_limited_cycles_ = 0;
  std::uint32_t arm_count_ = 0;
  bool reset_requested_ = false;
};

}  // namespace trainer::safety
