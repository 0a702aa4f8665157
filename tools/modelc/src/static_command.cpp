// `modelc static` (see static_command.hpp).
#include "static_command.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "command_line_values.hpp"
#include "trainer/model_offline/gmsh_reader.hpp"
#include "trainer/model_offline/loads.hpp"
#include "trainer/model_offline/mesh_generators.hpp"
#include "trainer/model_offline/shell_assembly.hpp"
#include "trainer/model_offline/static_solve.hpp"

namespace trainer::tools::modelc {
namespace {

namespace offline = model::offline;
using Clock = std::chrono::steady_clock;

template <class T>
T value_or_throw(core::Expected<T> result) {
  if (!result) throw std::runtime_error(result.error().message);
  return std::move(result).value();
}

void throw_if_error(const core::Expected<void>& result) {
  if (!result) throw std::runtime_error(result.error().message);
}

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

nlohmann::json vector_json(const Eigen::Vector3d& v) {
  return {v.x(), v.y(), v.z()};
}

std::string hash_text(std::uint64_t hash) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%016llx", static_cast<unsigned long long>(hash));
  return buffer;
}

}  // namespace

void run_static(const StaticOptions& options) {
  const offline::BendingElement element = parse_element(options.element);
  std::vector<offline::DofFix> fixes;
  for (const std::string& text : options.fixes) fixes.push_back(parse_fix(text));
  std::vector<GroupVector> loads;
  for (const std::string& text : options.loads) loads.push_back(parse_group_vector(text, "--load"));
  std::vector<GroupVector> surface_loads;
  for (const std::string& text : options.surface_loads) {
    surface_loads.push_back(parse_group_vector(text, "--surface-load"));
  }
  const offline::ShellMaterial material{options.young_modulus_pa, options.poisson_ratio,
                                        options.thickness_m, options.density_kg_per_m3};

  nlohmann::json inputs;
  offline::ShellMesh mesh;
  if (!options.mesh_path.empty()) {
    mesh = value_or_throw(offline::read_gmsh_shell(options.mesh_path));
    inputs["mesh"] = options.mesh_path;
  } else {
    const TubeSpec tube = parse_tube(options.tube);
    mesh =
        value_or_throw(offline::make_tube(tube.radius_m, tube.length_m, tube.rings, tube.segments));
    inputs["tube"] = {{"radius_m", tube.radius_m},
                      {"length_m", tube.length_m},
                      {"rings", tube.rings},
                      {"segments", tube.segments}};
  }
  inputs["element"] = element_name(element);
  inputs["material"] = {{"young_modulus_pa", material.young_modulus_pa},
                        {"poisson_ratio", material.poisson_ratio},
                        {"thickness_m", material.thickness_m},
                        {"density_kg_per_m3", material.density_kg_per_m3}};
  inputs["fixes"] = nlohmann::json::array();
  for (const offline::DofFix& fix : fixes) {
    nlohmann::json dofs = nlohmann::json::array();
    for (const int dof : fix.dofs) dofs.push_back(offline::shell_dof_name(dof));
    inputs["fixes"].push_back({{"group", fix.node_set}, {"dofs", dofs}});
  }
  inputs["loads"] = nlohmann::json::array();
  for (const GroupVector& load : loads) {
    inputs["loads"].push_back({{"group", load.group}, {"total_force_n", vector_json(load.value)}});
  }
  inputs["surface_loads"] = nlohmann::json::array();
  for (const GroupVector& load : surface_loads) {
    inputs["surface_loads"].push_back(
        {{"group", load.group}, {"traction_pa", vector_json(load.value)}});
  }

  const auto assembly_start = Clock::now();
  const offline::AssembledShell shell =
      value_or_throw(offline::assemble_shell(mesh, material, element, fixes));
  const double assembly_s = seconds_since(assembly_start);

  Eigen::VectorXd nodal_loads = offline::make_zero_loads(mesh);
  for (const GroupVector& load : loads) {
    throw_if_error(offline::add_node_set_force(mesh, load.group, load.value, nodal_loads));
  }
  for (const GroupVector& load : surface_loads) {
    throw_if_error(offline::add_surface_traction(mesh, load.group, load.value, nodal_loads));
  }

  const offline::ShellStaticSolver solver =
      value_or_throw(offline::ShellStaticSolver::create(shell));
  const offline::StaticSolution solution = value_or_throw(solver.solve(nodal_loads));

  double max_displacement_m = 0.0;
  int max_node = 0;
  for (Eigen::Index node = 0; node < solution.node_displacements.rows(); ++node) {
    const double magnitude = solution.node_displacements.row(node).head<3>().norm();
    if (magnitude > max_displacement_m) {
      max_displacement_m = magnitude;
      max_node = static_cast<int>(node);
    }
  }

  nlohmann::json report;
  report["command"] = "static";
  report["inputs"] = inputs;
  report["source_hash"] = hash_text(mesh.source_hash);
  const int total_dofs = static_cast<int>(mesh.nodes.rows()) * offline::kShellDofsPerNode;
  report["counts"] = {{"nodes", mesh.nodes.rows()},
                      {"triangles", mesh.triangles.rows()},
                      {"dofs", total_dofs},
                      {"free_dofs", shell.dofs.free_count()},
                      {"fixed_dofs", total_dofs - shell.dofs.free_count()}};
  report["timing_s"] = {{"assembly", assembly_s},
                        {"factorization", solver.factorization_time_s()},
                        {"solve", solution.solve_time_s}};
  report["total_applied_force_n"] = vector_json([&] {
    Eigen::Vector3d total = Eigen::Vector3d::Zero();
    for (Eigen::Index node = 0; node < mesh.nodes.rows(); ++node) {
      total += nodal_loads.segment<3>(node * offline::kShellDofsPerNode);
    }
    return total;
  }());
  nlohmann::json sets = nlohmann::json::object();
  for (const auto& [name, nodes] : mesh.node_sets) {
    nlohmann::json entries = nlohmann::json::array();
    for (const int node : nodes) {
      const auto row = solution.node_displacements.row(node);
      entries.push_back({{"index", node},
                         {"position_m", vector_json(mesh.nodes.row(node).transpose())},
                         {"displacement_m", {row(0), row(1), row(2)}},
                         {"rotation_rad", {row(3), row(4), row(5)}}});
    }
    sets[name] = entries;
  }
  report["node_sets"] = sets;
  report["max_displacement_m"] = max_displacement_m;
  report["max_displacement_node"] = max_node;

  std::ofstream file(options.report_path);
  if (!file) throw std::runtime_error(options.report_path + ": cannot open the report for writing");
  file << report.dump(2) << "\n";
  if (!file) throw std::runtime_error(options.report_path + ": write failed");

  std::cout << "modelc static: " << mesh.nodes.rows() << " nodes, " << mesh.triangles.rows()
            << " triangles, " << shell.dofs.free_count()
            << " free dofs; max |u| = " << max_displacement_m << " m at node " << max_node
            << "; report " << options.report_path << "\n";
}

