// The device logic of tools/usbgadget without USB (HapticEmulator): identity, sequence echo and
// wrap-around, plant time per exchange, the same physics as the sim backend's plant (a twin
// SimDevice stepped the same way gives the same counts), currents moving the joints only when
// enabled, the current limit, every watchdog rule of docs/usb-protocol.md, refused reports; and
// the FunctionFS blobs and configfs errors.
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include <gtest/gtest.h>

#include "ffs_descriptors.hpp"
#include "gadget_setup.hpp"
#include "haptic_emulator.hpp"
#include "trainer/app/device_wiring.hpp"
#include "trainer/config/device.hpp"

namespace trainer::tools::usbgadget {
namespace {

namespace up = hal::usbproto;
using Bytes = std::array<std::uint8_t, up::kReportSize>;

constexpr std::int64_t kMs = 1'000'000;

hal::sim::SimDeviceParams sim_plant() {
  auto device = config::load_device(std::string(TRAINER_SOURCE_DIR) + "/config/devices/sim.toml");
  EXPECT_TRUE(device.has_value());
  return app::sim_params_from(*device, "builtin:hold");
}

EmulatorParams sim_params() {
  EmulatorParams params;
  params.plant = sim_plant();
  params.frame_ns = kMs;
  return params;
}

Bytes out_bytes(std::uint16_t sequence, std::uint8_t flags, std::size_t channels,
                std::int16_t channel0_ma = 0) {
  up::OutReport out;
  out.sequence = sequence;
  out.flags = flags;
  out.channel_count = static_cast<std::uint8_t>(channels);
  out.current_ma[0] = channel0_ma;
  Bytes bytes{};
  EXPECT_EQ(up::encode(out, bytes), up::kReportSize);
  return bytes;
}

class Emulator : public ::testing::Test {
 protected:
  void SetUp() override {
    auto configured = emulator_.configure();
    ASSERT_TRUE(configured.has_value()) << configured.error().message;
    channels_ = emulator_.channel_count();
  }
  // Sends one report at now_ms_ (then +1 ms); the IN answer must come.
  up::InReport exchange(std::uint8_t flags, std::int16_t channel0_ma = 0) {
    up::InReport in;
    const Bytes bytes = out_bytes(++out_sequence_, flags, channels_, channel0_ma);
    EXPECT_TRUE(emulator_.on_out_report(bytes, now_ns_, in));
    now_ns_ += kMs;
    return in;
  }
  HapticEmulator emulator_{sim_params()};
  std::size_t channels_ = 0;
  std::uint16_t out_sequence_ = 0;
  std::int64_t now_ns_ = 5 * kMs;
};

TEST_F(Emulator, IdentityFromTheDeviceFile) {
  const up::Identity identity = emulator_.identity();
  EXPECT_EQ(identity.protocol_version, up::kProtocolVersion);
  EXPECT_EQ(identity.channel_count, 10);  // sim.toml: two instruments x 5 joints
  EXPECT_EQ(identity.frame_interval_us, 1000U);
  EXPECT_EQ(identity.watchdog_ms, kDefaultWatchdogMs);
  EXPECT_EQ(identity.max_current_ma, 3000);  // the largest current_limit_a of sim.toml
  EXPECT_EQ(identity.firmware_version, kFirmwareVersion);
}

TEST_F(Emulator, EchoesSequencesAndAdvancesPlantOneFramePerExchange) {
  std::uint16_t previous_in = 0;
  for (int i = 0; i < 100; ++i) {
    const up::InReport in = exchange(0);
    EXPECT_EQ(in.out_sequence_applied, out_sequence_);
    if (i > 0) {
      EXPECT_EQ(up::sequence_distance(in.sequence, previous_in), 1);
    }
    previous_in = in.sequence;
    EXPECT_EQ(in.device_time_us, static_cast<std::uint32_t>(1000 * (i + 1)));
    EXPECT_EQ(in.channel_count, 10);
    EXPECT_EQ(in.status & up::kStatusEnabled, 0);
  }
  // Wrap-around of the host's sequence.
  out_sequence_ = 0xFFFE;
  EXPECT_EQ(exchange(0).out_sequence_applied, 0xFFFF);
  EXPECT_EQ(exchange(0).out_sequence_applied, 0x0000);
  EXPECT_EQ(emulator_.plant_time_ns(), 102 * kMs);
}

TEST_F(Emulator, SamePhysicsAsTheSimBackendPlant) {
  // A twin of the sim backend's plant stepped as a SYNC steps simdrive's: advance, sample,
  // command. Counts must agree exactly (same code, same quantisation).
  core::ManualClock clock;
  hal::sim::SimDevice twin(clock, sim_plant());
  ASSERT_TRUE(twin.configure().has_value());
  ASSERT_TRUE(twin.activate().has_value());
  std::array<hal::EncoderSample, 10> samples{};
  std::array<hal::ActuatorCommand, 10> commands{};
  const double effort_per_amp = sim_plant().instruments[0].scales[0].effort_per_amp();
  for (int i = 0; i < 400; ++i) {
    const std::int16_t current_ma = static_cast<std::int16_t>(i < 200 ? 1200 : -800);
    const up::InReport in = exchange(up::kOutFlagEnable, current_ma);
    clock.advance_ns(kMs);
    ASSERT_EQ(twin.read_encoders(samples), hal::ReturnCode::ok);
    for (auto& command : commands) command = {0.0F, true};
    commands[0].effort = static_cast<float>(current_ma * 1e-3 * effort_per_amp);
    ASSERT_EQ(twin.write_actuators(commands), hal::ReturnCode::ok);
    for (std::size_t c = 0; c < 10; ++c) {
      ASSERT_EQ(in.counts[c], up::wire_count(samples[c].counts)) << "report " << i << " channel " << c;
    }
  }
}

TEST_F(Emulator, CurrentMovesTheJointOnlyWhenEnabled) {
  // pitch: 0.03 N·m/A x gear 15 = 0.45 N·m/A against the hand's 5 N·m/rad: 1 A deflects
  // 0.09 rad = 880 counts (4096 x 15 counts/rev) at rest.
  up::InReport in;
  for (int i = 0; i < 500; ++i) in = exchange(0, 1000);  // enable clear: nothing applied
  const std::int32_t disabled_counts = in.counts[0];
  EXPECT_NEAR(disabled_counts, 0, 2);
  for (int i = 0; i < 500; ++i) in = exchange(up::kOutFlagEnable, 1000);
  EXPECT_NE(in.status & up::kStatusEnabled, 0);
  const double expected = 0.45 / 5.0 / (2.0 * 3.14159265358979) * 4096.0 * 15.0;
  EXPECT_NEAR(in.counts[0] - disabled_counts, expected, 0.05 * expected);
  EXPECT_NEAR(in.counts[1], 0, 2);  // other channels stay
}

TEST_F(Emulator, CurrentLimitIsReported) {
  up::InReport in = exchange(up::kOutFlagEnable, 2500);
  in = exchange(up::kOutFlagEnable, 2500);
  EXPECT_EQ(in.status & up::kStatusCurrentLimited, 0);
  in = exchange(up::kOutFlagEnable, 5000);  // above 3 A
  EXPECT_NE(in.status & up::kStatusCurrentLimited, 0);
  EXPECT_EQ(emulator_.stats().current_limited_reports, 1U);
}

TEST_F(Emulator, WatchdogTripsLatchesAndClearsOnlyOnRequest) {
  up::InReport in;
  // Never enabled: not armed, never trips.
  exchange(0);
  EXPECT_FALSE(emulator_.on_time(now_ns_ + 1000 * kMs, in));
  EXPECT_EQ(emulator_.next_deadline_ns(), std::numeric_limits<std::int64_t>::max());

  for (int i = 0; i < 50; ++i) exchange(up::kOutFlagEnable, 1000);
  const std::int64_t last = now_ns_ - kMs;
  EXPECT_EQ(emulator_.next_deadline_ns(), last + 20 * kMs + 1);
  EXPECT_FALSE(emulator_.on_time(last + 20 * kMs, in));  // exactly the watchdog: not yet
  ASSERT_TRUE(emulator_.on_time(last + 20 * kMs + 1, in));
  EXPECT_NE(in.status & up::kStatusWatchdogTripped, 0);
  EXPECT_NE(in.status & up::kStatusNoNewOut, 0);
  EXPECT_EQ(in.status & up::kStatusEnabled, 0);
  EXPECT_EQ(in.out_sequence_applied, out_sequence_);
  EXPECT_TRUE(emulator_.tripped());
  EXPECT_FALSE(emulator_.on_time(last + 100 * kMs, in));  // one trip report only
  now_ns_ = last + 100 * kMs;

  // Latched: enable reports are answered but apply nothing; the joint returns to the hand.
  for (int i = 0; i < 500; ++i) in = exchange(up::kOutFlagEnable, 1000);
  EXPECT_NE(in.status & up::kStatusWatchdogTripped, 0);
  EXPECT_EQ(in.status & up::kStatusEnabled, 0);
  EXPECT_EQ(in.out_sequence_applied, out_sequence_);
  EXPECT_NEAR(in.counts[0], 0, 2);

  // Clear: latch gone, this report's current not applied, not armed until enabled.
  in = exchange(up::kOutFlagClearWatchdog | up::kOutFlagEnable, 1000);
  EXPECT_EQ(in.status & up::kStatusWatchdogTripped, 0);
  EXPECT_EQ(in.status & up::kStatusEnabled, 0);
  EXPECT_FALSE(emulator_.on_time(now_ns_ + 1000 * kMs, in));
  in = exchange(up::kOutFlagEnable, 1000);
  EXPECT_NE(in.status & up::kStatusEnabled, 0);
  EXPECT_EQ(emulator_.stats().watchdog_trips, 1U);
  EXPECT_EQ(emulator_.stats().clears, 1U);
}

TEST_F(Emulator, WatchdogFollowsSetWatchdog) {
  EXPECT_FALSE(emulator_.set_watchdog_ms(1));
  EXPECT_FALSE(emulator_.set_watchdog_ms(1001));
  exchange(up::kOutFlagEnable);  // armed with the default 20 ms
  ASSERT_TRUE(emulator_.set_watchdog_ms(5));
  EXPECT_EQ(emulator_.identity().watchdog_ms, 5);
  // Not in force before the next report: a late request does not trip retroactively.
  up::InReport in;
  EXPECT_FALSE(emulator_.on_time(now_ns_ - kMs + 6 * kMs, in));
  exchange(up::kOutFlagEnable);
  EXPECT_FALSE(emulator_.on_time(now_ns_ - kMs + 5 * kMs, in));
  EXPECT_TRUE(emulator_.on_time(now_ns_ - kMs + 5 * kMs + 1, in));
  EXPECT_EQ(emulator_.identity().watchdog_ms, 5);
}

TEST_F(Emulator, RefusedReportsAreFlaggedNotAnswered) {
  up::InReport in;
  Bytes garbage{};
  garbage.fill(0x55);
  EXPECT_FALSE(emulator_.on_out_report(garbage, now_ns_, in));
  EXPECT_FALSE(emulator_.on_out_report(std::span(garbage.data(), 10), now_ns_, in));
  const Bytes wrong_channels = out_bytes(77, up::kOutFlagEnable, 4);
  EXPECT_FALSE(emulator_.on_out_report(wrong_channels, now_ns_, in));
  EXPECT_EQ(emulator_.stats().out_rejected, 3U);
  EXPECT_EQ(emulator_.stats().out_wrong_channel_count, 1U);
  EXPECT_EQ(emulator_.stats().rejected_by_status[static_cast<std::size_t>(up::DecodeStatus::bad_magic)], 1U);
  EXPECT_EQ(emulator_.stats().rejected_by_status[static_cast<std::size_t>(up::DecodeStatus::wrong_length)], 1U);
  in = exchange(0);
  EXPECT_NE(in.status & up::kStatusOutRejected, 0);
  EXPECT_EQ(in.out_sequence_applied, out_sequence_);
  in = exchange(0);
  EXPECT_EQ(in.status & up::kStatusOutRejected, 0);
  // Refused reports do not feed the watchdog.
  exchange(up::kOutFlagEnable);
  const std::int64_t last = now_ns_ - kMs;
  for (int i = 1; i <= 25; ++i) (void)emulator_.on_out_report(garbage, last + i * kMs, in);
  EXPECT_TRUE(emulator_.on_time(last + 26 * kMs, in));
}

TEST(EmulatorConfigure, RefusesWhatTheProtocolCannotCarry) {
  EmulatorParams params = sim_params();
  params.frame_ns = 1'050'000;  // not a multiple of the 100 us sub-step
  HapticEmulator odd_frame(params);
  auto result = odd_frame.configure();
  ASSERT_FALSE(result.has_value());
  EXPECT_NE(result.error().message.find("1050000 ns"), std::string::npos) << result.error().message;

  params = sim_params();
  while (params.plant.instruments.size() < 4) {
    params.plant.instruments.push_back(params.plant.instruments[0]);
    params.plant.instruments.back().name = "extra" + std::to_string(params.plant.instruments.size());
  }
  HapticEmulator too_many(params);
  result = too_many.configure();
  ASSERT_FALSE(result.has_value());
  EXPECT_NE(result.error().message.find("20 channels"), std::string::npos) << result.error().message;

  params = sim_params();
  params.watchdog_ms = 1;
  HapticEmulator bad_watchdog(params);
  EXPECT_FALSE(bad_watchdog.configure().has_value());
}

// --- FunctionFS blobs -------------------------------------------------------------------------

std::uint32_t le32_at(const std::vector<std::uint8_t>& bytes, std::size_t at) {
  return static_cast<std::uint32_t>(bytes[at]) | (static_cast<std::uint32_t>(bytes[at + 1]) << 8) |
         (static_cast<std::uint32_t>(bytes[at + 2]) << 16) | (static_cast<std::uint32_t>(bytes[at + 3]) << 24);
}

TEST(FfsBlobs, DescriptorsHaveBothSpeedSets) {
  const std::vector<std::uint8_t> blob = ffs_descriptors();
  ASSERT_EQ(blob.size(), 20U + 2U * (9U + 7U + 7U));
  EXPECT_EQ(le32_at(blob, 0), 3U);  // FUNCTIONFS_DESCRIPTORS_MAGIC_V2
  EXPECT_EQ(le32_at(blob, 4), blob.size());
  EXPECT_EQ(le32_at(blob, 8), 3U);   // HAS_FS_DESC | HAS_HS_DESC
  EXPECT_EQ(le32_at(blob, 12), 3U);  // fs_count
  EXPECT_EQ(le32_at(blob, 16), 3U);  // hs_count
  for (const std::size_t set : {std::size_t{20}, std::size_t{43}}) {
    const std::vector<std::uint8_t> interface(blob.begin() + static_cast<long>(set),
                                              blob.begin() + static_cast<long>(set) + 9);
    EXPECT_EQ(interface, (std::vector<std::uint8_t>{9, 4, 0, 0, 2, 0xFF, 0, 0, 1}));
    const std::vector<std::uint8_t> in(blob.begin() + static_cast<long>(set) + 9,
                                       blob.begin() + static_cast<long>(set) + 16);
    EXPECT_EQ(in, (std::vector<std::uint8_t>{7, 5, 0x81, 3, 64, 0, 1}));
    const std::vector<std::uint8_t> out(blob.begin() + static_cast<long>(set) + 16,
                                        blob.begin() + static_cast<long>(set) + 23);
    EXPECT_EQ(out, (std::vector<std::uint8_t>{7, 5, 0x01, 3, 64, 0, 1}));
  }
}

TEST(FfsBlobs, Strings) {
  const std::vector<std::uint8_t> blob = ffs_strings("ab");
  EXPECT_EQ(blob, (std::vector<std::uint8_t>{2, 0, 0, 0, 21, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0,
                                             0x09, 0x04, 'a', 'b', 0}));
}

// --- configfs errors (the real tree needs the bench VM: tests/benchvm/usb_gadget_test.sh) -----

TEST(ConfigfsGadget, ErrorsNameThePath) {
  const std::filesystem::path root =
      std::filesystem::temp_directory_path() / ("usbgadget_test_" + std::to_string(::getpid()));
  std::filesystem::remove_all(root);
  {
    ConfigfsGadget missing(root / "usb_gadget", "g", root / "ffs");
    try {
      missing.create({});
      FAIL() << "created under a missing root";
    } catch (const std::runtime_error& error) {
      EXPECT_NE(std::string(error.what()).find((root / "usb_gadget").string()), std::string::npos) << error.what();
    }
  }
  std::filesystem::create_directories(root / "usb_gadget" / "g");
  {
    ConfigfsGadget existing(root / "usb_gadget", "g", root / "ffs");
    try {
      existing.create({});
      FAIL() << "took over an existing gadget";
    } catch (const std::runtime_error& error) {
      EXPECT_NE(std::string(error.what()).find("a gadget of this name exists"), std::string::npos) << error.what();
    }
  }
  EXPECT_TRUE(std::filesystem::is_directory(root / "usb_gadget" / "g"));  // not removed by us
  std::filesystem::remove_all(root);
}

}  // namespace
}  // namespace trainer::tools::usbgadget
