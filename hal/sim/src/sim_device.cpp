// SimDevice: parameter validation and lifecycle (setup path), the lazily advanced plant and
// the RT read/write calls, fault injection.
#include "trainer/hal_sim/sim_device.hpp"

#include "text_format.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

namespace trainer::hal::sim {

namespace {

constexpr double kSecondsPerNanosecond = 1e-9;

// Semi-implicit Euler of x'' = -ω²x - γx' is stable for γh < 2 and ω²h² + 2γh < 4 (the
// eigenvalues of its update matrix stay inside the unit circle). Demanding half of that
// keeps the discrete plant close to the continuous one, not merely bounded.
constexpr double kStabilityBound = 2.0;

using detail::format_number;

bool take_one(std::atomic<std::uint32_t>& counter) noexcept {
  std::uint32_t current = counter.load(std::memory_order_relaxed);
  while (current > 0) {
    if (counter.compare_exchange_weak(current, current - 1, std::memory_order_acq_rel,
                                      std::memory_order_relaxed)) {
      return true;
    }
  }
  return false;
}

JointKind expected_kind(std::size_t joint) noexcept {
  return joint == kInsertionJoint ? JointKind::prismatic : JointKind::revolute;
}

const char* kind_name(JointKind kind) noexcept {
  return kind == JointKind::prismatic ? "prismatic" : "revolute";
}

}  // namespace

SimDevice::SimDevice(core::Clock& clock, SimDeviceParams params)
    : clock_(clock), params_(std::move(params)) {}

// ---------------------------------------------------------------------------------------
// Setup path

core::Expected<void> SimDevice::validate_params() const {
  const std::string device = "sim device '" + params_.name + "': ";
  if (params_.name.empty()) return core::make_error("sim device: name is empty");
  const std::size_t instrument_count = params_.instruments.size();
  if (instrument_count < 1 || instrument_count > kMaxInstruments) {
    return core::make_error(device + std::to_string(instrument_count) +
                            " instruments; expected 1.." + std::to_string(kMaxInstruments) +
                            " (5 channels each: pitch, yaw, insertion, roll, grip)");
  }
  if (params_.plant_substep_ns < kMinPlantSubstepNs ||
      params_.plant_substep_ns > kMaxPlantSubstepNs) {
    return core::make_error(device + "plant_substep_ns = " +
                            std::to_string(params_.plant_substep_ns) + ": expected " +
                            std::to_string(kMinPlantSubstepNs) + ".." +
                            std::to_string(kMaxPlantSubstepNs) + " ns");
  }
  const double substep_s =
      static_cast<double>(params_.plant_substep_ns) * kSecondsPerNanosecond;

  for (std::size_t instrument = 0; instrument < instrument_count; ++instrument) {
    const SimInstrumentParams& params = params_.instruments[instrument];
    if (params.name.empty()) {
      return core::make_error(device + "instrument " + std::to_string(instrument) +
                              " has an empty name");
    }
    for (std::size_t other = 0; other < instrument; ++other) {
      if (params_.instruments[other].name == params.name) {
        return core::make_error(device + "instrument name '" + params.name +
                                "' is used twice (instruments " + std::to_string(other) +
                                " and " + std::to_string(instrument) + "); names must be unique");
      }
    }
    for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
      const std::string where =
          device + "instrument '" + params.name + "' joint " + kJointNames[joint] + ": ";
      const JointScale& scale = params.scales[joint];
      if (scale.kind != expected_kind(joint)) {
        return core::make_error(where + "scale.kind is " + kind_name(scale.kind) + "; expected " +
                                kind_name(expected_kind(joint)));
      }
      if (scale.counts_per_rev <= 0) {
        return core::make_error(where + "scale.counts_per_rev = " +
                                std::to_string(scale.counts_per_rev) + ": expected > 0");
      }
      if (!std::isfinite(scale.gear_ratio) || scale.gear_ratio <= 0.0) {
        return core::make_error(where + "scale.gear_ratio = " + format_number(scale.gear_ratio) +
                                ": expected a finite value > 0");
      }
      if (scale.kind == JointKind::prismatic &&
          (!std::isfinite(scale.capstan_radius_m) || scale.capstan_radius_m <= 0.0)) {
        return core::make_error(where + "scale.capstan_radius_m = " +
                                format_number(scale.capstan_radius_m) +
                                ": expected a finite value > 0 m for a prismatic joint");
      }
      if (!std::isfinite(scale.torque_constant_nm_per_a) || scale.torque_constant_nm_per_a <= 0.0) {
        return core::make_error(where + "scale.torque_constant_nm_per_a = " +
                                format_number(scale.torque_constant_nm_per_a) +
                                ": expected a finite value > 0 N·m/A");
      }
      if (!std::isfinite(scale.current_limit_a) || scale.current_limit_a < 0.0) {
        return core::make_error(where + "scale.current_limit_a = " +
                                format_number(scale.current_limit_a) +
                                ": expected a finite value >= 0 A (0 = unpowered axis)");
      }

      const JointPlantParams& plant = params.plant[joint];
      if (!std::isfinite(plant.inertia) || plant.inertia <= 0.0) {
        return core::make_error(where + "plant.inertia = " + format_number(plant.inertia) +
                                ": expected a finite value > 0 (kg·m² revolute, kg prismatic)");
      }
      if (!std::isfinite(plant.hand_stiffness) || plant.hand_stiffness < 0.0) {
        return core::make_error(where + "plant.hand_stiffness = " +
                                format_number(plant.hand_stiffness) +
                                ": expected a finite value >= 0 (N·m/rad revolute, N/m prismatic)");
      }
      if (!std::isfinite(plant.hand_damping) || plant.hand_damping < 0.0) {
        return core::make_error(
            where + "plant.hand_damping = " + format_number(plant.hand_damping) +
            ": expected a finite value >= 0 (N·m·s/rad revolute, N·s/m prismatic)");
      }
      if (!std::isfinite(plant.min_position) || !std::isfinite(plant.max_position) ||
          !(plant.min_position < plant.max_position)) {
        return core::make_error(where + "plant limits [" + format_number(plant.min_position) +
                                ", " + format_number(plant.max_position) +
                                "]: expected finite min_position < max_position");
      }
      const double omega_h_squared = plant.hand_stiffness / plant.inertia * substep_s * substep_s;
      const double gamma_h = plant.hand_damping / plant.inertia * substep_s;
      if (omega_h_squared + 2.0 * gamma_h >= kStabilityBound) {
        return core::make_error(
            where + "hand stiffness " + format_number(plant.hand_stiffness) + " and damping " +
            format_number(plant.hand_damping) + " on inertia " + format_number(plant.inertia) +
            " are too stiff for plant_substep_ns = " + std::to_string(params_.plant_substep_ns) +
            ": need (k/m)·h² + 2(c/m)·h < " + format_number(kStabilityBound) + ", got " +
            format_number(omega_h_squared + 2.0 * gamma_h) +
            "; lower the stiffness or damping, raise the inertia, or shorten the sub-step");
      }
    }
  }

