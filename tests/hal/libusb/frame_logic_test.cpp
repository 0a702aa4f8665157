// UsbFrameLogic without a device: IN reports made with the protocol library, fed as the event
// thread would hand them over, checked against the definitions in frame_logic.hpp.
#include "trainer/hal_libusb/frame_logic.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <vector>

#include "trainer/core/alloc_counter.hpp"

namespace trainer::hal::libusb {
namespace {

hal::JointScale revolute_scale() {
  hal::JointScale scale;
  scale.kind = hal::JointKind::revolute;
  scale.counts_per_rev = 4096;
  scale.gear_ratio = 15.0;
  scale.torque_constant_nm_per_a = 0.03;
  scale.current_limit_a = 3.0;
  return scale;
}

hal::JointScale prismatic_scale() {
  hal::JointScale scale;
  scale.kind = hal::JointKind::prismatic;
  scale.counts_per_rev = 2048;
  scale.gear_ratio = 4.0;
  scale.capstan_radius_m = 0.01;
  scale.torque_constant_nm_per_a = 0.025;
  scale.current_limit_a = 2.0;
  return scale;
}

class FrameLogicTest : public ::testing::Test {
 protected:
  void SetUp() override {
    scales_ = {revolute_scale(), revolute_scale(), prismatic_scale()};
    ASSERT_TRUE(logic_.configure(scales_, 2));
  }

  // An IN report as the event thread would publish it.
  RawInReport in(std::uint16_t sequence, std::uint16_t applied = 0, std::uint16_t status = 0,
                 std::array<std::int32_t, 3> counts = {}, std::int64_t received_ns = 0) {
    proto::InReport report;
    report.sequence = sequence;
    report.out_sequence_applied = applied;
    report.status = status;
    report.buttons = 0x5;
    report.channel_count = 3;
    for (std::size_t i = 0; i < 3; ++i) report.counts[i] = counts[i];
    RawInReport raw;
    raw.length = static_cast<std::uint16_t>(proto::encode(report, raw.bytes));
    raw.received_ns = received_ns;
    raw.index = ++index_;
    return raw;
  }

  std::vector<hal::JointScale> scales_;
  UsbFrameLogic logic_;
  std::uint64_t index_ = 0;
};

TEST_F(FrameLogicTest, ConfigureRefusesBadChannelCounts) {
  UsbFrameLogic logic;
  EXPECT_FALSE(logic.configure({}, 2));
  std::vector<hal::JointScale> many(proto::kMaxChannels + 1, revolute_scale());
  const auto refused = logic.configure(many, 2);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("expected 1..16"), std::string::npos);
  hal::JointScale zero = revolute_scale();
  zero.torque_constant_nm_per_a = 0.0;
  const std::array<hal::JointScale, 1> bad{zero};
  EXPECT_FALSE(logic.configure(bad, 2));
}

TEST_F(FrameLogicTest, CountsBecomeJointPositionsLikeTheJointScale) {
  const std::array<std::int32_t, 3> counts{12345, -4096 * 15, 2048};
  const RawInReport report = in(1, 0, 0, counts);
  logic_.on_cycle(&report);
  std::array<hal::EncoderSample, 3> samples{};
  logic_.fill_encoders(samples);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(samples[i].counts, counts[i]);
    EXPECT_FLOAT_EQ(samples[i].position,
                    static_cast<float>(scales_[i].position_from_counts(counts[i])));
    EXPECT_TRUE(samples[i].valid);
  }
  EXPECT_NEAR(samples[1].position, -2.0 * M_PI, 1e-5);  // one joint revolution backwards
  EXPECT_EQ(logic_.counters().last_buttons, 0x5);
}

TEST_F(FrameLogicTest, TwentyFourBitCountsAreUnwrapped) {
  // The device's absolute count crosses the 24-bit wire range: the host keeps counting.
  std::int64_t absolute = proto::kMaxWireCount - 30'000;
  std::uint16_t sequence = 0;
  for (int step = 0; step < 40; ++step) {
    absolute += 1000;
    const RawInReport report =
        in(++sequence, 0, 0, {proto::wire_count(absolute), 0, proto::wire_count(-absolute)});
    logic_.on_cycle(&report);
  }
  std::array<hal::EncoderSample, 3> samples{};
  logic_.fill_encoders(samples);
  // The first report starts at its wire value, which equals the absolute count here.
  EXPECT_EQ(samples[0].counts, absolute);
  EXPECT_EQ(samples[2].counts, -absolute);
}

