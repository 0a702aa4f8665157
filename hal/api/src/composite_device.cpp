#include "trainer/hal/composite_device.hpp"

#include <utility>

namespace trainer::hal {

CompositeDevice::CompositeDevice(std::string name, std::unique_ptr<Device> motion,
                                 std::unique_ptr<Device> io)
    : name_(std::move(name)), motion_(std::move(motion)), io_(std::move(io)) {}

CompositeDevice::~CompositeDevice() {
  deactivate();
}

core::Expected<void> CompositeDevice::configure() {
  if (auto configured = io_->configure(); !configured) return configured;
  if (auto configured = motion_->configure(); !configured) {
    io_->deactivate();
    return configured;
  }
  return {};
}

core::Expected<void> CompositeDevice::activate() {
  if (auto activated = io_->activate(); !activated) return activated;
  if (auto activated = motion_->activate(); !activated) {
    io_->deactivate();
    return activated;
  }
  return {};
}

void CompositeDevice::deactivate() noexcept {
  motion_->deactivate();
  io_->deactivate();
}

LifecycleState CompositeDevice::state() const noexcept {
  const LifecycleState motion = motion_->state();
  const LifecycleState io = io_->state();
  return static_cast<int>(motion) < static_cast<int>(io) ? motion : io;
}

}  // namespace trainer::hal