  const int estop_bit = params_.digital.estop_input_bit;
  const int enable_bit = params_.digital.enable_input_bit;
  const int input_count = static_cast<int>(kDigitalInputCount);
  for (const auto& [key, bit] : {std::pair{"digital.estop_input_bit", estop_bit},
                                 std::pair{"digital.enable_input_bit", enable_bit}}) {
    if (bit < -1 || bit >= input_count) {
      return core::make_error(device + key + " = " + std::to_string(bit) +
                              ": expected -1 (not wired) or 0.." + std::to_string(input_count - 1));
    }
  }
  if (estop_bit >= 0 && estop_bit == enable_bit) {
    return core::make_error(device + "digital.estop_input_bit and digital.enable_input_bit are " +
                            "both " + std::to_string(estop_bit) + "; expected different bits");
  }
  return {};
}

core::Expected<void> SimDevice::configure() {
  if (state_ == hal::LifecycleState::active) {
    return core::make_error("sim device '" + params_.name +
                            "': configure() while active; deactivate() first");
  }
  if (auto valid = validate_params(); !valid) return std::move(valid).error();

  std::vector<std::string> instrument_names;
  for (const SimInstrumentParams& instrument : params_.instruments) {
    instrument_names.push_back(instrument.name);
  }
  auto script = TraineeScript::load(params_.script, instrument_names);
  if (!script) {
    return core::make_error("sim device '" + params_.name +
                            "': trainee script: " + script.error().message);
  }

  script_ = std::move(script).value();
  instrument_count_ = params_.instruments.size();
  channel_count_ = instrument_count_ * kJointsPerInstrument;
  state_ = hal::LifecycleState::inactive;
  frozen_script_time_s_ = 0.0;
  script_origin_ns_ = clock_.now_ns();
  plant_time_ns_ = script_origin_ns_;
  reset_plant_to_script_start();
  drives_ = {};
  digital_outputs_.store(0, std::memory_order_relaxed);
  return {};
}

