// SimDriveNode: one simulated CiA 402 servo drive (cyclic synchronous torque only) as a CANopen
// slave, built from the protocol library (trainer::hal::canopen): its object dictionary, NMT
// slave, SDO server, heartbeat producer and consumer, EMCY producer, PDOs as the master maps
// them, and the CiA 402 power state machine. The plant behind it (one joint of the simulated
// bench) belongs to SimDriveBus, which hands each node its sample at every SYNC and takes the
// torque back; the node never touches the wall clock: every call takes `now_ns`.
//
// Object dictionary (docs/simdrive.md lists it with types and access):
//   0x1000 device type 0x00020192, 0x1001 error register, 0x1008 device name, 0x100A software
//   version,
//   0x1016:1..4 consumer heartbeat times, 0x1017 producer heartbeat time, 0x1018:1..4 identity,
//   0x1400..0x1403 / 0x1600..0x1603 RPDO communication / mapping,
//   0x1800..0x1803 / 0x1A00..0x1A03 TPDO communication / mapping,
//   0x6007 abort connection option, 0x603F error code, 0x6040 controlword, 0x6041 statusword,
//   0x605A..0x605E option codes, 0x6060 / 0x6061 mode (CST = 10 only), 0x6064 position actual
//   (encoder counts), 0x606C velocity actual (counts/s), 0x6071 target torque, 0x6072 max
//   torque, 0x6077 torque actual (per mille of 0x6076), 0x6076 motor rated torque (mN·m),
//   0x6502 supported drive modes (bit 9), 0x60FD digital inputs, 0x60FE:1/:2 outputs and mask.
// Defaults after reset: RPDO1 0x200+n / TPDO1 0x180+n valid, event-driven (255), mapping
// {0x6040} / {0x6041} (CiA 402's predefined first PDOs); PDOs 2..4 not valid, unmapped.
//
// PDOs: whatever mappable objects the master maps are packed per the mapping (PdoMapping,
// pdo_dictionary.hpp). Mapping writes are checked when written (object exists, mappable,
// sizes), only while the PDO is not valid (COB-ID bit 31; else abort 0x08000022) and, for
// sub 1..8, only while sub 0 is 0 (else 0x06010000); sub 0 = n checks entries 1..n
// (0x06040041 not mappable, 0x06040042 more than 64 bits or 8 entries). Transmission types:
// TPDO 1..240 every n-th SYNC, 0 at a SYNC when its data changed, 254/255 when its data
// changed (inhibit time sub 3) and every event timer period (sub 5); RPDO 0..240 latched and
// applied at the next SYNC, 254/255 applied at once. An RPDO's event timer is its deadline:
// armed by the first RPDO received, expiry sends EMCY 0x8250 and applies 0x6007.
//
// Abort connection (0x6007, Cia402StateMachine::connection_lost): on a heartbeat consumer
// timeout (EMCY 0x8130), an RPDO deadline (EMCY 0x8250), bus-off, and when NMT takes the node
// out of Operational (stop, pre-operational, reset) while its drive function is on.
// 0 nothing, 1 Fault, 2 disable voltage, 3 quick stop. Stop ramps are 0 by default: a torque
// drive drops its torque at once.
//
// Threads: one thread calls everything (SimDriveBus::poll's).
#pragma once

#include <linux/can.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "trainer/core/expected.hpp"
#include "trainer/core/fixed_vector.hpp"
#include "trainer/hal/joint_scale.hpp"
#include "trainer/hal_canopen/cia402.hpp"
#include "trainer/hal_canopen/cia402_drive.hpp"
#include "trainer/hal_canopen/heartbeat.hpp"
#include "trainer/hal_canopen/nmt.hpp"
#include "trainer/hal_canopen/object_dictionary.hpp"
#include "trainer/hal_canopen/pdo.hpp"
#include "trainer/hal_canopen/sdo_server.hpp"
#include "trainer/hal_simdrive/events.hpp"

