#include "trainer/app/report.hpp"
#include "trainer/app/rt_self_check.hpp"

#include <cstdio>
#include <sstream>

#include "trainer/metrics/metrics_report.hpp"
#include "report_compute.hpp"

namespace trainer::app {

namespace {

const char* model_kind_text(config::ModelKind kind) {
  switch (kind) {
    case config::ModelKind::modal_shell: return "modal_shell";
    case config::ModelKind::catheter: return "catheter";
    case config::ModelKind::tet_tensor: return "tet_tensor";
  }
  return "unknown";
}

nlohmann::json percentiles(const core::LatencyHistogram& histogram) {
  return {
      {"count", histogram.count()},
      {"min", histogram.min_ns()},
      {"p50", histogram.percentile_ns(0.50)},
      {"p99", histogram.percentile_ns(0.99)},
      {"p99_9", histogram.percentile_ns(0.999)},
      {"max", histogram.max_ns()},
      {"mean", histogram.mean_ns()},
  };
}

std::string microseconds(std::int64_t ns) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.1f", static_cast<double>(ns) * 1e-3);
  return buffer;
}

std::string microseconds_of_seconds(double seconds) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.2f", seconds * 1e6);
  return buffer;
}

std::string latency_line(const char* label, const core::LatencyHistogram& h) {
  return std::string(label) + " p50 " + microseconds(h.percentile_ns(0.5)) + "  p99 " +
         microseconds(h.percentile_ns(0.99)) + "  p99.9 " + microseconds(h.percentile_ns(0.999)) +
         "  max " + microseconds(h.max_ns()) + " us";
}

}  // namespace

// The cycle's phases (HapticApp's CyclePhase), each with its percentiles: where the step time goes.
nlohmann::json step_split(const AppStats& app) {
  nlohmann::json split = nlohmann::json::object();
  for (std::size_t phase = 0; phase < kCyclePhaseCount; ++phase) {
    split[kCyclePhaseNames[phase]] = percentiles(app.phase_ns[phase]);
  }
  return split;
}

