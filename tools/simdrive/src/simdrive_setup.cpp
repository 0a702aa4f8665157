#include "simdrive_setup.hpp"

#include "trainer/app/device_wiring.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

namespace trainer::tools::simdrive {

namespace sd = trainer::hal::simdrive;

core::Expected<sd::SimDriveBusParams> bus_params_from(const config::DeviceConfig& device,
                                                      const std::string& trainee_script,
                                                      std::int64_t loop_period_ns,
                                                      const IdentityOverrides& overrides) {
  const std::string file = device.source_path.string();
  if (device.backend != "canopen") {
    return core::make_error(file + ": device.backend = \"" + device.backend +
                            "\": simdrive simulates the drives of a \"canopen\" device file");
  }
  if (!(overrides.rated_torque_scale > 0.0) || !std::isfinite(overrides.rated_torque_scale)) {
    return core::make_error("rated torque scale must be a positive number");
  }
  sd::SimDriveBusParams params;
  params.name = device.name;
  params.sync_period_ns =
      device.canopen.sync_period_ns > 0 ? device.canopen.sync_period_ns : loop_period_ns;
  if (params.sync_period_ns <= 0) {
    return core::make_error(file +
                            ": canopen.sync_period_us = 0 (every loop period) and no loop "
                            "period given: the plant time per SYNC is unknown");
  }
  params.digital_inputs_node = device.canopen.digital_inputs_node;
  params.digital_outputs_node = device.canopen.digital_outputs_node;
  // The plant: what the sim backend builds from the same mechanism.
  params.plant = app::sim_params_from(device, trainee_script);
  for (const config::InstrumentDeviceConfig& instrument : device.instruments) {
    for (std::size_t j = 0; j < instrument.joints.size(); ++j) {
      const config::JointConfig& joint = instrument.joints[j];
      const config::CanopenJointConfig& drive = joint.canopen;
      sd::SimDriveNodeParams node;
      node.node_id = drive.node_id;
      const std::string joint_name(config::to_string(static_cast<config::JointId>(j)));
      node.device_name = ("simdrive " + instrument.name + "." + joint_name).substr(0, 32);
      node.identity.vendor_id = overrides.vendor_id.value_or(drive.vendor_id);
      node.identity.product_code = overrides.product_code.value_or(drive.product_code);
      node.identity.revision = drive.revision.value_or(1);
      node.identity.serial_number = drive.node_id;
      const double rated_mnm = drive.motor_rated_torque_nm * 1e3 * overrides.rated_torque_scale;
      node.motor_rated_torque_mnm =
          static_cast<std::uint32_t>(std::clamp(std::lround(rated_mnm), 1L, 0xFFFFFFFFL));
      node.scale = config::joint_scale(joint);
      node.sdo_timeout_ns =
          std::max<std::int64_t>(device.canopen.sdo_timeout_ns * 10, 1'000'000'000);
      params.nodes.push_back(std::move(node));
    }
  }
  return params;
}

core::Expected<config::SceneConfig> load_scene_with_device(
    const std::filesystem::path& scene_file,
    const std::optional<std::filesystem::path>& device_file) {
  // As the trainer's --device: the scene is checked against the replacing device file.
  config::LoadOptions options;
  options.device_file = device_file;
  auto scene = config::load_scene(scene_file, options);
  if (!scene) return std::move(scene).error();
  if (scene->device.backend != "canopen") {
    return core::make_error(scene->device.source_path.string() + ": device.backend = \"" +
                            scene->device.backend +
                            "\": simdrive simulates the drives of a \"canopen\" device file (give "
                            "one with --device, e.g. config/devices/canopen_vcan.toml)");
  }
  return scene;
}

}  // namespace trainer::tools::simdrive
