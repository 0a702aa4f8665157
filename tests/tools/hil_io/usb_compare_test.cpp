// hil scan, USB: constructed bus listings compared with the bench VM's USB device file
// (config/devices/usb_benchvm.toml: 1209:0001 serial usbgadget-0001, protocol 1, firmware >=
// 1.0, two instruments = 10 channels); the verdicts of the polarity and watchdog steps.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "trainer/config/device.hpp"
#include "trainer/hil/io_parts.hpp"

namespace trainer::hil {
namespace {

config::DeviceConfig usb_device() {
  auto loaded = config::load_device(std::string(TRAINER_SOURCE_DIR) +
                                    "/config/devices/usb_benchvm.toml");
  EXPECT_TRUE(loaded.has_value()) << (loaded ? "" : loaded.error().message);
  return *loaded;
}

UsbFoundDevice gadget(const std::string& serial = "usbgadget-0001") {
  UsbFoundDevice d;
  d.vendor_id = 0x1209;
  d.product_id = 0x0001;
  d.bus = 1;
  d.address = 2;
  d.serial = serial;
  d.vendor_interface = 0;
  d.protocol_ids = true;
  d.identity = UsbIdentity{1, 0x0100, 10, 100, 1000, 3000};
  return d;
}

const StepResult& usb_step(const std::vector<StepResult>& steps, const std::string& id) {
  for (const StepResult& step : steps) {
    if (step.id == id) return step;
  }
  ADD_FAILURE() << "no step " << id;
  static const StepResult none;
  return none;
}

TEST(UsbCompare, TheRightInterfacePasses) {
  const auto steps = compare_usb({gadget()}, usb_device());
  ASSERT_EQ(steps.size(), 4U);
  for (const StepResult& step : steps) EXPECT_EQ(step.outcome, Outcome::pass) << step.id << ": " << step.reason;
  EXPECT_EQ(steps[0].reason, "found 1209:0001 serial usbgadget-0001 (bus 1 device 2)");
  EXPECT_EQ(steps[3].reason, "the device has 10 channels, the device file 10 joints (2 instruments x 5)");
}

TEST(UsbCompare, MissingNamesWhatIsOnTheBus) {
  auto steps = compare_usb({}, usb_device());
  ASSERT_EQ(steps.size(), 1U);
  EXPECT_EQ(steps[0].outcome, Outcome::fail);
  EXPECT_EQ(steps[0].reason,
            "no USB device 1209:0001 serial 'usbgadget-0001' (with 1209:0001 on the bus: none)");
  // Another serial: missing, and that one is an extra.
  steps = compare_usb({gadget("other-7")}, usb_device());
  ASSERT_EQ(steps.size(), 2U);
  EXPECT_EQ(steps[0].reason,
            "no USB device 1209:0001 serial 'usbgadget-0001' (with 1209:0001 on the bus: 1209:0001 "
            "serial other-7 (bus 1 device 2))");
  EXPECT_EQ(usb_step(steps, "usb.scan.extra.other-7").outcome, Outcome::fail);
}

TEST(UsbCompare, ExtraAndAmbiguous) {
  auto steps = compare_usb({gadget(), gadget("spare-2")}, usb_device());
  EXPECT_EQ(usb_step(steps, "usb.scan.device").outcome, Outcome::pass);
  EXPECT_EQ(usb_step(steps, "usb.scan.extra.spare-2").reason,
            "1209:0001 serial spare-2 (bus 1 device 2) is not in the device file (usb.serial = "
            "'usbgadget-0001'): unplug it or name it");
  auto any = usb_device();
  any.usb.serial.clear();
  steps = compare_usb({gadget(), gadget("spare-2")}, any);
  EXPECT_EQ(usb_step(steps, "usb.scan.device").outcome, Outcome::fail);
  EXPECT_EQ(usb_step(steps, "usb.scan.device").reason.rfind("2 devices 1209:0001 and usb.serial is empty", 0), 0U);
}

TEST(UsbCompare, WrongIdentity) {
  UsbFoundDevice d = gadget();
  d.identity = UsbIdentity{2, 0x00FF, 5, 100, 1000, 3000};
  const auto steps = compare_usb({d}, usb_device());
  EXPECT_EQ(usb_step(steps, "usb.scan.protocol_version").reason,
            "the device reports protocol 2, usb.protocol_version = 1");
  EXPECT_EQ(usb_step(steps, "usb.scan.firmware_version").reason,
            "firmware 0.255, usb.min_firmware_version = 1.0");
  EXPECT_EQ(usb_step(steps, "usb.scan.channels").reason,
            "the device has 5 channels, the device file 10 joints (2 instruments x 5)");
  for (const char* id : {"usb.scan.protocol_version", "usb.scan.firmware_version", "usb.scan.channels"}) {
    EXPECT_EQ(usb_step(steps, id).outcome, Outcome::fail) << id;
  }
  d.identity.reset();
  d.error = "cannot claim interface 0: LIBUSB_ERROR_BUSY (in use by another program: a trainer?)";
  const auto busy = compare_usb({d}, usb_device());
  ASSERT_EQ(busy.size(), 1U);
  EXPECT_EQ(busy[0].reason, "1209:0001 serial usbgadget-0001 (bus 1 device 2): no identity: " + d.error);
}

TEST(UsbCompare, SectionListsEveryDeviceAndSkipsAnotherBackend) {
  UsbFoundDevice other;
  other.vendor_id = 0x0403;
  other.product_id = 0x6001;
  other.vendor_interface = 0;
  const ScanSection s = make_usb_scan_section({gadget(), other}, std::nullopt);
  ASSERT_EQ(s.found.size(), 2U);
  EXPECT_EQ(s.found[0].properties["identity"]["channels"], 10);
  EXPECT_EQ(s.found[1].name, "0403:6001 (bus 0 device 0)");
  auto gpio = config::load_device(std::string(TRAINER_SOURCE_DIR) + "/config/devices/gpio_sim_bench.toml");
  ASSERT_TRUE(gpio.has_value());
  const ScanSection skipped = make_usb_scan_section({gadget()}, *gpio);
  ASSERT_EQ(skipped.comparison.size(), 1U);
  EXPECT_EQ(skipped.comparison[0].outcome, Outcome::skip);
}

TEST(UsbVerdicts, Polarity) {
  EXPECT_EQ(judge_polarity("left.pitch", 120, 2, 0.0675, "N·m").outcome, Outcome::pass);
  const StepResult reversed = judge_polarity("left.pitch", -118, 2, 0.0675, "N·m");
  EXPECT_EQ(reversed.outcome, Outcome::fail);
  EXPECT_EQ(reversed.id, "usb.left.pitch.polarity");
  EXPECT_EQ(reversed.reason, "moved -118 counts under +0.0675 N·m: encoder direction and motor "
                             "polarity disagree (reverse one of them)");
  const StepResult still = judge_polarity("left.grip", 1, 2, 0.04, "N·m");
  EXPECT_EQ(still.outcome, Outcome::fail);
  EXPECT_EQ(still.reason.rfind("no motion under +0.04 N·m: 1 counts", 0), 0U) << still.reason;
}

TEST(UsbVerdicts, Watchdog) {
  constexpr std::int64_t ms = 1'000'000;
  EXPECT_EQ(judge_watchdog(1650 * ms, 1600 * ms, 1712 * ms, 9000 * ms, 16).outcome, Outcome::pass);
  const StepResult late = judge_watchdog(1800 * ms, 1600 * ms, 1712 * ms, 9000 * ms, 16);
  EXPECT_EQ(late.outcome, Outcome::fail);
  EXPECT_EQ(late.reason, "too late: tripped 1800.0 ms after the last OUT report; watchdog 100 ms "
                         "(x16: 1600 ms real), limit 1712.0 ms");
  EXPECT_EQ(judge_watchdog(1000 * ms, 1600 * ms, 1712 * ms, 9000 * ms, 16).outcome, Outcome::fail);
  const StepResult never = judge_watchdog(-1, 20 * ms, 25 * ms, 1100 * ms, 1);
  EXPECT_EQ(never.reason, "no watchdog trip reported within 1100 ms of silence: the device keeps "
                          "its currents (watchdog 20 ms)");
}

}  // namespace
}  // namespace trainer::hil