core::Expected<void> SimDevice::activate() {
  const std::string device = "sim device '" + params_.name + "': ";
  if (state_ == hal::LifecycleState::unconfigured) {
    return core::make_error(device + "activate() before configure()");
  }
  if (state_ == hal::LifecycleState::active) {
    return core::make_error(device + "activate() while already active");
  }
  for (std::size_t channel = 0; channel < channel_count_; ++channel) {
    if (drive_fault_[channel].load(std::memory_order_relaxed)) {
      return core::make_error(device + "drive of channel " + std::to_string(channel) + " (" +
                              channel_name(channel) +
                              ") reports a fault; it refuses to enable until the fault clears");
    }
  }
  const std::int64_t now_ns = clock_.now_ns();
  drives_ = {};
  state_ = hal::LifecycleState::active;
  script_origin_ns_ = now_ns;
  plant_time_ns_ = now_ns;
  frozen_script_time_s_ = 0.0;
  reset_plant_to_script_start();
  return {};
}

void SimDevice::deactivate() noexcept {
  if (state_ == hal::LifecycleState::active) {
    // The old efforts acted until now; integrate them before removing torque.
    advance_plant_to(clock_.now_ns());
    frozen_script_time_s_ = script_time_at(plant_time_ns_);
    state_ = hal::LifecycleState::inactive;
  }
  drives_ = {};
  digital_outputs_.store(0, std::memory_order_relaxed);
}

std::string SimDevice::channel_name(std::size_t channel) const {
  const std::size_t instrument = channel / kJointsPerInstrument;
  if (instrument >= params_.instruments.size()) return "channel " + std::to_string(channel);
  return params_.instruments[instrument].name + "." +
         kJointNames[channel % kJointsPerInstrument];
}

// ---------------------------------------------------------------------------------------
// Plant

const JointScale& SimDevice::scale(std::size_t channel) const noexcept {
  return params_.instruments[channel / kJointsPerInstrument].scales[channel % kJointsPerInstrument];
}

const JointPlantParams& SimDevice::plant(std::size_t channel) const noexcept {
  return params_.instruments[channel / kJointsPerInstrument].plant[channel % kJointsPerInstrument];
}

double SimDevice::script_time_at(std::int64_t time_ns) const noexcept {
  if (state_ != hal::LifecycleState::active) return frozen_script_time_s_;
  return static_cast<double>(time_ns - script_origin_ns_) * kSecondsPerNanosecond;
}

void SimDevice::reset_plant_to_script_start() noexcept {
  const double script_time_s = script_time_at(plant_time_ns_);
  for (std::size_t instrument = 0; instrument < instrument_count_; ++instrument) {
    const PoseSample target = script_.sample(instrument, script_time_s);
    for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
      const std::size_t channel = instrument * kJointsPerInstrument + joint;
      const JointPlantParams& limits = plant(channel);
      joints_[channel].position =
          std::clamp(target.position[joint], limits.min_position, limits.max_position);
      joints_[channel].velocity = 0.0;
      if (!stuck_encoder_[channel].load(std::memory_order_relaxed)) {
        reported_counts_[channel] = scale(channel).counts_from_position(joints_[channel].position);
      }
    }
  }
}

double SimDevice::effective_effort(std::size_t channel) const noexcept {
  const DriveState& drive = drives_[channel];
  if (state_ != hal::LifecycleState::active || !drive.enabled || drive.rejected_command ||
      drive_fault_[channel].load(std::memory_order_relaxed)) {
    return 0.0;
  }
  return drive.commanded_effort;
}

bool SimDevice::any_drive_faulted() const noexcept {
  for (std::size_t channel = 0; channel < channel_count_; ++channel) {
    if (drive_fault_[channel].load(std::memory_order_relaxed)) return true;
  }
  return false;
}

