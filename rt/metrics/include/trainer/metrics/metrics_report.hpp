// The `metrics` section of the trainer's JSON report (docs/report.md, docs/metrics.md): a
// SessionResult with the thresholds it was computed with, instruments and models by name.
// Setup/report path (allocates); the lead's integration calls it where the report is written.
#pragma once

#include <span>
#include <string>

#include <nlohmann/json.hpp>

#include "trainer/metrics/session_metrics.hpp"

namespace trainer::metrics {

// instrument_names: scene [[instrument]] names in order (at least result.instrument_count,
// otherwise entries are named by index); model_names: scene [[model]] names in order, for the
// damage peak's model (a model index outside them is written as its number).
nlohmann::json metrics_json(const SessionResult& result, const MetricsThresholds& thresholds,
                            std::span<const std::string> instrument_names,
                            std::span<const std::string> model_names);

// The same for the human summary the trainer prints after a run: one line for the session,
// one per instrument, e.g.
//   metrics: task 6.10 s (insertion target 10.0 mm reached), above safe force 0.03 s, no damage
//     left: path 75.0 mm, movements 2, idle 3.49 s, economy 1.00, peak 0.44 N, mean in contact 0.43 N, grasps 1 (slips 0)
std::string metrics_summary(const SessionResult& result,
                            std::span<const std::string> instrument_names);

}  // namespace trainer::metrics
