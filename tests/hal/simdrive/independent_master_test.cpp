// A master that is not the trainer's: every frame hand-made from CiA 301 / CiA 402 (the byte
// layouts in simdrive_test_support.hpp), a PDO layout the trainer never uses (TPDO1 = statusword
// + mode display, 3 bytes, on a COB-ID of its own choosing; RPDO1 left at its event-driven
// default; an event-timer TPDO), driving a drive to Operation enabled and torque into the plant.
#include <gtest/gtest.h>

#include "simdrive_test_support.hpp"

namespace trainer::hal::simdrive {
namespace {

using namespace test_support;  // NOLINT: test fixtures

TEST(IndependentMaster, ConfiguresItsOwnMappingAndDrivesTheDriveByTheStandard) {
  DriveHarness h;
  (void)h.power_on();
  // NMT reset communication (all nodes): every node answers with its boot-up message.
  std::vector<can_frame> frames = h.exchange({nmt_frame(kNmtResetCommunication, 0)});
  ASSERT_EQ(frames.size(), 5U);
  const std::uint8_t node = 3;  // the insertion joint: prismatic, 10 mm capstan, gear 10
  EXPECT_EQ(h.read(node, 0x1000, 0) & 0xFFFF, 402U) << "a CiA 402 device";
  EXPECT_NE(h.read(node, 0x6502, 0) & (1U << 9), 0U) << "CST supported";

  // TPDO1: disable (bit 31), new COB-ID 0x1A3 in the same write, synchronous every SYNC,
  // mapping off, {0x6041/16, 0x6061/8}, mapping on, enable.
  EXPECT_EQ(h.write(node, 0x1800, 1, 0xC00001A3, 4), 0U);
  EXPECT_EQ(h.write(node, 0x1800, 2, 0x01, 1), 0U);
  EXPECT_EQ(h.write(node, 0x1A00, 0, 0, 1), 0U);
  EXPECT_EQ(h.write(node, 0x1A00, 1, 0x60410010, 4), 0U);
  EXPECT_EQ(h.write(node, 0x1A00, 2, 0x60610008, 4), 0U);
  EXPECT_EQ(h.write(node, 0x1A00, 0, 2, 1), 0U);
  EXPECT_EQ(h.write(node, 0x1800, 1, 0x400001A3, 4), 0U);
  // TPDO2: torque actual, error register, position actual; event-driven (254) with a 5 ms
  // event timer and a 1 ms inhibit time.
  EXPECT_EQ(h.write(node, 0x1801, 1, 0xC0000283, 4), 0U);
  EXPECT_EQ(h.write(node, 0x1801, 2, 254, 1), 0U);
  EXPECT_EQ(h.write(node, 0x1801, 3, 10, 2), 0U);
  EXPECT_EQ(h.write(node, 0x1801, 5, 5, 2), 0U);
  EXPECT_EQ(h.write(node, 0x1A01, 0, 0, 1), 0U);
  EXPECT_EQ(h.write(node, 0x1A01, 1, 0x60770010, 4), 0U);
  EXPECT_EQ(h.write(node, 0x1A01, 2, 0x10010008, 4), 0U);
  EXPECT_EQ(h.write(node, 0x1A01, 3, 0x60640020, 4), 0U);
  EXPECT_EQ(h.write(node, 0x1A01, 0, 3, 1), 0U);
  EXPECT_EQ(h.write(node, 0x1801, 1, 0x40000283, 4), 0U);
  // RPDO1 stays as it is after reset (0x203, event-driven, controlword only); mode CST.
  EXPECT_EQ(h.read(node, 0x1400, 1), 0x203U);
  EXPECT_EQ(h.read(node, 0x1400, 2), 255U);
  EXPECT_EQ(h.write(node, 0x6060, 0, 10, 1), 0U);
  EXPECT_EQ(h.write(node, 0x6071, 0, 250, 2), 0U);

  frames = h.exchange({nmt_frame(kNmtStart, node)});
  ASSERT_EQ(with_id(frames, 0x283).size(), 1U) << "event-driven: sent when it starts";
  frames = h.sync();
  ASSERT_EQ(with_id(frames, 0x1A3).size(), 1U);
  EXPECT_FALSE(has_id(frames, 0x183)) << "the default COB-ID is gone";
  can_frame tpdo = with_id(frames, 0x1A3)[0];
  ASSERT_EQ(tpdo.len, 3) << "16 + 8 bits";
  EXPECT_TRUE(is_switch_on_disabled(le16(tpdo, 0)));
  EXPECT_EQ(tpdo.data[2], 10) << "modes of operation display: CST";

  // Event-driven RPDO1: each controlword acts when it arrives, no SYNC needed.
  (void)h.exchange({raw_frame(0x203, {0x06, 0x00})});
  (void)h.exchange({raw_frame(0x203, {0x07, 0x00})});
  frames = h.exchange({raw_frame(0x203, {0x0F, 0x00})});
  EXPECT_EQ(h.bus().node(2).power_state(), canopen::PowerState::operation_enabled);
  // 250 permille of 60 mN·m = 15 mN·m -> 0.6 A -> 0.6 * 0.025 * 10 / 0.01 = 15 N on the insertion.
  EXPECT_NEAR(h.bus().plant().applied_effort(2), 15.0, 1e-9);
  // The torque change is an event for TPDO2, after its 1 ms inhibit time.
  frames = h.poll(1'000'000);
  ASSERT_FALSE(with_id(frames, 0x283).empty());
  const can_frame torque = with_id(frames, 0x283).back();
  ASSERT_EQ(torque.len, 7);
  EXPECT_EQ(static_cast<std::int16_t>(le16(torque, 0)), 250);
  EXPECT_EQ(torque.data[2], 0x00) << "error register";
  frames = h.sync();
  tpdo = with_id(frames, 0x1A3).at(0);
  EXPECT_TRUE(is_operation_enabled(le16(tpdo, 0)));
  // Nothing changes without SYNCs except the event timer: TPDO2 every 5 ms.
  std::size_t timer_frames = 0;
  for (int ms = 0; ms < 20; ++ms) timer_frames += with_id(h.poll(1'000'000), 0x283).size();
  EXPECT_EQ(timer_frames, 4U);
  EXPECT_LE(h.next_deadline(), h.now() + 5'000'000);
}

TEST(IndependentMaster, TheDriveRefusesModesItDoesNotImplement) {
  DriveHarness h;
  (void)h.power_on();
  const SdoResult csp = h.sdo(sdo_download(1, 0x6060, 0, 8, 1));
  EXPECT_EQ(csp.abort, 0x06090030U);
  EXPECT_EQ(h.read(1, 0x6061, 0), 10U);
}

}  // namespace
}  // namespace trainer::hal::simdrive
