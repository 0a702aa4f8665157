#include "catheter_build.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <stdexcept>

#include "build_report.hpp"
#include "model_spec.hpp"
#include "trainer/model/catheter_chain.hpp"
#include "trainer/model_offline/catheter_image.hpp"

namespace trainer::tools::modelc {

nlohmann::json build_catheter_model(const std::string& name,
                                    const config::ModelDefinition& definition,
                                    double loop_period_s) {
  const auto start = std::chrono::steady_clock::now();
  const std::string where = definition.source_path.string() + ": ";
  const model::offline::CatheterImageInputs inputs = catheter_inputs_from(definition);
  auto record = model::offline::make_catheter_record(inputs);
  if (!record) throw std::runtime_error(where + record.error().message);
  std::filesystem::create_directories(definition.image_path.parent_path());
  // The writer checks the image with the runtime's loader (a [contact] stiffness beyond what the
  // substep keeps stable, say) before it replaces the file.
  if (auto written = model::offline::write_catheter_image(definition.image_path, inputs);
      !written) {
    throw std::runtime_error(where + written.error().message);
  }
  const double total_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const auto image_bytes = std::filesystem::file_size(definition.image_path);
  const double substep_s = static_cast<double>(record->stable_substep_s);
  const std::uint64_t substeps = model::catheter_substeps_for(loop_period_s, substep_s);

  char line[256];
  std::snprintf(line, sizeof line,
                "model '%s': catheter, %u particles, segment %.2f mm, largest substep %.2f us: %llu "
                "substeps per %.1f us loop period (budget %u)\n  built in %.3f ms\n",
                name.c_str(), record->particle_count,
                1e3 * static_cast<double>(record->rest_length_m), 1e6 * substep_s,
                static_cast<unsigned long long>(substeps), 1e6 * loop_period_s,
                record->max_substeps, 1e3 * total_s);
  std::cout << line << "  image " << definition.image_path.string() << " (" << image_bytes
            << " bytes)\n";
  if (substeps > record->max_substeps) {
    std::cout
        << "  warning: at this loop period the catheter needs more substeps than its max_substeps; "
           "the trainer refuses the scene unless the period is shortened\n";
  }
  nlohmann::json entry = built_image_entry(name, definition, "catheter");
  entry.update({{"particle_count", record->particle_count},
                {"rest_length_m", record->rest_length_m},
                {"stable_substep_s", substep_s},
                {"loop_period_s", loop_period_s},
                {"substeps_per_period", substeps},
                {"max_substeps", record->max_substeps},
                {"timings_s", {{"total", total_s}}}});
  return entry;
}

}  // namespace trainer::tools::modelc