namespace {

// The sub-stages of the stages the scene runs (substage_timer.hpp), each with its percentiles.
nlohmann::json substage_split(const AppStats& app) {
  nlohmann::json split = nlohmann::json::object();
  for (std::size_t substage = 0; substage < kSubstageCount; ++substage) {
    if (app.substage_ns[substage].count() == 0) continue;
    split[kSubstageNames[substage]] = percentiles(app.substage_ns[substage]);
  }
  return split;
}

nlohmann::json instruments_json(const RunResult& r) {
  nlohmann::json instruments = nlohmann::json::array();
  for (std::size_t i = 0; i < r.instrument_names.size(); ++i) {
    const InstrumentStats& s = r.app.instruments[i];
    instruments.push_back({
        {"name", r.instrument_names[i]},
        {"peak_force_n", s.peak_force_n},
        {"mean_contact_force_n",
         s.contact_cycles > 0 ? s.force_sum_n / static_cast<double>(s.contact_cycles) : 0.0},
        {"peak_depth_m", s.peak_depth_m},
        {"contact_cycles", s.contact_cycles},
        {"contact_onsets", s.contact_onsets},
        {"wall_segment_contact_cycles", s.wall_segment_contact_cycles},
        {"peak_joint_effort",
         {{"pitch_nm", s.peak_joint_effort[0]},
          {"yaw_nm", s.peak_joint_effort[1]},
          {"insertion_n", s.peak_joint_effort[2]},
          {"roll_nm", s.peak_joint_effort[3]},
          {"grip_nm", s.peak_joint_effort[4]}}},
        {"catheter",
         {{"contact_cycles", s.catheter_contact_cycles},
          {"grasps", s.grasps},
          {"slips", s.slips},
          {"grasping_cycles", s.grasping_cycles},
          {"peak_squeeze_n", s.peak_squeeze_n}}},
    });
  }
  return instruments;
}

void add_catheter_fields(const LoadedModelInfo& m, const CatheterStats& c, nlohmann::json& entry) {
  entry.update({{"particle_count", m.particle_count},
                {"stable_substep_s", m.stable_substep_s},
                {"substeps_per_period", m.substeps_per_period},
                {"max_substeps", m.max_substeps},
                {"hold_start", m.hold_start}});
  entry["wall_contact_cycles"] = c.wall_contact_cycles;
  entry["dropped_contacts"] = c.dropped_contacts;
  if (m.has_insertion_goal) {
    entry["insertion"] = {
        {"depth_m", c.insertion_depth_m},           {"peak_depth_m", c.peak_insertion_depth_m},
        {"peak_held_depth_m", c.peak_held_depth_m}, {"target_depth_m", m.insertion_target_depth_m},
        {"target_reached", c.target_reached},       {"first_target_cycle", c.first_target_cycle}};
  }
  if (!m.final_positions_m.empty()) {
    entry["final_root_position_m"] = m.final_positions_m.front();
    entry["final_tip_position_m"] = m.final_positions_m.back();
  }
}

void add_tensor_fields(const LoadedModelInfo& m, const TensorModelStats& t, nlohmann::json& entry) {
  entry.update({{"contact_node_count", m.contact_node_count},
                {"stored_node_count", m.stored_node_count},
                {"max_contacts", m.max_contacts},
                {"quasi_nonlinear", m.quasi_nonlinear}});
  entry["load"] = {
      {"peak_force_n", t.peak_force_n},
      {"mean_force_n",
       t.loaded_cycles > 0 ? t.force_sum_n / static_cast<double>(t.loaded_cycles) : 0.0},
      {"loaded_cycles", t.loaded_cycles},
      {"contact_onsets", t.contact_onsets},
      {"peak_contact_nodes", t.peak_contact_nodes},
      {"peak_indentation_m", t.peak_indentation_m},
      {"refused_solves", t.refused_solves}};
}

void add_modal_fields(const LoadedModelInfo& m, const ModalModelStats& d, nlohmann::json& entry) {
  entry.update({{"mode_count", m.mode_count},
                {"static_correction", m.static_correction},
                {"prepared_time_step_s", m.prepared_time_step_s}});
  entry["load"] = {
      {"peak_force_n", d.peak_force_n},
      {"mean_force_n",
       d.loaded_cycles > 0 ? d.force_sum_n / static_cast<double>(d.loaded_cycles) : 0.0},
      {"loaded_cycles", d.loaded_cycles},
      {"tool_contact_cycles", d.tool_contact_cycles},
      {"catheter_contact_cycles", d.catheter_contact_cycles},
      {"peak_catheter_contacts", d.peak_catheter_contacts},
      {"peak_catheter_force_n", d.peak_catheter_force_n}};
}

nlohmann::json models_json(const RunResult& r) {
  std::size_t modal_index = 0;
  std::size_t tensor_index = 0;
  std::size_t catheter_index = 0;
  nlohmann::json models = nlohmann::json::array();
  for (const LoadedModelInfo& m : r.models) {
    // Every kind: what it is, where it came from, what it costs, where the scene put it.
    nlohmann::json entry = {{"name", m.name},
                            {"kind", model_kind_text(m.kind)},
                            {"definition", m.definition_path},
                            {"arena_bytes", m.arena_bytes},
                            {"position_m", m.position_m},
                            {"rotation_deg", m.rotation_deg}};
    // Every kind is loaded from its image.
    entry.update({{"image", m.image_path},
                  {"image_checksum", m.image_checksum},
                  {"image_bytes", m.image_bytes}});
    if (m.kind == config::ModelKind::catheter) {
      add_catheter_fields(m, r.app.catheters[catheter_index++], entry);
    } else {
      entry["node_count"] = m.node_count;
      if (m.kind == config::ModelKind::tet_tensor) {
        add_tensor_fields(m, r.app.tensor_models[tensor_index++], entry);
      } else {
        add_modal_fields(m, r.app.modal_models[modal_index++], entry);
      }
    }
    models.push_back(std::move(entry));
  }
  return models;
}

// The telemetry stream to the graphics host (null when [telemetry] is off).
nlohmann::json telemetry_stream_json(const RunResult& r) {
  if (!r.telemetry_stream) return nullptr;
  const TelemetrySenderStats& t = *r.telemetry_stream;
  return {{"destination", t.destination},
          {"rate_hz", t.rate_hz},
          {"source_port", t.source_port},
          {"stream_id", t.stream_id},
          {"frames_sent", t.frames_sent},
          {"send_errors", t.send_errors},
          {"refused", t.refused},
          {"buffer_full", t.buffer_full},
          {"other_errors", t.other_errors},
          {"last_errno", t.last_errno},
          {"encode_errors", t.encode_errors},
          {"stale_skipped", t.stale_skipped},
          {"trimmed", t.trimmed},
          {"over_budget", t.over_budget},
          {"frame_bytes", {{"min", t.bytes_min}, {"p50", t.bytes_p50}, {"max", t.bytes_max}}}};
}

// The USB link as the host saw it (backend usb only; null otherwise).
nlohmann::json usb_json(const RunResult& r) {
  if (!r.usb) return nullptr;
  const hal::libusb::UsbDiagnostics& u = *r.usb;
  const hal::libusb::UsbFrameCounters& f = u.frames;
  const auto us = [](std::int64_t ns) { return static_cast<double>(ns) * 1e-3; };
  nlohmann::json lost = nullptr;
  if (u.lost_reported) {
    lost = {{"source", u.lost_source},
            {"reported_at_cycle", u.lost_report_cycle},
            {"latched_at_cycle", u.lost_latch_cycle},
            {"reported_ns", u.lost_report_ns},
            {"latched_ns", u.lost_latch_ns},
            {"latch_delay_us", u.lost_latch_ns > 0 ? us(u.lost_latch_ns - u.lost_report_ns) : -1.0}};
  }
  return {{"serial", u.serial},
          {"speed", u.speed},
          {"firmware_version", u.firmware_version},
          {"protocol_version", u.protocol_version},
          {"channels", u.device_channels},
          {"watchdog_ms", u.watchdog_ms},
          {"max_current_ma", u.max_current_ma},
          {"in_endpoint", u.in_endpoint},
          {"out_endpoint", u.out_endpoint},
          {"max_packet", u.max_packet},
          {"interval", u.interval},
          {"hotplug", u.hotplug},
          {"cycles", f.cycles},
          {"in_reports_used", f.in_reports_used},
          {"stale_frames", f.stale_frames},
          {"not_due_cycles", f.not_due_cycles},
          {"stale_run_max", f.stale_run_max},
          {"missed_frames", f.missed_frames},
          {"in_superseded", f.in_superseded},
          {"bad_reports", f.bad_reports},
          {"out_published", f.out_published},
          {"out_submitted", u.out_submitted},
          {"out_superseded", u.out_superseded},
          {"in_completed", u.in_completed},
          {"out_completed", u.out_completed},
          {"transfer_errors", u.transfer_errors},
          {"acks", f.acks},
          {"acks_unmatched", f.acks_unmatched},
          {"watchdog_reports", f.watchdog_reports},
          {"current_limited_reports", f.current_limited_cycles},
          {"out_rejected_reports", f.out_rejected_reports},
          {"round_trip_us",
           {{"count", u.round_trips},
            {"min", us(u.round_trip_min_ns)},
            {"p50", us(u.round_trip_p50_ns)},
            {"p99", us(u.round_trip_p99_ns)},
            {"p999", us(u.round_trip_p999_ns)},
            {"max", us(u.round_trip_max_ns)},
            {"mean", u.round_trip_mean_ns * 1e-3}}},
          {"device_lost", lost},
          {"shutdown_acknowledged", u.shutdown_acknowledged},
          {"faults", r.usb_faults}};
}

// The CAN bus as the master saw it (backend canopen only; null otherwise).
nlohmann::json can_json(const RunResult& r) {
  if (!r.can) return nullptr;
  const hal::socketcan::CanDiagnostics& c = *r.can;
  return {{"bus_load_estimate", c.bus_load},
          {"sync_sent", c.sync_sent},
          {"rpdo_sent", c.rpdo_sent},
          {"tpdo_received", c.tpdo_received},
          {"heartbeats_received", c.heartbeats_received},
          {"emcy_received", c.emcy_received},
          {"error_frames", c.error_frames},
          {"frames_rejected", c.frames_rejected},
          {"stale_samples", c.stale_samples},
          {"cycles_frame_budget_hit", c.cycles_frame_budget_hit},
          {"faults", r.can_faults},
          {"transport",
           {{"rx_frames", c.transport.rx_frames},
            {"rx_error_frames", c.transport.rx_error_frames},
            {"rx_kernel_drops", c.transport.rx_kernel_drops},
            {"rx_malformed", c.transport.rx_malformed},
            {"tx_frames", c.transport.tx_frames},
            {"tx_dropped", c.transport.tx_dropped},
            {"io_errors", c.transport.io_errors},
            {"rx_calls", c.transport.rx_calls},
            {"tx_calls", c.transport.tx_calls}}}};
}

}  // namespace

