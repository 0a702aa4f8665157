// SimDriveBus: the simulated drives of one device file on one CanTransport, with ONE
// hal::sim::SimDevice as the plant of every channel (channel = instrument * 5 + joint, node i of
// the params drives channel i), plus fault injection and the events log.
//
// Time model (docs/simdrive.md "Time"):
//  - the PLANT runs on a core::ManualClock advanced by sync_period_ns at every SYNC received, so
//    the bus, not the wall clock, sets plant time: deterministic, and right under a slow
//    emulator. Per SYNC: advance the plant clock, read the encoders (the sample is the position
//    at the SYNC instant), let every node apply its latched RPDOs, step its power state machine
//    and queue its TPDOs, then apply the torques to the plant (held until the next SYNC) and send.
//  - the plant's script time (the simulated hand) starts at the first NMT start seen by any
//    node (SimDevice::activate() then);
//  - PROTOCOL timers (heartbeat production and consumption, RPDO deadlines, SDO timeouts, TPDO
//    event timers, delayed frames, at_s faults) run on the `now_ns` poll() is given: the real
//    CLOCK_MONOTONIC in the program.
// poll(now_ns) handles everything pending (frames, timers, faults) and returns the next timer
// deadline, so a program can poll() the transport's fd with that timeout.
//
// Faults (fault.hpp), on the bus:
//   drop N      the node's TPDOs are not sent for N SYNCs (0: until cleared)
//   delay D ms  the node's TPDOs leave D ms after they were due (for N SYNCs, or until cleared)
//   corrupt     the node's TPDO1 leaves one byte short (length), or with `mask` XORed into data
//               byte `byte` (bits), for N SYNCs (default 1)
//   silent      the node sends nothing at all (heartbeat, PDO, SDO answer, EMCY); it still
//               receives and drives its joint
//   bus_off     a SocketCAN error frame CAN_ERR_FLAG|CAN_ERR_BUSOFF (8 bytes) is sent, every node
//               applies its abort-connection option (0x6007) and goes silent and deaf (the plant
//               still advances with the SYNCs) until cleared or for N SYNCs
//   emcy        EMCY `code` (default 0x2310), the node goes to Fault, torque off
//   encoder_jump position actual offset by `counts` from then on
//   lost_sync   the node ignores N SYNCs: no TPDO, no command applied, torque held
//   reboot      the node resets as by NMT reset node: boot-up, pre-operational, defaults
//   push        the hand pushes the node's joint: an effort hand_stiffness * move on the plant,
//               whatever the drive does (N SYNCs or until cleared)
//   clear       ends drop/delay/corrupt/silent/lost_sync/push of a node, or of all and bus-off
// Each is applied at once (inject() / post()) or when its at_sync / at_s comes.
//
// RT rules: poll() and inject() never allocate (fixed queues sized here, checked when full and
// counted), except the single SimDevice::activate() at the first NMT start. Threads: poll(),
// inject() and the observers from one thread; post() from any thread.
#pragma once

#include <linux/can.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "trainer/core/clock.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/core/fixed_vector.hpp"
#include "trainer/core/status.hpp"
#include "trainer/hal_sim/sim_device.hpp"
#include "trainer/hal_simdrive/events.hpp"
#include "trainer/hal_simdrive/fault.hpp"
#include "trainer/hal_simdrive/sim_drive_node.hpp"
#include "trainer/hal_socketcan/can_transport.hpp"

namespace trainer::hal::simdrive {

struct SimDriveBusParams {
  std::string name = "simdrive";
  // Node i drives plant channel i; as many nodes as the plant has channels.
  std::vector<SimDriveNodeParams> nodes;
  hal::sim::SimDeviceParams plant;
  std::int64_t sync_period_ns = 1'000'000;  // plant time per SYNC
  int digital_inputs_node = -1;             // its 0x60FD bits 16..31 carry the plant's switches
  int digital_outputs_node = -1;  // its 0x60FE:1 (& :2) bits 16..31 drive the plant's outputs
  std::size_t event_capacity = 16384;
};

struct NodeBusStats {
  std::uint64_t frames_sent = 0;
  std::uint64_t frames_suppressed = 0;  // silent or bus-off
  std::uint64_t tpdos_dropped = 0;
  std::uint64_t tpdos_delayed = 0;
  std::uint64_t tpdos_corrupted = 0;
  std::uint64_t syncs_ignored = 0;  // lost_sync
  std::uint64_t faults_injected = 0;
};

struct BusStats {
  std::uint64_t frames_received = 0;
  std::uint64_t error_frames_received = 0;
  std::uint64_t syncs = 0;  // valid SYNCs received
  std::uint64_t frames_sent = 0;
  std::uint64_t frames_not_sent = 0;  // the transport refused them (queue full, peer gone)
  std::uint64_t delay_overflows = 0;  // delayed TPDOs that did not fit the delay queue
  std::uint64_t faults_refused = 0;   // unknown node, schedule or mailbox full
  std::uint64_t polls_frame_budget_hit = 0;
};

class SimDriveBus {
 public:
  static constexpr std::size_t kMaxNodes = hal::sim::kMaxChannels;
  static constexpr std::size_t kMaxScheduledFaults = 64;
  static constexpr std::size_t kMaxPostedFaults = 32;
  static constexpr std::size_t kDelayQueueCapacity = 2048;
  static constexpr std::size_t kMaxFramesPerPoll = 1024;

  // Setup: validates the params (node ids unique, one node per plant channel), configures the
  // plant, builds every node. Errors name the node or key.
  static core::Expected<std::unique_ptr<SimDriveBus>> create(SimDriveBusParams params,
                                                             socketcan::CanTransport transport);
  SimDriveBus(const SimDriveBus&) = delete;
  SimDriveBus& operator=(const SimDriveBus&) = delete;
  ~SimDriveBus();

