// tradeoff: the speed/accuracy trade of every model a scene names, measured. For each knob a
// user trades (the duct's mode count, static correction, bending element, runtime precision
// and time step; the catheter's particle count; the tensor model's contact cap) it measures the
// cost per cycle (warm-up, repetitions, median and p99) and the error of the force felt against
// the model's reference over contact scenarios, then writes CSV and JSON, a Pareto plot per
// model and the cheapest configuration for each error budget. Usage: `tradeoff --help`;
// results and how to read them: docs/performance.md, "Speed/accuracy trade".
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "model_spec.hpp"
#include "pareto.hpp"
#include "trainer/app/haptic_app.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/model_offline/catheter_tradeoff.hpp"
#include "trainer/model_offline/modal_tradeoff.hpp"
#include "trainer/model_offline/tensor_tradeoff.hpp"

namespace {

namespace offline = trainer::model::offline;
namespace config = trainer::config;
using trainer::tools::tradeoff::TradePoint;

struct Options {
  std::string scene_path;
  std::string out_directory = "out/tradeoff";
  std::string only;
  bool quick = false;
  std::vector<double> budgets_percent{1.0, 2.0, 5.0, 10.0};
  double reference_step_us = 250.0;
  offline::CycleCostOptions cost;
};

template <class T>
T value_or_throw(trainer::core::Expected<T> expected) {
  if (!expected) throw std::runtime_error(expected.error().message);
  return std::move(expected).value();
}

std::string format(const char* pattern, double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, pattern, value);
  return buffer;
}

// Cost of one configuration per millisecond of simulated time: a 4 kHz model costs four cycles
// where a 1 kHz one costs one.
double cost_per_ms_ns(const offline::ModalTradePoint& point) {
  return point.cost.median_ns * (1e-3 / point.config.time_step_s);
}

struct SweepEntry {
  std::string sweep;
  offline::ModalTradeConfig config;
};

std::vector<SweepEntry> duct_sweep(const offline::ModalBuildSpec& definition, bool quick) {
  std::vector<SweepEntry> sweep;
  offline::ModalTradeConfig base;
  base.element = definition.bending;
  base.time_step_s = definition.time_step_s;
  const std::vector<int> modes = quick ? std::vector<int>{5, 10, 40}
                                       : std::vector<int>{5, 10, 20, 40, 80, 160};
  for (int r : modes) {
    for (bool correction : {false, true}) {
      offline::ModalTradeConfig c = base;
      c.modes = r;
      c.static_correction = correction;
      sweep.push_back({"modes x static correction", c});
    }
  }
  const offline::BendingElement other = definition.bending == offline::BendingElement::dkt
                                            ? offline::BendingElement::rao
                                            : offline::BendingElement::dkt;
  for (int r : quick ? std::vector<int>{40} : std::vector<int>{10, 20, 40, 80}) {
    offline::ModalTradeConfig c = base;
    c.modes = r;
    c.element = other;
    sweep.push_back({other == offline::BendingElement::rao ? "Rao element" : "DKT element", c});
  }
  for (int r : quick ? std::vector<int>{40} : std::vector<int>{10, 20, 40, 80}) {
    offline::ModalTradeConfig c = base;
    c.modes = r;
    c.precision = offline::RuntimePrecision::float64;
    sweep.push_back({"double at run time (static correction)", c});
  }
  // The time step is the loop period: a scene's [loop] period_us, not an image knob.
  for (double step_s : quick ? std::vector<double>{5e-4} : std::vector<double>{2.5e-4, 5e-4, 2e-3}) {
    if (std::abs(step_s - base.time_step_s) < 1e-12) continue;
    for (int r : quick ? std::vector<int>{40} : std::vector<int>{5, 10, 20, 40}) {
      offline::ModalTradeConfig c = base;
      c.modes = r;
      c.time_step_s = step_s;
      sweep.push_back({"time step x modes (static correction)", c});
    }
  }
  return sweep;
}

