#include "trainer/app/sim_wiring.hpp"

namespace trainer::app {

hal::sim::SimDeviceParams sim_params_from(const config::SceneConfig& scene) {
  const config::DeviceConfig& device = scene.device;
  hal::sim::SimDeviceParams params;
  params.name = device.name;
  params.plant_substep_ns = device.plant_substep_ns;
  params.digital.estop_input_bit = device.digital.estop_input_bit;
  params.digital.enable_input_bit = device.digital.enable_input_bit;
  params.script = scene.trainee.script;
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
