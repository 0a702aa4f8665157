// The CAN backend's cost per cycle (docs/canopen.md "Cost per cycle"): the trainer's CiA 402
// master (CanopenDevice) running the ten drives of config/devices/canopen_vcan.toml with the cbd
// scene's parameters, over a socketpair, against simdrive's drives in lockstep (the drives run
// between cycles, outside the timed region). Timed: what the trainer's hal_read and hal_write
// stages call — read_encoders (one or more recvmmsg, decode of 20 TPDOs and the heartbeats),
// read_actuator_status, read_digital_inputs, write_actuators (controlwords, per-mille torques,
// encode of 11 RPDOs + SYNC + heartbeat, one sendmmsg), write_digital_outputs.
// Counters: read_ns / write_ns (the two halves), frames and system calls per cycle.
// BM_CanDecodeTpdo: classify + decode of one TPDO1 (the pure library, no I/O).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <thread>

#include "simdrive_setup.hpp"
#include "trainer/app/device_wiring.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/clock.hpp"
#include "trainer/hal_canopen/cia402.hpp"
#include "trainer/hal_canopen/frame.hpp"
#include "trainer/hal_simdrive/sim_drive_bus.hpp"
#include "trainer/hal_socketcan/canopen_device.hpp"

namespace {

using namespace trainer;

std::int64_t now_ns() {
  core::MonotonicClock clock;
  return clock.now_ns();
}

void BM_CanMasterCycle(benchmark::State& state) {
  config::LoadOptions options;
  options.device_file = std::string(TRAINER_SOURCE_DIR) + "/config/devices/canopen_vcan.toml";
  auto scene = config::load_scene(std::string(TRAINER_SOURCE_DIR) + "/config/scenes/cbd.toml",
                                  options);
  if (!scene) {
    state.SkipWithError(scene.error().message.c_str());
    return;
  }
  auto pair = hal::socketcan::make_transport_pair("master", "simdrive");
  auto bus_params = tools::simdrive::bus_params_from(scene->device, "builtin:hold",
                                                     scene->loop.period_ns, {});
  if (!pair || !bus_params) {
    state.SkipWithError("setup failed");
    return;
  }
  auto bus = hal::simdrive::SimDriveBus::create(std::move(*bus_params), std::move(pair->b));
  if (!bus) {
    state.SkipWithError(bus.error().message.c_str());
    return;
  }
  core::MonotonicClock clock;
  hal::socketcan::CanopenDevice master(clock, app::canopen_params_from(*scene),
                                       std::move(pair->a));
  (*bus)->power_on(now_ns());
  std::atomic<bool> stop{false};
  std::thread drives([&] {  // serves configure()/activate(), which block on SDO answers
    while (!stop.load()) {
      const std::int64_t now = now_ns();
      const std::int64_t deadline = (*bus)->poll(now);
      (void)(*bus)->transport().wait_readable(std::clamp<std::int64_t>(deadline - now, 0, 1'000'000));
    }
  });
  auto configured = master.configure();
  auto activated = configured ? master.activate() : core::Expected<void>(configured.error());
  stop.store(true);
  drives.join();
  if (!activated) {
    state.SkipWithError(activated.error().message.c_str());
    return;
  }
  const std::size_t channels = master.encoder_count();
  std::vector<hal::EncoderSample> samples(channels);
  std::vector<hal::ActuatorStatus> status(channels);
  std::vector<hal::ActuatorCommand> commands(channels);
  for (std::size_t i = 0; i < channels; ++i) {
    commands[i] = {static_cast<float>(0.2 * master.params().drives[i].scale.max_effort()), true};
  }
  std::uint32_t inputs = 0;
  double read_s = 0.0;
  double write_s = 0.0;
  std::int64_t cycles = 0;
  bool faulted = false;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    faulted |= master.read_encoders(samples) == hal::ReturnCode::deactivate;
    (void)master.read_actuator_status(status);
    (void)master.read_digital_inputs(inputs);
    const auto t1 = std::chrono::steady_clock::now();
    (void)master.write_actuators(commands);
    (void)master.write_digital_outputs(0x1);
    const auto t2 = std::chrono::steady_clock::now();
    (*bus)->poll(now_ns());  // the drives' turn: untimed
    const double read = std::chrono::duration<double>(t1 - t0).count();
    const double write = std::chrono::duration<double>(t2 - t1).count();
    read_s += read;
    write_s += write;
    ++cycles;
    state.SetIterationTime(read + write);
  }
  if (faulted) state.SkipWithError(master.fault_report().c_str());
  const auto& d = master.diagnostics();
  const double n = static_cast<double>(std::max<std::int64_t>(cycles, 1));
  state.counters["read_ns"] = read_s / n * 1e9;
  state.counters["write_ns"] = write_s / n * 1e9;
  state.counters["frames_in"] = static_cast<double>(d.transport.rx_frames) / n;
  state.counters["frames_out"] = static_cast<double>(d.transport.tx_frames) / n;
  state.counters["syscalls"] =
      static_cast<double>(d.transport.rx_calls + d.transport.tx_calls) / n;
  state.counters["drives"] = static_cast<double>(channels);
  master.deactivate();
}
BENCHMARK(BM_CanMasterCycle)->UseManualTime()->Unit(benchmark::kMicrosecond)->MinTime(2.0);

void BM_CanDecodeTpdo(benchmark::State& state) {
  can_frame frame{};
  frame.can_id = 0x181;
  frame.len = 8;
  const std::uint8_t data[8] = {0x27, 0x02, 0xE8, 0x03, 0x00, 0x00, 0x14, 0x00};
  std::copy(std::begin(data), std::end(data), frame.data);
  for (auto _ : state) {
    benchmark::DoNotOptimize(frame);
    const hal::canopen::FrameClass c = hal::canopen::classify(frame);
    const auto statusword = static_cast<std::uint16_t>(frame.data[0] | (frame.data[1] << 8));
    benchmark::DoNotOptimize(c);
    benchmark::DoNotOptimize(hal::canopen::decode_statusword(statusword));
  }
}
BENCHMARK(BM_CanDecodeTpdo);

}  // namespace

BENCHMARK_MAIN();
