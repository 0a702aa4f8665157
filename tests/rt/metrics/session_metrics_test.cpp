// SessionMetrics on constructed trajectories whose answers are known in closed form
// (docs/metrics.md gives each definition). Samples are built on a 1 kHz clock; every time
// metric is a sum of whole sample intervals, so times are compared to the nanosecond-exact
// count of samples (tolerance 1e-9 s for the double sums), lengths to 1e-6 m (positions
// travel as float: ~1e-8 m rounding per point on 0.1 m).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdint>
#include <limits>
#include <vector>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/metrics/session_metrics.hpp"

namespace trainer::metrics {
namespace {

constexpr std::int64_t kPeriodNs = 1'000'000;
constexpr double kPeriodS = 1e-3;
constexpr double kTimeTolS = 1e-9;
constexpr double kLengthTolM = 1e-6;

SessionMetrics make_session(const SessionSetup& setup) {
  auto created = SessionMetrics::create(setup);
  EXPECT_TRUE(created.has_value()) << (created ? "" : created.error().message);
  return std::move(created).value();
}

SessionSetup one_instrument_setup() {
  SessionSetup setup;
  setup.period_ns = kPeriodNs;
  setup.instrument_count = 1;
  return setup;
}

// Sample k at time (k + 1) ms (the first deadline is one period after the start).
CycleSample sample_at(std::uint64_t k, std::uint32_t instruments = 1) {
  CycleSample s;
  s.cycle = k;
  s.time_ns = static_cast<std::int64_t>(k + 1) * kPeriodNs;
  s.instrument_count = instruments;
  s.insertion_depth_m = std::numeric_limits<float>::quiet_NaN();
  return s;
}

std::int64_t time_of(std::uint64_t k) { return static_cast<std::int64_t>(k + 1) * kPeriodNs; }

void set_tip(CycleSample& s, std::size_t i, double x, double y = 0.0, double z = 0.0) {
  s.instruments[i].tip_m = {static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)};
}

void add_ok(SessionMetrics& m, const CycleSample& s) {
  const core::Status status = m.add(s);
  ASSERT_TRUE(status.is_ok()) << status.detail();
}

// ---------------------------------------------------------------- path length, economy

TEST(SessionMetricsPath, StraightLineAtConstantSpeedHasExactLengthAndEconomyOne) {
  // 0.048 m/s along a diagonal for 2000 samples: 0.096 m. Each step (48 µm) is below the
  // default deadband (100 µm), so the deadband is crossed every second sample and the last
  // remainder is added at the end: the length is still exact for a straight line.
  SessionMetrics m = make_session(one_instrument_setup());
  const double step_m = 0.048 * kPeriodS;
  const double ux = 0.6;
  const double uy = 0.8;
  for (std::uint64_t k = 0; k <= 2000; ++k) {
    CycleSample s = sample_at(k);
    const double d = step_m * static_cast<double>(k);
    set_tip(s, 0, 0.01 + ux * d, -0.02 + uy * d, -0.1);
    add_ok(m, s);
  }
  const SessionResult r = m.result();
  const InstrumentMetrics& i = r.instruments[0];
  EXPECT_NEAR(i.path_length_m, 0.096, kLengthTolM);
  // The window speed is the displacement over the last 50 ms: 48 mm/s · k / 50 for k < 50,
  // reaching the start speed (10 mm/s) at k = 11 (10.4 rounded up).
  EXPECT_EQ(i.movements, 1U);
  ASSERT_TRUE(i.motion_economy.has_value());
  EXPECT_NEAR(*i.motion_economy, 1.0, 1e-5);
  EXPECT_TRUE(r.task_started);
  EXPECT_EQ(r.task_start_ns, time_of(11));
  EXPECT_FALSE(r.task_completed);
  EXPECT_EQ(r.task_end_ns, time_of(2000));
  EXPECT_NEAR(r.task_time_s, 1.989, kTimeTolS);
  EXPECT_NEAR(i.moving_time_s, 1.989, kTimeTolS);
  EXPECT_NEAR(i.idle_time_s, 0.0, kTimeTolS);
  EXPECT_NEAR(r.session_time_s, 2.001, kTimeTolS);
}

TEST(SessionMetricsPath, LShapeInOneMovementHasTheChordToPathRatio) {
  // L shape without stopping: 600 steps of 48 µm along x, then 800 along y (28.8 + 38.4 mm).
  SessionSetup setup = one_instrument_setup();
  setup.thresholds.path_deadband_m = 0.0;
  SessionMetrics m = make_session(setup);
  std::uint64_t k = 0;
  const double step_m = 0.048 * kPeriodS;
  for (int j = 0; j <= 600; ++j, ++k) {
    CycleSample s = sample_at(k);
    set_tip(s, 0, step_m * j);
    add_ok(m, s);
  }
  for (int j = 1; j <= 800; ++j, ++k) {
    CycleSample s = sample_at(k);
    set_tip(s, 0, 600 * step_m, step_m * j);
    add_ok(m, s);
  }
  const InstrumentMetrics i = m.result().instruments[0];
  EXPECT_NEAR(i.path_length_m, 1400 * step_m, kLengthTolM);
  EXPECT_EQ(i.movements, 1U);
  ASSERT_TRUE(i.motion_economy.has_value());
  // The movement is detected at sample 11 (window speed 48 mm/s · 11/50), so its chord and
  // path both start there.
  const double start_m = 11 * step_m;
  const double chord = std::hypot(600 * step_m - start_m, 800 * step_m);
  EXPECT_NEAR(*i.motion_economy, chord / (1400 * step_m - start_m), 1e-5);
}

TEST(SessionMetricsPath, EncoderQuantisationJitterAddsNoPathAndNoMovement) {
  // A still hand on an encoder edge: the tip flickers by one count at the tip (37 µm on the
  // sim device) every sample for 5 s. With the default deadband nothing is counted but the
  // final remainder (< one count); without a deadband the flicker would add 0.185 m.
  constexpr double kCountM = 37e-6;
  SessionMetrics with_deadband = make_session(one_instrument_setup());
  SessionSetup raw_setup = one_instrument_setup();
  raw_setup.thresholds.path_deadband_m = 0.0;
  SessionMetrics without_deadband = make_session(raw_setup);
  for (std::uint64_t k = 0; k < 5000; ++k) {
    CycleSample s = sample_at(k);
    set_tip(s, 0, 0.02 + ((k % 2) != 0 ? kCountM : 0.0), 0.01, -0.1);
    add_ok(with_deadband, s);
    add_ok(without_deadband, s);
  }
  const SessionResult r = with_deadband.result();
  EXPECT_LE(r.instruments[0].path_length_m, kCountM + 1e-9);
  EXPECT_EQ(r.instruments[0].movements, 0U);
  EXPECT_FALSE(r.task_started);
  // (1e-5: the float positions round each 37 µm step by up to ~2 nm.)
  EXPECT_NEAR(without_deadband.result().instruments[0].path_length_m, 4999 * kCountM, 1e-5);
  // The window speed of the flicker (one count per 50 ms) stays far below the stop speed.
  EXPECT_EQ(without_deadband.result().instruments[0].movements, 0U);
}

// ---------------------------------------------------------------- movements and idle time

TEST(SessionMetricsMovement, StopAndGoGivesKnownMovementsAndIdleTime) {
  // Speed window of one period: the speed is exact per sample, so a movement starts at the
  // first moving sample and ends at the first still one. Profile (samples): 1000 still,
  // 500 moving at 40 mm/s, 1000 still, 50 moving (a 50 ms twitch, below min_movement_s = 0.1),
  // 1000 still, 300 moving, 200 still, 400 moving, 500 still.
  SessionSetup setup = one_instrument_setup();
  setup.thresholds.speed_window_s = 1e-3;
  SessionMetrics m = make_session(setup);
  const double step_m = 0.04 * kPeriodS;
  struct Phase {
    int samples;
    bool moving;
  };
  const std::vector<Phase> phases = {{1000, false}, {500, true},  {1000, false}, {50, true},
                                     {1000, false}, {300, true},  {200, false},  {400, true},
                                     {500, false}};
  std::uint64_t k = 0;
  double x = 0.0;
  std::uint64_t first_moving = 0;
  {
    CycleSample s = sample_at(k++);
    set_tip(s, 0, x);
    add_ok(m, s);
  }
  for (const Phase& phase : phases) {
    for (int j = 0; j < phase.samples; ++j, ++k) {
      if (phase.moving) {
        x += step_m;
        if (first_moving == 0) first_moving = k;
      }
      CycleSample s = sample_at(k);
      set_tip(s, 0, x);
      add_ok(m, s);
    }
  }
  const SessionResult r = m.result();
  const InstrumentMetrics& i = r.instruments[0];
  EXPECT_EQ(i.movements, 3U);
  EXPECT_NEAR(i.moving_time_s, (500 + 300 + 400) * kPeriodS, kTimeTolS);
  ASSERT_TRUE(r.task_started);
  EXPECT_EQ(r.task_start_ns, time_of(first_moving));
  EXPECT_EQ(r.task_end_ns, time_of(k - 1));
  // The task runs from the first moving sample to the last sample; all of it that is not in a
  // counted movement is idle — the twitch included.
  EXPECT_NEAR(i.idle_time_s, r.task_time_s - i.moving_time_s, kTimeTolS);
  EXPECT_NEAR(i.idle_time_s, (1000 + 50 + 1000 + 200 + 500) * kPeriodS - kPeriodS, kTimeTolS);
  EXPECT_NEAR(i.path_length_m, (500 + 50 + 300 + 400) * step_m, kLengthTolM);
  ASSERT_TRUE(i.motion_economy.has_value());
  EXPECT_NEAR(*i.motion_economy, 1.0, 1e-5);
}

TEST(SessionMetricsMovement, HysteresisKeepsOneMovementThroughASlowPassage) {
  // Speed 20 mm/s, then 7 mm/s (between stop 5 and start 10 mm/s) for 200 ms, then 20 mm/s
  // again: one movement. The same dip to 3 mm/s splits it into two.
  const auto run = [](double slow_speed) {
    SessionSetup setup = one_instrument_setup();
    setup.thresholds.speed_window_s = 1e-3;
    SessionMetrics m = make_session(setup);
    double x = 0.0;
    std::uint64_t k = 0;
    const auto go = [&](int samples, double speed) {
      for (int j = 0; j < samples; ++j, ++k) {
        x += speed * kPeriodS;
        CycleSample s = sample_at(k);
        set_tip(s, 0, x);
        add_ok(m, s);
      }
    };
    go(1, 0.0);
    go(300, 0.020);
    go(200, slow_speed);
    go(300, 0.020);
    go(100, 0.0);
    return m.result().instruments[0].movements;
  };
  EXPECT_EQ(run(0.007), 1U);
  EXPECT_EQ(run(0.003), 2U);
}

TEST(SessionMetricsMovement, WindowedSpeedDelaysStartAndEndByKnownSampleCounts) {
  // Default 50-sample window, 40 mm/s: the window speed after j+1 moving samples is
  // 40·(j+1)/50 mm/s, reaching 10 mm/s at the 13th moving sample; j samples after the last
  // moving one it is 40·(50−j)/50 mm/s, below 5 mm/s from j = 44. The movement's time runs
  // from the entry sample to the exit sample.
  SessionMetrics m = make_session(one_instrument_setup());
  double x = 0.0;
  std::uint64_t k = 0;
  const auto go = [&](int samples, double speed) {
    for (int j = 0; j < samples; ++j, ++k) {
      x += speed * kPeriodS;
      CycleSample s = sample_at(k);
      set_tip(s, 0, x);
      add_ok(m, s);
    }
  };
  go(200, 0.0);
  go(500, 0.040);
  go(400, 0.0);
  const SessionResult r = m.result();
  EXPECT_EQ(r.instruments[0].movements, 1U);
  // First moving sample k = 200; entry at k = 212; last moving k = 699; exit at 699 + 44.
  EXPECT_EQ(r.task_start_ns, time_of(212));
  EXPECT_NEAR(r.instruments[0].moving_time_s, (699 + 44 - 212) * kPeriodS, kTimeTolS);
}

// ---------------------------------------------------------------- force on tissue, damage

void set_force(CycleSample& s, std::size_t i, double magnitude_n, bool contact) {
  // Direction (0.6, 0, −0.8): the magnitude is what counts.
  s.instruments[i].tissue_force_n = {static_cast<float>(0.6 * magnitude_n), 0.0F,
                                     static_cast<float>(-0.8 * magnitude_n)};
  s.instruments[i].tissue_contact = contact ? 1 : 0;
}

TEST(SessionMetricsForce, StepProfileGivesExactPeakMeanAndTimesAboveThresholds) {
  // safe 2 N, damage 4 N (defaults). Samples: 100 at 1 N, 50 at 3 N, 20 at 5 N, 30 without
  // contact, 10 at 4.5 N. The contact point moves with k so the peak's location is checkable.
  SessionSetup setup = one_instrument_setup();
  SessionMetrics m = make_session(setup);
  struct Step {
    int samples;
    double force_n;
  };
  const std::vector<Step> steps = {{100, 1.0}, {50, 3.0}, {20, 5.0}, {30, 0.0}, {10, 4.5}};
  std::uint64_t k = 0;
  for (const Step& step : steps) {
    for (int j = 0; j < step.samples; ++j, ++k) {
      CycleSample s = sample_at(k);
      set_tip(s, 0, 0.01, 0.0, -0.1);
      set_force(s, 0, step.force_n, step.force_n > 0.0);
      s.instruments[0].contact_point_m = {static_cast<float>(k) * 1e-4F, 0.002F, -0.1F};
      s.contact_model = step.force_n > 0.0 ? 1 : -1;
      add_ok(m, s);
    }
  }
  const SessionResult r = m.result();
  const InstrumentMetrics& i = r.instruments[0];
  constexpr double kForceTol = 1e-5;  // float components of the force
  EXPECT_NEAR(i.peak_force_n, 5.0, kForceTol);
  EXPECT_EQ(i.peak_force_time_ns, time_of(150));
  EXPECT_NEAR(i.contact_time_s, 180 * kPeriodS, kTimeTolS);
  const double integral = (100 * 1.0 + 50 * 3.0 + 20 * 5.0 + 10 * 4.5) * kPeriodS;
  EXPECT_NEAR(i.force_integral_n_s, integral, 1e-7);
  EXPECT_NEAR(i.mean_contact_force_n, integral / (180 * kPeriodS), kForceTol);
  EXPECT_NEAR(i.mean_session_force_n, integral / (210 * kPeriodS), kForceTol);
  EXPECT_NEAR(i.time_above_safe_s, 80 * kPeriodS, kTimeTolS);
  EXPECT_NEAR(r.time_above_safe_s, 80 * kPeriodS, kTimeTolS);
  EXPECT_NEAR(i.damage.time_above_s, 30 * kPeriodS, kTimeTolS);
  EXPECT_NEAR(i.damage.impulse_n_s, (20 * 1.0 + 10 * 0.5) * kPeriodS, 1e-7);
  EXPECT_EQ(i.damage.events, 2U);
  ASSERT_TRUE(i.damage.has_peak);
  EXPECT_NEAR(i.damage.peak_force_n, 5.0, kForceTol);
  EXPECT_EQ(i.damage.peak_time_ns, time_of(150));
  EXPECT_NEAR(i.damage.peak_point_m[0], 150 * 1e-4, 1e-7);
  EXPECT_NEAR(i.damage.peak_point_m[1], 0.002, 1e-7);
  EXPECT_EQ(i.damage.peak_model, 1);
  ASSERT_TRUE(r.worst_damage.has_peak);
  EXPECT_EQ(r.worst_damage.peak_instrument, 0U);
  EXPECT_NEAR(r.damage_impulse_n_s, i.damage.impulse_n_s, 1e-12);
}

TEST(SessionMetricsForce, SessionTimeAboveSafeIsTheUnionOverInstruments) {
  // Two instruments above the safe force for 100 samples each, overlapping by 40: the
  // session counts 160 samples, each instrument 100; the worst damage is the right one's.
  SessionSetup setup = one_instrument_setup();
  setup.instrument_count = 2;
  SessionMetrics m = make_session(setup);
  for (std::uint64_t k = 0; k < 300; ++k) {
    CycleSample s = sample_at(k, 2);
    set_force(s, 0, (k >= 50 && k < 150) ? 3.0 : 0.0, k >= 50 && k < 150);
    set_force(s, 1, (k >= 110 && k < 210) ? (k == 180 ? 6.0 : 3.0) : 0.0, k >= 110 && k < 210);
    add_ok(m, s);
  }
  const SessionResult r = m.result();
  EXPECT_NEAR(r.instruments[0].time_above_safe_s, 100 * kPeriodS, kTimeTolS);
  EXPECT_NEAR(r.instruments[1].time_above_safe_s, 100 * kPeriodS, kTimeTolS);
  EXPECT_NEAR(r.time_above_safe_s, 160 * kPeriodS, kTimeTolS);
  EXPECT_NEAR(r.time_above_damage_s, 1 * kPeriodS, kTimeTolS);
  ASSERT_TRUE(r.worst_damage.has_peak);
  EXPECT_EQ(r.worst_damage.peak_instrument, 1U);
  EXPECT_EQ(r.worst_damage.peak_time_ns, time_of(180));
  EXPECT_FALSE(r.instruments[0].damage.has_peak);
}

// ---------------------------------------------------------------- grasp slips

TEST(SessionMetricsGrasp, GraspLostWithClosedJawsIsASlipAndOpeningIsARelease) {
  SessionMetrics m = make_session(one_instrument_setup());
  std::uint64_t k = 0;
  const auto step = [&](bool grasping, float grip_rad) {
    CycleSample s = sample_at(k++);
    s.instruments[0].grasping = grasping ? 1 : 0;
    s.instruments[0].grip_rad = grip_rad;
    add_ok(m, s);
  };
  for (int j = 0; j < 10; ++j) step(false, 0.5F);
  // Grasp 1: closes from 0.3 to 0.10 rad while holding, lost at 0.12 (within 0.05): a slip.
  for (int j = 0; j < 100; ++j) step(true, 0.3F - 0.002F * static_cast<float>(j));
  step(false, 0.12F);
  for (int j = 0; j < 50; ++j) step(false, 0.12F);
  // Grasp 2: held at 0.1, lost as the jaws open to 0.2 (0.1 above): a release.
  for (int j = 0; j < 200; ++j) step(true, 0.1F);
  step(false, 0.2F);
  const InstrumentMetrics i = m.result().instruments[0];
  EXPECT_EQ(i.grasps, 2U);
  EXPECT_EQ(i.slips, 1U);
  EXPECT_NEAR(i.grasp_time_s, 300 * kPeriodS, kTimeTolS);
}

// ---------------------------------------------------------------- insertion and task time

TEST(SessionMetricsInsertion, DepthRampGivesDepthReachedAndTimeToTarget) {
  // The tip starts moving at k = 500 (20 mm/s, window one period); the catheter
  // depth ramps 20 µm per sample from k = 1000 and passes the 9.99 mm target at k = 1500
  // (9.98 mm at 1499, 10.00 at 1500). Motion after the target is reached is not counted.
  SessionSetup setup = one_instrument_setup();
  setup.thresholds.speed_window_s = 1e-3;
  setup.insertion_target_depth_m = 0.00999;
  SessionMetrics m = make_session(setup);
  double x = 0.0;
  for (std::uint64_t k = 0; k < 2500; ++k) {
    if (k >= 500) x += 0.02 * kPeriodS;
    CycleSample s = sample_at(k);
    set_tip(s, 0, x);
    s.insertion_depth_m = k >= 1000 ? static_cast<float>(2e-5 * static_cast<double>(k - 1000)) : 0.0F;
    add_ok(m, s);
  }
  const SessionResult r = m.result();
  ASSERT_TRUE(r.insertion.present);
  EXPECT_TRUE(r.insertion.target_reached);
  EXPECT_EQ(r.insertion.target_time_ns, time_of(1500));
  EXPECT_EQ(r.task_start_ns, time_of(500));
  EXPECT_TRUE(r.task_completed);
  EXPECT_EQ(r.task_end_ns, time_of(1500));
  EXPECT_NEAR(r.task_time_s, 1.0, kTimeTolS);
  EXPECT_NEAR(r.insertion.time_to_target_s, 1.0, kTimeTolS);
  EXPECT_NEAR(r.insertion.max_depth_m, 2e-5 * 1499, 1e-8);
  EXPECT_EQ(r.insertion.max_depth_time_ns, time_of(2499));
  // Path: 1001 steps of 20 µm, k = 500 to 1500; the movement ends with the task.
  EXPECT_NEAR(r.instruments[0].path_length_m, 1001 * 0.02 * kPeriodS, kLengthTolM);
  EXPECT_EQ(r.instruments[0].movements, 1U);
  EXPECT_NEAR(r.instruments[0].moving_time_s, 1.0, kTimeTolS);
}

TEST(SessionMetricsInsertion, NoCatheterLeavesInsertionAbsentAndTaskEndsWithSession) {
  SessionSetup setup = one_instrument_setup();
  setup.insertion_target_depth_m = 0.01;  // a goal, but no depth ever measured
  SessionMetrics m = make_session(setup);
  for (std::uint64_t k = 0; k < 100; ++k) add_ok(m, sample_at(k));  // depth NaN
  const SessionResult r = m.result();
  EXPECT_FALSE(r.insertion.present);
  EXPECT_FALSE(r.insertion.target_reached);
  EXPECT_FALSE(r.task_started);
  EXPECT_EQ(r.task_time_s, 0.0);
}

// ---------------------------------------------------------------- edge cases

TEST(SessionMetricsEdge, EmptySessionIsAllZero) {
  const SessionResult r = make_session(one_instrument_setup()).result();
  EXPECT_EQ(r.samples, 0U);
  EXPECT_EQ(r.session_time_s, 0.0);
  EXPECT_FALSE(r.task_started);
  EXPECT_EQ(r.instruments[0].path_length_m, 0.0);
  EXPECT_EQ(r.instruments[0].mean_session_force_n, 0.0);
  EXPECT_FALSE(r.instruments[0].motion_economy.has_value());
  EXPECT_FALSE(r.insertion.present);
  EXPECT_FALSE(r.worst_damage.has_peak);
}

TEST(SessionMetricsEdge, OneSampleLastsOnePeriod) {
  SessionMetrics m = make_session(one_instrument_setup());
  CycleSample s = sample_at(0);
  set_tip(s, 0, 0.05);
  set_force(s, 0, 3.0, true);
  add_ok(m, s);
  const SessionResult r = m.result();
  EXPECT_EQ(r.samples, 1U);
  EXPECT_NEAR(r.session_time_s, kPeriodS, kTimeTolS);
  EXPECT_NEAR(r.instruments[0].time_above_safe_s, kPeriodS, kTimeTolS);
  EXPECT_EQ(r.instruments[0].path_length_m, 0.0);
  EXPECT_FALSE(r.task_started);
}

TEST(SessionMetricsEdge, BadSamplesAreRefusedAndChangeNothing) {
  // The same session with and without bad samples interleaved gives the same metrics.
  SessionSetup setup = one_instrument_setup();
  setup.instrument_count = 2;
  SessionMetrics clean = make_session(setup);
  SessionMetrics dirty = make_session(setup);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  for (std::uint64_t k = 0; k < 400; ++k) {
    CycleSample s = sample_at(k, 2);
    set_tip(s, 0, 0.03 * kPeriodS * static_cast<double>(k));
    set_force(s, 1, k > 100 ? 4.5 : 0.0, k > 100);
    add_ok(clean, s);
    add_ok(dirty, s);
    if (k % 50 == 7) {
      CycleSample bad = s;
      bad.time_ns += kPeriodNs / 2;
      bad.instruments[0].tip_m[1] = nan;
      EXPECT_EQ(dirty.add(bad).code(), core::StatusCode::numeric_error);
      bad = s;
      bad.time_ns += kPeriodNs / 2;
      bad.instruments[1].tissue_force_n[2] = inf;
      EXPECT_EQ(dirty.add(bad).code(), core::StatusCode::numeric_error);
      if (s.instruments[1].tissue_contact != 0) {  // a contact point is read only then
        bad = s;
        bad.time_ns += kPeriodNs / 2;
        bad.instruments[1].contact_point_m[0] = nan;
        EXPECT_EQ(dirty.add(bad).code(), core::StatusCode::numeric_error);
      }
      bad = s;
      bad.time_ns += kPeriodNs / 2;
      bad.insertion_depth_m = -inf;
      EXPECT_EQ(dirty.add(bad).code(), core::StatusCode::numeric_error);
      bad = s;  // same time as the last accepted sample
      EXPECT_EQ(dirty.add(bad).code(), core::StatusCode::invalid_argument);
      bad = s;
      bad.time_ns += kPeriodNs / 2;
      bad.instrument_count = 1;
      EXPECT_EQ(dirty.add(bad).code(), core::StatusCode::invalid_argument);
    }
  }
  const SessionResult a = clean.result();
  const SessionResult b = dirty.result();
  // k = 7, 57, ..., 357: five refusals each, and the contact point on the six with contact.
  EXPECT_EQ(b.refused_samples, 8U * 5U + 6U);
  EXPECT_EQ(a.samples, b.samples);
  EXPECT_EQ(a.session_time_s, b.session_time_s);
  EXPECT_EQ(a.instruments[0].path_length_m, b.instruments[0].path_length_m);
  EXPECT_EQ(a.instruments[1].damage.impulse_n_s, b.instruments[1].damage.impulse_n_s);
  EXPECT_EQ(a.task_start_ns, b.task_start_ns);
}

TEST(SessionMetricsEdge, AddAndResultDoNotAllocate) {
  SessionSetup setup = one_instrument_setup();
  setup.instrument_count = 4;
  setup.insertion_target_depth_m = 0.01;
  SessionMetrics m = make_session(setup);
  std::vector<CycleSample> samples;
  for (std::uint64_t k = 0; k < 5000; ++k) {
    CycleSample s = sample_at(k, 4);
    for (std::size_t i = 0; i < 4; ++i) {
      set_tip(s, i, 0.01 * std::sin(static_cast<double>(k + i) * 0.01), 0.0, -0.1);
      set_force(s, i, 5.0 * std::fabs(std::sin(static_cast<double>(k) * 0.003)), true);
      s.instruments[i].grasping = (k / 300) % 2 == 0 ? 1 : 0;
    }
    s.insertion_depth_m = static_cast<float>(k) * 3e-6F;
    samples.push_back(s);
  }
  ASSERT_TRUE(core::alloc::hooks_installed());
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  std::uint32_t movements = 0;
  for (const CycleSample& s : samples) {
    (void)m.add(s);
    movements += m.result().instruments[0].movements;
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
  EXPECT_GT(movements, 0U);
  EXPECT_EQ(m.result().samples, 5000U);
}

// ---------------------------------------------------------------- invariants

TEST(SessionMetricsInvariants, RandomSessionsKeepEveryInvariant) {
  // 200 random sessions (fixed seed): random walks of up to four tips with pauses and jumps,
  // random forces, contacts, grasps, insertion depths, irregular periods and bad samples mixed
  // in. After every sample: every figure finite, times within the session, per instrument
  // moving + idle = task time, economy in (0, 1], damage within the time above the safe force.
  std::uint64_t state = 0x9E3779B97F4A7C15ULL;
  const auto next = [&state] {
    state ^= state << 13U;
    state ^= state >> 7U;
    state ^= state << 17U;
    return state;
  };
  const auto uniform = [&next](double low, double high) {
    return low + (high - low) * static_cast<double>(next() >> 11U) * 0x1.0p-53;
  };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::uint64_t checked = 0;
  // What the sessions reached, so the invariants are known to be exercised.
  std::uint64_t movements = 0, slips = 0, damage_events = 0, targets = 0, refused = 0;
  for (int session = 0; session < 200; ++session) {
    SessionSetup setup;
    setup.period_ns = 1'000'000;
    setup.instrument_count = static_cast<std::uint32_t>(1 + next() % 4);
    setup.thresholds.speed_window_s = uniform(0.001, 0.2);
    setup.thresholds.min_movement_s = uniform(0.0, 0.3);
    setup.thresholds.path_deadband_m = uniform(0.0, 5e-4);
    if (next() % 2 == 0) setup.insertion_target_depth_m = uniform(0.001, 0.02);
    SessionMetrics m = make_session(setup);
    std::array<std::array<double, 3>, 4> tip{};
    std::array<std::array<double, 3>, 4> velocity{};
    std::int64_t time_ns = 0;
    double depth = 0.0;
    const int samples = static_cast<int>(next() % 3000);
    for (int k = 0; k < samples; ++k) {
      time_ns += 1'000'000 + static_cast<std::int64_t>(next() % 3) * 1'000'000 * (next() % 50 == 0);
      CycleSample s;
      s.time_ns = time_ns;
      s.instrument_count = setup.instrument_count;
      s.insertion_depth_m = next() % 3 == 0 ? nan : static_cast<float>(depth += uniform(-2e-5, 5e-5));
      s.contact_model = static_cast<std::int32_t>(next() % 4) - 1;
      for (std::size_t i = 0; i < setup.instrument_count; ++i) {
        if (next() % 200 == 0) {
          for (double& v : velocity[i]) v = next() % 3 == 0 ? 0.0 : uniform(-0.1, 0.1);
        }
        for (std::size_t a = 0; a < 3; ++a) tip[i][a] += velocity[i][a] * 1e-3 + uniform(-4e-5, 4e-5);
        set_tip(s, i, tip[i][0], tip[i][1], tip[i][2]);
        set_force(s, i, uniform(0.0, 1.0) < 0.5 ? 0.0 : uniform(0.0, 8.0), next() % 2 == 0);
        s.instruments[i].contact_point_m = s.instruments[i].tip_m;
        s.instruments[i].grasping = (static_cast<std::size_t>(k / 97) + i) % 3 == 0 ? 1 : 0;
        s.instruments[i].grip_rad = static_cast<float>(uniform(0.0, 0.6));
      }
      if (next() % 100 == 0) s.instruments[0].tip_m[next() % 3] = nan;  // refused
      (void)m.add(s);
      if (k % 97 != 0 && k != samples - 1) continue;
      const SessionResult r = m.result();
      ++checked;
      if (k == samples - 1) {
        targets += r.insertion.target_reached ? 1U : 0U;
        refused += r.refused_samples;
        for (std::size_t i = 0; i < setup.instrument_count; ++i) {
          movements += r.instruments[i].movements;
          slips += r.instruments[i].slips;
          damage_events += r.instruments[i].damage.events;
        }
      }
      ASSERT_TRUE(std::isfinite(r.session_time_s) && std::isfinite(r.task_time_s));
      ASSERT_LE(r.task_time_s, r.session_time_s + 1e-9);
      ASSERT_LE(r.time_above_damage_s, r.time_above_safe_s + 1e-9);
      ASSERT_LE(r.time_above_safe_s, r.session_time_s + 1e-9);
      for (std::size_t i = 0; i < setup.instrument_count; ++i) {
        const InstrumentMetrics& im = r.instruments[i];
        ASSERT_TRUE(std::isfinite(im.path_length_m) && im.path_length_m >= 0.0);
        ASSERT_NEAR(im.moving_time_s + im.idle_time_s, r.task_time_s, 1e-6)
            << "session " << session << " sample " << k << " instrument " << i;
        if (im.motion_economy) {
          ASSERT_GT(*im.motion_economy, 0.0);
          ASSERT_LE(*im.motion_economy, 1.0);
        }
        ASSERT_LE(im.damage.time_above_s, im.time_above_safe_s + 1e-9);
        ASSERT_LE(im.contact_time_s, r.session_time_s + 1e-9);
        ASSERT_LE(im.grasp_time_s, r.session_time_s + 1e-9);
        ASSERT_LE(im.slips, im.grasps);
        ASSERT_TRUE(std::isfinite(im.mean_contact_force_n) && std::isfinite(im.damage.impulse_n_s));
      }
    }
  }
  EXPECT_GT(checked, 1000U);
  EXPECT_GT(movements, 100U);
  EXPECT_GT(slips, 10U);
  EXPECT_GT(damage_events, 100U);
  EXPECT_GT(targets, 10U);
  EXPECT_GT(refused, 100U);
  std::printf("checked %llu results: %llu movements, %llu slips, %llu damage events, %llu targets "
              "reached, %llu samples refused\n",
              static_cast<unsigned long long>(checked), static_cast<unsigned long long>(movements),
              static_cast<unsigned long long>(slips),
              static_cast<unsigned long long>(damage_events),
              static_cast<unsigned long long>(targets), static_cast<unsigned long long>(refused));
}

// ---------------------------------------------------------------- setup errors

TEST(SessionMetricsSetup, InconsistentThresholdsAreRefusedWithTheKey) {
  const auto error_of = [](const SessionSetup& setup) {
    auto created = SessionMetrics::create(setup);
    return created ? std::string() : created.error().message;
  };
  SessionSetup s = one_instrument_setup();
  s.thresholds.damage_force_n = 1.0;  // below safe 2 N
  EXPECT_EQ(error_of(s), "metrics.damage_force_n = 1: expected a finite force at least safe_force_n (2 N)");
  s = one_instrument_setup();
  s.thresholds.movement_stop_speed_m_per_s = 0.02;
  EXPECT_EQ(error_of(s),
            "metrics.movement_stop_speed_m_per_s = 0.02: expected a speed above 0 and at most "
            "movement_start_speed_m_per_s (0.01 m/s)");
  s = one_instrument_setup();
  s.thresholds.speed_window_s = 1.0;  // 1000 periods of 1 ms
  EXPECT_EQ(error_of(s), "metrics.speed_window_s = 1: expected at most 512 loop periods of 1000000 ns");
  s = one_instrument_setup();
  s.instrument_count = 0;
  EXPECT_EQ(error_of(s), "metrics: instrument_count = 0: expected 1 to 4");
  s = one_instrument_setup();
  s.thresholds.path_deadband_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(error_of(s), "metrics.path_deadband_m = nan: expected a finite length of at least 0 m");
  s = one_instrument_setup();
  EXPECT_EQ(error_of(s), "");
  EXPECT_EQ(make_session(s).speed_window_samples(), 50U);
}

}  // namespace
}  // namespace trainer::metrics
