// Turns a scene's device description into a HAL backend. Only the app names concrete
// backends; this is where they are wired: the simulated bench (hal/sim) and the hardware
// backends a device file can name ([device] backend).
#pragma once

#include <memory>
#include <string>

#include "trainer/config/scene.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/hal/device.hpp"
#include "trainer/hal_gpiod/gpio_device.hpp"
#include "trainer/hal_sim/sim_device.hpp"
#include "trainer/hal_libusb/usb_device.hpp"
#include "trainer/hal_socketcan/canopen_device.hpp"

namespace trainer::app {

hal::sim::SimDeviceParams sim_params_from(const config::SceneConfig& scene);
// The simulated plant of a device file's mechanism with `trainee_script` as the hand: also
// what simdrive puts behind its drives.
hal::sim::SimDeviceParams sim_params_from(const config::DeviceConfig& device,
                                          const std::string& trainee_script);

// The CiA 402 master's parameters: the device file's [canopen] table and drives (channel
// order = instrument * 5 + joint, as on the simulated bench), the scene's loop period.
hal::socketcan::CanopenDeviceParams canopen_params_from(const config::SceneConfig& scene);

// The USB haptic interface's parameters: the device file's [usb] table and one channel per
// joint (channel order = instrument * 5 + joint), the scene's loop period.
hal::libusb::UsbDeviceParams usb_params_from(const config::SceneConfig& scene);

// The GPIO lines of a device file's [gpio] table (digital_io = "gpio"): inputs then outputs,
// in file order.
hal::gpiod::GpioDeviceParams gpio_params_from(const config::DeviceConfig& device);

// `motion` as it is when the device file's digital I/O is the backend's own; with
// digital_io = "gpio" a hal::CompositeDevice of `motion` and the GPIO lines (lines claimed
// before the motion starts, released after it stopped).
std::unique_ptr<hal::Device> with_digital_io(const config::DeviceConfig& device,
                                             std::unique_ptr<hal::Device> motion);

// The hardware backend the scene's device file names, created but not configured (configure()
// opens the bus and checks every node and the parameters). `clock` must outlive the device.
core::Expected<std::unique_ptr<hal::Device>> make_hardware_device(
    const config::SceneConfig& scene, core::Clock& clock);

}  // namespace trainer::app
