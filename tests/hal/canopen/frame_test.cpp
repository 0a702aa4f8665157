// Identifiers and classification, SocketCAN error frames, NMT (codec and slave state
// machine), SYNC, heartbeat (codec and consumer), EMCY (codec and texts): byte-exact frames
// as CiA 301 v4.2 defines them.
#include <linux/can/error.h>

#include <array>
#include <cstring>
#include <string>
#include <string_view>

#include <gtest/gtest.h>

#include "trainer/hal_canopen/bus_error.hpp"
#include "trainer/hal_canopen/emcy.hpp"
#include "trainer/hal_canopen/frame.hpp"
#include "trainer/hal_canopen/heartbeat.hpp"
#include "trainer/hal_canopen/nmt.hpp"
#include "trainer/hal_canopen/sync.hpp"

namespace trainer::hal::canopen {
namespace {

can_frame frame_of(canid_t id, std::initializer_list<std::uint8_t> bytes) {
  can_frame frame{};
  frame.can_id = id;
  frame.len = static_cast<std::uint8_t>(bytes.size());
  std::copy(bytes.begin(), bytes.end(), frame.data);
  return frame;
}

constexpr std::int64_t kFrameMs = 1'000'000;

// --- classification ------------------------------------------------------------------------

TEST(Classify, PredefinedConnectionSet) {
  struct Case {
    canid_t id;
    std::uint8_t len;
    FrameKind kind;
    std::uint8_t node;
    std::uint8_t pdo;
  };
  const Case cases[] = {
      {0x000, 2, FrameKind::nmt, 0, 0},          {0x080, 0, FrameKind::sync, 0, 0},
      {0x080, 1, FrameKind::sync, 0, 0},         {0x085, 8, FrameKind::emcy, 5, 0},
      {0x100, 6, FrameKind::time, 0, 0},         {0x185, 8, FrameKind::tpdo, 5, 1},
      {0x205, 3, FrameKind::rpdo, 5, 1},         {0x285, 0, FrameKind::tpdo, 5, 2},
      {0x305, 8, FrameKind::rpdo, 5, 2},         {0x385, 8, FrameKind::tpdo, 5, 3},
      {0x405, 8, FrameKind::rpdo, 5, 3},         {0x4FF, 8, FrameKind::tpdo, 127, 4},
      {0x501, 8, FrameKind::rpdo, 1, 4},         {0x585, 8, FrameKind::sdo_response, 5, 0},
      {0x605, 8, FrameKind::sdo_request, 5, 0},  {0x705, 1, FrameKind::heartbeat, 5, 0},
      {0x001, 0, FrameKind::unknown, 0, 0},      {0x7E4, 8, FrameKind::unknown, 0, 0},
      {0x180, 8, FrameKind::unknown, 0, 0},      {0x6E0, 8, FrameKind::unknown, 0, 0},
  };
  for (const Case& c : cases) {
    can_frame frame{};
    frame.can_id = c.id;
    frame.len = c.len;
    const FrameClass result = classify(frame);
    EXPECT_EQ(result.kind, c.kind) << std::hex << c.id;
    EXPECT_EQ(result.node_id, c.node) << std::hex << c.id;
    EXPECT_EQ(result.pdo_number, c.pdo) << std::hex << c.id;
    EXPECT_TRUE(result.ok()) << std::hex << c.id << " " << to_string(result.problem);
  }
}

TEST(Classify, RejectsWhatTheProtocolForbids) {
  EXPECT_EQ(classify(frame_of(0x000, {1})).problem, FrameProblem::bad_length);               // NMT is 2 bytes
  EXPECT_EQ(classify(frame_of(0x080, {1, 2})).problem, FrameProblem::bad_length);            // SYNC 0/1
  EXPECT_EQ(classify(frame_of(0x085, {0, 0, 0, 0})).problem, FrameProblem::bad_length);      // EMCY 8
  EXPECT_EQ(classify(frame_of(0x605, {0x40, 0, 0x10, 0})).problem, FrameProblem::bad_length);  // SDO 8
  EXPECT_EQ(classify(frame_of(0x705, {0, 0})).problem, FrameProblem::bad_length);            // heartbeat 1
  can_frame rtr = frame_of(0x705 | CAN_RTR_FLAG, {});
  EXPECT_EQ(classify(rtr).problem, FrameProblem::remote_request);  // node guarding request
  EXPECT_EQ(classify(rtr).kind, FrameKind::heartbeat);
  const FrameClass extended = classify(frame_of(0x185 | CAN_EFF_FLAG, {1}));
  EXPECT_EQ(extended.problem, FrameProblem::extended_id);
  EXPECT_EQ(extended.kind, FrameKind::unknown);
  EXPECT_EQ(classify(frame_of(0x885, {0, 0, 0, 0, 0, 0, 0, 0})).problem, FrameProblem::extended_id);
  EXPECT_FALSE(decode_emcy(frame_of(0x885, {0, 0, 0, 0, 0, 0, 0, 0})).has_value());
  EXPECT_FALSE(decode_heartbeat(frame_of(0x1705, {5})).has_value());
  can_frame too_long = frame_of(0x185, {});
  too_long.len = 9;
  EXPECT_EQ(classify(too_long).problem, FrameProblem::bad_length);
}

TEST(Classify, DefaultCobIdsAndFrameBuilder) {
  EXPECT_EQ(cob_id(FrameKind::emcy, 3), 0x083);
  EXPECT_EQ(cob_id(FrameKind::tpdo, 3, 1), 0x183);
  EXPECT_EQ(cob_id(FrameKind::tpdo, 3, 4), 0x483);
  EXPECT_EQ(cob_id(FrameKind::rpdo, 3, 1), 0x203);
  EXPECT_EQ(cob_id(FrameKind::rpdo, 3, 4), 0x503);
  EXPECT_EQ(cob_id(FrameKind::sdo_response, 3), 0x583);
  EXPECT_EQ(cob_id(FrameKind::sdo_request, 3), 0x603);
  EXPECT_EQ(cob_id(FrameKind::heartbeat, 3), 0x703);
  EXPECT_EQ(cob_id(FrameKind::rpdo, 3, 5), 0);
  EXPECT_EQ(cob_id(FrameKind::heartbeat, 0), 0);
  EXPECT_EQ(cob_id(FrameKind::heartbeat, 128), 0);
  const std::uint8_t nine[9] = {1, 2, 3, 4, 5, 6, 7, 8, 9};
  const can_frame frame = make_frame(0x1234, nine);  // id masked to 11 bits, data cut at 8
  EXPECT_EQ(frame.can_id, 0x234U);
  EXPECT_EQ(frame.len, 8);
  EXPECT_EQ(frame.data[7], 8);
}

// --- error frames ------------------------------------------------------------------------------

TEST(BusError, DecodesBusOffAndControllerProblems) {
  can_frame frame = frame_of(CAN_ERR_FLAG | CAN_ERR_BUSOFF | CAN_ERR_CRTL | CAN_ERR_CNT,
                             {0, CAN_ERR_CRTL_TX_PASSIVE | CAN_ERR_CRTL_RX_WARNING, 0, 0, 0, 0, 200, 97});
  EXPECT_EQ(classify(frame).kind, FrameKind::error_frame);
  const auto error = decode_bus_error(frame);
  ASSERT_TRUE(error.has_value());
  EXPECT_TRUE(error->bus_off);
  EXPECT_TRUE(error->controller);
  EXPECT_FALSE(error->no_ack);
  EXPECT_EQ(error->severity, BusSeverity::bus_off);
  EXPECT_EQ(error->tx_error_count, 200);
  EXPECT_EQ(error->rx_error_count, 97);
  char text[160];
  EXPECT_EQ(format_bus_error(*error, text),
            "bus-off; controller: rx warning, tx error passive; tx/rx error counters 200/97");
}

TEST(BusError, ProtocolAckArbitrationRestart) {
  const auto protocol = decode_bus_error(
      frame_of(CAN_ERR_FLAG | CAN_ERR_PROT | CAN_ERR_ACK, {0, 0, CAN_ERR_PROT_FORM | CAN_ERR_PROT_TX,
                                                           CAN_ERR_PROT_LOC_ACK, 0, 0, 0, 0}));
  ASSERT_TRUE(protocol.has_value());
  EXPECT_EQ(protocol->severity, BusSeverity::warning);
  char text[160];
  EXPECT_EQ(format_bus_error(*protocol, text),
            "protocol violation: form error, on transmission at ACK slot; no ACK on transmission");
  const auto arbitration = decode_bus_error(frame_of(CAN_ERR_FLAG | CAN_ERR_LOSTARB, {12, 0, 0, 0, 0, 0, 0, 0}));
  ASSERT_TRUE(arbitration.has_value());
  EXPECT_EQ(arbitration->arbitration_bit, 12);
  EXPECT_EQ(format_bus_error(*arbitration, text), "lost arbitration at bit 12");
  const auto restarted = decode_bus_error(
      frame_of(CAN_ERR_FLAG | CAN_ERR_RESTARTED | CAN_ERR_CRTL, {0, CAN_ERR_CRTL_ACTIVE, 0, 0, 0, 0, 0, 0}));
  ASSERT_TRUE(restarted.has_value());
  EXPECT_EQ(restarted->severity, BusSeverity::info);
  EXPECT_EQ(format_bus_error(*restarted, text), "controller restarted; controller: back to error active");
  // Passive by counters alone; a short buffer cuts the text and stays terminated.
  const auto counters = decode_bus_error(frame_of(CAN_ERR_FLAG | CAN_ERR_CNT, {0, 0, 0, 0, 0, 0, 130, 0}));
  ASSERT_TRUE(counters.has_value());
  EXPECT_EQ(counters->severity, BusSeverity::error_passive);
  char small[8];
  EXPECT_EQ(format_bus_error(*counters, small), "tx/rx e");
  EXPECT_EQ(small[7], '\0');
  // Not an error frame, or a wrong length.
  EXPECT_FALSE(decode_bus_error(frame_of(0x085, {0, 0, 0, 0, 0, 0, 0, 0})).has_value());
  EXPECT_FALSE(decode_bus_error(frame_of(CAN_ERR_FLAG | CAN_ERR_BUSOFF, {0, 0})).has_value());
}

// --- NMT -------------------------------------------------------------------------------------

TEST(Nmt, CommandFramesAreByteExact) {
  const can_frame start = encode_nmt(NmtCommand::start, 5);
  EXPECT_EQ(start.can_id, 0x000U);
  ASSERT_EQ(start.len, 2);
  EXPECT_EQ(start.data[0], 0x01);
  EXPECT_EQ(start.data[1], 0x05);
  EXPECT_EQ(encode_nmt(NmtCommand::stop, 0).data[0], 0x02);
  EXPECT_EQ(encode_nmt(NmtCommand::enter_pre_operational, 0).data[0], 0x80);
  EXPECT_EQ(encode_nmt(NmtCommand::reset_node, 0).data[0], 0x81);
  EXPECT_EQ(encode_nmt(NmtCommand::reset_communication, 0).data[0], 0x82);
  const auto decoded = decode_nmt(encode_nmt(NmtCommand::reset_communication, 127));
  ASSERT_TRUE(decoded.has_value());
  EXPECT_EQ(decoded->command, NmtCommand::reset_communication);
  EXPECT_EQ(decoded->node_id, 127);
  EXPECT_FALSE(decode_nmt(frame_of(0x000, {0x03, 5})).has_value());  // undefined command
  EXPECT_FALSE(decode_nmt(frame_of(0x000, {0x01, 128})).has_value());
  EXPECT_FALSE(decode_nmt(frame_of(0x000, {0x01})).has_value());
  EXPECT_FALSE(decode_nmt(frame_of(0x001, {0x01, 5})).has_value());
}

TEST(Nmt, SlaveStateMachine) {
  NmtSlave nmt(5);
  EXPECT_TRUE(nmt.initialising());
  EXPECT_EQ(nmt.state(), NmtState::boot_up);
  EXPECT_FALSE(nmt.sdo_allowed());
  // Nothing but a reset applies during initialisation.
  EXPECT_EQ(nmt.on_frame(encode_nmt(NmtCommand::start, 5)), NmtEvent::none);
  const can_frame boot = nmt.boot();
  EXPECT_EQ(boot.can_id, 0x705U);
  ASSERT_EQ(boot.len, 1);
  EXPECT_EQ(boot.data[0], 0x00);
  EXPECT_EQ(nmt.state(), NmtState::pre_operational);
  EXPECT_TRUE(nmt.sdo_allowed());
  EXPECT_FALSE(nmt.pdo_allowed());

  EXPECT_EQ(nmt.on_frame(encode_nmt(NmtCommand::start, 6)), NmtEvent::none);  // another node
  EXPECT_EQ(nmt.state(), NmtState::pre_operational);
  EXPECT_EQ(nmt.on_frame(encode_nmt(NmtCommand::start, 5)), NmtEvent::state_changed);
  EXPECT_EQ(nmt.state(), NmtState::operational);
  EXPECT_TRUE(nmt.pdo_allowed());
  EXPECT_EQ(nmt.on_frame(encode_nmt(NmtCommand::start, 0)), NmtEvent::none);  // already there
  EXPECT_EQ(nmt.on_frame(encode_nmt(NmtCommand::stop, 0)), NmtEvent::state_changed);  // broadcast
  EXPECT_EQ(nmt.state(), NmtState::stopped);
  EXPECT_FALSE(nmt.sdo_allowed());
  EXPECT_FALSE(nmt.emcy_allowed());
  EXPECT_EQ(nmt.on_frame(encode_nmt(NmtCommand::enter_pre_operational, 5)), NmtEvent::state_changed);
  EXPECT_EQ(nmt.state(), NmtState::pre_operational);
  EXPECT_EQ(nmt.on_frame(encode_nmt(NmtCommand::stop, 5)), NmtEvent::state_changed);
  EXPECT_EQ(nmt.on_frame(encode_nmt(NmtCommand::start, 5)), NmtEvent::state_changed);  // stopped -> op
  EXPECT_EQ(nmt.state(), NmtState::operational);

  // Both resets go through initialisation: boot-up message again, then pre-operational.
  EXPECT_EQ(nmt.on_frame(encode_nmt(NmtCommand::reset_node, 5)), NmtEvent::reset_application);
  EXPECT_TRUE(nmt.initialising());
  EXPECT_FALSE(nmt.pdo_allowed());
  EXPECT_EQ(nmt.boot().data[0], 0x00);
  EXPECT_EQ(nmt.state(), NmtState::pre_operational);
  EXPECT_EQ(nmt.on_frame(encode_nmt(NmtCommand::start, 5)), NmtEvent::state_changed);
  EXPECT_EQ(nmt.on_frame(encode_nmt(NmtCommand::reset_communication, 0)), NmtEvent::reset_communication);
  (void)nmt.boot();
  EXPECT_EQ(nmt.state(), NmtState::pre_operational);
}

// --- SYNC ------------------------------------------------------------------------------------

TEST(Sync, EncodeDecodeWithAndWithoutCounter) {
  const can_frame plain = encode_sync();
  EXPECT_EQ(plain.can_id, 0x080U);
  EXPECT_EQ(plain.len, 0);
  ASSERT_TRUE(decode_sync(plain).has_value());
  EXPECT_FALSE(decode_sync(plain)->counter.has_value());
  const auto counted = decode_sync(encode_sync(7));
  ASSERT_TRUE(counted.has_value());
  EXPECT_EQ(counted->counter, 7);
  EXPECT_FALSE(decode_sync(frame_of(0x080, {0})).has_value());    // counter starts at 1
  EXPECT_FALSE(decode_sync(frame_of(0x080, {241})).has_value());  // above 240
  EXPECT_FALSE(decode_sync(frame_of(0x080, {1, 2})).has_value());
  EXPECT_FALSE(decode_sync(frame_of(0x081, {})).has_value());  // EMCY of node 1

  SyncProducer counting(3);
  EXPECT_TRUE(counting.valid());
  std::string sequence;
  for (int i = 0; i < 7; ++i) sequence += std::to_string(counting.next().data[0]);
  EXPECT_EQ(sequence, "1231231");
  counting.reset();
  EXPECT_EQ(counting.next().data[0], 1);
  SyncProducer plain_producer(0);
  EXPECT_EQ(plain_producer.next().len, 0);
  SyncProducer reserved(1);  // 1 is reserved in 0x1019
  EXPECT_FALSE(reserved.valid());
  EXPECT_EQ(reserved.next().len, 0);
}

// --- heartbeat -------------------------------------------------------------------------------

TEST(Heartbeat, EncodeDecode) {
  const can_frame frame = encode_heartbeat(9, NmtState::operational);
  EXPECT_EQ(frame.can_id, 0x709U);
  ASSERT_EQ(frame.len, 1);
  EXPECT_EQ(frame.data[0], 0x05);
  const auto message = decode_heartbeat(frame);
  ASSERT_TRUE(message.has_value());
  EXPECT_EQ(message->node_id, 9);
  EXPECT_EQ(message->state, NmtState::operational);
  EXPECT_EQ(decode_heartbeat(frame_of(0x709, {0x7F}))->state, NmtState::pre_operational);
  EXPECT_EQ(decode_heartbeat(frame_of(0x709, {0x04}))->state, NmtState::stopped);
  EXPECT_FALSE(decode_heartbeat(frame_of(0x709, {0x85})).has_value());  // guarding toggle bit
  EXPECT_FALSE(decode_heartbeat(frame_of(0x709, {0x01})).has_value());
  EXPECT_FALSE(decode_heartbeat(frame_of(0x700, {0x05})).has_value());
  EXPECT_FALSE(decode_heartbeat(frame_of(0x709 | CAN_RTR_FLAG, {0x05})).has_value());
  EXPECT_EQ(encode_consumer_entry(5, 100), 0x00050064U);
  EXPECT_EQ(decode_consumer_entry(0x00050064U).node_id, 5);
  EXPECT_EQ(decode_consumer_entry(0x00050064U).time_ms, 100);
}

TEST(Heartbeat, ConsumerDetectsTimeoutOnceAndBootUp) {
  HeartbeatConsumer consumer;
  ASSERT_TRUE(consumer.add(5, 100).is_ok());
  ASSERT_TRUE(consumer.add_entry(encode_consumer_entry(6, 50)).is_ok());
  EXPECT_FALSE(consumer.add(5, 10).is_ok());   // twice
  EXPECT_FALSE(consumer.add(0, 10).is_ok());   // node 0
  EXPECT_TRUE(consumer.add(7, 0).is_ok());     // time 0: entry unused
  EXPECT_EQ(consumer.status(7), nullptr);
  EXPECT_EQ(consumer.size(), 2U);

  // Not yet seen: no deadline runs.
  consumer.on_time(10'000 * kFrameMs);
  EXPECT_FALSE(consumer.next_event().has_value());
  EXPECT_EQ(consumer.status(5)->health, NodeHealth::not_seen);

  std::int64_t now = 10'000 * kFrameMs;
  EXPECT_TRUE(consumer.on_frame(encode_heartbeat(5, NmtState::pre_operational), now));
  EXPECT_TRUE(consumer.on_frame(encode_heartbeat(6, NmtState::operational), now));
  EXPECT_FALSE(consumer.on_frame(encode_heartbeat(8, NmtState::operational), now));  // not monitored
  EXPECT_EQ(consumer.status(5)->health, NodeHealth::alive);
  EXPECT_TRUE(consumer.all_alive());

  // Node 6 stops at 10 s; node 5 keeps beating every 40 ms and changes state once.
  for (int i = 1; i <= 5; ++i) {
    now += 40 * kFrameMs;
    consumer.on_frame(encode_heartbeat(5, i < 3 ? NmtState::pre_operational : NmtState::operational), now);
    consumer.on_time(now);
  }
  auto event = consumer.next_event();
  ASSERT_TRUE(event.has_value());
  EXPECT_EQ(event->node_id, 5);
  EXPECT_EQ(event->event, HeartbeatEvent::state_changed);
  event = consumer.next_event();
  ASSERT_TRUE(event.has_value());
  EXPECT_EQ(event->node_id, 6);
  EXPECT_EQ(event->event, HeartbeatEvent::timed_out);
  EXPECT_FALSE(consumer.next_event().has_value());  // reported once
  consumer.on_time(now + 1000 * kFrameMs);
  EXPECT_EQ(consumer.status(5)->health, NodeHealth::timed_out);
  EXPECT_EQ(consumer.status(6)->health, NodeHealth::timed_out);  // latched
  EXPECT_EQ(consumer.status(6)->timeout_count, 1U);
  event = consumer.next_event();
  ASSERT_TRUE(event.has_value());
  EXPECT_EQ(event->node_id, 5);
  EXPECT_EQ(event->event, HeartbeatEvent::timed_out);
  EXPECT_FALSE(consumer.next_event().has_value());
  EXPECT_FALSE(consumer.all_alive());

  // Node 6 restarts: boot-up = recovered + boot_up; no deadline until its first heartbeat.
  now += 2000 * kFrameMs;
  consumer.on_frame(encode_heartbeat(6, NmtState::boot_up), now);
  event = consumer.next_event();
  ASSERT_TRUE(event.has_value());
  EXPECT_EQ(event->event, HeartbeatEvent::recovered);
  event = consumer.next_event();
  ASSERT_TRUE(event.has_value());
  EXPECT_EQ(event->event, HeartbeatEvent::boot_up);
  EXPECT_EQ(event->state, NmtState::boot_up);
  EXPECT_EQ(consumer.status(6)->health, NodeHealth::booted);
  consumer.on_time(now + 10'000 * kFrameMs);
  EXPECT_EQ(consumer.status(6)->health, NodeHealth::booted);
  consumer.on_frame(encode_heartbeat(6, NmtState::pre_operational), now + 10'000 * kFrameMs);
  EXPECT_EQ(consumer.status(6)->health, NodeHealth::alive);
  EXPECT_FALSE(consumer.next_event().has_value());  // boot-up -> pre-op is not a "change"
  // Exactly at the consumer time is still in time; one ns later is not.
  consumer.on_time(now + 10'000 * kFrameMs + 50 * kFrameMs);
  EXPECT_EQ(consumer.status(6)->health, NodeHealth::alive);
  consumer.on_time(now + 10'000 * kFrameMs + 50 * kFrameMs + 1);
  EXPECT_EQ(consumer.status(6)->health, NodeHealth::timed_out);
}

TEST(Heartbeat, ConsumerCapacity) {
  HeartbeatConsumer consumer;
  for (std::uint8_t node = 1; node <= HeartbeatConsumer::kCapacity; ++node) {
    ASSERT_TRUE(consumer.add(node, 100).is_ok());
  }
  const core::Status full = consumer.add(100, 100);
  EXPECT_EQ(full.code(), core::StatusCode::capacity_exceeded);
}

// --- EMCY ------------------------------------------------------------------------------------

TEST(Emcy, RoundTripIsByteExact) {
  EmcyMessage message;
  message.node_id = 0x12;
  message.error_code = 0x2310;
  message.error_register = kErrorRegisterGeneric | kErrorRegisterCurrent;
  message.manufacturer_data = {0xA1, 0xA2, 0xA3, 0xA4, 0xA5};
  const can_frame frame = encode_emcy(message);
  EXPECT_EQ(frame.can_id, 0x092U);
  ASSERT_EQ(frame.len, 8);
  const std::uint8_t expected[8] = {0x10, 0x23, 0x03, 0xA1, 0xA2, 0xA3, 0xA4, 0xA5};
  EXPECT_EQ(std::memcmp(frame.data, expected, 8), 0);
  const auto decoded = decode_emcy(frame);
  ASSERT_TRUE(decoded.has_value());
  EXPECT_EQ(decoded->node_id, 0x12);
  EXPECT_EQ(decoded->error_code, 0x2310);
  EXPECT_EQ(decoded->error_register, 0x03);
  EXPECT_EQ(decoded->manufacturer_data, message.manufacturer_data);
  EXPECT_FALSE(decode_emcy(frame_of(0x092, {0x10, 0x23, 0x03})).has_value());
  EXPECT_FALSE(decode_emcy(frame_of(0x080, {0, 0, 0, 0, 0, 0, 0, 0})).has_value());  // SYNC id
}

TEST(Emcy, CodeTexts) {
  EXPECT_STREQ(describe_emcy_code(0x0000), "error reset or no error");
  EXPECT_STREQ(describe_emcy_code(0x1000), "generic error");
  EXPECT_STREQ(describe_emcy_code(0x2310), "continuous over-current (device output side)");
  EXPECT_STREQ(describe_emcy_code(0x2320), "short circuit/earth leakage (motor side)");
  EXPECT_STREQ(describe_emcy_code(0x3210), "DC link over-voltage");
  EXPECT_STREQ(describe_emcy_code(0x3220), "DC link under-voltage");
  EXPECT_STREQ(describe_emcy_code(0x4210), "excess temperature device");
  EXPECT_STREQ(describe_emcy_code(0x5530), "non-volatile data memory (EEPROM)");
  EXPECT_STREQ(describe_emcy_code(0x7300), "sensor");
  EXPECT_STREQ(describe_emcy_code(0x7305), "incremental sensor 1 fault");
  EXPECT_STREQ(describe_emcy_code(0x8110), "CAN overrun (objects lost)");
  EXPECT_STREQ(describe_emcy_code(0x8120), "CAN in error passive mode");
  EXPECT_STREQ(describe_emcy_code(0x8130), "life guard error or heartbeat error");
  EXPECT_STREQ(describe_emcy_code(0x8140), "recovered from bus-off");
  EXPECT_STREQ(describe_emcy_code(0x8250), "RPDO timeout");
  EXPECT_STREQ(describe_emcy_code(0x8611), "following error");
  // Numbered variants take their group's text; unknown codes their class.
  EXPECT_STREQ(describe_emcy_code(0x2311), "continuous over-current (device output side)");
  EXPECT_STREQ(describe_emcy_code(0x8251), "RPDO timeout");
  EXPECT_STREQ(describe_emcy_code(0x23AB), "current, device output side");
  EXPECT_STREQ(describe_emcy_code(0x6301), "data set");
  EXPECT_STREQ(describe_emcy_code(0x2F00), "current");
  EXPECT_STREQ(describe_emcy_code(0xFF00), "device specific (manufacturer)");
  EXPECT_STREQ(describe_emcy_code(0xFF17), "device specific (manufacturer)");
  EXPECT_STREQ(describe_emcy_code(0xA000), "unassigned error code class");
  char text[96];
  EXPECT_EQ(format_error_register(0x00, text), "no error");
  EXPECT_EQ(format_error_register(0x89, text), "generic, temperature, manufacturer");
  EXPECT_EQ(format_error_register(0x36, text), "current, voltage, communication, device profile");
}

}  // namespace
}  // namespace trainer::hal::canopen
