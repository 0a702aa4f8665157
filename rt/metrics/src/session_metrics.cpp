// SessionMetrics: definitions in docs/metrics.md; the order of the updates in add() is part of
// them (an interval is classified by the state before its closing sample).
#include "trainer/metrics/session_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

namespace trainer::metrics {

namespace {

constexpr double kSecondsPerNanosecond = 1e-9;

Point to_point(const std::array<float, 3>& v) noexcept {
  return {static_cast<double>(v[0]), static_cast<double>(v[1]), static_cast<double>(v[2])};
}

double distance_m(const Point& a, const Point& b) noexcept {
  const double dx = a[0] - b[0];
  const double dy = a[1] - b[1];
  const double dz = a[2] - b[2];
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

double magnitude(const std::array<float, 3>& v) noexcept {
  return distance_m(to_point(v), Point{});
}

bool all_finite(const std::array<float, 3>& v) noexcept {
  return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]);
}

std::string number_text(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%g", value);
  return buffer;
}

}  // namespace

core::Expected<SessionMetrics> SessionMetrics::create(const SessionSetup& setup) {
  const MetricsThresholds& t = setup.thresholds;
  const auto fail = [](const std::string& key, double value, const std::string& expected) {
    return core::make_error("metrics." + key + " = " + number_text(value) + ": expected " +
                            expected);
  };
  if (setup.instrument_count < 1 || setup.instrument_count > kMaxSampleInstruments) {
    return core::make_error("metrics: instrument_count = " +
                            std::to_string(setup.instrument_count) + ": expected 1 to " +
                            std::to_string(kMaxSampleInstruments));
  }
  if (setup.period_ns <= 0) {
    return core::make_error("metrics: period_ns = " + std::to_string(setup.period_ns) +
                            ": expected more than 0");
  }
  if (!(std::isfinite(t.safe_force_n) && t.safe_force_n > 0.0)) {
    return fail("safe_force_n", t.safe_force_n, "a finite force above 0 N");
  }
  if (!(std::isfinite(t.damage_force_n) && t.damage_force_n >= t.safe_force_n)) {
    return fail("damage_force_n", t.damage_force_n,
                "a finite force at least safe_force_n (" + number_text(t.safe_force_n) + " N)");
  }
  if (!(std::isfinite(t.movement_start_speed_m_per_s) && t.movement_start_speed_m_per_s > 0.0)) {
    return fail("movement_start_speed_m_per_s", t.movement_start_speed_m_per_s,
                "a finite speed above 0 m/s");
  }
  if (!(std::isfinite(t.movement_stop_speed_m_per_s) && t.movement_stop_speed_m_per_s > 0.0 &&
        t.movement_stop_speed_m_per_s <= t.movement_start_speed_m_per_s)) {
    return fail("movement_stop_speed_m_per_s", t.movement_stop_speed_m_per_s,
                "a speed above 0 and at most movement_start_speed_m_per_s (" +
                    number_text(t.movement_start_speed_m_per_s) + " m/s)");
  }
  if (!(std::isfinite(t.min_movement_s) && t.min_movement_s >= 0.0)) {
    return fail("min_movement_s", t.min_movement_s, "a finite duration of at least 0 s");
  }
  if (!(std::isfinite(t.path_deadband_m) && t.path_deadband_m >= 0.0)) {
    return fail("path_deadband_m", t.path_deadband_m, "a finite length of at least 0 m");
  }
  if (!(std::isfinite(t.grasp_open_tolerance_rad) && t.grasp_open_tolerance_rad >= 0.0)) {
    return fail("grasp_open_tolerance_rad", t.grasp_open_tolerance_rad,
                "a finite angle of at least 0 rad");
  }
  if (!(std::isfinite(t.speed_window_s) && t.speed_window_s > 0.0)) {
    return fail("speed_window_s", t.speed_window_s, "a finite duration above 0 s");
  }
  const double window_periods =
      std::round(t.speed_window_s / (static_cast<double>(setup.period_ns) * kSecondsPerNanosecond));
  if (window_periods > static_cast<double>(kMaxSpeedWindowSamples)) {
    return fail("speed_window_s", t.speed_window_s,
                "at most " + std::to_string(kMaxSpeedWindowSamples) + " loop periods of " +
                    std::to_string(setup.period_ns) + " ns");
  }
  if (setup.insertion_target_depth_m &&
      !(std::isfinite(*setup.insertion_target_depth_m) && *setup.insertion_target_depth_m > 0.0)) {
    return fail("insertion target_depth_m", *setup.insertion_target_depth_m,
                "a finite depth above 0 m");
  }
  const auto window_samples = static_cast<std::size_t>(std::max(1.0, window_periods));
  return SessionMetrics(setup, window_samples);
}

