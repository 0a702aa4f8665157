// What a jitter measurement concludes: the two wake-up latency distributions side by side,
// their percentile ratios, the acceptance verdict (--max-ratio, --max-overruns), the JSON
// summary (docs/timing.md lists its fields) and the short text printed at the end.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "jitter_run.hpp"
#include "latency_distribution.hpp"

namespace trainer::tools::jitter {

struct AcceptanceCriteria {
  std::optional<double> max_ratio;                    // trainer / cyclictest, each listed
  std::vector<std::string> ratio_at{"p99", "p99.9"};  // percentile names
  std::optional<std::uint64_t> max_overruns;          // trainer overruns over all runs
};

struct AcceptanceVerdict {
  bool evaluated = false;  // at least one criterion was given
  bool passed = true;
  std::vector<std::string> checks;      // every check made, with its numbers and result
  std::vector<std::string> violations;  // the failed ones
};

// Error only for an unknown percentile name in ratio_at. A ratio of 0 (a side measured
// nothing) fails the ratio criterion: nothing was shown to be within it.
core::Expected<AcceptanceVerdict> evaluate_acceptance(const AcceptanceCriteria& criteria,
                                                      const PercentileSet& ratios,
                                                      std::uint64_t overruns);

struct Comparison {
  LatencyDistribution trainer_wake;
  LatencyDistribution trainer_step;
  LatencyDistribution cyclictest;
  PercentileSet trainer_wake_us;
  PercentileSet trainer_step_us;
  PercentileSet cyclictest_us;
  PercentileSet ratios;                           // trainer / cyclictest
  std::uint64_t cyclictest_late_by_a_period = 0;  // samples with latency >= the period
};

Comparison compare(const JitterMeasurement& measurement);

nlohmann::json summary_json(const JitterMeasurement& measurement, const Comparison& comparison,
                            const AcceptanceCriteria& criteria, const AcceptanceVerdict& verdict,
                            const std::string& plot_status);

std::string summary_text(const JitterMeasurement& measurement, const Comparison& comparison,
                         const AcceptanceVerdict& verdict);

}  // namespace trainer::tools::jitter