  // Power-on: every node resets and sends its boot-up message.
  void power_on(std::int64_t now_ns) noexcept;
  // Receives and handles every waiting frame, runs the timers and due faults, sends; returns
  // the absolute time (same clock as now_ns) by which it must be called again (it may be called
  // earlier, and must be when the transport becomes readable).
  std::int64_t poll(std::int64_t now_ns) noexcept;

  // Applies `spec` now (or schedules it when it has at_sync / at_s). invalid_argument for a node
  // that is not on this bus; capacity_exceeded when the schedule is full.
  core::Status inject(const FaultSpec& spec, std::int64_t now_ns) noexcept;
  // Any thread: handed to the next poll(), which injects it. False when the mailbox is full.
  bool post(const FaultSpec& spec) noexcept;

  // --- observation (polling thread) --------------------------------------------------------
  std::size_t node_count() const noexcept { return nodes_.size(); }
  const SimDriveNode& node(std::size_t index) const noexcept { return *nodes_[index]; }
  SimDriveNode& node(std::size_t index) noexcept { return *nodes_[index]; }
  // nullptr when no node has this id.
  const SimDriveNode* find_node(std::uint8_t node_id) const noexcept;
  std::string channel_name(std::size_t index) const { return plant_.channel_name(index); }
  const NodeBusStats& node_stats(std::size_t index) const noexcept { return node_stats_[index]; }
  const BusStats& stats() const noexcept { return stats_; }
  hal::sim::SimDevice& plant() noexcept { return plant_; }
  const hal::sim::SimDevice& plant() const noexcept { return plant_; }
  std::int64_t plant_time_ns() const noexcept { return plant_.simulated_time_ns(); }
  std::uint64_t syncs_since_start() const noexcept { return syncs_since_start_; }
  bool plant_started() const noexcept { return plant_started_; }
  bool bus_off() const noexcept { return bus_off_.active; }
  EventLog& events() noexcept { return events_; }
  socketcan::CanTransport& transport() noexcept { return transport_; }
  const SimDriveBusParams& params() const noexcept { return params_; }
  // One line per node (final state, frames, faults) and one for the bus. Allocates.
  std::string summary() const;

 private:
  struct Lasting {
    bool active = false;
    std::uint32_t syncs_left = 0;  // 0 while active = until cleared
  };
  struct NodeFaults {
    Lasting drop;
    Lasting delay;
    Lasting corrupt;
    Lasting silent;
    Lasting lost_sync;
    Lasting push;
    double push_effort = 0.0;  // joint side, N·m or N, added to the drive's at every SYNC
    std::int64_t delay_ns = 0;
    CorruptMode corrupt_mode = CorruptMode::length;
    std::uint8_t corrupt_byte = 0;
    std::uint8_t corrupt_mask = 0;
  };
  struct Delayed {
    std::int64_t release_ns = 0;
    std::size_t node = 0;
    can_frame frame{};
  };
  struct Scheduled {
    FaultSpec spec;
    bool fired = false;
  };

  SimDriveBus(SimDriveBusParams params, socketcan::CanTransport transport);
  core::Expected<void> setup();

  void handle_frame(const can_frame& frame) noexcept;
  void handle_sync() noexcept;
  void start_plant() noexcept;
  void fire_due_faults(bool at_sync_only) noexcept;
  void apply_fault(const FaultSpec& spec) noexcept;
  void clear_faults(std::size_t index, const char* why) noexcept;
  void count_down(Lasting& lasting, std::uint8_t node, const char* what) noexcept;
  void write_plant() noexcept;
  void collect_tx() noexcept;
  void release_delayed() noexcept;
  void emit(const can_frame& frame) noexcept;
  void send_pending() noexcept;
  void log_bus(EventKind kind, std::uint8_t node, std::uint32_t a, std::uint32_t b,
               const char* cause, const char* text) noexcept;
  std::int64_t node_index(std::uint8_t node_id) const noexcept;

  SimDriveBusParams params_;
  socketcan::CanTransport transport_;
  EventLog events_;
  core::ManualClock plant_clock_;
  hal::sim::SimDevice plant_;
  std::vector<std::unique_ptr<SimDriveNode>> nodes_;
  std::array<std::int16_t, 128> node_of_id_{};  // node id -> index, -1 = none
  std::array<NodeFaults, kMaxNodes> faults_{};
  std::array<NodeBusStats, kMaxNodes> node_stats_{};
  std::array<hal::EncoderSample, kMaxNodes> samples_{};
  std::array<hal::ActuatorCommand, kMaxNodes> commands_{};
  std::array<can_frame, socketcan::kMaxFramesPerCall> rx_{};
  core::FixedVector<can_frame, socketcan::kMaxFramesPerCall> out_;
  core::FixedVector<Delayed, kDelayQueueCapacity> delayed_;  // in release order
  core::FixedVector<Scheduled, kMaxScheduledFaults> schedule_;
  std::mutex mailbox_mutex_;
  core::FixedVector<FaultSpec, kMaxPostedFaults> mailbox_;
  std::uint64_t mailbox_refused_ = 0;  // guarded by mailbox_mutex_
  core::FixedVector<FaultSpec, kMaxPostedFaults> mailbox_taken_;
  Lasting bus_off_;
  std::int64_t now_ns_ = 0;
  std::uint64_t syncs_ = 0;
  std::uint64_t syncs_since_start_ = 0;
  bool plant_started_ = false;
  std::int64_t start_ns_ = 0;
  BusStats stats_{};
};

}  // namespace trainer::hal::simdrive
