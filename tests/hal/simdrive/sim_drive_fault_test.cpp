// Losing the master (heartbeat consumer timeout, RPDO deadline) with each abort-connection
// option, every injected fault's effect on the frames, scheduled faults, and the events log;
// plus the no-heap check of SimDriveBus::poll over many SYNC cycles.
#include <gtest/gtest.h>
#include <linux/can/error.h>

#include <thread>

#include "simdrive_test_support.hpp"
#include "simdrive_setup.hpp"
#include "trainer/core/alloc_counter.hpp"

namespace trainer::hal::simdrive {
namespace {

using namespace test_support;  // NOLINT: test fixtures

constexpr std::uint8_t kMaster = 127;
constexpr std::int64_t kMs = 1'000'000;

// Nodes 1 and 2 with the trainer's PDOs, heartbeat producer 10 ms, consumer of the master
// (30 ms), abort connection `option`, operational, both enabled with 300 permille while the
// master's heartbeat comes every 10 ms (and keeps coming until the test stops it).
void running_drives(DriveHarness& h, std::uint32_t option, std::uint16_t rpdo_timer_ms = 0) {
  (void)h.power_on();
  for (std::uint8_t node = 1; node <= 2; ++node) {
    h.map_trainer_pdos(node, rpdo_timer_ms);
    EXPECT_EQ(h.write(node, 0x1017, 0, 10, 2), 0U);
    EXPECT_EQ(h.write(node, 0x1016, 1, (std::uint32_t{kMaster} << 16) | 30U, 4), 0U);
    EXPECT_EQ(h.write(node, 0x6007, 0, option, 2), 0U);
  }
  (void)h.exchange({nmt_frame(kNmtStart, 0)});
  h.keep_master_alive(kMaster, 10 * kMs);
  (void)h.poll();
  (void)h.sync({DriveHarness::rpdo1(1, 0x06, 0), DriveHarness::rpdo1(2, 0x06, 0)});
  (void)h.sync({DriveHarness::rpdo1(1, 0x07, 0), DriveHarness::rpdo1(2, 0x07, 0)});
  for (int i = 0; i < 12; ++i)
    (void)h.sync({DriveHarness::rpdo1(1, 0x0F, 300), DriveHarness::rpdo1(2, 0x0F, 300)});
  EXPECT_TRUE(is_operation_enabled(static_cast<std::uint16_t>(h.read(1, 0x6041, 0))));
  EXPECT_GT(h.bus().plant().applied_effort(0), 0.0);
}

class AbortConnection : public ::testing::TestWithParam<std::uint32_t> {};

TEST_P(AbortConnection, AMissingMasterHeartbeatAppliesTheOptionWithinTheConsumerTime) {
  const std::uint32_t option = GetParam();
  DriveHarness h;
  running_drives(h, option);
  h.stop_master_heartbeat();  // the trainer is killed
  const std::int64_t last_heartbeat = h.last_master_heartbeat();
  std::vector<DriveEvent> events = h.events();
  ASSERT_EQ(of_kind(events, EventKind::master_heartbeat_seen, 1).size(), 1U);
  EXPECT_EQ(of_kind(events, EventKind::master_heartbeat_seen, 1)[0].a, kMaster);
  EXPECT_LE(h.next_deadline(), last_heartbeat + 30 * kMs + 1)
      << "poll() asks to be called at the deadline";
  // The master stops (no SYNC, no RPDO, no heartbeat). 30 ms after its last heartbeat: still fine.
  (void)h.poll(last_heartbeat + 30 * kMs - h.now());
  EXPECT_TRUE(is_operation_enabled(h.bus().node(0).statusword()));
  const std::vector<can_frame> frames = h.poll(1 * kMs);
  // EMCY 0x8130 (heartbeat / life guard error), error register: communication.
  const auto emcy = with_id(frames, 0x081);
  ASSERT_EQ(emcy.size(), 1U);
  EXPECT_EQ(emcy[0].len, 8);
  EXPECT_EQ(le16(emcy[0], 0), 0x8130U);
  EXPECT_NE(emcy[0].data[2] & 0x10, 0) << "error register bit 4: communication";
  const std::uint16_t status = h.bus().node(0).statusword();
  events = h.events();
  const auto lost = of_kind(events, EventKind::master_heartbeat_lost, 1);
  ASSERT_EQ(lost.size(), 1U);
  EXPECT_EQ(lost[0].t_ns - last_heartbeat, 31 * kMs);
  const auto removed = of_kind(events, EventKind::torque_removed, 1);
  switch (option) {
    case 0:  // no action: the drive keeps its torque
      EXPECT_TRUE(is_operation_enabled(status));
      EXPECT_GT(h.bus().plant().applied_effort(0), 0.0);
      EXPECT_TRUE(removed.empty());
      break;
    case 1:
      EXPECT_TRUE(is_fault(status));
      EXPECT_EQ(h.read(1, 0x603F, 0), 0x8130U);
      break;
    case 2:
    case 3:  // disable voltage / quick stop (0x605A = 2, no ramp for torque): Switch on disabled
      EXPECT_TRUE(is_switch_on_disabled(status));
      break;
    default: break;
  }
  if (option != 0) {
    EXPECT_EQ(h.bus().plant().applied_effort(0), 0.0);
    EXPECT_EQ(h.bus().node(0).output().effort, 0.0);
    ASSERT_EQ(removed.size(), 1U);
    EXPECT_STREQ(removed[0].cause, "master heartbeat lost");
    EXPECT_LE(removed[0].t_ns - last_heartbeat, 31 * kMs)
        << "torque removed within the consumer time + 1 ms";
  }
  EXPECT_EQ(of_kind(events, EventKind::abort_connection, 1).at(0).a, option);
  // JSON line of the event a test reads from simdrive --events.
  const std::string json = to_json(lost[0]);
  EXPECT_NE(json.find("\"event\":\"master_heartbeat_lost\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"node\":1"), std::string::npos) << json;
  EXPECT_NE(json.find("\"producer\":127"), std::string::npos) << json;
  EXPECT_NE(json.find("\"t_ns\":" + std::to_string(lost[0].t_ns)), std::string::npos) << json;
}

INSTANTIATE_TEST_SUITE_P(Options, AbortConnection, ::testing::Values(0U, 1U, 2U, 3U));

TEST(SimDriveConnection, HeartbeatMonitoringStartsOnlyWithTheFirstHeartbeat) {
  DriveHarness h;
  (void)h.power_on();
  EXPECT_EQ(h.write(1, 0x1016, 1, (std::uint32_t{kMaster} << 16) | 30U, 4), 0U);
  (void)h.exchange({nmt_frame(kNmtStart, 1)});
  for (int i = 0; i < 10; ++i) EXPECT_FALSE(has_id(h.poll(100 * kMs), 0x081));
  EXPECT_TRUE(of_kind(h.events(), EventKind::master_heartbeat_lost).empty());
  (void)h.exchange({heartbeat_frame(kMaster, 0x05)});
  EXPECT_TRUE(has_id(h.poll(31 * kMs), 0x081));
  // Heard again: recovered. 0x6007 defaults to 1 (fault signal), so the drive sits in Fault
  // (even from Switch on disabled) and no "no error" EMCY follows until a fault reset.
  std::vector<can_frame> frames = h.exchange({heartbeat_frame(kMaster, 0x05)});
  EXPECT_FALSE(has_id(frames, 0x081));
  EXPECT_EQ(of_kind(h.events(), EventKind::master_heartbeat_recovered, 1).size(), 1U);
}

TEST(SimDriveConnection, TheRpdoDeadlineStartsWithTheFirstRpdoAndTripsAfterItsEventTimer) {
  DriveHarness h;
  (void)h.power_on();
  h.map_trainer_pdos(1, 10);
  (void)h.exchange({nmt_frame(kNmtStart, 1)});
  // SYNCs without an RPDO: not armed yet.
  for (int i = 0; i < 50; ++i) EXPECT_FALSE(has_id(h.sync(), 0x081));
  (void)h.enable(1, 200);
  const std::int64_t last_rpdo = h.now();  // stamped when the bus polled it, with the SYNC
  EXPECT_TRUE(is_operation_enabled(h.bus().node(0).statusword()));
  // SYNCs keep coming, RPDOs do not.
  std::vector<can_frame> frames;
  while (h.now() - last_rpdo < 10 * kMs) {
    frames = h.sync();
    EXPECT_FALSE(has_id(frames, 0x081)) << "at " << (h.now() - last_rpdo) / kMs << " ms";
  }
  frames = h.poll(1 * kMs);
  const auto emcy = with_id(frames, 0x081);
  ASSERT_EQ(emcy.size(), 1U);
  EXPECT_EQ(le16(emcy[0], 0), 0x8250U) << "RPDO timeout";
  EXPECT_TRUE(is_fault(h.bus().node(0).statusword())) << "0x6007 default 1: fault signal";
  EXPECT_EQ(h.read(1, 0x603F, 0), 0x8250U);
  EXPECT_EQ(h.bus().plant().applied_effort(0), 0.0);
  const auto expired = of_kind(h.events(), EventKind::rpdo_deadline_expired, 1);
  ASSERT_EQ(expired.size(), 1U);
  EXPECT_EQ(expired[0].a, 1U);
  EXPECT_EQ(expired[0].b, 10U);
  // Fault reset (bit 7 edge) by RPDO: Switch on disabled, "no error" EMCY, register clear.
  (void)h.sync({DriveHarness::rpdo1(1, 0x00, 0)});
  frames = h.sync({DriveHarness::rpdo1(1, 0x80, 0)});
  EXPECT_TRUE(is_switch_on_disabled(h.bus().node(0).statusword()));
  ASSERT_EQ(with_id(frames, 0x081).size(), 1U);
  EXPECT_EQ(le16(with_id(frames, 0x081)[0], 0), 0x0000U);
  EXPECT_EQ(with_id(frames, 0x081)[0].data[2], 0x00);
}

TEST(SimDriveConnection, NmtStopLosesTheConnectionButPreOperationalDoesNot) {
  DriveHarness h;
  running_drives(h, 2);
  (void)h.exchange({nmt_frame(kNmtPreOperational, 2)});
  EXPECT_TRUE(is_operation_enabled(h.bus().node(1).statusword()))
      << "not an abort-connection event";
  (void)h.exchange({nmt_frame(kNmtStop, 1)});
  EXPECT_TRUE(is_switch_on_disabled(h.bus().node(0).statusword())) << "0x6007 = 2 on NMT stop";
  EXPECT_EQ(h.bus().plant().applied_effort(0), 0.0);
}

// ------------------------------------------------------------------------------ faults

std::vector<can_frame> fault_now(DriveHarness& h, const char* spec) {
  auto parsed = parse_fault_spec(spec);
  EXPECT_TRUE(parsed) << (parsed ? "" : parsed.error().message);
  EXPECT_TRUE(h.bus().inject(*parsed, h.now()));
  return h.receive();
}

std::vector<can_frame> running_sync(DriveHarness& h) {
  return h.sync({DriveHarness::rpdo1(1, 0x0F, 300), DriveHarness::rpdo1(2, 0x0F, 300)});
}

TEST(SimDriveFaults, DropWithholdsTheTpdosForCountSyncs) {
  DriveHarness h;
  running_drives(h, 3);
  (void)fault_now(h, "drop:node=1,count=5");
  for (int i = 0; i < 5; ++i) {
    const auto frames = running_sync(h);
    EXPECT_FALSE(has_id(frames, 0x181)) << "SYNC " << i;
    EXPECT_TRUE(has_id(frames, 0x182)) << "other nodes unaffected";
  }
  EXPECT_TRUE(has_id(running_sync(h), 0x181));
  EXPECT_EQ(h.bus().node_stats(0).tpdos_dropped, 5U);
  // Heartbeats still flow during a drop.
  (void)fault_now(h, "drop:node=1");
  std::vector<can_frame> frames;
  for (int i = 0; i < 12; ++i) {
    const auto more = running_sync(h);
    frames.insert(frames.end(), more.begin(), more.end());
  }
  EXPECT_FALSE(has_id(frames, 0x181));
  EXPECT_TRUE(has_id(frames, 0x701));
  (void)fault_now(h, "clear:node=1");
  EXPECT_TRUE(has_id(running_sync(h), 0x181));
}

TEST(SimDriveFaults, DelayHoldsTheTpdosBackByItsTime) {
  DriveHarness h;
  running_drives(h, 3);
  (void)fault_now(h, "delay:node=2,ms=5,count=1");
  std::vector<can_frame> frames = running_sync(h);
  EXPECT_FALSE(has_id(frames, 0x182));
  EXPECT_TRUE(has_id(frames, 0x181));
  const std::int64_t due = h.now() + 5 * kMs;
  EXPECT_LE(h.next_deadline(), due);
  frames = h.poll(4 * kMs);
  EXPECT_FALSE(has_id(frames, 0x182));
  frames = h.poll(1 * kMs);
  ASSERT_EQ(with_id(frames, 0x182).size(), 1U) << "released 5 ms after its SYNC";
  EXPECT_TRUE(has_id(running_sync(h), 0x182)) << "count=1: the next SYNC's TPDO is on time";
}

TEST(SimDriveFaults, CorruptShortensTpdo1OrFlipsItsBits) {
  DriveHarness h;
  running_drives(h, 3);
  const can_frame good = with_id(running_sync(h), 0x181).at(0);
  (void)fault_now(h, "corrupt:node=1");
  can_frame bad = with_id(running_sync(h), 0x181).at(0);
  EXPECT_EQ(bad.len, 7) << "one byte short of its mapping";
  EXPECT_EQ(with_id(running_sync(h), 0x181).at(0).len, 8) << "count=1 by default";
  (void)fault_now(h, "corrupt:node=1,mode=bits,count=2");
  bad = with_id(running_sync(h), 0x181).at(0);
  EXPECT_EQ(bad.len, 8);
  EXPECT_EQ(le16(bad, 0) & 0x4F, 0x0F) << "bit 3 of the statusword flipped: fault reaction active";
  EXPECT_TRUE(is_operation_enabled(h.bus().node(0).statusword())) << "the drive itself is fine";
  (void)fault_now(h, "corrupt:node=1,mode=bits,byte=1,mask=0x40");
  const can_frame flipped = with_id(running_sync(h), 0x181).at(0);
  EXPECT_EQ(flipped.data[1] ^ good.data[1], 0x40) << "statusword bit 14 flipped";
  EXPECT_EQ(flipped.data[0], good.data[0]);
}

TEST(SimDriveFaults, SilentSendsNothingAtAllUntilCleared) {
  DriveHarness h;
  running_drives(h, 3);
  EXPECT_TRUE(fault_now(h, "silent:node=1").empty());
  std::vector<can_frame> frames;
  for (int i = 0; i < 25; ++i) {
    const auto more = running_sync(h);
    frames.insert(frames.end(), more.begin(), more.end());
  }
  const auto sdo = h.sdo(sdo_upload(1, 0x1000, 0));
  EXPECT_FALSE(sdo.answered);
  for (const can_frame& frame : frames)
    EXPECT_NE(frame.can_id & 0x7F, 1U) << std::hex << frame.can_id;
  EXPECT_TRUE(has_id(frames, 0x702));
  EXPECT_TRUE(is_operation_enabled(h.bus().node(0).statusword())) << "it still drives its joint";
  EXPECT_GT(h.bus().plant().applied_effort(0), 0.0);
  (void)fault_now(h, "clear:node=1");
  frames = running_sync(h);
  EXPECT_TRUE(has_id(frames, 0x181));
}

TEST(SimDriveFaults, BusOffSendsTheErrorFrameAndEveryNodeDropsItsTorqueAndFallsSilent) {
  DriveHarness h;
  running_drives(h, 3);
  const std::vector<can_frame> frames = fault_now(h, "bus_off");
  ASSERT_EQ(frames.size(), 1U);
  EXPECT_EQ(frames[0].can_id, CAN_ERR_FLAG | CAN_ERR_BUSOFF);
  EXPECT_EQ(frames[0].len, 8);
  EXPECT_TRUE(h.bus().bus_off());
  EXPECT_TRUE(is_switch_on_disabled(h.bus().node(0).statusword())) << "0x6007 = 3 on bus-off";
  EXPECT_EQ(h.bus().plant().applied_effort(0), 0.0);
  const std::int64_t plant_before = h.bus().plant_time_ns();
  for (int i = 0; i < 20; ++i) EXPECT_TRUE(running_sync(h).empty());
  EXPECT_EQ(h.bus().plant_time_ns() - plant_before, 20 * kSyncPeriodNs) << "the plant keeps going";
  EXPECT_TRUE(is_switch_on_disabled(h.bus().node(0).statusword()))
      << "deaf: the enable commands do not arrive";
  const auto removed = of_kind(h.events(), EventKind::torque_removed, 1);
  ASSERT_EQ(removed.size(), 1U);
  EXPECT_STREQ(removed[0].cause, "bus-off");
  (void)fault_now(h, "clear");
  EXPECT_FALSE(h.bus().bus_off());
  EXPECT_TRUE(has_id(running_sync(h), 0x181));
}

TEST(SimDriveFaults, EmcyFaultsTheDriveUntilTheMasterResetsIt) {
  DriveHarness h;
  running_drives(h, 3);
  std::vector<can_frame> frames = fault_now(h, "emcy:node=2");
  const auto emcy = with_id(frames, 0x082);
  ASSERT_EQ(emcy.size(), 1U);
  EXPECT_EQ(le16(emcy[0], 0), 0x2310U);
  EXPECT_EQ(emcy[0].data[2], 0x03) << "generic + current";
  EXPECT_TRUE(is_fault(h.bus().node(1).statusword()));
  EXPECT_EQ(h.bus().plant().applied_effort(1), 0.0);
  frames = running_sync(h);
  EXPECT_TRUE(is_fault(le16(with_id(frames, 0x182).at(0), 0)));
  EXPECT_EQ(h.read(2, 0x603F, 0), 0x2310U);
  EXPECT_EQ(h.read(2, 0x1001, 0), 0x03U);
  (void)h.sync({DriveHarness::rpdo1(2, 0x00, 0)});
  frames = h.sync({DriveHarness::rpdo1(2, 0x80, 0)});
  ASSERT_EQ(with_id(frames, 0x082).size(), 1U);
  EXPECT_EQ(le16(with_id(frames, 0x082)[0], 0), 0x0000U);
  EXPECT_TRUE(is_switch_on_disabled(h.bus().node(1).statusword()));
  EXPECT_EQ(h.read(2, 0x1001, 0), 0U);
  const auto sent = of_kind(h.events(), EventKind::emcy_sent, 2);
  ASSERT_EQ(sent.size(), 2U);
  EXPECT_EQ(sent[0].a, 0x2310U);
  EXPECT_EQ(sent[1].a, 0U);
}

TEST(SimDriveFaults, EncoderJumpOffsetsPositionActualFromThenOn) {
  DriveHarness h;
  running_drives(h, 3);
  const hal::JointScale& scale = h.bus().params().plant.instruments[0].scales[0];
  const auto truth = [&] { return scale.counts_from_position(h.bus().plant().true_position(0)); };
  const auto reported = [&] {
    return static_cast<std::int32_t>(le32(with_id(running_sync(h), 0x181).at(0), 2));
  };
  const std::int32_t before = reported();
  EXPECT_EQ(before, truth());
  (void)fault_now(h, "encoder_jump:node=1,counts=5000");
  for (int i = 0; i < 3; ++i) {
    const std::int32_t after = reported();
    EXPECT_EQ(after - truth(), 5000) << "the joint moves; the report is 5000 counts off it";
  }
}

TEST(SimDriveFaults, LostSyncSkipsTheTpdosAndTheCommandsOfCountSyncs) {
  DriveHarness h;
  running_drives(h, 3);
  (void)fault_now(h, "lost_sync:node=1,count=3");
  for (int i = 0; i < 3; ++i) {
    const auto frames =
        h.sync({DriveHarness::rpdo1(1, 0x02, 0), DriveHarness::rpdo1(2, 0x0F, 300)});
    EXPECT_FALSE(has_id(frames, 0x181));
    EXPECT_TRUE(has_id(frames, 0x182));
    EXPECT_TRUE(is_operation_enabled(h.bus().node(0).statusword())) << "the quick stop waits";
  }
  const auto frames = running_sync(h);
  EXPECT_TRUE(has_id(frames, 0x181));
  EXPECT_EQ(h.bus().node_stats(0).syncs_ignored, 3U);
}

TEST(SimDriveFaults, RebootSendsABootUpAndComesBackWithDefaults) {
  DriveHarness h;
  running_drives(h, 3);
  std::vector<can_frame> frames = fault_now(h, "reboot:node=2");
  ASSERT_EQ(with_id(frames, 0x702).size(), 1U);
  EXPECT_EQ(with_id(frames, 0x702)[0].data[0], 0x00);
  EXPECT_EQ(h.bus().node(1).nmt_state(), canopen::NmtState::pre_operational);
  EXPECT_TRUE(is_switch_on_disabled(h.bus().node(1).statusword()));
  EXPECT_EQ(h.bus().plant().applied_effort(1), 0.0);
  frames = running_sync(h);
  EXPECT_FALSE(has_id(frames, 0x182)) << "pre-operational: no PDO";
  EXPECT_EQ(h.read(2, 0x1017, 0), 0U);
  EXPECT_EQ(h.read(2, 0x1A00, 0), 1U) << "mapping back to the default";
  EXPECT_EQ(h.read(2, 0x1016, 1), 0U);
}

TEST(SimDriveFaults, ScheduledFaultsFireAtTheirSyncOrTimeAfterTheFirstNmtStart) {
  DriveHarness h;
  (void)h.power_on();
  h.map_trainer_pdos(1);
  h.map_trainer_pdos(2);
  EXPECT_TRUE(h.bus().inject(*parse_fault_spec("emcy:node=1,at_sync=5,code=0x4310"), h.now()));
  EXPECT_TRUE(h.bus().inject(*parse_fault_spec("silent:node=2,at_s=0.0205"), h.now()));
  EXPECT_FALSE(h.bus().inject(*parse_fault_spec("reboot:node=9"), h.now())) << "no node 9";
  for (int i = 0; i < 10; ++i)
    EXPECT_FALSE(has_id(h.sync(), 0x081)) << "not started: nothing fires";
  (void)h.exchange({nmt_frame(kNmtStart, 0)});
  for (int sync = 1; sync <= 30; ++sync) {
    const auto frames = h.sync();
    EXPECT_EQ(has_id(frames, 0x081), sync == 5) << "SYNC " << sync;
    EXPECT_EQ(has_id(frames, 0x182), sync <= 20) << "SYNC " << sync;
  }
  const auto injected = of_kind(h.events(), EventKind::fault_injected);
  ASSERT_EQ(injected.size(), 2U);
  EXPECT_STREQ(injected[0].text.data(), "emcy:node=1,at_sync=5,code=0x4310");
  EXPECT_EQ(injected[0].node, 1);
  EXPECT_EQ(injected[0].sync, 15U) << "10 SYNCs before the start + 5";
  EXPECT_EQ(injected[1].sync, 30U) << "20.5 ms: before the 21st SYNC after the start";
}

TEST(SimDriveFaults, PostedFromAnotherThreadActsAtTheNextPoll) {
  DriveHarness h;
  running_drives(h, 3);
  std::thread other(
      [&] { EXPECT_TRUE(h.bus().post(*parse_fault_spec("emcy:node=1,code=0x3210"))); });
  other.join();
  const auto frames = h.poll();
  ASSERT_EQ(with_id(frames, 0x081).size(), 1U);
  EXPECT_EQ(le16(with_id(frames, 0x081)[0], 0), 0x3210U);
  EXPECT_EQ(with_id(frames, 0x081)[0].data[2], 0x05) << "generic + voltage";
}

// ------------------------------------------------------------------------------ no heap

TEST(SimDriveBusRt, PollDoesNotTouchTheHeapOverThousandsOfSyncCycles) {
  DriveHarness h(test_bus_params("builtin:sweep"));
  running_drives(h, 3, 10);
  h.stop_master_heartbeat();  // sent below, as part of the measured cycles
  const std::array<can_frame, 3> frames{DriveHarness::rpdo1(1, 0x0F, 300),
                                        DriveHarness::rpdo1(2, 0x0F, -300),
                                        heartbeat_frame(kMaster, 0x05)};
  ASSERT_TRUE(h.bus().inject(*parse_fault_spec("drop:node=2,at_sync=300,count=5"), h.now()));
  ASSERT_TRUE(h.bus().inject(*parse_fault_spec("delay:node=1,at_sync=500,ms=3,count=20"), h.now()));
  ASSERT_TRUE(h.bus().inject(*parse_fault_spec("corrupt:node=1,at_sync=700,count=10"), h.now()));
  ASSERT_TRUE(
      h.bus().inject(*parse_fault_spec("encoder_jump:node=2,at_sync=800,counts=100"), h.now()));
  std::array<can_frame, 64> sink{};
  std::int64_t now = h.now();
  std::uint64_t received = 0;
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (int cycle = 0; cycle < 5000; ++cycle) {
    now += kSyncPeriodNs;
    const std::size_t count = cycle % 10 == 0 ? 3 : 2;  // a master heartbeat every 10 ms
    (void)h.master().send(std::span(frames.data(), count));
    (void)h.master().send_one(sync_frame());
    (void)h.bus().poll(now);
    received += h.master().receive(sink);
    received += h.master().receive(sink);
    DriveEvent event;
    while (h.bus().events().pop(event)) {
    }
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
  EXPECT_GT(received, 5000U * 2);
  EXPECT_TRUE(is_operation_enabled(h.bus().node(0).statusword()));
  EXPECT_EQ(h.bus().node_stats(1).tpdos_dropped, 5U);
  EXPECT_EQ(h.bus().node_stats(0).tpdos_delayed, 20U);
}

}  // namespace
}  // namespace trainer::hal::simdrive

// ---------------------------------------------------------------- miswiring and the hand (hil)

namespace trainer::hal::simdrive {
namespace {

using namespace test_support;  // NOLINT: test fixtures

TEST(SimDriveMiswiring, AReversedEncoderReportsThePositionNegated) {
  SimDriveBusParams params = test_bus_params();
  params.nodes[0].reverse_encoder = true;
  DriveHarness h(std::move(params));
  running_drives(h, 3);
  const hal::JointScale& scale = h.bus().params().plant.instruments[0].scales[0];
  for (int i = 0; i < 3; ++i) {
    const auto frames = running_sync(h);
    const auto reported = static_cast<std::int32_t>(le32(with_id(frames, 0x181).at(0), 2));
    EXPECT_EQ(reported, -scale.counts_from_position(h.bus().plant().true_position(0)));
    EXPECT_NE(reported, 0);
  }
}

TEST(SimDriveMiswiring, AReversedMotorTurnsTheJointTheOtherWay) {
  SimDriveBusParams params = test_bus_params();
  params.nodes[1].reverse_motor = true;
  DriveHarness h(std::move(params));
  running_drives(h, 3);  // both commanded +300 permille
  EXPECT_GT(h.bus().plant().applied_effort(0), 0.0);
  EXPECT_LT(h.bus().plant().applied_effort(1), 0.0);
  EXPECT_GT(static_cast<std::int16_t>(h.bus().node(1).torque_actual_permille()), 0)
      << "the drive's own torque actual keeps the commanded sign";
}

TEST(SimDriveMiswiring, APushMovesTheJointByAboutItsMoveWithTheDrivesOff) {
  DriveHarness h;
  running_drives(h, 3);
  const auto idle = [&] {
    return h.sync({DriveHarness::rpdo1(1, 0x06, 0), DriveHarness::rpdo1(2, 0x06, 0)});
  };
  for (int i = 0; i < 300; ++i) (void)idle();
  const double before = h.bus().plant().true_position(0);
  const double other_before = h.bus().plant().true_position(1);
  (void)fault_now(h, "push:node=1,move=0.05,count=400");
  for (int i = 0; i < 300; ++i) (void)idle();
  EXPECT_NEAR(h.bus().plant().true_position(0) - before, 0.05, 0.01);
  EXPECT_NEAR(h.bus().plant().true_position(1), other_before, 0.001) << "only node 1's joint";
  for (int i = 0; i < 400; ++i) (void)idle();  // the push ended after its 400 SYNCs
  EXPECT_NEAR(h.bus().plant().true_position(0), before, 0.01);
}

// simdrive's --miswire / --node-id-map (tools/simdrive simdrive_setup).
TEST(SimDriveMiswiring, OptionsParseApplyAndRefuseWhatCannotBeWired) {
  namespace ts = trainer::tools::simdrive;
  ts::Miswiring miswiring;
  ASSERT_TRUE(ts::parse_miswire("reverse_encoder:node=2", miswiring));
  ASSERT_TRUE(ts::parse_miswire("reverse_motor:node=4", miswiring));
  ASSERT_TRUE(ts::parse_node_id_map("3=13", miswiring));
  SimDriveBusParams params = test_bus_params();
  ASSERT_TRUE(ts::apply_miswiring(miswiring, params));
  EXPECT_TRUE(params.nodes[1].reverse_encoder);
  EXPECT_FALSE(params.nodes[0].reverse_encoder);
  EXPECT_TRUE(params.nodes[3].reverse_motor);
  EXPECT_EQ(params.nodes[2].node_id, 13);
  EXPECT_EQ(params.nodes[2].identity.serial_number, 1003U) << "the same drive, another id";

  const auto refusal = [](auto&& result) {
    return result ? std::string() : result.error().message;
  };
  ts::Miswiring bad;
  EXPECT_EQ(refusal(ts::parse_miswire("reverse_encoder:node=0", bad)),
            "--miswire 'reverse_encoder:node=0': expected KIND:node=N with N a node id 1..127");
  EXPECT_EQ(refusal(ts::parse_miswire("swap:node=2", bad)),
            "--miswire 'swap:node=2': unknown kind 'swap': expected reverse_encoder or "
            "reverse_motor");
  EXPECT_EQ(refusal(ts::parse_node_id_map("3-13", bad)),
            "--node-id-map '3-13': expected FILE_ID=BUS_ID, both node ids 1..127 (e.g. 3=13)");
  ts::Miswiring clash;
  ASSERT_TRUE(ts::parse_node_id_map("3=2", clash));
  SimDriveBusParams clash_params = test_bus_params();
  EXPECT_EQ(refusal(ts::apply_miswiring(clash, clash_params)),
            "--node-id-map: two drives would answer as node 2");
  ts::Miswiring absent;
  ASSERT_TRUE(ts::parse_miswire("reverse_motor:node=40", absent));
  SimDriveBusParams absent_params = test_bus_params();
  EXPECT_EQ(refusal(ts::apply_miswiring(absent, absent_params)),
            "--miswire reverse_motor: node 40 is not a drive of the device file");
}

}  // namespace
}  // namespace trainer::hal::simdrive
