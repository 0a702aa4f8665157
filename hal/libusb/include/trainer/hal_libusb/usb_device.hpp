// UsbDevice: the HAL backend for a USB haptic interface speaking the trainer's vendor protocol
// (docs/usb-protocol.md, hal/usbproto) through libusb-1.0. One channel per joint (encoder
// count in, motor current out), the device's buttons as the digital input word.
//
// Lifecycle (non-RT, bounded by the device file's timeouts):
//  configure(): libusb context, the device by VID:PID and serial (the error lists what is on
//    the bus instead), the vendor-specific interface claimed (a kernel driver detached), the
//    interrupt IN/OUT endpoints and their max packet read from the descriptors, the identity
//    by control request checked against the device file (protocol version, channel count,
//    firmware version, current limits), the device watchdog set by control request.
//  activate(): pre-allocates the transfers (kInTransfers IN + one OUT), submits the INs, starts
//    the non-RT event thread, clears a watchdog trip left from before, waits for the device to
//    answer with a clean status. From here the IN transfers are always in flight.
//  deactivate(): zero currents + disable sent and waited for (until the device acknowledges it
//    or usb.stop_timeout_ms), transfers cancelled and freed, thread joined, interface
//    released, device closed: the device is unconfigured again (a replugged device needs
//    configure() + activate(), an operator's reset; nothing re-arms by itself).
//
// Threads: the RT thread (read/write) and the libusb event thread share only two LatestValue
// triple buffers (newest IN report, next OUT report) and a few atomics; the RT thread never
// calls libusb, never waits, never allocates; its one system call is a non-blocking write to an
// eventfd that wakes the event thread when an OUT report was published. The event thread
// sleeps in poll() on libusb's descriptors and that eventfd, resubmits each completed IN
// transfer at once, and sends a new OUT report whenever the RT cycle published one and the OUT
// transfer is idle. An OUT report is never repeated: if the loop stops, the device's watchdog
// must see the silence and drop the currents.
//
// Unplug: the hotplug "device left" callback (where libusb supports hotplug) or a transfer
// completing with LIBUSB_TRANSFER_NO_DEVICE sets an atomic flag; the next RT call latches
// UsbFault::device_lost and returns ReturnCode::deactivate from then on. The time and loop
// cycle of the library's report and of the latch are in the diagnostics.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "trainer/core/clock.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/hal/device.hpp"
#include "trainer/hal/joint_scale.hpp"
#include "trainer/hal_libusb/frame_logic.hpp"
#include "trainer/hal_libusb/latest_value.hpp"

struct libusb_context;
struct libusb_device_handle;
struct libusb_transfer;

