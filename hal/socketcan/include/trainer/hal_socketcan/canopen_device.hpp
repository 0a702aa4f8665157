// CanopenDevice: the HAL backend for CiA 402 servo drives on a CAN bus (CANopen, CiA 301
// communication), one drive (node) per joint, over a CanTransport (SocketCAN or socketpair).
//
// Lifecycle (non-RT, blocking up to the device file's timeouts, SDO allowed):
//  configure(): opens the bus (unless a transport was handed in), checks the bus load against
//    the bitrate, resets every node's communication (NMT) and waits for its boot-up, then per
//    node over SDO: identity 0x1018 against the device file, supported modes 0x6502 (cyclic
//    synchronous torque), motor rated torque 0x6076 against the file, mode 0x6060 = CST, max
//    torque 0x6072 from the current limit, abort-connection option 0x6007, heartbeat producer
//    0x1017 and consumer 0x1016 (of the master's heartbeat), the PDOs (mapping below, RPDO1
//    with an event-timer deadline), unused PDOs off. Any failure names the node, the joint,
//    the object and what was expected; the device stays unconfigured.
//  activate(): clears drive faults (fault reset over SDO; a drive that stays faulted fails
//    activate with its error code 0x603F decoded), NMT start. Heartbeats, SYNC and PDOs only
//    begin with the first RT cycle, so the drives' deadline monitoring (which starts with the
//    first heartbeat / RPDO received) cannot trip while the app is still being set up.
//  deactivate(): zero torque + "disable voltage" in RPDO1, a SYNC, NMT enter pre-operational.
//    Never blocks (non-blocking sends), never fails, any state.
//
// RT cycle (noexcept, no heap, no blocking; SDO never runs here):
//  read_encoders(): drains the bus (bounded), decodes TPDOs, heartbeats, EMCYs and error
//    frames, runs the heartbeat consumer, then reports each joint's position actual. A TPDO1
//    older than max_pdo_age_syncs SYNCs (kMaxPdoAgeSyncs) latches pdo_timeout (the sample is
//    invalid).
//  write_actuators(): per drive the CiA 402 controlword toward Operation enabled (enable) or
//    Switch on disabled (no torque), target torque in per-mille of the rated torque (clipped at the
//    max torque, saturated flag), then, on SYNC cycles, RPDO1 of every drive, RPDO2 (digital
//    outputs), the SYNC and, when due, the master's heartbeat in one sendmmsg.
//  The latched faults: bus-off, an EMCY (other than "no error"), a drive in Fault or Fault
//    reaction active, a drive's heartbeat lost, a node that rebooted, a node that left
//    Operational, a TPDO missing for a whole period, a TPDO of the wrong length. From that cycle every RT call returns ReturnCode::deactivate and every
//    RPDO carries zero torque with "quick stop"; communication recovering never clears it —
//    only deactivate() + activate() (an operator's restart) does.
//
// PDO layout (CiA 301 mapping entries index:sub/bits):
//   RPDO1 0x200+n, synchronous (type 1): 0x6040:00/16 controlword, 0x6071:00/16 target torque
//   RPDO2 0x300+n, digital-outputs node only: 0x60FE:01/32 physical outputs
//   TPDO1 0x180+n, every SYNC: 0x6041:00/16 statusword, 0x6064:00/32 position actual,
//                               0x6077:00/16 torque actual
//   TPDO2 0x280+n: 0x606C:00/32 velocity actual, 0x60FD:00/32 digital inputs; every SYNC from
//         the digital-inputs node (the e-stop), every kDiagnosticPdoEverySyncs-th from others
// Units: position actual in encoder counts (the device file's counts per motor revolution),
// torques in per-mille of 0x6076 (motor side); joint-side SI through hal::JointScale.
//
// Threads: lifecycle and RT calls from one thread at a time (the loop's); diagnostics() from
// the same thread or while it is stopped.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "trainer/core/clock.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/hal/device.hpp"
#include "trainer/hal/joint_scale.hpp"
#include "trainer/hal_canopen/heartbeat.hpp"
#include "trainer/hal_canopen/pdo.hpp"
#include "trainer/hal_socketcan/can_transport.hpp"

