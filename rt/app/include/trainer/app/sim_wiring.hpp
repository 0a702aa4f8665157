// Turns a scene's device description into the simulated device's parameters. Only the app
// names concrete backends; this is where the simulated one is wired.
#pragma once

#include "trainer/config/scene.hpp"
#include "trainer/hal_sim/sim_device.hpp"

namespace trainer::app {

hal::sim::SimDeviceParams sim_params_from(const config::SceneConfig& scene);

}  // namespace trainer::app
