// The simulated drives against hand-written CiA 301 / CiA 402 frames over a socketpair: boot-up,
// NMT, SDO (identity, mode, aborts), PDO mapping (the library's SDO client running the standard
// sequence, and the checks with their abort codes), synchronous and event-driven RPDOs, the
// power state machine and where torque reaches the plant, digital I/O.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "simdrive_test_support.hpp"
#include "trainer/core/fixed_vector.hpp"
#include "trainer/hal_canopen/pdo.hpp"
#include "trainer/hal_canopen/sdo_client.hpp"

namespace trainer::hal::simdrive {
namespace {

using namespace test_support;  // NOLINT: test fixtures

constexpr std::uint32_t kAbortNoObject = 0x06020000;
constexpr std::uint32_t kAbortNoSub = 0x06090011;
constexpr std::uint32_t kAbortReadOnly = 0x06010002;
constexpr std::uint32_t kAbortInvalidValue = 0x06090030;
constexpr std::uint32_t kAbortLengthHigh = 0x06070012;
constexpr std::uint32_t kAbortNotMappable = 0x06040041;
constexpr std::uint32_t kAbortPdoLength = 0x06040042;
constexpr std::uint32_t kAbortUnsupportedAccess = 0x06010000;
constexpr std::uint32_t kAbortDeviceState = 0x08000022;
constexpr std::uint32_t kAbortIncompatible = 0x06040043;

TEST(SimDriveProtocol, EveryNodeSendsItsBootUpAtPowerOnAndAfterEachReset) {
  DriveHarness h;
  const std::vector<can_frame> boot = h.power_on();
  ASSERT_EQ(boot.size(), 5U);
  for (std::uint8_t node = 1; node <= 5; ++node) {
    const auto frames = with_id(boot, 0x700U + node);
    ASSERT_EQ(frames.size(), 1U) << "node " << int{node};
    EXPECT_EQ(frames[0].len, 1);
    EXPECT_EQ(frames[0].data[0], 0x00) << "boot-up state byte";
  }
  // Reset communication restores the communication area only; reset node everything.
  EXPECT_EQ(h.write(3, 0x1017, 0, 50, 2), 0U);
  EXPECT_EQ(h.write(3, 0x6072, 0, 500, 2), 0U);
  std::vector<can_frame> frames = h.exchange({nmt_frame(kNmtResetCommunication, 3)});
  ASSERT_EQ(frames.size(), 1U);
  EXPECT_EQ(frames[0].can_id, 0x703U);
  EXPECT_EQ(frames[0].data[0], 0x00);
  EXPECT_EQ(h.read(3, 0x1017, 0), 0U) << "0x1017 back to its default";
  EXPECT_EQ(h.read(3, 0x6072, 0), 500U) << "the application area survives a communication reset";
  frames = h.exchange({nmt_frame(kNmtResetNode, 3)});
  ASSERT_EQ(frames.size(), 1U);
  EXPECT_EQ(frames[0].can_id, 0x703U);
  EXPECT_EQ(h.read(3, 0x6072, 0), 1000U) << "reset node restores the application area too";
  // Broadcast (node 0): all of them.
  frames = h.exchange({nmt_frame(kNmtResetCommunication, 0)});
  EXPECT_EQ(frames.size(), 5U);
  // After boot: pre-operational, reported by the heartbeat once 0x1017 is set.
  EXPECT_EQ(h.write(2, 0x1017, 0, 10, 2), 0U);
  frames = h.poll(10'000'000);
  const auto beats = with_id(frames, 0x702);
  ASSERT_EQ(beats.size(), 1U);
  EXPECT_EQ(beats[0].data[0], 0x7F);
}

TEST(SimDriveProtocol, SdoReadsIdentityAndProfileObjectsAndAbortsWrongAccess) {
  DriveHarness h;
  (void)h.power_on();
  EXPECT_EQ(h.read(2, 0x1000, 0), 0x00020192U);
  EXPECT_EQ(h.read(2, 0x1018, 0), 4U);
  EXPECT_EQ(h.read(2, 0x1018, 1), kVendor);
  EXPECT_EQ(h.read(2, 0x1018, 2), kProduct);
  EXPECT_EQ(h.read(2, 0x1018, 3), 7U);
  EXPECT_EQ(h.read(2, 0x1018, 4), 1002U);
  EXPECT_EQ(h.read(2, 0x6502, 0), 1U << 9) << "cyclic synchronous torque only";
  EXPECT_EQ(h.read(2, 0x6076, 0), kRatedMnm);
  EXPECT_EQ(h.read(2, 0x6060, 0), 10U);
  EXPECT_EQ(h.read(2, 0x6061, 0), 10U);
  EXPECT_TRUE(is_switch_on_disabled(static_cast<std::uint16_t>(h.read(2, 0x6041, 0))));

  EXPECT_EQ(h.sdo(sdo_upload(2, 0x2000, 0)).abort, kAbortNoObject);
  EXPECT_EQ(h.sdo(sdo_upload(2, 0x1018, 7)).abort, kAbortNoSub);
  EXPECT_EQ(h.write(2, 0x1018, 1, 1, 4), kAbortReadOnly);
  EXPECT_EQ(h.write(2, 0x6041, 0, 0, 2), kAbortReadOnly);
  EXPECT_EQ(h.write(2, 0x6040, 0, 6, 4), kAbortLengthHigh) << "a u16 written with 4 bytes";
  for (const std::uint32_t mode : {1U, 4U, 8U, 9U, 0U, 0xF6U /* -10 */}) {
    EXPECT_EQ(h.write(2, 0x6060, 0, mode, 1), kAbortInvalidValue) << "mode " << mode;
  }
  EXPECT_EQ(h.write(2, 0x6060, 0, 10, 1), 0U);
  EXPECT_EQ(h.write(2, 0x6007, 0, 4, 2), kAbortInvalidValue);
  EXPECT_EQ(h.write(2, 0x6007, 0, 0xFFFF, 2), kAbortInvalidValue)
      << "negative (manufacturer) option";
  EXPECT_EQ(h.write(2, 0x605A, 0, 9, 2), kAbortInvalidValue);
  EXPECT_EQ(h.write(2, 0x605A, 0, 6, 2), 0U);
  // One consumer time per producer (CiA 301 7.5.2.22).
  EXPECT_EQ(h.write(2, 0x1016, 1, (127U << 16) | 30U, 4), 0U);
  EXPECT_EQ(h.write(2, 0x1016, 2, (127U << 16) | 50U, 4), kAbortIncompatible);
  EXPECT_EQ(h.write(2, 0x1016, 2, (126U << 16) | 50U, 4), 0U);
  // The device name is longer than 4 bytes: a segmented upload through the library's client.
  canopen::SdoClient client;
  std::array<std::uint8_t, 64> name{};
  ASSERT_TRUE(client.start_upload(2, 0x1008, 0, name, h.now()));
  for (int round = 0; round < 20 && client.busy(); ++round) {
    while (const auto tx = client.next_tx()) ASSERT_TRUE(h.master().send_one(*tx));
    for (const can_frame& frame : h.poll()) (void)client.on_frame(frame, h.now());
  }
  ASSERT_EQ(client.status(), canopen::SdoStatus::done);
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(name.data()), client.transferred_bytes()),
            "trainer simdrive");
}

