#include "trainer/app/device_wiring.hpp"

#include "trainer/hal/composite_device.hpp"

namespace trainer::app {

hal::sim::SimDeviceParams sim_params_from(const config::SceneConfig& scene) {
  return sim_params_from(scene.device, scene.trainee.script);
}

hal::sim::SimDeviceParams sim_params_from(const config::DeviceConfig& device,
                                          const std::string& trainee_script) {
  hal::sim::SimDeviceParams params;
  params.name = device.name;
  params.plant_substep_ns = device.plant_substep_ns;
  params.digital.estop_input_bit = device.digital.estop_input_bit;
  params.digital.enable_input_bit = device.digital.enable_input_bit;
  params.script = trainee_script;
  for (const config::InstrumentDeviceConfig& instrument : device.instruments) {
    hal::sim::SimInstrumentParams sim;
    sim.name = instrument.name;
    for (std::size_t j = 0; j < instrument.joints.size(); ++j) {
      const config::JointConfig& joint = instrument.joints[j];
      sim.scales[j] = config::joint_scale(joint);
      hal::sim::JointPlantParams& plant = sim.plant[j];
      plant.inertia = joint.inertia;
      plant.hand_stiffness = joint.hand_stiffness;
      plant.hand_damping = joint.hand_damping;
      plant.min_position = joint.min_position;
      plant.max_position = joint.max_position;
    }
    params.instruments.push_back(std::move(sim));
  }
  return params;
}

}  // namespace trainer::app

namespace trainer::app {

hal::socketcan::CanopenDeviceParams canopen_params_from(const config::SceneConfig& scene) {
  const config::DeviceConfig& device = scene.device;
  const config::CanopenConfig& bus = device.canopen;
  hal::socketcan::CanopenDeviceParams params;
  params.name = device.name;
  params.interface = bus.interface;
  params.bitrate = bus.bitrate;
  params.loop_period_ns = scene.loop.period_ns;
  params.sync_period_ns = bus.sync_period_ns > 0 ? bus.sync_period_ns : scene.loop.period_ns;
  params.master_node_id = bus.master_node_id;
  params.master_heartbeat_ns = bus.master_heartbeat_ns;
  params.drive_heartbeat_consumer_ns = bus.drive_heartbeat_consumer_ns;
  params.drive_heartbeat_ns = bus.drive_heartbeat_ns;
  params.drive_heartbeat_timeout_ns = bus.drive_heartbeat_timeout_ns;
  params.rpdo_timeout_ns = bus.rpdo_timeout_ns;
  params.abort_connection_option = static_cast<std::uint8_t>(bus.abort_connection);
  params.sdo_timeout_ns = bus.sdo_timeout_ns;
  params.boot_timeout_ns = bus.boot_timeout_ns;
  params.digital_inputs_node = bus.digital_inputs_node;
  params.digital_outputs_node = bus.digital_outputs_node;
  for (std::size_t i = 0; i < device.instruments.size(); ++i) {
    const config::InstrumentDeviceConfig& instrument = device.instruments[i];
    for (std::size_t j = 0; j < instrument.joints.size(); ++j) {
      const config::JointConfig& joint = instrument.joints[j];
      const std::string joint_name(config::to_string(static_cast<config::JointId>(j)));
      hal::socketcan::DriveParams drive;
      drive.channel_name = instrument.name + "." + joint_name;
      drive.config_key = "instrument[" + std::to_string(i) + "]." + joint_name;
      drive.node_id = joint.canopen.node_id;
      drive.vendor_id = joint.canopen.vendor_id;
      drive.product_code = joint.canopen.product_code;
      drive.revision = joint.canopen.revision;
      drive.motor_rated_torque_nm = joint.canopen.motor_rated_torque_nm;
      drive.scale = config::joint_scale(joint);
      params.drives.push_back(std::move(drive));
    }
  }
  return params;
}

hal::gpiod::GpioDeviceParams gpio_params_from(const config::DeviceConfig& device) {
  hal::gpiod::GpioDeviceParams params;
  params.name = device.name + " GPIO";
  params.consumer = device.gpio.consumer;
  const auto add = [&](const config::GpioLineConfig& line, hal::gpiod::Direction direction) {
    hal::gpiod::LineParams out;
    out.config_key = line.key;
    out.direction = direction;
    out.bit = line.bit;
    out.chip = line.chip;
    out.line_name = line.line_name;
    out.offset = line.offset;
    out.active_low = line.active_low;
    out.bias = static_cast<hal::gpiod::Bias>(line.bias);
    out.latch = line.latch == config::GpioLatch::active ? hal::gpiod::Latch::active
                                                         : hal::gpiod::Latch::inactive;
    params.lines.push_back(std::move(out));
  };
  for (const config::GpioLineConfig& line : device.gpio.inputs) {
    add(line, hal::gpiod::Direction::input);
  }
  for (const config::GpioLineConfig& line : device.gpio.outputs) {
    add(line, hal::gpiod::Direction::output);
  }
  return params;
}

hal::libusb::UsbDeviceParams usb_params_from(const config::SceneConfig& scene) {
  const config::DeviceConfig& device = scene.device;
  const config::UsbConfig& usb = device.usb;
  hal::libusb::UsbDeviceParams params;
  params.name = device.name;
  params.vendor_id = usb.vendor_id;
  params.product_id = usb.product_id;
  params.serial = usb.serial;
  params.protocol_version = usb.protocol_version;
  params.min_firmware_version = usb.min_firmware_version;
  params.watchdog_ms = usb.watchdog_ms;
  params.stale_limit_cycles = usb.stale_limit_cycles;
  params.control_timeout_ns = usb.control_timeout_ns;
  params.start_timeout_ns = usb.start_timeout_ns;
  params.stop_timeout_ns = usb.stop_timeout_ns;
  params.event_poll_ns = usb.event_poll_ns;
  params.loop_period_ns = scene.loop.period_ns;
  for (std::size_t i = 0; i < device.instruments.size(); ++i) {
    const config::InstrumentDeviceConfig& instrument = device.instruments[i];
    for (std::size_t j = 0; j < instrument.joints.size(); ++j) {
      const std::string joint_name(config::to_string(static_cast<config::JointId>(j)));
      hal::libusb::UsbChannelParams channel;
      channel.channel_name = instrument.name + "." + joint_name;
      channel.config_key = "instrument[" + std::to_string(i) + "]." + joint_name;
      channel.scale = config::joint_scale(instrument.joints[j]);
      params.channels.push_back(std::move(channel));
    }
  }
  return params;
}

std::unique_ptr<hal::Device> with_digital_io(const config::DeviceConfig& device,
                                             std::unique_ptr<hal::Device> motion) {
  if (device.digital_io != config::DigitalIo::gpio) return motion;
  return std::make_unique<hal::CompositeDevice>(
      device.name, std::move(motion),
      std::make_unique<hal::gpiod::GpioDevice>(gpio_params_from(device)));
}

core::Expected<std::unique_ptr<hal::Device>> make_hardware_device(
    const config::SceneConfig& scene, core::Clock& clock) {
  const config::DeviceConfig& device = scene.device;
  if (device.backend == "canopen") {
    return with_digital_io(
        device, std::make_unique<hal::socketcan::CanopenDevice>(clock, canopen_params_from(scene)));
  }
  if (device.backend == "usb") {
    return with_digital_io(device,
                           std::make_unique<hal::libusb::UsbDevice>(clock, usb_params_from(scene)));
  }
  return core::make_error(device.source_path.string() + ": backend '" + device.backend +
                          "' has no hardware device in this build");
}

}  // namespace trainer::app
