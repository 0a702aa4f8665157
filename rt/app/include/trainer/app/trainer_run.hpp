// One run of the trainer: load the scene, build the HAL backend it names, carve the arena,
// start the RT thread, arm, supervise until the run ends or a stop signal arrives, shut down
// with outputs zeroed, and return everything the report needs. The `trainer` program is a thin
// CLI over run_trainer(); tests call it directly with a simulated clock.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "trainer/app/compute_trace.hpp"
#include "trainer/app/haptic_app.hpp"
#include "trainer/app/telemetry_sender.hpp"
#include "trainer/appliance/rt_check.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/loop/periodic_loop.hpp"
#include "trainer/hal_libusb/usb_device.hpp"
#include "trainer/hal_socketcan/canopen_device.hpp"
#include "trainer/loop/rt_settings.hpp"
#include "trainer/metrics/session_metrics.hpp"

namespace trainer::app {

enum class TimeSource : std::uint8_t {
  real,       // CLOCK_MONOTONIC, real sleeps: the appliance
  simulated,  // a manual clock: the loop and the simulated device run as fast as they can,
              // deterministically (offline runs, tests, golden traces); sim backend only
};

struct RunOptions {
  std::filesystem::path scene_file;
  // Replaces the device file the scene names (trainer --device FILE); the scene is checked
  // against it as if it named it.
  std::optional<std::filesystem::path> device_file;
  // "device": the backend the device file names ([device] backend); "sim": the simulated
  // bench with the device file's mechanism, whatever backend the file names.
  std::string hal = "device";
  std::optional<std::uint64_t> cycles;  // run length; default: the trainee script's length
  std::optional<double> seconds;
  // Upper bound on the run length whatever set it (cycles, seconds, the script's end, or a run
  // until a signal); > 0. The jitter tool runs a scene back to back with it.
  std::optional<std::uint64_t> max_cycles;
  // Replace the scene's loop.period_us / priority / cpu for this run (range-checked as in the
  // file; the report shows what ran).
  config::LoopOverrides loop_overrides;
  TimeSource time_source = TimeSource::real;
  // Real time slowed down by this whole factor (core::SlowMotionClock): for emulators (the
  // bench VM runs code ~20x slower than the hardware) and debugging. 1 = the appliance.
  std::int64_t slow_motion = 1;
  bool apply_rt_settings = true;  // SCHED_FIFO, affinity, mlockall from the scene's [loop]
  // Root of the /proc and /sys trees the RT self-check reads (tests give constructed trees).
  // The check runs when RT settings are applied in real time, before the device is created.
  std::filesystem::path rt_check_root = "/";
  bool arm = true;                // issue the explicit reset that arms the safety chain
  // Replaces the device file's [telemetry] for this run (trainer --telemetry ADDR:PORT).
  std::optional<config::TelemetryConfig> telemetry;
  // Called from the supervisor thread about 30 times a second with the newest snapshot.
  std::function<void(const TelemetrySnapshot&)> on_telemetry;
  // Record the session into this MCAP file (docs/recording.md): every cycle's HAL inputs,
  // outputs and state hash, written by the supervisor thread from a lock-free ring.
  std::optional<std::filesystem::path> record_file;
  // Receives formatted log lines drained from the RT log ring (default: stderr).
  std::function<void(const std::string&)> on_log;
  // Every cycle's real-clock step, stage and sub-stage times go into this trace, sized by the
  // run before arming (run_trainer_repeated; nullptr: none).
  CycleTimeTrace* compute_trace = nullptr;
};

struct RunResult {
  std::filesystem::path scene_file;
  std::string scene_name;
  std::string hal;  // the backend that ran: "sim", "canopen" or "usb"
  std::filesystem::path device_file;
  std::string time_source;
  std::int64_t slow_motion = 1;
  std::int64_t period_ns = 0;
  std::uint64_t requested_cycles = 0;
  loop::LoopStats loop;
  loop::RtReport rt;
  // The RT self-check run before arming (empty when RT settings were not applied).
  std::vector<appliance::RtCheckResult> rt_check;
  AppStats app;
  std::uint32_t latched_faults = 0;  // at the end of the run, before shutdown
  std::string first_fault;
  std::uint64_t first_fault_cycle = 0;
  std::vector<std::pair<std::string, std::uint64_t>> fault_counts;  // kinds raised, with counts
  std::uint64_t force_clamped_cycles = 0;
  std::uint64_t force_slew_limited_cycles = 0;
  std::uint32_t arm_count = 0;
  bool stopped_by_signal = false;
  bool allocation_hooks_installed = false;
  bool malloc_family_counted = false;
  std::uint64_t heap_allocations_after_arming = 0;
  std::size_t arena_bytes_used = 0;
  std::size_t arena_bytes_capacity = 0;
  std::uint64_t log_records_dropped = 0;
  bool outputs_zeroed_at_exit = false;
  // The session recording (--record): file, cycles written, cycles a full ring dropped,
  // bytes, the first write error (the run goes on without recording).
  std::string recording_file;
  std::uint64_t recorded_cycles = 0;
  std::uint64_t recording_dropped_cycles = 0;
  std::uint64_t recording_bytes = 0;
  std::string recording_error;
  // The trainee metrics of the session (docs/metrics.md), from every cycle's record (a cycle a
  // full ring dropped, recording_dropped_cycles, is missing from them too), with the scene's
  // thresholds; samples the metrics refused (non-finite values).
  std::optional<metrics::SessionResult> metrics;
  metrics::MetricsThresholds metrics_thresholds;
  std::uint64_t metrics_refused_samples = 0;
  double wall_time_s = 0.0;
  std::vector<std::string> instrument_names;
  std::vector<LoadedModelInfo> models;
  // CAN backend only: the bus's counters and the device's latched faults, decoded.
  std::optional<hal::socketcan::CanDiagnostics> can;
  std::string can_faults;
  std::optional<hal::libusb::UsbDiagnostics> usb;  // backend usb only
  std::string usb_faults;
  // The telemetry stream's counters ([telemetry] enabled only).
  std::optional<TelemetrySenderStats> telemetry_stream;
  // The app's state hash (docs/recording.md) when the loop ended, before shutdown: equal
  // for runs of the same session in simulated time.
  std::uint64_t final_state_hash = 0;
  // run_trainer_repeated only: the per-cycle minimum compute over the runs.
  std::optional<ComputeSummary> compute;
};

// In simulated time the loop's clock is a manual clock; the step time (run_cycle) is timed on
// the real monotonic clock, like the stage split, so both are the cycle's real compute time
// (the wake-up latency and the measured period stay on the manual clock: 0 and the period).
core::Expected<RunResult> run_trainer(const RunOptions& options);

// Runs at most this many times in one --repeat series.
inline constexpr std::uint32_t kMaxRepeatRuns = 100;

// trainer --repeat N (issue 19): the same simulated-time session `runs` times, each exactly as
// run_trainer runs it once (fresh device, app and arena), every cycle's real-clock step, stage
// and sub-stage times kept (buffers sized before arming); the result is the last run's, with
// `compute`: per cycle the minimum over the runs, and its percentiles. The runs must be
// identical (cycles, final state hash, faults, armed cycles): compute.identical says whether
// they were. Errors: real time (not deterministic), runs outside 1..kMaxRepeatRuns, a
// recording with runs > 1 (each run would overwrite it), any run's setup error (named "run k
// of N"). A stop signal ends the series after the run it interrupted, which is not folded.
core::Expected<RunResult> run_trainer_repeated(const RunOptions& options, std::uint32_t runs);

}  // namespace trainer::app
