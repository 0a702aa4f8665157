// `modelc static` (see static_command.hpp).
#include "static_command.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
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
#include "trainer/model_offline/tet_elasticity.hpp"
#include "trainer/model_offline/tet_mesh_generators.hpp"

namespace trainer::tools::modelc {
namespace {

namespace offline = model::offline;
using Clock = std::chrono::steady_clock;


void throw_if_error(const core::Expected<void>& result) {
  if (!result) throw std::runtime_error(result.error().message);
}

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

nlohmann::json vector_json(const Eigen::Vector3d& v) {
  return {v.x(), v.y(), v.z()};
}

// The node with the largest translation |u| (the first three columns of any displacement table).
struct LargestTranslation {
  double magnitude_m = 0.0;
  int node = 0;
};
template <class Table>
LargestTranslation largest_translation(const Table& displacements) {
  LargestTranslation largest;
  for (Eigen::Index node = 0; node < displacements.rows(); ++node) {
    const double magnitude = displacements.row(node).template head<3>().norm();
    if (magnitude > largest.magnitude_m) largest = {magnitude, static_cast<int>(node)};
  }
  return largest;
}

void write_report(const std::string& path, const nlohmann::json& report) {
  std::ofstream file(path);
  if (!file) throw std::runtime_error(path + ": cannot open the report for writing");
  file << report.dump(2) << "\n";
  if (!file) throw std::runtime_error(path + ": write failed");
}

std::string hash_text(std::uint64_t hash) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%016llx", static_cast<unsigned long long>(hash));
  return buffer;
}

// Splits "A,B,C" into numbers for the generator options; throws naming the option and the
// expected form. `integer_from` = index of the first field that must be an integer.
std::vector<double> parse_generator_values(const std::string& text, const std::string& option,
                                           std::size_t count, std::size_t integer_from,
                                           const std::string& expected) {
  std::vector<double> values;
  std::size_t start = 0;
  while (true) {
    const std::size_t end = text.find(',', start);
    std::string field =
        text.substr(start, end == std::string::npos ? std::string::npos : end - start);
    field.erase(0, field.find_first_not_of(" \t"));
    field.erase(field.find_last_not_of(" \t") + 1);
    const std::size_t index = values.size();
    double value = 0.0;
    bool ok = false;
    const char* first = field.data();
    const char* last = first + field.size();
    if (index >= integer_from) {
      int integer = 0;
      const auto [stop, error] = std::from_chars(first, last, integer);
      ok = !field.empty() && error == std::errc() && stop == last;
      value = integer;
    } else {
      if (first != last && *first == '+') ++first;
      const auto [stop, error] = std::from_chars(first, last, value);
      ok = !field.empty() && error == std::errc() && stop == last && std::isfinite(value);
    }
    if (!ok) {
      throw std::invalid_argument(option + " '" + text + "': field " + std::to_string(index + 1) +
                                  " '" + field + "' is not " +
                                  (index >= integer_from ? "an integer" : "a finite number") +
                                  "; expected " + expected);
    }
    values.push_back(value);
    if (end == std::string::npos) break;
    start = end + 1;
  }
  if (values.size() != count) {
    throw std::invalid_argument(option + " '" + text + "': " + std::to_string(values.size()) +
                                " values; expected " + expected);
  }
  return values;
}

// --fix for tet4: the translations only ("all" = x,y,z); a rotation is refused by name.
offline::TetNodeFix parse_tet_fix(const std::string& text, const offline::TetMesh& mesh,
                                  nlohmann::json& inputs) {
  const offline::DofFix fix = parse_fix(text);  // checks the syntax and the dof names
  std::string list = text.substr(text.find('=') + 1);
  list.erase(std::remove_if(list.begin(), list.end(), [](char c) { return c == ' ' || c == '\t'; }),
             list.end());
  for (const char* rotation : {"rx", "ry", "rz"}) {
    const std::string token = rotation;
    if (("," + list + ",").find("," + token + ",") != std::string::npos) {
      throw std::invalid_argument("--fix '" + text + "': " + token +
                                  " is a rotation, but --element tet4 nodes have only the "
                                  "translations x, y, z; expected GROUP=x,y,z (any subset) or all");
    }
  }
  offline::TetNodeFix result;
  nlohmann::json dofs = nlohmann::json::array();
  for (const int dof : fix.dofs) {
    if (dof >= offline::kTetDofsPerNode) continue;  // "all" lists the shell rotations too
    result.axes[static_cast<std::size_t>(dof)] = true;
    dofs.push_back(offline::shell_dof_name(dof));
  }
  const auto found = mesh.node_sets.find(fix.node_set);
  if (found == mesh.node_sets.end()) {
    std::string known;
    for (const auto& [name, nodes] : mesh.node_sets) known += (known.empty() ? "" : ", ") + name;
    throw std::invalid_argument("--fix '" + text + "': unknown node set '" + fix.node_set +
                                "' (the mesh has: " + (known.empty() ? "none" : known) + ")");
  }
  result.nodes = found->second;
  inputs["fixes"].push_back({{"group", fix.node_set}, {"dofs", dofs}});
  return result;
}

// The tet4 path of run_static (same report shape as the shell path, without rotations).
void run_static_tet(const StaticOptions& options) {
  if (!options.tube.empty()) {
    throw std::invalid_argument(
        "--tube makes a shell surface; --element tet4 needs a volume: "
        "use --mesh (tetrahedra), --box or --cylinder");
  }
  if (options.thickness_m != 0.0) {
    throw std::invalid_argument(
        "--thickness has no meaning for --element tet4 (a solid element); "
        "remove it");
  }
  std::vector<GroupVector> loads;
  for (const std::string& text : options.loads) loads.push_back(parse_group_vector(text, "--load"));
  std::vector<GroupVector> surface_loads;
  for (const std::string& text : options.surface_loads) {
    surface_loads.push_back(parse_group_vector(text, "--surface-load"));
  }
  const offline::TetMaterial material{options.young_modulus_pa, options.poisson_ratio,
                                      options.density_kg_per_m3};

  nlohmann::json inputs;
  offline::TetMesh mesh;
  if (!options.mesh_path.empty()) {
    mesh = value_or_throw(offline::read_gmsh_tet(options.mesh_path));
    inputs["mesh"] = options.mesh_path;
    // A mesh whose surface was not tagged still gets its boundary as set "surface".
    if (mesh.triangles.rows() == 0) {
      mesh.triangles = offline::boundary_triangles(mesh);
      std::vector<int> faces(static_cast<std::size_t>(mesh.triangles.rows()));
      std::vector<int> nodes;
      for (int f = 0; f < static_cast<int>(faces.size()); ++f) {
        faces[static_cast<std::size_t>(f)] = f;
        for (int c = 0; c < 3; ++c) nodes.push_back(mesh.triangles(f, c));
      }
      std::sort(nodes.begin(), nodes.end());
      nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
      mesh.triangle_sets.emplace("surface", std::move(faces));
      mesh.node_sets.emplace("surface", std::move(nodes));
    }
  } else if (!options.box.empty()) {
    const std::string expected =
        "LX,LY,LZ,NX,NY,NZ (box sizes in m > 0, hexahedra per direction >= 1)";
    const auto v = parse_generator_values(options.box, "--box", 6, 3, expected);
    const int nx = static_cast<int>(v[3]), ny = static_cast<int>(v[4]), nz = static_cast<int>(v[5]);
    auto box = offline::make_tet_box(v[0], v[1], v[2], nx, ny, nz);
    if (!box) throw std::invalid_argument("--box '" + options.box + "': " + box.error().message);
    mesh = std::move(box).value();
    inputs["box"] = {{"lx_m", v[0]}, {"ly_m", v[1]}, {"lz_m", v[2]},
                     {"nx", nx},     {"ny", ny},     {"nz", nz}};
  } else {
    const std::string expected =
        "R,H,RADIAL,AXIAL (radius m > 0, height m > 0, rings from axis to wall >= 1, layers "
        "along z >= 1)";
    const auto v = parse_generator_values(options.cylinder, "--cylinder", 4, 2, expected);
    const int radial = static_cast<int>(v[2]), axial = static_cast<int>(v[3]);
    auto cylinder = offline::make_tet_cylinder(v[0], v[1], radial, axial);
    if (!cylinder) {
      throw std::invalid_argument("--cylinder '" + options.cylinder +
                                  "': " + cylinder.error().message);
    }
    mesh = std::move(cylinder).value();
    inputs["cylinder"] = {
        {"radius_m", v[0]}, {"height_m", v[1]}, {"radial", radial}, {"axial", axial}};
  }
  throw_if_error(offline::validate_tet_mesh(mesh));
  inputs["element"] = "tet4";
  inputs["material"] = {{"young_modulus_pa", material.young_modulus_pa},
                        {"poisson_ratio", material.poisson_ratio},
                        {"density_kg_per_m3", material.density_kg_per_m3}};
  inputs["fixes"] = nlohmann::json::array();
  std::vector<offline::TetNodeFix> fixes;
  for (const std::string& text : options.fixes) fixes.push_back(parse_tet_fix(text, mesh, inputs));

  const auto assembly_start = Clock::now();
  const offline::AssembledTet assembled =
      value_or_throw(offline::assemble_tet(mesh, material, fixes));
  const double assembly_s = seconds_since(assembly_start);

  offline::TetNodalLoads nodal_loads = offline::TetNodalLoads::Zero(mesh.nodes.rows(), 3);
  inputs["loads"] = nlohmann::json::array();
  for (const GroupVector& load : loads) {
    const offline::TetLoadDistribution distribution =
        value_or_throw(offline::add_tet_group_force(mesh, load.group, load.value, nodal_loads));
    inputs["loads"].push_back(
        {{"group", load.group},
         {"total_force_n", vector_json(load.value)},
         {"distribution", distribution == offline::TetLoadDistribution::area_weighted
                              ? "area_weighted"
                              : "equal_per_node"}});
  }
  inputs["surface_loads"] = nlohmann::json::array();
  for (const GroupVector& load : surface_loads) {
    throw_if_error(offline::add_tet_surface_traction(mesh, load.group, load.value, nodal_loads));
    inputs["surface_loads"].push_back(
        {{"group", load.group}, {"traction_pa", vector_json(load.value)}});
  }

  const offline::TetStaticSolver solver =
      value_or_throw(offline::TetStaticSolver::create(assembled));
  const auto solve_start = Clock::now();
  const offline::TetNodalLoads displacements = value_or_throw(solver.solve_nodal(nodal_loads));
  const double solve_s = seconds_since(solve_start);

  const auto [max_displacement_m, max_node] = largest_translation(displacements);
  nlohmann::json report;
  report["command"] = "static";
  report["inputs"] = inputs;
  report["source_hash"] = hash_text(mesh.source_hash);
  const int total_dofs = static_cast<int>(mesh.nodes.rows()) * offline::kTetDofsPerNode;
  report["counts"] = {{"nodes", mesh.nodes.rows()},
                      {"tetrahedra", mesh.tetrahedra.rows()},
                      {"triangles", mesh.triangles.rows()},
                      {"dofs", total_dofs},
                      {"free_dofs", assembled.dofs.free_count},
                      {"fixed_dofs", total_dofs - assembled.dofs.free_count}};
  report["volume_m3"] = assembled.volume_m3;
  report["timing_s"] = {{"assembly", assembly_s},
                        {"factorization", solver.factorization_time_s()},
                        {"solve", solve_s}};
  report["total_applied_force_n"] = vector_json(nodal_loads.colwise().sum().transpose().eval());
  nlohmann::json sets = nlohmann::json::object();
  for (const auto& [name, nodes] : mesh.node_sets) {
    nlohmann::json entries = nlohmann::json::array();
    for (const int node : nodes) {
      entries.push_back({{"index", node},
                         {"position_m", vector_json(mesh.nodes.row(node).transpose())},
                         {"displacement_m", vector_json(displacements.row(node).transpose())}});
    }
    sets[name] = entries;
  }
  report["node_sets"] = sets;
  report["max_displacement_m"] = max_displacement_m;
  report["max_displacement_node"] = max_node;

  write_report(options.report_path, report);

  std::cout << "modelc static: " << mesh.nodes.rows() << " nodes, " << mesh.tetrahedra.rows()
            << " tetrahedra (tet4), " << assembled.dofs.free_count
            << " free dofs; max |u| = " << max_displacement_m << " m at node " << max_node
            << "; report " << options.report_path << "\n";
}

}  // namespace

