#include "jitter_summary.hpp"

#include <cmath>
#include <cstdio>
#include <sstream>

namespace trainer::tools::jitter {

namespace {

// Microseconds to 3 decimals (ns resolution) in the JSON, so no float noise is printed.
double rounded_us(double value_us) {
  return std::round(value_us * 1000.0) / 1000.0;
}
double rounded_ratio(double ratio) {
  return std::round(ratio * 1000.0) / 1000.0;
}

nlohmann::json percentiles_json(const PercentileSet& set, double (*round)(double)) {
  return {{"p50", round(set.p50_us)},
          {"p90", round(set.p90_us)},
          {"p99", round(set.p99_us)},
          {"p99_9", round(set.p99_9_us)},
          {"max", round(set.max_us)}};
}

nlohmann::json latency_json(const LatencyDistribution& distribution, const PercentileSet& set,
                            double mean_us, double min_us) {
  nlohmann::json json = percentiles_json(set, rounded_us);
  json["count"] = distribution.count();
  json["min"] = rounded_us(min_us);
  json["mean"] = rounded_us(mean_us);
  return json;
}

std::string format(const char* pattern, double value) {
  char text[32];
  std::snprintf(text, sizeof text, pattern, value);
  return text;
}

std::string row(const PercentileSet& set, const char* pattern) {
  return "p50 " + format(pattern, set.p50_us) + "  p90 " + format(pattern, set.p90_us) + "  p99 " +
         format(pattern, set.p99_us) + "  p99.9 " + format(pattern, set.p99_9_us) + "  max " +
         format(pattern, set.max_us);
}

}  // namespace

core::Expected<AcceptanceVerdict> evaluate_acceptance(const AcceptanceCriteria& criteria,
                                                      const PercentileSet& ratios,
                                                      std::uint64_t overruns) {
  AcceptanceVerdict verdict;
  if (criteria.max_ratio) {
    verdict.evaluated = true;
    for (const std::string& name : criteria.ratio_at) {
      auto ratio = percentile_by_name(ratios, name);
      if (!ratio) return std::move(ratio).error();
      const bool ok = *ratio > 0.0 && *ratio <= *criteria.max_ratio;
      const std::string check = "wake-up latency " + name + " trainer/cyclictest " +
                                format("%.3f", *ratio) + (ok ? " <= " : " > ") +
                                format("%.3f", *criteria.max_ratio) + " (--max-ratio)";
      verdict.checks.push_back(check + (ok ? ": ok" : ": FAILED"));
      if (!ok) verdict.violations.push_back(check);
    }
  }
  if (criteria.max_overruns) {
    verdict.evaluated = true;
    const bool ok = overruns <= *criteria.max_overruns;
    const std::string check = "trainer overruns " + std::to_string(overruns) +
                              (ok ? " <= " : " > ") + std::to_string(*criteria.max_overruns) +
                              " (--max-overruns)";
    verdict.checks.push_back(check + (ok ? ": ok" : ": FAILED"));
    if (!ok) verdict.violations.push_back(check);
  }
  verdict.passed = verdict.violations.empty();
  return verdict;
}

Comparison compare(const JitterMeasurement& measurement) {
  Comparison comparison;
  comparison.trainer_wake = LatencyDistribution::from_histogram(*measurement.trainer.wake_latency);
  comparison.trainer_step = LatencyDistribution::from_histogram(*measurement.trainer.step_time);
  comparison.cyclictest = measurement.cyclictest.histogram.distribution();
  comparison.trainer_wake_us = comparison.trainer_wake.percentiles();
  comparison.trainer_step_us = comparison.trainer_step.percentiles();
  comparison.cyclictest_us = comparison.cyclictest.percentiles();
  comparison.ratios = percentile_ratios(comparison.trainer_wake_us, comparison.cyclictest_us);
  comparison.cyclictest_late_by_a_period =
      comparison.cyclictest.count_at_or_above(measurement.settings.period_ns);
  return comparison;
}

nlohmann::json summary_json(const JitterMeasurement& m, const Comparison& c,
                            const AcceptanceCriteria& criteria, const AcceptanceVerdict& verdict,
                            const std::string& plot_status) {
  const EffectiveSettings& s = m.settings;
  const TrainerSide& t = m.trainer;
  const CyclictestHistogram& h = m.cyclictest.histogram;

  nlohmann::json runs = nlohmann::json::array();
  for (const TrainerRunRecord& run : t.runs) {
    runs.push_back({{"cycles", run.cycles},
                    {"wall_time_s", run.wall_time_s},
                    {"overruns", run.overruns},
                    {"longest_overrun_streak", run.longest_overrun_streak},
                    {"faults_latched", run.latched_faults},
                    {"first_fault", run.first_fault},
                    {"report", run.report_file.filename().string()}});
  }
  std::string command;
  for (const std::string& argument : m.cyclictest.arguments) {
    command += (command.empty() ? "" : " ") + argument;
  }

  nlohmann::json json;
  json["schema_version"] = 1;
  json["started_utc"] = m.started_utc;
  json["mode"] = to_string(m.mode);
  json["mode_description"] =
      m.mode == Mode::alongside
          ? "cyclictest ran alongside: started before the trainer's first run, stopped with "
            "SIGINT after its last"
          : "one after the other: the trainer's runs, then cyclictest for as many loops";
  json["scene"] = {{"file", s.scene_file.string()}, {"name", s.scene_name}};
  json["settings"] = {{"period_us", static_cast<double>(s.period_ns) / 1000.0},
                      {"priority", s.priority},
                      {"policy", s.priority > 0 ? "SCHED_FIFO" : "SCHED_OTHER"},
                      {"cpu", s.cpu},
                      {"cyclictest_cpu", s.cyclictest_cpu},
                      {"lock_memory", s.lock_memory},
                      {"cpu_dma_latency_us", s.cpu_dma_latency_us},
                      {"requested_seconds", m.requested_seconds},
                      {"target_cycles", s.target_cycles},
                      {"cyclictest_histogram_limit_us", s.histogram_limit_us}};
  json["host"] = {{"kernel_release", m.kernel_release},
                  {"kernel_version", m.kernel_version},
                  {"preempt_rt", m.preempt_rt},
                  {"online_cpus", m.online_cpus},
                  {"load_average_start", m.load_average_start},
                  {"load_average_end", m.load_average_end}};
  json["trainer"] = {
      {"runs", t.runs.size()},
      {"run_list", runs},
      {"cycles", t.cycles},
      {"loop_time_s", t.loop_time_s},
      {"elapsed_time_s", t.elapsed_time_s},
      {"wake_latency_us",
       latency_json(c.trainer_wake, c.trainer_wake_us, t.wake_latency->mean_ns() / 1000.0,
                    static_cast<double>(t.wake_latency->min_ns()) / 1000.0)},
      {"step_time_us",
       latency_json(c.trainer_step, c.trainer_step_us, t.step_time->mean_ns() / 1000.0,
                    static_cast<double>(t.step_time->min_ns()) / 1000.0)},
      {"overruns", t.overruns},
      {"longest_overrun_streak", t.longest_overrun_streak},
      {"skipped_periods", t.skipped_periods},
      {"cycle_errors", t.cycle_errors},
      {"faulted_runs", t.faulted_runs},
      {"heap_allocations_after_arming", t.heap_allocations_after_arming},
      {"rt",
       {{"policy", t.rt.policy},
        {"priority", t.rt.priority},
        {"cpu", t.rt.cpu},
        {"memory_locked", t.rt.memory_locked},
        {"cpu_dma_latency_us", t.rt.cpu_dma_latency_us},
        {"warnings", t.rt.warnings}}},
      {"wake_latency_histogram", "trainer_wake_latency.csv"},
      {"step_time_histogram", "trainer_step_time.csv"}};
  nlohmann::json cyclictest_latency =
      latency_json(c.cyclictest, c.cyclictest_us, c.cyclictest.midpoint_mean_ns() / 1000.0,
                   static_cast<double>(h.min_us));
  json["cyclictest"] = {{"command", command},
                        {"exit_status", m.cyclictest.exit_status},
                        {"stopped_with_sigint", m.cyclictest.interrupted},
                        {"loops", h.samples()},
                        {"latency_us", cyclictest_latency},
                        {"reported_min_us", h.min_us},
                        {"reported_avg_us", h.avg_us},
                        {"reported_max_us", h.max_us},
                        {"histogram_overflows", h.overflows},
                        {"late_by_a_period", c.cyclictest_late_by_a_period},
                        {"histogram", "cyclictest_latency.csv"},
                        {"raw_histogram", m.cyclictest.histogram_file.filename().string()},
                        {"raw_output", m.cyclictest.output_file.filename().string()}};
  json["ratio_trainer_over_cyclictest"] = percentiles_json(c.ratios, rounded_ratio);
  json["acceptance"] = {{"evaluated", verdict.evaluated},
                        {"passed", verdict.passed},
                        {"ratio_at", criteria.ratio_at},
                        {"checks", verdict.checks},
                        {"violations", verdict.violations}};
  json["acceptance"]["max_ratio"] =
      criteria.max_ratio ? nlohmann::json(*criteria.max_ratio) : nlohmann::json(nullptr);
  json["acceptance"]["max_overruns"] =
      criteria.max_overruns ? nlohmann::json(*criteria.max_overruns) : nlohmann::json(nullptr);
  json["plot"] = plot_status;
  json["stopped_by_signal"] = m.stopped_by_signal;
  json["warnings"] = m.warnings;
  return json;
}

std::string summary_text(const JitterMeasurement& m, const Comparison& c,
                         const AcceptanceVerdict& verdict) {
  const EffectiveSettings& s = m.settings;
  const TrainerSide& t = m.trainer;
  std::ostringstream out;
  out << "jitter: scene '" << s.scene_name << "', period "
      << static_cast<double>(s.period_ns) / static_cast<double>(kNanosecondsPerMicrosecond)
      << " us, " << (s.priority > 0 ? "SCHED_FIFO " + std::to_string(s.priority) : "SCHED_OTHER")
      << ", trainer cpu " << (s.cpu < 0 ? std::string("any") : std::to_string(s.cpu))
      << ", cyclictest cpu "
      << (s.cyclictest_cpu < 0 ? std::string("any") : std::to_string(s.cyclictest_cpu)) << ", "
      << to_string(m.mode) << "\n";
  out << "  trainer:    " << t.cycles << " cycles in " << t.runs.size() << " run(s), "
      << format("%.1f", t.loop_time_s) << " s of loop (" << format("%.1f", t.elapsed_time_s)
      << " s with setup between runs)\n";
  out << "  wake-up latency, us (bin upper bounds):\n";
  out << "    trainer     " << row(c.trainer_wake_us, "%.1f") << "\n";
  out << "    cyclictest  " << row(c.cyclictest_us, "%.0f") << "  ("
      << m.cyclictest.histogram.samples() << " loops, " << m.cyclictest.histogram.overflows
      << " above " << s.histogram_limit_us << " us)\n";
  out << "    ratio       " << row(c.ratios, "%.2f") << "\n";
  out << "  trainer step time, us: " << row(c.trainer_step_us, "%.1f") << "\n";
  out << "  trainer overruns " << t.overruns << " (longest streak " << t.longest_overrun_streak
      << ", skipped periods " << t.skipped_periods << "), faulted runs " << t.faulted_runs
      << ", heap allocations after arming " << t.heap_allocations_after_arming
      << "; cyclictest wake-ups late by a period or more " << c.cyclictest_late_by_a_period << "\n";
  out << "  rt: trainer " << t.rt.policy << " " << t.rt.priority << " cpu " << t.rt.cpu
      << ", mlock " << (t.rt.memory_locked ? "yes" : "no") << ", cpu wake-up latency "
      << (t.rt.cpu_dma_latency_us < 0 ? std::string("not held")
                                      : std::to_string(t.rt.cpu_dma_latency_us) + " us")
      << "; kernel " << m.kernel_release << (m.preempt_rt ? " (PREEMPT_RT)" : " (not PREEMPT_RT)");
  if (m.load_average_start.size() == 3 && m.load_average_end.size() == 3) {
    out << "; load average " << format("%.2f", m.load_average_start[0]) << " -> "
        << format("%.2f", m.load_average_end[0]);
  }
  out << "\n";
  for (const std::string& warning : m.warnings) out << "  warning: " << warning << "\n";
  for (const std::string& check : verdict.checks) out << "  acceptance: " << check << "\n";
  return out.str();
}

}  // namespace trainer::tools::jitter
