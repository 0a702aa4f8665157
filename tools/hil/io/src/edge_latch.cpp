// The edge-to-latch bookkeeping of hil check's e-stop and enable steps (docs/hil-io.md): from
// the kernel's timestamp of a line's first edge to the return of the read that reported it.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "trainer/hil/io_parts.hpp"

namespace trainer::hil {
namespace {

// Reads after a level-only report within which the press's event must have been drained.
constexpr std::int64_t kEdgeLagReads = 50;

double edge_latch_ms(std::int64_t ns) {
  return static_cast<double>(ns) / 1e6;
}

std::string edge_latch_fmt(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.2f", value);
  return text;
}

std::int64_t edge_latch_rank(const std::vector<std::int64_t>& sorted, double q) {
  // Nearest rank: the smallest value with at least q of the samples at or below it.
  const auto n = sorted.size();
  auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(n)));
  rank = std::clamp<std::size_t>(rank, 1, n);
  return sorted[rank - 1];
}

}  // namespace

void EdgeLatchMeter::arm(std::int64_t now_ns) {
  armed_ = true;
  latched_ = false;
  unreported_start_ns_ = 0;
  arm_ns_ = now_ns;
  trial_ = LatchTrial{};
}

bool EdgeLatchMeter::on_read(const LatchRead& read) {
  last_active_ = read.reported_active;
  inactive_streak_ = read.reported_active ? 0 : inactive_streak_ + 1;
  if (!armed_) return false;
  ++trial_.reads;
  const bool fresh_event = read.event_ns != 0 && read.event_ns >= arm_ns_;
  if (!latched_) {
    if (!read.reported_active) {
      unreported_start_ns_ = read.start_ns;
      return false;
    }
    if (read.event_ns != 0 && !fresh_event) {
      // Reported because of an event from before the arming (the previous release, queued
      // late): not this press.
      ++stale_reports_;
      return false;
    }
    latched_ = true;
    trial_.latch_ns = read.done_ns;
    trial_.latch_read_start_ns = read.start_ns;
    if (fresh_event) {
      complete(read.event_ns);
      return true;
    }
    trial_.level_before_event = true;
    return false;
  }
  if (fresh_event) {
    complete(read.event_ns);
    return true;
  }
  if (trial_.reads > kEdgeLagReads) {  // reported, but the kernel never queued an edge
    armed_ = false;
    return true;
  }
  return false;
}

void EdgeLatchMeter::complete(std::int64_t edge_ns) {
  trial_.edge_ns = edge_ns;
  trial_.missed_by_a_read = unreported_start_ns_ != 0 && unreported_start_ns_ > edge_ns;
  armed_ = false;
}

LatchSummary summarize_latches(const std::vector<LatchTrial>& trials, std::int64_t limit_ns,
                               std::int64_t period_ns) {
  LatchSummary summary;
  std::vector<std::int64_t> values;
  for (const LatchTrial& trial : trials) {
    if (trial.level_before_event) ++summary.level_before_event;
    if (trial.missed_by_a_read) ++summary.missed_by_a_read;
    if (period_ns > 0 && !trial.missed_by_a_read && trial.edge_ns != 0 &&
        trial.latch_read_start_ns != 0 &&
        trial.latch_read_start_ns - trial.edge_ns > period_ns) {
      ++summary.late_reader;
    }
    if (trial.edge_ns == 0) {
      ++summary.over_limit;  // no edge timestamp: cannot be shown within the limit
      continue;
    }
    values.push_back(trial.edge_to_latch_ns());
    if (trial.edge_to_latch_ns() > limit_ns) ++summary.over_limit;
  }
  summary.trials = trials.size();
  if (values.empty()) return summary;
  std::sort(values.begin(), values.end());
  summary.p50_ns = edge_latch_rank(values, 0.50);
  summary.p90_ns = edge_latch_rank(values, 0.90);
  summary.p99_ns = edge_latch_rank(values, 0.99);
  summary.max_ns = values.back();
  summary.min_ns = values.front();
  return summary;
}