nlohmann::json run_duct(const Options& options, const std::string& name,
                        const config::ModelDefinition& definition,
                        const std::filesystem::path& directory) {
  const offline::ModalBuildSpec spec =
      value_or_throw(trainer::tools::modelc::modal_spec_from(definition));
  std::vector<offline::ContactScenario> scenarios = offline::default_duct_scenarios(spec.mesh);
  std::cout << "model '" << name << "' (modal shell, " << spec.mesh.nodes.rows()
            << " nodes): reference = DNIOS at " << options.reference_step_us << " us, "
            << scenarios.size() << " scenarios\n";
  auto study = value_or_throw(offline::DuctTradeStudy::create(
      spec, std::move(scenarios), options.reference_step_us * 1e-6));
  std::cout << "  reference built in " << format("%.2f", study->reference_build_s())
            << " s, DNIOS step median " << format("%.0f", study->reference_step_ns()) << " ns\n";

  std::vector<offline::ModalTradePoint> points;
  std::vector<std::string> sweeps;
  for (const SweepEntry& entry : duct_sweep(spec, options.quick)) {
    offline::ModalTradePoint point = value_or_throw(study->measure(entry.config, options.cost));
    std::printf("  %-28s %-26s cost %8.0f ns (p99 %8.0f)  tuning %7.3f %%  held-out %7.3f %%\n",
                entry.sweep.c_str(), point.config.label().c_str(), point.cost.median_ns,
                point.cost.p99_ns, 100.0 * point.tuning_error, 100.0 * point.validation_error);
    points.push_back(std::move(point));
    sweeps.push_back(entry.sweep);
  }

  // CSV: one row per configuration, and one per configuration and scenario.
  {
    std::ofstream csv(directory / (name + ".csv"));
    csv << "sweep,label,modes,static_correction,element,precision,time_step_us,precompute_s,"
           "data_bytes,cost_median_ns,cost_p99_ns,haptic_median_ns,haptic_p99_ns,"
           "repetition_median_min_ns,repetition_median_max_ns,cost_per_ms_ns,tuning_error,"
           "validation_error,worst_error,worst_peak_error\n";
    for (std::size_t i = 0; i < points.size(); ++i) {
      const auto& p = points[i];
      csv << '"' << sweeps[i] << "\",\"" << p.config.label() << "\"," << p.config.modes << ','
          << (p.config.static_correction ? 1 : 0) << ','
          << (p.config.element == offline::BendingElement::dkt ? "dkt" : "rao") << ','
          << offline::to_string(p.config.precision) << ',' << p.config.time_step_s * 1e6 << ','
          << p.precompute_s << ',' << p.data_bytes << ',' << p.cost.median_ns << ','
          << p.cost.p99_ns << ',' << p.cost.haptic_median_ns << ',' << p.cost.haptic_p99_ns << ','
          << p.cost.repetition_median_min_ns << ',' << p.cost.repetition_median_max_ns << ','
          << cost_per_ms_ns(p) << ',' << p.tuning_error << ',' << p.validation_error << ','
          << p.worst_error << ',' << p.worst_peak_error << '\n';
    }
    std::ofstream scenarios_csv(directory / (name + "_scenarios.csv"));
    scenarios_csv << "label,scenario,tuning,contact_node,peak_error,rms_error,"
                     "reference_peak_force_n\n";
    for (const auto& p : points) {
      for (const auto& e : p.errors) {
        scenarios_csv << '"' << p.config.label() << "\"," << e.scenario << ','
                      << (e.tuning ? 1 : 0) << ',' << e.contact_node << ',' << e.peak_error << ','
                      << e.rms_error << ',' << e.reference_peak_force_n << '\n';
      }
    }
  }

  std::vector<TradePoint> plotted;
  for (std::size_t i = 0; i < points.size(); ++i) {
    plotted.push_back({sweeps[i], points[i].config.label(), points[i].worst_error,
                       cost_per_ms_ns(points[i])});
  }
  const std::string plot_problem = trainer::tools::tradeoff::plot_pareto(
      directory, name, "'" + name + "': force error vs DNIOS against cost (Pareto front joined)",
      "force error, worst scenario (RMS over time, % of the reference RMS)", plotted);
  if (!plot_problem.empty()) std::cerr << "tradeoff: " << plot_problem << "\n";

  // Recommendation per budget, chosen on the tuning scenarios and checked on the held-out ones
  // (as `modelc build --error-budget` does): (a) among what an image carries — mode count and
  // static correction at the definition's element and time step; (b) also trading the loop
  // period (time step), by cost per millisecond of simulated time.
  std::vector<offline::ModalTradePoint> image_points;
  std::vector<offline::ModalTradePoint> period_points;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (sweeps[i] == "modes x static correction") image_points.push_back(points[i]);
    if (points[i].config.element == spec.bending &&
        points[i].config.precision == offline::RuntimePrecision::float32) {
      period_points.push_back(points[i]);
    }
  }
  nlohmann::json recommendations = nlohmann::json::array();
  const auto recommend = [&](const std::vector<offline::ModalTradePoint>& candidates,
                             const std::string& among) {
    std::cout << "  recommendation, " << among << ":\n";
    for (double budget_percent : options.budgets_percent) {
      std::vector<std::string> log;
      auto selected = offline::select_for_budget(candidates, budget_percent / 100.0, &log);
      if (!selected) {
        std::cout << "    budget " << budget_percent << " %: " << selected.error().message << "\n";
        recommendations.push_back({{"among", among},
                                   {"budget_percent", budget_percent},
                                   {"met", false},
                                   {"reason", selected.error().message}});
        continue;
      }
      const auto& chosen = candidates[*selected];
      std::printf("    budget %5.2f %%: r = %d, static correction %s, step %.0f us: %.0f ns per "
                  "cycle (p99 %.0f), %.0f ns per ms; tuning error %.3f %%, held-out %.3f %%\n",
                  budget_percent, chosen.config.modes,
                  chosen.config.static_correction ? "on" : "off", chosen.config.time_step_s * 1e6,
                  chosen.cost.median_ns, chosen.cost.p99_ns, cost_per_ms_ns(chosen),
                  100.0 * chosen.tuning_error, 100.0 * chosen.validation_error);
      recommendations.push_back({{"among", among},
                                 {"budget_percent", budget_percent},
                                 {"met", true},
                                 {"modes", chosen.config.modes},
                                 {"static_correction", chosen.config.static_correction},
                                 {"time_step_s", chosen.config.time_step_s},
                                 {"label", chosen.config.label()},
                                 {"cost_median_ns", chosen.cost.median_ns},
                                 {"cost_p99_ns", chosen.cost.p99_ns},
                                 {"cost_per_ms_ns", cost_per_ms_ns(chosen)},
                                 {"tuning_error", chosen.tuning_error},
                                 {"validation_error", chosen.validation_error},
                                 {"passed_over", log}});
    }
  };
  recommend(image_points, "image knobs at the definition's time step (modelc build --error-budget)");
  recommend(period_points, "image knobs and the loop period");
  nlohmann::json front = nlohmann::json::array();
  for (std::size_t i : trainer::tools::tradeoff::pareto_front(plotted)) {
    front.push_back({{"label", plotted[i].label},
                     {"error", plotted[i].error},
                     {"cost_per_ms_ns", plotted[i].cost_ns}});
  }
  nlohmann::json scenario_json = nlohmann::json::array();
  for (const auto& s : study->scenarios()) {
    scenario_json.push_back({{"name", s.name}, {"description", s.description}, {"tuning", s.tuning}});
  }
  return {{"name", name},
          {"kind", "modal_shell"},
          {"definition", definition.source_path.string()},
          {"reference", "DNIOS (full Newmark, double) with the same imposed displacement"},
          {"reference_time_step_s", study->reference_time_step_s()},
          {"reference_step_median_ns", study->reference_step_ns()},
          {"scenarios", scenario_json},
          {"csv", (directory / (name + ".csv")).string()},
          {"plot", plot_problem.empty() ? (directory / (name + ".png")).string() : ""},
          {"pareto_front", front},
          {"recommendations", recommendations}};
}