namespace trainer::hal::libusb {

struct UsbHotplugAccess;

inline constexpr std::size_t kInTransfers = 2;

struct UsbChannelParams {
  std::string channel_name;  // "left.pitch"
  std::string config_key;    // "instrument[0].pitch"
  hal::JointScale scale;
};

struct UsbDeviceParams {
  std::string name;
  std::uint16_t vendor_id = proto::kVendorId;
  std::uint16_t product_id = proto::kProductId;
  std::string serial;                      // empty = the only device with this VID:PID
  std::uint8_t protocol_version = proto::kProtocolVersion;
  std::optional<std::uint16_t> min_firmware_version;  // major << 8 | minor
  std::uint16_t watchdog_ms = 50;          // set on the device at configure
  std::uint32_t stale_limit_cycles = 2;
  std::int64_t control_timeout_ns = 100'000'000;
  std::int64_t start_timeout_ns = 1'000'000'000;
  std::int64_t stop_timeout_ns = 100'000'000;
  std::int64_t event_poll_ns = 10'000'000; // the event thread's longest sleep without events
  std::int64_t loop_period_ns = 1'000'000; // the RT cycle's period (watchdog check)
  std::vector<UsbChannelParams> channels;  // channel order
};

struct UsbDiagnostics {
  UsbFrameCounters frames;
  // Event thread.
  std::uint64_t in_completed = 0;
  std::uint64_t out_completed = 0;
  std::uint64_t out_submitted = 0;
  std::uint64_t out_superseded = 0;  // OUT reports replaced by a newer one before being sent
  std::uint64_t transfer_errors = 0; // completions other than ok / cancelled / no device
  // Identity and bus.
  std::uint16_t firmware_version = 0;
  std::uint8_t protocol_version = 0;
  std::uint8_t device_channels = 0;
  std::uint16_t watchdog_ms = 0;
  std::uint16_t max_current_ma = 0;
  std::uint8_t in_endpoint = 0;
  std::uint8_t out_endpoint = 0;
  std::uint16_t max_packet = 0;
  std::uint8_t interval = 0;   // bInterval of the IN endpoint
  std::string speed;           // "high", "full", ...
  std::string serial;
  bool hotplug = false;        // the hotplug callback was registered
  // Unplug: when libusb reported it (event thread) and when the RT cycle latched it.
  bool lost_reported = false;
  std::string lost_source;     // "hotplug" or "transfer"
  std::uint64_t lost_report_cycle = 0;  // RT cycles completed when the library reported it
  std::int64_t lost_report_ns = 0;      // CLOCK_MONOTONIC
  std::uint64_t lost_latch_cycle = 0;
  std::int64_t lost_latch_ns = 0;
  bool shutdown_acknowledged = false;   // deactivate(): the device acknowledged zero + disable
  // Round trip OUT -> device -> IN (frame_logic.hpp), from the fixed histogram: percentiles
  // are upper bin edges (10 us bins), min/max/mean exact.
  std::uint64_t round_trips = 0;
  std::int64_t round_trip_min_ns = 0;
  std::int64_t round_trip_p50_ns = 0;
  std::int64_t round_trip_p99_ns = 0;
  std::int64_t round_trip_p999_ns = 0;
  std::int64_t round_trip_max_ns = 0;
  double round_trip_mean_ns = 0.0;
};

class UsbDevice final : public hal::Device,
                        public hal::EncoderInterface,
                        public hal::ActuatorInterface,
                        public hal::DigitalInputInterface {
 public:
  UsbDevice(core::Clock& clock, UsbDeviceParams params);
  ~UsbDevice() override;

  std::string_view name() const noexcept override { return params_.name; }
  core::Expected<void> configure() override;
  core::Expected<void> activate() override;
  void deactivate() noexcept override;
  hal::LifecycleState state() const noexcept override { return state_; }

  hal::EncoderInterface* encoders() noexcept override { return this; }
  hal::ActuatorInterface* actuators() noexcept override { return this; }
  hal::DigitalInputInterface* digital_inputs() noexcept override { return this; }

  std::size_t encoder_count() const noexcept override { return params_.channels.size(); }
  hal::ReturnCode read_encoders(std::span<hal::EncoderSample> out) noexcept override;
  std::size_t actuator_count() const noexcept override { return params_.channels.size(); }
  hal::ReturnCode write_actuators(std::span<const hal::ActuatorCommand> commands) noexcept override;
  hal::ReturnCode read_actuator_status(std::span<hal::ActuatorStatus> out) noexcept override;
  std::size_t digital_input_count() const noexcept override { return 16; }
  hal::ReturnCode read_digital_inputs(std::uint32_t& levels) noexcept override;

  // Snapshot for the report (from the loop's thread or after it stopped).
  UsbDiagnostics diagnostics() const;
  std::string fault_report() const;
  const core::LatencyHistogram& round_trip() const noexcept { return logic_.round_trip(); }
  const UsbDeviceParams& params() const noexcept { return params_; }

 private:
  friend struct UsbHotplugAccess;
  static void in_callback(libusb_transfer* transfer);
  static void out_callback(libusb_transfer* transfer);
  void event_loop() noexcept;
  void report_lost(const char* source) noexcept;
  void submit_pending_out() noexcept;
  void wake_events() noexcept;
  core::Expected<void> open_device();
  core::Expected<void> check_identity();
  void close_device() noexcept;
  void stop_events() noexcept;
  void drain_transfers() noexcept;
  void latch_lost_if_reported() noexcept;
  // Setup path: publish one OUT report (all channels disabled, or a watchdog clear) and wait
  // until the device acknowledged it, up to timeout_ns.
  bool exchange_setup_report(bool clear_watchdog, std::int64_t timeout_ns) noexcept;

  core::Clock& clock_;
  core::MonotonicClock wall_;
  UsbDeviceParams params_;
  hal::LifecycleState state_ = hal::LifecycleState::unconfigured;
  bool configured_once_ = false;

  libusb_context* context_ = nullptr;
  libusb_device_handle* handle_ = nullptr;
  int interface_number_ = -1;
  int hotplug_handle_ = 0;
  bool hotplug_registered_ = false;
  std::array<libusb_transfer*, kInTransfers> in_transfers_{};
  libusb_transfer* out_transfer_ = nullptr;
  std::array<std::array<std::uint8_t, proto::kReportSize>, kInTransfers> in_buffers_{};
  std::array<std::uint8_t, proto::kReportSize> out_buffer_{};

  // Shared between the RT and the event thread.
  LatestValue<RawInReport> in_reports_;    // producer: event thread
  LatestValue<RawOutReport> out_reports_;  // producer: RT thread
  int wake_fd_ = -1;                       // eventfd: RT cycle -> event thread, "OUT published"
  std::atomic<bool> stop_{false};
  std::atomic<bool> lost_{false};
  std::atomic<std::uint64_t> rt_cycles_{0};
  std::atomic<std::uint64_t> in_completed_{0};
  std::atomic<std::uint64_t> out_completed_{0};
  std::atomic<std::uint64_t> out_submitted_{0};
  std::atomic<std::uint64_t> transfer_errors_{0};
  std::atomic<std::int64_t> lost_report_ns_{0};
  std::atomic<std::uint64_t> lost_report_cycle_{0};
  std::atomic<const char*> lost_source_{nullptr};

  // Event thread only.
  std::thread events_;
  int in_flight_ = 0;
  bool out_busy_ = false;
  std::uint64_t in_index_ = 0;

  // RT thread only (and setup while it is not running).
  UsbFrameLogic logic_;
  std::uint64_t out_superseded_ = 0;
  std::int64_t last_out_cycle_ns_ = 0;  // clock_ time of the last OUT report published
  std::uint64_t lost_latch_cycle_ = 0;
  std::int64_t lost_latch_ns_ = 0;
  bool shutdown_acknowledged_ = false;
  UsbDiagnostics identity_{};  // the identity / bus fields, filled at configure
};

}  // namespace trainer::hal::libusb