namespace {

// The trainee metrics (docs/metrics.md) with the thresholds they were computed with; null when
// the run computed none.
nlohmann::json metrics_section_json(const RunResult& r) {
  if (!r.metrics) return nullptr;
  std::vector<std::string> model_names;
  for (const LoadedModelInfo& m : r.models) model_names.push_back(m.name);
  nlohmann::json section =
      metrics::metrics_json(*r.metrics, r.metrics_thresholds, r.instrument_names, model_names);
  section["refused_samples"] = r.metrics_refused_samples;
  section["dropped_cycles"] = r.recording_dropped_cycles;
  return section;
}

}  // namespace

nlohmann::json report_json(const RunResult& r) {
  nlohmann::json fault_counts = nlohmann::json::object();
  for (const auto& [name, count] : r.fault_counts) fault_counts[name] = count;

  return {
      {"schema_version", kReportSchemaVersion},
      {"scene", {{"file", r.scene_file.string()}, {"name", r.scene_name}}},
      {"hal", r.hal},
      {"device_file", r.device_file.string()},
      {"time_source", r.time_source},
      {"slow_motion", r.slow_motion},
      {"period_ns", r.period_ns},
      {"requested_cycles", r.requested_cycles},
      {"cycles", r.loop.cycles},
      {"wall_time_s", r.wall_time_s},
      {"stopped_by_signal", r.stopped_by_signal},
      {"overruns", r.loop.overruns},
      {"longest_overrun_streak", r.loop.longest_overrun_streak},
      {"skipped_periods", r.loop.skipped_periods},
      {"cycle_errors", r.loop.cycle_errors},
      {"wake_latency_ns", percentiles(r.loop.wake_latency)},
      {"step_time_ns", percentiles(r.loop.step_time)},
      {"step_split_ns", step_split(r.app)},
      {"step_substages_ns", substage_split(r.app)},
      {"period_measured_ns", percentiles(r.loop.period)},
      {"memory",
       {{"heap_allocations_after_arming", r.heap_allocations_after_arming},
        {"allocation_counting",
         r.allocation_hooks_installed
             ? (r.malloc_family_counted ? "operator new and malloc family"
                                        : "operator new only (sanitizer build)")
             : "not measured (allocation hooks not linked)"},
        {"arena_bytes_used", r.arena_bytes_used},
        {"arena_bytes_capacity", r.arena_bytes_capacity}}},
      {"rt",
       {{"policy", r.rt.policy},
        {"priority", r.rt.priority},
        {"cpu", r.rt.cpu},
        {"memory_locked", r.rt.memory_locked},
        {"cpu_dma_latency_us", r.rt.cpu_dma_latency_us},
        {"preempt_rt", r.rt.preempt_rt},
        {"kernel_release", r.rt.kernel_release},
        {"kernel_version", r.rt.kernel_version},
        {"warnings", r.rt.warnings},
        {"self_check", rt_check_json(r.rt_check)}}},
      {"safety",
       {{"faults_latched_at_end", r.latched_faults},
        {"first_fault", r.first_fault},
        {"first_fault_cycle", r.first_fault_cycle},
        {"fault_counts", fault_counts},
        {"arm_count", r.arm_count},
        {"force_clamped_cycles", r.force_clamped_cycles},
        {"force_slew_limited_cycles", r.force_slew_limited_cycles},
        {"effort_limited_cycles", r.app.effort_limited_cycles},
        {"outputs_zeroed_at_exit", r.outputs_zeroed_at_exit}}},
      {"hal_errors",
       {{"read", r.app.hal_read_errors},
        {"write", r.app.hal_write_errors},
        {"invalid_encoder_cycles", r.app.invalid_encoder_cycles},
        {"saturated_actuator_cycles", r.app.saturated_actuator_cycles}}},
      {"armed_cycles", r.app.armed_cycles},
      {"instruments", instruments_json(r)},
      {"models", models_json(r)},
      {"model_step_errors", r.app.model_step_errors},
      {"log_records_dropped", r.log_records_dropped},
      {"recording", r.recording_file.empty()
                        ? nlohmann::json(nullptr)
                        : nlohmann::json{{"file", r.recording_file},
                                         {"cycles", r.recorded_cycles},
                                         {"bytes", r.recording_bytes},
                                         {"dropped_cycles", r.recording_dropped_cycles},
                                         {"error", r.recording_error}}},
      {"metrics", metrics_section_json(r)},
      {"can", can_json(r)},
      {"usb", usb_json(r)},
      {"telemetry", telemetry_stream_json(r)},
      {"compute", compute_section_json(r)},
  };
}