// The cheapest measured configuration within `budget` on the tuning scenarios and then on the
// held-out ones (the duct's rule, modal_tradeoff.hpp, for models with one knob): index or none.
struct SimplePoint {
  std::string label;
  bool usable = true;  // false: refused at start (e.g. over the catheter's substep budget)
  double cost_ns = 0.0;
  double tuning_error = 0.0;
  double validation_error = 0.0;
};

nlohmann::json recommend_simple(const std::vector<SimplePoint>& points,
                                const std::vector<double>& budgets_percent) {
  std::vector<std::size_t> order(points.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return points[a].cost_ns < points[b].cost_ns; });
  nlohmann::json recommendations = nlohmann::json::array();
  std::cout << "  recommendation (cheapest within the budget on the tuning scenarios, then on the "
               "held-out ones; refused configurations excluded):\n";
  for (double budget_percent : budgets_percent) {
    const double budget = budget_percent / 100.0;
    const auto found = std::find_if(order.begin(), order.end(), [&](std::size_t i) {
      return points[i].usable && points[i].tuning_error <= budget &&
             points[i].validation_error <= budget;
    });
    if (found == order.end()) {
      std::printf("    budget %5.2f %%: no usable configuration meets it\n", budget_percent);
      recommendations.push_back({{"budget_percent", budget_percent}, {"met", false}});
      continue;
    }
    const SimplePoint& chosen = points[*found];
    std::printf("    budget %5.2f %%: %s, %.0f ns per cycle, error %.3f %% tuning, %.3f %% held out\n",
                budget_percent, chosen.label.c_str(), chosen.cost_ns, 100.0 * chosen.tuning_error,
                100.0 * chosen.validation_error);
    recommendations.push_back({{"budget_percent", budget_percent},
                               {"met", true},
                               {"label", chosen.label},
                               {"cost_median_ns", chosen.cost_ns},
                               {"tuning_error", chosen.tuning_error},
                               {"validation_error", chosen.validation_error}});
  }
  return recommendations;
}

