// The trainee metrics in the telemetry stream (wire format 1.1, section 18): a session's
// SessionResult becomes the frame's metrics, survives encode → decode, and its flags say what
// the panel may show (task state, insertion goal and target).
#include "trainer/app/stream_metrics.hpp"

#include <gtest/gtest.h>

#include <memory>
#include <vector>

namespace trainer::app {
namespace {

metrics::SessionResult cbd_like_result() {
  metrics::SessionResult r;
  r.session_time_s = 11.0;
  r.task_started = true;
  r.task_completed = true;
  r.task_time_s = 6.095;
  r.time_above_safe_s = 0.027;
  r.damage_impulse_n_s = 0.5;
  r.instrument_count = 2;
  r.instruments[0].path_length_m = 0.075;
  r.instruments[0].idle_time_s = 3.49;
  r.instruments[0].peak_force_n = 0.443;
  r.instruments[0].mean_contact_force_n = 0.429;
  r.instruments[0].movements = 2;
  r.instruments[0].grasps = 1;
  r.instruments[1].path_length_m = 0.076;
  r.instruments[1].peak_force_n = 1.52;
  r.instruments[1].time_above_safe_s = 0.027;
  r.instruments[1].slips = 70000;  // saturates at the wire's u16
  r.insertion.present = true;
  r.insertion.max_depth_m = 0.01198;
  r.insertion.target_depth_m = 0.010;
  r.insertion.target_reached = true;
  r.insertion.time_to_target_s = 6.095;
  return r;
}

TEST(StreamMetrics, ASessionsMetricsTravelInTheFrame) {
  const telemetry::SessionMetrics m = stream_metrics(cbd_like_result());
  EXPECT_EQ(m.flags, telemetry::kMetricsTaskStarted | telemetry::kMetricsTaskCompleted |
                         telemetry::kMetricsInsertionGoal | telemetry::kMetricsTargetReached);
  EXPECT_FLOAT_EQ(m.task_time_s, 6.095F);
  EXPECT_FLOAT_EQ(m.insertion_depth_m, 0.01198F);
  EXPECT_EQ(m.instruments[1].slips, 0xFFFFU);

  auto frame = std::make_unique<telemetry::Frame>();
  frame->instrument_count = 2;
  frame->has_metrics = true;
  frame->metrics = m;
  std::vector<std::byte> bytes(telemetry::encoded_size(*frame));
  ASSERT_TRUE(telemetry::encode(*frame, bytes).ok());
  auto decoded = std::make_unique<telemetry::Frame>();
  ASSERT_TRUE(telemetry::decode(bytes, *decoded).ok());
  ASSERT_TRUE(decoded->has_metrics);
  EXPECT_EQ(decoded->metrics.instrument_count, 2);
  EXPECT_FLOAT_EQ(decoded->metrics.instruments[0].path_length_m, 0.075F);
  EXPECT_EQ(decoded->metrics.instruments[0].grasps, 1);
  EXPECT_FLOAT_EQ(decoded->metrics.time_to_target_s, 6.095F);
}

TEST(StreamMetrics, NoGoalNoTargetBeforeTheTaskStarts) {
  metrics::SessionResult r;
  r.instrument_count = 1;
  const telemetry::SessionMetrics m = stream_metrics(r);
  EXPECT_EQ(m.flags, 0);
  EXPECT_EQ(m.instrument_count, 1);
  EXPECT_EQ(m.insertion_depth_m, 0.0F);
  EXPECT_EQ(m.time_to_target_s, 0.0F);
}

}  // namespace
}  // namespace trainer::app
