#include "trainer/metrics/metrics_report.hpp"

#include <cstddef>
#include <cstdio>

namespace trainer::metrics {

namespace {

nlohmann::json model_name_json(std::int32_t model, std::span<const std::string> model_names) {
  if (model < 0) return nullptr;
  const auto index = static_cast<std::size_t>(model);
  if (index < model_names.size()) return model_names[index];
  return model;
}

nlohmann::json peak_json(const DamageMetrics& d, std::span<const std::string> model_names) {
  if (!d.has_peak) return nullptr;
  return {{"force_n", d.peak_force_n},
          {"time_ns", d.peak_time_ns},
          {"point_m", d.peak_point_m},
          {"model", model_name_json(d.peak_model, model_names)}};
}

nlohmann::json thresholds_json(const MetricsThresholds& t) {
  return {{"safe_force_n", t.safe_force_n},
          {"damage_force_n", t.damage_force_n},
          {"movement_start_speed_m_per_s", t.movement_start_speed_m_per_s},
          {"movement_stop_speed_m_per_s", t.movement_stop_speed_m_per_s},
          {"min_movement_s", t.min_movement_s},
          {"speed_window_s", t.speed_window_s},
          {"path_deadband_m", t.path_deadband_m},
          {"grasp_open_tolerance_rad", t.grasp_open_tolerance_rad}};
}

nlohmann::json instrument_json(const InstrumentMetrics& m, const std::string& name,
                               std::span<const std::string> model_names) {
  return {{"name", name},
          {"path_length_m", m.path_length_m},
          {"movements", m.movements},
          {"moving_time_s", m.moving_time_s},
          {"idle_time_s", m.idle_time_s},
          {"motion_economy", m.motion_economy ? nlohmann::json(*m.motion_economy) : nullptr},
          {"peak_force_n", m.peak_force_n},
          {"peak_force_time_ns", m.peak_force_time_ns},
          {"contact_time_s", m.contact_time_s},
          {"mean_contact_force_n", m.mean_contact_force_n},
          {"mean_session_force_n", m.mean_session_force_n},
          {"force_integral_n_s", m.force_integral_n_s},
          {"time_above_safe_s", m.time_above_safe_s},
          {"damage",
           {{"time_above_s", m.damage.time_above_s},
            {"impulse_n_s", m.damage.impulse_n_s},
            {"events", m.damage.events},
            {"peak", peak_json(m.damage, model_names)}}},
          {"grasps", m.grasps},
          {"slips", m.slips},
          {"grasp_time_s", m.grasp_time_s}};
}

}  // namespace

nlohmann::json metrics_json(const SessionResult& r, const MetricsThresholds& thresholds,
                            std::span<const std::string> instrument_names,
                            std::span<const std::string> model_names) {
  nlohmann::json instruments = nlohmann::json::array();
  for (std::size_t i = 0; i < r.instrument_count && i < r.instruments.size(); ++i) {
    const std::string name =
        i < instrument_names.size() ? instrument_names[i] : std::to_string(i);
    instruments.push_back(instrument_json(r.instruments[i], name, model_names));
  }
  nlohmann::json worst = peak_json(r.worst_damage, model_names);
  if (!worst.is_null()) {
    const std::size_t i = r.worst_damage.peak_instrument;
    worst["instrument"] = i < instrument_names.size() ? instrument_names[i] : std::to_string(i);
  }
  nlohmann::json insertion = nullptr;
  if (r.insertion.present) {
    const InsertionMetrics& in = r.insertion;
    insertion = {{"max_depth_m", in.max_depth_m},
                 {"max_depth_time_ns", in.max_depth_time_ns},
                 {"target_depth_m", in.target_depth_m ? nlohmann::json(*in.target_depth_m) : nullptr},
                 {"target_reached", in.target_reached},
                 {"target_time_ns", in.target_reached ? nlohmann::json(in.target_time_ns) : nullptr},
                 {"time_to_target_s",
                  in.target_reached ? nlohmann::json(in.time_to_target_s) : nullptr}};
  }
  return {{"thresholds", thresholds_json(thresholds)},
          {"samples", r.samples},
          {"refused_samples", r.refused_samples},
          {"session_time_s", r.session_time_s},
          {"faulted_time_s", r.faulted_time_s},
          {"task",
           {{"started", r.task_started},
            {"completed", r.task_completed},
            {"start_ns", r.task_started ? nlohmann::json(r.task_start_ns) : nullptr},
            {"end_ns", r.task_started ? nlohmann::json(r.task_end_ns) : nullptr},
            {"time_s", r.task_time_s}}},
          {"time_above_safe_s", r.time_above_safe_s},
          {"time_above_damage_s", r.time_above_damage_s},
          {"damage_impulse_n_s", r.damage_impulse_n_s},
          {"worst_damage", worst},
          {"instruments", instruments},
          {"insertion", insertion}};
}

namespace {

std::string formatted(const char* format, double a, double b = 0.0, double c = 0.0) {
  char buffer[160];
  std::snprintf(buffer, sizeof buffer, format, a, b, c);
  return buffer;
}

}  // namespace

std::string metrics_summary(const SessionResult& r, std::span<const std::string> instrument_names) {
  std::string text = "metrics: ";
  if (!r.task_started) {
    text += "no motion";
  } else {
    text += formatted("task %.2f s", r.task_time_s);
    if (r.task_completed && r.insertion.target_depth_m) {
      text += formatted(" (insertion target %.1f mm reached)", *r.insertion.target_depth_m * 1e3);
    }
  }
  text += formatted(", above safe force %.2f s", r.time_above_safe_s);
  if (r.worst_damage.has_peak) {
    const std::size_t i = r.worst_damage.peak_instrument;
    text += formatted(", damage %.2f s, %.3f N·s, peak %.2f N", r.time_above_damage_s,
                      r.damage_impulse_n_s, r.worst_damage.peak_force_n);
    text += " (" + (i < instrument_names.size() ? instrument_names[i] : std::to_string(i)) + ")";
  } else {
    text += ", no damage";
  }
  if (r.insertion.present) {
    text += formatted(", insertion depth %.1f mm", r.insertion.max_depth_m * 1e3);
  }
  if (r.refused_samples > 0) text += ", " + std::to_string(r.refused_samples) + " samples refused";
  text += "\n";
  for (std::size_t i = 0; i < r.instrument_count && i < r.instruments.size(); ++i) {
    const InstrumentMetrics& m = r.instruments[i];
    text += "  " + (i < instrument_names.size() ? instrument_names[i] : std::to_string(i)) + ": ";
    text += formatted("path %.1f mm, ", m.path_length_m * 1e3);
    text += "movements " + std::to_string(m.movements);
    text += formatted(", idle %.2f s", m.idle_time_s);
    if (m.motion_economy) text += formatted(", economy %.2f", *m.motion_economy);
    text += formatted(", peak %.2f N, mean in contact %.2f N", m.peak_force_n, m.mean_contact_force_n);
    text += ", grasps " + std::to_string(m.grasps) + " (slips " + std::to_string(m.slips) + ")\n";
  }
  return text;
}

}  // namespace trainer::metrics