SessionMetrics::SessionMetrics(const SessionSetup& setup, std::size_t window_samples) noexcept
    : setup_(setup), window_samples_(window_samples) {
  result_.instrument_count = setup.instrument_count;
  result_.insertion.target_depth_m = setup.insertion_target_depth_m;
}

core::Status SessionMetrics::check_sample(const CycleSample& sample,
                                          std::uint32_t instrument_count, bool have_previous,
                                          std::int64_t previous_time_ns) noexcept {
  if (sample.instrument_count != instrument_count) {
    return {core::StatusCode::invalid_argument, "sample instrument_count differs from the setup"};
  }
  if (have_previous && sample.time_ns <= previous_time_ns) {
    return {core::StatusCode::invalid_argument, "sample time_ns not after the previous sample"};
  }
  for (std::size_t i = 0; i < instrument_count; ++i) {
    const InstrumentSample& in = sample.instruments[i];
    if (!all_finite(in.tip_m) || !all_finite(in.tissue_force_n) || !std::isfinite(in.grip_rad)) {
      return {core::StatusCode::numeric_error, "non-finite tip, force or grip in a sample"};
    }
    if (in.tissue_contact != 0 && !all_finite(in.contact_point_m)) {
      return {core::StatusCode::numeric_error, "non-finite contact point in a sample"};
    }
  }
  if (std::isinf(sample.insertion_depth_m)) {
    return {core::StatusCode::numeric_error, "infinite insertion depth in a sample"};
  }
  return core::Status::ok();
}

double SessionMetrics::path_to(const InstrumentState& state, const Point& tip) noexcept {
  return state.path_committed_m + distance_m(tip, state.anchor_m);
}

double SessionMetrics::window_speed(InstrumentState& state, const Point& tip,
                                    std::int64_t time_ns) noexcept {
  const std::size_t capacity = window_samples_ + 1;
  state.history[state.history_next] = TipHistoryEntry{tip, time_ns};
  state.history_next = (state.history_next + 1) % capacity;
  state.history_count = std::min(state.history_count + 1, capacity);
  if (state.history_count < 2) return 0.0;
  const std::size_t oldest = (state.history_next + capacity - state.history_count) % capacity;
  const TipHistoryEntry& old = state.history[oldest];
  // Displacement over the window: while fewer than window + 1 samples exist (the session's
  // start) the span is still taken as the full window, so the first samples cannot make a
  // speed out of one count of jitter over one period.
  const double span_s = std::max(static_cast<double>(time_ns - old.time_ns) * kSecondsPerNanosecond,
                                 setup_.thresholds.speed_window_s);
  return distance_m(tip, old.tip_m) / span_s;
}

void SessionMetrics::close_episode(const InstrumentState& state, InstrumentMetrics& metrics,
                                   double& chord_sum_m, double& movement_path_sum_m) const noexcept {
  if (state.episode_s >= setup_.thresholds.min_movement_s && state.episode_s > 0.0) {
    ++metrics.movements;
    metrics.moving_time_s += state.episode_s;
    chord_sum_m += distance_m(state.last_tip_m, state.episode_start_tip_m);
    movement_path_sum_m += path_to(state, state.last_tip_m) - state.episode_start_path_m;
  } else {
    metrics.idle_time_s += state.episode_s;
  }
}

void SessionMetrics::end_episode(InstrumentState& state) noexcept {
  close_episode(state, state.metrics, state.chord_sum_m, state.movement_path_sum_m);
  state.episode_s = 0.0;
  state.moving = false;
}