TEST(SimDriveProtocol, AStoppedNodeAnswersNothingButNmtAndKeepsItsHeartbeat) {
  DriveHarness h;
  (void)h.power_on();
  EXPECT_EQ(h.write(2, 0x1017, 0, 10, 2), 0U);
  std::vector<can_frame> frames = h.exchange({nmt_frame(kNmtStop, 2)});
  EXPECT_TRUE(frames.empty());
  EXPECT_FALSE(h.sdo(sdo_upload(2, 0x1000, 0)).answered) << "no SDO while stopped";
  frames = h.sync();  // no TPDO either
  EXPECT_FALSE(has_id(frames, 0x182));
  frames = h.poll(10'000'000);
  ASSERT_EQ(with_id(frames, 0x702).size(), 1U);
  EXPECT_EQ(with_id(frames, 0x702)[0].data[0], 0x04) << "heartbeat reports stopped";
  frames = h.exchange({nmt_frame(kNmtStart, 2)});
  // TPDO1's default (statusword, event-driven) goes out when the node becomes operational.
  ASSERT_EQ(with_id(frames, 0x182).size(), 1U);
  EXPECT_TRUE(is_switch_on_disabled(le16(with_id(frames, 0x182)[0], 0)));
  EXPECT_TRUE(h.sdo(sdo_upload(2, 0x1000, 0)).answered);
  frames = h.poll(10'000'000);
  EXPECT_EQ(with_id(frames, 0x702).at(0).data[0], 0x05);
}

