// `modelc static` (the real binary, MODELC_PATH) against published shell results, on the Gmsh
// fixtures that tools/gen_plate_msh.py writes (docs/model-verification.md):
//   * clamped square plate under uniform pressure q: centre deflection w_c = 0.00126 q a⁴ / D,
//     D = E t³ / (12 (1 − ν²)) (Timoshenko & Woinowsky-Krieger, Theory of Plates and Shells,
//     2nd ed. 1959, §44 Table 35, ν = 0.3). Tolerance 2 %: DKT on this 16 × 16 alternating mesh
//     is measured 1.1 % above the series value (discretisation error, shell_benchmark_test); a
//     wrong bending scale (t³, D, a load factor) moves the answer by far more.
//   * Scordelis–Lo roof (MacNeal & Harder, Finite Elements in Analysis and Design 1, 1985):
//     vertical drop of the free edge at mid-span 0.3024. Tolerance 3 % on the 32 × 32 quarter:
//     DKT + CST facets converge from below and measure 1.5 % low there (CST membrane stiffness).
// Each CLI answer is also compared with the library on the generator's own mesh, to round-off:
// the file, the reader, the group → fix/load mapping and the report add nothing.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <numbers>
#include <sstream>
#include <string>

#include "command_test_support.hpp"
#include "trainer/model_offline/gmsh_reader.hpp"
#include "trainer/model_offline/loads.hpp"
#include "trainer/model_offline/mesh_generators.hpp"
#include "trainer/model_offline/shell_assembly.hpp"
#include "trainer/model_offline/static_solve.hpp"

