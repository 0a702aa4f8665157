// Every per-cycle call of hal_canopen runs without touching the heap: a master cycle and a
// slave cycle exchanging SYNC, PDOs, heartbeats, EMCY and segmented SDO transfers, counted
// by trainer::alloc_hooks over many cycles.
#include <array>
#include <string>

#include <gtest/gtest.h>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/fixed_vector.hpp"
#include "trainer/hal_canopen/bus_error.hpp"
#include "trainer/hal_canopen/cia402.hpp"
#include "trainer/hal_canopen/cia402_drive.hpp"
#include "trainer/hal_canopen/emcy.hpp"
#include "trainer/hal_canopen/frame.hpp"
#include "trainer/hal_canopen/heartbeat.hpp"
#include "trainer/hal_canopen/nmt.hpp"
#include "trainer/hal_canopen/object_dictionary.hpp"
#include "trainer/hal_canopen/pdo.hpp"
#include "trainer/hal_canopen/pdo_dictionary.hpp"
#include "trainer/hal_canopen/sdo_client.hpp"
#include "trainer/hal_canopen/sdo_server.hpp"
#include "trainer/hal_canopen/sync.hpp"

namespace trainer::hal::canopen {
namespace {

constexpr std::uint8_t kHeapNode = 3;

TEST(NoHeap, MasterAndSlaveCyclesAllocateNothing) {
  ASSERT_TRUE(core::alloc::hooks_installed());
  // --- setup (may allocate) ---
  std::array<std::uint8_t, 256> domain{};
  ObjectDictionary od;
  ASSERT_TRUE(od.add({.index = 0x6040, .sub = 0, .type = DataType::u16, .access = Access::wo, .pdo_mappable = true}));
  ASSERT_TRUE(od.add({.index = 0x6041, .sub = 0, .type = DataType::u16, .access = Access::ro, .pdo_mappable = true}));
  ASSERT_TRUE(od.add({.index = 0x6071, .sub = 0, .type = DataType::i16, .access = Access::rw, .pdo_mappable = true}));
  ASSERT_TRUE(od.add({.index = 0x6077, .sub = 0, .type = DataType::i16, .access = Access::ro, .pdo_mappable = true}));
  ASSERT_TRUE(od.add_domain(0x2002, 0, Access::rw, domain, 0));
  PdoMapping rpdo;
  const std::uint32_t rpdo_entries[2] = {0x60400010, 0x60710010};
  ASSERT_EQ(map_from_dictionary(rpdo_entries, PdoDirection::receive, od, rpdo), 0U);
  PdoMapping tpdo;
  const std::uint32_t tpdo_entries[2] = {0x60410010, 0x60770010};
  ASSERT_EQ(map_from_dictionary(tpdo_entries, PdoDirection::transmit, od, tpdo), 0U);
  NmtSlave nmt(kHeapNode);
  SdoServer server(od, kHeapNode);
  Cia402StateMachine drive;
  SdoClient client;
  HeartbeatConsumer heartbeats;
  ASSERT_TRUE(heartbeats.add(kHeapNode, 100).is_ok());
  SyncProducer sync(0);
  std::array<std::uint8_t, 40> payload{};
  std::array<std::uint8_t, 40> readback{};
  for (std::size_t i = 0; i < payload.size(); ++i) payload[i] = static_cast<std::uint8_t>(i * 7);
  core::FixedVector<SdoWrite, kMaxPdoConfigurationWrites> writes;
  PdoConfiguration config;
  config.can_id = cob_id(FrameKind::rpdo, kHeapNode, 1);
  config.mapping = rpdo;
  char text[160];

  std::uint16_t controlword = 0;
  std::uint64_t checksum = 0;
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  (void)nmt.boot();
  nmt.apply(NmtCommand::start);
  for (int cycle = 0; cycle < 20'000; ++cycle) {
    const std::int64_t now = static_cast<std::int64_t>(cycle) * 1'000'000;
    // Master: SYNC, RPDO with the controlword from the drive's state.
    const can_frame sync_frame = sync.next();
    const PowerState state = decode_statusword(static_cast<std::uint16_t>(od.get_int(0x6041, 0).value_or(0)));
    controlword = next_controlword(state, PowerTarget::operation_enabled, controlword);
    const std::int64_t rx_values[2] = {controlword, (cycle % 2000) - 1000};
    can_frame rx = make_frame(config.can_id, {});
    checksum += rpdo.pack(rx_values, rx).is_ok() ? 1U : 0U;
    // Slave: classify, store the RPDO, run the drive, answer with a TPDO and heartbeat.
    checksum += static_cast<std::uint64_t>(classify(sync_frame).kind);
    checksum += decode_sync(sync_frame).has_value() ? 1U : 0U;
    if (classify(rx).kind == FrameKind::rpdo && nmt.pdo_allowed()) {
      checksum += unpack_to_dictionary(rpdo, rx, od).is_ok() ? 1U : 0U;
    }
    if (cycle == 5000) drive.raise_fault(0x2310, now);
    drive.update(static_cast<std::uint16_t>(od.get_int(0x6040, 0).value_or(0)), now);
    const double torque = drive.torque_output(static_cast<double>(od.get_int(0x6071, 0).value_or(0)));
    (void)od.set<std::uint16_t>(0x6041, 0, drive.statusword());
    (void)od.set<std::int16_t>(0x6077, 0, static_cast<std::int16_t>(torque));
    can_frame tx = make_frame(cob_id(FrameKind::tpdo, kHeapNode, 1), {});
    checksum += pack_from_dictionary(tpdo, od, tx).is_ok() ? 1U : 0U;
    std::int64_t tx_values[2] = {};
    checksum += tpdo.unpack(tx, tx_values).is_ok() ? static_cast<std::uint64_t>(tx_values[0]) : 0U;
    if (cycle % 20 == 0) heartbeats.on_frame(encode_heartbeat(kHeapNode, nmt.state()), now);
    heartbeats.on_time(now);
    while (auto event = heartbeats.next_event()) checksum += event->node_id;
    // EMCY and error frames with their texts.
    const auto emcy = decode_emcy(encode_emcy({kHeapNode, 0x8611, 0x21, {}}));
    checksum += emcy ? std::char_traits<char>::length(describe_emcy_code(emcy->error_code)) : 0U;
    checksum += format_error_register(0x21, text).size();
    can_frame error{};
    error.can_id = CAN_ERR_FLAG | 0x4C;
    error.len = 8;
    if (const auto bus = decode_bus_error(error)) checksum += format_bus_error(*bus, text).size();
    // An SDO transfer every cycle: segmented write then read of 40 bytes.
    if (!client.busy()) {
      if (cycle % 2 == 0) {
        (void)client.start_download(kHeapNode, 0x2002, 0, payload, now);
      } else {
        (void)client.start_upload(kHeapNode, 0x2002, 0, readback, now);
      }
    }
    for (int hop = 0; hop < 20; ++hop) {
      if (auto request = client.next_tx()) server.on_frame(*request, now);
      if (auto response = server.next_tx()) client.on_frame(*response, now);
    }
    client.on_time(now);
    server.on_time(now);
    checksum += client.transferred_bytes();
    checksum += std::char_traits<char>::length(describe_sdo_abort(client.abort_code()));
    checksum += pdo_configuration_writes(config, writes).is_ok() ? writes.size() : 0U;
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
  EXPECT_GT(checksum, 0U);
  EXPECT_EQ(readback, payload);
  EXPECT_EQ(client.status(), SdoStatus::done);
  EXPECT_EQ(drive.state(), PowerState::operation_enabled);  // recovered from the fault
}

}  // namespace
}  // namespace trainer::hal::canopen