namespace trainer::hal::socketcan {

inline constexpr std::size_t kMaxDrives = 20;
// Age of a drive's newest TPDO1, counted in SYNCs sent since the one it answered. 0: it
// answered the last SYNC; 1: the answer to the last SYNC is not in yet, the one before is
// used (one SYNC old, tolerated: a drive answers within a period on a real bus, a slow host
// may read first); 2 or more: a whole period passed without the answer, the drive is lost
// for this purpose and the device latches pdo_timeout.
inline constexpr std::uint32_t kMaxPdoAgeSyncs = 1;
// Frames drained from the bus per read_encoders() at most (several recvmmsg calls).
inline constexpr std::size_t kMaxFramesPerCycle = 256;
// TPDO2 (velocity actual, digital inputs) of drives that are not the digital-inputs node:
// transmission type = every this many SYNCs (diagnostics only; saves bus bandwidth).
inline constexpr std::uint8_t kDiagnosticPdoEverySyncs = 10;

// The trainer's PDO layout (the table above) as the library's mappings: configure() writes
// them to the drives and the RT cycle packs and unpacks frames with the same objects.
struct PdoLayout {
  canopen::PdoMapping rpdo1;  // controlword, target torque
  canopen::PdoMapping rpdo2;  // physical outputs (digital-outputs node)
  canopen::PdoMapping tpdo1;  // statusword, position actual, torque actual
  canopen::PdoMapping tpdo2;  // velocity actual, digital inputs
};
const PdoLayout& pdo_layout() noexcept;

struct DriveParams {
  std::string channel_name;   // "left.pitch": used in every message about this drive
  std::string config_key;     // "instrument[0].pitch": the device file's table for messages
  std::uint8_t node_id = 0;   // 1..127
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0;
  std::optional<std::uint32_t> revision;
  double motor_rated_torque_nm = 0.0;  // 0x6076
  hal::JointScale scale;
};

struct CanopenDeviceParams {
  std::string name;
  std::string interface;         // SocketCAN interface (ignored when a transport is given)
  std::uint32_t bitrate = 0;     // bit/s; 0 = a virtual bus (no bus-load limit)
  std::int64_t loop_period_ns = 0;   // the RT cycle's period
  std::int64_t sync_period_ns = 0;   // a whole multiple of loop_period_ns
  std::uint8_t master_node_id = 127;
  std::int64_t master_heartbeat_ns = 0;
  std::int64_t drive_heartbeat_consumer_ns = 0;
  std::int64_t drive_heartbeat_ns = 0;
  std::int64_t drive_heartbeat_timeout_ns = 0;
  std::int64_t rpdo_timeout_ns = 0;
  std::uint8_t abort_connection_option = 3;  // 0x6007 value: 1 fault, 2 disable voltage, 3 quick stop
  std::int64_t sdo_timeout_ns = 0;
  std::int64_t boot_timeout_ns = 0;
  int digital_inputs_node = -1;   // -1 = no digital inputs
  int digital_outputs_node = -1;  // -1 = no digital outputs
  // Oldest TPDO (in SYNCs since the one it answered) still used; older latches pdo_timeout.
  // The trainer keeps kMaxPdoAgeSyncs; only tests whose drives run in another process on a
  // shared machine widen it, as they widen the other deadlines. [1, 1000]
  std::uint32_t max_pdo_age_syncs = kMaxPdoAgeSyncs;
  std::vector<DriveParams> drives;  // channel order
};

// Why the device latched (bits; the first one is kept with its node).
enum class CanFault : std::uint32_t {
  none = 0,
  bus_off = 1U << 0,
  emcy = 1U << 1,
  drive_fault = 1U << 2,
  heartbeat_lost = 1U << 3,
  node_rebooted = 1U << 4,
  node_not_operational = 1U << 5,
  pdo_timeout = 1U << 6,        // a TPDO older than max_pdo_age_syncs
  bad_pdo = 1U << 7,            // a TPDO of the wrong length for its mapping
};
const char* to_string(CanFault fault) noexcept;

struct CanDiagnostics {
  CanCounters transport;
  std::uint64_t sync_sent = 0;
  std::uint64_t rpdo_sent = 0;
  std::uint64_t tpdo_received = 0;
  std::uint64_t heartbeats_received = 0;
  std::uint64_t emcy_received = 0;
  std::uint64_t error_frames = 0;
  std::uint64_t frames_rejected = 0;     // malformed for their COB-ID, or unknown
  std::uint64_t stale_samples = 0;       // joint-cycles that used a TPDO1 one SYNC old
  std::uint64_t cycles_frame_budget_hit = 0;  // cycles that left frames on the bus
  std::uint32_t faults = 0;              // CanFault bits latched
  CanFault first_fault = CanFault::none;
  std::uint8_t first_fault_node = 0;
  std::uint16_t first_emcy_code = 0;     // of the first EMCY (0 = none)
  std::uint8_t first_emcy_register = 0;
  double bus_load = 0.0;                 // estimated fraction of the bitrate (0 = virtual bus)
};

class CanopenDevice final : public hal::Device,
                            public hal::EncoderInterface,
                            public hal::ActuatorInterface,
                            public hal::DigitalInputInterface,
                            public hal::DigitalOutputInterface {
 public:
  // `clock` must outlive the device. `transport`: an already open bus (tests: socketpair);
  // without it configure() opens params.interface.
  CanopenDevice(core::Clock& clock, CanopenDeviceParams params,
                std::optional<CanTransport> transport = std::nullopt);
  ~CanopenDevice() override;

  std::string_view name() const noexcept override { return params_.name; }
  core::Expected<void> configure() override;
  core::Expected<void> activate() override;
  void deactivate() noexcept override;
  hal::LifecycleState state() const noexcept override { return state_; }

  hal::EncoderInterface* encoders() noexcept override { return this; }
  hal::ActuatorInterface* actuators() noexcept override { return this; }
  hal::DigitalInputInterface* digital_inputs() noexcept override {
    return params_.digital_inputs_node > 0 ? this : nullptr;
  }
  hal::DigitalOutputInterface* digital_outputs() noexcept override {
    return params_.digital_outputs_node > 0 ? this : nullptr;
  }

  std::size_t encoder_count() const noexcept override { return drives_.size(); }
  hal::ReturnCode read_encoders(std::span<hal::EncoderSample> out) noexcept override;
  std::size_t actuator_count() const noexcept override { return drives_.size(); }
  hal::ReturnCode write_actuators(std::span<const hal::ActuatorCommand> commands) noexcept override;
  hal::ReturnCode read_actuator_status(std::span<hal::ActuatorStatus> out) noexcept override;
  std::size_t digital_input_count() const noexcept override { return 16; }
  hal::ReturnCode read_digital_inputs(std::uint32_t& levels) noexcept override;
  std::size_t digital_output_count() const noexcept override { return 16; }
  hal::ReturnCode write_digital_outputs(std::uint32_t levels) noexcept override;

  // Setup path, after deactivate(): asks every drive over SDO for its statusword (0x6041) and
  // torque actual (0x6077), so that read_actuator_status() reports what the drives say now
  // rather than their last PDO (no PDOs flow once the drives are pre-operational). Errors name
  // the drive that did not answer.
  core::Expected<void> refresh_status();

  const CanDiagnostics& diagnostics() const noexcept { return diagnostics_; }
  // One line per latched fault with node, joint and (for EMCY) the decoded error code.
  std::string fault_report() const;
  const CanopenDeviceParams& params() const noexcept { return params_; }
  // Estimated bus load (fraction of the bitrate) of these params' cyclic traffic.
  static double estimate_bus_load(const CanopenDeviceParams& params) noexcept;

 private:
  struct Drive {
    std::uint8_t node = 0;
    std::int32_t max_torque_permille = 0;  // 0x6072 as written
    double effort_per_permille = 0.0;      // joint-side N·m or N per per-mille
    // Latest TPDO1 / TPDO2.
    std::uint16_t statusword = 0;
    std::int32_t position_counts = 0;
    std::int16_t torque_actual_permille = 0;
    std::int32_t velocity_actual = 0;
    std::uint32_t digital_inputs = 0;
    bool tpdo1_seen = false;
    std::uint64_t tpdo1_sync = 0;  // SYNCs sent when it arrived
    bool tpdo2_seen = false;
    std::uint64_t tpdo2_sync = 0;
    // What goes out in the next RPDO1.
    std::uint16_t controlword = 0;
    std::int16_t target_permille = 0;
    bool saturated = false;
  };

  core::Expected<void> check_params() const;
  core::Expected<void> configure_node(std::size_t index);
  void reset_rt_state() noexcept;
  void drain_bus(std::int64_t now_ns) noexcept;
  void handle_frame(const can_frame& frame, std::int64_t now_ns) noexcept;
  void latch(CanFault fault, std::uint8_t node) noexcept;
  bool latched() const noexcept { return diagnostics_.faults != 0; }
  std::uint16_t next_controlword(const Drive& drive, bool enable) const noexcept;
  void send_cycle_frames(std::int64_t now_ns) noexcept;
  std::string drive_label(std::size_t index) const;

  core::Clock& clock_;
  CanopenDeviceParams params_;
  std::optional<CanTransport> transport_;
  hal::LifecycleState state_ = hal::LifecycleState::unconfigured;
  std::vector<Drive> drives_;                    // sized at configure, never resized after
  std::array<std::int16_t, 128> drive_of_node_{};  // node id -> drive index, -1 = none
  std::uint32_t sync_every_cycles_ = 1;
  std::uint64_t cycles_ = 0;
  std::uint64_t syncs_sent_ = 0;
  std::int64_t next_heartbeat_ns_ = 0;
  bool rt_started_ = false;
  std::uint32_t digital_outputs_ = 0;
  canopen::HeartbeatConsumer heartbeats_;  // the drives' heartbeats, from the first RT cycle
  CanDiagnostics diagnostics_{};
};

}  // namespace trainer::hal::socketcan
