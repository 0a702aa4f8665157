// Whole runs of the trainer on the simulated bench: the no-heap proof over 100,000 cycles of
// the wall scene, the late-reply overrun policy end to end, and setup errors.
#include "trainer/app/trainer_run.hpp"

#include <gtest/gtest.h>

#include "trainer/app/report.hpp"
#include "trainer/core/alloc_counter.hpp"

namespace trainer::app {
namespace {

std::filesystem::path wall_scene() {
  return std::filesystem::path(TRAINER_SOURCE_DIR) / "config/scenes/wall.toml";
}

RunOptions simulated(std::uint64_t cycles) {
  RunOptions options;
  options.scene_file = wall_scene();
  options.time_source = TimeSource::simulated;
  options.cycles = cycles;
  options.on_log = [](const std::string&) {};
  return options;
}

TEST(TrainerRun, WallSceneMakesNoHeapAllocationsOver100000Cycles) {
  ASSERT_TRUE(core::alloc::hooks_installed());
  auto result = run_trainer(simulated(100'000));
  ASSERT_TRUE(result) << result.error().message;
  EXPECT_EQ(result->loop.cycles, 100'000U);
  EXPECT_EQ(result->heap_allocations_after_arming, 0U);
  // The run really exercised the chain: armed throughout, contact with the wall, force fed back.
  EXPECT_EQ(result->latched_faults, 0U) << result->first_fault;
  EXPECT_EQ(result->app.armed_cycles, 100'000U);
  EXPECT_GT(result->app.instruments[0].contact_cycles, 1000U);
  EXPECT_GT(result->app.instruments[0].peak_force_n, 1.0F);
  EXPECT_LE(result->app.instruments[0].peak_force_n, 8.0F + 1e-4F);
  EXPECT_TRUE(result->outputs_zeroed_at_exit);
  EXPECT_GT(result->arena_bytes_used, 0U);
}

TEST(TrainerRun, CountingWouldSeeAnAllocation) {
  // The no-heap proof is only worth something if the counter sees allocations on this path.
  core::alloc::begin_counting_this_thread();
  const auto before = core::alloc::counted_allocations();
  int* volatile allocated = new int(3);  // volatile: the compiler may not elide the pair
  delete allocated;
  const auto after = core::alloc::counted_allocations();
  core::alloc::end_counting_this_thread();
  EXPECT_GT(after, before);
}

TEST(TrainerRun, ReportCarriesTheRequiredFields) {
  auto result = run_trainer(simulated(2000));
  ASSERT_TRUE(result) << result.error().message;
  const nlohmann::json report = report_json(*result);
  for (const char* key : {"cycles", "period_ns", "overruns", "longest_overrun_streak",
                          "wake_latency_ns", "step_time_ns", "memory", "rt", "safety"}) {
    EXPECT_TRUE(report.contains(key)) << key;
  }
  for (const char* key : {"p50", "p99", "p99_9", "max"}) {
    EXPECT_TRUE(report["wake_latency_ns"].contains(key)) << key;
    EXPECT_TRUE(report["step_time_ns"].contains(key)) << key;
  }
  EXPECT_EQ(report["cycles"], 2000);
  EXPECT_EQ(report["period_ns"], 1'000'000);
  EXPECT_EQ(report["memory"]["heap_allocations_after_arming"], 0);
  // The trainee metrics (docs/metrics.md) from every cycle: the tip moved, and the wall is a
  // rigid object, not tissue, so no force on tissue.
  ASSERT_TRUE(report["metrics"].is_object());
  EXPECT_EQ(report["metrics"]["samples"], 2000);
  EXPECT_EQ(report["metrics"]["refused_samples"], 0);
  EXPECT_GT(report["metrics"]["instruments"][0]["path_length_m"].get<double>(), 0.0);
  EXPECT_EQ(report["metrics"]["instruments"][0]["peak_force_n"].get<double>(), 0.0);
  EXPECT_TRUE(report["rt"].contains("preempt_rt"));
  EXPECT_FALSE(report_summary(*result).empty());
}

TEST(TrainerRun, UnarmedRunReportsNotArmed) {
  RunOptions options = simulated(500);
  options.arm = false;
  auto result = run_trainer(options);
  ASSERT_TRUE(result);
  EXPECT_EQ(result->app.armed_cycles, 0U);
  EXPECT_EQ(result->latched_faults & 1U, 1U);  // not_armed
}

TEST(TrainerRun, RealClockShortRunCompletes) {
  // Real sleeps, no timing assertions (shared machines are noisy): the run completes, every
  // cycle is measured, and no heap is touched.
  RunOptions options;
  options.scene_file = wall_scene();
  options.cycles = 300;
  options.apply_rt_settings = false;
  options.on_log = [](const std::string&) {};
  auto result = run_trainer(options);
  ASSERT_TRUE(result) << result.error().message;
  EXPECT_EQ(result->loop.cycles, 300U);
  EXPECT_EQ(result->loop.wake_latency.count(), 300U);
  EXPECT_EQ(result->heap_allocations_after_arming, 0U);
  EXPECT_EQ(result->time_source, "real");
}

TEST(TrainerRun, LoopOverridesReplaceTheScenesPeriod) {
  RunOptions options = simulated(200);
  options.loop_overrides.period_us = 250;
  auto result = run_trainer(options);
  ASSERT_TRUE(result) << result.error().message;
  EXPECT_EQ(result->period_ns, 250'000);
  EXPECT_EQ(result->loop.cycles, 200U);
  EXPECT_EQ(result->latched_faults, 0U) << result->first_fault;

  RunOptions bad = simulated(10);
  bad.loop_overrides.priority = 120;
  auto refused = run_trainer(bad);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("loop.priority = 120"), std::string::npos)
      << refused.error().message;
}

TEST(TrainerRun, MaxCyclesCapsEveryWayOfChoosingTheLength) {
  RunOptions cycles = simulated(500);
  cycles.max_cycles = 120;
  auto capped = run_trainer(cycles);
  ASSERT_TRUE(capped) << capped.error().message;
  EXPECT_EQ(capped->loop.cycles, 120U);
  EXPECT_EQ(capped->requested_cycles, 120U);

  // A cap above the asked length changes nothing.
  RunOptions longer = simulated(90);
  longer.max_cycles = 1000;
  auto uncapped = run_trainer(longer);
  ASSERT_TRUE(uncapped) << uncapped.error().message;
  EXPECT_EQ(uncapped->loop.cycles, 90U);

  // No length at all (a run until a signal) is bounded by the cap alone, even in simulated
  // time, which otherwise refuses an unbounded run.
  RunOptions open_ended = simulated(1);
  open_ended.cycles.reset();
  open_ended.max_cycles = 75;
  auto bounded = run_trainer(open_ended);
  ASSERT_TRUE(bounded) << bounded.error().message;
  EXPECT_EQ(bounded->loop.cycles, 75U);

  RunOptions zero = simulated(10);
  zero.max_cycles = 0;
  EXPECT_FALSE(run_trainer(zero));
}

TEST(TrainerRun, BadSceneAndBackendAreRefusedWithMessages) {
  RunOptions missing = simulated(10);
  missing.scene_file = "/nonexistent/scene.toml";
  auto r1 = run_trainer(missing);
  ASSERT_FALSE(r1);
  EXPECT_NE(r1.error().message.find("/nonexistent/scene.toml"), std::string::npos);

  RunOptions backend = simulated(10);
  backend.hal = "socketcan";
  auto r2 = run_trainer(backend);
  ASSERT_FALSE(r2);
  EXPECT_NE(r2.error().message.find("socketcan"), std::string::npos);
}

std::filesystem::path canopen_device() {
  return std::filesystem::path(TRAINER_SOURCE_DIR) / "config/devices/canopen_vcan.toml";
}

TEST(TrainerRun, TheDeviceFileOptionPicksTheBackend) {
  // --device with a canopen file: simulated time cannot drive real drives.
  RunOptions options = simulated(10);
  options.device_file = canopen_device();
  auto refused = run_trainer(options);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("names backend 'canopen'"), std::string::npos)
      << refused.error().message;
  EXPECT_NE(refused.error().message.find("--hal sim"), std::string::npos);

  // --hal sim runs the same file's mechanism on the simulated bench.
  options.hal = "sim";
  auto simulated_bench = run_trainer(options);
  ASSERT_TRUE(simulated_bench) << simulated_bench.error().message;
  EXPECT_EQ(simulated_bench->hal, "sim");
  EXPECT_EQ(simulated_bench->device_file, canopen_device());
  EXPECT_EQ(simulated_bench->loop.cycles, 10U);
  EXPECT_FALSE(simulated_bench->can.has_value());
}

TEST(TrainerRun, ACanInterfaceThatIsNotThereFailsConfigureNamingIt) {
  // In real time the canopen backend opens the file's interface (vcan0), which this test
  // machine does not have (the bench VM does): configure fails before anything is armed.
  RunOptions options = simulated(10);
  options.time_source = TimeSource::real;
  options.apply_rt_settings = false;
  options.device_file = canopen_device();
  auto result = run_trainer(options);
  if (result) GTEST_SKIP() << "this machine has a CAN interface vcan0 with drives on it";
  const std::string& message = result.error().message;
  EXPECT_NE(message.find("canopen_vcan.toml"), std::string::npos) << message;
  EXPECT_NE(message.find("'vcan0'"), std::string::npos) << message;
}

}  // namespace
}  // namespace trainer::app
