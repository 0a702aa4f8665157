// usbbench: measures the USB link of a device file's interface with the trainer's own backend
// (hal/libusb UsbDevice, the same transfers, threads and per-cycle logic as the trainer):
// N cycles at a fixed period, each taking the newest IN report and publishing one OUT report
// (zero current, disabled unless --enable), then the round trip OUT -> device -> IN
// (percentiles of the fixed histogram), stale cycles, missed frames (device sequence gaps the
// host never received), transfer errors and the heap allocations of the cycle loop. The
// device answers each OUT report with one IN report, so a cycle whose previous round trip took
// longer than the period is stale; the bench counts those instead of latching (--stale-limit).
//
//   usbbench --device config/devices/usb_benchvm.toml --frames 100000 --period-us 1000
//            --report out/usbbench.json
// Exit status: 0 done, 1 setup failed, 3 the device latched a fault during the run.
#include <CLI/CLI.hpp>

#include <array>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "trainer/app/device_wiring.hpp"
#include "trainer/config/device.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/clock.hpp"
#include "trainer/hal_libusb/usb_device.hpp"

namespace {

using trainer::hal::libusb::UsbDevice;
using trainer::hal::libusb::UsbDiagnostics;

double us(std::int64_t ns) { return static_cast<double>(ns) * 1e-3; }

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"usbbench: round trip and missed frames of a USB haptic interface"};
  std::string device_file;
  std::uint64_t frames = 100'000;
  std::int64_t period_us = 1000;
  std::int64_t slow_motion = 1;
  bool enable = false;
  std::uint32_t stale_limit = 1000;
  std::string report_file;
  cli.add_option("--device", device_file, "device file with backend \"usb\"")->required();
  cli.add_option("--frames", frames, "cycles (one OUT and one IN report each)")
      ->check(CLI::Range(std::uint64_t{1}, std::uint64_t{100'000'000}));
  cli.add_option("--period-us", period_us, "cycle period, microseconds")
      ->check(CLI::Range(50, 100'000));
  cli.add_option("--slow-motion", slow_motion,
                 "slow the cycle clock down by this factor (as the trainer's --slow-motion)")
      ->check(CLI::Range(1, 1000));
  cli.add_option("--stale-limit", stale_limit,
                 "stale cycles in a row that latch device_stopped (the device file's "
                 "usb.stale_limit_cycles is for the trainer; the bench counts stale cycles "
                 "and keeps measuring)")
      ->check(CLI::Range(1U, 1'000'000U));
  cli.add_flag("--enable", enable, "send enable (with zero current) instead of disabled");
  cli.add_option("--report", report_file, "write the figures as JSON here");
  CLI11_PARSE(cli, argc, argv);

  auto device_config = trainer::config::load_device(device_file);
  if (!device_config) {
    std::cerr << "usbbench: " << device_config.error().message << "\n";
    return 1;
  }
  if (device_config->backend != "usb") {
    std::cerr << "usbbench: " << device_file << ": backend '" << device_config->backend
              << "', expected \"usb\"\n";
    return 1;
  }
  trainer::config::SceneConfig scene;
  scene.device = std::move(*device_config);
  scene.loop.period_ns = period_us * 1000;
  trainer::core::SlowMotionClock clock(slow_motion);
  trainer::hal::libusb::UsbDeviceParams params = trainer::app::usb_params_from(scene);
  params.stale_limit_cycles = stale_limit;
  UsbDevice device(clock, params);
  if (auto configured = device.configure(); !configured) {
    std::cerr << "usbbench: " << device_file << ": " << configured.error().message << "\n";
    return 1;
  }
  if (auto activated = device.activate(); !activated) {
    std::cerr << "usbbench: " << device_file << ": " << activated.error().message << "\n";
    device.deactivate();
    return 1;
  }
  const std::size_t channels = device.encoder_count();
  std::vector<trainer::hal::EncoderSample> samples(channels);
  std::vector<trainer::hal::ActuatorCommand> commands(channels);
  for (auto& command : commands) command.enable = enable;

  const std::int64_t period_ns = period_us * 1000;
  std::int64_t deadline = clock.now_ns();
  std::uint64_t late_cycles = 0;
  std::uint64_t ran = 0;
  bool faulted = false;
  const std::uint64_t allocations_before = trainer::core::alloc::counted_allocations();
  trainer::core::alloc::begin_counting_this_thread();
  for (; ran < frames; ++ran) {
    deadline += period_ns;
    clock.sleep_until_ns(deadline);
    if (clock.now_ns() > deadline + period_ns / 2) ++late_cycles;
    const auto read = device.read_encoders(samples);
    const auto wrote = device.write_actuators(commands);
    if (read == trainer::hal::ReturnCode::deactivate ||
        wrote == trainer::hal::ReturnCode::deactivate) {
      faulted = true;
      ++ran;
      break;
    }
  }
  trainer::core::alloc::end_counting_this_thread();
  const std::uint64_t allocations =
      trainer::core::alloc::counted_allocations() - allocations_before;
  device.deactivate();

  const UsbDiagnostics d = device.diagnostics();
  const auto& f = d.frames;
  const double received = static_cast<double>(d.in_completed);
  const double missed_rate =
      received + static_cast<double>(f.missed_frames) > 0.0
          ? static_cast<double>(f.missed_frames) / (received + static_cast<double>(f.missed_frames))
          : 0.0;
  nlohmann::json report = {
      {"device_file", device_file},
      {"serial", d.serial},
      {"speed", d.speed},
      {"firmware_version", d.firmware_version},
      {"interval", d.interval},
      {"period_us", period_us},
      {"slow_motion", slow_motion},
      {"frames_requested", frames},
      {"cycles", ran},
      {"late_cycles", late_cycles},
      {"heap_allocations_in_loop", allocations},
      {"allocation_hooks_installed", trainer::core::alloc::hooks_installed()},
      {"in_completed", d.in_completed},
      {"in_reports_used", f.in_reports_used},
      {"in_superseded", f.in_superseded},
      {"stale_frames", f.stale_frames},
      {"not_due_cycles", f.not_due_cycles},
      {"stale_run_max", f.stale_run_max},
      {"missed_frames", f.missed_frames},
      {"missed_rate", missed_rate},
      {"bad_reports", f.bad_reports},
      {"out_published", f.out_published},
      {"out_submitted", d.out_submitted},
      {"out_completed", d.out_completed},
      {"out_superseded", d.out_superseded},
      {"transfer_errors", d.transfer_errors},
      {"acks", f.acks},
      {"round_trip_us",
       {{"count", d.round_trips},
        {"min", us(d.round_trip_min_ns)},
        {"p50", us(d.round_trip_p50_ns)},
        {"p99", us(d.round_trip_p99_ns)},
        {"p999", us(d.round_trip_p999_ns)},
        {"max", us(d.round_trip_max_ns)},
        {"mean", d.round_trip_mean_ns * 1e-3}}},
      {"faults", device.fault_report()},
      {"shutdown_acknowledged", d.shutdown_acknowledged},
  };
  if (!report_file.empty()) std::ofstream(report_file) << report.dump(2) << "\n";
  std::printf(
      "usbbench: %llu cycles of %lld us (x%lld), %llu late; IN %llu received, %llu used, %llu "
      "stale cycles, %llu missed frames (rate %.2e), %llu bad, %llu transfer errors; round trip "
      "over %llu: min %.0f p50 %.0f p99 %.0f p99.9 %.0f max %.0f us; heap in loop %llu; "
      "faults: %s\n",
      static_cast<unsigned long long>(ran), static_cast<long long>(period_us),
      static_cast<long long>(slow_motion), static_cast<unsigned long long>(late_cycles),
      static_cast<unsigned long long>(d.in_completed),
      static_cast<unsigned long long>(f.in_reports_used),
      static_cast<unsigned long long>(f.stale_frames),
      static_cast<unsigned long long>(f.missed_frames), missed_rate,
      static_cast<unsigned long long>(f.bad_reports),
      static_cast<unsigned long long>(d.transfer_errors),
      static_cast<unsigned long long>(d.round_trips), us(d.round_trip_min_ns),
      us(d.round_trip_p50_ns), us(d.round_trip_p99_ns), us(d.round_trip_p999_ns),
      us(d.round_trip_max_ns), static_cast<unsigned long long>(allocations),
      faulted ? device.fault_report().c_str() : "none");
  return faulted ? 3 : 0;
}