nlohmann::json run_catheter(const Options& options, const std::string& name,
                            const config::ModelDefinition& definition,
                            const std::filesystem::path& directory) {
  const config::CatheterConfig& cfg = definition.catheter;
  offline::CatheterStudySpec spec;
  spec.params.length_m = static_cast<float>(cfg.length_m);
  spec.params.outer_radius_m = static_cast<float>(cfg.outer_radius_m);
  spec.params.bending_stiffness_n_m2 = static_cast<float>(cfg.bending_stiffness_n_m2);
  spec.params.axial_stiffness_n = static_cast<float>(cfg.axial_stiffness_n);
  spec.params.linear_density_kg_per_m = static_cast<float>(cfg.linear_density_kg_per_m);
  spec.params.damping_n_s_per_m = static_cast<float>(cfg.damping_n_s_per_m);
  spec.params.particle_count = cfg.particle_count;
  spec.params.contact_stiffness_n_per_m = trainer::model::catheter_contact_stiffness(
      static_cast<float>(cfg.wall_stiffness_n_per_m), static_cast<float>(cfg.tool_stiffness_n_per_m));
  spec.max_substeps = cfg.max_substeps;
  spec.contact.stiffness_n_per_m = cfg.wall_stiffness_n_per_m;
  spec.contact.damping_n_s_per_m = cfg.wall_damping_n_s_per_m;
  spec.contact.max_force_n = cfg.max_contact_force_n;
  // The reference: N = 81 in double, extrapolated with N = 41 (--quick: 41 with 21).
  spec.reference_particle_count = options.quick ? 41U : 81U;
  std::cout << "model '" << name << "' (particle catheter, L " << cfg.length_m
            << " m, definition N = " << cfg.particle_count << ", budget " << cfg.max_substeps
            << " substeps): reference N = " << spec.reference_particle_count
            << " in double, Richardson-extrapolated with the order observed against N/2 and N/4\n";
  auto study = value_or_throw(offline::CatheterTradeStudy::create(
      spec, offline::default_catheter_scenarios(cfg.length_m)));
  std::cout << "  reference runs " << format("%.1f", study->reference_run_s()) << " s";
  nlohmann::json orders = nlohmann::json::array();
  for (std::size_t k = 0; k < study->reference_orders().size(); ++k) {
    const auto& order = study->reference_orders()[k];
    const std::string& scenario = study->scenarios()[k].name;
    std::cout << (k == 0 ? "; observed order (shape/grasp force): " : ", ") << scenario << ' '
              << format("%.2f", order.shape) << '/'
              << (order.force > 0.0 ? format("%.2f", order.force) : std::string("-"));
    orders.push_back({{"scenario", scenario}, {"shape", order.shape}, {"grasp_force", order.force}});
  }
  std::cout << "\n";

  const std::vector<std::uint32_t> counts = options.quick ? std::vector<std::uint32_t>{6, 11}
                                                          : std::vector<std::uint32_t>{6, 11, 16, 21, 31, 41};
  std::vector<offline::CatheterTradePoint> points;
  for (std::uint32_t count : counts) {
    offline::CatheterTradePoint point =
        value_or_throw(study->measure({count}, options.cost, /*measure_beyond_budget=*/true));
    std::printf("  N %3u: %3u substeps%s  cost %9.0f ns (p99 %9.0f)  tuning %7.3f %%  held-out %7.3f %%\n",
                count, point.substeps_per_period, point.refused ? " (refused: over budget)" : "",
                point.cost.median_ns, point.cost.p99_ns, 100.0 * point.tuning_error,
                100.0 * point.validation_error);
    points.push_back(std::move(point));
  }
  {
    std::ofstream csv(directory / (name + ".csv"));
    csv << "label,particles,substeps_per_period,stable_substep_us,refused,cost_median_ns,cost_p99_ns,"
           "step_median_ns,tuning_error,validation_error,worst_error\n";
    std::ofstream scenarios_csv(directory / (name + "_scenarios.csv"));
    scenarios_csv << "label,scenario,tuning,force_error,force_error_per_period,tip_error,"
                     "shape_error,error,reference_peak_force_n\n";
    for (const auto& p : points) {
      csv << p.config.label() << ',' << p.config.particle_count << ',' << p.substeps_per_period
          << ',' << p.stable_substep_s * 1e6 << ',' << (p.refused ? 1 : 0) << ','
          << p.cost.median_ns << ',' << p.cost.p99_ns << ',' << p.cost.haptic_median_ns << ','
          << p.tuning_error << ',' << p.validation_error << ',' << p.worst_error << '\n';
      for (const auto& e : p.errors) {
        scenarios_csv << p.config.label() << ',' << e.scenario << ',' << (e.tuning ? 1 : 0) << ','
                      << e.force_error << ',' << e.force_error_per_period << ',' << e.tip_error
                      << ',' << e.shape_error << ',' << e.error << ','
                      << e.reference_peak_force_n << '\n';
      }
    }
  }
  std::vector<TradePoint> plotted;
  std::vector<SimplePoint> simple;
  for (const auto& p : points) {
    plotted.push_back({p.refused ? "over the substep budget (refused at start)" : "particle count",
                       p.config.label(), p.worst_error, p.cost.median_ns});
    simple.push_back({p.config.label(), !p.refused, p.cost.median_ns, p.tuning_error,
                      p.validation_error});
  }
  const std::string plot_problem = trainer::tools::tradeoff::plot_pareto(
      directory, name, "'" + name + "': grasp force and shape error vs extrapolated fine chain",
      "error, worst scenario (max of grasp-force and shape error, %)", plotted);
  if (!plot_problem.empty()) std::cerr << "tradeoff: " << plot_problem << "\n";
  return {{"name", name},
          {"kind", "catheter"},
          {"definition", definition.source_path.string()},
          {"reference", "the same chain in double at N = " +
                            std::to_string(spec.reference_particle_count) +
                            ", Richardson-extrapolated with the observed order"},
          {"reference_orders", orders},
          {"csv", (directory / (name + ".csv")).string()},
          {"plot", plot_problem.empty() ? (directory / (name + ".png")).string() : ""},
          {"recommendations", recommend_simple(simple, options.budgets_percent)}};
}

