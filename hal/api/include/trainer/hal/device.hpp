// The HAL contract. A backend instance is a Device: it owns a transport (a simulated plant,
// a SocketCAN socket, GPIO lines, a USB handle) and offers one or more per-kind RT
// interfaces. The lifecycle (configure -> activate -> deactivate) is non-RT and may fail
// with a message; the RT calls read()/write() never throw, never allocate, never block
// beyond the transport's own bounded I/O, and return a ReturnCode.
//
// Units at this boundary are joint-side SI: radians and metres for positions,
// newton-metres and newtons for efforts. Raw encoder counts travel alongside positions for
// diagnostics. Channel order is fixed at configure time and documented per backend.
#pragma once

#include <cstdint>
#include <span>
#include <string_view>

#include "trainer/core/expected.hpp"

namespace trainer::hal {

// ros2_control-style result of an RT call: ok, a recoverable error this cycle (counted and
// fed to the safety chain), or "deactivate" when the device has gone to its safe state by
// itself (drive fault, bus-off) and the controller must latch a fault.
enum class ReturnCode : std::uint8_t { ok, error, deactivate };
const char* to_string(ReturnCode code) noexcept;

enum class LifecycleState : std::uint8_t { unconfigured, inactive, active };
const char* to_string(LifecycleState state) noexcept;

enum class JointKind : std::uint8_t { revolute, prismatic };

struct EncoderSample {
  std::int64_t counts = 0;  // raw counts as the device reports them
  float position = 0.0F;    // joint side: rad (revolute) or m (prismatic)
  bool valid = false;       // false when this channel could not be read this cycle
};

class EncoderInterface {
 public:
  virtual std::size_t encoder_count() const noexcept = 0;
  // Fills out[0 .. encoder_count()). `out` must be at least that long.
  virtual ReturnCode read_encoders(std::span<EncoderSample> out) noexcept = 0;

 protected:
  ~EncoderInterface() = default;
};

struct ActuatorCommand {
  float effort = 0.0F;  // joint side: N·m (revolute) or N (prismatic)
  bool enable = false;  // false removes torque on this channel
};

struct ActuatorStatus {
  float applied_effort = 0.0F;  // after the device's own current limit, joint side
  bool enabled = false;
  bool saturated = false;  // the command exceeded the current limit and was clipped
  bool fault = false;      // the drive reports a fault (it has removed torque itself)
};

class ActuatorInterface {
 public:
  virtual std::size_t actuator_count() const noexcept = 0;
  virtual ReturnCode write_actuators(std::span<const ActuatorCommand> commands) noexcept = 0;
  virtual ReturnCode read_actuator_status(std::span<ActuatorStatus> out) noexcept = 0;

 protected:
  ~ActuatorInterface() = default;
};

// Digital lines as a bit set; which bit means what (e-stop, enable switch, drive enable,
// fault lamp) comes from the device file.
class DigitalInputInterface {
 public:
  virtual std::size_t digital_input_count() const noexcept = 0;
  virtual ReturnCode read_digital_inputs(std::uint32_t& levels) noexcept = 0;

 protected:
  ~DigitalInputInterface() = default;
};

class DigitalOutputInterface {
 public:
  virtual std::size_t digital_output_count() const noexcept = 0;
  virtual ReturnCode write_digital_outputs(std::uint32_t levels) noexcept = 0;

 protected:
  ~DigitalOutputInterface() = default;
};

class Device {
 public:
  Device() = default;
  Device(const Device&) = delete;
  Device& operator=(const Device&) = delete;
  virtual ~Device() = default;

  virtual std::string_view name() const noexcept = 0;

  // Non-RT lifecycle. configure(): open the transport, check channels against the device
  // file. activate(): power stages on (drives enabled, lines claimed). deactivate(): remove
  // torque and disable; must not fail and is safe to call in any state (also from the RT
  // thread at shutdown, hence noexcept).
  virtual core::Expected<void> configure() = 0;
  virtual core::Expected<void> activate() = 0;
  virtual void deactivate() noexcept = 0;
  virtual LifecycleState state() const noexcept = 0;

  // The per-kind interfaces this device offers (nullptr when it offers none of that kind).
  virtual EncoderInterface* encoders() noexcept { return nullptr; }
  virtual ActuatorInterface* actuators() noexcept { return nullptr; }
  virtual DigitalInputInterface* digital_inputs() noexcept { return nullptr; }
  virtual DigitalOutputInterface* digital_outputs() noexcept { return nullptr; }
};

}  // namespace trainer::hal
