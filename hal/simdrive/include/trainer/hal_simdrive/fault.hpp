// Faults the simulated drives can be told to show on the bus, their text form (the program's
// --fault SPEC and stdin lines) and when they fire.
//
// SPEC syntax: KIND[:KEY=VALUE[,KEY=VALUE]...], numbers decimal or 0x-hex, e.g.
//   emcy:node=3,at_sync=500,code=0x2310     silent:node=2,at_s=1.5
//   drop:node=1,at_sync=100,count=5          bus_off:at_sync=800      clear:node=2
// Keys: node (1..127: which drive; not for bus_off; optional for clear = every node),
//   at_sync (fires at that SYNC counted from the first NMT start, 1 = the first SYNC after it),
//   at_s (fires that many seconds, monotonic clock, after the first NMT start), without either
//   the fault fires when injected; count (SYNCs the fault lasts; 0 = until cleared),
//   ms (delay: how long TPDOs are held back), code (emcy), counts (encoder_jump),
//   mode = length | bits, byte, mask (corrupt), move (push: joint-side rad or m, non-zero).
// What each kind does on the bus: docs/simdrive.md and SimDriveBus (sim_drive_bus.hpp).
//
// Parsing allocates (setup and the program's command line); a parsed FaultSpec is a plain
// value the bus stores in fixed-size queues.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "trainer/core/expected.hpp"

namespace trainer::hal::simdrive {

enum class FaultKind : std::uint8_t {
  drop,          // the node's TPDOs are not sent (count SYNCs, or until cleared)
  delay,         // the node's TPDOs leave `ms` later than they were due
  corrupt,       // the node's TPDO1 leaves one byte short (mode=length) or with bits flipped
  silent,        // the node sends nothing at all: no heartbeat, PDO, SDO answer or EMCY
  bus_off,       // an error frame CAN_ERR_BUSOFF, then every node silent and deaf
  emcy,          // EMCY `code`, the drive goes to Fault and removes torque
  encoder_jump,  // position actual offset by `counts` from then on
  lost_sync,     // the node ignores `count` SYNCs (no TPDO, no command applied)
  reboot,        // the node resets: boot-up message, pre-operational, dictionary defaults
  clear,         // ends the lasting faults of a node (or of every node, and bus-off)
  push,          // the trainee's hand pushes the joint by about `move` (rad or m) against the
                 // hand spring, independent of the drive (count SYNCs, or until cleared): what a
                 // bench engineer does when `hil check` asks to move a joint by hand
};
const char* to_string(FaultKind kind) noexcept;

enum class CorruptMode : std::uint8_t { length, bits };

struct FaultSpec {
  FaultKind kind = FaultKind::drop;
  std::uint8_t node_id = 0;              // 0: every node (bus_off, clear)
  std::optional<std::uint64_t> at_sync;  // SYNCs since the first NMT start
  std::optional<std::int64_t> at_ns;     // ns since the first NMT start (from at_s)
  std::uint32_t count = 0;               // SYNCs it lasts; 0 = until cleared
  std::int64_t delay_ns = 0;             // delay
  std::uint16_t code = 0x2310;           // emcy: continuous over-current
  std::int32_t counts = 0;               // encoder_jump
  double move = 0.0;                     // push: joint-side displacement, rad or m
  CorruptMode corrupt_mode = CorruptMode::length;
  std::uint8_t corrupt_byte = 0;     // bits: which data byte of TPDO1
  std::uint8_t corrupt_mask = 0x08;  // bits: XOR mask (statusword bit 3, "fault", when
                                     // byte 0 carries 0x6041 as in the trainer's TPDO1)
  bool scheduled() const noexcept { return at_sync.has_value() || at_ns.has_value(); }
};

// Parses one SPEC; the error names the spec, the key and what was expected.
core::Expected<FaultSpec> parse_fault_spec(std::string_view text);
// The canonical text of a spec into `out` (NUL-terminated, cut when too small); returns the
// length written. No heap: the bus logs it.
std::size_t format_fault_spec(const FaultSpec& spec, std::span<char> out) noexcept;
std::string format_fault_spec(const FaultSpec& spec);

}  // namespace trainer::hal::simdrive
