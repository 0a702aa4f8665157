// The whole haptic cycle as the trainer runs it, and each of its stages, on a manual clock so
// only computation is timed (no sleeping). Each session is a scene's scripted trainee driving
// the simulated bench from its first cycle to the end of its script, state advancing as in a
// `trainer --time simulated` run; the benchmark runs whole sessions back to back (a fresh app,
// arena and device each), so its distribution is the run's, not one lucky phase.
//
//   BM_SceneCycle/<scene>         the full cycle (run_cycle: HAL read, with the simulated
//                                 plant's integration, to publish), one iteration per cycle
//   BM_SceneCycle/cbd_10khz       the same at 10 kHz: the scene's loop period replaced by
//                                 100 µs as `trainer --period-us 100` does (issue 19's goal)
//   BM_CbdStage/<stage>           the cbd cycle again, each iteration timed as one stage alone
//                                 (the StageRunner's own clock reads, as the report's split)
//   BM_SceneCycleRecorded/cbd     the full cycle with the session recording on (HAL taps, state
//                                 hash, derived block, ring push; the ring drained untimed)
//   BM_CbdStateHash               the state hash alone, after each cycle (docs/recording.md)
//   BM_CbdRecordPush              the cycle's record (912 bytes) copied into the ring alone
// Counters: p50/p99/p99.9/max of the per-cycle time (µs) and heap allocations per cycle
// (counted by the allocation hooks). Times are real-clock, warm caches: compute only.
//
// Needs the scenes' model images: `modelc build --scene config/scenes/cbd.toml` (and liver);
// tools/bootstrap.sh bench builds them and runs this. docs/performance.md has the figures.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "trainer/app/hal_taps.hpp"
#include "trainer/app/haptic_app.hpp"
#include "trainer/app/device_wiring.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/histogram.hpp"
#include "trainer/hal_sim/sim_device.hpp"

namespace {

using namespace trainer;

// One scene on the simulated bench in simulated time, armed, from cycle 0 to the script's end.
class SceneSession {
 public:
  // period_us > 0 replaces the scene's loop.period_us (trainer --period-us).
  static std::unique_ptr<SceneSession> open(const std::string& scene_file, std::string& error,
                                            bool record = false, std::int64_t period_us = 0) {
    auto scene = config::load_scene(std::string(TRAINER_SOURCE_DIR) + "/" + scene_file);
    if (!scene) {
      error = scene.error().message;
      return nullptr;
    }
    if (period_us > 0) {
      config::LoopOverrides overrides;
      overrides.period_us = period_us;
      if (auto replaced = config::apply_loop_overrides(scene->loop, overrides); !replaced) {
        error = replaced.error().message;
        return nullptr;
      }
    }
    std::unique_ptr<SceneSession> session(new SceneSession(std::move(*scene)));
    if (auto started = session->start(record); !started) {
      error = started.error().message;
      return nullptr;
    }
    return session;
  }
  ~SceneSession() {
    app_.reset();
    device_->deactivate();
  }

  bool finished() const noexcept { return cycle_ >= cycles_; }
  void step() noexcept {
    clock_.advance_ns(scene_.loop.period_ns);
    timing_.cycle_index = cycle_++;
    timing_.wake_ns = timing_.deadline_ns = clock_.now_ns();
    benchmark::DoNotOptimize(app_->run_cycle(timing_));
  }
  const app::HapticApp& app() const noexcept { return *app_; }
  // The cycle's record into the ring now (what the next cycle's start does).
  void push_record() noexcept {
    if (taps_) taps_->begin_cycle(timing_);
  }
  // The consumer's side of the recording (untimed): empties the ring.
  void drain() noexcept {
    if (!ring_) return;
    while (ring_->pop(record_)) benchmark::DoNotOptimize(record_.state_hash);
  }

