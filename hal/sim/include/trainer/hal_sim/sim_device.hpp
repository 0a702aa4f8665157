// SimDevice: the simulated bench, a hal::Device offering encoders, actuators and digital I/O
// at the level of the real signals (ArduPilot SITL style), so the controller's real conversion
// and safety code runs unchanged against it.
//
// What is simulated, per joint (channel = instrument * 5 + joint, sim_params.hpp):
//  - the plant: an inertia driven by the trainee's hand (a spring-damper toward the scripted
//    target, trainee_script.hpp) and by the applied motor effort; joint limits are hard stops.
//    Semi-implicit Euler in fixed sub-steps of plant_substep_ns. The plant advances lazily:
//    read_encoders() and write_actuators() first advance it from its last time to
//    clock.now_ns() (the remainder below one sub-step is carried), so a core::ManualClock makes
//    it deterministic and core::MonotonicClock makes it real time. The motor effort is held
//    constant between writes (zero-order hold, as a drive's current loop does).
//  - the encoder: counts = JointScale::counts_from_position (real quantisation; counts are
//    absolute, 0 at joint position 0, as if homed).
//  - the drive: current limit (clip + saturated flag), rejection of non-finite commands.
//  - two switches on digital inputs (e-stop, enable) and latched digital outputs. The e-stop
//    does NOT cut motor power in the simulation: removing torque is the controller's job and
//    the sim must let tests see whether it does.
//
// Script time starts at activate(); while inactive the hand holds the script pose at the time
// the device was last deactivated (the initial pose after configure()).
//
// Threads: lifecycle and RT calls come from one thread at a time (the loop's). The inject_* /
// set_* fault controls are atomics and may be called from any thread while the loop runs. The
// observation getters (true_position() ...) read plain state: call them from the loop's thread
// or while it is stopped (digital_output_levels() is atomic and safe anywhere).
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

#include "trainer/core/clock.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/hal/device.hpp"
#include "trainer/hal_sim/sim_params.hpp"
#include "trainer/hal_sim/trainee_script.hpp"

