// hil check, GPIO: the edge-to-latch bookkeeping over the trainer's own GpioDevice, with line
// events and their kernel timestamps injected through hal/gpiod's LineIo seam and a clock of
// the test's: a held press, a pulse shorter than a period, the previous release's events, a
// level seen before its event, the enable switch's release; percentiles and verdicts.
#include <gtest/gtest.h>

#include <array>
#include <memory>
#include <vector>

#include "trainer/hal_gpiod/gpio_device.hpp"
#include "trainer/hil/io_parts.hpp"

namespace trainer::hil {
namespace {

using hal::gpiod::kMaxLines;

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kUs = 1'000;

// The kernel as the seam shows it: each input's level and its queued events' timestamps.
struct TimedLines {
  std::array<bool, kMaxLines> level{};
  std::array<std::vector<std::int64_t>, kMaxLines> events{};
  void edge(std::size_t i, bool active, std::int64_t t) {
    level[i] = active;
    events[i].push_back(t);
  }
};

class TimedLineIo final : public hal::gpiod::LineIo {
 public:
  explicit TimedLineIo(TimedLines& lines) : lines_(lines) {}
  core::Expected<void> claim(std::span<const hal::gpiod::LineParams>, std::string_view) override {
    return {};
  }
  hal::ReturnCode sample_input(std::size_t i, bool& active, bool& changed) noexcept override {
    active = lines_.level[i];
    changed = !lines_.events[i].empty();
    oldest_[i] = changed ? lines_.events[i].front() : 0;
    lines_.events[i].clear();
    return hal::ReturnCode::ok;
  }
  std::int64_t oldest_event_ns(std::size_t i) const noexcept override { return oldest_[i]; }
  hal::ReturnCode write_outputs(std::span<const std::uint8_t, kMaxLines>) noexcept override {
    return hal::ReturnCode::ok;
  }
  void release() noexcept override {}

 private:
  TimedLines& lines_;
  std::array<std::int64_t, kMaxLines> oldest_{};
};

class EdgeLatch : public ::testing::Test {
 protected:
  void SetUp() override {
    hal::gpiod::GpioDeviceParams params;
    params.name = "hil";
    hal::gpiod::LineParams estop;
    estop.config_key = "gpio.input[0]";
    estop.bit = 0;
    estop.chip = "bench";
    estop.line_name = "estop";
    hal::gpiod::LineParams enable = estop;
    enable.config_key = "gpio.input[1]";
    enable.bit = 1;
    enable.line_name = "enable";
    enable.latch = hal::gpiod::Latch::inactive;
    params.lines = {estop, enable};
    device_ = std::make_unique<hal::gpiod::GpioDevice>(params, std::make_unique<TimedLineIo>(lines_));
    ASSERT_TRUE(device_->configure().has_value());
    ASSERT_TRUE(device_->activate().has_value());
  }

  // One read of line `index` at `t` (returning 50 us later), as hil's reader makes it.
  LatchRead read_at(std::int64_t t, std::size_t index = 0, bool interest_when_set = true) {
    const std::uint64_t before = device_->stats().changed_reads[index];
    std::uint32_t levels = 0;
    EXPECT_EQ(device_->read_digital_inputs(levels), hal::ReturnCode::ok);
    LatchRead read;
    read.start_ns = t;
    read.done_ns = t + 50 * kUs;
    read.reported_active = (((levels >> index) & 1U) != 0) == interest_when_set;
    if (device_->stats().changed_reads[index] != before) {
      read.event_ns = device_->stats().last_change_event_ns[index];
    }
    return read;
  }

