// UsbDevice's setup path where no device is needed: parameter checks before libusb is touched,
// and the "not found" message when the bus has no such device (this machine has no USB at
// all; in the bench VM the gadget tests cover the found case). RT calls on a device that was
// never configured are refused with a status, not a crash.
#include "trainer/hal_libusb/usb_device.hpp"

#include <gtest/gtest.h>

#include <array>
#include <string>

namespace trainer::hal::libusb {
namespace {

UsbDeviceParams two_channels() {
  UsbDeviceParams params;
  params.name = "usb-test";
  params.serial = "no-such-serial-4711";
  params.vendor_id = 0x1209;
  params.product_id = 0x0001;
  params.loop_period_ns = 1'000'000;
  params.watchdog_ms = 20;
  for (const char* joint : {"pitch", "yaw"}) {
    UsbChannelParams channel;
    channel.channel_name = std::string("left.") + joint;
    channel.config_key = std::string("instrument[0].") + joint;
    channel.scale.counts_per_rev = 4096;
    channel.scale.gear_ratio = 15.0;
    channel.scale.torque_constant_nm_per_a = 0.03;
    channel.scale.current_limit_a = 3.0;
    params.channels.push_back(channel);
  }
  return params;
}

TEST(UsbDeviceSetup, AWatchdogShorterThanTwoPeriodsIsRefused) {
  core::ManualClock clock;
  UsbDeviceParams params = two_channels();
  params.loop_period_ns = 16'000'000;
  UsbDevice device(clock, params);
  const auto configured = device.configure();
  ASSERT_FALSE(configured);
  EXPECT_NE(configured.error().message.find(
                "usb.watchdog_ms = 20 is shorter than two loop periods (16000 us each)"),
            std::string::npos)
      << configured.error().message;
  EXPECT_EQ(device.state(), hal::LifecycleState::unconfigured);
}

TEST(UsbDeviceSetup, TooManyChannelsAreRefused) {
  core::ManualClock clock;
  UsbDeviceParams params = two_channels();
  while (params.channels.size() <= proto::kMaxChannels) params.channels.push_back(params.channels[0]);
  UsbDevice device(clock, params);
  const auto configured = device.configure();
  ASSERT_FALSE(configured);
  EXPECT_NE(configured.error().message.find("17 channels, expected 1..16"), std::string::npos)
      << configured.error().message;
}

TEST(UsbDeviceSetup, NoSuchDeviceNamesWhatWasWantedAndWhatIsThere) {
  core::ManualClock clock;
  UsbDevice device(clock, two_channels());
  const auto configured = device.configure();
  ASSERT_FALSE(configured);
  const std::string& message = configured.error().message;
  EXPECT_NE(message.find("usb-test: no USB device 1209:0001 serial \"no-such-serial-4711\" "
                         "(usb.vendor_id, usb.product_id, usb.serial); found: "),
            std::string::npos)
      << message;
  EXPECT_EQ(device.state(), hal::LifecycleState::unconfigured);
  // Nothing configured: RT calls are refused, lifecycle calls are safe.
  std::array<hal::EncoderSample, 2> samples{};
  std::array<hal::ActuatorCommand, 2> commands{};
  std::array<hal::ActuatorStatus, 2> status{};
  std::uint32_t levels = 0;
  EXPECT_EQ(device.read_encoders(samples), hal::ReturnCode::error);
  EXPECT_EQ(device.write_actuators(commands), hal::ReturnCode::error);
  EXPECT_EQ(device.read_actuator_status(status), hal::ReturnCode::error);
  EXPECT_EQ(device.read_digital_inputs(levels), hal::ReturnCode::error);
  EXPECT_FALSE(device.activate());
  device.deactivate();
  EXPECT_EQ(device.state(), hal::LifecycleState::unconfigured);
}

}  // namespace
}  // namespace trainer::hal::libusb
