// Gmsh MSH 4.1 reader: the hand-written fixtures in data/, the tetrahedral path, and one test
// per parse error (each must name file:line and the problem).
#include <gtest/gtest.h>

#include <xxhash.h>

#include <fstream>
#include <sstream>
#include <string>

#include "trainer/model_offline/gmsh_reader.hpp"
#include "trainer/model_offline/loads.hpp"
#include "trainer/model_offline/mesh_generators.hpp"
#include "trainer/model_offline/mesh_validation.hpp"
#include "trainer/model_offline/shell_assembly.hpp"
#include "trainer/model_offline/static_solve.hpp"

namespace trainer::model::offline {
namespace {

const std::string kDataDir = std::string(TRAINER_SOURCE_DIR) + "/tests/model/offline/data/";

std::string file_text(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  std::ostringstream text;
  text << file.rdbuf();
  return text.str();
}

TEST(GmshReader, TwoTriangleSquareGroupsAndRenumbering) {
  const std::string path = kDataDir + "two_triangle_square.msh";
  auto mesh = read_gmsh_shell(path);
  ASSERT_TRUE(mesh) << mesh.error().message;
  // Node tag 9 (first in the file) is used by no element: dropped; tags 1..4 → 0..3.
  ASSERT_EQ(mesh->nodes.rows(), 4);
  EXPECT_TRUE(mesh->nodes.row(0).isApprox(Eigen::RowVector3d(0, 0, 0)));
  EXPECT_TRUE(mesh->nodes.row(2).isApprox(Eigen::RowVector3d(1, 1, 0)));
  ASSERT_EQ(mesh->triangles.rows(), 2);
  EXPECT_EQ(mesh->triangles.row(0), Eigen::RowVector3i(0, 1, 2));
  EXPECT_EQ(mesh->triangles.row(1), Eigen::RowVector3i(0, 2, 3));
  EXPECT_EQ(mesh->node_sets.at("corner"), std::vector<int>({0}));
  EXPECT_EQ(mesh->node_sets.at("left edge"), std::vector<int>({0, 3}));
  EXPECT_EQ(mesh->node_sets.at("square"), std::vector<int>({0, 1, 2, 3}));
  EXPECT_EQ(mesh->triangle_sets.at("square"), std::vector<int>({0, 1}));
  EXPECT_EQ(mesh->triangle_sets.count("left edge"), 0u);
  const std::string text = file_text(path);
  EXPECT_EQ(mesh->source_hash, XXH64(text.data(), text.size(), 0));
  EXPECT_TRUE(validate_shell_mesh(*mesh));
}

// The plate fixture holds the same triangles as make_rectangle_plate(1, 1, 2, 2, right) with
// Gmsh's node order; the static answers must agree node by node (matched by position).
TEST(GmshReader, PlateFixtureSolvesLikeTheGeneratedPlate) {
  auto read = read_gmsh_shell(kDataDir + "plate_with_groups.msh");
  ASSERT_TRUE(read) << read.error().message;
  EXPECT_EQ(read->nodes.rows(), 9);
  EXPECT_EQ(read->triangles.rows(), 8);
  EXPECT_EQ(read->node_sets.at("clamped").size(), 3u);
  EXPECT_EQ(read->node_sets.at("tip").size(), 3u);
  EXPECT_EQ(read->node_sets.at("7").size(), 3u) << "unnamed groups are named by number";
  EXPECT_EQ(read->triangle_sets.at("plate").size(), 8u);

  auto generated = make_rectangle_plate(1.0, 1.0, 2, 2, TrianglePattern::right);
  ASSERT_TRUE(generated);
  const ShellMaterial material{1e9, 0.3, 0.01, 1000.0};
  const std::vector<int> all{kUx, kUy, kUz, kRx, kRy, kRz};
  auto solve = [&](const ShellMesh& mesh, const std::string& clamped, const std::string& tip) {
    auto shell = assemble_shell(mesh, material, BendingElement::dkt, {{clamped, all}});
    EXPECT_TRUE(shell) << (shell ? "" : shell.error().message);
    Eigen::VectorXd loads = make_zero_loads(mesh);
    EXPECT_TRUE(add_node_set_force(mesh, tip, Eigen::Vector3d(0.0, 0.0, -3.0), loads));
    auto solution = static_solve(*shell, loads);
    EXPECT_TRUE(solution);
    return solution->node_displacements;
  };
  const auto from_file = solve(*read, "clamped", "tip");
  const auto from_generator = solve(*generated, "x0", "x1");
  for (Eigen::Index a = 0; a < read->nodes.rows(); ++a) {
    Eigen::Index match = -1;
    for (Eigen::Index b = 0; b < generated->nodes.rows(); ++b) {
      if ((read->nodes.row(a) - generated->nodes.row(b)).norm() < 1e-12) match = b;
    }
    ASSERT_GE(match, 0);
    EXPECT_LE((from_file.row(a) - from_generator.row(match)).norm(),
              1e-12 * from_generator.cwiseAbs().maxCoeff());
  }
  EXPECT_GT(from_generator.cwiseAbs().maxCoeff(), 0.0);
}

constexpr const char* kTetMesh = R"($MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
2
2 1 "base"
3 2 "body"
$EndPhysicalNames
$Entities
0 0 1 1
1 0 0 0 1 1 0 1 1 0
1 0 0 0 1 1 1 1 2 1 1
$EndEntities
$Nodes
1 6 1 6
3 1 0 6
1
2
3
4
5
6
0 0 0
1 0 0
0 1 0
0 0 1
1 1 1
7 7 7
$EndNodes
$Elements
2 3 1 3
2 1 2 1
1 1 2 3
3 1 4 2
2 1 2 3 4
3 2 3 4 5
$EndElements
)";

TEST(GmshReader, TetrahedraAndTheirGroups) {
  auto mesh = parse_gmsh_tet(kTetMesh, "tets.msh");
  ASSERT_TRUE(mesh) << mesh.error().message;
  EXPECT_EQ(mesh->nodes.rows(), 5) << "node 6 is used by nothing";
  ASSERT_EQ(mesh->tetrahedra.rows(), 2);
  EXPECT_EQ(mesh->tetrahedra.row(1), Eigen::RowVector4i(1, 2, 3, 4));
  ASSERT_EQ(mesh->triangles.rows(), 1);
  EXPECT_EQ(mesh->triangle_sets.at("base"), std::vector<int>({0}));
  EXPECT_EQ(mesh->node_sets.at("base"), std::vector<int>({0, 1, 2}));
  EXPECT_EQ(mesh->tetrahedron_sets.at("body"), std::vector<int>({0, 1}));
  EXPECT_EQ(mesh->node_sets.at("body"), std::vector<int>({0, 1, 2, 3, 4}));

  // The same file read as a shell keeps only the triangle and its nodes.
  auto shell = parse_gmsh_shell(kTetMesh, "tets.msh");
  ASSERT_TRUE(shell) << shell.error().message;
  EXPECT_EQ(shell->nodes.rows(), 3);
  EXPECT_EQ(shell->triangles.rows(), 1);
  EXPECT_EQ(shell->node_sets.count("body"), 0u) << "3-D groups are ignored for shells";

  auto no_tets = read_gmsh_tet(kDataDir + "two_triangle_square.msh");
  ASSERT_FALSE(no_tets);
  EXPECT_NE(no_tets.error().message.find("no 4-node tetrahedra"), std::string::npos);
}

// A valid minimal file to mutate: one triangle, one group.
std::string minimal(const std::string& elements_section, const std::string& format = "4.1 0 8",
                    const std::string& nodes_header = "1 3 1 3") {
  return "$MeshFormat\n" + format +
         "\n$EndMeshFormat\n"
         "$PhysicalNames\n1\n2 1 \"wall\"\n$EndPhysicalNames\n"
         "$Entities\n0 0 1 0\n1 0 0 0 1 1 0 1 1 0\n$EndEntities\n"
         "$Nodes\n" +
         nodes_header + "\n2 1 0 3\n1\n2\n3\n0 0 0\n1 0 0\n0 1 0\n$EndNodes\n" + elements_section;
}

const std::string kGoodElements = "$Elements\n1 1 1 1\n2 1 2 1\n1 1 2 3\n$EndElements\n";

struct ErrorCase {
  const char* name;
  std::string text;
  const char* expected_location;  // "file:line"
  const char* expected_problem;
};

TEST(GmshReader, EveryParseErrorNamesFileLineAndProblem) {
  ASSERT_TRUE(parse_gmsh_shell(minimal(kGoodElements), "m.msh"));
  const ErrorCase cases[] = {
      {"version 2.2", minimal(kGoodElements, "2.2 0 8"), "m.msh:2:", "unsupported MSH version 2.2"},
      {"binary", minimal(kGoodElements, "4.1 1 8"),
       "m.msh:2:", "binary MSH files are not supported"},
      {"missing elements", minimal(""), "m.msh:", "missing $Elements section"},
      {"missing nodes", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n" + kGoodElements,
       "m.msh:4:", "$Elements comes before $Nodes"},
      {"no mesh format", "$Nodes\n0 0 0 0\n$EndNodes\n",
       "m.msh:1:", "expected $MeshFormat as the first section"},
      {"node count too large", minimal(kGoodElements, "4.1 0 8", "1 4 1 3"),
       "m.msh:13:", "announces 4 nodes but its 1 blocks hold 3"},
      {"element block short", minimal("$Elements\n1 2 1 2\n2 1 2 2\n1 1 2 3\n$EndElements\n"),
       "m.msh:26:", "announces 2 elements but has only 1"},
      {"element count mismatch", minimal("$Elements\n1 2 1 1\n2 1 2 1\n1 1 2 3\n$EndElements\n"),
       "m.msh:23:", "announces 2 elements but its 1 blocks hold 1"},
      {"unsupported type in group",
       minimal("$Elements\n2 2 1 2\n2 1 2 1\n1 1 2 3\n2 1 3 1\n2 1 2 3 1\n$EndElements\n"),
       "m.msh:26:", "unsupported element type 3 (4-node quadrangle) used by physical group 'wall'"},
      {"unknown node tag", minimal("$Elements\n1 1 1 1\n2 1 2 1\n1 1 2 7\n$EndElements\n"),
       "m.msh:25:", "uses node tag 7, which $Nodes does not define"},
      {"wrong node count", minimal("$Elements\n1 1 1 1\n2 1 2 1\n1 1 2\n$EndElements\n"),
       "m.msh:25:", "has 2 node tags; expected 3"},
      {"not a number", minimal("$Elements\n1 1 1 1\n2 1 2 1\n1 1 2 x3\n$EndElements\n"),
       "m.msh:25:", "expected a node tag (an integer), found 'x3'"},
      {"unterminated section", minimal(kGoodElements) + "$Comments\nhello\n",
       "m.msh:", "section $Comments has no $EndComments"},
      {"unknown entity", minimal("$Elements\n1 1 1 1\n2 5 2 1\n1 1 2 3\n$EndElements\n"),
       "m.msh:24:", "entity (dimension 2, tag 5) that $Entities does not define"},
      {"no triangles", minimal("$Elements\n1 1 1 1\n1 1 1 1\n1 1 2\n$EndElements\n"),
       "m.msh:", "no 3-node triangles"},
      {"physical names without entities",
       "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n2 1 \"wall\"\n$EndPhysicalNames\n"
       "$Nodes\n1 3 1 3\n2 1 0 3\n1\n2\n3\n0 0 0\n1 0 0\n0 1 0\n$EndNodes\n" +
           kGoodElements,
       "m.msh:4:", "$Entities section that assigns entities to physical groups is missing"},
  };
  for (const ErrorCase& c : cases) {
    auto result = parse_gmsh_shell(c.text, "m.msh");
    ASSERT_FALSE(result) << c.name;
    const std::string& message = result.error().message;
    EXPECT_EQ(message.rfind(c.expected_location, 0), 0u) << c.name << ": " << message;
    EXPECT_NE(message.find(c.expected_problem), std::string::npos) << c.name << ": " << message;
  }
}

TEST(GmshReader, GroupNodeThatNoTriangleUsesIsRefused) {
  // A physical point on node 4, which no triangle uses.
  const std::string text =
      "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"
      "$PhysicalNames\n1\n0 9 \"tip\"\n$EndPhysicalNames\n"
      "$Entities\n1 0 1 0\n1 5 5 0 1 9\n1 0 0 0 1 1 0 0 0\n$EndEntities\n"
      "$Nodes\n2 4 1 4\n2 1 0 3\n1\n2\n3\n0 0 0\n1 0 0\n0 1 0\n0 1 0 1\n4\n5 5 0\n$EndNodes\n"
      "$Elements\n2 2 1 2\n0 1 15 1\n1 4\n2 1 2 1\n2 1 2 3\n$EndElements\n";
  auto result = parse_gmsh_shell(text, "p.msh");
  ASSERT_FALSE(result);
  EXPECT_NE(result.error().message.find("p.msh:29: physical group 'tip' (dimension 0) uses node "
                                        "tag 4, which no triangle uses"),
            std::string::npos)
      << result.error().message;
}

TEST(GmshReader, MissingFileIsReported) {
  auto result = read_gmsh_shell(kDataDir + "does_not_exist.msh");
  ASSERT_FALSE(result);
  EXPECT_NE(result.error().message.find("does_not_exist.msh: cannot open"), std::string::npos);
}

}  // namespace
}  // namespace trainer::model::offline