namespace trainer::hal::simdrive {

inline constexpr std::uint32_t kDeviceTypeServoDrive = 0x00020192;  // CiA 402, servo drive
inline constexpr std::uint16_t kObjectSoftwareVersion = 0x100A;      // visible string
inline constexpr std::size_t kPdoCount = 4;                         // RPDO1..4, TPDO1..4
inline constexpr std::size_t kConsumerHeartbeatEntries = 4;         // 0x1016:1..4
inline constexpr std::size_t kNodeTxCapacity = 32;                  // frames queued per node

struct DriveIdentity {
  std::uint32_t vendor_id = 0;      // 0x1018:1
  std::uint32_t product_code = 0;   // 0x1018:2
  std::uint32_t revision = 0;       // 0x1018:3
  std::uint32_t serial_number = 0;  // 0x1018:4
};

struct SimDriveNodeParams {
  std::uint8_t node_id = 0;                      // 1..127
  std::string device_name = "trainer simdrive";  // 0x1008, at most 32 characters
  std::string software_version = "simdrive 1.0";  // 0x100A, at most 32 characters
  DriveIdentity identity;
  std::uint32_t motor_rated_torque_mnm = 0;  // 0x6076, > 0
  std::uint16_t max_torque_permille = 1000;  // 0x6072 default
  // Counts <-> joint position and motor current <-> joint effort of the joint it drives; the
  // torque it applies is also limited by scale.current_limit_a.
  hal::JointScale scale;
  std::int64_t slow_down_ramp_ns = 0;           // 0x605B/C option 1, 0x605A 1/5
  std::int64_t quick_stop_ramp_ns = 0;          // 0x605A 2/6, 0x605E 2
  std::int64_t sdo_timeout_ns = 1'000'000'000;  // segmented SDO transfers
  // Miswiring (simdrive --miswire): the drive as a bench wired wrongly presents it.
  bool reverse_encoder = false;  // position and velocity actual negated
  bool reverse_motor = false;    // the torque turns the joint the other way
};

// What a node asks the bus to send. The bus applies the injected faults by kind.
enum class TxKind : std::uint8_t { boot_up, heartbeat, sdo, emcy, tpdo };
struct TxFrame {
  can_frame frame{};
  TxKind kind = TxKind::tpdo;
  std::uint8_t pdo_number = 0;  // TPDO 1..4
  const char* cause = nullptr;  // EMCY: why (static text, for the events log)
};

// The plant's joint at a SYNC, as the drive's sensors see it.
struct PlantSample {
  std::int64_t position_counts = 0;  // encoder counts (motor side)
  double velocity_counts_per_s = 0.0;
  std::uint32_t digital_inputs = 0;  // 0x60FD as wired (bits 16..31 the trainer's switches)
};

// What the drive applies to its joint.
struct DriveOutput {
  double effort = 0.0;   // joint side N·m or N, after 0x6072 and the current limit
  bool enabled = false;  // drive function on (power stage drives the motor)
};

class SimDriveNode final : private canopen::ObjectDictionaryObserver {
 public:
  // Setup: checks the parameters and builds the dictionary; the error names the node and
  // what was expected. `events` must outlive the node. The node is not booted: power_on().
  static core::Expected<std::unique_ptr<SimDriveNode>> create(const SimDriveNodeParams& params,
                                                              EventLog& events);
  SimDriveNode(const SimDriveNode&) = delete;
  SimDriveNode& operator=(const SimDriveNode&) = delete;
  ~SimDriveNode() = default;

  // --- driven by the bus (noexcept, no heap) ---------------------------------------------
  // Power-on: dictionary defaults, power state machine reset, boot-up message queued.
  void power_on(std::int64_t now_ns, std::uint64_t sync) noexcept;
  // A frame from the bus (NMT, SDO request, RPDO, heartbeat of a consumed producer, a SYNC of a
  // wrong length). Valid SYNCs go to on_sync(). Returns true when the frame concerned the node.
  bool on_frame(const can_frame& frame, std::int64_t now_ns, std::uint64_t sync) noexcept;
  // One SYNC: latched RPDOs applied, the power state machine's cycle, actual values from
  // `sample`, the torque, the TPDOs due.
  void on_sync(const PlantSample& sample, std::int64_t now_ns, std::uint64_t sync) noexcept;
  // Heartbeat production and consumption, RPDO deadlines, TPDO event timers, SDO timeout,
  // event-driven TPDOs whose data changed.
  void on_time(std::int64_t now_ns, std::uint64_t sync) noexcept;
  // The earliest time on_time() has something to do (INT64_MAX: nothing).
  std::int64_t next_deadline_ns(std::int64_t now_ns) const noexcept;

