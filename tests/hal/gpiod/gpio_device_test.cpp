// GpioDevice over a scripted LineIo: bits in and out, the latch of short pulses (events between
// two reads), claim failures passed on, lifecycle (outputs inactive before release), no heap.
#include <gtest/gtest.h>

#include <array>
#include <deque>
#include <memory>
#include <string>
#include <vector>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/hal_gpiod/gpio_device.hpp"

namespace trainer::hal::gpiod {
namespace {

// What the kernel would show: each input's level and its pending-event count; the outputs'
// levels as last written; a journal of calls.
struct ScriptedLines {
  std::array<bool, kMaxLines> level{};
  std::array<int, kMaxLines> pending_events{};
  std::array<std::uint8_t, kMaxLines> outputs{};
  bool claimed = false;
  bool fail_claim = false;
  bool fail_read = false;
  std::vector<std::string> journal;
  int writes = 0;

  // The line changes to `active`: one event, as the kernel queues it.
  void set(std::size_t index, bool active) {
    if (level[index] != active) ++pending_events[index];
    level[index] = active;
  }
};

class ScriptedLineIo final : public LineIo {
 public:
  explicit ScriptedLineIo(ScriptedLines& lines) : lines_(lines) {}
  core::Expected<void> claim(std::span<const LineParams> lines,
                             std::string_view consumer) override {
    if (lines_.fail_claim) {
      return core::make_error(lines[0].config_key + ": " + describe_line(lines[0]) +
                              ": already used by 'other' as an input");
    }
    lines_.journal.push_back("claim " + std::string(consumer));
    lines_.claimed = true;
    lines_.outputs.fill(0);
    return {};
  }
  ReturnCode sample_input(std::size_t index, bool& active, bool& changed) noexcept override {
    if (lines_.fail_read) return ReturnCode::error;
    active = lines_.level[index];
    changed = lines_.pending_events[index] > 0;
    lines_.pending_events[index] = 0;
    return ReturnCode::ok;
  }
  ReturnCode write_outputs(std::span<const std::uint8_t, kMaxLines> levels) noexcept override {
    for (std::size_t i = 0; i < kMaxLines; ++i) lines_.outputs[i] = levels[i];
    ++lines_.writes;
    return ReturnCode::ok;
  }
  void release() noexcept override {
    lines_.journal.push_back(std::string("release outputs ") +
                             (lines_.outputs[2] != 0 || lines_.outputs[3] != 0 ? "high" : "low"));
    lines_.claimed = false;
  }

