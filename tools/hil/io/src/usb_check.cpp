// hil check, USB (docs/hil-io.md), through the trainer's own backend (hal/libusb UsbDevice: the
// same transfers, event thread and per-cycle frame logic as the trainer): the round trip and
// missed/stale frames over N exchanges, a small torque pulse per channel (encoder direction vs
// motor polarity), and the device watchdog (the host stops sending: the device must drop the
// currents within its watchdog time, timed).
#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "trainer/app/device_wiring.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/clock.hpp"
#include "trainer/hal_libusb/usb_device.hpp"
#include "trainer/hil/io_parts.hpp"

namespace trainer::hil {
namespace {

namespace up = trainer::hal::usbproto;
using hal::libusb::UsbDevice;

std::int64_t usb_check_wall_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

std::string usb_check_fmt(double value, const char* format = "%.2f") {
  char text[48];
  std::snprintf(text, sizeof text, format, value);
  return text;
}

double usb_check_ms(std::int64_t ns) { return static_cast<double>(ns) / 1e6; }

// Runs `cycles` loop cycles (read, then write `commands`) at the device's period on `clock`.
// Returns false when the device latched a fault.
bool usb_check_cycles(UsbDevice& device, core::Clock& clock, std::int64_t period_ns,
                      std::int64_t& deadline, std::int64_t cycles,
                      std::vector<hal::EncoderSample>& samples,
                      const std::vector<hal::ActuatorCommand>& commands) {
  for (std::int64_t i = 0; i < cycles; ++i) {
    deadline += period_ns;
    clock.sleep_until_ns(deadline);
    if (clock.now_ns() > deadline + period_ns) deadline = clock.now_ns();  // late: no burst
    const auto read = device.read_encoders(samples);
    const auto wrote = device.write_actuators(commands);
    if (read == hal::ReturnCode::deactivate || wrote == hal::ReturnCode::deactivate) return false;
  }
  return true;
}

StepResult usb_check_failed(const std::string& id, const std::string& title, std::string reason) {
  StepResult step;
  step.id = id;
  step.title = title;
  step.outcome = Outcome::fail;
  step.reason = std::move(reason);
  return step;
}

}  // namespace

StepResult judge_polarity(const std::string& channel, std::int64_t delta_counts,
                          std::int64_t min_counts, double effort, const std::string& unit) {
  StepResult step;
  step.id = "usb." + channel + ".polarity";
  step.title = channel + ": encoder direction and motor polarity (torque pulse)";
  step.figures = {{"delta", static_cast<double>(delta_counts), "counts"},
                  {"effort", effort, unit}};
  const std::string pulse = "+" + usb_check_fmt(effort, "%.3g") + " " + unit;
  if (std::abs(delta_counts) < min_counts) {
    step.outcome = Outcome::fail;
    step.reason = "no motion under " + pulse + ": " + std::to_string(delta_counts) +
                  " counts (at least " + std::to_string(min_counts) +
                  " expected) — motor or encoder not connected, or the joint is blocked";
  } else if (delta_counts < 0) {
    step.outcome = Outcome::fail;
    step.reason = "moved " + std::to_string(delta_counts) + " counts under " + pulse +
                  ": encoder direction and motor polarity disagree (reverse one of them)";
  } else {
    step.outcome = Outcome::pass;
    step.reason = "moved +" + std::to_string(delta_counts) + " counts under " + pulse;
  }
  return step;
}

StepResult judge_watchdog(std::int64_t trip_ns, std::int64_t watchdog_ns, std::int64_t limit_ns,
                          std::int64_t waited_ns, std::int64_t slow_motion) {
  StepResult step;
  step.id = "usb.watchdog";
  step.title = "device watchdog: currents dropped when the host stops sending";
  const double slow = static_cast<double>(std::max<std::int64_t>(1, slow_motion));
  const std::string wd = usb_check_fmt(usb_check_ms(watchdog_ns) / slow, "%.0f") + " ms" +
                         (slow_motion > 1 ? " (x" + std::to_string(slow_motion) + ": " +
                                                usb_check_fmt(usb_check_ms(watchdog_ns), "%.0f") +
                                                " ms real)"
                                          : "");
  step.figures = {{"watchdog", usb_check_ms(watchdog_ns), "ms"},
                  {"limit", usb_check_ms(limit_ns), "ms"}};
  if (trip_ns < 0) {
    step.outcome = Outcome::fail;
    step.reason = "no watchdog trip reported within " +
                  usb_check_fmt(usb_check_ms(waited_ns), "%.0f") +
                  " ms of silence: the device keeps its currents (watchdog " + wd + ")";
    return step;
  }
  step.figures.push_back({"trip", usb_check_ms(trip_ns), "ms"});
  const std::string numbers = "tripped " + usb_check_fmt(usb_check_ms(trip_ns), "%.1f") +
                              " ms after the last OUT report; watchdog " + wd + ", limit " +
                              usb_check_fmt(usb_check_ms(limit_ns), "%.1f") + " ms";
  if (trip_ns > limit_ns) {
    step.outcome = Outcome::fail;
    step.reason = "too late: " + numbers;
  } else if (static_cast<double>(trip_ns) < 0.9 * static_cast<double>(watchdog_ns)) {
    step.outcome = Outcome::fail;
    step.reason = "too early (before 0.9 x the watchdog): " + numbers;
  } else {
    step.outcome = Outcome::pass;
    step.reason = numbers;
  }
  return step;
}

StepResult judge_round_trip(const hal::libusb::UsbDiagnostics& d, std::int64_t exchanges,
                            std::int64_t real_period_ns, std::uint32_t stale_limit,
                            const std::string& fault) {
  StepResult step;
  step.id = "usb.round_trip";
  step.title = "round trip OUT -> device -> IN over " + std::to_string(exchanges) +
               " exchanges";
  const double real_period_ms = usb_check_ms(real_period_ns);
  step.figures = {{"exchanges", static_cast<double>(exchanges), "cycles"},
                  {"round_trips", static_cast<double>(d.round_trips), "reports"},
                  {"p50", usb_check_ms(d.round_trip_p50_ns), "ms"},
                  {"p99", usb_check_ms(d.round_trip_p99_ns), "ms"},
                  {"max", usb_check_ms(d.round_trip_max_ns), "ms"},
                  {"missed", static_cast<double>(d.frames.missed_frames), "frames"},
                  {"stale", static_cast<double>(d.frames.stale_frames), "cycles"},
                  {"stale_run_max", static_cast<double>(d.frames.stale_run_max), "cycles"},
                  {"period", real_period_ms, "ms"}};
  step.details = {{"bad_reports", d.frames.bad_reports},
                  {"transfer_errors", d.transfer_errors},
                  {"in_completed", d.in_completed},
                  {"out_superseded", d.out_superseded},
                  {"speed", d.speed},
                  {"serial", d.serial}};
  const std::string numbers =
      "p50 " + usb_check_fmt(usb_check_ms(d.round_trip_p50_ns)) + " ms, p99 " +
      usb_check_fmt(usb_check_ms(d.round_trip_p99_ns)) + " ms, max " +
      usb_check_fmt(usb_check_ms(d.round_trip_max_ns)) + " ms over " +
      std::to_string(d.round_trips) + " round trips; " + std::to_string(d.frames.missed_frames) +
      " missed frames, " + std::to_string(d.frames.stale_frames) + " stale cycles; period " +
      usb_check_fmt(real_period_ms) + " ms";
  if (!fault.empty()) {
    step.outcome = Outcome::fail;
    step.reason = "the device latched " + fault + ": " + numbers;
  } else if (d.frames.bad_reports > 0 || d.transfer_errors > 0) {
    step.outcome = Outcome::fail;
    step.reason = std::to_string(d.frames.bad_reports) + " IN reports refused, " +
                  std::to_string(d.transfer_errors) + " transfer errors: " + numbers;
  } else if (static_cast<std::int64_t>(d.round_trips) < exchanges / 10) {
    step.outcome = Outcome::fail;
    step.reason = "too few round trips measured: " + numbers;
  } else if (d.frames.stale_run_max >= stale_limit) {
    step.outcome = Outcome::fail;
    step.reason = std::to_string(d.frames.stale_run_max) +
                  " stale cycles in a row: the trainer would latch device_stopped (usb."
                  "stale_limit_cycles = " + std::to_string(stale_limit) + "): " + numbers;
  } else {
    step.outcome = Outcome::pass;
    step.reason = numbers + "; longest stale run " + std::to_string(d.frames.stale_run_max) +
                  " < usb.stale_limit_cycles " + std::to_string(stale_limit);
    if (usb_check_ms(d.round_trip_p99_ns) > real_period_ms) {
      step.reason += " (p99 above a period: answers often come a cycle late)";
    }
  }
  return step;
}

CheckSection check_usb(const BenchContext& bench) { return check_usb(bench, UsbCheckOptions{}); }

CheckSection check_usb(const BenchContext& bench, const UsbCheckOptions& options) {
  CheckSection section;
  section.part = "usb";
  auto skip_all = [](const std::string& reason) {
    return skipped_checks("usb", "USB checks", reason);
  };
  if (!bench.device) return skip_all("no device file: the interface and its channels are the [usb] table's");
  if (bench.device->backend != "usb") {
    return skip_all(bench.device->source_path.string() + " has backend \"" + bench.device->backend +
                    "\", not \"usb\"");
  }
  const std::int64_t slow = std::max<std::int64_t>(1, bench.slow_motion);
  config::SceneConfig scene;
  scene.device = *bench.device;
  scene.loop.period_ns = options.period_ns > 0 ? options.period_ns : 1'000'000;
  const std::int64_t period_ns = scene.loop.period_ns;
  core::SlowMotionClock clock(slow);
  hal::libusb::UsbDeviceParams params = app::usb_params_from(scene);
  params.name = "hil";
  // The round trip counts stale cycles instead of latching on them (as usbbench) and judges
  // the longest run against the device file's limit.
  const std::uint32_t file_stale_limit = params.stale_limit_cycles;
  params.stale_limit_cycles = std::max<std::uint32_t>(params.stale_limit_cycles, 1000);
  // The identity's frame interval (plant time per exchange), asked before the backend claims
  // the interface.
  std::int64_t frame_interval_us = 1000;
  for (const UsbFoundDevice& d : list_usb_devices(params.vendor_id, params.product_id)) {
    if (d.protocol_ids && d.identity && (params.serial.empty() || d.serial == params.serial) &&
        d.identity->frame_interval_us > 0) {
      frame_interval_us = d.identity->frame_interval_us;
    }
  }
  UsbDevice device(clock, params);
  if (auto configured = device.configure(); !configured) {
    section.steps.push_back(usb_check_failed("usb.open", "open the USB interface",
                                             configured.error().message));
    return section;
  }
  if (auto active = device.activate(); !active) {
    section.steps.push_back(usb_check_failed("usb.open", "open the USB interface",
                                             active.error().message));
    device.deactivate();
    return section;
  }
  const std::size_t channels = device.encoder_count();
  std::vector<hal::EncoderSample> samples(channels);
  std::vector<hal::ActuatorCommand> commands(channels);
  std::int64_t deadline = clock.now_ns();

  // 1. Round trip and missed/stale frames, currents zero and disabled.
  {
    const bool ok = usb_check_cycles(device, clock, period_ns, deadline, options.exchanges, samples,
                                     commands);
    const hal::libusb::UsbDiagnostics d = device.diagnostics();
    StepResult step = judge_round_trip(d, options.exchanges, period_ns * slow, file_stale_limit,
                                       ok ? std::string() : device.fault_report());
    section.steps.push_back(std::move(step));
    if (!ok) {
      device.deactivate();
      return section;
    }
  }

  // 2. Per channel a small torque pulse: + effort must move the encoder +.
  const bool torque_ok =
      bench.op != nullptr &&
      bench.op->confirm("apply torque pulses of " +
                        usb_check_fmt(bench.max_torque_fraction * 100.0, "%.0f") +
                        " % of each joint's current limit, one joint at a time, and then "
                        "enable a small torque and stop sending (watchdog)?");
  if (!torque_ok) {
    StepResult step;
    step.id = "usb.polarity";
    step.title = "encoder direction and motor polarity";
    step.reason = "torque not confirmed";
    section.steps.push_back(step);
    step.id = "usb.watchdog";
    step.title = "device watchdog";
    section.steps.push_back(std::move(step));
    device.deactivate();
    return section;
  }
  // The pulse lasts ~20 ms of the device's plant time (its frame interval per exchange), then a
  // quarter of that at zero (each channel's motion is measured on that channel alone).
  const std::int64_t pulse_cycles =
      std::clamp<std::int64_t>(20'000 / std::max<std::int64_t>(1, frame_interval_us), 10, 300);
  for (auto& c : commands) {
    c.enable = true;
    c.effort = 0.0F;
  }
  bool running = usb_check_cycles(device, clock, period_ns, deadline, 5, samples, commands);
  for (std::size_t ch = 0; ch < channels && running; ++ch) {
    const auto& channel = params.channels[ch];
    const double effort = bench.max_torque_fraction * channel.scale.max_effort();
    running = usb_check_cycles(device, clock, period_ns, deadline, 3, samples, commands);
    const std::int64_t before = samples[ch].counts;
    commands[ch].effort = static_cast<float>(effort);
    running = running && usb_check_cycles(device, clock, period_ns, deadline, pulse_cycles, samples,
                                          commands);
    const std::int64_t after = samples[ch].counts;
    commands[ch].effort = 0.0F;
    running = running && usb_check_cycles(device, clock, period_ns, deadline, pulse_cycles / 4,
                                          samples, commands);
    if (!running) {
      section.steps.push_back(usb_check_failed("usb." + channel.channel_name + ".polarity",
                                               channel.channel_name + ": torque pulse",
                                               "the device latched " + device.fault_report()));
      break;
    }
    StepResult step = judge_polarity(channel.channel_name, after - before, 2, effort,
                                     channel.scale.kind == hal::JointKind::prismatic ? "N" : "N·m");
    step.details = {{"config_key", channel.config_key}, {"before", before}, {"after", after}};
    section.steps.push_back(std::move(step));
  }
  if (!running) {
    device.deactivate();
    return section;
  }

  // 3. The watchdog: a small torque enabled, then silence; the device's trip report timed
  // from the last OUT report's publication.
  {
    commands[0].effort = static_cast<float>(bench.max_torque_fraction * params.channels[0].scale.max_effort());
    running = usb_check_cycles(device, clock, period_ns, deadline, 5, samples, commands);
    const std::int64_t last_out = usb_check_wall_ns();
    const std::int64_t watchdog_ns = static_cast<std::int64_t>(params.watchdog_ms) * 1'000'000 * slow;
    // A period of the device's frame and of this poll on top of the watchdog.
    const std::int64_t limit_ns = watchdog_ns + 2 * period_ns * slow + 5'000'000 * slow;
    const std::int64_t wait_ns = 5 * watchdog_ns + 1'000'000'000;
    std::int64_t trip_ns = -1;
    const std::uint64_t reports_before = device.diagnostics().frames.watchdog_reports;
    while (running && usb_check_wall_ns() - last_out < wait_ns) {
      timespec pause{0, 500'000};
      nanosleep(&pause, nullptr);
      (void)device.read_encoders(samples);  // reads only: no OUT report is published
      const auto d = device.diagnostics();
      if (d.frames.watchdog_reports > reports_before ||
          (d.frames.last_status & up::kStatusWatchdogTripped) != 0) {
        trip_ns = usb_check_wall_ns() - last_out;
        if ((d.frames.last_status & up::kStatusEnabled) != 0) trip_ns = -1;  // still enabled?
        break;
      }
    }
    StepResult step = judge_watchdog(trip_ns, watchdog_ns, limit_ns, wait_ns, slow);
    if (!running) step = usb_check_failed("usb.watchdog", step.title, "the device latched " + device.fault_report());
    section.steps.push_back(std::move(step));
  }
  device.deactivate();
  return section;
}

}  // namespace trainer::hil
