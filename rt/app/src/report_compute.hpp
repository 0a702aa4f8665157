// Private to rt/app: the run report's `compute` section (trainer --repeat: the per-cycle minimum
// compute over the runs, docs/report.md) and its lines in the human summary; report.cpp calls
// these.
#pragma once

#include <ostream>

#include <nlohmann/json.hpp>

#include "trainer/app/trainer_run.hpp"

namespace trainer::app {

// The `compute` object of the report JSON; null when the run was not a --repeat run.
nlohmann::json compute_section_json(const RunResult& r);

// The summary's "compute, per-cycle minimum ..." lines; nothing when not a --repeat run.
void summarize_compute_section(const RunResult& r, std::ostream& out);

}  // namespace trainer::app
