// The CAN part of `hil` (docs/hil.md "CAN"): what answers on the bus and how each drive of the
// device file behaves, through the project's CANopen library (hal/canopen) and the trainer's
// own setup sequence (hal/socketcan canopen_setup: reset, identity, CST, max torque,
// heartbeats, PDOs), on any CanTransport (SocketCAN, or a socketpair in tests).
//
// scan: listens for boot-ups/heartbeats, probes every node id 1..127 with one SDO upload of
//   0x1000 at once (answers within the probe timeout mark a node present), then reads from each
//   present node 0x1000 device type, 0x1018:1..4 identity, 0x1001 error register and 0x100A
//   software version (when it has one). With a device file: one step per drive (present with
//   the file's identity / missing / wrong identity) and one per node the file does not have;
//   an extra node with the identity the file expects of a missing one yields the node_id
//   correction. Passive otherwise; NMT reset communication to every node (so that they all
//   send their boot-up) only with options.nmt_reset and the operator's confirmation.
// check: per drive, one at a time, configured as the trainer does but with max torque 0x6072
//   at the context's torque fraction: torque_limit (0x6072 written and read back),
//   encoder_direction (the operator moves the joint by hand: direction and scale of the
//   counts), motor_polarity (a small torque: which way the joint goes), heartbeat_loss (the
//   master's heartbeat stops while the drive holds a small torque: time to torque off against
//   its consumer time 0x1016); then, with every drive operational and disabled, sync_jitter and
//   pdo_round_trip on the bus. Torque is removed on every way out (step end, fault, exception,
//   interruption): RPDO1 "disable voltage" with zero torque, a SYNC, NMT pre-operational.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "trainer/hal_socketcan/can_transport.hpp"
#include "trainer/hil/step.hpp"
#include "trainer/hil/step_filter.hpp"

namespace trainer::hil::can {

struct CanOptions {
  std::int64_t listen_ns = 300'000'000;        // scan: passive listening (bench time)
  std::int64_t probe_timeout_ns = 50'000'000;  // scan: wait for the SDO probe's answers
  bool nmt_reset = false;                      // scan: NMT reset communication first (asks)
  std::int64_t period_ns = 4'000'000;          // check: SYNC period when the file says 0
  std::int64_t jitter_syncs = 500;             // check: SYNCs of the bus statistics
};

ScanSection scan(const BenchContext& context, hal::socketcan::CanTransport& bus,
                 const CanOptions& options = {});
CheckSection check(const BenchContext& context, hal::socketcan::CanTransport& bus,
                   const StepFilter& filter, const CanOptions& options = {});

}  // namespace trainer::hil::can