namespace {

void summarize_catheter(const RunResult& r, const LoadedModelInfo& m, const CatheterStats& c,
                        std::ostream& out) {
  if (m.has_insertion_goal) {
    out << "  model '" << m.name << "': insertion depth " << c.insertion_depth_m * 1e3F
        << " mm (peak " << c.peak_insertion_depth_m * 1e3F << " mm, held in the jaws "
        << c.peak_held_depth_m * 1e3F << " mm, target " << m.insertion_target_depth_m * 1e3
        << " mm: " << (c.target_reached ? "reached" : "NOT reached") << "), wall contact cycles "
        << c.wall_contact_cycles << "\n";
  }
  out << "  model '" << m.name << "': catheter, " << m.particle_count << " particles, largest substep "
      << microseconds_of_seconds(m.stable_substep_s) << " us, " << m.substeps_per_period
      << " substeps per " << microseconds(r.period_ns) << " us period (budget " << m.max_substeps
      << "), " << (m.hold_start ? "held at the introducer" : "free start") << ", image "
      << m.image_bytes << " bytes, arena " << m.arena_bytes << " bytes\n";
}

void summarize_tensor(const LoadedModelInfo& m, const TensorModelStats& t, std::ostream& out) {
  if (t.loaded_cycles > 0) {
    out << "  model '" << m.name << "': peak force " << t.peak_force_n << " N, mean "
        << t.force_sum_n / static_cast<double>(t.loaded_cycles) << " N over " << t.loaded_cycles
        << " loaded cycles, " << t.contact_onsets << " contact(s), peak indentation "
        << t.peak_indentation_m * 1e3F << " mm on up to " << t.peak_contact_nodes << " nodes\n";
  }
  out << "  model '" << m.name << "': tensor model, " << m.node_count << " nodes, "
      << m.contact_node_count << " contact nodes, up to " << m.max_contacts
      << " contacts, quasi-non-linear " << (m.quasi_nonlinear ? "on" : "off") << ", image "
      << m.image_bytes << " bytes, arena " << m.arena_bytes << " bytes\n";
}

void summarize_modal(const LoadedModelInfo& m, const ModalModelStats& d, std::ostream& out) {
  if (d.loaded_cycles > 0) {
    out << "  model '" << m.name << "': peak force " << d.peak_force_n << " N, mean "
        << d.force_sum_n / static_cast<double>(d.loaded_cycles) << " N over " << d.loaded_cycles
        << " loaded cycles (tools " << d.tool_contact_cycles << ", catheter "
        << d.catheter_contact_cycles << ", at most " << d.peak_catheter_contacts
        << " catheter contacts)\n";
  }
  out << "  model '" << m.name << "': " << m.node_count << " nodes, " << m.mode_count
      << " modes, static correction " << (m.static_correction ? "on" : "off") << ", image "
      << m.image_bytes << " bytes, arena " << m.arena_bytes << " bytes\n";
}

void summarize_timing(const RunResult& r, std::ostream& out) {
  out << "  " << latency_line("wake-up latency:", r.loop.wake_latency) << "\n";
  out << "  " << latency_line("step time:      ", r.loop.step_time) << "\n";
  out << "  step split p50/p99/p99.9 us:";
  for (std::size_t phase = 0; phase < kCyclePhaseCount; ++phase) {
    const core::LatencyHistogram& h = r.app.phase_ns[phase];
    if (h.count() == 0) continue;  // a stage this scene does not run
    out << " " << kCyclePhaseNames[phase] << " " << microseconds(h.percentile_ns(0.5)) << "/"
        << microseconds(h.percentile_ns(0.99)) << "/" << microseconds(h.percentile_ns(0.999));
  }
  out << "\n";
  bool any_substage = false;
  for (std::size_t substage = 0; substage < kSubstageCount; ++substage) {
    const core::LatencyHistogram& h = r.app.substage_ns[substage];
    if (h.count() == 0) continue;
    if (!any_substage) out << "  sub-stages p50/p99/p99.9 us:";
    any_substage = true;
    out << " " << kSubstageNames[substage] << " " << microseconds(h.percentile_ns(0.5)) << "/"
        << microseconds(h.percentile_ns(0.99)) << "/" << microseconds(h.percentile_ns(0.999));
  }
  if (any_substage) out << "\n";
  out << "  overruns " << r.loop.overruns << ", longest streak " << r.loop.longest_overrun_streak
      << ", skipped periods " << r.loop.skipped_periods << "\n";
}

void summarize_rt(const RunResult& r, std::ostream& out) {
  out << "  heap allocations after arming: " << r.heap_allocations_after_arming
      << (r.allocation_hooks_installed ? "" : " (not measured)") << "; arena " << r.arena_bytes_used
      << " of " << r.arena_bytes_capacity << " bytes\n";
  out << "  rt: " << r.rt.policy << " priority " << r.rt.priority << ", cpu "
      << (r.rt.cpu < 0 ? std::string("any") : std::to_string(r.rt.cpu)) << ", mlock "
      << (r.rt.memory_locked ? "yes" : "no") << ", cpu wake-up latency "
      << (r.rt.cpu_dma_latency_us < 0 ? std::string("default")
                                      : std::to_string(r.rt.cpu_dma_latency_us) + " us")
      << ", kernel " << r.rt.kernel_release
      << (r.rt.preempt_rt ? " (PREEMPT_RT)" : " (not PREEMPT_RT)") << "\n";
  for (const std::string& warning : r.rt.warnings) out << "  warning: " << warning << "\n";
}

void summarize_instruments(const RunResult& r, std::ostream& out) {
  for (std::size_t i = 0; i < r.instrument_names.size(); ++i) {
    const InstrumentStats& s = r.app.instruments[i];
    out << "  instrument '" << r.instrument_names[i] << "': peak force " << s.peak_force_n
        << " N, peak depth " << s.peak_depth_m * 1e3F << " mm, contact cycles " << s.contact_cycles;
    if (s.grasps > 0 || s.catheter_contact_cycles > 0) {
      out << ", catheter contact cycles " << s.catheter_contact_cycles << ", grasps " << s.grasps
          << " (slips " << s.slips << "), peak squeeze " << s.peak_squeeze_n << " N";
    }
    out << "\n";
  }
}

}  // namespace