StepResult judge_edge_to_latch(const std::string& id, const std::string& title,
                               const std::vector<LatchTrial>& trials, std::size_t wanted,
                               std::int64_t period_ns, std::int64_t limit_ns) {
  StepResult step;
  step.id = id;
  step.title = title;
  const LatchSummary s = summarize_latches(trials, limit_ns, period_ns);
  step.figures = {{"trials", static_cast<double>(s.trials), "presses"},
                  {"p50", edge_latch_ms(s.p50_ns), "ms"},
                  {"p90", edge_latch_ms(s.p90_ns), "ms"},
                  {"p99", edge_latch_ms(s.p99_ns), "ms"},
                  {"max", edge_latch_ms(s.max_ns), "ms"},
                  {"period", edge_latch_ms(period_ns), "ms"},
                  {"limit", edge_latch_ms(limit_ns), "ms"}};
  nlohmann::json samples = nlohmann::json::array();
  for (const LatchTrial& t : trials) {
    samples.push_back({{"edge_to_latch_us", t.edge_ns == 0 ? -1 : t.edge_to_latch_ns() / 1000},
                       {"latch_read_start_after_edge_us",
                        t.edge_ns == 0 ? -1 : (t.latch_read_start_ns - t.edge_ns) / 1000},
                       {"reads", t.reads},
                       {"level_before_event", t.level_before_event},
                       {"missed_by_a_read", t.missed_by_a_read}});
  }
  step.details = {{"trials", samples},
                  {"over_limit", s.over_limit},
                  {"level_before_event", s.level_before_event},
                  {"missed_by_a_read", s.missed_by_a_read},
                  {"late_reader", s.late_reader},
                  {"min_ms", edge_latch_ms(s.min_ns)}};
  const std::string numbers = "p50 " + edge_latch_fmt(edge_latch_ms(s.p50_ns)) + " ms, p90 " +
                              edge_latch_fmt(edge_latch_ms(s.p90_ns)) + " ms, p99 " +
                              edge_latch_fmt(edge_latch_ms(s.p99_ns)) + " ms, max " +
                              edge_latch_fmt(edge_latch_ms(s.max_ns)) + " ms over " +
                              std::to_string(s.trials) + " trial(s); limit " +
                              edge_latch_fmt(edge_latch_ms(limit_ns)) + " ms (period " +
                              edge_latch_fmt(edge_latch_ms(period_ns)) + " ms + margin)";
  if (trials.empty()) {
    step.outcome = Outcome::fail;
    step.reason = "no trial completed";
    return step;
  }
  if (s.over_limit > 0) {
    step.outcome = Outcome::fail;
    step.reason = std::to_string(s.over_limit) + " of " + std::to_string(s.trials) +
                  " latched later than the limit (or without a kernel edge): " + numbers +
                  "; the reporting read began over a period after the edge (reader late) in " +
                  std::to_string(s.late_reader) + ", a read after the edge missed it (event "
                  "queued late) in " + std::to_string(s.missed_by_a_read);
    return step;
  }
  if (trials.size() < wanted) {
    step.outcome = Outcome::fail;
    step.reason = "only " + std::to_string(trials.size()) + " of " + std::to_string(wanted) +
                  " trials completed: " + numbers;
    return step;
  }
  step.outcome = Outcome::pass;
  step.reason = "every trial latched within the limit: " + numbers;
  if (s.missed_by_a_read > 0) {
    // Within the limit, but one read late: the kernel queued the event after a read that
    // began after the edge (the GPIO IRQ thread ran late, docs/gpio.md).
    step.reason += "; " + std::to_string(s.missed_by_a_read) +
                   " reported only by the second read after the edge (event queued late)";
  }
  return step;
}

}  // namespace trainer::hil
