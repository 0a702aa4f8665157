#include "trainer/app/stream_metrics.hpp"

#include <algorithm>

namespace trainer::app {
namespace {

std::uint16_t saturated_u16(std::uint32_t value) noexcept {
  return static_cast<std::uint16_t>(std::min<std::uint32_t>(value, 0xFFFFU));
}

}  // namespace

telemetry::SessionMetrics stream_metrics(const metrics::SessionResult& r) noexcept {
  telemetry::SessionMetrics m;
  if (r.task_started) m.flags |= telemetry::kMetricsTaskStarted;
  if (r.task_completed) m.flags |= telemetry::kMetricsTaskCompleted;
  if (r.insertion.target_depth_m) m.flags |= telemetry::kMetricsInsertionGoal;
  if (r.insertion.target_reached) m.flags |= telemetry::kMetricsTargetReached;
  m.session_time_s = static_cast<float>(r.session_time_s);
  m.task_time_s = static_cast<float>(r.task_time_s);
  m.time_above_safe_s = static_cast<float>(r.time_above_safe_s);
  m.damage_impulse_n_s = static_cast<float>(r.damage_impulse_n_s);
  m.insertion_depth_m = r.insertion.present ? static_cast<float>(r.insertion.max_depth_m) : 0.0F;
  m.time_to_target_s =
      r.insertion.target_reached ? static_cast<float>(r.insertion.time_to_target_s) : 0.0F;
  const std::size_t count = std::min<std::size_t>(r.instrument_count, telemetry::kMaxInstruments);
  m.instrument_count = static_cast<std::uint8_t>(count);
  for (std::size_t i = 0; i < count; ++i) {
    const metrics::InstrumentMetrics& in = r.instruments[i];
    telemetry::InstrumentMetrics& out = m.instruments[i];
    out.path_length_m = static_cast<float>(in.path_length_m);
    out.idle_time_s = static_cast<float>(in.idle_time_s);
    out.peak_force_n = static_cast<float>(in.peak_force_n);
    out.mean_contact_force_n = static_cast<float>(in.mean_contact_force_n);
    out.time_above_safe_s = static_cast<float>(in.time_above_safe_s);
    out.movements = saturated_u16(in.movements);
    out.grasps = saturated_u16(in.grasps);
    out.slips = saturated_u16(in.slips);
  }
  return m;
}

}  // namespace trainer::app