TEST_F(FrameLogicTest, NoReportIsStaleAndTwoInARowLatchDeviceStopped) {
  const RawInReport first = in(1);
  logic_.on_cycle(&first);
  logic_.on_cycle(nullptr);  // one stale cycle is tolerated
  EXPECT_EQ(logic_.counters().stale_frames, 1U);
  EXPECT_FALSE(logic_.latched());
  const RawInReport second = in(2);
  logic_.on_cycle(&second);  // resets the run
  logic_.on_cycle(nullptr);
  EXPECT_FALSE(logic_.latched());
  logic_.on_cycle(nullptr);
  EXPECT_TRUE(logic_.latched());
  EXPECT_EQ(logic_.counters().first_fault, UsbFault::device_stopped);
  EXPECT_EQ(logic_.counters().stale_run_max, 2U);
  std::array<hal::EncoderSample, 3> samples{};
  logic_.fill_encoders(samples);
  EXPECT_FALSE(samples[0].valid);
}

TEST_F(FrameLogicTest, TheFirstCycleAfterActivateExpectsNothing) {
  const RawInReport setup = in(1);  // activate's exchange
  logic_.on_cycle(&setup);
  logic_.restart_cycle_count();
  logic_.on_cycle(nullptr);  // cycle 1: no OUT report since the restart, nothing to answer
  EXPECT_EQ(logic_.counters().stale_frames, 0U);
  RawOutReport out;
  const std::array<hal::ActuatorCommand, 3> commands{};
  ASSERT_TRUE(logic_.build_out(commands, false, 0, out));
  logic_.on_cycle(nullptr);  // cycle 2: the answer to cycle 1's OUT report is missing
  EXPECT_EQ(logic_.counters().stale_frames, 1U);
  EXPECT_EQ(logic_.counters().cycles, 2U);
}

TEST_F(FrameLogicTest, AnAnswerNotDueYetIsNotStale) {
  const RawInReport first = in(1);
  logic_.on_cycle(&first);
  logic_.on_cycle(nullptr, false);  // back-to-back after an overrun: not due
  logic_.on_cycle(nullptr, false);
  EXPECT_EQ(logic_.counters().stale_frames, 0U);
  EXPECT_EQ(logic_.counters().not_due_cycles, 2U);
  logic_.on_cycle(nullptr, true);
  logic_.on_cycle(nullptr, false);  // neither grows nor resets the run
  EXPECT_FALSE(logic_.latched());
  logic_.on_cycle(nullptr, true);
  EXPECT_TRUE(logic_.latched());
  EXPECT_EQ(logic_.counters().stale_frames, 2U);
}

TEST_F(FrameLogicTest, SameSequenceAgainIsStale) {
  const RawInReport first = in(7);
  logic_.on_cycle(&first);
  RawInReport again = first;
  again.index = ++index_;
  logic_.on_cycle(&again);
  EXPECT_EQ(logic_.counters().stale_frames, 1U);
  EXPECT_EQ(logic_.counters().in_reports_used, 1U);
  logic_.on_cycle(&again);
  EXPECT_TRUE(logic_.latched());
}

TEST_F(FrameLogicTest, GapsSplitIntoMissedOnTheBusAndSupersededOnTheHost) {
  const RawInReport a = in(10);
  logic_.on_cycle(&a);
  // Device sequence 11..13 were received by the event thread, only 13 taken: 2 superseded.
  index_ += 2;
  const RawInReport b = in(13);
  logic_.on_cycle(&b);
  EXPECT_EQ(logic_.counters().in_superseded, 2U);
  EXPECT_EQ(logic_.counters().missed_frames, 0U);
  // Device jumped 13 -> 20 but the host received only one report: 6 never arrived.
  const RawInReport c = in(20);
  logic_.on_cycle(&c);
  EXPECT_EQ(logic_.counters().missed_frames, 6U);
  EXPECT_EQ(logic_.counters().in_superseded, 2U);
  // An older sequence (half the space or more behind) is not new: stale, nothing counted.
  const RawInReport old = in(65000);
  logic_.on_cycle(&old);
  EXPECT_EQ(logic_.counters().stale_frames, 1U);
  EXPECT_EQ(logic_.counters().missed_frames, 6U);
}

TEST_F(FrameLogicTest, SequenceGapsAcrossTheWrap) {
  const RawInReport a = in(65534);
  logic_.on_cycle(&a);
  const RawInReport b = in(65535);
  logic_.on_cycle(&b);
  const RawInReport c = in(2);  // 0 and 1 never arrived
  logic_.on_cycle(&c);
  EXPECT_EQ(logic_.counters().missed_frames, 2U);
  EXPECT_EQ(logic_.counters().stale_frames, 0U);
}

