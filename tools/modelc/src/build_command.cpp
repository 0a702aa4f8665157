#include "build_command.hpp"

#include "command_line_values.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <numeric>
#include <optional>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "build_report.hpp"
#include "catheter_build.hpp"
#include "model_spec.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/model_offline/modal_accuracy.hpp"
#include "trainer/model_offline/modal_tradeoff.hpp"
#include "trainer/model_offline/tensor_build.hpp"
#include "trainer/model_offline/tet_mesh_generators.hpp"

namespace trainer::tools::modelc {

namespace {

namespace offline = model::offline;


std::string fixed(double value, int decimals) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*f", decimals, value);
  return buffer;
}

void write_json(const std::string& path, const nlohmann::json& json) {
  if (path.empty()) return;
  std::ofstream out(path);
  out << json.dump(2) << "\n";
  if (!out) throw std::runtime_error("cannot write report '" + path + "'");
  std::cout << "report: " << path << "\n";
}

// Cotin's tensor model: assemble, factorise once, precompute the tensors of every contact
// node, write the image, then check the float32 runtime against a direct solve.
nlohmann::json build_tensor_model(const std::string& name,
                                  const config::ModelDefinition& definition) {
  const auto start = std::chrono::steady_clock::now();
  const std::string where = definition.source_path.string() + ": ";
  const offline::TetMesh mesh = value_or_throw(tet_mesh_from(definition));
  const std::vector<offline::TetNodeFix> fixes = value_or_throw(tet_fixes_from(definition, mesh));
  const offline::TetMaterial material{definition.material.young_modulus_pa,
                                      definition.material.poisson_ratio,
                                      definition.material.density_kg_per_m3};
  const auto assembly_start = std::chrono::steady_clock::now();
  const offline::AssembledTet assembled =
      value_or_throw(offline::assemble_tet(mesh, material, fixes));
  const double assembly_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - assembly_start).count();
  const offline::TetStaticSolver solver = value_or_throw(offline::TetStaticSolver::create(assembled));
  const std::vector<int> fixed_nodes = offline::partly_fixed_nodes(assembled.dofs);

  const config::TensorConfig& tensor = definition.tensor;
  const auto contact_set = mesh.node_sets.find(tensor.contact_set);
  if (contact_set == mesh.node_sets.end()) {
    throw std::runtime_error(where + "[tensor] contact_set '" + tensor.contact_set +
                             "' is not a node set of the mesh");
  }
  const auto sorted_unique = [](std::vector<int> nodes) {
    std::sort(nodes.begin(), nodes.end());
    nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
    return nodes;
  };
  offline::TensorPrecomputeOptions options;
  // A node fixed on any axis cannot be displaced by a tool: it is not a contact node.
  const std::vector<int> candidates = sorted_unique(contact_set->second);
  std::set_difference(candidates.begin(), candidates.end(), fixed_nodes.begin(), fixed_nodes.end(),
                      std::back_inserter(options.contact_nodes));
  if (options.contact_nodes.empty()) {
    throw std::runtime_error(where + "[tensor] contact_set '" + tensor.contact_set +
                             "' has no node free on all three axes");
  }
  if (tensor.stored == config::TensorStorage::all) {
    options.response_nodes.resize(static_cast<std::size_t>(mesh.nodes.rows()));
    std::iota(options.response_nodes.begin(), options.response_nodes.end(), 0);
  } else {
    std::vector<int> stored = sorted_unique(mesh.node_sets.at("surface"));
    stored.insert(stored.end(), options.contact_nodes.begin(), options.contact_nodes.end());
    options.response_nodes = sorted_unique(std::move(stored));
  }
  const offline::TensorPrecompute tensors =
      value_or_throw(offline::precompute_tensors(assembled, solver, options));
  offline::TensorImageInputs inputs;
  inputs.mesh = &mesh;
  inputs.boundary_triangles = offline::boundary_triangles(mesh);
  inputs.material = material;
  inputs.fixed_nodes = fixed_nodes;
  inputs.time_step_s = tensor.time_step_s;
  const std::vector<std::byte> bytes = value_or_throw(offline::serialize_tensor_image(inputs, tensors));
  std::filesystem::create_directories(definition.image_path.parent_path());
  if (auto written = offline::write_tensor_image(definition.image_path, inputs, tensors); !written) {
    throw std::runtime_error(written.error().message);
  }
  const double total_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const auto image_bytes = std::filesystem::file_size(definition.image_path);
  const std::vector<offline::TensorAgreement> agreement = value_or_throw(
      offline::measure_tensor_agreement(mesh, assembled, bytes, tensor.max_contacts));