namespace trainer::hal::sim {

class SimDevice final : public hal::Device,
                        public hal::EncoderInterface,
                        public hal::ActuatorInterface,
                        public hal::DigitalInputInterface,
                        public hal::DigitalOutputInterface {
 public:
  // `clock` must outlive the device. Nothing is validated until configure().
  SimDevice(core::Clock& clock, SimDeviceParams params);
  ~SimDevice() override = default;

  // --- hal::Device ----------------------------------------------------------------------
  std::string_view name() const noexcept override { return params_.name; }
  // Validates the parameters, loads the trainee script, places the plant at the script's
  // initial pose at rest. Allowed when unconfigured or inactive.
  core::Expected<void> configure() override;
  // Drives on: refuses while an injected drive fault is present. Restarts script time at 0
  // and the plant at the initial pose at rest; clears commands and rejected-command faults.
  core::Expected<void> activate() override;
  // Zero efforts, disable every channel, all digital outputs low. Any state, never fails.
  void deactivate() noexcept override;
  hal::LifecycleState state() const noexcept override { return state_; }

  hal::EncoderInterface* encoders() noexcept override { return this; }
  hal::ActuatorInterface* actuators() noexcept override { return this; }
  hal::DigitalInputInterface* digital_inputs() noexcept override { return this; }
  hal::DigitalOutputInterface* digital_outputs() noexcept override { return this; }

  // --- RT interfaces (noexcept, no heap) --------------------------------------------------
  // All return ReturnCode::error without touching `out` when unconfigured or when a span is
  // shorter than the channel count.
  std::size_t encoder_count() const noexcept override { return channel_count_; }
  // error while an injected read failure is pending (samples marked invalid).
  hal::ReturnCode read_encoders(std::span<hal::EncoderSample> out) noexcept override;

  std::size_t actuator_count() const noexcept override { return channel_count_; }
  // Only while active. error when a command was non-finite (that channel applies zero and
  // reports a fault until a finite command arrives); deactivate while any drive is faulted.
  hal::ReturnCode write_actuators(std::span<const hal::ActuatorCommand> commands) noexcept override;
  // deactivate while any drive is faulted (the statuses are still filled).
  hal::ReturnCode read_actuator_status(std::span<hal::ActuatorStatus> out) noexcept override;

  std::size_t digital_input_count() const noexcept override { return kDigitalInputCount; }
  hal::ReturnCode read_digital_inputs(std::uint32_t& levels) noexcept override;
  std::size_t digital_output_count() const noexcept override { return kDigitalOutputCount; }
  // error (nothing stored) if a bit at or above digital_output_count() is set.
  hal::ReturnCode write_digital_outputs(std::uint32_t levels) noexcept override;

  // --- Fault injection (thread-safe, any thread, any state) -------------------------------
  // Channel-indexed calls return false for a channel outside 0 .. kMaxChannels-1.
  // The encoder keeps reporting the counts it had when it got stuck.
  bool inject_stuck_encoder(std::size_t channel, bool stuck) noexcept;
  // The next `count` read_encoders() calls fail (replaces any pending count).
  void inject_read_failures(std::uint32_t count) noexcept;
  // The next `count` read_encoders() calls first sleep `delay_ns` on the device's clock
  // (ManualClock: time jumps forward; MonotonicClock: the call really blocks).
  void inject_late_reply(std::int64_t delay_ns, std::uint32_t count) noexcept;
  void set_estop(bool pressed) noexcept;
  void set_enable_switch(bool held) noexcept;  // held by default
  // A faulted drive removes torque on its channel and reports fault until cleared.
  bool inject_drive_fault(std::size_t channel, bool faulted) noexcept;

  // --- Observation for tests and reports (see the threading note above) --------------------
  std::size_t channel_count() const noexcept { return channel_count_; }
  std::string channel_name(std::size_t channel) const;  // "left.insertion"
  // True plant state, joint side (rad or m, rad/s or m/s); 0 for an out-of-range channel.
  double true_position(std::size_t channel) const noexcept;
  double true_velocity(std::size_t channel) const noexcept;
  // Effort acting on the plant now (after clipping, enable and drive faults), N·m or N.
  double applied_effort(std::size_t channel) const noexcept;
  // Where the simulated hand pulls the joint at the plant's current time.
  double hand_target_position(std::size_t channel) const noexcept;
  std::uint32_t digital_output_levels() const noexcept;
  // Clock time up to which the plant has been integrated (a multiple of the sub-step behind
  // the last advance), and the script time at that instant.
  std::int64_t simulated_time_ns() const noexcept { return plant_time_ns_; }
  double script_time_s() const noexcept { return script_time_at(plant_time_ns_); }
  double script_duration_s() const noexcept { return script_.duration_s(); }
  const TraineeScript& script() const noexcept { return script_; }
  const SimDeviceParams& params() const noexcept { return params_; }

 private:
  struct JointState {
    double position = 0.0;
    double velocity = 0.0;
  };
  struct DriveState {
    double commanded_effort = 0.0;  // after clipping; what the drive applies when enabled
    bool enabled = false;
    bool saturated = false;
    bool rejected_command = false;  // last command was non-finite
  };

  core::Expected<void> validate_params() const;
  bool configured() const noexcept { return state_ != hal::LifecycleState::unconfigured; }
  void reset_plant_to_script_start() noexcept;
  void advance_plant_to(std::int64_t time_ns) noexcept;
  double script_time_at(std::int64_t time_ns) const noexcept;
  double effective_effort(std::size_t channel) const noexcept;
  bool any_drive_faulted() const noexcept;
  const JointScale& scale(std::size_t channel) const noexcept;
  const JointPlantParams& plant(std::size_t channel) const noexcept;

  core::Clock& clock_;
  SimDeviceParams params_;
  TraineeScript script_;
  hal::LifecycleState state_ = hal::LifecycleState::unconfigured;
  std::size_t channel_count_ = 0;
  std::size_t instrument_count_ = 0;

  // Plant clock: the plant is integrated up to plant_time_ns_; script time is
  // (t - script_origin_ns_) while active, else frozen at frozen_script_time_s_.
  std::int64_t plant_time_ns_ = 0;
  std::int64_t script_origin_ns_ = 0;
  double frozen_script_time_s_ = 0.0;

  std::array<JointState, kMaxChannels> joints_{};
  std::array<DriveState, kMaxChannels> drives_{};
  std::array<std::int64_t, kMaxChannels> reported_counts_{};

  // Fault injection and switches, written by any thread.
  std::array<std::atomic<bool>, kMaxChannels> stuck_encoder_{};
  std::array<std::atomic<bool>, kMaxChannels> drive_fault_{};
  std::atomic<std::uint32_t> pending_read_failures_{0};
  std::atomic<std::uint32_t> pending_late_replies_{0};
  std::atomic<std::int64_t> late_reply_delay_ns_{0};
  std::atomic<bool> estop_pressed_{false};
  std::atomic<bool> enable_switch_held_{true};
  std::atomic<std::uint32_t> digital_outputs_{0};
};

}  // namespace trainer::hal::sim
