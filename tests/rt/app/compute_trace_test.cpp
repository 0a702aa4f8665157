// trainer --repeat's arithmetic and runs (issue 19): the per-cycle minimum over runs, exact
// nearest-rank percentiles, and run_trainer_repeated on the wall scene (the compute section's
// figures, identical runs, no heap after arming, the refusals).
#include "trainer/app/compute_trace.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

#include "trainer/app/report.hpp"
#include "trainer/app/trainer_run.hpp"

namespace trainer::app {
namespace {

TEST(ComputeTrace, ColumnsAreStepThenPhasesThenSubstages) {
  EXPECT_STREQ(compute_column_name(kStepColumn), "step");
  EXPECT_STREQ(compute_column_name(kFirstPhaseColumn), "hal_read");
  EXPECT_STREQ(compute_column_name(kFirstPhaseColumn + 2), "modal_models");
  EXPECT_STREQ(compute_column_name(kFirstSubstageColumn), "modal_near");
  EXPECT_STREQ(compute_column_name(kComputeColumns - 1), "catheter_reactions");
}

TEST(ComputeTrace, NearestRankPercentilesAreExact) {
  std::vector<std::int64_t> values(1000);
  std::iota(values.begin(), values.end(), 1);  // 1 .. 1000
  std::vector<std::int64_t> shuffled;
  for (std::size_t k = 0; k < values.size(); ++k) shuffled.push_back(values[(k * 7919) % 1000]);
  const ComputeStatistics s = compute_statistics("x", shuffled);
  EXPECT_EQ(s.count, 1000U);
  EXPECT_EQ(s.min_ns, 1);
  EXPECT_EQ(s.p50_ns, 500);    // rank ceil(0.5 * 1000) = 500
  EXPECT_EQ(s.p99_ns, 990);    // rank 990
  EXPECT_EQ(s.p99_9_ns, 999);  // rank 999
  EXPECT_EQ(s.max_ns, 1000);
  EXPECT_DOUBLE_EQ(s.mean_ns, 500.5);
  // Few samples: p99.9 of three values is the largest; nothing is the empty statistic.
  const std::vector<std::int64_t> three{30, 10, 20};
  EXPECT_EQ(compute_statistics("y", three).p99_9_ns, 30);
  EXPECT_EQ(compute_statistics("y", three).p50_ns, 20);
  EXPECT_EQ(compute_statistics("z", {}).count, 0U);
}

// Two "runs" of four cycles: an interrupt in cycle 1 of the first, in cycle 3 of the second;
// the per-cycle minimum has neither.
TEST(ComputeTrace, TheFoldKeepsEachCyclesMinimumOverTheRuns) {
  CycleTimeTrace run;
  CycleTimeTrace minimum;
  run.prepare(4);
  std::vector<std::int64_t> first{10, 47, 12, 11};
  std::copy(first.begin(), first.end(), run.step_ns().begin());
  minimum.fold_minimum(run, 4);
  run.prepare(4);
  std::vector<std::int64_t> second{11, 10, 12, 50};
  std::copy(second.begin(), second.end(), run.step_ns().begin());
  minimum.fold_minimum(run, 4);
  EXPECT_EQ(minimum.folds(), 2U);
  const auto step = minimum.column(kStepColumn);
  EXPECT_EQ(std::vector<std::int64_t>(step.begin(), step.end()),
            (std::vector<std::int64_t>{10, 10, 12, 11}));
  EXPECT_EQ(compute_statistics("step", step).max_ns, 12);
}

RunOptions wall(std::uint64_t cycles) {
  RunOptions options;
  options.scene_file = std::filesystem::path(TRAINER_SOURCE_DIR) / "config/scenes/wall.toml";
  options.time_source = TimeSource::simulated;
  options.cycles = cycles;
  options.on_log = [](const std::string&) {};
  return options;
}

TEST(TrainerRepeat, ThreeRunsOfTheWallSceneGiveThePerCycleMinimum) {
  auto result = run_trainer_repeated(wall(500), 3);
  ASSERT_TRUE(result) << result.error().message;
  ASSERT_TRUE(result->compute.has_value());
  const ComputeSummary& c = *result->compute;
  EXPECT_EQ(c.runs, 3U);
  EXPECT_EQ(c.cycles, 500U);
  EXPECT_EQ(c.period_ns, 1'000'000);
  EXPECT_TRUE(c.identical) << c.mismatch;
  ASSERT_EQ(c.per_run.size(), 3U);
  for (const ComputeRun& run : c.per_run) {
    EXPECT_EQ(run.cycles, 500U);
    EXPECT_EQ(run.final_state_hash, c.per_run[0].final_state_hash);
    // The minimum over the runs is never above a run's own order statistics.
    EXPECT_LE(c.step.p50_ns, run.step.p50_ns);
    EXPECT_LE(c.step.max_ns, run.step.max_ns);
  }
  EXPECT_NE(c.per_run[0].final_state_hash, 0U);
  // Real-clock compute: positive, below a millisecond for the wall scene's ~1 µs cycle.
  EXPECT_EQ(c.step.count, 500U);
  EXPECT_GT(c.step.min_ns, 0);
  EXPECT_LT(c.step.p50_ns, 1'000'000);
  EXPECT_LE(c.step.p50_ns, c.step.p99_9_ns);
  // The wall scene runs no model stage and so has no sub-stage; the step holds its stages.
  std::vector<std::string> stages;
  double stage_means = 0.0;
  for (const ComputeStatistics& s : c.stages) {
    stages.push_back(s.name);
    stage_means += s.mean_ns;
  }
  EXPECT_EQ(stages,
            (std::vector<std::string>{"hal_read", "kinematics", "forces", "hal_write", "publish"}));
  EXPECT_TRUE(c.substages.empty());
  EXPECT_GE(c.step.mean_ns, stage_means);
  // The run itself: the simulated-time step is real-clock now, and nothing touched the heap.
  EXPECT_GT(result->loop.step_time.min_ns(), 0);
  EXPECT_EQ(result->heap_allocations_after_arming, 0U);
  EXPECT_EQ(result->loop.cycles, 500U);
  const nlohmann::json report = report_json(*result);
  ASSERT_TRUE(report["compute"].is_object());
  EXPECT_EQ(report["compute"]["runs"], 3);
  EXPECT_EQ(report["compute"]["per_run"].size(), 3U);
  EXPECT_TRUE(report["compute"]["stages_ns"].contains("hal_read"));
  EXPECT_NE(report_summary(*result).find("compute, per-cycle minimum of 3 run(s)"),
            std::string::npos);
}

TEST(TrainerRepeat, TheCsvHoldsThePerCycleMinimumOfEveryCycle) {
  auto result = run_trainer_repeated(wall(50), 2);
  ASSERT_TRUE(result) << result.error().message;
  ASSERT_TRUE(result->compute && result->compute->per_cycle_minimum);
  std::ostringstream csv;
  write_compute_csv(*result->compute, csv);
  std::istringstream lines(csv.str());
  std::string line;
  ASSERT_TRUE(std::getline(lines, line));
  EXPECT_EQ(line, "cycle,step,hal_read,kinematics,forces,hal_write,publish");
  std::int64_t largest_step_ns = 0;
  std::size_t rows = 0;
  for (; std::getline(lines, line); ++rows) {
    EXPECT_EQ(line.rfind(std::to_string(rows) + ",", 0), 0U) << line;
    const std::size_t first = line.find(',') + 1;
    largest_step_ns = std::max<std::int64_t>(
        largest_step_ns, std::stoll(line.substr(first, line.find(',', first) - first)));
  }
  EXPECT_EQ(rows, 50U);
  EXPECT_EQ(largest_step_ns, result->compute->step.max_ns);
}

TEST(TrainerRepeat, OneRunStillReportsItsCycles) {
  auto result = run_trainer_repeated(wall(100), 1);
  ASSERT_TRUE(result) << result.error().message;
  ASSERT_TRUE(result->compute.has_value());
  EXPECT_EQ(result->compute->runs, 1U);
  EXPECT_EQ(result->compute->step.count, 100U);
  // A plain run has no compute section.
  auto plain = run_trainer(wall(100));
  ASSERT_TRUE(plain) << plain.error().message;
  EXPECT_FALSE(plain->compute.has_value());
  EXPECT_TRUE(report_json(*plain)["compute"].is_null());
}

TEST(TrainerRepeat, RefusesRealTimeARecordingAndAnOutOfRangeCount) {
  RunOptions real = wall(100);
  real.time_source = TimeSource::real;
  auto refused = run_trainer_repeated(real, 2);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("--repeat needs --time simulated"), std::string::npos);
  RunOptions recorded = wall(100);
  recorded.record_file = std::filesystem::temp_directory_path() / "never-written.mcap";
  auto no_recording = run_trainer_repeated(recorded, 2);
  ASSERT_FALSE(no_recording);
  EXPECT_NE(no_recording.error().message.find("cannot record"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(*recorded.record_file));
  EXPECT_FALSE(run_trainer_repeated(wall(100), 0));
  EXPECT_FALSE(run_trainer_repeated(wall(100), kMaxRepeatRuns + 1));
  RunOptions missing = wall(100);
  missing.scene_file = "no/such/scene.toml";
  auto setup_error = run_trainer_repeated(missing, 2);
  ASSERT_FALSE(setup_error);
  EXPECT_EQ(setup_error.error().message.rfind("run 1 of 2: ", 0), 0U)
      << setup_error.error().message;
}

}  // namespace
}  // namespace trainer::app