// Runs every write of `config` through the protocol library's SDO client (CiA 301 sequence:
// disable, parameters, mapping off, entries, mapping on, enable). Returns the first abort.
std::uint32_t configure_with_client(DriveHarness& h, std::uint8_t node,
                                    const canopen::PdoConfiguration& config) {
  core::FixedVector<canopen::SdoWrite, canopen::kMaxPdoConfigurationWrites> writes;
  EXPECT_TRUE(canopen::pdo_configuration_writes(config, writes));
  canopen::SdoClient client;
  for (const canopen::SdoWrite& write : writes) {
    EXPECT_TRUE(client.start_download(node, write.index, write.sub, write.bytes(), h.now()));
    for (int round = 0; round < 10 && client.busy(); ++round) {
      while (const auto tx = client.next_tx()) EXPECT_TRUE(h.master().send_one(*tx));
      for (const can_frame& frame : h.poll()) (void)client.on_frame(frame, h.now());
    }
    if (client.status() != canopen::SdoStatus::done)
      return client.abort_code() != 0 ? client.abort_code() : 1U;
  }
  return 0;
}

TEST(SimDriveProtocol, TpdosCarryWhatTheMasterMappedWithTheStandardSequence) {
  DriveHarness h;
  (void)h.power_on();
  canopen::PdoConfiguration tpdo1;
  tpdo1.direction = canopen::PdoDirection::transmit;
  tpdo1.pdo_number = 1;
  tpdo1.can_id = 0x181;
  tpdo1.transmission_type = 1;
  ASSERT_TRUE(tpdo1.mapping.add(0x6041, 0, 16, false));
  ASSERT_TRUE(tpdo1.mapping.add(0x6064, 0, 32, true));
  ASSERT_TRUE(tpdo1.mapping.add(0x6077, 0, 16, true));
  canopen::PdoConfiguration tpdo2;
  tpdo2.direction = canopen::PdoDirection::transmit;
  tpdo2.pdo_number = 2;
  tpdo2.can_id = 0x281;
  tpdo2.transmission_type = 2;  // every second SYNC
  ASSERT_TRUE(tpdo2.mapping.add(0x606C, 0, 32, true));
  ASSERT_TRUE(tpdo2.mapping.add(0x60FD, 0, 32, false));
  ASSERT_EQ(configure_with_client(h, 1, tpdo1), 0U);
  ASSERT_EQ(configure_with_client(h, 1, tpdo2), 0U);
  EXPECT_EQ(h.read(1, 0x1A00, 0), 3U);
  EXPECT_EQ(h.read(1, 0x1A00, 2), 0x60640020U);

  // Pre-operational: SYNCs run the drive but no PDO leaves.
  std::vector<can_frame> frames = h.sync();
  EXPECT_FALSE(has_id(frames, 0x181));
  (void)h.exchange({nmt_frame(kNmtStart, 1)});
  h.bus().plant().set_estop(true);  // input bit 0 -> 0x60FD bit 16
  frames = h.sync();
  ASSERT_EQ(with_id(frames, 0x181).size(), 1U);
  EXPECT_FALSE(has_id(frames, 0x281)) << "type 2: not at the first SYNC";
  const can_frame tpdo = with_id(frames, 0x181)[0];
  EXPECT_EQ(tpdo.len, 8);
  EXPECT_TRUE(is_switch_on_disabled(le16(tpdo, 0)));
  const auto expected_counts = h.bus().params().plant.instruments[0].scales[0].counts_from_position(
      h.bus().plant().true_position(0));
  EXPECT_EQ(static_cast<std::int32_t>(le32(tpdo, 2)), expected_counts)
      << "position actual at the SYNC";
  EXPECT_EQ(static_cast<std::int32_t>(le32(tpdo, 2)),
            static_cast<std::int32_t>(h.read(1, 0x6064, 0)));
  EXPECT_EQ(le16(tpdo, 6), 0U) << "no torque while disabled";
  frames = h.sync();
  ASSERT_EQ(with_id(frames, 0x281).size(), 1U);
  EXPECT_EQ(with_id(frames, 0x281)[0].len, 8);
  EXPECT_EQ(le32(with_id(frames, 0x281)[0], 4), (1U << 16) | (1U << 17))
      << "the e-stop (input bit 0) and the enable switch (bit 1, held) on 0x60FD bits 16, 17";
  // Node 2 was not configured: its default TPDO1 (statusword, event-driven) only.
  EXPECT_FALSE(has_id(frames, 0x182));
}

