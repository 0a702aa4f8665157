#include "trainer/app/compute_trace.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace trainer::app {

const char* compute_column_name(std::size_t column) noexcept {
  if (column == kStepColumn) return "step";
  if (column < kFirstSubstageColumn) return kCyclePhaseNames[column - kFirstPhaseColumn];
  if (column < kComputeColumns) return kSubstageNames[column - kFirstSubstageColumn];
  return "unknown";
}

void CycleTimeTrace::prepare(std::size_t cycles) {
  cycles_ = cycles;
  values_.assign(kComputeColumns * cycles, 0);
  folds_ = 0;
}

void CycleTimeTrace::record_stages(std::uint64_t cycle, const StageRunner& runner,
                                   const SubstageTimer& laps) noexcept {
  if (cycle >= cycles_) return;
  const auto k = static_cast<std::size_t>(cycle);
  for (std::size_t phase = 0; phase < kCyclePhaseCount; ++phase) {
    values_[(kFirstPhaseColumn + phase) * cycles_ + k] =
        runner.last_ns(static_cast<CyclePhase>(phase));
  }
  for (std::size_t substage = 0; substage < kSubstageCount; ++substage) {
    values_[(kFirstSubstageColumn + substage) * cycles_ + k] =
        laps.last_ns(static_cast<Substage>(substage));
  }
}

void CycleTimeTrace::fold_minimum(const CycleTimeTrace& run, std::size_t cycles) {
  if (folds_ == 0) {
    cycles_ = cycles;
    values_.assign(kComputeColumns * cycles, 0);
  }
  const std::size_t n = std::min({cycles, cycles_, run.cycles()});
  for (std::size_t column = 0; column < kComputeColumns; ++column) {
    const std::span<const std::int64_t> source = run.column(column);
    const std::span<std::int64_t> target = column_span(column);
    for (std::size_t k = 0; k < n; ++k) {
      target[k] = folds_ == 0 ? source[k] : std::min(target[k], source[k]);
    }
  }
  ++folds_;
}

ComputeStatistics compute_statistics(std::string name, std::span<const std::int64_t> values) {
  ComputeStatistics statistics;
  statistics.name = std::move(name);
  statistics.count = values.size();
  if (values.empty()) return statistics;
  std::vector<std::int64_t> sorted(values.begin(), values.end());
  std::sort(sorted.begin(), sorted.end());
  const auto at_rank = [&](double fraction) {
    // Nearest rank: ceil(fraction * n), 1-based; at least rank 1.
    const double rank = std::ceil(fraction * static_cast<double>(sorted.size()));
    const std::size_t index = rank < 1.0 ? 0 : static_cast<std::size_t>(rank) - 1;
    return sorted[std::min(index, sorted.size() - 1)];
  };
  statistics.min_ns = sorted.front();
  statistics.p50_ns = at_rank(0.50);
  statistics.p99_ns = at_rank(0.99);
  statistics.p99_9_ns = at_rank(0.999);
  statistics.max_ns = sorted.back();
  const long double sum = std::accumulate(
      sorted.begin(), sorted.end(), 0.0L,
      [](long double acc, std::int64_t v) { return acc + static_cast<long double>(v); });
  statistics.mean_ns = static_cast<double>(sum / static_cast<long double>(sorted.size()));
  return statistics;
}

ComputeSummary summarize_compute(const CycleTimeTrace& minimum, std::size_t cycles,
                                 const AppStats& app) {
  ComputeSummary summary;
  summary.runs = minimum.folds();
  summary.cycles = cycles;
  const std::size_t n = std::min(cycles, minimum.cycles());
  const auto column = [&](std::size_t c) {
    return compute_statistics(compute_column_name(c), minimum.column(c).first(n));
  };
  summary.step = column(kStepColumn);
  for (std::size_t phase = 0; phase < kCyclePhaseCount; ++phase) {
    if (app.phase_ns[phase].count() == 0) continue;  // a stage the scene does not run
    summary.stages.push_back(column(kFirstPhaseColumn + phase));
  }
  for (std::size_t substage = 0; substage < kSubstageCount; ++substage) {
    if (app.substage_ns[substage].count() == 0) continue;
    summary.substages.push_back(column(kFirstSubstageColumn + substage));
  }
  return summary;
}

void write_compute_csv(const ComputeSummary& summary, std::ostream& out) {
  if (!summary.per_cycle_minimum) return;
  const CycleTimeTrace& minimum = *summary.per_cycle_minimum;
  std::vector<std::size_t> columns{kStepColumn};
  for (std::size_t column = kFirstPhaseColumn; column < kComputeColumns; ++column) {
    const char* name = compute_column_name(column);
    const auto named = [&](const ComputeStatistics& s) { return s.name == name; };
    if (std::any_of(summary.stages.begin(), summary.stages.end(), named) ||
        std::any_of(summary.substages.begin(), summary.substages.end(), named)) {
      columns.push_back(column);
    }
  }
  out << "cycle";
  for (std::size_t column : columns) out << ',' << compute_column_name(column);
  out << '\n';
  const std::size_t cycles = std::min<std::size_t>(summary.cycles, minimum.cycles());
  for (std::size_t k = 0; k < cycles; ++k) {
    out << k;
    for (std::size_t column : columns) out << ',' << minimum.column(column)[k];
    out << '\n';
  }
}

}  // namespace trainer::app