void add_static_command(CLI::App& app, int& exit_code) {
  auto options = std::make_shared<StaticOptions>();
  CLI::App* command = app.add_subcommand(
      "static",
      "Linear static solve of the shell model (membrane + plate bending, 6 dofs per node: "
      "ux,uy,uz in m, rx,ry,rz in rad). SI units: m, Pa, N, kg/m^3.");
  auto* mesh = command
                   ->add_option("--mesh", options->mesh_path,
                                "Gmsh MSH 4.1 ASCII surface mesh (3-node triangles); "
                                "physical groups name the node sets")
                   ->check(CLI::ExistingFile);
  auto* tube = command->add_option(
      "--tube", options->tube,
      "generated tube along +x: R,L,RINGS,SEGMENTS (radius m, length m, node rings >= 2, nodes "
      "per ring >= 3); node sets clamped (x=0), free_end (x=L), all; triangle set wall");
  mesh->excludes(tube);
  tube->excludes(mesh);
  command->add_option("--element", options->element, "bending element: shell-dkt or shell-rao")
      ->required()
      ->check(CLI::IsMember({"shell-dkt", "shell-rao"}));
  command->add_option("--young", options->young_modulus_pa, "Young's modulus E (Pa), > 0")
      ->required();
  command->add_option("--poisson", options->poisson_ratio, "Poisson's ratio nu, -1 < nu < 0.5")
      ->required();
  command->add_option("--thickness", options->thickness_m, "shell thickness t (m), > 0")
      ->required();
  command
      ->add_option("--density", options->density_kg_per_m3,
                   "density (kg/m^3), > 0; only enters the lumped mass")
      ->capture_default_str();
  command->add_option("--fix", options->fixes,
                      "GROUP=DOFS: fix DOFS (comma list of x,y,z,rx,ry,rz, or all) on every node "
                      "of node set GROUP; repeatable");
  command->add_option("--load", options->loads,
                      "GROUP=FX,FY,FZ: total force (N, global frame) on node set GROUP, split "
                      "equally over its nodes (not the consistent edge load); repeatable");
  command->add_option("--surface-load", options->surface_loads,
                      "GROUP=PX,PY,PZ: traction (Pa = N/m^2, global frame) on triangle set GROUP, "
                      "as consistent nodal loads (p*A/3 per corner); repeatable");
  command->add_option("--report", options->report_path, "JSON report to write")->required();
  command->callback([options, command, &exit_code] {
    if (options->mesh_path.empty() && options->tube.empty()) {
      throw CLI::RequiredError(command->get_name() + ": one of --mesh or --tube");
    }
    try {
      run_static(*options);
      exit_code = 0;
    } catch (const std::exception& error) {
      std::cerr << "modelc static: " << error.what() << "\n";
      exit_code = 1;
    }
  });
}

}  // namespace trainer::tools::modelc
