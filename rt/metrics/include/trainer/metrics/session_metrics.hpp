// SessionMetrics: the trainee metrics of one session (docs/metrics.md), accumulated one
// CycleSample at a time so the same code runs live (a non-RT thread reading the cycle's
// samples), over a recording, on a replay and in the viewer. add() is noexcept, allocation
// free and O(instruments); result() can be called at any time and gives the metrics as if the
// session ended with the last accepted sample.
//
// Time: sample k stands for the cycle interval (t[k-1], t[k]] of length dt[k] = t[k] − t[k-1];
// the first sample's dt is the loop period. Every "time" metric is a sum of those dt over the
// samples it selects, so a profile built on a fixed period is exact to the sample.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>

#include "trainer/core/expected.hpp"
#include "trainer/core/status.hpp"
#include "trainer/metrics/cycle_sample.hpp"
#include "trainer/metrics/thresholds.hpp"

namespace trainer::metrics {

using Point = std::array<double, 3>;

struct SessionSetup {
  MetricsThresholds thresholds{};
  std::int64_t period_ns = 1'000'000;  // loop period (> 0): dt of the first sample
  std::uint32_t instrument_count = 1;  // 1..kMaxSampleInstruments, every sample must match
  // The scene's [model.insertion] target_depth_m; empty when it has none (the task then ends
  // with the session).
  std::optional<double> insertion_target_depth_m{};
};

// Force above damage_force_n (docs/metrics.md "Tissue damage").
struct DamageMetrics {
  double time_above_s = 0.0;  // time with |F| > damage_force_n
  double impulse_n_s = 0.0;   // ∫ (|F| − damage_force_n) dt over that time
  std::uint32_t events = 0;   // separate episodes above the threshold
  bool has_peak = false;      // the fields below are valid (some sample exceeded it)
  double peak_force_n = 0.0;  // largest |F| above the threshold
  std::int64_t peak_time_ns = 0;
  Point peak_point_m{};          // contact_point_m at the peak (tip_m if no contact flagged)
  std::int32_t peak_model = -1;  // CycleSample::contact_model at the peak
  std::uint32_t peak_instrument = 0;  // session level: which instrument
};

struct InstrumentMetrics {
  // Motion (session start → task end; movements and idle within the task window).
  double path_length_m = 0.0;
  std::uint32_t movements = 0;
  double moving_time_s = 0.0;  // inside counted movements
  double idle_time_s = 0.0;    // task window minus counted movements
  // Σ straight-line distance start→end of counted movements / Σ their path length, in (0, 1];
  // empty when no movement has a path.
  std::optional<double> motion_economy{};
  // Force on tissue |tissue_force_n| (whole session).
  double peak_force_n = 0.0;
  std::int64_t peak_force_time_ns = 0;
  double contact_time_s = 0.0;           // samples with tissue_contact
  double mean_contact_force_n = 0.0;     // ∫|F|dt over contact time / contact time (0 if none)
  double mean_session_force_n = 0.0;     // ∫|F|dt / session time
  double force_integral_n_s = 0.0;       // ∫|F|dt
  double time_above_safe_s = 0.0;        // |F| > safe_force_n
  DamageMetrics damage{};
  // Grasps of a catheter.
  std::uint32_t grasps = 0;
  std::uint32_t slips = 0;  // grasp lost with the jaws still closed
  double grasp_time_s = 0.0;
};

struct InsertionMetrics {
  bool present = false;             // some accepted sample had a finite insertion depth
  double max_depth_m = 0.0;
  std::int64_t max_depth_time_ns = 0;
  std::optional<double> target_depth_m{};
  bool target_reached = false;
  std::int64_t target_time_ns = 0;  // first sample with depth ≥ target
  double time_to_target_s = 0.0;    // target_time − task start (session start if no motion)
};

struct SessionResult {
  std::uint64_t samples = 0;          // accepted
  std::uint64_t refused_samples = 0;  // refused by add() (not used)
  std::int64_t first_time_ns = 0;
  std::int64_t last_time_ns = 0;
  double session_time_s = 0.0;  // Σ dt of accepted samples
  double faulted_time_s = 0.0;  // samples with latched_faults ≠ 0
  // Task: first motion of any instrument → insertion target reached, else the last sample.
  bool task_started = false;
  bool task_completed = false;  // ended by reaching the insertion target
  std::int64_t task_start_ns = 0;
  std::int64_t task_end_ns = 0;
  double task_time_s = 0.0;
  // Session level: time any instrument is above the threshold (not a sum over instruments).
  double time_above_safe_s = 0.0;
  double time_above_damage_s = 0.0;
  double damage_impulse_n_s = 0.0;  // sum over instruments
  DamageMetrics worst_damage{};     // the instrument peak with the largest force
  std::uint32_t instrument_count = 0;
  std::array<InstrumentMetrics, kMaxSampleInstruments> instruments{};
  InsertionMetrics insertion{};
};

class SessionMetrics {
 public:
  // Setup path: checks the thresholds and the setup (each message names the key of the
  // scene's [metrics] table or the setup field and the expected range).
  static core::Expected<SessionMetrics> create(const SessionSetup& setup);

