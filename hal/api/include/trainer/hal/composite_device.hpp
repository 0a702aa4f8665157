// CompositeDevice: one hal::Device made of two, the motion (encoders and actuators: a CAN
// master, the simulated bench) and the digital I/O (e-stop, enable switch, drive enable:
// GPIO lines), e.g. drives on CAN and safety lines on GPIO. It owns both.
//
// Lifecycle order, chosen so that power can only reach the drives through a claimed,
// inactive drive-enable line:
//  configure(): I/O first (lines claimed, outputs inactive: drive enable off), then motion;
//    a motion failure releases the I/O again.
//  activate(): I/O first, then motion (drives enabled; drive enable still off until the
//    controller arms); a motion failure deactivates the I/O.
//  deactivate(): motion first (torque off, drives disabled), then the I/O (outputs driven
//    inactive, lines released).
// state() is the lower of the two. RT calls go straight to the part that offers the interface.
#pragma once

#include <memory>
#include <string>
#include <string_view>

#include "trainer/hal/device.hpp"

namespace trainer::hal {

class CompositeDevice final : public Device {
 public:
  // `motion` offers encoders and actuators, `io` the digital inputs and/or outputs; the
  // motion's own digital interfaces are not used.
  CompositeDevice(std::string name, std::unique_ptr<Device> motion, std::unique_ptr<Device> io);
  ~CompositeDevice() override;

  std::string_view name() const noexcept override { return name_; }
  core::Expected<void> configure() override;
  core::Expected<void> activate() override;
  void deactivate() noexcept override;
  LifecycleState state() const noexcept override;

  EncoderInterface* encoders() noexcept override { return motion_->encoders(); }
  ActuatorInterface* actuators() noexcept override { return motion_->actuators(); }
  DigitalInputInterface* digital_inputs() noexcept override { return io_->digital_inputs(); }
  DigitalOutputInterface* digital_outputs() noexcept override { return io_->digital_outputs(); }

  Device& motion() noexcept { return *motion_; }
  Device& io() noexcept { return *io_; }

 private:
  std::string name_;
  std::unique_ptr<Device> motion_;
  std::unique_ptr<Device> io_;
};

}  // namespace trainer::hal
