// Runs the real `modelc static` binary (MODELC_PATH) and checks its JSON report against an
// exact answer (a tube in uniform tension, ν = 0: δ = F L / (E t P) with P the facetted
// perimeter) and against the library called directly, plus its refusals.
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
#include "trainer/model_offline/gmsh_reader.hpp"
#include "trainer/model_offline/loads.hpp"
#include "trainer/model_offline/mesh_generators.hpp"
#include "trainer/model_offline/shell_assembly.hpp"
#include "trainer/model_offline/static_solve.hpp"

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

}  // namespace
}  // namespace trainer::model::offline