 private:
  ScriptedLines& lines_;
};

LineParams input(std::string key, int bit, std::string name, Latch latch = Latch::active) {
  LineParams line;
  line.config_key = std::move(key);
  line.direction = Direction::input;
  line.bit = bit;
  line.chip = "bench";
  line.line_name = std::move(name);
  line.latch = latch;
  return line;
}

LineParams output(std::string key, int bit, int offset) {
  LineParams line;
  line.config_key = std::move(key);
  line.direction = Direction::output;
  line.bit = bit;
  line.chip = "gpiochip0";
  line.offset = offset;
  return line;
}

// Lines 0 e-stop (input bit 0), 1 enable (input bit 1, latches inactive), 2 drive enable
// (output bit 0), 3 fault lamp (output bit 1).
GpioDeviceParams bench_params() {
  GpioDeviceParams params;
  params.name = "bench";
  params.consumer = "trainer-test";
  params.lines = {input("gpio.input[0]", 0, "estop"),
                  input("gpio.input[1]", 1, "enable", Latch::inactive),
                  output("gpio.output[0]", 0, 2), output("gpio.output[1]", 1, 3)};
  return params;
}

struct Bench {
  ScriptedLines lines;
  GpioDevice device{bench_params(), std::make_unique<ScriptedLineIo>(lines)};
  std::uint32_t read() {
    std::uint32_t levels = 0xFFFF'FFFF;
    EXPECT_EQ(device.read_digital_inputs(levels), ReturnCode::ok);
    return levels;
  }
};

TEST(GpioDevice, ClaimsAtConfigureAndMapsBits) {
  Bench bench;
  ASSERT_TRUE(bench.device.configure());
  EXPECT_TRUE(bench.lines.claimed);
  EXPECT_EQ(bench.device.digital_input_count(), 2U);
  EXPECT_EQ(bench.device.digital_output_count(), 2U);
  ASSERT_TRUE(bench.device.activate());
  EXPECT_EQ(bench.read(), 0U);
  bench.lines.set(1, true);  // enable held
  EXPECT_EQ(bench.read(), 0U) << "a line that changed reports its latch level (enable: released)";
  EXPECT_EQ(bench.read(), 2U);
  bench.lines.set(0, true);  // e-stop pressed
  EXPECT_EQ(bench.read(), 3U);
  EXPECT_EQ(bench.read(), 3U);
  ASSERT_EQ(bench.device.write_digital_outputs(0b01), ReturnCode::ok);
  EXPECT_EQ(bench.lines.outputs[2], 1);
  EXPECT_EQ(bench.lines.outputs[3], 0);
  ASSERT_EQ(bench.device.write_digital_outputs(0b10), ReturnCode::ok);
  EXPECT_EQ(bench.lines.outputs[2], 0);
  EXPECT_EQ(bench.lines.outputs[3], 1);
}

TEST(GpioDevice, PressShorterThanAPeriodIsLatchedForOneRead) {
  Bench bench;
  ASSERT_TRUE(bench.device.configure());
  ASSERT_TRUE(bench.device.activate());
  for (int press = 0; press < 1000; ++press) {
    bench.lines.set(0, true);
    bench.lines.set(0, false);  // pressed and released between two reads
    ASSERT_EQ(bench.read() & 1U, 1U) << "press " << press;
    ASSERT_EQ(bench.read() & 1U, 0U) << "press " << press << ": one read only";
  }
  EXPECT_EQ(bench.device.stats().pulses_latched[0], 1000U);
  EXPECT_EQ(bench.device.stats().changed_reads[0], 1000U);
}

TEST(GpioDevice, ShortReleaseOfTheEnableSwitchIsLatched) {
  Bench bench;
  ASSERT_TRUE(bench.device.configure());
  ASSERT_TRUE(bench.device.activate());
  bench.lines.set(1, true);
  (void)bench.read();
  EXPECT_EQ(bench.read(), 2U);
  bench.lines.set(1, false);
  bench.lines.set(1, true);  // released and held again between two reads
  EXPECT_EQ(bench.read(), 0U) << "the dead-man release must be seen";
  EXPECT_EQ(bench.read(), 2U);
  EXPECT_EQ(bench.device.stats().pulses_latched[1], 2U);  // the first hold, this release
}

TEST(GpioDevice, EventsWhileInactiveAreDroppedAtActivate) {
  Bench bench;
  ASSERT_TRUE(bench.device.configure());
  bench.lines.set(0, true);
  bench.lines.set(0, false);
  ASSERT_TRUE(bench.device.activate());
  EXPECT_EQ(bench.read(), 0U);
}

TEST(GpioDevice, ReadErrorIsReported) {
  Bench bench;
  ASSERT_TRUE(bench.device.configure());
  ASSERT_TRUE(bench.device.activate());
  bench.lines.fail_read = true;
  std::uint32_t levels = 0;
  EXPECT_EQ(bench.device.read_digital_inputs(levels), ReturnCode::error);
  EXPECT_EQ(bench.device.stats().read_errors, 1U);
}

TEST(GpioDevice, DeactivateDrivesOutputsInactiveThenReleases) {
  Bench bench;
  ASSERT_TRUE(bench.device.configure());
  ASSERT_TRUE(bench.device.activate());
  ASSERT_EQ(bench.device.write_digital_outputs(0b11), ReturnCode::ok);
  bench.device.deactivate();
  ASSERT_EQ(bench.lines.journal.size(), 2U);
  EXPECT_EQ(bench.lines.journal[0], "claim trainer-test");
  EXPECT_EQ(bench.lines.journal[1], "release outputs low");
  EXPECT_FALSE(bench.lines.claimed);
  std::uint32_t levels = 0;
  EXPECT_EQ(bench.device.read_digital_inputs(levels), ReturnCode::error);
  EXPECT_EQ(bench.device.write_digital_outputs(1), ReturnCode::error);
  // An operator's restart claims again.
  ASSERT_TRUE(bench.device.activate());
  EXPECT_TRUE(bench.lines.claimed);
  EXPECT_EQ(bench.device.state(), LifecycleState::active);
}

TEST(GpioDevice, ClaimFailureNamesTheLine) {
  Bench bench;
  bench.lines.fail_claim = true;
  auto configured = bench.device.configure();
  ASSERT_FALSE(configured);
  EXPECT_EQ(configured.error().message,
            "bench: gpio.input[0]: chip 'bench' line 'estop': already used by 'other' as an input");
  EXPECT_EQ(bench.device.state(), LifecycleState::unconfigured);
}

TEST(GpioDevice, ParameterErrors) {
  {
    GpioDeviceParams params = bench_params();
    params.lines[1].bit = 0;
    ScriptedLines lines;
    GpioDevice device(params, std::make_unique<ScriptedLineIo>(lines));
    auto configured = device.configure();
    ASSERT_FALSE(configured);
    EXPECT_EQ(configured.error().message,
              "bench: gpio.input[1] (chip 'bench' line 'enable'): bit 0 is already "
              "gpio.input[0]'s");
    EXPECT_FALSE(lines.claimed);
  }
  {
    GpioDeviceParams params = bench_params();
    params.lines[2].bit = 32;
    ScriptedLines lines;
    GpioDevice device(params, std::make_unique<ScriptedLineIo>(lines));
    auto configured = device.configure();
    ASSERT_FALSE(configured);
    EXPECT_EQ(configured.error().message,
              "bench: gpio.output[0] (chip 'gpiochip0' line 2): bit 32 is not 0..31");
  }
  {
    GpioDeviceParams params = bench_params();
    while (params.lines.size() <= kMaxLines) params.lines.push_back(params.lines[0]);
    ScriptedLines lines;
    GpioDevice device(params, std::make_unique<ScriptedLineIo>(lines));
    auto configured = device.configure();
    ASSERT_FALSE(configured);
    EXPECT_EQ(configured.error().message, "bench: 17 GPIO lines: at most 16");
  }
}

TEST(GpioDevice, NoHeapOverManyCycles) {
  Bench bench;
  ASSERT_TRUE(bench.device.configure());
  ASSERT_TRUE(bench.device.activate());
  ASSERT_TRUE(core::alloc::hooks_installed());
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  std::uint32_t latched = 0;
  for (int cycle = 0; cycle < 100'000; ++cycle) {
    if (cycle % 7 == 0) {
      bench.lines.set(0, true);
      bench.lines.set(0, false);
    }
    std::uint32_t levels = 0;
    (void)bench.device.read_digital_inputs(levels);
    latched += levels & 1U;
    (void)bench.device.write_digital_outputs(static_cast<std::uint32_t>(cycle & 3));
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
  EXPECT_EQ(latched, 100'000U / 7 + 1);
}

}  // namespace
}  // namespace trainer::hal::gpiod

namespace trainer::hal::gpiod {
namespace {

// The real libgpiod path where no such chip exists (this machine has no GPIO chip; on one that
// has, the label below still names none): configure fails naming chip and line, nothing claimed.
TEST(GpiodLineIo, MissingChipFailsConfigureNamingChipAndLine) {
  GpioDeviceParams params;
  params.name = "host";
  params.lines = {input("gpio.input[0]", 0, "estop")};
  params.lines[0].chip = "trainer-test-no-such-chip";
  GpioDevice device(params);
  auto configured = device.configure();
  ASSERT_FALSE(configured);
  EXPECT_EQ(configured.error().message.rfind(
                "host: gpio.input[0]: chip 'trainer-test-no-such-chip' line 'estop': no such GPIO "
                "chip (",
                0),
            0U)
      << configured.error().message;
  EXPECT_EQ(device.state(), LifecycleState::unconfigured);
  std::uint32_t levels = 0;
  EXPECT_EQ(device.read_digital_inputs(levels), ReturnCode::error);
  device.deactivate();  // safe in any state
}

}  // namespace
}  // namespace trainer::hal::gpiod