  std::cout << "model '" << name << "': " << mesh.nodes.rows() << " nodes, "
            << mesh.tetrahedra.rows() << " tetrahedra, " << assembled.dofs.free_count
            << " free dofs, " << tensors.contact_nodes.size() << " contact nodes, "
            << tensors.response_nodes.size() << " stored nodes\n"
            << "  built in " << fixed(total_s, 3) << " s (assembly " << fixed(assembly_s, 3)
            << ", factorisation " << fixed(solver.factorization_time_s(), 3) << ", tensors "
            << fixed(tensors.solve_time_s, 3) << "); T(k,k) = I to "
            << tensors.self_tensor_error << "\n  image " << definition.image_path.string() << " ("
            << image_bytes << " bytes)\n";
  nlohmann::json checks = nlohmann::json::array();
  for (const offline::TensorAgreement& a : agreement) {
    std::cout << "  vs direct solve, " << a.contact_count << " contact"
              << (a.contact_count == 1 ? "" : "s") << ": displacement error "
              << a.displacement_error << ", force error " << a.force_error << " (of max), tensor "
              << fixed(a.tensor_solve_us, 1) << " us vs direct " << fixed(1e3 * a.direct_solve_s, 1)
              << " ms\n";
    checks.push_back({{"contacts", a.contact_count},
                      {"displacement_error", a.displacement_error},
                      {"force_error", a.force_error},
                      {"tensor_solve_us", a.tensor_solve_us},
                      {"direct_solve_s", a.direct_solve_s}});
  }
  nlohmann::json entry = built_image_entry(name, definition, "tet_tensor");
  entry.update({{"node_count", mesh.nodes.rows()},
                {"tetrahedron_count", mesh.tetrahedra.rows()},
                {"free_dofs", assembled.dofs.free_count},
                {"contact_node_count", tensors.contact_nodes.size()},
                {"stored_node_count", tensors.response_nodes.size()},
                {"self_tensor_error", tensors.self_tensor_error},
                {"timings_s",
                 {{"assembly", assembly_s},
                  {"factorization", solver.factorization_time_s()},
                  {"tensors", tensors.solve_time_s},
                  {"total", total_s}}},
                {"agreement_with_direct_solve", checks}});
  return entry;
}

struct BuildOptions {
  std::string scene_path;
  std::string only;
  std::string report_path;
  std::optional<double> error_budget_percent;
};

