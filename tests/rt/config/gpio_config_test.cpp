// The device file's digital_io = "gpio" and [gpio] table: the repository's GPIO device files
// load, and every mistake names file, line, key, value and expectation.
#include <gtest/gtest.h>

#include <string>

#include "config_test_files.hpp"
#include "trainer/config/device.hpp"

namespace trainer::config {
namespace {

using testing::ConfigFileTest;
using testing::expect_contains;
using testing::read_text;
using testing::replace_first;
using testing::repo_path;

TEST(GpioDeviceFile, BenchVmFileLoads) {
  auto device = load_device(repo_path("config/devices/gpio_sim_bench.toml"));
  ASSERT_TRUE(device) << device.error().message;
  EXPECT_EQ(device->backend, "sim");
  EXPECT_EQ(device->digital_io, DigitalIo::gpio);
  EXPECT_EQ(device->gpio.consumer, "trainer");
  ASSERT_EQ(device->gpio.inputs.size(), 2U);
  ASSERT_EQ(device->gpio.outputs.size(), 2U);
  EXPECT_EQ(device->gpio.inputs[0].key, "gpio.input[0]");
  EXPECT_EQ(device->gpio.inputs[0].line_name, "estop");
  EXPECT_EQ(device->gpio.inputs[0].latch, GpioLatch::active);
  EXPECT_EQ(device->gpio.inputs[1].latch, GpioLatch::inactive);  // the enable bit
  EXPECT_EQ(device->gpio.outputs[0].line_name, "");
  EXPECT_EQ(device->gpio.outputs[0].offset, 2);
  EXPECT_EQ(device->gpio.outputs[1].chip, "trainer-bench");
}

TEST(GpioDeviceFile, CanopenWithGpioExampleLoads) {
  auto device = load_device(repo_path("config/devices/canopen_gpio_example.toml"));
  ASSERT_TRUE(device) << device.error().message;
  EXPECT_EQ(device->backend, "canopen");
  EXPECT_EQ(device->digital_io, DigitalIo::gpio);
  EXPECT_TRUE(device->gpio.inputs[1].active_low);
  EXPECT_EQ(device->gpio.inputs[1].bias, GpioBias::pull_up);
  EXPECT_EQ(device->canopen.digital_inputs_node, -1);
}

TEST(GpioDeviceFile, BenchVmCanopenWithGpioLoads) {
  auto device = load_device(repo_path("config/devices/canopen_vcan_gpio.toml"));
  ASSERT_TRUE(device) << device.error().message;
  EXPECT_EQ(device->backend, "canopen");
  EXPECT_EQ(device->digital_io, DigitalIo::gpio);
  EXPECT_EQ(device->canopen.interface, "vcan0");
  EXPECT_EQ(device->gpio.inputs.size() + device->gpio.outputs.size(), 4U);
}

TEST_F(ConfigFileTest, CanopenDigitalNodeWithGpioIsRefused) {
  const std::string text = read_text(repo_path("config/devices/canopen_vcan_gpio.toml"));
  const auto edited = replace_first(text, "digital_inputs_node = -1 ", "digital_inputs_node = 1 ");
  const auto path = write("devices/gpio.toml", edited.text);
  auto result = load_device(path);
  ASSERT_FALSE(result);
  expect_contains(result.error().message,
                  path.string() + ":" + std::to_string(edited.line) +
                      ": canopen.digital_inputs_node = 1: expected -1: the digital words come "
                      "from GPIO lines (device.digital_io = \"gpio\")");
}

TEST(GpioDeviceFile, DefaultIsTheBackendsOwnIo) {
  auto device = load_device(repo_path("config/devices/sim.toml"));
  ASSERT_TRUE(device) << device.error().message;
  EXPECT_EQ(device->digital_io, DigitalIo::backend);
  EXPECT_TRUE(device->gpio.inputs.empty());
}

struct GpioErrorCase {
  const char* name;
  const char* from;  // first occurrence in config/devices/gpio_sim_bench.toml is replaced
  const char* to;
  const char* expected;  // after "<file>:<line>: "
};

std::ostream& operator<<(std::ostream& stream, const GpioErrorCase& error_case) {
  return stream << error_case.name;
}

class GpioErrorTest : public ConfigFileTest, public ::testing::WithParamInterface<GpioErrorCase> {};

TEST_P(GpioErrorTest, MessageNamesFileLineKeyValueAndExpectation) {
  const GpioErrorCase& error_case = GetParam();
  const std::string text = read_text(repo_path("config/devices/gpio_sim_bench.toml"));
  const auto edited = replace_first(text, error_case.from, error_case.to);
  const auto path = write("devices/gpio.toml", edited.text);
  auto result = load_device(path);
  ASSERT_FALSE(result);
  expect_contains(result.error().message,
                  path.string() + ":" + std::to_string(edited.line) + ": " + error_case.expected);
}

const GpioErrorCase kGpioErrorCases[] = {
    {"digital_io_unknown", "digital_io = \"gpio\"", "digital_io = \"gpiod\"",
     "device.digital_io = \"gpiod\": expected one of: backend, gpio"},
    {"bit_out_of_range", "bit = 0                            # bit of the input word",
     "bit = 32 # bit of the input word",
     "gpio.input[0].bit = 32 is out of range: expected 0 to 31 (bit of the digital "
     "input word)"},
    {"bit_twice", "bit = 1\n", "bit = 0\n",
     "gpio.input[1].bit = 0 is already used by gpio.input[0].bit: expected one line per bit"},
    {"line_and_offset", "line = \"estop\"", "offset = 0\nline = \"estop\"",
     "gpio.input[0].offset = 0: expected either line (a name) or offset, not both"},
    {"offset_negative", "offset = 2 ", "offset = -1 ",
     "gpio.output[0].offset = -1 is out of range: expected 0 to 511 (line offset on the chip)"},
    {"bias_unknown", "active_low = false                 # default false",
     "bias = \"pull-sideways\"",
     "gpio.input[0].bias = \"pull-sideways\": expected one of: as-is, disable, pull-up, pull-down"},
    {"latch_unknown", "# latch = \"active\"", "latch = \"sticky\"",
     "gpio.input[0].latch = \"sticky\": expected one of: active, inactive"},
    {"estop_without_line", "estop_input_bit = 0", "estop_input_bit = 5",
     "digital.estop_input_bit = 5: digital_io = \"gpio\" but no [[gpio.input]] has bit = 5"},
    {"drive_enable_without_line", "drive_enable_output_bit = 0", "drive_enable_output_bit = 7",
     "digital.drive_enable_output_bit = 7: digital_io = \"gpio\" but no [[gpio.output]] has "
     "bit = 7"},
    {"unknown_key", "active_low = false                 # default false", "active_lo = true",
     "unknown key 'gpio.input[0].active_lo'"},
    {"consumer_too_long", "consumer = \"trainer\"",
     "consumer = \"a-consumer-name-of-32-characters\"",
     "gpio.consumer = \"a-consumer-name-of-32-characters\": expected 1..31 characters"},
};

INSTANTIATE_TEST_SUITE_P(EveryMistake, GpioErrorTest, ::testing::ValuesIn(kGpioErrorCases),
                         [](const auto& param_info) { return std::string(param_info.param.name); });

TEST_F(ConfigFileTest, GpioTableWithoutDigitalIoGpioIsUnknown) {
  const std::string text = read_text(repo_path("config/devices/gpio_sim_bench.toml"));
  const auto edited = replace_first(text, "digital_io = \"gpio\"", "digital_io = \"backend\"");
  const auto path = write("devices/gpio.toml", edited.text);
  auto result = load_device(path);
  ASSERT_FALSE(result);
  expect_contains(result.error().message, "unknown key 'gpio'");
}

TEST_F(ConfigFileTest, GpioNeedsALineNameOrOffset) {
  const std::string text = read_text(repo_path("config/devices/gpio_sim_bench.toml"));
  const auto edited = replace_first(text, "line = \"estop\"", "");
  const auto path = write("devices/gpio.toml", edited.text);
  auto result = load_device(path);
  ASSERT_FALSE(result);
  expect_contains(result.error().message, ": missing required key 'gpio.input[0].line'");
}

}  // namespace
}  // namespace trainer::config