  // Frames to send, in order; the bus empties the queue. Frames that did not fit are counted.
  std::span<const TxFrame> tx_queue() const noexcept { return tx_.span(); }
  void clear_tx_queue() noexcept { tx_.clear(); }

  // --- faults (from the bus) --------------------------------------------------------------
  // EMCY `code`, drive to Fault (torque off); resettable by the master's fault reset.
  void inject_emcy(std::uint16_t code, std::int64_t now_ns, std::uint64_t sync) noexcept;
  void add_encoder_offset(std::int32_t counts) noexcept { encoder_offset_counts_ += counts; }
  // Node reset as by NMT reset node: boot-up, pre-operational, all dictionary defaults.
  void reboot(std::int64_t now_ns, std::uint64_t sync) noexcept;
  // The bus went off: 0x6007 applied (cause "bus-off"), error code 0x8140 for a Fault.
  void bus_off(std::int64_t now_ns, std::uint64_t sync) noexcept;

  // --- observation ------------------------------------------------------------------------
  std::uint8_t node_id() const noexcept { return params_.node_id; }
  const SimDriveNodeParams& params() const noexcept { return params_; }
  canopen::NmtState nmt_state() const noexcept { return nmt_.state(); }
  canopen::PowerState power_state() const noexcept { return power_.state(); }
  std::uint16_t statusword() const noexcept { return power_.statusword(); }
  const DriveOutput& output() const noexcept { return output_; }
  std::int16_t torque_actual_permille() const noexcept { return torque_actual_permille_; }
  // Set when output() changed since the bus last took it.
  bool take_output_changed() noexcept;
  std::uint32_t digital_outputs() const noexcept;  // 0x60FE:1 & 0x60FE:2
  const canopen::ObjectDictionary& dictionary() const noexcept { return od_; }
  canopen::ObjectDictionary& dictionary() noexcept { return od_; }
  // The consumer of the producers in 0x1016 (e.g. when the master's last heartbeat came).
  const canopen::HeartbeatConsumer& heartbeat_consumer() const noexcept { return consumer_; }
  const canopen::PdoMapping& rpdo_mapping(std::size_t pdo_number) const noexcept;
  const canopen::PdoMapping& tpdo_mapping(std::size_t pdo_number) const noexcept;

  struct Counters {
    std::uint64_t frames_received = 0;  // frames that concerned this node
    std::uint64_t syncs = 0;            // SYNCs processed
    std::uint64_t rpdos = 0;            // RPDOs accepted
    std::uint64_t rpdo_length_errors = 0;
    std::uint64_t tpdos = 0;  // TPDOs queued
    std::uint64_t sdo_requests = 0;
    std::uint64_t sdo_aborts = 0;
    std::uint64_t emcys = 0;       // EMCYs produced (sent or suppressed)
    std::uint64_t heartbeats = 0;  // heartbeats queued
    std::uint64_t boots = 0;
    std::uint64_t tx_overflows = 0;  // frames that did not fit the node's queue
  };
  const Counters& counters() const noexcept { return counters_; }

 private:
  struct RpdoState {
    bool valid = false;
    std::uint16_t can_id = 0;
    std::uint8_t transmission_type = 255;
    std::uint16_t event_timer_ms = 0;
    canopen::PdoMapping mapping;
    bool latched = false;
    can_frame latched_frame{};
    bool deadline_armed = false;
    std::int64_t deadline_ns = 0;
    bool length_error_reported = false;
  };
  struct TpdoState {
    bool valid = false;
    std::uint16_t can_id = 0;
    std::uint8_t transmission_type = 255;
    std::uint16_t inhibit_100us = 0;
    std::uint16_t event_timer_ms = 0;
    canopen::PdoMapping mapping;
    std::uint32_t sync_counter = 0;
    bool sent_once = false;
    std::array<std::uint8_t, CAN_MAX_DLEN> last_data{};
    std::uint8_t last_length = 0;
    std::int64_t last_sent_ns = 0;
    std::int64_t next_event_ns = 0;
  };
  // The time and SYNC count of the call being handled (every event and timer uses them).
  struct Context {
    std::int64_t now_ns = 0;
    std::uint64_t sync = 0;
  };