  // One cycle. Refused (counted in refused_samples, nothing else changes): instrument_count
  // different from the setup's (invalid_argument), time_ns not after the previous accepted
  // sample (invalid_argument), a non-finite tip, force or grip, a non-finite contact point
  // with tissue_contact set, or an infinite insertion depth (numeric_error). NaN insertion depth
  // is "no catheter depth this cycle", not an error.
  core::Status add(const CycleSample& sample) noexcept;

  SessionResult result() const noexcept;
  const SessionSetup& setup() const noexcept { return setup_; }
  std::size_t speed_window_samples() const noexcept { return window_samples_; }

 private:
  struct TipHistoryEntry {
    std::array<double, 3> tip_m{};
    std::int64_t time_ns = 0;
  };
  struct InstrumentState {
    std::array<TipHistoryEntry, kMaxSpeedWindowSamples + 1> history{};
    std::size_t history_next = 0;   // ring index of the next write
    std::size_t history_count = 0;  // valid entries (≤ window + 1)
    Point last_tip_m{};
    // Path with deadband: `anchor` is the last counted point.
    Point anchor_m{};
    double path_committed_m = 0.0;
    // Movement segmentation.
    bool moving = false;
    double episode_s = 0.0;
    Point episode_start_tip_m{};
    double episode_start_path_m = 0.0;
    double chord_sum_m = 0.0;
    double movement_path_sum_m = 0.0;
    // Force.
    bool above_damage = false;
    double contact_force_integral_n_s = 0.0;
    // Grasp.
    bool grasping = false;
    float min_grip_rad = 0.0F;
    InstrumentMetrics metrics{};
  };

  explicit SessionMetrics(const SessionSetup& setup, std::size_t window_samples) noexcept;
  static core::Status check_sample(const CycleSample& sample, std::uint32_t instrument_count,
                                   bool have_previous, std::int64_t previous_time_ns) noexcept;
  double window_speed(InstrumentState& state, const Point& tip, std::int64_t time_ns) noexcept;
  void update_motion(InstrumentState& state, const InstrumentSample& in, std::int64_t time_ns,
                     double dt_s, bool in_task_window, bool first_sample) noexcept;
  // Returns kAboveSafe | kAboveDamage for this instrument's sample.
  std::uint8_t update_force(InstrumentState& state, const InstrumentSample& in,
                            std::int32_t contact_model, std::int64_t time_ns, double dt_s) noexcept;
  static constexpr std::uint8_t kAboveSafe = 1;
  static constexpr std::uint8_t kAboveDamage = 2;
  void update_grasp(InstrumentState& state, const InstrumentSample& in, double dt_s) noexcept;
  static double path_to(const InstrumentState& state, const Point& tip) noexcept;
  // Ends the open movement episode of `state` into `metrics` and the economy sums (a counted
  // movement, or idle time if shorter than min_movement_s); the caller clears `moving`.
  void close_episode(const InstrumentState& state, InstrumentMetrics& metrics, double& chord_sum_m,
                     double& movement_path_sum_m) const noexcept;
  void end_episode(InstrumentState& state) noexcept;

  SessionSetup setup_{};
  std::size_t window_samples_ = 1;
  std::array<InstrumentState, kMaxSampleInstruments> instruments_{};
  SessionResult result_{};
  bool have_previous_ = false;
  std::int64_t previous_time_ns_ = 0;
  bool task_window_closed_ = false;  // task ended (target reached): motion metrics frozen
};

}  // namespace trainer::metrics
