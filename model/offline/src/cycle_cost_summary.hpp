// Private to model/offline: turns per-cycle wall times of a trade study's timing loop into a
// CycleCost (modal_tradeoff.hpp) — percentiles over every timed cycle and the spread of the
// repetitions' medians — so each model's study times its cycle the same way.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "trainer/core/expected.hpp"
#include "trainer/model_offline/modal_tradeoff.hpp"

namespace trainer::model::offline::cycle_cost {

using Clock = std::chrono::steady_clock;

inline double nanoseconds(Clock::duration d) {
  return std::chrono::duration<double, std::nano>(d).count();
}

// Order statistic at fraction q of `values` (nearest rank, as the reports use); 0 if empty.
inline double percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  const auto rank = static_cast<std::size_t>(
      std::clamp(std::ceil(q * static_cast<double>(values.size())) - 1.0, 0.0,
                 static_cast<double>(values.size()) - 1.0));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(rank),
                   values.end());
  return values[rank];
}

// Refuses counts a timing loop cannot use (`what` names the study in the message).
inline core::Expected<void> check_options(const CycleCostOptions& options, const char* what) {
  if (options.warmup_cycles < 0 || options.repetitions < 1 || options.cycles_per_repetition < 1) {
    return core::make_error(std::string(what) + ": cycle cost options warm-up " +
                            std::to_string(options.warmup_cycles) + ", repetitions " +
                            std::to_string(options.repetitions) + ", cycles per repetition " +
                            std::to_string(options.cycles_per_repetition) +
                            ": expected warm-up >= 0, repetitions >= 1, cycles >= 1");
  }
  return {};
}

// total_ns and haptic_ns: one entry per timed cycle (warm-up excluded), repetition after
// repetition, options.repetitions × options.cycles_per_repetition of them.
inline CycleCost summarize(const CycleCostOptions& options, const std::vector<double>& total_ns,
                           const std::vector<double>& haptic_ns) {
  CycleCost cost;
  cost.median_ns = percentile(total_ns, 0.5);
  cost.p99_ns = percentile(total_ns, 0.99);
  cost.haptic_median_ns = percentile(haptic_ns, 0.5);
  cost.haptic_p99_ns = percentile(haptic_ns, 0.99);
  const auto per_repetition = static_cast<std::size_t>(options.cycles_per_repetition);
  std::vector<double> medians;
  for (std::size_t begin = 0; begin + per_repetition <= total_ns.size(); begin += per_repetition) {
    const auto first = total_ns.begin() + static_cast<std::ptrdiff_t>(begin);
    medians.push_back(
        percentile(std::vector<double>(first, first + static_cast<std::ptrdiff_t>(per_repetition)),
                   0.5));
  }
  if (!medians.empty()) {
    cost.repetition_median_min_ns = *std::min_element(medians.begin(), medians.end());
    cost.repetition_median_max_ns = *std::max_element(medians.begin(), medians.end());
  }
  cost.warmup_cycles = options.warmup_cycles;
  cost.repetitions = options.repetitions;
  cost.cycles_per_repetition = options.cycles_per_repetition;
  return cost;
}

}  // namespace trainer::model::offline::cycle_cost
