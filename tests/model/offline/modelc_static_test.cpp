// Runs the real `modelc static` binary (MODELC_PATH) and checks its JSON report against an
// exact answer (a tube in uniform tension, ν = 0: δ = F L / (E t P) with P the facetted
// perimeter; for tet4 a bar in uniaxial tension, exact for linear tetrahedra) and against the
// library called directly, plus its refusals.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>

#include "command_test_support.hpp"
#include "tet_test_support.hpp"
#include "trainer/model_offline/gmsh_reader.hpp"
#include "trainer/model_offline/loads.hpp"
#include "trainer/model_offline/mesh_generators.hpp"
#include "trainer/model_offline/shell_assembly.hpp"
#include "trainer/model_offline/static_solve.hpp"
#include "trainer/model_offline/tet_elasticity.hpp"
#include "trainer/model_offline/tet_mesh_generators.hpp"

namespace trainer::model::offline {
namespace {

namespace fs = std::filesystem;

const std::string kDataDir = std::string(TRAINER_SOURCE_DIR) + "/tests/model/offline/data/";

class ModelcStatic : public testing::CommandTest {
 protected:
  int run(const std::string& arguments) { return CommandTest::run(MODELC_PATH, arguments); }
};

TEST_F(ModelcStatic, TubeInUniformTensionMatchesTheExactStretch) {
  const double radius = 0.004, length = 0.04, young = 1e6, thickness = 5e-4, force = 0.1;
  const int rings = 11, segments = 16;
  ASSERT_EQ(run("static --tube 0.004,0.04,11,16 --element shell-dkt --young 1e6 --poisson 0 "
                "--thickness 5e-4 --fix clamped=all --load free_end=0.1,0,0 --report " +
                report_path()),
            0)
      << output_;
  const nlohmann::json json = report();
  const double perimeter = segments * 2.0 * radius * std::sin(std::numbers::pi / segments);
  const double expected = force * length / (young * thickness * perimeter);

  EXPECT_EQ(json["command"], "static");
  EXPECT_EQ(json["inputs"]["tube"]["rings"], rings);
  EXPECT_EQ(json["inputs"]["element"], "shell-dkt");
  EXPECT_EQ(json["inputs"]["material"]["young_modulus_pa"], young);
  EXPECT_EQ(json["inputs"]["fixes"][0]["group"], "clamped");
  EXPECT_EQ(json["inputs"]["fixes"][0]["dofs"].size(), 6u);
  EXPECT_EQ(json["counts"]["nodes"], rings * segments);
  EXPECT_EQ(json["counts"]["triangles"], 2 * (rings - 1) * segments);
  EXPECT_EQ(json["counts"]["free_dofs"], (rings - 1) * segments * 6);
  EXPECT_GE(json["timing_s"]["solve"].get<double>(), 0.0);
  EXPECT_NEAR(json["total_applied_force_n"][0].get<double>(), force, 1e-15);

  ASSERT_EQ(json["node_sets"]["free_end"].size(), static_cast<std::size_t>(segments));
  for (const auto& node : json["node_sets"]["free_end"]) {
    EXPECT_NEAR(node["position_m"][0].get<double>(), length, 1e-15);
    EXPECT_NEAR(node["displacement_m"][0].get<double>(), expected, 1e-9 * expected);
    EXPECT_NEAR(node["displacement_m"][1].get<double>(), 0.0, 1e-9 * expected);
    EXPECT_NEAR(node["rotation_rad"][2].get<double>(), 0.0, 1e-9);
  }
  for (const auto& node : json["node_sets"]["clamped"]) {
    EXPECT_EQ(node["displacement_m"][0].get<double>(), 0.0);
  }
  EXPECT_NEAR(json["max_displacement_m"].get<double>(), expected, 1e-9 * expected);
  EXPECT_NE(output_.find("max |u|"), std::string::npos);
}

// The mesh path with a surface load: the report equals the library's own answer.
TEST_F(ModelcStatic, GmshMeshWithSurfaceLoadMatchesTheLibrary) {
  const std::string mesh_path = kDataDir + "plate_with_groups.msh";
  ASSERT_EQ(run("static --mesh " + mesh_path +
                " --element shell-rao --young 2e9 --poisson 0.3 --thickness 0.01 "
                "--fix clamped=x,y,z,rx,ry,rz --load tip=0,0,-3 --surface-load plate=0,0,-10 "
                "--report " +
                report_path()),
            0)
      << output_;
  const nlohmann::json json = report();

  auto mesh = read_gmsh_shell(mesh_path);
  ASSERT_TRUE(mesh);
  const std::vector<int> all{kUx, kUy, kUz, kRx, kRy, kRz};
  auto shell = assemble_shell(*mesh, ShellMaterial{2e9, 0.3, 0.01, 1000.0}, BendingElement::rao,
                              {{"clamped", all}});
  ASSERT_TRUE(shell);
  Eigen::VectorXd loads = make_zero_loads(*mesh);
  ASSERT_TRUE(add_node_set_force(*mesh, "tip", Eigen::Vector3d(0, 0, -3), loads));
  ASSERT_TRUE(add_surface_traction(*mesh, "plate", Eigen::Vector3d(0, 0, -10), loads));
  auto solution = static_solve(*shell, loads);
  ASSERT_TRUE(solution);
  const double scale = solution->node_displacements.cwiseAbs().maxCoeff();
  ASSERT_GT(scale, 0.0);
  for (const char* set : {"tip", "7", "plate", "clamped"}) {
    ASSERT_TRUE(json["node_sets"].contains(set)) << set;
    for (const auto& node : json["node_sets"][set]) {
      const int index = node["index"];
      for (int d = 0; d < 3; ++d) {
        EXPECT_NEAR(node["displacement_m"][static_cast<std::size_t>(d)].get<double>(),
                    solution->node_displacements(index, d), 1e-12 * scale);
        EXPECT_NEAR(node["rotation_rad"][static_cast<std::size_t>(d)].get<double>(),
                    solution->node_displacements(index, 3 + d), 1e-12 * scale);
      }
    }
  }
  EXPECT_NEAR(json["total_applied_force_n"][2].get<double>(), -3.0 - 10.0, 1e-12);
}

TEST_F(ModelcStatic, BadInputsAreRefusedWithAMessage) {
  const std::string common =
      " --element shell-dkt --young 1e6 --poisson 0.3 --thickness 1e-3 "
      "--report " +
      report_path();
  EXPECT_NE(run("static --tube 0.004,0.04,5,8 --fix clampd=all" + common), 0);
  EXPECT_NE(output_.find("unknown node set 'clampd'"), std::string::npos) << output_;

  EXPECT_NE(run("static --tube 0.004,0.04,5,8 --fix clamped=x" + common), 0);
  EXPECT_NE(output_.find("rigid-body mode free"), std::string::npos) << output_;

  EXPECT_NE(run("static --tube 0.004,0.04,5,8 --fix clamped=x,q" + common), 0);
  EXPECT_NE(output_.find("unknown dof 'q'"), std::string::npos) << output_;

  EXPECT_NE(run("static --tube 0.004,0.04,5 --fix clamped=all" + common), 0);
  EXPECT_NE(output_.find("R,L,RINGS,SEGMENTS"), std::string::npos) << output_;

  EXPECT_NE(run("static --tube 0.004,0.04,5,8 --fix clamped=all --load free_end=1,2" + common), 0);
  EXPECT_NE(output_.find("GROUP=X,Y,Z"), std::string::npos) << output_;

  EXPECT_NE(run("static --fix clamped=all" + common), 0);
  EXPECT_NE(output_.find("--mesh or --tube"), std::string::npos) << output_;

  EXPECT_NE(run("static --mesh " + kDataDir + "two_triangle_square.msh --tube 1,1,3,3 --fix a=all" +
                common),
            0);

  EXPECT_NE(run("static --tube 0.004,0.04,5,8 --fix clamped=all --element shell-rao --young 1e6 "
                "--poisson 0.6 --thickness 1e-3 --report " +
                report_path()),
            0);
  EXPECT_NE(output_.find("poisson_ratio"), std::string::npos) << output_;
  EXPECT_FALSE(fs::exists(report_path())) << "no report is written on failure";
}

TEST_F(ModelcStatic, HelpStatesTheUnits) {
  EXPECT_EQ(run("static --help"), 0);
  EXPECT_NE(output_.find("(Pa)"), std::string::npos) << output_;
  EXPECT_NE(output_.find("(m)"), std::string::npos) << output_;
  EXPECT_NE(output_.find("--surface-load"), std::string::npos);
}

// tet4 on a generated box: a bar with symmetry-plane rollers and the end force spread by area;
// u = (F/(E A)) (x, −ν y, −ν z) is exact for linear tetrahedra (tolerance 1e-9 relative).
TEST_F(ModelcStatic, Tet4BoxBarInTensionIsExact) {
  const double length = 0.1, side = 0.01, young = 2e6, poisson = 0.3, force = 0.5;
  ASSERT_EQ(run("static --box 0.1,0.01,0.01,20,2,2 --element tet4 --young 2e6 --poisson 0.3 "
                "--fix x0=x --fix y0=y --fix z0=z --load x1=0.5,0,0 --report " +
                report_path()),
            0)
      << output_;
  const nlohmann::json json = report();
  EXPECT_EQ(json["inputs"]["element"], "tet4");
  EXPECT_EQ(json["inputs"]["box"]["nx"], 20);
  EXPECT_FALSE(json["inputs"]["material"].contains("thickness_m"));
  EXPECT_EQ(json["inputs"]["fixes"][1]["group"], "y0");
  EXPECT_EQ(json["inputs"]["fixes"][1]["dofs"].size(), 1u);
  EXPECT_EQ(json["inputs"]["loads"][0]["distribution"], "area_weighted");
  EXPECT_EQ(json["counts"]["nodes"], 21 * 3 * 3);
  EXPECT_EQ(json["counts"]["tetrahedra"], 6 * 20 * 2 * 2);
  EXPECT_EQ(json["counts"]["dofs"], 3 * 21 * 3 * 3);
  EXPECT_EQ(json["counts"]["fixed_dofs"], 3 * 3 + 21 * 3 + 21 * 3);
  EXPECT_NEAR(json["volume_m3"].get<double>(), length * side * side, 1e-15);
  EXPECT_NEAR(json["total_applied_force_n"][0].get<double>(), force, 1e-15);
  EXPECT_GE(json["timing_s"]["factorization"].get<double>(), 0.0);
  const double strain = force / (young * side * side);
  for (const char* set : {"x1", "y1", "z1", "all"}) {
    ASSERT_TRUE(json["node_sets"].contains(set)) << set;
    for (const auto& node : json["node_sets"][set]) {
      EXPECT_FALSE(node.contains("rotation_rad"));
      const double scale = poisson * strain * side;
      EXPECT_NEAR(node["displacement_m"][0].get<double>(),
                  strain * node["position_m"][0].get<double>(), 1e-9 * strain * length);
      EXPECT_NEAR(node["displacement_m"][1].get<double>(),
                  -poisson * strain * node["position_m"][1].get<double>(), 1e-9 * scale);
      EXPECT_NEAR(node["displacement_m"][2].get<double>(),
                  -poisson * strain * node["position_m"][2].get<double>(), 1e-9 * scale);
    }
  }
  EXPECT_EQ(json["node_sets"]["x1"].size(), 9u);
  EXPECT_NEAR(json["max_displacement_m"].get<double>(),
              std::hypot(strain * length, poisson * strain * side, poisson * strain * side),
              1e-9 * strain * length);
  EXPECT_NE(output_.find("tet4"), std::string::npos) << output_;
}

// tet4 on a Gmsh volume mesh (a generated cylinder written as MSH 4.1): the report equals the
// library's own answer, with a group force and a surface traction.
TEST_F(ModelcStatic, Tet4GmshMeshMatchesTheLibrary) {
  auto cylinder = make_tet_cylinder(0.01, 0.02, 3, 6);
  ASSERT_TRUE(cylinder);
  const std::string mesh_path = (directory_ / "cylinder.msh").string();
  {
    std::ofstream file(mesh_path);
    file << testing::write_gmsh_tet(*cylinder, {"bottom", "top", "side"});
  }
  ASSERT_EQ(run("static --mesh " + mesh_path +
                " --element tet4 --young 5e5 --poisson 0.45 --density 1050 --fix bottom=all "
                "--load top=0.002,0,-0.01 --surface-load side=0,0,-3 --report " +
                report_path()),
            0)
      << output_;
  const nlohmann::json json = report();

  auto mesh = read_gmsh_tet(mesh_path);
  ASSERT_TRUE(mesh) << mesh.error().message;
  auto assembled = assemble_tet(*mesh, {5e5, 0.45, 1050.0},
                                {{mesh->node_sets.at("bottom"), {true, true, true}}});
  ASSERT_TRUE(assembled);
  auto solver = TetStaticSolver::create(*assembled);
  ASSERT_TRUE(solver);
  TetNodalLoads loads = TetNodalLoads::Zero(mesh->nodes.rows(), 3);
  ASSERT_TRUE(add_tet_group_force(*mesh, "top", Eigen::Vector3d(0.002, 0, -0.01), loads));
  ASSERT_TRUE(add_tet_surface_traction(*mesh, "side", Eigen::Vector3d(0, 0, -3), loads));
  auto u = solver->solve_nodal(loads);
  ASSERT_TRUE(u);
  const double scale = u->cwiseAbs().maxCoeff();
  ASSERT_GT(scale, 0.0);
  EXPECT_EQ(json["counts"]["tetrahedra"], cylinder->tetrahedra.rows());
  EXPECT_EQ(json["inputs"]["mesh"], mesh_path);
  for (const char* set : {"bottom", "top", "side", "body"}) {
    ASSERT_TRUE(json["node_sets"].contains(set)) << set;
    for (const auto& node : json["node_sets"][set]) {
      const int index = node["index"];
      for (int d = 0; d < 3; ++d) {
        EXPECT_NEAR(node["displacement_m"][static_cast<std::size_t>(d)].get<double>(),
                    (*u)(index, d), 1e-12 * scale);
      }
    }
  }
  for (const auto& node : json["node_sets"]["bottom"]) {
    EXPECT_EQ(node["displacement_m"][2].get<double>(), 0.0);
  }
  // Side area: 18-gon perimeter (3 rings → 18 wall nodes) × height.
  const double side_area = 18 * 2 * 0.01 * std::sin(std::numbers::pi / 18) * 0.02;
  EXPECT_NEAR(json["total_applied_force_n"][2].get<double>(), -0.01 - 3.0 * side_area, 1e-15);
  EXPECT_NEAR(json["total_applied_force_n"][0].get<double>(), 0.002, 1e-15);
}

TEST_F(ModelcStatic, Tet4BadInputsAreRefusedWithAMessage) {
  const std::string common = " --element tet4 --young 1e6 --poisson 0.3 --report " + report_path();
  const std::string box = "static --box 0.02,0.01,0.01,4,2,2";
  EXPECT_NE(run(box + " --fix x0=x,y,rx" + common), 0);
  EXPECT_NE(output_.find("rx is a rotation"), std::string::npos) << output_;
  EXPECT_NE(run(box + " --fix x0=all --thickness 1e-3" + common), 0);
  EXPECT_NE(output_.find("--thickness has no meaning"), std::string::npos) << output_;
  EXPECT_NE(run(box + " --fix x0=x" + common), 0);
  EXPECT_NE(output_.find("rigid-body motion"), std::string::npos) << output_;
  EXPECT_NE(run(box + " --fix x9=all" + common), 0);
  EXPECT_NE(output_.find("unknown node set 'x9'"), std::string::npos) << output_;
  EXPECT_NE(run(box + " --fix x0=all --load tip=1,0,0" + common), 0);
  EXPECT_NE(output_.find("'tip'"), std::string::npos) << output_;
  EXPECT_NE(run("static --box 0.02,0.01,4,2,2 --fix x0=all" + common), 0);
  EXPECT_NE(output_.find("--box"), std::string::npos) << output_;
  EXPECT_NE(output_.find("LX,LY,LZ,NX,NY,NZ"), std::string::npos) << output_;
  EXPECT_NE(run("static --box 0.02,0.01,0.01,4,0,2 --fix x0=all" + common), 0);
  EXPECT_NE(output_.find("expected each >= 1"), std::string::npos) << output_;
  EXPECT_NE(run("static --cylinder 0.01,0.02,two,4 --fix bottom=all" + common), 0);
  EXPECT_NE(output_.find("--cylinder"), std::string::npos) << output_;
  EXPECT_NE(output_.find("is not an integer"), std::string::npos) << output_;
  EXPECT_NE(run("static --tube 0.004,0.04,5,8 --fix clamped=all" + common), 0);
  EXPECT_NE(output_.find("--tube makes a shell surface"), std::string::npos) << output_;
  EXPECT_NE(run("static --mesh " + kDataDir + "two_triangle_square.msh --fix a=all" + common), 0);
  EXPECT_NE(output_.find("no 4-node tetrahedra"), std::string::npos) << output_;
  EXPECT_NE(run(box + " --cylinder 0.01,0.02,2,2 --fix x0=all" + common), 0);
  EXPECT_NE(run(box +
                " --fix x0=all --element shell-dkt --young 1e6 --poisson 0.3 "
                "--thickness 1e-3 --report " +
                report_path()),
            0);
  EXPECT_NE(output_.find("need --element tet4"), std::string::npos) << output_;
  EXPECT_NE(
      run(box + " --fix x0=all --element tet4 --young 1e6 --poisson 0.5 --report " + report_path()),
      0);
  EXPECT_NE(output_.find("poisson_ratio"), std::string::npos) << output_;
  EXPECT_FALSE(fs::exists(report_path())) << "no report is written on failure";
}

}  // namespace
}  // namespace trainer::model::offline