std::string report_summary(const RunResult& r) {
  std::ostringstream out;
  out << "trainer: scene '" << r.scene_name << "' on hal '" << r.hal << "' (" << r.time_source
      << " time)\n";
  out << "  cycles " << r.loop.cycles << " at " << microseconds(r.period_ns) << " us period, "
      << "wall time " << r.wall_time_s << " s"
      << (r.stopped_by_signal ? " (stopped by signal)" : "") << "\n";
  summarize_timing(r, out);
  summarize_compute_section(r, out);
  summarize_rt(r, out);
  summarize_instruments(r, out);
  std::size_t text_modal = 0;
  std::size_t text_tensor = 0;
  std::size_t text_catheter = 0;
  for (const LoadedModelInfo& m : r.models) {
    if (m.kind == config::ModelKind::catheter) {
      summarize_catheter(r, m, r.app.catheters[text_catheter++], out);
    } else if (m.kind == config::ModelKind::tet_tensor) {
      summarize_tensor(m, r.app.tensor_models[text_tensor++], out);
    } else {
      summarize_modal(m, r.app.modal_models[text_modal++], out);
    }
  }
  out << "  safety: armed " << r.arm_count << " time(s), armed cycles " << r.app.armed_cycles;
  if (r.fault_counts.empty()) {
    out << ", no faults";
  } else {
    out << ", first fault '" << r.first_fault << "' at cycle " << r.first_fault_cycle
        << "; raised:";
    for (const auto& [name, count] : r.fault_counts) out << " " << name << "×" << count;
  }
  out << "\n  outputs zeroed at exit: " << (r.outputs_zeroed_at_exit ? "yes" : "NO") << "\n";
  if (r.metrics) {
    std::istringstream lines(metrics::metrics_summary(*r.metrics, r.instrument_names));
    for (std::string line; std::getline(lines, line);) out << "  " << line << "\n";
  }
  if (r.can) {
    const hal::socketcan::CanDiagnostics& c = *r.can;
    out << "  can: " << c.sync_sent << " SYNCs, " << c.tpdo_received << " TPDOs, "
        << c.stale_samples << " one SYNC old, " << c.error_frames << " error frames, "
        << c.transport.rx_kernel_drops << " kernel drops, " << c.transport.tx_dropped
        << " frames not sent; faults: " << (r.can_faults.empty() ? "none" : r.can_faults)
        << "\n";
  }
  if (r.usb) {
    const hal::libusb::UsbDiagnostics& u = *r.usb;
    const hal::libusb::UsbFrameCounters& f = u.frames;
    out << "  usb: " << f.in_reports_used << " IN reports used, " << f.stale_frames
        << " stale cycles, " << f.missed_frames << " missed frames, " << f.bad_reports
        << " bad reports, " << u.transfer_errors << " transfer errors; round trip p50 "
        << static_cast<double>(u.round_trip_p50_ns) * 1e-3 << " us, p99 "
        << static_cast<double>(u.round_trip_p99_ns) * 1e-3 << " us, max "
        << static_cast<double>(u.round_trip_max_ns) * 1e-3 << " us over " << u.round_trips
        << "; faults: " << (r.usb_faults.empty() ? "none" : r.usb_faults) << "\n";
  }
  if (r.telemetry_stream) {
    const TelemetrySenderStats& t = *r.telemetry_stream;
    out << "  telemetry: " << t.frames_sent << " frames to " << t.destination << " at "
        << t.rate_hz << " Hz, " << t.send_errors << " send errors (" << t.refused
        << " refused), frame bytes p50 " << t.bytes_p50 << " max " << t.bytes_max << "\n";
  }
  return out.str();
}

}  // namespace trainer::app
