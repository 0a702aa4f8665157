// The report's `metrics` section (docs/report.md): every field docs/metrics.md names, nulls
// where a metric does not apply (no movement, no damage, no catheter), names resolved.
#include <gtest/gtest.h>

#include <limits>
#include <string>
#include <vector>

#include "trainer/metrics/metrics_report.hpp"

namespace trainer::metrics {
namespace {

TEST(MetricsReport, SectionNamesInstrumentsModelsAndNullsWhatDoesNotApply) {
  SessionSetup setup;
  setup.period_ns = 1'000'000;
  setup.instrument_count = 2;
  setup.insertion_target_depth_m = 0.004995;  // half a step below sample 500's depth
  auto created = SessionMetrics::create(setup);
  ASSERT_TRUE(created.has_value());
  SessionMetrics& m = *created;
  for (std::uint64_t k = 0; k < 1000; ++k) {
    CycleSample s;
    s.time_ns = static_cast<std::int64_t>(k + 1) * 1'000'000;
    s.instrument_count = 2;
    s.instruments[0].tip_m = {static_cast<float>(k) * 2.2e-5F, 0.0F, -0.1F};  // 22 mm/s
    s.instruments[1].tissue_force_n = {0.0F, 0.0F, k == 600 ? 5.0F : 1.0F};
    s.instruments[1].tissue_contact = 1;
    s.instruments[1].contact_point_m = {0.01F, 0.02F, -0.1F};
    s.contact_model = 1;
    s.insertion_depth_m = static_cast<float>(k) * 1e-5F;
    ASSERT_TRUE(m.add(s).is_ok());
  }
  const std::vector<std::string> instruments = {"left", "right"};
  const std::vector<std::string> models = {"duct", "catheter"};
  const nlohmann::json j = metrics_json(m.result(), setup.thresholds, instruments, models);
  EXPECT_EQ(j["samples"], 1000);
  EXPECT_EQ(j["thresholds"]["safe_force_n"], 2.0);
  EXPECT_EQ(j["task"]["completed"], true);
  EXPECT_EQ(j["task"]["start_ns"], 24'000'000);  // window speed 22 mm/s · k/50 ≥ 10 at k = 23
  EXPECT_EQ(j["task"]["end_ns"], 501'000'000);  // depth 5 mm at sample 500
  ASSERT_EQ(j["instruments"].size(), 2U);
  EXPECT_EQ(j["instruments"][0]["name"], "left");
  EXPECT_EQ(j["instruments"][0]["movements"], 1);
  EXPECT_TRUE(j["instruments"][0]["motion_economy"].is_number());
  EXPECT_TRUE(j["instruments"][0]["damage"]["peak"].is_null());
  EXPECT_TRUE(j["instruments"][1]["motion_economy"].is_null());
  EXPECT_EQ(j["instruments"][1]["damage"]["peak"]["model"], "catheter");
  EXPECT_EQ(j["worst_damage"]["instrument"], "right");
  EXPECT_EQ(j["worst_damage"]["time_ns"], 601'000'000);
  EXPECT_EQ(j["insertion"]["target_reached"], true);
  EXPECT_NEAR(j["insertion"]["time_to_target_s"].get<double>(), 0.477, 1e-9);

  // Task 501 − 24 ms; right: 5 N once above the 4 N damage force, 1 ms above safe.
  EXPECT_EQ(metrics_summary(m.result(), instruments),
            "metrics: task 0.48 s (insertion target 5.0 mm reached), above safe force 0.00 s, "
            "damage 0.00 s, 0.001 N·s, peak 5.00 N (right), insertion depth 10.0 mm\n"
            "  left: path 11.0 mm, movements 1, idle 0.00 s, economy 1.00, peak 0.00 N, mean in "
            "contact 0.00 N, grasps 0 (slips 0)\n"
            "  right: path 0.0 mm, movements 0, idle 0.48 s, peak 5.00 N, mean in contact 1.00 N, "
            "grasps 0 (slips 0)\n");
}

TEST(MetricsReport, NoCatheterAndNoDamageGiveNulls) {
  SessionSetup setup;
  auto created = SessionMetrics::create(setup);
  ASSERT_TRUE(created.has_value());
  CycleSample s;
  s.time_ns = 1'000'000;
  s.instrument_count = 1;
  s.insertion_depth_m = std::numeric_limits<float>::quiet_NaN();
  ASSERT_TRUE(created->add(s).is_ok());
  const nlohmann::json j = metrics_json(created->result(), setup.thresholds, {}, {});
  EXPECT_TRUE(j["insertion"].is_null());
  EXPECT_TRUE(j["worst_damage"].is_null());
  EXPECT_EQ(j["instruments"][0]["name"], "0");
  EXPECT_EQ(j["task"]["started"], false);
  EXPECT_TRUE(j["task"]["start_ns"].is_null());
}

}  // namespace
}  // namespace trainer::metrics
