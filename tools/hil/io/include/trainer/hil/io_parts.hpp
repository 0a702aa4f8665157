// The GPIO and USB parts of `hil`, the bring-up tool (docs/hil-io.md): what `hil scan` finds on
// the bench's GPIO chips and USB bus and how it compares with the device file's [gpio] / [usb]
// tables, and the steps of `hil check` (e-stop and enable edge to latch, outputs set and read
// back, USB round trip, identity, watchdog). Each part returns the shared vocabulary of
// trainer/hil/step.hpp; the program registers them next to the CAN part.
//
// Underneath, the pieces that are tested in process: the GPIO listing as plain data and its
// comparison with a [gpio] table, and the edge-to-latch bookkeeping over a read loop.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "trainer/config/device.hpp"
#include "trainer/hal_libusb/usb_device.hpp"
#include "trainer/hil/step.hpp"

namespace trainer::hil {

// ---------------------------------------------------------------- the parts
ScanSection scan_gpio(const BenchContext& bench);
CheckSection check_gpio(const BenchContext& bench);
ScanSection scan_usb(const BenchContext& bench);
CheckSection check_usb(const BenchContext& bench);

// The options of the GPIO checks that BenchContext does not carry. Defaults: the trainer's 1 ms
// loop period stretched by the bench's slow motion, a margin of half a period.
struct GpioCheckOptions {
  std::int64_t period_ns = 0;  // 0 = 1 ms x slow_motion
  std::int64_t margin_ns = -1;  // -1 = half the period
  bool realtime = true;        // read loop at SCHED_FIFO 40 when permitted
};
CheckSection check_gpio(const BenchContext& bench, const GpioCheckOptions& options);

// ---------------------------------------------------------------- GPIO listing and comparison
struct GpioLineInfo {
  unsigned offset = 0;
  std::string name;      // "" when the line has none
  std::string consumer;  // "" when free
  bool used = false;
  bool output = false;
  bool active_low = false;
};

struct GpioChipInfo {
  std::string name;   // "gpiochip0"
  std::string label;  // "trainer-bench"
  std::string path;   // "/dev/gpiochip0"
  std::vector<GpioLineInfo> lines;  // by offset
};

// Every GPIO chip of the system and its lines (libgpiod). Empty when there is none; `error`
// says why when the chips exist but cannot be read (permissions).
std::vector<GpioChipInfo> list_gpio_chips(std::string* error = nullptr);

// What a [gpio] line is for, from the [digital] bits: "estop", "enable", "drive_enable",
// "fault_lamp", else "input0" / "output3" (by bit).
std::string gpio_line_role(const config::DeviceConfig& device, const config::GpioLineConfig& line,
                           bool output);

// The chip a device file names (label first unless "gpiochipN" or a path; as hal/gpiod).
const GpioChipInfo* find_gpio_chip(const std::vector<GpioChipInfo>& chips, const std::string& text);

// One step per [gpio] line: chip missing, line missing / offset out of range, used by another
// consumer, wrong direction, the same line twice. Ids "gpio.scan.<role>".
std::vector<StepResult> compare_gpio(const std::vector<GpioChipInfo>& chips,
                                     const config::DeviceConfig& device);

ScanSection make_gpio_scan_section(const std::vector<GpioChipInfo>& chips,
                                   const std::optional<config::DeviceConfig>& device);

// ---------------------------------------------------------------- edge to latch
// One read of the periodic loop as the measurement sees it: when the read returned, whether it
// reported the input active (GpioDevice's latched level), and the kernel timestamp of the
// oldest edge event that read drained (0 = none).
struct LatchRead {
  std::int64_t start_ns = 0;  // when the read began (0 = unknown)
  std::int64_t done_ns = 0;
  bool reported_active = false;
  std::int64_t event_ns = 0;
};

struct LatchTrial {
  std::int64_t edge_ns = 0;   // kernel timestamp of the press's first edge (0 = none seen)
  std::int64_t latch_ns = 0;  // the read that first reported the press returned
  std::int64_t reads = 0;     // reads from arming up to and including that read
  // The read reported the level before any event of the press was drained: the edge's
  // timestamp came from a later read (the kernel's IRQ thread ran after the read).
  bool level_before_event = false;
  // A read that began after the edge did not report it: the press was seen one read late
  // (its event was queued after that read: the kernel's IRQ thread ran late).
  bool missed_by_a_read = false;
  // The read that reported it began more than a period after the edge: the reader was late.
  std::int64_t latch_read_start_ns = 0;
  std::int64_t edge_to_latch_ns() const { return latch_ns - edge_ns; }
};

// The bookkeeping of one input over a read loop: arm() before asking for the press; on_read()
// for every read; a trial is complete when the press was reported and its edge's timestamp is
// known (the same read, or — when the level came first — a later one). Events older than the
// arming are ignored (the previous release's). `quiet()` says the input has read inactive for
// two reads in a row: ready for the next trial.
class EdgeLatchMeter {
 public:
  void arm(std::int64_t now_ns);
  // Returns true when this read completed the armed trial (then trial() holds it).
  bool on_read(const LatchRead& read);
  bool armed() const { return armed_; }
  bool quiet() const { return inactive_streak_ >= 2; }
  bool active() const { return last_active_; }
  const LatchTrial& trial() const { return trial_; }
  // Reads while armed that reported the input only because of an event older than the arming.
  std::int64_t stale_reports() const { return stale_reports_; }