TEST(SimDriveProtocol, MappingWritesAreCheckedWithTheCiA301AbortCodes) {
  DriveHarness h;
  (void)h.power_on();
  // TPDO1 is valid by default: its mapping cannot change.
  EXPECT_EQ(h.write(1, 0x1A00, 0, 0, 1), kAbortDeviceState);
  EXPECT_EQ(h.write(1, 0x1A00, 1, 0x60640020, 4), kAbortDeviceState);
  EXPECT_EQ(h.write(1, 0x1800, 1, 0x40000190, 4), kAbortInvalidValue) << "new id while valid";
  EXPECT_EQ(h.write(1, 0x1800, 3, 10, 2), kAbortInvalidValue) << "inhibit time while valid";
  EXPECT_EQ(h.write(1, 0x1800, 1, 0xC0000181, 4), 0U);
  // Mapping enabled (sub 0 = 1): entries cannot change.
  EXPECT_EQ(h.write(1, 0x1A00, 1, 0x60640020, 4), kAbortUnsupportedAccess);
  EXPECT_EQ(h.write(1, 0x1A00, 0, 0, 1), 0U);
  EXPECT_EQ(h.write(1, 0x1A00, 1, 0x65020020, 4), kAbortNotMappable) << "0x6502 is not mappable";
  EXPECT_EQ(h.write(1, 0x1A00, 1, 0x10000020, 4), kAbortNotMappable) << "0x1000 is not mappable";
  EXPECT_EQ(h.write(1, 0x1A00, 1, 0x60410020, 4), kAbortNotMappable)
      << "16-bit object mapped as 32 bits";
  EXPECT_EQ(h.write(1, 0x1A00, 1, 0x20000020, 4), kAbortNoObject);
  EXPECT_EQ(h.write(1, 0x1A00, 1, 0x60FE0320, 4), kAbortNoSub);
  for (std::uint8_t sub = 1; sub <= 3; ++sub) EXPECT_EQ(h.write(1, 0x1A00, sub, 0x60640020, 4), 0U);
  EXPECT_EQ(h.write(1, 0x1A00, 0, 3, 1), kAbortPdoLength) << "96 bits";
  EXPECT_EQ(h.write(1, 0x1A00, 0, 9, 1), kAbortPdoLength) << "more than 8 entries";
  EXPECT_EQ(h.write(1, 0x1A00, 0, 2, 1), 0U);
  EXPECT_EQ(h.write(1, 0x1800, 2, 252, 1), kAbortInvalidValue) << "RTR-only: not supported";
  EXPECT_EQ(h.write(1, 0x1800, 2, 241, 1), kAbortInvalidValue) << "reserved";
  EXPECT_EQ(h.write(1, 0x1800, 1, 0x40000601, 4), kAbortInvalidValue) << "an SDO identifier";
  EXPECT_EQ(h.write(1, 0x1800, 1, 0x60000181, 4), kAbortInvalidValue) << "29-bit id";
  EXPECT_EQ(h.write(1, 0x1800, 1, 0x40000181, 4), 0U);
  EXPECT_EQ(h.read(1, 0x1A00, 0), 2U);
  // RPDOs take writable objects only (the statusword cannot be received).
  EXPECT_EQ(h.write(1, 0x1400, 1, 0x80000201, 4), 0U);
  EXPECT_EQ(h.write(1, 0x1600, 0, 0, 1), 0U);
  EXPECT_EQ(h.write(1, 0x1600, 1, 0x60410010, 4), kAbortNotMappable);
  EXPECT_EQ(h.write(1, 0x1600, 1, 0x60710010, 4), 0U);
}