nlohmann::json run_tensor(const Options& options, const std::string& name,
                          const config::ModelDefinition& definition,
                          const std::filesystem::path& directory) {
  offline::TensorStudySpec spec;
  spec.mesh = value_or_throw(trainer::tools::modelc::tet_mesh_from(definition));
  spec.fixes = value_or_throw(trainer::tools::modelc::tet_fixes_from(definition, spec.mesh));
  spec.material = {definition.material.young_modulus_pa, definition.material.poisson_ratio,
                   definition.material.density_kg_per_m3};
  spec.contact_set = definition.tensor.contact_set;
  spec.nonlinear = value_or_throw(trainer::app::tensor_settings_from(definition)).nonlinear;
  const auto set = spec.mesh.node_sets.find(spec.contact_set);
  if (set == spec.mesh.node_sets.end()) {
    throw std::runtime_error(definition.source_path.string() + ": [tensor] contact_set '" +
                             spec.contact_set + "' is not a node set of the mesh");
  }
  std::vector<int> fixed;
  for (const auto& fix : spec.fixes) fixed.insert(fixed.end(), fix.nodes.begin(), fix.nodes.end());
  std::sort(fixed.begin(), fixed.end());
  std::vector<int> contacts;
  for (int node : set->second) {
    if (!std::binary_search(fixed.begin(), fixed.end(), node)) contacts.push_back(node);
  }
  std::sort(contacts.begin(), contacts.end());
  contacts.erase(std::unique(contacts.begin(), contacts.end()), contacts.end());
  auto scenarios = value_or_throw(offline::default_tensor_scenarios(spec.mesh, contacts));
  std::cout << "model '" << name << "' (tensor model, " << spec.mesh.nodes.rows()
            << " nodes): reference = direct sparse solve with every probe-covered node\n";
  auto study = value_or_throw(offline::TensorTradeStudy::create(std::move(spec), std::move(scenarios)));
  std::cout << "  precompute " << format("%.1f", study->precompute_s()) << " s, reference solves "
            << format("%.1f", study->reference_solve_s()) << " s, largest contact set "
            << study->largest_contact_set() << " nodes\n";
  const std::vector<std::uint32_t> caps = options.quick ? std::vector<std::uint32_t>{1, 4, 8}
                                                        : std::vector<std::uint32_t>{1, 2, 3, 4, 6, 8, 12, 16};
  std::vector<offline::TensorTradePoint> points;
  for (std::uint32_t cap : caps) {
    offline::TensorTradePoint point = value_or_throw(study->measure({cap}, options.cost));
    std::printf("  m %2u: solve %8.0f ns, solve + field %8.0f ns (p99 %8.0f)  tuning %9.5f %%  held-out %9.5f %%\n",
                cap, point.cost.haptic_median_ns, point.cost.median_ns, point.cost.p99_ns,
                100.0 * point.tuning_error, 100.0 * point.validation_error);
    points.push_back(std::move(point));
  }
  {
    std::ofstream csv(directory / (name + ".csv"));
    csv << "label,max_contacts,solve_median_ns,solve_p99_ns,solve_and_field_median_ns,"
           "solve_and_field_p99_ns,state_bytes,tuning_error,validation_error,worst_error\n";
    std::ofstream scenarios_csv(directory / (name + "_scenarios.csv"));
    scenarios_csv << "label,scenario,tuning,radius_m,covered_nodes,contact_nodes,imposed_nodes,"
                     "force_error,direction_error_rad,reference_force_n\n";
    for (const auto& p : points) {
      csv << p.config.label() << ',' << p.config.max_contacts << ',' << p.cost.haptic_median_ns
          << ',' << p.cost.haptic_p99_ns << ',' << p.cost.median_ns << ',' << p.cost.p99_ns << ','
          << p.state_bytes << ',' << p.tuning_error << ',' << p.validation_error << ','
          << p.worst_error << '\n';
      for (const auto& e : p.errors) {
        scenarios_csv << p.config.label() << ',' << e.scenario << ',' << (e.tuning ? 1 : 0) << ','
                      << e.radius_m << ',' << e.covered_nodes << ',' << e.contact_nodes << ','
                      << e.imposed_nodes << ',' << e.force_error << ',' << e.direction_error_rad
                      << ',' << e.reference_force_n << '\n';
      }
    }
  }
  // The haptic cycle needs the forces (solve); the field is graphics' and collision's.
  std::vector<TradePoint> plotted;
  std::vector<SimplePoint> simple;
  for (const auto& p : points) {
    plotted.push_back({"contact cap m (solve)", p.config.label(), p.worst_error,
                       p.cost.haptic_median_ns});
    simple.push_back({p.config.label(), true, p.cost.haptic_median_ns, p.tuning_error,
                      p.validation_error});
  }
  const std::string plot_problem = trainer::tools::tradeoff::plot_pareto(
      directory, name, "'" + name + "': probe force error vs direct solve against solve cost",
      "total probe force error, worst scenario and depth (%)", plotted);
  if (!plot_problem.empty()) std::cerr << "tradeoff: " << plot_problem << "\n";
  return {{"name", name},
          {"kind", "tet_tensor"},
          {"definition", definition.source_path.string()},
          {"reference", "direct sparse solve (double) with every probe-covered node imposed"},
          {"csv", (directory / (name + ".csv")).string()},
          {"plot", plot_problem.empty() ? (directory / (name + ".png")).string() : ""},
          {"recommendations", recommend_simple(simple, options.budgets_percent)}};
}

