#include "stages/instrument_rig.hpp"

#include "stages/vector_config.hpp"
#include "trainer/app/force_command.hpp"
#include "trainer/app/instrument_geometry.hpp"

namespace trainer::app {

kinematics::TrocarGeometry trocar_geometry(const config::InstrumentDeviceConfig& device) {
  kinematics::TrocarGeometry geometry;
  geometry.pivot_m = to_vec3(device.trocar_position_m);
  geometry.shaft_axis = to_vec3(device.shaft_axis);
  geometry.up_axis = to_vec3(device.up_axis);
  geometry.shaft_length_m = static_cast<float>(device.shaft_length_m);
  geometry.jaw_length_m = static_cast<float>(device.jaw_length_m);
  return geometry;
}

core::Expected<std::span<InstrumentRig>> make_instrument_rigs(const config::SceneConfig& scene,
                                                              core::Arena& arena) {
  auto rigs = arena.allocate_array<InstrumentRig>(scene.instruments.size(), "instrument state");
  if (!rigs) return std::move(rigs).error();
  for (std::size_t i = 0; i < scene.instruments.size(); ++i) {
    const std::size_t device_index = scene.instruments[i].device_instrument;
    const config::InstrumentDeviceConfig& device = scene.device.instruments[device_index];
    InstrumentRig& rig = (*rigs)[i];
    rig.kinematics = kinematics::TrocarKinematics(trocar_geometry(device));
    rig.first_channel = device_index * kinematics::kJointCount;
    for (std::size_t j = 0; j < kinematics::kJointCount; ++j) {
      rig.kinds[j] = device.joints[j].kind;
      rig.effort_limits[j] = effort_limit(config::joint_scale(device.joints[j]));
    }
  }
  return rigs;
}

}  // namespace trainer::app
