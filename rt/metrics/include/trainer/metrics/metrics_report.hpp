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

}  // namespace trainer::metrics