// `--error-budget`: measure every mode count (5..160, with and without static correction) of the
// definition at its element and time step against DNIOS over the trade study's scenarios, and
// return the cheapest that meets the budget on the tuning scenarios and then on the held-out
// ones (modal_tradeoff.hpp). The spec comes back with that mode count, correction and the
// study's damping; `json` receives what was measured.
offline::BudgetChoice choose_modes_for_budget(const std::string& name, offline::ModalBuildSpec& spec,
                                              double budget_percent, nlohmann::json& json) {
  const double budget = budget_percent / 100.0;
  // The reference step must divide the definition's: a quarter of it.
  const double reference_step_s = spec.time_step_s / 4.0;
  auto study = value_or_throw(offline::DuctTradeStudy::create(
      spec, offline::default_duct_scenarios(spec.mesh), reference_step_s));
  std::vector<offline::ModalTradeConfig> candidates;
  for (int modes : {5, 10, 20, 40, 80, 160}) {
    for (bool correction : {false, true}) {
      offline::ModalTradeConfig config;
      config.modes = modes;
      config.static_correction = correction;
      config.element = spec.bending;
      config.time_step_s = spec.time_step_s;
      candidates.push_back(config);
    }
  }
  auto chosen_or_error = offline::choose_for_budget(*study, budget, candidates, {});
  if (!chosen_or_error) {
    // Mode count and correction are what an image carries; at 1 kHz the time step, not r, sets
    // the error floor (docs/performance.md): say what else would meet the budget.
    throw std::runtime_error(
        "model '" + name + "': " + chosen_or_error.error().message + " at time_step_s = " +
        fixed(spec.time_step_s * 1e3, 3) +
        " ms; raise the budget, or shorten the definition's time_step_s together with the "
        "scene's loop.period_us (`tradeoff --scene FILE` measures r against the time step)");
  }
  offline::BudgetChoice choice = std::move(chosen_or_error).value();
  std::cout << "model '" << name << "': error budget " << budget_percent
            << " % (RMS force error, worst scenario, vs DNIOS at "
            << fixed(reference_step_s * 1e6, 0) << " us): " << choice.candidates.size()
            << " configurations measured\n";
  for (const std::string& line : choice.log) std::cout << "  passed over: " << line << "\n";
  const offline::ModalTradePoint& chosen = choice.chosen;
  std::printf("  chosen: r = %d, static correction %s: %.0f ns per cycle (p99 %.0f), error "
              "%.3f %% on the tuning scenarios, %.3f %% held out\n",
              chosen.config.modes, chosen.config.static_correction ? "on" : "off",
              chosen.cost.median_ns, chosen.cost.p99_ns, 100.0 * chosen.tuning_error,
              100.0 * chosen.validation_error);
  nlohmann::json candidates_json = nlohmann::json::array();
  for (const offline::ModalTradePoint& point : choice.candidates) {
    candidates_json.push_back({{"modes", point.config.modes},
                               {"static_correction", point.config.static_correction},
                               {"selection_cost_ns", offline::selection_cost_ns(point)},
                               {"cost_median_ns", point.cost.median_ns},
                               {"cost_p99_ns", point.cost.p99_ns},
                               {"tuning_error", point.tuning_error},
                               {"validation_error", point.validation_error}});
  }
  json = {{"budget", budget},
          {"definition_mode_count", spec.mode_count},
          {"definition_static_correction", spec.static_correction},
          {"chosen_mode_count", chosen.config.modes},
          {"chosen_static_correction", chosen.config.static_correction},
          {"tuning_error", chosen.tuning_error},
          {"validation_error", chosen.validation_error},
          {"measured_error", chosen.worst_error},
          {"selection_cost_ns", offline::selection_cost_ns(chosen)},
          {"cost_median_ns", chosen.cost.median_ns},
          {"cost_p99_ns", chosen.cost.p99_ns},
          {"reference_time_step_s", reference_step_s},
          {"passed_over", choice.log},
          {"candidates", candidates_json}};
  spec.mode_count = chosen.config.modes;
  spec.static_correction = chosen.config.static_correction;
  spec.damping_override = study->damping();
  return choice;
}

