// The HAL interfaces one haptic app runs on: whatever backend the trainer wired (sim, CAN,
// GPIO, USB), the cycle sees only these. Digital inputs and outputs are optional.
#pragma once

#include <cstdint>

#include "trainer/hal/device.hpp"

namespace trainer::app {

// Consecutive HAL read (or write) errors tolerated — the cycle holds the last good state —
// before the device is declared lost and a fault latched.
inline constexpr std::uint32_t kToleratedHalErrorStreak = 3;

struct HalBinding {
  hal::EncoderInterface* encoders = nullptr;
  hal::ActuatorInterface* actuators = nullptr;
  hal::DigitalInputInterface* digital_inputs = nullptr;
  hal::DigitalOutputInterface* digital_outputs = nullptr;
};

}  // namespace trainer::app
