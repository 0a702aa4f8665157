// libFuzzer target: arbitrary bytes -> a sequence of can_frames (with any id, flags and
// length, also lengths above 8) and times, through classify(), every decoder, the NMT
// slave, the heartbeat consumer, the CiA 402 coding and drive state machine, and a PDO
// mapping. Besides memory and UB errors (ASan+UBSan) it checks invariants: every frame a
// decoder accepts re-encodes to the same bytes, texts are never null, the drive's
// statusword decodes to its state, torque scale stays in [0, 1].
//
// Input: records of 15 bytes: can_id (u32 LE, flags included), len (u8), data[8],
// time step (u16 LE, units of 100 us).
#include <linux/can.h>

#include <cstdint>
#include <cstring>

#include "fuzz_input.hpp"
#include "trainer/hal_canopen/bus_error.hpp"
#include "trainer/hal_canopen/cia402.hpp"
#include "trainer/hal_canopen/cia402_drive.hpp"
#include "trainer/hal_canopen/emcy.hpp"
#include "trainer/hal_canopen/frame.hpp"
#include "trainer/hal_canopen/heartbeat.hpp"
#include "trainer/hal_canopen/nmt.hpp"
#include "trainer/hal_canopen/pdo.hpp"
#include "trainer/hal_canopen/sdo.hpp"
#include "trainer/hal_canopen/sync.hpp"

