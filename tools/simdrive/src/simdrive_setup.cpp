#include "simdrive_setup.hpp"

#include "trainer/app/device_wiring.hpp"

#include <algorithm>
#include <charconv>
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
  for (hal::sim::SimInstrumentParams& instrument : params.plant.instruments) {
    for (hal::JointScale& scale : instrument.scales) {
      scale.encoder_direction = 1;
      scale.motor_direction = 1;
    }
  }
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
      node.scale.encoder_direction = 1;  // the simulated wiring is right unless miswired
      node.scale.motor_direction = 1;
      node.sdo_timeout_ns =
          std::max<std::int64_t>(device.canopen.sdo_timeout_ns * 10, 1'000'000'000);
      params.nodes.push_back(std::move(node));
    }
  }
  return params;
}

namespace {

bool parse_node_number(std::string_view text, std::uint8_t& out) {
  int value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc{} || end != text.data() + text.size() || value < 1 || value > 127)
    return false;
  out = static_cast<std::uint8_t>(value);
  return true;
}

}  // namespace

core::Expected<void> parse_miswire(std::string_view text, Miswiring& out) {
  const std::string quoted = "--miswire '" + std::string(text) + "': ";
  const std::size_t colon = text.find(':');
  const std::string_view kind = text.substr(0, colon);
  const std::string_view rest = colon == std::string_view::npos ? std::string_view{} : text.substr(colon + 1);
  std::uint8_t node = 0;
  if (rest.substr(0, 5) != "node=" || !parse_node_number(rest.substr(5), node)) {
    return core::make_error(quoted + "expected KIND:node=N with N a node id 1..127");
  }
  if (kind == "reverse_encoder") {
    out.reverse_encoder.push_back(node);
  } else if (kind == "reverse_motor") {
    out.reverse_motor.push_back(node);
  } else {
    return core::make_error(quoted + "unknown kind '" + std::string(kind) +
                            "': expected reverse_encoder or reverse_motor");
  }
  return {};
}

core::Expected<void> parse_node_id_map(std::string_view text, Miswiring& out) {
  const std::size_t equals = text.find('=');
  std::uint8_t from = 0;
  std::uint8_t to = 0;
  if (equals == std::string_view::npos || !parse_node_number(text.substr(0, equals), from) ||
      !parse_node_number(text.substr(equals + 1), to)) {
    return core::make_error("--node-id-map '" + std::string(text) +
                            "': expected FILE_ID=BUS_ID, both node ids 1..127 (e.g. 3=13)");
  }
  out.node_id_map.emplace_back(from, to);
  return {};
}

core::Expected<void> apply_miswiring(const Miswiring& miswiring, sd::SimDriveBusParams& params) {
  const auto find = [&](std::uint8_t id) -> sd::SimDriveNodeParams* {
    for (sd::SimDriveNodeParams& node : params.nodes) {
      if (node.node_id == id) return &node;
    }
    return nullptr;
  };
  const auto missing = [](const char* what, std::uint8_t id) {
    return core::make_error(std::string(what) + ": node " + std::to_string(id) +
                            " is not a drive of the device file");
  };
  for (const std::uint8_t id : miswiring.reverse_encoder) {
    sd::SimDriveNodeParams* node = find(id);
    if (node == nullptr) return missing("--miswire reverse_encoder", id);
    node->reverse_encoder = true;
  }
  for (const std::uint8_t id : miswiring.reverse_motor) {
    sd::SimDriveNodeParams* node = find(id);
    if (node == nullptr) return missing("--miswire reverse_motor", id);
    node->reverse_motor = true;
  }
  // All lookups by the file's ids first, then the renames (so 1=2 2=1 swaps two drives).
  std::vector<std::pair<sd::SimDriveNodeParams*, std::uint8_t>> renames;
  for (const auto& [from, to] : miswiring.node_id_map) {
    sd::SimDriveNodeParams* node = find(from);
    if (node == nullptr) return missing("--node-id-map", from);
    renames.emplace_back(node, to);
  }
  for (const auto& [node, to] : renames) node->node_id = to;
  for (std::size_t i = 0; i < params.nodes.size(); ++i) {
    for (std::size_t j = i + 1; j < params.nodes.size(); ++j) {
      if (params.nodes[i].node_id == params.nodes[j].node_id) {
        return core::make_error("--node-id-map: two drives would answer as node " +
                                std::to_string(params.nodes[i].node_id));
      }
    }
  }
  if (params.digital_inputs_node > 0 || params.digital_outputs_node > 0) {
    for (const auto& [from, to] : miswiring.node_id_map) {
      if (params.digital_inputs_node == from) params.digital_inputs_node = to;
      if (params.digital_outputs_node == from) params.digital_outputs_node = to;
    }
  }
  return {};
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