TEST(SimDriveProtocol, ASynchronousRpdoActsAtTheNextSyncAnEventDrivenOneAtOnce) {
  DriveHarness h;
  (void)h.power_on();
  h.map_trainer_pdos(1);
  (void)h.exchange({nmt_frame(kNmtStart, 1)});
  std::vector<can_frame> frames = h.exchange({DriveHarness::rpdo1(1, 0x06, 0)});
  EXPECT_TRUE(is_switch_on_disabled(static_cast<std::uint16_t>(h.read(1, 0x6041, 0))))
      << "latched, not applied before the SYNC";
  EXPECT_EQ(h.read(1, 0x6040, 0), 0U);
  frames = h.sync();
  ASSERT_EQ(with_id(frames, 0x181).size(), 1U);
  EXPECT_TRUE(is_ready_to_switch_on(le16(with_id(frames, 0x181)[0], 0)));
  EXPECT_EQ(h.read(1, 0x6040, 0), 6U);
  // Transmission type 255: at once.
  EXPECT_EQ(h.write(1, 0x1400, 2, 255, 1), 0U);
  (void)h.exchange({DriveHarness::rpdo1(1, 0x07, 0)});
  EXPECT_TRUE(is_switched_on(static_cast<std::uint16_t>(h.read(1, 0x6041, 0))));
  // A short RPDO is not processed: EMCY 0x8210 once.
  frames = h.exchange({raw_frame(0x201, {0x0F, 0x00})});
  ASSERT_EQ(with_id(frames, 0x081).size(), 1U);
  EXPECT_EQ(le16(with_id(frames, 0x081)[0], 0), 0x8210U);
  EXPECT_TRUE(is_switched_on(static_cast<std::uint16_t>(h.read(1, 0x6041, 0))));
  frames = h.exchange({raw_frame(0x201, {0x0F, 0x00})});
  EXPECT_FALSE(has_id(frames, 0x081)) << "reported once until a good RPDO";
}

TEST(SimDriveProtocol, TorqueReachesThePlantOnlyInOperationEnabled) {
  DriveHarness h;
  (void)h.power_on();
  h.map_trainer_pdos(1);
  h.map_trainer_pdos(4);
  (void)h.exchange({nmt_frame(kNmtStart, 0)});
  const double gear = 20.0;
  // 500 permille of 60 mN·m = 30 mN·m motor = 0.6 N·m at the joint.
  std::vector<can_frame> frames = h.sync({DriveHarness::rpdo1(1, 0x06, 500)});
  EXPECT_TRUE(is_ready_to_switch_on(le16(with_id(frames, 0x181).at(0), 0)));
  EXPECT_EQ(h.bus().plant().applied_effort(0), 0.0);
  EXPECT_EQ(le16(with_id(frames, 0x181)[0], 6), 0U);
  frames = h.sync({DriveHarness::rpdo1(1, 0x07, 500)});
  EXPECT_TRUE(is_switched_on(le16(with_id(frames, 0x181).at(0), 0)));
  EXPECT_EQ(h.bus().plant().applied_effort(0), 0.0);
  frames = h.sync({DriveHarness::rpdo1(1, 0x0F, 500)});
  const can_frame enabled = with_id(frames, 0x181).at(0);
  EXPECT_TRUE(is_operation_enabled(le16(enabled, 0)));
  EXPECT_NE(le16(enabled, 0) & (1U << 12), 0U) << "bit 12: following the command";
  EXPECT_EQ(static_cast<std::int16_t>(le16(enabled, 6)), 500);
  EXPECT_NEAR(h.bus().plant().applied_effort(0), 0.030 * gear, 1e-6);
  const auto torque_events = of_kind(h.events(), EventKind::torque_enabled, 1);
  EXPECT_EQ(torque_events.size(), 1U);
  // 0x6072 (default 1000 permille) clips, and says so in statusword bit 11.
  frames = h.sync({DriveHarness::rpdo1(1, 0x0F, -2000)});
  EXPECT_EQ(static_cast<std::int16_t>(le16(with_id(frames, 0x181).at(0), 6)), -1000);
  EXPECT_NE(le16(with_id(frames, 0x181)[0], 0) & (1U << 11), 0U);
  EXPECT_NEAR(h.bus().plant().applied_effort(0), -0.060 * gear, 1e-6);
  // Node 4 (roll): the 1 A current limit (30 mN·m = 500 permille) clips below 0x6072.
  (void)h.enable(4, 800);
  EXPECT_EQ(static_cast<std::int16_t>(h.read(4, 0x6077, 0)), 500);
  EXPECT_NEAR(h.bus().plant().applied_effort(3), 0.030 * 12.0, 1e-6);
  // Quick stop (0x605A = 2, ramp 0 for a torque drive): torque off at once, Switch on disabled.
  frames = h.sync({DriveHarness::rpdo1(1, 0x02, 500)});
  EXPECT_TRUE(is_switch_on_disabled(le16(with_id(frames, 0x181).at(0), 0)));
  EXPECT_EQ(h.bus().plant().applied_effort(0), 0.0);
  EXPECT_EQ(le16(with_id(frames, 0x181)[0], 6), 0U);
  const auto removed = of_kind(h.events(), EventKind::torque_removed, 1);
  ASSERT_EQ(removed.size(), 1U);
  EXPECT_STREQ(removed[0].cause, "controlword (RPDO)");
  // A mode other than CST cannot be set; 0x6061 shows CST.
  EXPECT_EQ(h.read(1, 0x6061, 0), 10U);
}