namespace {

using namespace trainer::hal::canopen;  // NOLINT: a fuzz target, one file
using trainer::fuzz::FuzzInput;

bool same_frame(const can_frame& a, const can_frame& b) {
  return a.can_id == b.can_id && a.len == b.len && std::memcmp(a.data, b.data, a.len) == 0;
}

void check_decoders(const can_frame& frame) {
  const FrameClass c = classify(frame);
  FUZZ_CHECK(to_string(c.kind) != nullptr && to_string(c.problem) != nullptr);
  if (c.ok() && c.kind != FrameKind::error_frame && c.kind != FrameKind::unknown) {
    FUZZ_CHECK(frame.len <= CAN_MAX_DLEN);
  }
  if (c.kind == FrameKind::tpdo || c.kind == FrameKind::rpdo) {
    FUZZ_CHECK(c.pdo_number >= 1 && c.pdo_number <= 4 && is_valid_node_id(c.node_id));
    FUZZ_CHECK(cob_id(c.kind, c.node_id, c.pdo_number) == frame_id(frame));
  }

  if (const auto error = decode_bus_error(frame)) {
    FUZZ_CHECK(c.kind == FrameKind::error_frame && c.ok());
    char text[96];
    const std::string_view view = format_bus_error(*error, text);
    FUZZ_CHECK(!view.empty() && view.size() < sizeof(text) && text[view.size()] == '\0');
    FUZZ_CHECK(to_string(error->severity) != nullptr);
    FUZZ_CHECK(describe_protocol_location(error->protocol_location) != nullptr);
  }
  if (const auto nmt = decode_nmt(frame)) {
    FUZZ_CHECK(c.kind == FrameKind::nmt && c.ok());
    FUZZ_CHECK(same_frame(encode_nmt(nmt->command, nmt->node_id), frame));
  }
  if (const auto sync = decode_sync(frame)) {
    FUZZ_CHECK(c.kind == FrameKind::sync && c.ok());
    FUZZ_CHECK(same_frame(sync->counter ? encode_sync(*sync->counter) : encode_sync(), frame));
  }
  if (const auto heartbeat = decode_heartbeat(frame)) {
    FUZZ_CHECK(c.kind == FrameKind::heartbeat && c.ok() && c.node_id == heartbeat->node_id);
    FUZZ_CHECK(same_frame(encode_heartbeat(heartbeat->node_id, heartbeat->state), frame));
  }
  if (const auto emcy = decode_emcy(frame)) {
    FUZZ_CHECK(c.kind == FrameKind::emcy && c.ok() && c.node_id == emcy->node_id);
    FUZZ_CHECK(same_frame(encode_emcy(*emcy), frame));
    FUZZ_CHECK(describe_emcy_code(emcy->error_code) != nullptr);
    char text[48];
    const std::string_view view = format_error_register(emcy->error_register, text);
    FUZZ_CHECK(view.size() < sizeof(text) && text[view.size()] == '\0');
  }
  if (frame.len <= CAN_MAX_DLEN && frame.len >= 4) {
    std::uint32_t code = 0;
    std::memcpy(&code, frame.data, 4);
    FUZZ_CHECK(describe_sdo_abort(code) != nullptr);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzInput input(data, size);
  NmtSlave nmt(5);
  (void)nmt.boot();
  HeartbeatConsumer heartbeats;
  (void)heartbeats.add(5, 100);
  (void)heartbeats.add(6, 20);
  (void)heartbeats.add_entry(encode_consumer_entry(0x7F, 1));
  Cia402Options options;
  options.quick_stop_option = static_cast<std::int16_t>(size % 9);
  options.fault_reaction_option = static_cast<std::int16_t>(size % 5);
  options.shutdown_option = static_cast<std::int16_t>(size % 2);
  options.abort_connection_option = static_cast<std::int16_t>(size % 4);
  Cia402StateMachine drive(options);
  PdoMapping mapping;
  (void)mapping.add(0x6041, 0, 16, false);
  (void)mapping.add(0x6077, 0, 16, true);
  (void)mapping.add(0x6064, 0, 32, true);
  std::uint16_t controlword = 0;
  std::int64_t now_ns = 0;

  while (!input.empty()) {
    can_frame frame{};
    frame.can_id = input.u32();
    frame.len = input.u8();
    for (std::uint8_t& byte : frame.data) byte = input.u8();
    now_ns += static_cast<std::int64_t>(input.u16()) * 100'000;

    check_decoders(frame);
    (void)nmt.on_frame(frame);
    FUZZ_CHECK(to_string(nmt.state()) != nullptr);
    heartbeats.on_frame(frame, now_ns);
    heartbeats.on_time(now_ns);
    while (const auto event = heartbeats.next_event()) {
      FUZZ_CHECK(heartbeats.status(event->node_id) != nullptr && to_string(event->event) != nullptr);
    }

    // CiA 402: the frame's first bytes as a statusword and a controlword.
    const auto word = static_cast<std::uint16_t>(frame.data[0] | (frame.data[1] << 8));
    const PowerState observed = decode_statusword(word);
    FUZZ_CHECK(to_string(observed) != nullptr);
    controlword = next_controlword(observed, static_cast<PowerTarget>(frame.data[2] % 3), controlword);
    if ((frame.data[3] & 0x0F) == 0x0F) drive.raise_fault(word, now_ns);
    if (frame.data[3] == 0xA5) drive.fault_reaction_done();
    if (frame.data[3] == 0x5A) drive.connection_lost(0x8130, now_ns);
    drive.set_fault_present((frame.data[4] & 1U) != 0);
    drive.update(word, now_ns);
    FUZZ_CHECK(decode_statusword(drive.statusword()) == drive.state());
    const double scale = drive.torque_scale();
    FUZZ_CHECK(scale >= 0.0 && scale <= 1.0);
    const double torque = drive.torque_output(static_cast<double>(static_cast<std::int16_t>(word)));
    FUZZ_CHECK(drive.drive_function_enabled() || torque == 0.0);
    FUZZ_CHECK(torque_to_permille(torque, frame.data[5]) <= 32767);

    // PDO: whatever unpacks packs back to the same bytes.
    std::int64_t values[3] = {};
    if (mapping.unpack(frame, values).is_ok()) {
      can_frame repacked{};
      FUZZ_CHECK(mapping.pack(values, repacked).is_ok());
      FUZZ_CHECK(std::memcmp(repacked.data, frame.data, mapping.byte_length()) == 0);
    }
  }
  return 0;
}