void SessionMetrics::update_motion(InstrumentState& state, const InstrumentSample& in,
                                   std::int64_t time_ns, double dt_s, bool in_task_window,
                                   bool first_sample) noexcept {
  const Point tip = to_point(in.tip_m);
  // The interval that ends with this sample belongs to the state before it.
  if (in_task_window) {
    if (state.moving) {
      state.episode_s += dt_s;
    } else {
      state.metrics.idle_time_s += dt_s;
    }
  }
  // Path with a deadband around the last counted point (docs/metrics.md "Path length").
  if (first_sample) {
    state.anchor_m = tip;
  } else {
    const double step_m = distance_m(tip, state.anchor_m);
    if (step_m > 0.0 && step_m >= setup_.thresholds.path_deadband_m) {
      state.path_committed_m += step_m;
      state.anchor_m = tip;
    }
  }
  state.last_tip_m = tip;
  const double speed = window_speed(state, tip, time_ns);
  if (!state.moving && speed >= setup_.thresholds.movement_start_speed_m_per_s) {
    state.moving = true;
    state.episode_s = 0.0;
    state.episode_start_tip_m = tip;
    state.episode_start_path_m = path_to(state, tip);
  } else if (state.moving && speed < setup_.thresholds.movement_stop_speed_m_per_s) {
    end_episode(state);
  }
}

std::uint8_t SessionMetrics::update_force(InstrumentState& state, const InstrumentSample& in,
                                          std::int32_t contact_model, std::int64_t time_ns,
                                          double dt_s) noexcept {
  InstrumentMetrics& m = state.metrics;
  const MetricsThresholds& t = setup_.thresholds;
  const double force_n = magnitude(in.tissue_force_n);
  std::uint8_t flags = 0;
  m.force_integral_n_s += force_n * dt_s;
  if (force_n > m.peak_force_n) {
    m.peak_force_n = force_n;
    m.peak_force_time_ns = time_ns;
  }
  if (in.tissue_contact != 0) {
    m.contact_time_s += dt_s;
    state.contact_force_integral_n_s += force_n * dt_s;
  }
  if (force_n > t.safe_force_n) {
    m.time_above_safe_s += dt_s;
    flags |= kAboveSafe;
  }
  if (force_n > t.damage_force_n) {
    flags |= kAboveDamage;
    DamageMetrics& d = m.damage;
    d.time_above_s += dt_s;
    d.impulse_n_s += (force_n - t.damage_force_n) * dt_s;
    if (!state.above_damage) ++d.events;
    state.above_damage = true;
    if (!d.has_peak || force_n > d.peak_force_n) {
      d.has_peak = true;
      d.peak_force_n = force_n;
      d.peak_time_ns = time_ns;
      d.peak_point_m = to_point(in.tissue_contact != 0 ? in.contact_point_m : in.tip_m);
      d.peak_model = contact_model;
    }
  } else {
    state.above_damage = false;
  }
  return flags;
}

void SessionMetrics::update_grasp(InstrumentState& state, const InstrumentSample& in,
                                  double dt_s) noexcept {
  InstrumentMetrics& m = state.metrics;
  const bool grasping = in.grasping != 0;
  if (grasping) m.grasp_time_s += dt_s;
  if (grasping && !state.grasping) {
    ++m.grasps;
    state.min_grip_rad = in.grip_rad;
  } else if (grasping) {
    state.min_grip_rad = std::min(state.min_grip_rad, in.grip_rad);
  } else if (state.grasping) {
    const double opened_rad =
        static_cast<double>(in.grip_rad) - static_cast<double>(state.min_grip_rad);
    if (opened_rad <= setup_.thresholds.grasp_open_tolerance_rad) ++m.slips;
  }
  state.grasping = grasping;
}

