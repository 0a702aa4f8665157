#include "trainer/app/trainer_run.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>
#include <span>

#include "trainer/app/device_wiring.hpp"
#include "trainer/app/rt_self_check.hpp"
#include "trainer/app/service_supervision.hpp"
#include "trainer/app/session_recording.hpp"
#include "trainer/app/stream_metrics.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/core/clock.hpp"
#include "trainer/core/log_ring.hpp"
#include "trainer/core/triple_buffer.hpp"
#include "trainer/hal/composite_device.hpp"
#include "trainer/hal_sim/sim_device.hpp"
#include "trainer/loop/rt_thread.hpp"
#include "trainer/loop/stop_signals.hpp"

namespace trainer::app {

namespace {

constexpr std::int64_t kSupervisorPeriodNs = 33'000'000;     // ~30 Hz telemetry / log drain
constexpr std::int64_t kRecordingDrainPeriodNs = 2'000'000;  // simulated time, recording
constexpr double kScriptTailS = 0.5;  // keep running briefly after the script's last keyframe

// The motion backend: the device itself, or the motion half of a composite (a device file
// with digital_io = "gpio"), whose CAN or USB diagnostics and shutdown checks the report needs.
hal::Device& motion_of(hal::Device& device) {
  if (auto* composite = dynamic_cast<hal::CompositeDevice*>(&device)) return composite->motion();
  return device;
}

void drain_log(core::LogRing& ring, const RunOptions& options) {
  core::LogRecord record;
  while (ring.pop(record)) {
    char stamp[48];
    std::snprintf(stamp, sizeof stamp, "[%.6f s] ", static_cast<double>(record.time_ns) * 1e-9);
    std::string line(stamp);
    line.append(core::to_string(record.level)).append(": ").append(core::format_log_record(record));
    if (options.on_log) {
      options.on_log(line);
    } else {
      std::cerr << line << '\n';
    }
  }
}

// The run length before the max_cycles cap; 0 = until SIGINT/SIGTERM.
core::Expected<std::uint64_t> uncapped_cycles(const RunOptions& options,
                                              const config::SceneConfig& scene,
                                              double script_duration_s) {
  const double period_s = static_cast<double>(scene.loop.period_ns) * 1e-9;
  if (options.cycles) return *options.cycles;
  if (options.seconds) {
    if (!(*options.seconds > 0.0)) return core::make_error("--seconds must be positive");
    return static_cast<std::uint64_t>(std::ceil(*options.seconds / period_s));
  }
  if (scene.trainee.end_run_with_script && script_duration_s > 0.0) {
    return static_cast<std::uint64_t>(std::ceil((script_duration_s + kScriptTailS) / period_s));
  }
  if (options.time_source == TimeSource::simulated && !options.max_cycles) {
    return core::make_error(
        "simulated time needs a run length: give --cycles or --seconds (or a scene whose "
        "trainee script ends, with trainee.end_run_with_script = true)");
  }
  return std::uint64_t{0};
}

core::Expected<std::uint64_t> cycles_to_run(const RunOptions& options,
                                            const config::SceneConfig& scene,
                                            double script_duration_s) {
  auto cycles = uncapped_cycles(options, scene, script_duration_s);
  if (!cycles || !options.max_cycles) return cycles;
  if (*options.max_cycles == 0) return core::make_error("max_cycles must be positive");
  return *cycles == 0 ? *options.max_cycles : std::min(*cycles, *options.max_cycles);
}

}  // namespace

namespace {

// Everything one run owns, created on the setup path before the RT thread starts. Members are
// destroyed in reverse order: the app before the arena it lives in, the device last.
struct RunSetup {
  config::SceneConfig scene;
  std::unique_ptr<core::Clock> clock;
  std::unique_ptr<hal::Device> device;
  hal::sim::SimDevice* sim = nullptr;  // the device when it is the simulated bench
  std::optional<core::Arena> arena;
  std::unique_ptr<core::LogRing> log = std::make_unique<core::LogRing>();
  std::unique_ptr<core::TripleBuffer<TelemetrySnapshot>> telemetry =
      std::make_unique<core::TripleBuffer<TelemetrySnapshot>>();
  std::unique_ptr<HalTaps> taps;  // --record: before the app that uses them
  std::unique_ptr<SessionRecorder> recorder;
  std::unique_ptr<HapticApp> app;
  std::unique_ptr<TelemetrySender> telemetry_sender;  // [telemetry] enabled, or recording
  std::uint64_t cycles = 0;
  std::string backend;  // "sim" or the device file's hardware backend
  std::vector<appliance::RtCheckResult> rt_check;
};

// The scene with this run's loop overrides, the HAL backend configured and active, the arena
// carved and sealed, the app created; the device is deactivated again on any error.
core::Expected<void> prepare_run(const RunOptions& options, RunSetup& setup) {
  if (options.slow_motion < 1 || options.slow_motion > 1000) {
    return core::make_error("--slow-motion " + std::to_string(options.slow_motion) +
                            ": expected 1 (real time) to 1000");
  }
  if (options.slow_motion > 1 && options.time_source != TimeSource::real) {
    return core::make_error("--slow-motion slows real time: it needs --time real");
  }
  if (options.hal != "device" && options.hal != "sim") {
    return core::make_error("--hal " + options.hal +
                            ": unknown choice; expected 'device' (the device file's backend) or "
                            "'sim' (the simulated bench with the device file's mechanism)");
  }
  config::LoadOptions load_options;
  load_options.device_file = options.device_file;
  auto scene = config::load_scene(options.scene_file, load_options);
  if (!scene) return std::move(scene).error();
  if (auto overridden = config::apply_loop_overrides(scene->loop, options.loop_overrides);
      !overridden) {
    return std::move(overridden).error();
  }
  setup.scene = std::move(*scene);
  const config::SceneConfig& cfg = setup.scene;
  // The machine is checked before anything is powered: a fatal failure stops here.
  if (options.apply_rt_settings && options.time_source == TimeSource::real) {
    setup.rt_check = run_scene_rt_check(cfg, options.rt_check_root);
    if (auto refused = refuse_on_fatal(cfg, setup.rt_check); !refused) {
      return std::move(refused).error();
    }
  }
  const bool simulated_bench = options.hal == "sim" || cfg.device.backend == "sim";
  if (options.time_source == TimeSource::simulated) {
    if (!simulated_bench) {
      return core::make_error("--time simulated needs the simulated bench, but device file " +
                              cfg.device.source_path.string() + " names backend '" +
                              cfg.device.backend + "': run in real time or add --hal sim");
    }
    setup.clock = std::make_unique<core::ManualClock>(0);
  } else if (options.slow_motion > 1) {
    setup.clock = std::make_unique<core::SlowMotionClock>(options.slow_motion);
  } else {
    setup.clock = std::make_unique<core::MonotonicClock>();
  }
  setup.backend = simulated_bench ? "sim" : cfg.device.backend;
  if (cfg.device.digital_io == config::DigitalIo::gpio) setup.backend += "+gpio";
  if (simulated_bench) {
    auto sim = std::make_unique<hal::sim::SimDevice>(*setup.clock, sim_params_from(cfg));
    setup.sim = sim.get();
    // The simulated motion with the device file's real GPIO lines when it names them.
    setup.device = with_digital_io(cfg.device, std::move(sim));
  } else {
    auto device = make_hardware_device(cfg, *setup.clock);
    if (!device) return std::move(device).error();
    setup.device = std::move(*device);
  }
  hal::Device& device = *setup.device;
  if (auto configured = device.configure(); !configured) {
    return core::make_error(cfg.device.source_path.string() + ": " + configured.error().message);
  }
  // Deactivation is safe in any state: it also leaves a configured CAN bus in a safe state.
  const auto fail = [&](core::Error error) -> core::Expected<void> {
    device.deactivate();
    return error;
  };
  auto arena = core::Arena::create(cfg.memory.arena_bytes);
  if (!arena) return fail(std::move(arena).error());
  setup.arena.emplace(std::move(*arena));
  HalBinding binding{device.encoders(), device.actuators(), device.digital_inputs(),
                     device.digital_outputs()};
  // Every session goes through the HAL taps: their per-cycle records feed the trainee metrics
  // and, with --record, the recording.
  auto taps = HalTaps::create(binding, nullptr);
  if (!taps) return fail(std::move(taps).error());
  setup.taps = std::move(*taps);
  binding = setup.taps->binding();
  auto app =
      HapticApp::create(cfg, binding, *setup.arena, *setup.log, *setup.telemetry, *setup.clock);
  if (!app) return fail(std::move(app).error());
  setup.app = std::move(*app);
  if (options.record_file) {
    auto recorder = SessionRecorder::open(
        *options.record_file,
        session_info(cfg, setup.app->models(),
                     options.time_source == TimeSource::real ? "real" : "simulated",
                     device.digital_inputs() != nullptr, device.digital_outputs() != nullptr));
    if (!recorder) return fail(std::move(recorder).error());
    setup.recorder = std::move(*recorder);
  } else {
    setup.recorder = SessionRecorder::metrics_only();
  }
  auto session_metrics = metrics::SessionMetrics::create(metrics_setup(cfg));
  if (!session_metrics) {
    return fail(core::make_error(cfg.source_path.string() + ": [metrics] " +
                                 session_metrics.error().message));
  }
  setup.recorder->set_metrics(std::move(*session_metrics));
  setup.taps->set_ring(&setup.recorder->ring());
  setup.taps->set_wait_when_full(options.time_source == TimeSource::simulated);
  setup.app->set_recorder(setup.taps.get());
  const config::TelemetryConfig& stream = options.telemetry ? *options.telemetry : cfg.device.telemetry;
  if (stream.enabled) {
    auto sender = TelemetrySender::create(
        stream, options.telemetry ? std::string("--telemetry") : cfg.device.source_path.string());
    if (!sender) return fail(std::move(sender).error());
    setup.telemetry_sender = std::move(*sender);
  }
  // A recording keeps the stream's frames (channel 2) at its rate, sent or not.
  if (setup.recorder->recording()) {
    if (!setup.telemetry_sender) {
      auto encoder = TelemetrySender::create_unsent(
          stream, options.telemetry ? std::string("--telemetry") : cfg.device.source_path.string());
      if (!encoder) return fail(std::move(encoder).error());
      setup.telemetry_sender = std::move(*encoder);
    }
    setup.telemetry_sender->set_frame_sink(
        [recorder = setup.recorder.get()](std::span<const std::byte> bytes,
                                          const telemetry::Frame& frame) {
          recorder->add_telemetry(bytes, frame.cycle_time_ns, frame.sequence);
        });
  }
  // The trainee script plays on the simulated bench only; on hardware a person moves the
  // handles and the run lasts --cycles/--seconds or until a stop signal.
  const double script_duration_s = setup.sim != nullptr ? setup.sim->script_duration_s() : 0.0;
  auto cycles = cycles_to_run(options, cfg, script_duration_s);
  if (!cycles) return fail(std::move(cycles).error());
  setup.cycles = *cycles;
  // Power on last, just before the RT thread starts: a CAN drive's deadline monitoring must
  // not run while models load.
  if (auto activated = device.activate(); !activated) {
    return fail(
        core::make_error(cfg.device.source_path.string() + ": " + activated.error().message));
  }
  setup.arena->seal();  // from here on nothing may be carved from the arena
  return {};
}

// The safety record as the run left it (before the routine shutdown latch).
void record_safety(const safety::SafetySupervisor& safety, RunResult& result) {
  result.latched_faults = safety.latched_faults();
  result.first_fault = safety::to_string(safety.first_fault());
  result.first_fault_cycle = safety.first_fault_cycle();
  for (std::size_t k = 0; k < safety::kFaultKinds; ++k) {
    if (safety.fault_counts()[k] == 0) continue;
    result.fault_counts.emplace_back(safety::to_string(static_cast<safety::Fault>(1U << k)),
                                     safety.fault_counts()[k]);
  }
}

// The RT thread: RT settings, armed (heap use counted), the periodic loop, shutdown. The
// calling (supervisor) thread drains the log and telemetry until it ends or a signal stops it.
core::Expected<void> run_loop(const RunOptions& options, RunSetup& setup,
                              loop::StopSignals& signals, RunResult& result) {
  const config::SceneConfig& scene = setup.scene;
  HapticApp& haptic = *setup.app;
  loop::PeriodicLoop periodic(
      *setup.clock,
      loop::LoopSettings{scene.loop.period_ns, scene.loop.overrun_streak_limit, setup.cycles});
  // Simulated time: the step is timed on the real clock (the manual clock does not move
  // during a cycle), as the stage split is.
  core::MonotonicClock step_clock;
  if (options.time_source == TimeSource::simulated) periodic.set_step_clock(&step_clock);
  if (options.compute_trace != nullptr) {
    options.compute_trace->prepare(static_cast<std::size_t>(setup.cycles));
    periodic.set_step_trace(options.compute_trace->step_ns());
    haptic.set_compute_trace(options.compute_trace);
  }
  if (options.arm) haptic.request_reset();
  loop::RtRequest request;
  request.priority = scene.loop.priority;
  request.cpu = scene.loop.cpu;
  request.lock_memory = scene.loop.lock_memory;
  request.stack_prefault_bytes = scene.loop.stack_prefault_bytes;
  const bool apply_rt = options.apply_rt_settings && options.time_source == TimeSource::real;
  // Held until this function returns, i.e. for the whole loop.
  loop::CpuLatencyRequest cpu_latency;
  if (apply_rt) cpu_latency = loop::CpuLatencyRequest::hold(scene.loop.cpu_dma_latency_us);

  std::atomic<bool> stop{false};
  std::atomic<bool> finished{false};
  auto thread = loop::RtThread::start([&] {
    if (apply_rt) {
      result.rt = loop::apply_rt_settings(request);
    } else {
      result.rt.policy = "SCHED_OTHER";
      result.rt.preempt_rt = loop::kernel_is_preempt_rt();
      result.rt.warnings.push_back(options.time_source == TimeSource::simulated
                                       ? "RT settings not applied: simulated time"
                                       : "RT settings not applied: disabled by the caller");
    }
    loop::prefault_stack(request.stack_prefault_bytes);
    // Armed: from here to the end of the loop this thread may not touch the heap.
    core::alloc::begin_counting_this_thread();
    const std::uint64_t before = core::alloc::counted_allocations();
    periodic.run(haptic, stop);
    if (setup.taps) setup.taps->finish();  // the last cycle's record, before shutdown's writes
    result.heap_allocations_after_arming = core::alloc::counted_allocations() - before;
    core::alloc::end_counting_this_thread();
    result.final_state_hash = haptic.state_hash();
    record_safety(haptic.safety(), result);
    haptic.shutdown();
    finished.store(true, std::memory_order_release);
  });
  if (!thread) return std::move(thread).error();
  ServiceSupervision service(options.arm, scene.name, scene.loop.period_ns);
  // A recording in simulated time: the cycle thread waits for the writer when the ring is
  // full (HalTaps::set_wait_when_full), so drain often.
  const std::int64_t supervisor_period_ns =
      setup.recorder && options.time_source == TimeSource::simulated ? kRecordingDrainPeriodNs
                                                                     : kSupervisorPeriodNs;
  TelemetrySender* sender = setup.telemetry_sender.get();
  // Every frame carries the session's trainee metrics so far (the viewer's session panel).
  telemetry::SessionMetrics frame_metrics{};
  if (sender != nullptr && setup.recorder->session_metrics()) sender->set_metrics(&frame_metrics);
  bool have_snapshot = false;
  const auto monotonic_now_ns = [] {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
  };
  // The stream's schedule: CLOCK_MONOTONIC in real time; in simulated time the loop's clock
  // (the newest snapshot's cycle time), so a recording's frames come at the stream's rate per
  // session second (at most one per supervisor wake, every 2 ms of wall time).
  const bool simulated = options.time_source == TimeSource::simulated;
  const auto stream_now_ns = [&] {
    if (!simulated) return monotonic_now_ns();
    return have_snapshot ? setup.telemetry->latest().time_ns : std::int64_t{0};
  };
  bool fresh_snapshot = false;
  std::int64_t supervised_ns = 0;
  while (!finished.load(std::memory_order_acquire)) {
    // Wakes at the recording's drain period or, with a telemetry stream, when its next frame
    // is due (30–120 Hz), whichever comes first; else at ~30 Hz.
    const std::int64_t wait_ns =
        sender != nullptr && !simulated
            ? std::clamp<std::int64_t>(sender->ns_until_due(stream_now_ns()), 0,
                                       supervisor_period_ns)
            : supervisor_period_ns;
    if (signals.wait_for(wait_ns) != 0) {
      result.stopped_by_signal = true;
      stop.store(true, std::memory_order_release);
    }
    setup.recorder->drain();
    if (simulated && setup.telemetry->update()) {  // the stream's clock in simulated time
      have_snapshot = true;
      fresh_snapshot = true;
    }
    // Log, telemetry and service supervision at ~30 Hz whatever the recording's drain rate.
    const bool frame_due = sender != nullptr && sender->ns_until_due(stream_now_ns()) <= 0;
    if (supervisor_period_ns < kSupervisorPeriodNs && !frame_due &&
        !finished.load(std::memory_order_acquire) &&
        monotonic_now_ns() - supervised_ns < kSupervisorPeriodNs) {
      continue;
    }
    supervised_ns = monotonic_now_ns();
    drain_log(*setup.log, options);
    if (setup.telemetry->update()) fresh_snapshot = true;
    if (fresh_snapshot) {
      fresh_snapshot = false;
      have_snapshot = true;
      service.observe(setup.telemetry->latest());
      if (options.on_telemetry) options.on_telemetry(setup.telemetry->latest());
    }
    if (sender != nullptr && have_snapshot && frame_due) {
      if (const auto& session = setup.recorder->session_metrics())
        frame_metrics = stream_metrics(session->result());
      sender->send_if_due(setup.telemetry->latest(), stream_now_ns());
    }
    service.tick(finished.load(std::memory_order_acquire), monotonic_now_ns());
  }
  service.stopping(result.stopped_by_signal);
  thread->join();
  if (sender != nullptr) {
    if (setup.telemetry->update()) have_snapshot = true;
    if (have_snapshot) {
      setup.recorder->drain();  // every cycle's record into the final frame's metrics
      if (const auto& session = setup.recorder->session_metrics())
        frame_metrics = stream_metrics(session->result());
      sender->send_final(setup.telemetry->latest(), stream_now_ns());
    }
    if (sender->sends()) result.telemetry_stream = sender->stats();
  }
  result.rt.cpu_dma_latency_us = cpu_latency.latency_us();
  if (!cpu_latency.warning().empty()) result.rt.warnings.push_back(cpu_latency.warning());
  result.loop = periodic.stats();
  return {};
}

// What the run leaves for the report, after the loop and the device stopped.
void collect_result(const RunSetup& setup, bool status_known, RunResult& result) {
  // Shutdown check through the HAL itself: every channel reports zero effort, disabled (drives
  // on a bus were asked again after the deactivation, see run_trainer).
  std::vector<hal::ActuatorStatus> status(setup.device->actuators()->actuator_count());
  (void)setup.device->actuators()->read_actuator_status(status);
  result.outputs_zeroed_at_exit = status_known;
  for (const hal::ActuatorStatus& s : status) {
    if (s.applied_effort != 0.0F || s.enabled) result.outputs_zeroed_at_exit = false;
  }
  const HapticApp& haptic = *setup.app;
  result.app = haptic.stats();
  result.models = haptic.models();
  for (LoadedModelInfo& model : result.models) {
    if (model.kind == config::ModelKind::catheter)
      model.final_positions_m = haptic.catheter_positions_m(model.name);
  }
  const safety::SafetySupervisor& safety = haptic.safety();
  result.force_clamped_cycles = safety.clamped_cycles();
  result.force_slew_limited_cycles = safety.slew_limited_cycles();
  result.arm_count = safety.arm_count();
  result.allocation_hooks_installed = core::alloc::hooks_installed();
  result.malloc_family_counted = core::alloc::malloc_family_counted();
  result.arena_bytes_used = setup.arena->used_bytes();
  result.arena_bytes_capacity = setup.arena->capacity_bytes();
  result.log_records_dropped = setup.log->dropped();
  if (const auto* can =
          dynamic_cast<const hal::socketcan::CanopenDevice*>(&motion_of(*setup.device))) {
    result.can = can->diagnostics();
    result.can_faults = can->fault_report();
  }
  if (const auto* usb = dynamic_cast<const hal::libusb::UsbDevice*>(&motion_of(*setup.device))) {
    result.usb = usb->diagnostics();
    result.usb_faults = usb->fault_report();
  }
}

}  // namespace

core::Expected<RunResult> run_trainer(const RunOptions& options) {
  // Block SIGINT/SIGTERM before any thread exists so every thread inherits the mask and only
  // this supervisor thread receives them (no async handler runs on the RT thread).
  loop::StopSignals signals;
  RunSetup setup;
  if (auto prepared = prepare_run(options, setup); !prepared) return std::move(prepared).error();

  RunResult result;
  result.scene_file = options.scene_file;
  result.scene_name = setup.scene.name;
  result.hal = setup.backend;
  result.device_file = setup.scene.device.source_path;
  result.time_source = options.time_source == TimeSource::real ? "real" : "simulated";
  result.slow_motion = options.slow_motion;
  result.period_ns = setup.scene.loop.period_ns;
  result.requested_cycles = setup.cycles;
  result.rt_check = setup.rt_check;
  for (const auto& instrument : setup.scene.instruments)
    result.instrument_names.push_back(instrument.name);

  const auto wall_start = std::chrono::steady_clock::now();
  auto ran = run_loop(options, setup, signals, result);
  drain_log(*setup.log, options);
  setup.device->deactivate();
  if (setup.recorder) {
    setup.recorder->close();
    if (setup.recorder->recording()) {
      result.recording_file = setup.recorder->path().string();
      result.recorded_cycles = setup.recorder->records();
      result.recording_bytes = setup.recorder->bytes();
      result.recording_error = setup.recorder->error();
    }
    result.recording_dropped_cycles = setup.recorder->dropped();
    if (const auto& session = setup.recorder->session_metrics()) {
      result.metrics = session->result();
      result.metrics_thresholds = session->setup().thresholds;
    }
    result.metrics_refused_samples = setup.recorder->refused_samples();
  }
  if (!ran) return std::move(ran).error();
  // A bus's drives report their state only in PDOs, which stop with the deactivation: ask them.
  bool status_known = true;
  if (auto* can = dynamic_cast<hal::socketcan::CanopenDevice*>(&motion_of(*setup.device))) {
    if (auto refreshed = can->refresh_status(); !refreshed) {
      status_known = false;
      result.rt.warnings.push_back("shutdown check failed: " + refreshed.error().message);
    }
  }
  // A USB device confirms the zero + disable report by acknowledging it (unless it is gone).
  if (const auto* usb = dynamic_cast<const hal::libusb::UsbDevice*>(&motion_of(*setup.device))) {
    const hal::libusb::UsbDiagnostics usb_state = usb->diagnostics();
    if (!usb_state.shutdown_acknowledged && !usb_state.lost_reported) {
      status_known = false;
      result.rt.warnings.push_back(
          "shutdown check failed: the USB device did not acknowledge zero current + disable "
          "within usb.stop_timeout_ms");
    }
  }
  result.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  collect_result(setup, status_known, result);
  return result;
}

}  // namespace trainer::app