void run_build(const BuildOptions& options) {
  config::LoadOptions load;
  load.require_script_file = false;  // building models does not need the trainee's recording
  const config::SceneConfig scene = value_or_throw(config::load_scene(options.scene_path, load));
  nlohmann::json report = {{"scene", options.scene_path}, {"models", nlohmann::json::array()}};
  if (scene.models.empty()) std::cout << "modelc: scene '" << scene.name << "' names no models\n";
  for (const config::SceneModelConfig& entry : scene.models) {
    if (!options.only.empty() && entry.name != options.only) continue;
    const config::ModelDefinition& definition = entry.definition;
    if (definition.kind == config::ModelKind::catheter) {
      const double loop_period_s = static_cast<double>(scene.loop.period_ns) * 1e-9;
      report["models"].push_back(build_catheter_model(entry.name, definition, loop_period_s));
      continue;
    }
    if (definition.kind == config::ModelKind::tet_tensor) {
      report["models"].push_back(build_tensor_model(entry.name, definition));
      continue;
    }
    offline::ModalBuildSpec spec = value_or_throw(modal_spec_from(definition));
    std::optional<offline::ErrorBudgetRecord> budget_record;
    nlohmann::json budget_json;
    if (options.error_budget_percent) {
      const offline::BudgetChoice choice =
          choose_modes_for_budget(entry.name, spec, *options.error_budget_percent, budget_json);
      budget_record = offline::ErrorBudgetRecord{*options.error_budget_percent / 100.0,
                                                 choice.chosen.worst_error};
    }
    const offline::ModalBuildResult built = value_or_throw(offline::build_modal_model(spec));
    std::filesystem::create_directories(definition.image_path.parent_path());
    if (auto written =
            offline::write_modal_image(spec, built, definition.image_path, budget_record);
        !written) {
      throw std::runtime_error(written.error().message);
    }
    const auto image_bytes = std::filesystem::file_size(definition.image_path);
    const double omega_1 = std::sqrt(built.basis.omega_squared(0));
    const double omega_r = std::sqrt(built.basis.omega_squared(built.basis.mode_count() - 1));
    std::cout << "model '" << entry.name << "': " << spec.mesh.nodes.rows() << " nodes, "
              << spec.mesh.triangles.rows() << " triangles, " << built.shell.dofs.free_count()
              << " free dofs, " << built.basis.mode_count() << " modes ("
              << offline::to_string(built.basis.method) << "), f1 "
              << fixed(omega_1 / (2.0 * M_PI), 2) << " Hz .. f" << built.basis.mode_count() << " "
              << fixed(omega_r / (2.0 * M_PI), 1) << " Hz\n"
              << "  static error of " << built.basis.mode_count()
              << " modes without correction: max " << fixed(100.0 * built.truncation.max_local_relative, 2)
              << " %, mean " << fixed(100.0 * built.truncation.mean_local_relative, 2) << " %"
              << (spec.static_correction ? " (static correction stored: exact at surface nodes)" : "")
              << "\n  built in " << fixed(built.timings.total_s, 3) << " s (assembly "
              << fixed(built.timings.assembly_s, 3) << ", modes " << fixed(built.timings.modes_s, 3)
              << ", residual " << fixed(built.timings.residual_s, 3) << ", error estimate "
              << fixed(built.timings.error_estimate_s, 3) << ")\n  image "
              << definition.image_path.string() << " (" << image_bytes << " bytes)\n";
    nlohmann::json built_entry = built_image_entry(entry.name, definition, "modal_shell");
    built_entry.update({
        {"node_count", spec.mesh.nodes.rows()},
        {"triangle_count", spec.mesh.triangles.rows()},
        {"free_dofs", built.shell.dofs.free_count()},
        {"mode_count", built.basis.mode_count()},
        {"modal_method", offline::to_string(built.basis.method)},
        {"frequency_first_hz", omega_1 / (2.0 * M_PI)},
        {"frequency_last_hz", omega_r / (2.0 * M_PI)},
        {"rayleigh_mass_per_s", built.rayleigh.mass_proportional_per_s},
        {"rayleigh_stiffness_s", built.rayleigh.stiffness_proportional_s},
        {"truncation_error_max", built.truncation.max_local_relative},
        {"truncation_error_mean", built.truncation.mean_local_relative},
        {"static_correction", spec.static_correction},
        {"surface_node_count", built.surface_nodes.size()},
        {"timings_s",
         {{"assembly", built.timings.assembly_s},
          {"modes", built.timings.modes_s},
          {"residual", built.timings.residual_s},
          {"error_estimate", built.timings.error_estimate_s},
          {"total", built.timings.total_s}}},
    });
    if (budget_record) built_entry["error_budget"] = budget_json;
    report["models"].push_back(std::move(built_entry));
  }
  write_json(options.report_path, report);
}

struct AccuracyOptions {
  std::string model_path;
  std::vector<int> modes{10, 20, 40};
  double force_n = 0.05;
  std::string report_path;
};