 private:
  bool armed_ = false;
  bool latched_ = false;  // reported, waiting for the edge's timestamp
  std::int64_t arm_ns_ = 0;
  std::int64_t inactive_streak_ = 0;
  std::int64_t stale_reports_ = 0;
  std::int64_t unreported_start_ns_ = 0;  // the last armed read that did not report the press
  void complete(std::int64_t edge_ns);
  bool last_active_ = false;
  LatchTrial trial_;
};

struct LatchSummary {
  std::size_t trials = 0;
  std::int64_t p50_ns = 0, p90_ns = 0, p99_ns = 0, max_ns = 0, min_ns = 0;
  std::size_t over_limit = 0;
  std::size_t level_before_event = 0;
  std::size_t missed_by_a_read = 0;   // see LatchTrial
  std::size_t late_reader = 0;        // latching read began > one period after the edge
};
// Percentiles by nearest rank over the trials' edge-to-latch times.
LatchSummary summarize_latches(const std::vector<LatchTrial>& trials, std::int64_t limit_ns,
                               std::int64_t period_ns = 0);

// The step's verdict: pass when every trial latched within `limit_ns`; `wanted` trials were
// asked for (fewer = some were not pressed in time: fail naming the line).
StepResult judge_edge_to_latch(const std::string& id, const std::string& title,
                               const std::vector<LatchTrial>& trials, std::size_t wanted,
                               std::int64_t period_ns, std::int64_t limit_ns);

// ---------------------------------------------------------------- USB listing and comparison
struct UsbIdentity {  // the protocol's GET_IDENTITY answer (hal/usbproto Identity)
  unsigned protocol_version = 0;
  unsigned firmware_version = 0;  // major << 8 | minor
  unsigned channel_count = 0;
  unsigned watchdog_ms = 0;
  unsigned frame_interval_us = 0;
  unsigned max_current_ma = 0;
};

struct UsbFoundDevice {
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  unsigned bus = 0;
  unsigned address = 0;
  std::string serial;
  int vendor_interface = -1;   // first vendor-specific (0xFF) interface, -1 = none
  bool protocol_ids = false;   // the VID:PID asked for (the protocol's or the device file's)
  std::optional<UsbIdentity> identity;  // asked of protocol_ids devices only
  std::string error;           // why the identity (or the serial) could not be read
};

// The devices with that VID:PID (identity asked) and every other device with a vendor-specific
// interface (listed only: a vendor request means something else to another vendor's device).
std::vector<UsbFoundDevice> list_usb_devices(std::uint16_t vendor_id, std::uint16_t product_id,
                                             std::string* error = nullptr);

// usb.scan.device (missing, ambiguous, no identity), usb.scan.protocol_version,
// usb.scan.firmware_version, usb.scan.channels (device vs instruments x 5), usb.scan.extra.<serial>.
std::vector<StepResult> compare_usb(const std::vector<UsbFoundDevice>& found,
                                    const config::DeviceConfig& device);
ScanSection make_usb_scan_section(const std::vector<UsbFoundDevice>& found,
                                  const std::optional<config::DeviceConfig>& device);

// The options of the USB checks that BenchContext does not carry.
struct UsbCheckOptions {
  std::int64_t exchanges = 1000;  // round-trip step
  std::int64_t period_ns = 0;     // loop period (device time); 0 = 1 ms
};
CheckSection check_usb(const BenchContext& bench, const UsbCheckOptions& options);

// The round-trip step's verdict from the backend's diagnostics after `exchanges` cycles of
// `real_period_ns` (wall clock): fails on a latched fault (`fault` non-empty), a refused report
// or transfer error, fewer round trips than a tenth of the cycles, or a run of stale cycles
// reaching the device file's `stale_limit` (the trainer would latch device_stopped).
StepResult judge_round_trip(const hal::libusb::UsbDiagnostics& diagnostics, std::int64_t exchanges,
                            std::int64_t real_period_ns, std::uint32_t stale_limit,
                            const std::string& fault);
// A channel's torque pulse: + effort must move the encoder + by at least min_counts.
StepResult judge_polarity(const std::string& channel, std::int64_t delta_counts,
                          std::int64_t min_counts, double effort, const std::string& unit);
// The device watchdog: currents dropped (the trip report seen) `trip_ns` after the last OUT
// report (-1 = never within the wait); pass within [0.9 x watchdog, limit].
StepResult judge_watchdog(std::int64_t trip_ns, std::int64_t watchdog_ns, std::int64_t limit_ns,
                          std::int64_t waited_ns, std::int64_t slow_motion);

// ---------------------------------------------------------------- output

}  // namespace trainer::hil