namespace trainer::model::offline {
namespace {

namespace fs = std::filesystem;

const std::string kSourceDir = TRAINER_SOURCE_DIR;
const std::string kDataDir = kSourceDir + "/tests/model/offline/data/";
const std::string kPlateMesh = kDataDir + "clamped_plate_16.msh";
const std::string kRoofMesh = kDataDir + "scordelis_lo_quarter_32.msh";

// The plate fixture's parameters (tools/gen_plate_msh.py plate --divisions 16 --side 1.0) and
// the load case; a / t = 100, a thin plate.
constexpr int kPlateDivisions = 16;
constexpr double kSide = 1.0, kPlateThickness = 0.01, kPlateYoung = 1.0e9, kPlatePoisson = 0.3,
                 kPressure = 100.0;
constexpr double kTimoshenkoCoefficient = 0.00126;

// The roof fixture (tools/gen_plate_msh.py roof --divisions 32) and MacNeal–Harder's data.
constexpr int kRoofDivisions = 32;
constexpr double kRadius = 25.0, kHalfLength = 25.0, kHalfAngleDeg = 40.0, kRoofThickness = 0.25,
                 kRoofYoung = 4.32e8, kSelfWeight = 90.0;
constexpr double kScordelisLoReference = 0.3024;

std::string read_text(const fs::path& path) {
  std::ifstream file(path, std::ios::binary);
  std::ostringstream text;
  text << file.rdbuf();
  return text.str();
}

using ModelcPublished = testing::CommandTest;

// The single node of a 0-D group in the report, with its position checked.
const nlohmann::json& single_node(const nlohmann::json& report, const std::string& group,
                                  const Eigen::Vector3d& expected_position_m) {
  const nlohmann::json& nodes = report["node_sets"][group];
  EXPECT_EQ(nodes.size(), 1u) << group;
  const nlohmann::json& node = nodes.at(0);
  for (std::size_t axis = 0; axis < 3; ++axis) {
    EXPECT_NEAR(node["position_m"][axis].get<double>(),
                expected_position_m(static_cast<Eigen::Index>(axis)), 1e-12)
        << group << " axis " << axis;
  }
  return node;
}

double plate_rigidity() {
  return kPlateYoung * std::pow(kPlateThickness, 3) / (12.0 * (1.0 - kPlatePoisson * kPlatePoisson));
}

// ---- the fixtures themselves ----

TEST_F(ModelcPublished, PlateFixtureIsTheGeneratorsPlateWithItsGroups) {
  auto mesh = read_gmsh_shell(kPlateMesh);
  ASSERT_TRUE(mesh) << mesh.error().message;
  auto generated = make_rectangle_plate(kSide, kSide, kPlateDivisions, kPlateDivisions,
                                        TrianglePattern::alternating);
  ASSERT_TRUE(generated);
  // Node tags are in grid order and every node is used, so the reader's renumbering keeps it:
  // the same positions (bit for bit, repr() round-trips) and the same triangles, same order.
  ASSERT_EQ(mesh->nodes.rows(), (kPlateDivisions + 1) * (kPlateDivisions + 1));
  ASSERT_EQ(mesh->triangles.rows(), 2 * kPlateDivisions * kPlateDivisions);
  EXPECT_TRUE(mesh->nodes == generated->nodes);
  EXPECT_TRUE(mesh->triangles == generated->triangles);

  ASSERT_EQ(mesh->triangle_sets.count("plate"), 1u);
  EXPECT_EQ(mesh->triangle_sets.at("plate").size(), 2u * kPlateDivisions * kPlateDivisions);
  ASSERT_EQ(mesh->node_sets.count("edges"), 1u);
  const std::vector<int>& edges = mesh->node_sets.at("edges");
  EXPECT_EQ(edges.size(), 4u * kPlateDivisions);
  int boundary_nodes = 0;
  for (Eigen::Index node = 0; node < mesh->nodes.rows(); ++node) {
    const double x = mesh->nodes(node, 0), y = mesh->nodes(node, 1);
    const bool on_boundary = x == 0.0 || x == kSide || y == 0.0 || y == kSide;
    boundary_nodes += on_boundary ? 1 : 0;
    const bool in_group =
        std::find(edges.begin(), edges.end(), static_cast<int>(node)) != edges.end();
    EXPECT_EQ(in_group, on_boundary) << "node " << node;
  }
  EXPECT_EQ(boundary_nodes, 4 * kPlateDivisions);
  ASSERT_EQ(mesh->node_sets.count("centre"), 1u);
  ASSERT_EQ(mesh->node_sets.at("centre").size(), 1u);
  const int centre = mesh->node_sets.at("centre").front();
  EXPECT_EQ(mesh->nodes(centre, 0), 0.5 * kSide);
  EXPECT_EQ(mesh->nodes(centre, 1), 0.5 * kSide);
}

TEST_F(ModelcPublished, RoofFixtureIsTheGeneratorsPanelWithItsGroups) {
  auto mesh = read_gmsh_shell(kRoofMesh);
  ASSERT_TRUE(mesh) << mesh.error().message;
  auto generated = make_cylindrical_panel(kRadius, kHalfLength, 0.0,
                                          kHalfAngleDeg * std::numbers::pi / 180.0,
                                          kRoofDivisions, kRoofDivisions,
                                          TrianglePattern::alternating);
  ASSERT_TRUE(generated);
  ASSERT_EQ(mesh->nodes.rows(), generated->nodes.rows());
  ASSERT_EQ(mesh->triangles.rows(), generated->triangles.rows());
  // Python's and glibc's sin/cos agree here; allow one ulp-scale difference all the same.
  EXPECT_LT((mesh->nodes - generated->nodes).cwiseAbs().maxCoeff(), 1e-13);
  EXPECT_TRUE(mesh->triangles == generated->triangles);
  // The generator's sets under the fixture's names.
  const std::vector<std::pair<std::string, std::string>> same{
      {"diaphragm", "x0"}, {"symmetry_x", "x1"}, {"crown", "arc0"}, {"free_edge", "arc1"}};
  for (const auto& [fixture_name, generator_name] : same) {
    ASSERT_EQ(mesh->node_sets.count(fixture_name), 1u) << fixture_name;
    std::vector<int> expected = generated->node_sets.at(generator_name);
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(mesh->node_sets.at(fixture_name), expected) << fixture_name;
  }
  EXPECT_EQ(mesh->triangle_sets.at("roof").size(), 2u * kRoofDivisions * kRoofDivisions);
  EXPECT_EQ(mesh->node_sets.at("free_edge_midspan"),
            std::vector<int>{kRoofDivisions * (kRoofDivisions + 1) + kRoofDivisions});
}

// The committed files are what the script writes today (byte for byte here).
TEST_F(ModelcPublished, FixturesAreUpToDateWithTheirGenerator) {
  if (std::system("python3 --version > /dev/null 2>&1") != 0) {
    GTEST_SKIP() << "python3 not found; cannot regenerate the fixtures";
  }
  const std::string script = kSourceDir + "/tools/gen_plate_msh.py";
  const fs::path plate = directory_ / "plate.msh", roof = directory_ / "roof.msh";
  ASSERT_EQ(run("python3", script + " plate --divisions 16 --side 1.0 --output " + plate.string()),
            0)
      << output_;
  ASSERT_EQ(run("python3", script + " roof --divisions 32 --output " + roof.string()), 0)
      << output_;
  EXPECT_EQ(read_text(plate), read_text(kPlateMesh))
      << "regenerate tests/model/offline/data/clamped_plate_16.msh with tools/gen_plate_msh.py";
  // The roof's coordinates come from libm's sin/cos, which may differ by an ulp between CPUs
  // (glibc picks FMA or plain variants at run time): same mesh to 1e-13, same groups.
  if (read_text(roof) != read_text(kRoofMesh)) {
    auto fresh = read_gmsh_shell(roof.string());
    auto committed = read_gmsh_shell(kRoofMesh);
    ASSERT_TRUE(fresh && committed);
    ASSERT_EQ(fresh->nodes.rows(), committed->nodes.rows())
        << "regenerate tests/model/offline/data/scordelis_lo_quarter_32.msh with "
           "tools/gen_plate_msh.py";
    EXPECT_LT((fresh->nodes - committed->nodes).cwiseAbs().maxCoeff(), 1e-13);
    EXPECT_TRUE(fresh->triangles == committed->triangles);
    EXPECT_EQ(fresh->node_sets, committed->node_sets);
    EXPECT_EQ(fresh->triangle_sets, committed->triangle_sets);
  }
}

// ---- published results through the CLI ----

TEST_F(ModelcPublished, ClampedPlateCentreDeflectionMatchesTimoshenko) {
  ASSERT_EQ(run(MODELC_PATH, "static --mesh " + kPlateMesh +
                                 " --element shell-dkt --young 1e9 --poisson 0.3 --thickness 0.01"
                                 " --fix edges=all --surface-load plate=0,0,-100 --report " +
                                 report_path()),
            0)
      << output_;
  const nlohmann::json json = report();
  EXPECT_EQ(json["inputs"]["fixes"][0]["dofs"].size(), 6u);
  // The consistent nodal loads carry the whole pressure: q a² downward.
  EXPECT_NEAR(json["total_applied_force_n"][2].get<double>(), -kPressure * kSide * kSide, 1e-9);
  for (const auto& node : json["node_sets"]["edges"]) {
    for (std::size_t axis = 0; axis < 3; ++axis) {
      EXPECT_EQ(node["displacement_m"][axis].get<double>(), 0.0);
      EXPECT_EQ(node["rotation_rad"][axis].get<double>(), 0.0);
    }
  }

  const nlohmann::json& centre =
      single_node(json, "centre", Eigen::Vector3d(0.5 * kSide, 0.5 * kSide, 0.0));
  const double centre_uz = centre["displacement_m"][2].get<double>();
  const double expected =
      -kTimoshenkoCoefficient * kPressure * std::pow(kSide, 4) / plate_rigidity();
  const double coefficient = -centre_uz * plate_rigidity() / (kPressure * std::pow(kSide, 4));
  std::cout << "[measured] modelc static, clamped plate 16x16 alternating, DKT: w_c = "
            << centre_uz << " m, w_c D/(q a^4) = " << coefficient << " ("
            << coefficient / kTimoshenkoCoefficient << " of 0.00126)\n";
  EXPECT_NEAR(centre_uz / expected, 1.0, 0.02);
  // By symmetry the centre moves only along z, does not rotate, and moves the most.
  EXPECT_NEAR(centre["displacement_m"][0].get<double>(), 0.0, 1e-9 * std::abs(centre_uz));
  EXPECT_NEAR(centre["displacement_m"][1].get<double>(), 0.0, 1e-9 * std::abs(centre_uz));
  EXPECT_NEAR(centre["rotation_rad"][0].get<double>(), 0.0, 1e-9 * std::abs(centre_uz));
  EXPECT_NEAR(centre["rotation_rad"][1].get<double>(), 0.0, 1e-9 * std::abs(centre_uz));
  EXPECT_EQ(json["max_displacement_node"], centre["index"]);
  EXPECT_NEAR(json["max_displacement_m"].get<double>(), std::abs(centre_uz),
              1e-12 * std::abs(centre_uz));

  // The library on the generator's mesh (as shell_benchmark_test solves it) agrees to round-off.
  auto mesh = make_rectangle_plate(kSide, kSide, kPlateDivisions, kPlateDivisions,
                                   TrianglePattern::alternating);
  ASSERT_TRUE(mesh);
  const std::vector<int> all{kUx, kUy, kUz, kRx, kRy, kRz};
  auto shell = assemble_shell(
      *mesh, ShellMaterial{kPlateYoung, kPlatePoisson, kPlateThickness, 1000.0},
      BendingElement::dkt, {{"x0", all}, {"x1", all}, {"y0", all}, {"y1", all}});
  ASSERT_TRUE(shell);
  Eigen::VectorXd loads = make_zero_loads(*mesh);
  ASSERT_TRUE(add_surface_traction(*mesh, "plate", Eigen::Vector3d(0, 0, -kPressure), loads));
  auto solution = static_solve(*shell, loads);
  ASSERT_TRUE(solution);
  const int library_centre = (kPlateDivisions / 2) * (kPlateDivisions + 1) + kPlateDivisions / 2;
  EXPECT_EQ(centre["index"].get<int>(), library_centre);
  EXPECT_NEAR(centre_uz, solution->node_displacements(library_centre, kUz),
              1e-10 * std::abs(centre_uz));
}

TEST_F(ModelcPublished, ScordelisLoRoofFreeEdgeDropMatchesMacNealHarder) {
  // Quarter model boundary conditions (as shell_benchmark_test): rigid diaphragm at x = 0
  // (no motion in its own y–z plane), symmetry planes x = L/2 and y = 0 (the crown line).
  const std::string fixes =
      " --fix diaphragm=y,z,rx --fix symmetry_x=x,ry,rz --fix crown=y,rx,rz";
  ASSERT_EQ(run(MODELC_PATH, "static --mesh " + kRoofMesh +
                                 " --element shell-dkt --young 4.32e8 --poisson 0 --thickness 0.25" +
                                 fixes + " --surface-load roof=0,0,-90 --report " + report_path()),
            0)
      << output_;
  const nlohmann::json json = report();
  const double half_angle = kHalfAngleDeg * std::numbers::pi / 180.0;
  const nlohmann::json& midspan =
      single_node(json, "free_edge_midspan",
                  Eigen::Vector3d(kHalfLength, kRadius * std::sin(half_angle),
                                  kRadius * std::cos(half_angle)));
  const double drop = -midspan["displacement_m"][2].get<double>();
  std::cout << "[measured] modelc static, Scordelis-Lo 32x32 quarter, DKT: free-edge mid-span "
               "drop "
            << drop << " (" << drop / kScordelisLoReference << " of 0.3024)\n";
  EXPECT_NEAR(drop / kScordelisLoReference, 1.0, 0.03);

  // Self-weight on the quarter: 90 × area (R × angle × L/2), all of it downward.
  const double area = kRadius * half_angle * kHalfLength;
  const double total_z = json["total_applied_force_n"][2].get<double>();
  // The facets' area is slightly less than the cylinder's (chords): 1 − cos-type error ~1e-4.
  EXPECT_NEAR(total_z / (-kSelfWeight * area), 1.0, 2e-4);
  EXPECT_NEAR(json["total_applied_force_n"][0].get<double>(), 0.0, 1e-9 * std::abs(total_z));
  EXPECT_NEAR(json["total_applied_force_n"][1].get<double>(), 0.0, 1e-9 * std::abs(total_z));
  // The diaphragm holds y and z; the free edge's largest drop is at mid-span.
  for (const auto& node : json["node_sets"]["diaphragm"]) {
    EXPECT_EQ(node["displacement_m"][1].get<double>(), 0.0);
    EXPECT_EQ(node["displacement_m"][2].get<double>(), 0.0);
  }
  for (const auto& node : json["node_sets"]["free_edge"]) {
    EXPECT_LE(-node["displacement_m"][2].get<double>(), drop * (1.0 + 1e-12))
        << "node " << node["index"];
  }

  // The library on the generator's panel with the generator's set names gives the same answer.
  auto mesh = make_cylindrical_panel(kRadius, kHalfLength, 0.0, half_angle, kRoofDivisions,
                                     kRoofDivisions, TrianglePattern::alternating);
  ASSERT_TRUE(mesh);
  auto shell = assemble_shell(*mesh, ShellMaterial{kRoofYoung, 0.0, kRoofThickness, 1.0},
                              BendingElement::dkt,
                              {{"x0", {kUy, kUz, kRx}}, {"x1", {kUx, kRy, kRz}},
                               {"arc0", {kUy, kRx, kRz}}});
  ASSERT_TRUE(shell);
  Eigen::VectorXd loads = make_zero_loads(*mesh);
  ASSERT_TRUE(add_surface_traction(*mesh, "panel", Eigen::Vector3d(0, 0, -kSelfWeight), loads));
  auto solution = static_solve(*shell, loads);
  ASSERT_TRUE(solution);
  const int node = midspan["index"].get<int>();
  EXPECT_NEAR(drop, -solution->node_displacements(node, kUz), 1e-9 * drop);
}

}  // namespace
}  // namespace trainer::model::offline