void run_accuracy(const AccuracyOptions& options) {
  const config::ModelDefinition definition =
      value_or_throw(config::load_model_definition(options.model_path));
  if (definition.kind != config::ModelKind::modal_shell) {
    throw std::runtime_error(options.model_path +
                             ": `modelc accuracy` compares a modal_shell model with DNIOS; a " +
                             (definition.kind == config::ModelKind::catheter ? "catheter" : "tet_tensor") +
                             " model is checked by `modelc build` (tet_tensor: tensor vs direct "
                             "solve in its report) and `modelc catheter-static`");
  }
  offline::ModalBuildSpec spec = value_or_throw(modal_spec_from(definition));
  spec.static_correction = true;  // measure both: the residual is needed for "with"
  // One build per r, as an image of that size would be (its residual belongs to its r modes).
  std::vector<offline::ModalBuildResult> builds;
  for (int r : options.modes) {
    spec.mode_count = r;
    builds.push_back(value_or_throw(offline::build_modal_model(spec)));
  }
  const offline::ModalBuildResult& built = builds.front();

  // Probe points on the model's surface: the node nearest each point gets a radial push.
  const Eigen::Vector3d lower = spec.mesh.nodes.colwise().minCoeff();
  const Eigen::Vector3d upper = spec.mesh.nodes.colwise().maxCoeff();
  const Eigen::Vector3d centre = 0.5 * (lower + upper);
  const Eigen::Vector3d extent = upper - lower;
  std::vector<offline::AccuracyScenario> scenarios = {
      {"press at mid-length", {centre.x(), centre.y(), upper.z()}, {0.0, 0.0, -options.force_n}},
      {"press near the free end",
       {lower.x() + 0.9 * extent.x(), centre.y(), upper.z()},
       {0.0, 0.0, -options.force_n}},
  };
  nlohmann::json report = {{"model", options.model_path},
                           {"node_count", spec.mesh.nodes.rows()},
                           {"free_dofs", built.shell.dofs.free_count()},
                           {"time_step_s", spec.time_step_s},
                           {"damping_ratio", spec.damping_ratio},
                           {"force_n", options.force_n},
                           {"points", nlohmann::json::array()}};
  std::cout << "modal model vs DNIOS (full Newmark, " << built.shell.dofs.free_count()
            << " dofs), " << spec.mesh.nodes.rows() << " nodes, dt " << spec.time_step_s
            << " s, force " << options.force_n << " N ramped over 20 ms, 0.3 s\n";
  std::cout << "scenario                  r  static  local err  field err  modal ns  DNIOS ns  speedup\n";
  for (const offline::AccuracyScenario& scenario : scenarios) {
    std::vector<offline::AccuracyPoint> points;
    for (std::size_t b = 0; b < builds.size(); ++b) {
      const int r = options.modes[b];
      for (const auto& point : value_or_throw(offline::measure_modal_accuracy(
               spec, builds[b], std::span<const int>(&r, 1), scenario))) {
        points.push_back(point);
      }
    }
    for (const offline::AccuracyPoint& p : points) {
      char line[200];
      std::snprintf(line, sizeof line, "%-24s %3d  %-6s  %9s  %9s  %8.0f  %8.0f  %7.1f\n",
                    p.scenario.c_str(), p.modes, p.static_correction ? "on" : "off",
                    (fixed(100.0 * p.local_error, 2) + "%").c_str(),
                    (fixed(100.0 * p.field_error, 2) + "%").c_str(), p.modal_step_ns,
                    p.reference_step_ns, p.speedup);
      std::cout << line;
      report["points"].push_back({{"scenario", p.scenario},
                                  {"load_node", p.load_node},
                                  {"modes", p.modes},
                                  {"static_correction", p.static_correction},
                                  {"local_error", p.local_error},
                                  {"final_local_error", p.final_local_error},
                                  {"field_error", p.field_error},
                                  {"modal_step_ns", p.modal_step_ns},
                                  {"reference_step_ns", p.reference_step_ns},
                                  {"speedup", p.speedup}});
    }
  }
  write_json(options.report_path, report);
}

}  // namespace

void add_build_command(CLI::App& app, int& exit_code) {
  auto options = std::make_shared<BuildOptions>();
  CLI::App* command = app.add_subcommand(
      "build", "Build the image of every model a scene names ([[model]] entries), each written "
               "where its definition file's [model] image says");
  command->add_option("--scene", options->scene_path, "scene file (TOML)")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_option("--only", options->only, "build only the model with this name");
  command->add_option("--report", options->report_path, "write a JSON report of the build");
  command->add_option("--error-budget", options->error_budget_percent,
                      "modal models: build the cheapest mode count (and static correction) whose "
                      "force error against DNIOS is within PCT % on held-out contact scenarios; "
                      "the budget and the measured error go in the image metadata")
      ->check(CLI::Range(0.001, 100.0));
  command->callback([options, &exit_code] {
    run_build(*options);
    exit_code = 0;
  });
}

void add_accuracy_command(CLI::App& app, int& exit_code) {
  auto options = std::make_shared<AccuracyOptions>();
  CLI::App* command = app.add_subcommand(
      "accuracy",
      "Error and per-step cost of the reduced-modal model (float32 runtime, r modes, static "
      "correction off/on) against direct Newmark integration of the full system (DNIOS), for "
      "radial pushes at mid-length and near the free end");
  command->add_option("--model", options->model_path, "model definition file (TOML)")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_option("--modes", options->modes, "mode counts to compare (e.g. 10,20,40)")
      ->delimiter(',')
      ->capture_default_str();
  command->add_option("--force", options->force_n, "peak force of the push (N)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_option("--report", options->report_path, "write the table as JSON");
  command->callback([options, &exit_code] {
    run_accuracy(*options);
    exit_code = 0;
  });
}

}  // namespace trainer::tools::modelc