namespace trainer::hil {
namespace {

namespace proto = trainer::hal::usbproto;

// The round-trip verdict over the backend's own per-cycle logic (UsbFrameLogic) driven with
// hand-made IN reports, as UsbDevice feeds it: answered cycles, then a device that stops
// answering for a run of cycles.
class RoundTripVerdict : public ::testing::Test {
 protected:
  void SetUp() override {
    hal::JointScale scale;
    scale.counts_per_rev = 4096;
    scale.gear_ratio = 15.0;
    scale.torque_constant_nm_per_a = 0.03;
    scale.current_limit_a = 3.0;
    scales_ = {scale};
    ASSERT_TRUE(logic_.configure(scales_, 1000).has_value());
  }

  // One cycle: the answer to the previous OUT report (or none), then the next OUT report.
  void cycle(bool answered) {
    if (answered) {
      proto::InReport report;
      report.sequence = ++in_sequence_;
      report.out_sequence_applied = logic_.last_out_sequence();
      report.channel_count = 1;
      hal::libusb::RawInReport raw;
      raw.length = static_cast<std::uint16_t>(proto::encode(report, raw.bytes));
      now_ += 2'000'000;
      raw.received_ns = now_;
      raw.index = ++index_;
      logic_.on_cycle(&raw);
      now_ += 14'000'000;
    } else {
      logic_.on_cycle(nullptr);
      now_ += 16'000'000;
    }
    hal::libusb::RawOutReport out;
    const std::array<hal::ActuatorCommand, 1> commands{};
    ASSERT_TRUE(logic_.build_out(commands, false, now_, out));
  }

