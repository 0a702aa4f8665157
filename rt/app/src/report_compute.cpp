// The report's `compute` section and its summary lines (trainer --repeat); see report_compute.hpp.
// Moved out of report.cpp unchanged: the helpers carry a compute_ prefix because unity builds
// may put this file in one translation unit with report.cpp.
#include "report_compute.hpp"

#include <cstdint>
#include <cstdio>
#include <string>

#include "trainer/app/compute_trace.hpp"

namespace trainer::app {

namespace {

std::string compute_microseconds(std::int64_t ns) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.1f", static_cast<double>(ns) * 1e-3);
  return buffer;
}

nlohmann::json compute_statistics_json(const ComputeStatistics& s) {
  return {{"count", s.count},    {"min", s.min_ns}, {"p50", s.p50_ns},  {"p99", s.p99_ns},
          {"p99_9", s.p99_9_ns}, {"max", s.max_ns}, {"mean", s.mean_ns}};
}

std::string compute_hash_hex(std::uint64_t hash) {
  char text[24];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(hash));
  return text;
}

std::string compute_statistics_line(const ComputeStatistics& s) {
  return compute_microseconds(s.p50_ns) + "/" + compute_microseconds(s.p99_ns) + "/" +
         compute_microseconds(s.p99_9_ns) + "/" + compute_microseconds(s.max_ns);
}

}  // namespace

// trainer --repeat: the per-cycle minimum compute over the runs (null otherwise).
nlohmann::json compute_section_json(const RunResult& r) {
  if (!r.compute) return nullptr;
  const ComputeSummary& c = *r.compute;
  nlohmann::json stages = nlohmann::json::object();
  for (const ComputeStatistics& s : c.stages) stages[s.name] = compute_statistics_json(s);
  nlohmann::json substages = nlohmann::json::object();
  for (const ComputeStatistics& s : c.substages) substages[s.name] = compute_statistics_json(s);
  nlohmann::json runs = nlohmann::json::array();
  for (const ComputeRun& run : c.per_run) {
    runs.push_back({{"cycles", run.cycles},
                    {"final_state_hash", compute_hash_hex(run.final_state_hash)},
                    {"wall_time_s", run.wall_time_s},
                    {"step_ns", compute_statistics_json(run.step)}});
  }
  return {{"clock", "CLOCK_MONOTONIC"},
          {"statistic", "per-cycle minimum over the runs"},
          {"runs", c.runs},
          {"cycles", c.cycles},
          {"period_ns", c.period_ns},
          {"identical", c.identical},
          {"mismatch", c.mismatch},
          {"step_ns", compute_statistics_json(c.step)},
          {"stages_ns", stages},
          {"substages_ns", substages},
          {"per_run", runs}};
}

// trainer --repeat: the per-cycle minimum over the runs, and each run's own step for contrast.
void summarize_compute_section(const RunResult& r, std::ostream& out) {
  if (!r.compute) return;
  const ComputeSummary& c = *r.compute;
  out << "  compute, per-cycle minimum of " << c.runs << " run(s) of " << c.cycles
      << " cycles (real clock), p50/p99/p99.9/max us:\n";
  if (!c.identical)
    out << "  WARNING: the runs were not identical (" << c.mismatch
        << "): the per-cycle minima mean nothing\n";
  out << "    step " << compute_statistics_line(c.step) << " (mean "
      << compute_microseconds(static_cast<std::int64_t>(c.step.mean_ns)) << ")\n";
  out << "    stages:";
  for (const ComputeStatistics& s : c.stages)
    out << " " << s.name << " " << compute_statistics_line(s);
  out << "\n";
  if (!c.substages.empty()) {
    out << "    sub-stages:";
    for (const ComputeStatistics& s : c.substages)
      out << " " << s.name << " " << compute_statistics_line(s);
    out << "\n";
  }
  out << "    each run's own step p50/p99.9 us:";
  for (const ComputeRun& run : c.per_run)
    out << " " << compute_microseconds(run.step.p50_ns) << "/"
        << compute_microseconds(run.step.p99_9_ns);
  out << "\n";
}

}  // namespace trainer::app