TEST(SimDriveProtocol, DigitalOutputsOfTheOutputsNodeReachThePlant) {
  DriveHarness h;
  (void)h.power_on();
  EXPECT_EQ(h.write(1, 0x1401, 1, 0x80000301, 4), 0U);
  EXPECT_EQ(h.write(1, 0x1401, 2, 1, 1), 0U);
  EXPECT_EQ(h.write(1, 0x1601, 0, 0, 1), 0U);
  EXPECT_EQ(h.write(1, 0x1601, 1, 0x60FE0120, 4), 0U);
  EXPECT_EQ(h.write(1, 0x1601, 0, 1, 1), 0U);
  EXPECT_EQ(h.write(1, 0x1401, 1, 0x00000301, 4), 0U);
  (void)h.exchange({nmt_frame(kNmtStart, 1)});
  (void)h.sync({raw_frame(0x301, {0x00, 0x00, 0x03, 0x00})});  // bits 16, 17
  EXPECT_EQ(h.bus().plant().digital_output_levels(), 0x3U);
  EXPECT_EQ(h.write(1, 0x60FE, 2, 0x00010000, 4), 0U);  // mask: only bit 16 enabled
  (void)h.sync();
  EXPECT_EQ(h.bus().plant().digital_output_levels(), 0x1U);
}

TEST(SimDriveProtocol, ThePlantAdvancesExactlyOneSyncPeriodPerSyncWhateverTheWallClock) {
  DriveHarness h;
  (void)h.power_on();
  const std::int64_t t0 = h.bus().plant_time_ns();
  for (int i = 0; i < 7; ++i) (void)h.poll(50'000'000);  // protocol time passes, no SYNC
  EXPECT_EQ(h.bus().plant_time_ns(), t0);
  (void)h.exchange({nmt_frame(kNmtStart, 0)});  // script time starts here
  const std::int64_t start = h.bus().plant_time_ns();
  for (int i = 1; i <= 25; ++i) {
    (void)h.exchange({sync_frame()}, i % 3 == 0 ? 7'000'000 : 100'000);  // irregular wall time
    EXPECT_EQ(h.bus().plant_time_ns() - start, i * kSyncPeriodNs);
  }
  EXPECT_NEAR(h.bus().plant().script_time_s(), 25 * 1e-3, 1e-12);
  EXPECT_EQ(h.bus().syncs_since_start(), 25U);
}

// The same frames at the same protocol times give the same frames out, byte for byte
// (plant with a moving hand, torque, heartbeats, an injected fault).
TEST(SimDriveProtocol, SameFramesInGiveTheSameFramesOut) {
  const auto run = [] {
    DriveHarness h(test_bus_params("builtin:sweep"));
    std::vector<can_frame> all = h.power_on();
    h.map_trainer_pdos(1);
    h.map_trainer_pdos(3);
    EXPECT_EQ(h.write(3, 0x1017, 0, 7, 2), 0U);
    EXPECT_TRUE(
        h.bus().inject(*parse_fault_spec("encoder_jump:node=1,at_sync=40,counts=77"), h.now()));
    (void)h.exchange({nmt_frame(kNmtStart, 0)});
    for (int i = 0; i < 300; ++i) {
      const std::uint16_t controlword = i == 0 ? 0x06 : (i == 1 ? 0x07 : 0x0F);
      const auto torque = static_cast<std::int16_t>((i * 37) % 900 - 450);
      const auto frames = h.sync({DriveHarness::rpdo1(1, controlword, torque),
                                  DriveHarness::rpdo1(3, controlword, torque)});
      all.insert(all.end(), frames.begin(), frames.end());
    }
    return all;
  };
  const std::vector<can_frame> first = run();
  const std::vector<can_frame> second = run();
  ASSERT_EQ(first.size(), second.size());
  ASSERT_GT(first.size(), 600U);
  for (std::size_t i = 0; i < first.size(); ++i) {
    ASSERT_EQ(first[i].can_id, second[i].can_id) << "frame " << i;
    ASSERT_EQ(first[i].len, second[i].len) << "frame " << i;
    ASSERT_EQ(0, std::memcmp(first[i].data, second[i].data, first[i].len)) << "frame " << i;
  }
}

}  // namespace
}  // namespace trainer::hal::simdrive
