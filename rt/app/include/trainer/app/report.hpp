// The run report: a JSON document (schema in docs/report.md) and a human summary.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "trainer/app/trainer_run.hpp"

namespace trainer::app {

inline constexpr int kReportSchemaVersion = 2;

nlohmann::json report_json(const RunResult& result);
std::string report_summary(const RunResult& result);

}  // namespace trainer::app