 private:
  explicit SceneSession(config::SceneConfig scene) : scene_(std::move(scene)) {}
  core::Expected<void> start(bool record) {
    device_ = std::make_unique<hal::sim::SimDevice>(clock_, app::sim_params_from(scene_));
    if (auto ok = device_->configure(); !ok) return ok;
    if (auto ok = device_->activate(); !ok) return ok;
    auto arena = core::Arena::create(scene_.memory.arena_bytes);
    if (!arena) return std::move(arena).error();
    arena_.emplace(std::move(*arena));
    app::HalBinding binding{device_->encoders(), device_->actuators(), device_->digital_inputs(),
                            device_->digital_outputs()};
    if (record) {
      ring_ = std::make_unique<app::RecordRing>();
      auto taps = app::HalTaps::create(binding, ring_.get());
      if (!taps) return std::move(taps).error();
      taps_ = std::move(*taps);
      binding = taps_->binding();
    }
    auto app = app::HapticApp::create(scene_, binding, *arena_, log_, telemetry_, clock_);
    if (!app) return std::move(app).error();
    app_ = std::move(*app);
    if (taps_) app_->set_recorder(taps_.get());
    arena_->seal();
    app_->request_reset();
    // As the trainer runs a scripted scene: the script, then half a second more.
    const double period_s = static_cast<double>(scene_.loop.period_ns) * 1e-9;
    cycles_ =
        static_cast<std::uint64_t>(std::ceil((device_->script_duration_s() + 0.5) / period_s));
    timing_.dt_s = period_s;
    return {};
  }