void SimDevice::advance_plant_to(std::int64_t time_ns) noexcept {
  const std::int64_t substep_ns = params_.plant_substep_ns;
  if (time_ns - plant_time_ns_ < substep_ns) return;
  // Motor efforts are a zero-order hold over this whole advance (a fault injected meanwhile
  // takes effect from the next advance, i.e. within one loop cycle).
  std::array<double, kMaxChannels> effort{};
  for (std::size_t channel = 0; channel < channel_count_; ++channel) {
    effort[channel] = effective_effort(channel);
  }
  const double substep_s = static_cast<double>(substep_ns) * kSecondsPerNanosecond;
  while (time_ns - plant_time_ns_ >= substep_ns) {
    plant_time_ns_ += substep_ns;
    // Hand target at the end of the sub-step, matching the velocity-then-position update.
    const double script_time_s = script_time_at(plant_time_ns_);
    for (std::size_t instrument = 0; instrument < instrument_count_; ++instrument) {
      const PoseSample target = script_.sample(instrument, script_time_s);
      for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
        const std::size_t channel = instrument * kJointsPerInstrument + joint;
        const JointPlantParams& params = plant(channel);
        JointState& state = joints_[channel];
        const double hand_effort =
            params.hand_stiffness * (target.position[joint] - state.position) +
            params.hand_damping * (target.velocity[joint] - state.velocity);
        const double acceleration = (hand_effort + effort[channel]) / params.inertia;
        // Semi-implicit (symplectic) Euler: velocity first, then position with the new velocity.
        state.velocity += acceleration * substep_s;
        state.position += state.velocity * substep_s;
        // Hard stops: the joint rests on the stop; motion into it is absorbed, motion away from
        // it is kept.
        if (state.position >= params.max_position) {
          state.position = params.max_position;
          state.velocity = std::min(state.velocity, 0.0);
        } else if (state.position <= params.min_position) {
          state.position = params.min_position;
          state.velocity = std::max(state.velocity, 0.0);
        }
      }
    }
  }
}

// ---------------------------------------------------------------------------------------
// RT interfaces

hal::ReturnCode SimDevice::read_encoders(std::span<hal::EncoderSample> out) noexcept {
  if (!configured() || out.size() < channel_count_) return hal::ReturnCode::error;
  if (take_one(pending_late_replies_)) {
    const std::int64_t delay_ns = late_reply_delay_ns_.load(std::memory_order_relaxed);
    clock_.sleep_until_ns(clock_.now_ns() + delay_ns);
  }
  advance_plant_to(clock_.now_ns());
  const bool failed = take_one(pending_read_failures_);
  for (std::size_t channel = 0; channel < channel_count_; ++channel) {
    const JointScale& joint_scale = scale(channel);
    if (!failed && !stuck_encoder_[channel].load(std::memory_order_relaxed)) {
      reported_counts_[channel] = joint_scale.counts_from_position(joints_[channel].position);
    }
    // A failed read reports the last good counts, flagged invalid.
    out[channel].counts = reported_counts_[channel];
    out[channel].position =
        static_cast<float>(joint_scale.position_from_counts(reported_counts_[channel]));
    out[channel].valid = !failed;
  }
  return failed ? hal::ReturnCode::error : hal::ReturnCode::ok;
}

hal::ReturnCode SimDevice::write_actuators(
    std::span<const hal::ActuatorCommand> commands) noexcept {
  if (state_ != hal::LifecycleState::active || commands.size() < channel_count_) {
    return hal::ReturnCode::error;
  }
  advance_plant_to(clock_.now_ns());
  bool rejected_any = false;
  for (std::size_t channel = 0; channel < channel_count_; ++channel) {
    const hal::ActuatorCommand& command = commands[channel];
    DriveState& drive = drives_[channel];
    const double effort = static_cast<double>(command.effort);
    drive.enabled = command.enable;
    if (!std::isfinite(effort)) {
      // A real drive rejects the set-point and removes torque rather than guess a value.
      drive.commanded_effort = 0.0;
      drive.saturated = false;
      drive.rejected_command = true;
      rejected_any = true;
      continue;
    }
    const double max_effort = scale(channel).max_effort();
    drive.rejected_command = false;
    drive.saturated = std::abs(effort) > max_effort;
    drive.commanded_effort = std::clamp(effort, -max_effort, max_effort);
  }
  if (any_drive_faulted()) return hal::ReturnCode::deactivate;
  return rejected_any ? hal::ReturnCode::error : hal::ReturnCode::ok;
}