  hal::libusb::UsbDiagnostics diagnostics() const {
    hal::libusb::UsbDiagnostics d;
    d.frames = logic_.counters();
    const auto& h = logic_.round_trip();
    d.round_trips = h.count();
    d.round_trip_p50_ns = h.percentile_ns(0.50);
    d.round_trip_p99_ns = h.percentile_ns(0.99);
    d.round_trip_max_ns = h.max_ns();
    return d;
  }

  std::vector<hal::JointScale> scales_;
  hal::libusb::UsbFrameLogic logic_;
  std::uint16_t in_sequence_ = 0;
  std::uint64_t index_ = 0;
  std::int64_t now_ = 0;
};

TEST_F(RoundTripVerdict, AnsweredCyclesPassAndAStaleRunAtTheFileLimitFails) {
  for (int i = 0; i < 50; ++i) cycle(true);
  cycle(false);
  cycle(false);
  for (int i = 0; i < 20; ++i) cycle(true);
  auto d = diagnostics();
  EXPECT_EQ(d.frames.stale_run_max, 2U);
  EXPECT_GE(d.round_trips, 60U);
  const StepResult pass = judge_round_trip(d, 72, 16'000'000, 5, "");
  EXPECT_EQ(pass.outcome, Outcome::pass) << pass.reason;
  EXPECT_NE(pass.reason.find("2 stale cycles; period 16.00 ms; longest stale run 2 < "
                             "usb.stale_limit_cycles 5"), std::string::npos) << pass.reason;
  for (int i = 0; i < 5; ++i) cycle(false);
  cycle(true);
  d = diagnostics();
  const StepResult stalled = judge_round_trip(d, 78, 16'000'000, 5, "");
  EXPECT_EQ(stalled.outcome, Outcome::fail);
  EXPECT_EQ(stalled.reason.rfind("5 stale cycles in a row: the trainer would latch device_stopped "
                                 "(usb.stale_limit_cycles = 5)", 0), 0U) << stalled.reason;
}

TEST_F(RoundTripVerdict, RefusedReportsFaultsAndTooFewRoundTripsFail) {
  for (int i = 0; i < 20; ++i) cycle(true);
  auto d = diagnostics();
  hal::libusb::RawInReport garbage;
  garbage.length = proto::kReportSize;  // all zero: bad magic
  garbage.index = ++index_;
  logic_.on_cycle(&garbage);
  d = diagnostics();
  EXPECT_EQ(d.frames.bad_reports, 1U);
  EXPECT_EQ(judge_round_trip(d, 21, 16'000'000, 5, "").reason.rfind("1 IN reports refused, 0 transfer errors", 0), 0U);
  d.frames.bad_reports = 0;
  EXPECT_EQ(judge_round_trip(d, 21, 16'000'000, 5, "watchdog_tripped").reason.rfind(
                "the device latched watchdog_tripped: ", 0), 0U);
  EXPECT_EQ(judge_round_trip(d, 1000, 16'000'000, 5, "").reason.rfind("too few round trips measured", 0), 0U);
}

}  // namespace
}  // namespace trainer::hil