TEST_F(FrameLogicTest, BadReportsAreCountedAndStale) {
  const RawInReport good = in(1);
  logic_.on_cycle(&good);
  RawInReport bad = in(2);
  bad.bytes[5] ^= 0xFF;  // breaks the CRC
  logic_.on_cycle(&bad);
  EXPECT_EQ(logic_.counters().bad_reports, 1U);
  EXPECT_EQ(logic_.counters().last_bad_status, proto::DecodeStatus::bad_checksum);
  EXPECT_EQ(logic_.counters().stale_frames, 1U);
  RawInReport short_report = in(3);
  short_report.length = 10;
  logic_.on_cycle(&short_report);
  EXPECT_EQ(logic_.counters().last_bad_status, proto::DecodeStatus::wrong_length);
  EXPECT_TRUE(logic_.latched());
}

TEST_F(FrameLogicTest, AnotherChannelCountLatches) {
  proto::InReport report;
  report.sequence = 1;
  report.channel_count = 2;
  RawInReport raw;
  raw.length = static_cast<std::uint16_t>(proto::encode(report, raw.bytes));
  raw.index = 1;
  logic_.on_cycle(&raw);
  EXPECT_EQ(logic_.counters().first_fault, UsbFault::channel_mismatch);
}

TEST_F(FrameLogicTest, AcknowledgementsMeasureTheRoundTripOnce) {
  RawOutReport out;
  const std::array<hal::ActuatorCommand, 3> commands{};
  ASSERT_TRUE(logic_.build_out(commands, false, 1'000'000, out));
  EXPECT_EQ(out.sequence, 1U);
  ASSERT_TRUE(logic_.build_out(commands, false, 2'000'000, out));
  EXPECT_EQ(out.sequence, 2U);
  const RawInReport ack1 = in(1, 1, 0, {}, 1'450'000);
  logic_.on_cycle(&ack1);
  const RawInReport ack1_again = in(2, 1, 0, {}, 1'900'000);  // same ack: not measured again
  logic_.on_cycle(&ack1_again);
  const RawInReport ack2 = in(3, 2, 0, {}, 3'200'000);
  logic_.on_cycle(&ack2);
  EXPECT_EQ(logic_.counters().acks, 2U);
  EXPECT_EQ(logic_.round_trip().count(), 2U);
  EXPECT_EQ(logic_.round_trip().min_ns(), 450'000);
  EXPECT_EQ(logic_.round_trip().max_ns(), 1'200'000);
  // The upper edge of the bin holding 450 us: core::LatencyHistogram's bins are at most 1/32
  // of their value wide.
  EXPECT_GE(logic_.round_trip().percentile_ns(0.5), 450'000);
  EXPECT_LE(logic_.round_trip().percentile_ns(0.5), 450'000 + 450'000 / 32);
  EXPECT_TRUE(logic_.acknowledged(2));
  EXPECT_TRUE(logic_.acknowledged(1));
  EXPECT_FALSE(logic_.acknowledged(3));
}

TEST_F(FrameLogicTest, EffortBecomesCurrentClippedToTheLimit) {
  RawOutReport out;
  const double per_amp = scales_[0].effort_per_amp();  // N·m per A at the joint
  const std::array<hal::ActuatorCommand, 3> commands{{
      {static_cast<float>(0.5 * per_amp), true},   // 500 mA
      {static_cast<float>(-10.0 * per_amp), true}, // beyond 3 A: clipped
      {1.0F, false},                               // disabled: 0
  }};
  ASSERT_TRUE(logic_.build_out(commands, false, 0, out));
  proto::OutReport report;
  ASSERT_EQ(proto::decode(out.bytes, report), proto::DecodeStatus::ok);
  EXPECT_EQ(report.current_ma[0], 500);
  EXPECT_EQ(report.current_ma[1], -3000);
  EXPECT_EQ(report.current_ma[2], 0);
  EXPECT_EQ(report.flags, proto::kOutFlagEnable);
  EXPECT_EQ(report.channel_count, 3U);
  // Status: applied effort only once the device says it is enabled.
  std::array<hal::ActuatorStatus, 3> status{};
  logic_.fill_status(status);
  EXPECT_FALSE(status[0].enabled);
  const RawInReport enabled = in(1, 1, proto::kStatusEnabled);
  logic_.on_cycle(&enabled);
  logic_.fill_status(status);
  EXPECT_TRUE(status[0].enabled);
  EXPECT_NEAR(status[0].applied_effort, 0.5 * per_amp, 1e-6);
  EXPECT_TRUE(status[1].saturated);
  EXPECT_NEAR(status[1].applied_effort, -3.0 * per_amp, 1e-5);
  EXPECT_FALSE(status[2].enabled);
}

// The device file's encoder_direction / motor_direction (-1: wired reversed): counts read
// negated, current sent negated, the effort read back with the joint's sign again.
TEST(FrameLogicDirections, ReversedEncoderAndMotorAreCompensated) {
  hal::JointScale reversed = revolute_scale();
  reversed.encoder_direction = -1;
  reversed.motor_direction = -1;
  const std::array<hal::JointScale, 1> scales{reversed};
  UsbFrameLogic logic;
  ASSERT_TRUE(logic.configure(scales, 2));
  const double per_amp = reversed.effort_per_amp();
  const std::array<hal::ActuatorCommand, 1> commands{{{static_cast<float>(0.5 * per_amp), true}}};
  RawOutReport out;
  ASSERT_TRUE(logic.build_out(commands, false, 0, out));
  proto::OutReport report;
  ASSERT_EQ(proto::decode(out.bytes, report), proto::DecodeStatus::ok);
  EXPECT_EQ(report.current_ma[0], -500);
  proto::InReport in_report;
  in_report.sequence = 1;
  in_report.out_sequence_applied = 1;
  in_report.status = proto::kStatusEnabled;
  in_report.channel_count = 1;
  in_report.counts[0] = 4096 * 15;  // one joint revolution on the encoder
  RawInReport raw;
  raw.length = static_cast<std::uint16_t>(proto::encode(in_report, raw.bytes));
  raw.index = 1;
  logic.on_cycle(&raw);
  std::array<hal::EncoderSample, 1> samples{};
  logic.fill_encoders(samples);
  EXPECT_NEAR(samples[0].position, -2.0 * M_PI, 1e-5) << "the encoder counts the other way";
  std::array<hal::ActuatorStatus, 1> status{};
  logic.fill_status(status);
  EXPECT_NEAR(status[0].applied_effort, 0.5 * per_amp, 1e-6);
}

TEST_F(FrameLogicTest, NonFiniteEffortSendsZeroAndReportsIt) {
  RawOutReport out;
  const std::array<hal::ActuatorCommand, 3> commands{{{NAN, true}, {0.1F, true}, {0.0F, true}}};
  EXPECT_FALSE(logic_.build_out(commands, false, 0, out));
  proto::OutReport report;
  ASSERT_EQ(proto::decode(out.bytes, report), proto::DecodeStatus::ok);
  EXPECT_EQ(report.current_ma[0], 0);
  EXPECT_NE(report.current_ma[1], 0);
}

TEST_F(FrameLogicTest, LatchedMeansZeroCurrentAndNoEnable) {
  logic_.latch(UsbFault::device_lost);
  RawOutReport out;
  const std::array<hal::ActuatorCommand, 3> commands{{{0.1F, true}, {0.1F, true}, {0.1F, true}}};
  ASSERT_TRUE(logic_.build_out(commands, false, 0, out));
  proto::OutReport report;
  ASSERT_EQ(proto::decode(out.bytes, report), proto::DecodeStatus::ok);
  EXPECT_EQ(report.flags, 0U);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(report.current_ma[i], 0);
  RawOutReport clear;
  ASSERT_TRUE(logic_.build_out(commands, true, 0, clear));
  ASSERT_EQ(proto::decode(clear.bytes, report), proto::DecodeStatus::ok);
  EXPECT_EQ(report.flags, proto::kOutFlagClearWatchdog);
}

TEST_F(FrameLogicTest, WatchdogBitIsAFaultOnlyOnceArmed) {
  const RawInReport tripped = in(1, 0, proto::kStatusWatchdogTripped);
  logic_.on_cycle(&tripped);
  EXPECT_FALSE(logic_.latched());  // left from before: activate() clears it
  logic_.arm_watchdog_check(true);
  const RawInReport again = in(2, 0, proto::kStatusWatchdogTripped);
  logic_.on_cycle(&again);
  EXPECT_EQ(logic_.counters().first_fault, UsbFault::watchdog_tripped);
  EXPECT_EQ(logic_.counters().watchdog_reports, 2U);
}

TEST_F(FrameLogicTest, NoHeapOverManyCycles) {
  std::vector<RawInReport> reports;
  for (std::uint16_t i = 1; i <= 1000; ++i) reports.push_back(in(i, i, proto::kStatusEnabled));
  RawOutReport out;
  std::array<hal::EncoderSample, 3> samples{};
  std::array<hal::ActuatorStatus, 3> status{};
  const std::array<hal::ActuatorCommand, 3> commands{{{0.1F, true}, {-0.1F, true}, {1.0F, true}}};
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (int cycle = 0; cycle < 100'000; ++cycle) {
    (void)logic_.build_out(commands, false, cycle, out);
    logic_.on_cycle(cycle % 7 == 3 ? nullptr : &reports[static_cast<std::size_t>(cycle) % 1000]);
    logic_.fill_encoders(samples);
    logic_.fill_status(status);
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
  EXPECT_TRUE(core::alloc::hooks_installed());
}

}  // namespace
}  // namespace trainer::hal::libusb