hal::ReturnCode SimDevice::read_actuator_status(std::span<hal::ActuatorStatus> out) noexcept {
  if (!configured() || out.size() < channel_count_) return hal::ReturnCode::error;
  bool faulted_any = false;
  for (std::size_t channel = 0; channel < channel_count_; ++channel) {
    const DriveState& drive = drives_[channel];
    const bool drive_faulted = drive_fault_[channel].load(std::memory_order_relaxed);
    faulted_any = faulted_any || drive_faulted;
    hal::ActuatorStatus& status = out[channel];
    status.applied_effort = static_cast<float>(effective_effort(channel));
    status.enabled = state_ == hal::LifecycleState::active && drive.enabled && !drive_faulted &&
                     !drive.rejected_command;
    status.saturated = drive.saturated;
    status.fault = drive_faulted || drive.rejected_command;
  }
  return faulted_any ? hal::ReturnCode::deactivate : hal::ReturnCode::ok;
}

hal::ReturnCode SimDevice::read_digital_inputs(std::uint32_t& levels) noexcept {
  if (!configured()) return hal::ReturnCode::error;
  std::uint32_t result = 0;
  const int estop_bit = params_.digital.estop_input_bit;
  const int enable_bit = params_.digital.enable_input_bit;
  if (estop_bit >= 0 && estop_pressed_.load(std::memory_order_relaxed)) {
    result |= std::uint32_t{1} << static_cast<unsigned>(estop_bit);
  }
  if (enable_bit >= 0 && enable_switch_held_.load(std::memory_order_relaxed)) {
    result |= std::uint32_t{1} << static_cast<unsigned>(enable_bit);
  }
  levels = result;
  return hal::ReturnCode::ok;
}

hal::ReturnCode SimDevice::write_digital_outputs(std::uint32_t levels) noexcept {
  if (!configured()) return hal::ReturnCode::error;
  if ((levels >> kDigitalOutputCount) != 0) return hal::ReturnCode::error;
  digital_outputs_.store(levels, std::memory_order_relaxed);
  return hal::ReturnCode::ok;
}

// ---------------------------------------------------------------------------------------
// Fault injection

bool SimDevice::inject_stuck_encoder(std::size_t channel, bool stuck) noexcept {
  if (channel >= kMaxChannels) return false;
  stuck_encoder_[channel].store(stuck, std::memory_order_relaxed);
  return true;
}

void SimDevice::inject_read_failures(std::uint32_t count) noexcept {
  pending_read_failures_.store(count, std::memory_order_release);
}

void SimDevice::inject_late_reply(std::int64_t delay_ns, std::uint32_t count) noexcept {
  // Delay first, then the count that makes the reader look at it (release/acquire pair).
  late_reply_delay_ns_.store(delay_ns, std::memory_order_relaxed);
  pending_late_replies_.store(count, std::memory_order_release);
}

void SimDevice::set_estop(bool pressed) noexcept {
  estop_pressed_.store(pressed, std::memory_order_relaxed);
}

void SimDevice::set_enable_switch(bool held) noexcept {
  enable_switch_held_.store(held, std::memory_order_relaxed);
}

bool SimDevice::inject_drive_fault(std::size_t channel, bool faulted) noexcept {
  if (channel >= kMaxChannels) return false;
  drive_fault_[channel].store(faulted, std::memory_order_relaxed);
  return true;
}

// ---------------------------------------------------------------------------------------
// Observation

double SimDevice::true_position(std::size_t channel) const noexcept {
  return channel < channel_count_ ? joints_[channel].position : 0.0;
}

double SimDevice::true_velocity(std::size_t channel) const noexcept {
  return channel < channel_count_ ? joints_[channel].velocity : 0.0;
}

double SimDevice::applied_effort(std::size_t channel) const noexcept {
  return channel < channel_count_ ? effective_effort(channel) : 0.0;
}

double SimDevice::hand_target_position(std::size_t channel) const noexcept {
  if (channel >= channel_count_) return 0.0;
  return script_.sample(channel / kJointsPerInstrument, script_time_s())
      .position[channel % kJointsPerInstrument];
}

std::uint32_t SimDevice::digital_output_levels() const noexcept {
  return digital_outputs_.load(std::memory_order_relaxed);
}

}  // namespace trainer::hal::sim