void run_static(const StaticOptions& options) {
  if (options.element == "tet4") {
    run_static_tet(options);
    return;
  }
  if (!options.box.empty() || !options.cylinder.empty()) {
    throw std::invalid_argument(
        "--box and --cylinder make tetrahedral meshes; they need "
        "--element tet4 (got --element " +
        options.element + ")");
  }
  if (!(options.thickness_m > 0.0)) {
    throw std::invalid_argument("--thickness is required (> 0, m) for --element " +
                                options.element);
  }
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

  const auto [max_displacement_m, max_node] = largest_translation(solution.node_displacements);

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

  write_report(options.report_path, report);

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
      "ux,uy,uz in m, rx,ry,rz in rad) or, with --element tet4, of the linear tetrahedral "
      "model (3 dofs per node: ux,uy,uz in m). SI units: m, Pa, N, kg/m^3.");
  auto* mesh = command
                   ->add_option("--mesh", options->mesh_path,
                                "Gmsh MSH 4.1 ASCII mesh: 3-node triangles for the shells, "
                                "4-node tetrahedra for tet4; physical groups name the node sets")
                   ->check(CLI::ExistingFile);
  auto* tube = command->add_option(
      "--tube", options->tube,
      "generated tube along +x: R,L,RINGS,SEGMENTS (radius m, length m, node rings >= 2, nodes "
      "per ring >= 3); node sets clamped (x=0), free_end (x=L), all; triangle set wall");
  auto* box = command->add_option(
      "--box", options->box,
      "generated tet4 box [0,LX]x[0,LY]x[0,LZ]: LX,LY,LZ,NX,NY,NZ (sizes m, hexahedra per "
      "direction >= 1, 6 tetrahedra each); node and triangle sets x0,x1,y0,y1,z0,z1 (faces), "
      "surface; node set all");
  auto* cylinder = command->add_option(
      "--cylinder", options->cylinder,
      "generated tet4 solid cylinder about z: R,H,RADIAL,AXIAL (radius m, height m, rings from "
      "axis to wall >= 1, layers >= 1); node and triangle sets bottom (z=0), top (z=H), side, "
      "surface; node sets top_center, all");
  const std::vector<CLI::Option*> sources{mesh, tube, box, cylinder};
  for (CLI::Option* source : sources) {
    for (CLI::Option* other : sources) {
      if (other != source) source->excludes(other);
    }
  }
  command
      ->add_option("--element", options->element,
                   "element: shell-dkt or shell-rao (shells), tet4 (linear tetrahedron)")
      ->required()
      ->check(CLI::IsMember({"shell-dkt", "shell-rao", "tet4"}));
  command->add_option("--young", options->young_modulus_pa, "Young's modulus E (Pa), > 0")
      ->required();
  command->add_option("--poisson", options->poisson_ratio, "Poisson's ratio nu, -1 < nu < 0.5")
      ->required();
  command->add_option("--thickness", options->thickness_m,
                      "shell thickness t (m), > 0; required for the shells, refused for tet4");
  command
      ->add_option("--density", options->density_kg_per_m3,
                   "density (kg/m^3), > 0; only enters the lumped mass")
      ->capture_default_str();
  command->add_option("--fix", options->fixes,
                      "GROUP=DOFS: fix DOFS (comma list of x,y,z,rx,ry,rz, or all; tet4: x,y,z "
                      "or all) on every node of node set GROUP; repeatable");
  command->add_option("--load", options->loads,
                      "GROUP=FX,FY,FZ: total force (N, global frame) on node set GROUP, split "
                      "equally over its nodes (not the consistent edge load); tet4: spread by "
                      "area over triangle set GROUP when it exists (a uniform traction), else "
                      "equally over node set GROUP; repeatable");
  command->add_option("--surface-load", options->surface_loads,
                      "GROUP=PX,PY,PZ: traction (Pa = N/m^2, global frame) on triangle set GROUP, "
                      "as consistent nodal loads (p*A/3 per corner); repeatable");
  command->add_option("--report", options->report_path, "JSON report to write")->required();
  command->callback([options, command, &exit_code] {
    if (options->mesh_path.empty() && options->tube.empty() && options->box.empty() &&
        options->cylinder.empty()) {
      throw CLI::RequiredError(command->get_name() +
                               ": one of --mesh or --tube (shells), --mesh, --box or --cylinder "
                               "(tet4)");
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
