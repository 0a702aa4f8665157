// Cost of one haptic cycle of the wall scene, measured on a manual clock so only computation is
// timed (no sleeping): HAL read/write through the simulated backend, kinematics, contact,
// safety, publish. The clock is rewound every 400 ms of simulated time to stay in the pressed
// phase; the simulated plant integrates only when time passes its last point, so nearly every
// timed cycle is the controller's own work (a hardware backend does no physics either).
#include <benchmark/benchmark.h>

#include <memory>

#include "trainer/app/haptic_app.hpp"
#include "trainer/app/sim_wiring.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/hal_sim/sim_device.hpp"

namespace {

using namespace trainer;

void BM_WallSceneCycle(benchmark::State& state) {
  auto scene = config::load_scene(std::string(TRAINER_SOURCE_DIR) + "/config/scenes/wall.toml");
  if (!scene) {
    state.SkipWithError(scene.error().message.c_str());
    return;
  }
  core::ManualClock clock(0);
  hal::sim::SimDevice device(clock, app::sim_params_from(*scene));
  if (!device.configure() || !device.activate()) {
    state.SkipWithError("sim device did not start");
    return;
  }
  auto arena = core::Arena::create(scene->memory.arena_bytes);
  core::LogRing log;
  core::TripleBuffer<app::TelemetrySnapshot> telemetry;
  auto haptic = app::HapticApp::create(
      *scene, {device.encoders(), device.actuators(), device.digital_inputs(), device.digital_outputs()},
      *arena, log, telemetry, clock);
  if (!haptic) {
    state.SkipWithError(haptic.error().message.c_str());
    return;
  }
  (*haptic)->request_reset();
  const std::int64_t period = scene->loop.period_ns;
  loop::CycleTiming timing{};
  timing.dt_s = static_cast<double>(period) * 1e-9;
  // Start in contact with the wall (the script presses it at 6-7 s) so the contact path runs.
  for (std::uint64_t i = 0; i < 6500; ++i) {
    clock.advance_ns(period);
    timing.cycle_index = i;
    timing.wake_ns = timing.deadline_ns = clock.now_ns();
    (void)(*haptic)->run_cycle(timing);
  }
  std::uint64_t cycle = 6500;
  for (auto _ : state) {
    // Rewind into the pressed phase so every measured cycle is in contact.
    if (clock.now_ns() > 6'900'000'000) clock.advance_ns(-400'000'000);
    clock.advance_ns(period);
    timing.cycle_index = cycle++;
    timing.wake_ns = timing.deadline_ns = clock.now_ns();
    benchmark::DoNotOptimize((*haptic)->run_cycle(timing));
  }
  state.counters["armed"] = (*haptic)->safety().armed() ? 1 : 0;
}
BENCHMARK(BM_WallSceneCycle);

}  // namespace

BENCHMARK_MAIN();