int run(const Options& options) {
  config::LoadOptions load;
  load.require_script_file = false;
  const config::SceneConfig scene = value_or_throw(config::load_scene(options.scene_path, load));
  const std::filesystem::path directory = std::filesystem::path(options.out_directory) / scene.name;
  std::filesystem::create_directories(directory);
  nlohmann::json summary = {{"scene", options.scene_path},
                            {"quick", options.quick},
                            {"cost_options",
                             {{"warmup_cycles", options.cost.warmup_cycles},
                              {"repetitions", options.cost.repetitions},
                              {"cycles_per_repetition", options.cost.cycles_per_repetition}}},
                            {"models", nlohmann::json::array()}};
  for (const config::SceneModelConfig& entry : scene.models) {
    if (!options.only.empty() && entry.name != options.only) continue;
    switch (entry.definition.kind) {
      case config::ModelKind::modal_shell:
        summary["models"].push_back(run_duct(options, entry.name, entry.definition, directory));
        break;
      case config::ModelKind::catheter:
        summary["models"].push_back(run_catheter(options, entry.name, entry.definition, directory));
        break;
      case config::ModelKind::tet_tensor:
        summary["models"].push_back(run_tensor(options, entry.name, entry.definition, directory));
        break;
    }
  }
  const auto summary_path = directory / "summary.json";
  std::ofstream(summary_path) << summary.dump(2) << "\n";
  std::cout << "tradeoff: results in " << directory.string() << " (summary.json, <model>.csv, "
            << "<model>.png)\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"tradeoff: cost per cycle against error for the knobs of a scene's models"};
  Options options;
  app.add_option("--scene", options.scene_path, "scene file (TOML)")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--out", options.out_directory, "output directory (a subdirectory per scene)")
      ->capture_default_str();
  app.add_option("--only", options.only, "study only the model of this name");
  app.add_flag("--quick", options.quick,
               "fewer configurations and cycles (a smoke test; the numbers are not for docs)");
  app.add_option("--budgets", options.budgets_percent, "error budgets to recommend for, in %")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--reference-step-us", options.reference_step_us,
                 "DNIOS reference time step (must divide every configuration's step)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--warmup", options.cost.warmup_cycles, "untimed cycles before timing")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--repetitions", options.cost.repetitions, "timed repetitions")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--cycles", options.cost.cycles_per_repetition, "cycles per repetition")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  if (options.quick) {
    options.cost.warmup_cycles = std::min(options.cost.warmup_cycles, 200);
    options.cost.repetitions = std::min(options.cost.repetitions, 2);
    options.cost.cycles_per_repetition = std::min(options.cost.cycles_per_repetition, 300);
  }
  try {
    return run(options);
  } catch (const std::exception& error) {
    std::cerr << "tradeoff: " << error.what() << "\n";
    return 1;
  }
}
