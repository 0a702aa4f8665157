// What a measurement concludes, on synthetic data: the acceptance verdict (ratio and overrun
// limits), the comparison and JSON summary built from a trainer histogram and a cyclictest
// file with known percentiles, and the plot data (density per µs, a falling CCDF).
#include "jitter_summary.hpp"

#include <gtest/gtest.h>

#include <sstream>
#include <string>

#include "jitter_plot.hpp"

namespace trainer::tools::jitter {
namespace {

TEST(Acceptance, RatioAndOverrunLimits) {
  const PercentileSet ratios{1.1, 1.2, 1.3, 1.6, 4.0};
  AcceptanceCriteria criteria;
  criteria.max_ratio = 1.5;  // ratio_at defaults to p99 and p99.9
  auto verdict = evaluate_acceptance(criteria, ratios, 3);
  ASSERT_TRUE(verdict) << verdict.error().message;
  EXPECT_TRUE(verdict->evaluated);
  EXPECT_FALSE(verdict->passed);
  ASSERT_EQ(verdict->checks.size(), 2U);
  ASSERT_EQ(verdict->violations.size(), 1U);
  EXPECT_NE(verdict->violations[0].find("p99.9 trainer/cyclictest 1.600 > 1.500"),
            std::string::npos)
      << verdict->violations[0];

  criteria.ratio_at = {"p50", "p99"};
  criteria.max_overruns = 3;
  verdict = evaluate_acceptance(criteria, ratios, 3);
  ASSERT_TRUE(verdict);
  EXPECT_TRUE(verdict->passed);
  EXPECT_EQ(verdict->checks.size(), 3U);

  verdict = evaluate_acceptance(criteria, ratios, 4);
  ASSERT_TRUE(verdict);
  EXPECT_FALSE(verdict->passed);
  ASSERT_EQ(verdict->violations.size(), 1U);
  EXPECT_NE(verdict->violations[0].find("trainer overruns 4 > 3"), std::string::npos);

  // A missing side (ratio 0) proves nothing, so it cannot pass.
  criteria.max_overruns.reset();
  verdict = evaluate_acceptance(criteria, PercentileSet{0.0, 0.0, 0.0, 0.0, 0.0}, 0);
  ASSERT_TRUE(verdict);
  EXPECT_FALSE(verdict->passed);

  const AcceptanceCriteria none;
  verdict = evaluate_acceptance(none, ratios, 1000);
  ASSERT_TRUE(verdict);
  EXPECT_FALSE(verdict->evaluated);
  EXPECT_TRUE(verdict->passed);

  criteria.ratio_at = {"p42"};
  EXPECT_FALSE(evaluate_acceptance(criteria, ratios, 0));
}

// 1000 trainer wake-ups: 990 at 20 us, 9 at 50 us, 1 at 3 ms; cyclictest: 1000 loops, 990 in
// [16, 17) us, 9 in [40, 41) us, 1 in [900, 901) us.
JitterMeasurement synthetic_measurement() {
  JitterMeasurement m;
  m.mode = Mode::alongside;
  m.requested_seconds = 1.0;
  m.settings.scene_name = "wall";
  m.settings.scene_file = "config/scenes/wall.toml";
  m.settings.period_ns = 1'000'000;
  m.settings.priority = 80;
  m.settings.cpu = 1;
  m.settings.cyclictest_cpu = 0;
  m.settings.histogram_limit_us = 1000;
  m.settings.target_cycles = 1000;
  for (int i = 0; i < 990; ++i) m.trainer.wake_latency->record(20'000);
  for (int i = 0; i < 9; ++i) m.trainer.wake_latency->record(50'000);
  m.trainer.wake_latency->record(3'000'000);
  for (int i = 0; i < 1000; ++i) m.trainer.step_time->record(5'000);
  m.trainer.cycles = 1000;
  m.trainer.overruns = 1;
  m.trainer.runs.push_back(TrainerRunRecord{1000, 1.0, 1, 1, 0, "none", "trainer_run_1.json"});
  std::string text = "# Histogram\n";
  for (int k = 0; k < 1000; ++k) {
    const int count = k == 16 ? 990 : k == 40 ? 9 : k == 900 ? 1 : 0;
    text += std::to_string(k) + " " + std::to_string(count) + "\n";
  }
  text +=
      "# Total: 1000\n# Min Latencies: 16\n# Avg Latencies: 16\n# Max Latencies: 900\n"
      "# Histogram Overflows: 0\n";
  auto histogram = parse_cyclictest_histogram(text, "synthetic");
  EXPECT_TRUE(histogram) << histogram.error().message;
  if (histogram) m.cyclictest.histogram = *histogram;
  m.cyclictest.arguments = {"cyclictest", "-q", "-t1"};
  return m;
}

TEST(Summary, ComparesLikeForLikeAndReportsEveryField) {
  const JitterMeasurement m = synthetic_measurement();
  const Comparison c = compare(m);
  // 20 us sits in the trainer's [19.968, 20.480) us bin: p50 and p99 are its upper edge.
  EXPECT_DOUBLE_EQ(c.trainer_wake_us.p50_us, 20.48);
  EXPECT_DOUBLE_EQ(c.trainer_wake_us.p99_us, 20.48);
  EXPECT_DOUBLE_EQ(c.trainer_wake_us.p99_9_us, 50.176);  // rank 999: 50 us in [49.152, 50.176)
  EXPECT_DOUBLE_EQ(c.trainer_wake_us.max_us, 3000.0);
  EXPECT_DOUBLE_EQ(c.cyclictest_us.p50_us, 17.0);
  EXPECT_DOUBLE_EQ(c.cyclictest_us.p99_9_us, 41.0);
  EXPECT_DOUBLE_EQ(c.cyclictest_us.max_us, 901.0);
  EXPECT_DOUBLE_EQ(c.ratios.p99_us, 20.48 / 17.0);
  EXPECT_DOUBLE_EQ(c.ratios.p99_9_us, 50.176 / 41.0);
  EXPECT_EQ(c.cyclictest_late_by_a_period, 0U);

  AcceptanceCriteria criteria;
  criteria.max_ratio = 1.5;
  const auto verdict = evaluate_acceptance(criteria, c.ratios, m.trainer.overruns);
  ASSERT_TRUE(verdict);
  const nlohmann::json json = summary_json(m, c, criteria, *verdict, "jitter.png");
  EXPECT_EQ(json["mode"], "alongside");
  EXPECT_EQ(json["scene"]["name"], "wall");
  EXPECT_EQ(json["settings"]["period_us"], 1000.0);
  EXPECT_EQ(json["settings"]["cyclictest_cpu"], 0);
  EXPECT_EQ(json["trainer"]["cycles"], 1000);
  EXPECT_EQ(json["trainer"]["wake_latency_us"]["count"], 1000);
  EXPECT_EQ(json["trainer"]["wake_latency_us"]["p99_9"], 50.176);
  // Every step took exactly 5 us: the bin's edge (5.12 us) is clamped to the exact maximum.
  EXPECT_EQ(json["trainer"]["step_time_us"]["p50"], 5.0);
  EXPECT_EQ(json["trainer"]["overruns"], 1);
  EXPECT_EQ(json["trainer"]["runs"], 1);
  EXPECT_EQ(json["cyclictest"]["loops"], 1000);
  EXPECT_EQ(json["cyclictest"]["latency_us"]["p50"], 17.0);
  EXPECT_EQ(json["cyclictest"]["reported_max_us"], 900);
  EXPECT_EQ(json["cyclictest"]["command"], "cyclictest -q -t1");
  EXPECT_EQ(json["ratio_trainer_over_cyclictest"]["p99"], 1.205);  // 20.48 / 17, 3 decimals
  EXPECT_EQ(json["acceptance"]["passed"], true);
  EXPECT_EQ(json["acceptance"]["max_ratio"], 1.5);
  EXPECT_TRUE(json["acceptance"]["max_overruns"].is_null());

  const std::string text = summary_text(m, c, *verdict);
  EXPECT_NE(text.find("alongside"), std::string::npos) << text;
  EXPECT_NE(text.find("p99 1.20"), std::string::npos) << text;
}

TEST(Plot, DataHoldsDensityAndAFallingCcdfPerSide) {
  const JitterMeasurement m = synthetic_measurement();
  const Comparison c = compare(m);
  const std::string data = plot_data(c.trainer_wake, c.cyclictest);
  // Four data sets, two blank lines apart.
  std::vector<std::vector<std::pair<double, double>>> sets(1);
  std::istringstream lines(data);
  int blank = 0;
  for (std::string line; std::getline(lines, line);) {
    if (line.empty()) {
      if (++blank == 2) sets.emplace_back();
      continue;
    }
    blank = 0;
    if (line[0] == '#') continue;
    std::istringstream fields(line);
    double x = 0.0;
    double y = 0.0;
    fields >> x >> y;
    sets.back().emplace_back(x, y);
  }
  ASSERT_EQ(sets.size(), 4U);
  ASSERT_EQ(sets[1].size(), 3U);  // cyclictest's three non-empty bins
  EXPECT_DOUBLE_EQ(sets[1][0].first, 16.5);
  EXPECT_DOUBLE_EQ(sets[1][0].second, 990.0);  // 1 us bins: samples per us = count
  // The trainer's 20 us bin is 0.512 us wide: 990 / 0.512 samples per us.
  EXPECT_NEAR(sets[0][0].second, 990.0 / 0.512, 0.01);
  for (const std::size_t index : {2U, 3U}) {
    const auto& ccdf = sets[index];
    ASSERT_GE(ccdf.size(), 2U);
    EXPECT_DOUBLE_EQ(ccdf.front().second, 1.0);
    for (std::size_t i = 1; i < ccdf.size(); ++i) {
      EXPECT_LE(ccdf[i].second, ccdf[i - 1].second);
      EXPECT_GE(ccdf[i].first, ccdf[i - 1].first);
    }
    EXPECT_DOUBLE_EQ(ccdf.back().second, 0.001);  // the one largest sample of 1000
  }
  EXPECT_DOUBLE_EQ(sets[3].back().first, 901.0);

  const std::string script = plot_script(
      c.trainer_wake, c.cyclictest, PlotLabels{"a \"title\"\nline two", "trainer", "cyclictest"});
  EXPECT_NE(script.find("set output 'jitter.png'"), std::string::npos);
  EXPECT_NE(script.find("\"a \\\"title\\\"\\nline two\""), std::string::npos) << script;
  EXPECT_NE(script.find("index 3"), std::string::npos);
}

}  // namespace
}  // namespace trainer::tools::jitter
