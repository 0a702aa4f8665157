// An instrument's trocar geometry as its device file gives it (trainer frame, SI), in the float
// the cycle's kinematics uses. The app's instrument rigs and the tests build it the same way.
#pragma once

#include "trainer/config/device.hpp"
#include "trainer/kinematics/trocar_kinematics.hpp"

namespace trainer::app {

kinematics::TrocarGeometry trocar_geometry(const config::InstrumentDeviceConfig& device);

}  // namespace trainer::app