core::Status SessionMetrics::add(const CycleSample& sample) noexcept {
  if (const core::Status check =
          check_sample(sample, setup_.instrument_count, have_previous_, previous_time_ns_);
      !check) {
    ++result_.refused_samples;
    return check;
  }
  const bool first_sample = !have_previous_;
  const std::int64_t dt_ns = first_sample ? setup_.period_ns : sample.time_ns - previous_time_ns_;
  const double dt_s = static_cast<double>(dt_ns) * kSecondsPerNanosecond;
  if (first_sample) result_.first_time_ns = sample.time_ns;
  result_.last_time_ns = sample.time_ns;
  ++result_.samples;
  result_.session_time_s += dt_s;
  if (sample.latched_faults != 0) result_.faulted_time_s += dt_s;

  const bool in_task_window = result_.task_started && !task_window_closed_;
  std::uint8_t any_flags = 0;
  bool any_moving = false;
  for (std::size_t i = 0; i < setup_.instrument_count; ++i) {
    InstrumentState& state = instruments_[i];
    const InstrumentSample& in = sample.instruments[i];
    if (!task_window_closed_) {
      update_motion(state, in, sample.time_ns, dt_s, in_task_window, first_sample);
      any_moving = any_moving || state.moving;
    }
    const std::uint8_t flags = update_force(state, in, sample.contact_model, sample.time_ns, dt_s);
    any_flags = static_cast<std::uint8_t>(any_flags | flags);
    update_grasp(state, in, dt_s);
  }
  if ((any_flags & kAboveSafe) != 0) result_.time_above_safe_s += dt_s;
  if ((any_flags & kAboveDamage) != 0) result_.time_above_damage_s += dt_s;
  if (!result_.task_started && any_moving) {
    result_.task_started = true;
    result_.task_start_ns = sample.time_ns;
  }

  InsertionMetrics& insertion = result_.insertion;
  const double depth_m = static_cast<double>(sample.insertion_depth_m);
  if (std::isfinite(depth_m)) {
    if (!insertion.present || depth_m > insertion.max_depth_m) {
      insertion.max_depth_m = depth_m;
      insertion.max_depth_time_ns = sample.time_ns;
    }
    insertion.present = true;
    // Compared in the sample's float precision, as the cycle compares its depth with the
    // target: a depth equal to the target as a float has reached it.
    if (insertion.target_depth_m && !insertion.target_reached &&
        sample.insertion_depth_m >= static_cast<float>(*insertion.target_depth_m)) {
      insertion.target_reached = true;
      insertion.target_time_ns = sample.time_ns;
      const std::int64_t from_ns =
          result_.task_started ? result_.task_start_ns : result_.first_time_ns;
      insertion.time_to_target_s =
          static_cast<double>(sample.time_ns - from_ns) * kSecondsPerNanosecond;
      if (!task_window_closed_) {
        // The task is done: close open movements and freeze the motion metrics.
        task_window_closed_ = true;
        result_.task_completed = true;
        result_.task_end_ns = sample.time_ns;
        for (std::size_t i = 0; i < setup_.instrument_count; ++i) {
          InstrumentState& state = instruments_[i];
          if (state.moving) end_episode(state);
        }
      }
    }
  }
  have_previous_ = true;
  previous_time_ns_ = sample.time_ns;
  return core::Status::ok();
}

SessionResult SessionMetrics::result() const noexcept {
  SessionResult out = result_;
  DamageMetrics worst{};
  for (std::size_t i = 0; i < setup_.instrument_count; ++i) {
    const InstrumentState& state = instruments_[i];
    InstrumentMetrics m = state.metrics;
    double chord_sum_m = state.chord_sum_m;
    double movement_path_sum_m = state.movement_path_sum_m;
    // An open movement is closed tentatively, as if the session ended here.
    if (state.moving) close_episode(state, m, chord_sum_m, movement_path_sum_m);
    m.path_length_m = path_to(state, state.last_tip_m);
    if (movement_path_sum_m > 0.0) {
      m.motion_economy = std::min(1.0, chord_sum_m / movement_path_sum_m);
    }
    m.mean_contact_force_n =
        m.contact_time_s > 0.0 ? state.contact_force_integral_n_s / m.contact_time_s : 0.0;
    m.mean_session_force_n =
        out.session_time_s > 0.0 ? m.force_integral_n_s / out.session_time_s : 0.0;
    out.damage_impulse_n_s += m.damage.impulse_n_s;
    if (m.damage.has_peak && (!worst.has_peak || m.damage.peak_force_n > worst.peak_force_n)) {
      worst = m.damage;
      worst.peak_instrument = static_cast<std::uint32_t>(i);
    }
    out.instruments[i] = m;
  }
  out.worst_damage = worst;
  if (out.task_started) {
    if (!out.task_completed) out.task_end_ns = out.last_time_ns;
    out.task_time_s = static_cast<double>(out.task_end_ns - out.task_start_ns) * kSecondsPerNanosecond;
  }
  return out;
}

}  // namespace trainer::metrics
