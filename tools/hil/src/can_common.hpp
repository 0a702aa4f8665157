// What the CAN part's scan and check share: the device file's drives in channel order, number
// formatting.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "trainer/config/device.hpp"

namespace trainer::hil::can {

inline constexpr std::uint16_t kObjectSoftwareVersion = 0x100A;  // visible string, optional

struct FileDrive {
  std::size_t channel = 0;   // instrument * 5 + joint: the master's drive order
  std::string axis;          // "left.pitch"
  std::string instrument;    // "left"
  std::string joint_name;    // "pitch"
  std::string key;           // "instrument[0].pitch": how the loader's messages name the table
  config::JointConfig joint;
  config::CanopenJointConfig config;
};

inline std::vector<FileDrive> file_drives(const config::DeviceConfig& device) {
  std::vector<FileDrive> out;
  for (std::size_t i = 0; i < device.instruments.size(); ++i) {
    const config::InstrumentDeviceConfig& instrument = device.instruments[i];
    for (std::size_t j = 0; j < config::kJointCount; ++j) {
      const config::JointConfig& joint = instrument.joints[j];
      if (joint.canopen.node_id == 0) continue;
      FileDrive drive;
      drive.channel = i * config::kJointCount + j;
      drive.instrument = instrument.name;
      drive.joint_name = std::string(config::to_string(static_cast<config::JointId>(j)));
      drive.axis = instrument.name + "." + drive.joint_name;
      drive.key = "instrument[" + std::to_string(i) + "]." + drive.joint_name;
      drive.joint = joint;
      drive.config = joint.canopen;
      out.push_back(std::move(drive));
    }
  }
  return out;
}

inline std::string hex32(std::uint32_t value) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%08X", value);
  return text;
}

inline std::string hex16(std::uint32_t value) {
  char text[8];
  std::snprintf(text, sizeof text, "0x%04X", value & 0xFFFFU);
  return text;
}

inline std::string hex8(std::uint32_t value) {
  char text[8];
  std::snprintf(text, sizeof text, "0x%02X", value & 0xFFU);
  return text;
}

inline std::string format_double(double value, const char* format = "%.4g") {
  char text[64];
  std::snprintf(text, sizeof text, format, value);
  return text;
}

}  // namespace trainer::hil::can
