// The thresholds of the trainee metrics: the scene's [metrics] table (docs/config.md), here
// as plain numbers with their defaults so that rt/config (which reads them) and SessionMetrics
// (which uses them) share one definition. What each one does: docs/metrics.md.
#pragma once

#include <cstddef>
#include <cstdint>

namespace trainer::metrics {

struct MetricsThresholds {  // [metrics]
  // Force on tissue (|tissue_force_n| of an instrument): above safe_force_n counts as time
  // above the safe force; above damage_force_n counts towards the damage measure.
  // damage_force_n >= safe_force_n.
  double safe_force_n = 2.0;
  double damage_force_n = 4.0;
  // Movement segmentation on the tip speed averaged over speed_window_s: a movement starts
  // when the speed reaches movement_start_speed_m_per_s and ends when it falls below
  // movement_stop_speed_m_per_s (< start: hysteresis); episodes shorter than
  // min_movement_s are not counted as movements (their time counts as idle).
  double movement_start_speed_m_per_s = 0.010;
  double movement_stop_speed_m_per_s = 0.005;
  double min_movement_s = 0.10;
  double speed_window_s = 0.050;
  // Path length counts tip motion only once the tip has left a ball of this radius around
  // the last counted point, so encoder quantisation jitter (one count at the tip is ~37 µm on
  // the sim device's 0.36 m shaft) adds nothing. 0 = every sample counts.
  double path_deadband_m = 1.0e-4;
  // A grasp lost while the jaws are no more than this above the smallest opening held during
  // the grasp is a slip (the catheter was pulled out); a larger opening is a release.
  double grasp_open_tolerance_rad = 0.05;
};

// The speed window holds at most this many samples (the window in loop periods; rt/config
// refuses a [metrics] speed_window_s longer than this many of its loop periods).
inline constexpr std::size_t kMaxSpeedWindowSamples = 512;

}  // namespace trainer::metrics