  TimedLines lines_;
  std::unique_ptr<hal::gpiod::GpioDevice> device_;
  EdgeLatchMeter meter_;
};

TEST_F(EdgeLatch, HeldPressIsTimedFromItsEdgeToTheReadThatReportedIt) {
  EXPECT_FALSE(meter_.on_read(read_at(1 * kMs)));
  EXPECT_FALSE(meter_.on_read(read_at(2 * kMs)));
  EXPECT_TRUE(meter_.quiet());
  meter_.arm(2500 * kUs);
  EXPECT_FALSE(meter_.on_read(read_at(3 * kMs)));
  lines_.edge(0, true, 3300 * kUs);
  ASSERT_TRUE(meter_.on_read(read_at(4 * kMs)));
  const LatchTrial& t = meter_.trial();
  EXPECT_EQ(t.edge_ns, 3300 * kUs);
  EXPECT_EQ(t.latch_ns, 4050 * kUs);
  EXPECT_EQ(t.edge_to_latch_ns(), 750 * kUs);
  EXPECT_EQ(t.reads, 2);
  EXPECT_FALSE(t.level_before_event);
  EXPECT_FALSE(meter_.armed());
  EXPECT_FALSE(meter_.quiet());
  // Still held: no new trial; released: quiet after two reads.
  EXPECT_FALSE(meter_.on_read(read_at(5 * kMs)));
  lines_.edge(0, false, 5500 * kUs);
  EXPECT_FALSE(meter_.on_read(read_at(6 * kMs)));  // the release's event: latched active once more
  EXPECT_FALSE(meter_.quiet());
  EXPECT_FALSE(meter_.on_read(read_at(7 * kMs)));
  EXPECT_FALSE(meter_.on_read(read_at(8 * kMs)));
  EXPECT_TRUE(meter_.quiet());
}

TEST_F(EdgeLatch, PressShorterThanAPeriodIsLatchedByTheNextRead) {
  meter_.on_read(read_at(1 * kMs));
  meter_.arm(1500 * kUs);
  lines_.edge(0, true, 1700 * kUs);
  lines_.edge(0, false, 1900 * kUs);  // released before the read: the level reads 0
  ASSERT_TRUE(meter_.on_read(read_at(2 * kMs)));
  EXPECT_EQ(meter_.trial().edge_to_latch_ns(), 350 * kUs);
  EXPECT_EQ(device_->stats().pulses_latched[0], 1U);  // seen only through its events
}

TEST_F(EdgeLatch, EventsOlderThanTheArmingAreNotThePress) {
  meter_.on_read(read_at(1 * kMs));
  lines_.edge(0, false, 1200 * kUs);  // a late event of the previous release ...
  meter_.arm(1500 * kUs);
  // ... drained by a read that reports the e-stop (latched active) although no press began:
  // not the press, its timestamp is before the arming.
  EXPECT_FALSE(meter_.on_read(read_at(2 * kMs)));
  EXPECT_FALSE(meter_.on_read(read_at(3 * kMs)));
  lines_.edge(0, true, 3400 * kUs);
  ASSERT_TRUE(meter_.on_read(read_at(4 * kMs)));
  EXPECT_EQ(meter_.trial().edge_ns, 3400 * kUs);
  EXPECT_EQ(meter_.trial().latch_ns, 4050 * kUs);
  EXPECT_FALSE(meter_.trial().level_before_event);
  EXPECT_EQ(meter_.stale_reports(), 1);
}

TEST_F(EdgeLatch, LevelReadBeforeTheKernelQueuedTheEdge) {
  meter_.on_read(read_at(1 * kMs));
  meter_.arm(1100 * kUs);
  lines_.level[0] = true;  // the level is there, the IRQ thread has not run yet
  EXPECT_FALSE(meter_.on_read(read_at(2 * kMs)));
  lines_.events[0].push_back(1800 * kUs);  // queued late, with the edge's time
  ASSERT_TRUE(meter_.on_read(read_at(3 * kMs)));
  const LatchTrial& t = meter_.trial();
  EXPECT_TRUE(t.level_before_event);
  EXPECT_EQ(t.latch_ns, 2050 * kUs);
  EXPECT_EQ(t.edge_ns, 1800 * kUs);
  EXPECT_EQ(t.edge_to_latch_ns(), 250 * kUs);
  EXPECT_FALSE(t.missed_by_a_read);
}

TEST_F(EdgeLatch, PulseWhoseEventCameAfterAReadIsCountedAsMissedByARead) {
  meter_.on_read(read_at(1 * kMs));
  meter_.arm(1100 * kUs);
  // A pulse at 1.5 ms, over before the 2 ms read, its event queued only after that read.
  EXPECT_FALSE(meter_.on_read(read_at(2 * kMs)));
  lines_.events[0].push_back(1500 * kUs);
  ASSERT_TRUE(meter_.on_read(read_at(3 * kMs)));
  EXPECT_TRUE(meter_.trial().missed_by_a_read);
  EXPECT_EQ(meter_.trial().edge_to_latch_ns(), 1550 * kUs);
  const LatchSummary s = summarize_latches({meter_.trial()}, 1500 * kUs, 1 * kMs);
  EXPECT_EQ(s.missed_by_a_read, 1U);
  EXPECT_EQ(s.late_reader, 0U);
  EXPECT_EQ(s.over_limit, 1U);
  // Within the time limit it passes, saying that the first read after the edge missed it.
  const StepResult step = judge_edge_to_latch("id", "t", {meter_.trial()}, 1, kMs, 5 * kMs);
  EXPECT_EQ(step.outcome, Outcome::pass);
  EXPECT_NE(step.reason.find("; 1 reported only by the second read after the edge (event queued "
                             "late)"), std::string::npos) << step.reason;
}

TEST_F(EdgeLatch, ReaderThatRanLateIsToldApart) {
  meter_.on_read(read_at(1 * kMs));
  meter_.arm(1100 * kUs);
  lines_.edge(0, true, 1200 * kUs);
  // The reader was descheduled: its next read begins at 3.5 ms.
  ASSERT_TRUE(meter_.on_read(read_at(3500 * kUs)));
  EXPECT_FALSE(meter_.trial().missed_by_a_read);
  const LatchSummary s = summarize_latches({meter_.trial()}, 1500 * kUs, 1 * kMs);
  EXPECT_EQ(s.late_reader, 1U);
  EXPECT_EQ(s.missed_by_a_read, 0U);
  StepResult step = judge_edge_to_latch("id", "t", {meter_.trial()}, 1, kMs, 1500 * kUs);
  EXPECT_EQ(step.outcome, Outcome::fail);
  EXPECT_NE(step.reason.find("(reader late) in 1, a read after the edge missed it (event queued "
                             "late) in 0"), std::string::npos) << step.reason;
}

TEST_F(EdgeLatch, ReportedWithoutAnyEdgeGivesUpAfterFiftyReads) {
  meter_.arm(0);
  lines_.level[0] = true;
  bool done = false;
  int reads = 0;
  for (; reads < 60 && !done; ++reads) done = meter_.on_read(read_at((reads + 1) * kMs));
  EXPECT_TRUE(done);
  EXPECT_EQ(reads, 51);
  EXPECT_EQ(meter_.trial().edge_ns, 0);
  EXPECT_EQ(summarize_latches({meter_.trial()}, 10 * kMs).over_limit, 1U);
}

TEST_F(EdgeLatch, EnableSwitchReleaseIsTheEventOfInterest) {
  lines_.edge(1, true, 500 * kUs);  // held: that change itself latches "released" once
  meter_.on_read(read_at(1 * kMs, 1, false));
  EXPECT_TRUE(meter_.active());
  meter_.on_read(read_at(2 * kMs, 1, false));
  EXPECT_FALSE(meter_.quiet());
  meter_.on_read(read_at(3 * kMs, 1, false));
  EXPECT_TRUE(meter_.quiet());
  meter_.arm(3100 * kUs);
  lines_.edge(1, false, 3400 * kUs);
  lines_.edge(1, true, 3600 * kUs);  // held again before the read: latched "inactive"
  ASSERT_TRUE(meter_.on_read(read_at(4 * kMs, 1, false)));
  EXPECT_EQ(meter_.trial().edge_to_latch_ns(), 650 * kUs);
}

TEST(EdgeLatchVerdict, PercentilesByNearestRank) {
  std::vector<LatchTrial> trials;
  for (std::int64_t i = 100; i >= 1; --i) trials.push_back({1, 1 + i * kUs, 1, false});
  const LatchSummary s = summarize_latches(trials, 1 * kMs);
  EXPECT_EQ(s.trials, 100U);
  EXPECT_EQ(s.p50_ns, 50 * kUs);
  EXPECT_EQ(s.p90_ns, 90 * kUs);
  EXPECT_EQ(s.p99_ns, 99 * kUs);
  EXPECT_EQ(s.max_ns, 100 * kUs);
  EXPECT_EQ(s.min_ns, 1 * kUs);
  EXPECT_EQ(s.over_limit, 0U);
}

TEST(EdgeLatchVerdict, PassFailAndTheNumbers) {
  std::vector<LatchTrial> trials;
  for (int i = 0; i < 5; ++i) trials.push_back({1 * kMs, 1 * kMs + 800 * kUs, 1, false});
  StepResult pass = judge_edge_to_latch("gpio.estop.edge_to_latch", "e-stop", trials, 5, kMs,
                                        1500 * kUs);
  EXPECT_EQ(pass.outcome, Outcome::pass) << pass.reason;
  EXPECT_EQ(pass.reason,
            "every trial latched within the limit: p50 0.80 ms, p90 0.80 ms, p99 0.80 ms, max "
            "0.80 ms over 5 trial(s); limit 1.50 ms (period 1.00 ms + margin)");
  EXPECT_EQ(pass.details["trials"].size(), 5U);
  EXPECT_EQ(pass.figures[1].name, "p50");
  EXPECT_DOUBLE_EQ(pass.figures[1].value, 0.8);

  trials[3].latch_ns = 1 * kMs + 2 * kMs;  // 2 ms: one late latch
  StepResult late = judge_edge_to_latch("gpio.estop.edge_to_latch", "e-stop", trials, 5, kMs,
                                        1500 * kUs);
  EXPECT_EQ(late.outcome, Outcome::fail);
  EXPECT_EQ(late.reason.rfind("1 of 5 latched later than the limit", 0), 0U) << late.reason;

  trials.pop_back();
  trials[3].latch_ns = 1 * kMs + 800 * kUs;
  StepResult fewer = judge_edge_to_latch("id", "t", trials, 5, kMs, 1500 * kUs);
  EXPECT_EQ(fewer.outcome, Outcome::fail);
  EXPECT_EQ(fewer.reason.rfind("only 4 of 5 trials completed", 0), 0U) << fewer.reason;

  EXPECT_EQ(judge_edge_to_latch("id", "t", {}, 5, kMs, 1500 * kUs).outcome, Outcome::fail);
}

}  // namespace
}  // namespace trainer::hil
