// hil scan, GPIO: a constructed listing (what libgpiod would report) compared with the bench
// VM's device file (config/devices/gpio_sim_bench.toml): every kind of mismatch is a failed
// step with the line named, a good bench passes.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "trainer/config/device.hpp"
#include "trainer/hil/io_parts.hpp"

namespace trainer::hil {
namespace {

config::DeviceConfig bench_device() {
  auto loaded = config::load_device(std::string(TRAINER_SOURCE_DIR) +
                                    "/config/devices/gpio_sim_bench.toml");
  EXPECT_TRUE(loaded.has_value()) << (loaded ? "" : loaded.error().message);
  return *loaded;
}

// gpiochip0 'pinctrl' (3 unnamed lines) and gpiochip1 'trainer-bench' as the bench VM creates it.
std::vector<GpioChipInfo> good_bench() {
  GpioChipInfo soc{"gpiochip0", "pinctrl", "/dev/gpiochip0", {}};
  for (unsigned i = 0; i < 3; ++i) soc.lines.push_back({i, "", "", false, false, false});
  GpioChipInfo sim{"gpiochip1", "trainer-bench", "/dev/gpiochip1", {}};
  const char* names[] = {"estop", "enable", "drive_enable", "fault_lamp", "spare"};
  for (unsigned i = 0; i < 5; ++i) sim.lines.push_back({i, names[i], "", false, false, false});
  return {soc, sim};
}

const StepResult& step_of(const std::vector<StepResult>& steps, const std::string& id) {
  for (const StepResult& step : steps) {
    if (step.id == id) return step;
  }
  ADD_FAILURE() << "no step " << id;
  static const StepResult none;
  return none;
}

TEST(GpioCompare, GoodBenchPassesEveryLineWithItsRole) {
  const auto steps = compare_gpio(good_bench(), bench_device());
  ASSERT_EQ(steps.size(), 4U);
  for (const StepResult& step : steps) EXPECT_EQ(step.outcome, Outcome::pass) << step.reason;
  EXPECT_EQ(steps[0].id, "gpio.scan.estop");
  EXPECT_EQ(steps[1].id, "gpio.scan.enable");
  EXPECT_EQ(steps[2].id, "gpio.scan.drive_enable");
  EXPECT_EQ(steps[3].id, "gpio.scan.fault_lamp");
  EXPECT_EQ(steps[2].details["found"], "gpiochip1:2 'drive_enable'");  // by offset 2
  EXPECT_NE(steps[0].reason.find("gpiochip1:0 'estop'"), std::string::npos) << steps[0].reason;
}

TEST(GpioCompare, ChipMissingNamesTheChipsThereAre) {
  auto chips = good_bench();
  chips.pop_back();
  const auto steps = compare_gpio(chips, bench_device());
  const StepResult& estop = step_of(steps, "gpio.scan.estop");
  EXPECT_EQ(estop.outcome, Outcome::fail);
  EXPECT_EQ(estop.reason, "no GPIO chip 'trainer-bench' (chips on this system: gpiochip0 'pinctrl')");
}

TEST(GpioCompare, LineNameMissingAndOffsetOutOfRange) {
  auto chips = good_bench();
  chips[1].lines[0].name = "estp";           // a typo in the chip's line names
  chips[1].lines.resize(2);                  // offsets 0..1 only: drive_enable (offset 2) gone
  const auto steps = compare_gpio(chips, bench_device());
  EXPECT_EQ(step_of(steps, "gpio.scan.estop").reason,
            "no line named 'estop' on gpiochip1 'trainer-bench'");
  EXPECT_EQ(step_of(steps, "gpio.scan.drive_enable").reason,
            "offset 2 out of range: gpiochip1 'trainer-bench' has offsets 0..1");
  EXPECT_EQ(step_of(steps, "gpio.scan.drive_enable").outcome, Outcome::fail);
  EXPECT_EQ(step_of(steps, "gpio.scan.enable").outcome, Outcome::pass);
  EXPECT_EQ(step_of(steps, "gpio.scan.fault_lamp").reason,
            "no line named 'fault_lamp' on gpiochip1 'trainer-bench'");
}

TEST(GpioCompare, UsedLinesAndWrongDirection) {
  auto chips = good_bench();
  chips[1].lines[0] = {0, "estop", "other-program", true, false, false};  // input, taken
  chips[1].lines[1] = {1, "enable", "enable-hog", true, true, false};     // an output hog
  chips[1].lines[3] = {3, "fault_lamp", "trainer", true, true, false};    // a running trainer
  const auto steps = compare_gpio(chips, bench_device());
  EXPECT_EQ(step_of(steps, "gpio.scan.estop").reason,
            "gpiochip1:0 'estop' already used by 'other-program' as an input");
  EXPECT_EQ(step_of(steps, "gpio.scan.enable").reason,
            "gpiochip1:1 'enable' already used by 'enable-hog' as an output: wrong direction, "
            "the device file wants an input");
  EXPECT_EQ(step_of(steps, "gpio.scan.fault_lamp").reason,
            "gpiochip1:3 'fault_lamp' already used by 'trainer' as an output (the consumer name of "
            "this device file: is a trainer running?)");
  for (const char* id : {"gpio.scan.estop", "gpio.scan.enable", "gpio.scan.fault_lamp"}) {
    EXPECT_EQ(step_of(steps, id).outcome, Outcome::fail) << id;
  }
  EXPECT_EQ(step_of(steps, "gpio.scan.drive_enable").outcome, Outcome::pass);
}

TEST(GpioCompare, FreeLineInTheOtherDirectionPassesWithANote) {
  auto chips = good_bench();
  chips[1].lines[2].output = false;  // drive enable currently an input, free
  const auto steps = compare_gpio(chips, bench_device());
  const StepResult& step = step_of(steps, "gpio.scan.drive_enable");
  EXPECT_EQ(step.outcome, Outcome::pass);
  EXPECT_NE(step.reason.find("now an input (the trainer requests it as an output)"),
            std::string::npos) << step.reason;
}

TEST(GpioCompare, TheSameLineTwiceAndChipByNameOrPath) {
  auto device = bench_device();
  device.gpio.outputs[1].line_name.clear();
  device.gpio.outputs[1].offset = 2;           // the fault lamp on the drive-enable line
  device.gpio.outputs[1].chip = "gpiochip1";   // by name
  device.gpio.inputs[1].chip = "/dev/gpiochip1";  // by path
  const auto steps = compare_gpio(good_bench(), device);
  EXPECT_EQ(step_of(steps, "gpio.scan.fault_lamp").reason,
            "gpiochip1:2 'drive_enable' is the same line as gpio.output[0]");
  EXPECT_EQ(step_of(steps, "gpio.scan.enable").outcome, Outcome::pass);
  // Label lookup does not match a chip's name, and vice versa.
  EXPECT_EQ(find_gpio_chip(good_bench(), "gpiochip1")->label, "trainer-bench");
  EXPECT_EQ(find_gpio_chip(good_bench(), "trainer-bench")->name, "gpiochip1");
  EXPECT_EQ(find_gpio_chip(good_bench(), "gpiochip7"), nullptr);
}

TEST(GpioCompare, ScanSectionListsChipsAndLinesAndSkipsWithoutGpioTable) {
  const auto chips = good_bench();
  const ScanSection none = make_gpio_scan_section(chips, std::nullopt);
  EXPECT_EQ(none.part, "gpio");
  EXPECT_EQ(none.found.size(), 2U + 3U + 5U);
  EXPECT_TRUE(none.comparison.empty());
  EXPECT_EQ(none.found[4].name, "gpiochip1");
  EXPECT_EQ(none.found[5].name, "gpiochip1:0 'estop'");
  EXPECT_EQ(none.found[5].properties["direction"], "input");
  auto device = bench_device();
  device.digital_io = config::DigitalIo::backend;
  const ScanSection skipped = make_gpio_scan_section(chips, device);
  ASSERT_EQ(skipped.comparison.size(), 1U);
  EXPECT_EQ(skipped.comparison[0].outcome, Outcome::skip);
  const ScanSection compared = make_gpio_scan_section(chips, bench_device());
  ASSERT_EQ(compared.comparison.size(), 4U);
  EXPECT_EQ(compared.comparison[0].outcome, Outcome::pass);
}

}  // namespace
}  // namespace trainer::hil