  config::SceneConfig scene_;
  core::ManualClock clock_{0};
  std::unique_ptr<hal::sim::SimDevice> device_;
  std::optional<core::Arena> arena_;
  core::LogRing log_;
  core::TripleBuffer<app::TelemetrySnapshot> telemetry_;
  std::unique_ptr<app::RecordRing> ring_;
  std::unique_ptr<app::HalTaps> taps_;
  record::CycleRecord record_{};
  std::unique_ptr<app::HapticApp> app_;
  loop::CycleTiming timing_{};
  std::uint64_t cycle_ = 0;
  std::uint64_t cycles_ = 0;
};

// Runs whole sessions of `scene_file`, one cycle per iteration; the iteration's time is the
// full cycle, or only `stage` when given.
enum class Timed : std::uint8_t { cycle, state_hash, record_push };

void run_sessions(benchmark::State& state, const std::string& scene_file,
                  std::optional<app::CyclePhase> stage, bool record = false,
                  Timed timed = Timed::cycle, std::int64_t period_us = 0) {
  std::string error;
  auto session = SceneSession::open(scene_file, error, record, period_us);
  if (!session) {
    state.SkipWithError(
        (error + " (build the images: modelc build --scene " + scene_file + ")").c_str());
    return;
  }
  core::MonotonicClock clock;
  core::LatencyHistogram cycle_ns;
  std::uint64_t sessions = 1;
  std::uint64_t allocations = 0;
  for (auto _ : state) {
    if (session->finished()) {
      state.PauseTiming();
      session.reset();
      session = SceneSession::open(scene_file, error, record, period_us);
      ++sessions;
      state.ResumeTiming();
      if (!session) {
        state.SkipWithError(error.c_str());
        return;
      }
    }
    core::alloc::begin_counting_this_thread();
    const std::uint64_t before = core::alloc::counted_allocations();
    const std::int64_t start_ns = clock.now_ns();
    session->step();
    std::int64_t cycle_time_ns = clock.now_ns() - start_ns;
    if (timed == Timed::state_hash) {
      const std::int64_t hash_start_ns = clock.now_ns();
      benchmark::DoNotOptimize(session->app().state_hash());
      cycle_time_ns = clock.now_ns() - hash_start_ns;
    } else if (timed == Timed::record_push) {
      const std::int64_t push_start_ns = clock.now_ns();
      session->push_record();
      cycle_time_ns = clock.now_ns() - push_start_ns;
    }
    allocations += core::alloc::counted_allocations() - before;
    core::alloc::end_counting_this_thread();
    session->drain();
    const std::int64_t ns = stage ? session->app().last_stage_ns(*stage) : cycle_time_ns;
    cycle_ns.record(ns);
    state.SetIterationTime(static_cast<double>(ns) * 1e-9);
  }
  const auto us = [&](double q) { return static_cast<double>(cycle_ns.percentile_ns(q)) * 1e-3; };
  state.counters["p50_us"] = us(0.5);
  state.counters["p99_us"] = us(0.99);
  state.counters["p99.9_us"] = us(0.999);
  state.counters["max_us"] = static_cast<double>(cycle_ns.max_ns()) * 1e-3;
  state.counters["sessions"] = static_cast<double>(sessions);
  state.counters["heap_allocations_per_cycle"] =
      static_cast<double>(allocations) / static_cast<double>(state.iterations());
}

// Three whole sessions of each scene's script (cbd 11 s, liver 16 s, wall 10 s at 1 kHz).
constexpr std::int64_t kCbdIterations = 3 * 11'000;

void BM_SceneCycle(benchmark::State& state, const std::string& scene_file,
                   std::int64_t period_us = 0) {
  run_sessions(state, scene_file, std::nullopt, false, Timed::cycle, period_us);
}
BENCHMARK_CAPTURE(BM_SceneCycle, cbd, std::string("config/scenes/cbd.toml"))
    ->UseManualTime()
    ->Iterations(kCbdIterations)
    ->Unit(benchmark::kMicrosecond);
// 10 kHz: the same scripted session is ten times as many cycles (3 × 110,000).
BENCHMARK_CAPTURE(BM_SceneCycle, cbd_10khz, std::string("config/scenes/cbd.toml"),
                  std::int64_t{100})
    ->UseManualTime()
    ->Iterations(10 * kCbdIterations)
    ->Unit(benchmark::kMicrosecond);
void BM_SceneCycleRecorded(benchmark::State& state, const std::string& scene_file) {
  run_sessions(state, scene_file, std::nullopt, true);
}
BENCHMARK_CAPTURE(BM_SceneCycleRecorded, cbd, std::string("config/scenes/cbd.toml"))
    ->UseManualTime()
    ->Iterations(kCbdIterations)
    ->Unit(benchmark::kMicrosecond);
void BM_CbdStateHash(benchmark::State& state) {
  run_sessions(state, "config/scenes/cbd.toml", std::nullopt, false, Timed::state_hash);
}
void BM_CbdRecordPush(benchmark::State& state) {
  run_sessions(state, "config/scenes/cbd.toml", std::nullopt, true, Timed::record_push);
}
BENCHMARK(BM_CbdRecordPush)
    ->UseManualTime()
    ->Iterations(kCbdIterations)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_CbdStateHash)
    ->UseManualTime()
    ->Iterations(kCbdIterations)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_SceneCycle, liver, std::string("config/scenes/liver.toml"))
    ->UseManualTime()
    ->Iterations(3 * 16'000)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_SceneCycle, wall, std::string("config/scenes/wall.toml"))
    ->UseManualTime()
    ->Iterations(3 * 10'000)
    ->Unit(benchmark::kMicrosecond);

// BM_CbdStage/<stage> for every stage the cbd scene runs (it has no tensor model).
const bool kStagesRegistered = [] {
  for (std::size_t k = 0; k < app::kCyclePhaseCount; ++k) {
    const auto phase = static_cast<app::CyclePhase>(k);
    if (phase == app::CyclePhase::tensor_models) continue;
    benchmark::RegisterBenchmark(
        (std::string("BM_CbdStage/") + app::kCyclePhaseNames[k]).c_str(),
        [phase](benchmark::State& state) { run_sessions(state, "config/scenes/cbd.toml", phase); })
        ->UseManualTime()
        ->Iterations(kCbdIterations)
        ->Unit(benchmark::kMicrosecond);
  }
  return true;
}();

}  // namespace

BENCHMARK_MAIN();
