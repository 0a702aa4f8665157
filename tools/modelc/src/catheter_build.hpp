// `modelc build` for a kind = "catheter" definition: the chain derived from the definition in
// the runtime's precision, written as the catheter image the definition names, with a line of
// output and an entry of the build report (--report).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "trainer/config/model.hpp"

namespace trainer::tools::modelc {

// Builds and writes the image; `loop_period_s` (the scene's loop.period_us) only informs the
// output: the substeps one period costs at the stored substep, against the definition's budget
// (the trainer refuses a catheter beyond it when it loads the scene). Throws std::runtime_error
// with the definition's refusal.
nlohmann::json build_catheter_model(const std::string& name,
                                    const config::ModelDefinition& definition,
                                    double loop_period_s);

}  // namespace trainer::tools::modelc
