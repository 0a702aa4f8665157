// Assembly, boundary conditions, lumped mass, loads and the static solve, checked against
// answers whose value depends on each stiffness's scale: uniform in-plane tension (membrane,
// exact for the CST) and a cantilever strip under a tip load (bending, Euler–Bernoulli).
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <iostream>
#include <numbers>

#include "shell_test_support.hpp"
#include "trainer/model_offline/loads.hpp"
#include "trainer/model_offline/mesh_generators.hpp"
#include "trainer/model_offline/shell_assembly.hpp"
#include "trainer/model_offline/static_solve.hpp"

namespace trainer::model::offline {
namespace {

using test::element_test_name;
using test::test_material;

const std::vector<int> kAllDofs{kUx, kUy, kUz, kRx, kRy, kRz};

class AssemblyBothBendings : public ::testing::TestWithParam<BendingElement> {};


INSTANTIATE_TEST_SUITE_P(Bending, AssemblyBothBendings,
                         ::testing::Values(BendingElement::dkt, BendingElement::rao),
                         element_test_name);

TEST_P(AssemblyBothBendings, TubeStiffnessIsSymmetricPositiveDefiniteAfterClamping) {
  auto mesh = make_tube(0.004, 0.04, 9, 12);
  ASSERT_TRUE(mesh) << mesh.error().message;
  auto shell = assemble_shell(*mesh, test_material(1e6, 0.45, 5e-4, 1000.0), GetParam(),
                              {{"clamped", kAllDofs}});
  ASSERT_TRUE(shell) << shell.error().message;
  const int free_count = (9 - 1) * 12 * 6;
  EXPECT_EQ(shell->dofs.free_count(), free_count);
  EXPECT_EQ(shell->stiffness.rows(), free_count);
  const Eigen::SparseMatrix<double> asymmetry =
      shell->stiffness - Eigen::SparseMatrix<double>(shell->stiffness.transpose());
  EXPECT_LE(asymmetry.norm(), 1e-14 * shell->stiffness.norm());
  auto solver = ShellStaticSolver::create(*shell);
  ASSERT_TRUE(solver) << solver.error().message;
  EXPECT_GT(solver->smallest_pivot(), 0.0);
  EXPECT_GT(solver->smallest_pivot_ratio(), kSingularPivotRatio);
  // Dense cross-check: every eigenvalue positive.
  const Eigen::MatrixXd dense(shell->stiffness);
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(dense).eigenvalues().minCoeff(), 0.0);
}

TEST(ShellAssembly, LumpedMassPutsRhoTAOverThreeOnTranslationsOnly) {
  auto mesh = make_tube(0.005, 0.05, 6, 10);
  ASSERT_TRUE(mesh);
  const ShellMaterial material = test_material(1e6, 0.3, 4e-4, 1100.0);
  auto shell = assemble_shell(*mesh, material, BendingElement::dkt, {{"clamped", kAllDofs}});
  ASSERT_TRUE(shell) << shell.error().message;
  double surface_area = 0.0;
  for (Eigen::Index t = 0; t < mesh->triangles.rows(); ++t) {
    const Eigen::RowVector3d p0 = mesh->nodes.row(mesh->triangles(t, 0));
    surface_area += 0.5 * (mesh->nodes.row(mesh->triangles(t, 1)) - p0)
                              .cross(mesh->nodes.row(mesh->triangles(t, 2)) - p0)
                              .norm();
  }
  // The clamped ring's share is eliminated with its dofs: one ring of 5 equal cell rings
  // holds half a cell ring's area, i.e. 1/10 of the total.
  const double free_mass = 0.9 * material.density_kg_per_m3 * material.thickness_m * surface_area;
  double mass_x = 0.0;
  for (int i = 0; i < shell->dofs.free_count(); ++i) {
    const int dof = shell->dofs.free_to_node_dof[static_cast<std::size_t>(i)] % kShellDofsPerNode;
    if (dof >= kRx) {
      EXPECT_EQ(shell->lumped_mass(i), 0.0);
    } else {
      EXPECT_GT(shell->lumped_mass(i), 0.0);
    }
    if (dof == kUx) mass_x += shell->lumped_mass(i);
  }
  EXPECT_NEAR(mass_x, free_mass, 1e-12 * free_mass);
}

// Uniform tension of a strip on rollers (ux = 0 on x = 0, uy = 0 at one corner, plane stress):
// δ = F L / (E t w) and lateral contraction ν ε w, exact for the CST whatever the bending
// element. A wrong membrane thickness factor fails this; a rigid-body or patch test cannot.
TEST_P(AssemblyBothBendings, StripInTensionStretchesByFLOverEtw) {
  const double length = 0.5, width = 0.08, thickness = 0.002;
  const double young = 3.0e6, nu = 0.35, force = 2.0;
  auto mesh = make_rectangle_plate(length, width, 20, 4, TrianglePattern::alternating);
  ASSERT_TRUE(mesh);
  mesh->node_sets["corner"] = {0};
  auto shell = assemble_shell(*mesh, test_material(young, nu, thickness, 1000.0), GetParam(),
                              {{"x0", {kUx}}, {"corner", {kUy}}, {"all", {kUz, kRx, kRy}}});
  ASSERT_TRUE(shell) << shell.error().message;
  // Consistent edge load: the two end nodes of the uniformly meshed edge take half a share.
  Eigen::VectorXd loads = make_zero_loads(*mesh);
  const auto& edge = mesh->node_sets.at("x1");
  const double share = force / static_cast<double>(edge.size() - 1);
  for (std::size_t i = 0; i < edge.size(); ++i) {
    const bool end = i == 0 || i + 1 == edge.size();
    loads(edge[i] * kShellDofsPerNode + kUx) = end ? 0.5 * share : share;
  }
  auto solution = static_solve(*shell, loads);
  ASSERT_TRUE(solution) << solution.error().message;
  const double expected = force * length / (young * thickness * width);
  const double strain = expected / length;
  for (const int node : edge) {
    EXPECT_NEAR(solution->node_displacements(node, kUx), expected, 1e-6 * expected);
    const double y = mesh->nodes(node, 1);
    EXPECT_NEAR(solution->node_displacements(node, kUy), -nu * strain * y, 1e-6 * expected);
  }
}

// The equal split of add_node_set_force is documented as not the consistent edge load: on
// the same strip it gives the same total but a non-uniform end displacement.
TEST(Loads, EqualSplitOnAnOpenEdgeIsNotTheConsistentLoad) {
  auto mesh = make_rectangle_plate(0.5, 0.08, 20, 4, TrianglePattern::alternating);
  ASSERT_TRUE(mesh);
  mesh->node_sets["corner"] = {0};
  auto shell = assemble_shell(*mesh, test_material(3e6, 0.0, 0.002, 1000.0), BendingElement::dkt,
                              {{"x0", {kUx}}, {"corner", {kUy}}, {"all", {kUz, kRx, kRy}}});
  ASSERT_TRUE(shell);
  Eigen::VectorXd loads = make_zero_loads(*mesh);
  ASSERT_TRUE(add_node_set_force(*mesh, "x1", Eigen::Vector3d(2.0, 0.0, 0.0), loads));
  EXPECT_NEAR(loads.sum(), 2.0, 1e-15);
  EXPECT_NEAR(loads(mesh->node_sets.at("x1").front() * kShellDofsPerNode), 2.0 / 5.0, 1e-15);
  auto solution = static_solve(*shell, loads);
  ASSERT_TRUE(solution);
  const auto& edge = mesh->node_sets.at("x1");
  const double end_node = solution->node_displacements(edge.front(), kUx);
  const double middle_node = solution->node_displacements(edge[2], kUx);
  EXPECT_GT(std::abs(end_node - middle_node), 1e-3 * std::abs(middle_node));
}

// Cantilever strip (L/w = 10, ν = 0 so plate and beam theory coincide: no anticlastic
// restraint at the clamp) under a tip line load: w_tip = F L³ / (3 E I), I = w t³ / 12.
// Returns the mean tip deflection over Euler–Bernoulli's.
double cantilever_tip_ratio(int nx, int ny, BendingElement element, TrianglePattern pattern) {
  const double length = 1.0, width = 0.1, thickness = 0.01, young = 2.0e9, force = 1.0;
  auto mesh = make_rectangle_plate(length, width, nx, ny, pattern);
  if (!mesh) throw std::runtime_error(mesh.error().message);
  auto shell = assemble_shell(*mesh, test_material(young, 0.0, thickness, 1000.0), element,
                              {{"x0", kAllDofs}});
  if (!shell) throw std::runtime_error(shell.error().message);
  Eigen::VectorXd loads = make_zero_loads(*mesh);
  if (auto ok = add_node_set_force(*mesh, "x1", Eigen::Vector3d(0.0, 0.0, -force), loads); !ok) {
    throw std::runtime_error(ok.error().message);
  }
  auto solution = static_solve(*shell, loads);
  if (!solution) throw std::runtime_error(solution.error().message);
  const double inertia = width * thickness * thickness * thickness / 12.0;
  const double expected = force * length * length * length / (3.0 * young * inertia);
  double tip = 0.0;
  for (const int node : mesh->node_sets.at("x1")) tip += solution->node_displacements(node, kUz);
  tip /= static_cast<double>(mesh->node_sets.at("x1").size());
  return -tip / expected;
}

const char* pattern_label(TrianglePattern pattern) {
  switch (pattern) {
    case TrianglePattern::alternating: return "alternating";
    case TrianglePattern::right: return "right";
    case TrianglePattern::left: return "left";
  }
  return "?";
}

// DKT is a Kirchhoff element (no shear), so on 40 × 4 cells it reproduces beam theory up to
// discretisation error; 1 % leaves room for the equal split of the tip load (measured 1e-4).
TEST(CantileverStrip, DktTipDeflectionMatchesEulerBernoulli) {
  for (const TrianglePattern pattern : {TrianglePattern::alternating, TrianglePattern::right}) {
    const double ratio = cantilever_tip_ratio(40, 4, BendingElement::dkt, pattern);
    std::cout << "[measured] cantilever strip 40x4 " << pattern_label(pattern)
              << ", DKT: tip deflection / Euler-Bernoulli = " << ratio << "\n";
    EXPECT_NEAR(ratio, 1.0, 0.01);
  }
}

// Rao's non-conforming cubic converges only on some mesh patterns (METHODS.md §1): with every
// quad split the same way it converges (error falls with refinement, < 2.5 % on 80 × 8);
// with alternating diagonals it settles ~24 % too flexible and does not improve. Both facts
// are asserted so the documentation's claim stays true (or the test says it changed).
TEST(CantileverStrip, RaoConvergesOnUniformDiagonalsButNotOnAlternatingOnes) {
  double previous_error = 1.0;
  for (const int nx : {20, 40, 80}) {
    const double uniform =
        cantilever_tip_ratio(nx, nx / 10, BendingElement::rao, TrianglePattern::right);
    const double alternating =
        cantilever_tip_ratio(nx, nx / 10, BendingElement::rao, TrianglePattern::alternating);
    std::cout << "[measured] cantilever strip " << nx << "x" << nx / 10
              << ", Rao: tip / Euler-Bernoulli = " << uniform << " (right), " << alternating
              << " (alternating)\n";
    const double error = std::abs(uniform - 1.0);
    EXPECT_LT(error, previous_error);
    previous_error = error;
    EXPECT_GT(alternating - 1.0, 0.15);
  }
  EXPECT_LT(previous_error, 0.025);
}

TEST(ShellAssembly, FreeRigidBodyModeIsRefusedAndNamed) {
  auto mesh = make_tube(0.004, 0.04, 5, 8);
  ASSERT_TRUE(mesh);
  // Fixing only the axial translation of one ring leaves y, z translation and the spin about
  // the tube's axis free.
  auto shell = assemble_shell(*mesh, test_material(), BendingElement::dkt, {{"clamped", {kUx}}});
  ASSERT_FALSE(shell);
  const std::string& message = shell.error().message;
  EXPECT_NE(message.find("rigid-body mode free (3 of 6)"), std::string::npos) << message;
  EXPECT_NE(message.find("translation along"), std::string::npos) << message;
  EXPECT_NE(message.find("rotation about axis (1, 0, 0)"), std::string::npos) << message;
  EXPECT_NE(message.find("Fix at least"), std::string::npos) << message;

  auto unconstrained = assemble_shell(*mesh, test_material(), BendingElement::rao, {});
  ASSERT_FALSE(unconstrained);
  EXPECT_NE(unconstrained.error().message.find("(6 of 6)"), std::string::npos)
      << unconstrained.error().message;

  // Translations of three nodes not on one line are enough.
  mesh->node_sets["three"] = {0, 3, 5 * 8 - 2};
  EXPECT_TRUE(
      assemble_shell(*mesh, test_material(), BendingElement::dkt, {{"three", {kUx, kUy, kUz}}}));
}

TEST(ShellAssembly, BadBoundaryConditionsAndMaterialsAreRefused) {
  auto mesh = make_tube(0.004, 0.04, 5, 8);
  ASSERT_TRUE(mesh);
  auto unknown =
      assemble_shell(*mesh, test_material(), BendingElement::dkt, {{"clampd", kAllDofs}});
  ASSERT_FALSE(unknown);
  EXPECT_NE(unknown.error().message.find("unknown node set 'clampd'"), std::string::npos);
  EXPECT_NE(unknown.error().message.find("clamped"), std::string::npos) << "lists known sets";

  auto bad_dof = assemble_shell(*mesh, test_material(), BendingElement::dkt, {{"clamped", {6}}});
  ASSERT_FALSE(bad_dof);
  EXPECT_NE(bad_dof.error().message.find("dof 6"), std::string::npos) << bad_dof.error().message;

  struct Case {
    ShellMaterial material;
    const char* field;
  };
  const Case cases[] = {
      {{0.0, 0.3, 1e-3, 1000.0}, "young_modulus_pa"},
      {{1e6, 0.5, 1e-3, 1000.0}, "poisson_ratio"},
      {{1e6, -1.0, 1e-3, 1000.0}, "poisson_ratio"},
      {{1e6, 0.3, 0.0, 1000.0}, "thickness_m"},
      {{1e6, 0.3, 1e-3, -1.0}, "density_kg_per_m3"},
      {{std::nan(""), 0.3, 1e-3, 1000.0}, "young_modulus_pa"},
  };
  for (const Case& c : cases) {
    auto result = assemble_shell(*mesh, c.material, BendingElement::dkt, {{"clamped", kAllDofs}});
    ASSERT_FALSE(result) << c.field;
    EXPECT_NE(result.error().message.find(c.field), std::string::npos) << result.error().message;
  }
}

TEST(StaticSolve, SingularMatrixIsRefusedNamingTheDof) {
  // A hand-made 12-dof system whose node 1 rz has no stiffness at all.
  AssembledShell shell;
  shell.dofs.node_count = 2;
  for (int i = 0; i < 12; ++i) {
    shell.dofs.free_index.push_back(i);
    shell.dofs.free_to_node_dof.push_back(i);
  }
  Eigen::MatrixXd dense = Eigen::MatrixXd::Identity(12, 12);
  dense(11, 11) = 0.0;
  shell.stiffness = dense.sparseView();
  shell.lumped_mass = Eigen::VectorXd::Ones(12);
  auto solver = ShellStaticSolver::create(shell);
  ASSERT_FALSE(solver);
  EXPECT_NE(solver.error().message.find("node 1 dof rz"), std::string::npos)
      << solver.error().message;

  dense(11, 11) = 2.0;
  shell.stiffness = dense.sparseView();
  auto good = ShellStaticSolver::create(shell);
  ASSERT_TRUE(good) << good.error().message;
  Eigen::VectorXd loads = Eigen::VectorXd::LinSpaced(12, 1.0, 12.0);
  auto solution = good->solve(loads);
  ASSERT_TRUE(solution);
  EXPECT_DOUBLE_EQ(solution->node_displacements(1, kRz), 6.0);
  EXPECT_DOUBLE_EQ(solution->node_displacements(0, kUy), 2.0);
  EXPECT_FALSE(good->solve(Eigen::VectorXd::Ones(5))) << "wrong load size is refused";
}

TEST(Loads, SurfaceTractionIsConsistentAndNodeSetForceIsSplitEqually) {
  auto mesh = make_rectangle_plate(2.0, 1.0, 4, 2, TrianglePattern::right);
  ASSERT_TRUE(mesh);
  Eigen::VectorXd loads = make_zero_loads(*mesh);
  ASSERT_TRUE(add_surface_traction(*mesh, "plate", Eigen::Vector3d(0.0, 0.0, -90.0), loads));
  double total_z = 0.0;
  for (Eigen::Index n = 0; n < mesh->nodes.rows(); ++n) {
    total_z += loads(n * kShellDofsPerNode + kUz);
    EXPECT_EQ(loads(n * kShellDofsPerNode + kUx), 0.0);
    EXPECT_EQ(loads.segment<3>(n * kShellDofsPerNode + kRx).norm(), 0.0);
  }
  EXPECT_NEAR(total_z, -90.0 * 2.0, 1e-12);
  // Node 0 (corner (0,0), pattern right) touches one triangle of area 0.25 / 2 ... its
  // share is p·A/3 per triangle it belongs to.
  const double cell_triangle_area = 0.5 * 0.5 * 0.5;
  int corner_triangles = 0;
  for (Eigen::Index t = 0; t < mesh->triangles.rows(); ++t) {
    for (int c = 0; c < 3; ++c) corner_triangles += mesh->triangles(t, c) == 0 ? 1 : 0;
  }
  EXPECT_NEAR(loads(kUz), -90.0 * cell_triangle_area / 3.0 * corner_triangles, 1e-12);

  Eigen::VectorXd pressure = make_zero_loads(*mesh);
  ASSERT_TRUE(add_normal_pressure(*mesh, "plate", 10.0, pressure));
  EXPECT_NEAR(pressure.sum(), 10.0 * 2.0, 1e-12) << "plate normals are +z";

  EXPECT_FALSE(add_surface_traction(*mesh, "nope", Eigen::Vector3d::Zero(), loads));
  EXPECT_FALSE(add_node_set_force(*mesh, "nope", Eigen::Vector3d::Zero(), loads));
  Eigen::VectorXd wrong_size = Eigen::VectorXd::Zero(3);
  EXPECT_FALSE(add_node_set_force(*mesh, "x0", Eigen::Vector3d::UnitX(), wrong_size));
}

}  // namespace
}  // namespace trainer::model::offline