  SimDriveNode(const SimDriveNodeParams& params, EventLog& events);
  core::Expected<void> add_objects();
  void restore_defaults(bool application_too) noexcept;
  // NMT resets (CiA 301 7.2.8.1): communication area defaults / every default and the power
  // state machine; both end with boot(): runtime state reloaded, boot-up message queued.
  void reset_communication() noexcept;
  void reset_application(const char* cause) noexcept;
  void boot() noexcept;
  canopen::Cia402Options options_from_dictionary() const noexcept;
  void reload_pdo(canopen::PdoDirection direction, std::size_t index) noexcept;
  void reload_all_pdos() noexcept;
  void reload_heartbeat_consumer() noexcept;
  void restart_heartbeat_producer() noexcept;
  void reset_pdo_runtime() noexcept;

  void handle_nmt(const can_frame& frame) noexcept;
  void handle_rpdo(std::size_t index, const can_frame& frame) noexcept;
  void handle_heartbeat_events() noexcept;
  void check_rpdo_deadlines() noexcept;
  void send_tpdo(std::size_t index, bool only_if_changed) noexcept;
  void check_event_tpdos() noexcept;

  // Power: run one state machine step / event, then publish statusword and torque and log.
  void power_update(std::uint16_t controlword, const char* cause) noexcept;
  void power_connection_lost(std::uint16_t error_code, const char* cause) noexcept;
  void power_fault(std::uint16_t error_code, const char* cause) noexcept;
  void after_power_change(canopen::PowerState before, bool drive_was_on,
                          const char* cause) noexcept;
  void refresh_torque() noexcept;
  void publish_status() noexcept;
  void send_emcy(std::uint16_t code, const char* cause) noexcept;
  std::uint8_t error_register() const noexcept;

  void queue(const can_frame& frame, TxKind kind, std::uint8_t pdo_number = 0,
             const char* cause = nullptr) noexcept;
  void log(EventKind kind, std::uint32_t a = 0, std::uint32_t b = 0, const char* cause = nullptr,
           const char* text = nullptr) noexcept;

  // ObjectDictionaryObserver: SDO writes.
  std::uint32_t validate_write(const canopen::ObjectEntry& entry,
                               std::span<const std::uint8_t> value) noexcept override;
  void on_written(const canopen::ObjectEntry& entry) noexcept override;
  std::uint32_t validate_pdo_communication(canopen::PdoDirection direction, std::size_t index,
                                           std::uint8_t sub, std::uint32_t value) const noexcept;
  std::uint32_t validate_pdo_mapping(canopen::PdoDirection direction, std::size_t index,
                                     std::uint8_t sub, std::uint32_t value) const noexcept;
  bool pdo_valid(canopen::PdoDirection direction, std::size_t index) const noexcept;

  SimDriveNodeParams params_;
  EventLog& events_;
  canopen::ObjectDictionary od_;
  canopen::NmtSlave nmt_;
  canopen::SdoServer sdo_;
  canopen::Cia402StateMachine power_;
  canopen::HeartbeatConsumer consumer_;
  std::array<RpdoState, kPdoCount> rpdo_{};
  std::array<TpdoState, kPdoCount> tpdo_{};
  // Values of every dictionary entry after create() (dictionary order): the reset defaults.
  std::array<std::int64_t, canopen::kObjectDictionaryCapacity> defaults_{};

  Context now_{};
  std::int64_t next_heartbeat_ns_ = 0;
  std::uint16_t heartbeat_period_ms_ = 0;
  std::int32_t encoder_offset_counts_ = 0;
  std::int16_t torque_actual_permille_ = 0;
  DriveOutput output_{};
  bool output_changed_ = false;
  bool heartbeat_lost_ = false;  // communication errors (error register bit 4, warning)
  bool rpdo_timed_out_ = false;
  bool sync_length_reported_ = false;
  core::FixedVector<TxFrame, kNodeTxCapacity> tx_;
  Counters counters_{};
};

}  // namespace trainer::hal::simdrive
