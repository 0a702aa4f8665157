// Linear tetrahedral elasticity (METHODS.md §3): the element against continuum identities
// (rigid-body modes, strain energy of a uniform strain), the patch test, exact and beam-theory
// answers on generated boxes, the CHOLMOD solver's refusals and multi-column solves, the Gmsh
// path, and the assembly/factorisation timings reported in docs/model-verification.md.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include "tet_test_support.hpp"
#include "trainer/model_offline/gmsh_reader.hpp"
#include "trainer/model_offline/tet_elasticity.hpp"
#include "trainer/model_offline/tet_mesh_generators.hpp"

namespace trainer::model::offline {
namespace {

constexpr double kYoung = 2.0e6;  // Pa, a soft-tissue-like modulus (answers scale as 1/E)
constexpr double kPoisson = 0.3;

// A deliberately irregular tetrahedron (positive volume).
Eigen::Matrix<double, 4, 3> irregular_tet() {
  Eigen::Matrix<double, 4, 3> corners;
  corners << 0.001, -0.002, 0.0005,  //
      0.012, 0.001, -0.001,          //
      0.003, 0.009, 0.002,           //
      0.002, 0.003, 0.011;
  return corners;
}

// Displacement of node positions under u(x) = a + A x, as a 3n vector.
Eigen::VectorXd linear_field(const Eigen::Ref<const Eigen::MatrixXd>& positions,
                             const Eigen::Vector3d& offset, const Eigen::Matrix3d& gradient) {
  Eigen::VectorXd u(3 * positions.rows());
  for (Eigen::Index n = 0; n < positions.rows(); ++n) {
    u.segment<3>(3 * n) = offset + gradient * positions.row(n).transpose();
  }
  return u;
}

TEST(Tet4Element, SymmetricWithSixRigidBodyModesAndSixPositive) {
  auto stiffness = tet4_stiffness(irregular_tet(), kYoung, kPoisson);
  ASSERT_TRUE(stiffness) << stiffness.error().message;
  const Eigen::Matrix<double, 12, 12>& k = *stiffness;
  const double scale = k.cwiseAbs().maxCoeff();
  // Symmetry: exact up to rounding of the product V Bᵀ D B.
  EXPECT_LE((k - k.transpose()).cwiseAbs().maxCoeff(), 1e-14 * scale);

  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> eigen(k);
  const auto& values = eigen.eigenvalues();  // ascending
  // Six rigid-body modes (3 translations, 3 rotations): zero to rounding, 1e-12 of the largest.
  for (int i = 0; i < 6; ++i) EXPECT_LE(std::abs(values(i)), 1e-12 * values(11)) << i;
  // Six strain modes (the 6 constant strains): clearly positive.
  for (int i = 6; i < 12; ++i) EXPECT_GT(values(i), 1e-3 * values(11)) << i;

  // The rigid motions themselves are in the null space.
  const Eigen::Vector3d centre = irregular_tet().colwise().mean().transpose();
  for (int axis = 0; axis < 3; ++axis) {
    const Eigen::Vector3d translation = Eigen::Vector3d::Unit(axis);
    Eigen::Matrix3d rotation = Eigen::Matrix3d::Zero();  // infinitesimal rotation about `axis`
    rotation(static_cast<Eigen::Index>((axis + 1) % 3), static_cast<Eigen::Index>((axis + 2) % 3)) =
        -1.0;
    rotation(static_cast<Eigen::Index>((axis + 2) % 3), static_cast<Eigen::Index>((axis + 1) % 3)) =
        1.0;
    const Eigen::VectorXd moved =
        linear_field(irregular_tet(), translation, Eigen::Matrix3d::Zero());
    const Eigen::VectorXd turned = linear_field(irregular_tet(), -rotation * centre, rotation);
    EXPECT_LE((k * moved).norm(), 1e-12 * scale);
    EXPECT_LE((k * turned).norm(), 1e-12 * scale * 0.01);  // rotation amplitudes ~ 0.01 m
  }
}

// ½ uᵀ K u for a uniform strain equals V (λ/2 (tr ε)² + μ ε:ε), computed here from the
// continuum formula, independently of the element's D matrix; a linear element is exact.
TEST(Tet4Element, StrainEnergyOfAUniformStrainIsExact) {
  auto stiffness = tet4_stiffness(irregular_tet(), kYoung, kPoisson);
  ASSERT_TRUE(stiffness);
  Eigen::Matrix3d gradient;
  gradient << 1e-3, 4e-4, -2e-4,  //
      -1e-4, -5e-4, 3e-4,         //
      6e-4, 2e-4, 8e-4;
  const Eigen::Matrix3d strain = 0.5 * (gradient + gradient.transpose());
  const double lambda = kYoung * kPoisson / ((1 + kPoisson) * (1 - 2 * kPoisson));
  const double mu = kYoung / (2 * (1 + kPoisson));
  const double density =
      0.5 * lambda * strain.trace() * strain.trace() + mu * strain.cwiseProduct(strain).sum();
  const double volume = tet_signed_volume(irregular_tet());
  const Eigen::VectorXd u = linear_field(irregular_tet(), Eigen::Vector3d(1e-4, 0, 0), gradient);
  const double energy = 0.5 * u.dot(*stiffness * u);
  EXPECT_NEAR(energy, volume * density, 1e-12 * volume * density);
}

TEST(Tet4Element, RefusesBadGeometryAndMaterial) {
  Eigen::Matrix<double, 4, 3> flat = irregular_tet();
  flat.row(3) = 0.5 * (flat.row(1) + flat.row(2));  // in the plane of the other three
  auto degenerate = tet4_stiffness(flat, kYoung, kPoisson);
  ASSERT_FALSE(degenerate);
  EXPECT_NE(degenerate.error().message.find("degenerate"), std::string::npos)
      << degenerate.error().message;

  Eigen::Matrix<double, 4, 3> inverted = irregular_tet();
  inverted.row(2).swap(inverted.row(3));
  auto refused = tet4_stiffness(inverted, kYoung, kPoisson);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("inverted"), std::string::npos) << refused.error().message;

  Eigen::Matrix<double, 4, 3> not_finite = irregular_tet();
  not_finite(1, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(tet4_stiffness(not_finite, kYoung, kPoisson));

  auto no_modulus = tet4_stiffness(irregular_tet(), 0.0, kPoisson);
  ASSERT_FALSE(no_modulus);
  EXPECT_NE(no_modulus.error().message.find("young_modulus_pa"), std::string::npos);
  for (const double nu : {0.5, -1.0, 0.7}) {
    auto bad = tet4_stiffness(irregular_tet(), kYoung, nu);
    ASSERT_FALSE(bad) << nu;
    EXPECT_NE(bad.error().message.find("poisson_ratio"), std::string::npos);
  }
  EXPECT_TRUE(tet4_stiffness(irregular_tet(), kYoung, 0.49));
}

// Patch test: boundary nodes of a box driven by a linear displacement field; the interior nodes
// must reproduce the field to rounding (1e-10 of its size), whatever the mesh.
TEST(TetAssembly, PatchTestReproducesALinearField) {
  auto mesh = make_tet_box(0.02, 0.015, 0.01, 4, 3, 3);
  ASSERT_TRUE(mesh) << mesh.error().message;
  // Shake the interior nodes so the tetrahedra are irregular (still positive).
  std::vector<bool> on_surface(static_cast<std::size_t>(mesh->nodes.rows()), false);
  for (const int node : mesh->node_sets.at("surface"))
    on_surface[static_cast<std::size_t>(node)] = true;
  for (Eigen::Index n = 0; n < mesh->nodes.rows(); ++n) {
    if (on_surface[static_cast<std::size_t>(n)]) continue;
    mesh->nodes.row(n) += 8e-4 * Eigen::RowVector3d(std::sin(3.0 * static_cast<double>(n)),
                                                    std::cos(5.0 * static_cast<double>(n)),
                                                    std::sin(7.0 * static_cast<double>(n)));
  }
  ASSERT_TRUE(validate_tet_mesh(*mesh));
  const TetMaterial material{kYoung, kPoisson, 1000.0};
  auto full = assemble_tet(*mesh, material, {});  // K of every dof (singular, not solved)
  ASSERT_TRUE(full) << full.error().message;
  auto fixed = assemble_tet(*mesh, material, {{mesh->node_sets.at("surface"), {true, true, true}}});
  ASSERT_TRUE(fixed) << fixed.error().message;
  const auto solver = TetStaticSolver::create(*fixed);
  ASSERT_TRUE(solver) << solver.error().message;

  Eigen::Matrix3d gradient;
  gradient << 2e-3, -1e-3, 5e-4,  //
      3e-4, -1.5e-3, 1e-3,        //
      -7e-4, 4e-4, 2.5e-3;
  const Eigen::VectorXd field =
      linear_field(mesh->nodes, Eigen::Vector3d(1e-5, -2e-5, 3e-5), gradient);
  // Interior equations: K_ii u_i = −K_ib u_b, i.e. the interior rows of K applied to the field
  // with the interior part zeroed.
  Eigen::VectorXd boundary_only = field;
  const TetDofMap& interior = fixed->dofs;
  for (int d = 0; d < static_cast<int>(interior.free_index.size()); ++d) {
    if (interior.free_index[static_cast<std::size_t>(d)] >= 0) boundary_only(d) = 0.0;
  }
  const Eigen::VectorXd full_forces = full->stiffness_free * boundary_only;  // no fixes: dof = row
  Eigen::VectorXd rhs(interior.free_count);
  for (int i = 0; i < interior.free_count; ++i) {
    rhs(i) = -full_forces(interior.free_to_node_dof[static_cast<std::size_t>(i)]);
  }
  auto interior_u = solver->solve_free(rhs);
  ASSERT_TRUE(interior_u) << interior_u.error().message;
  ASSERT_GT(interior.free_count, 0);
  for (int i = 0; i < interior.free_count; ++i) {
    EXPECT_NEAR((*interior_u)(i, 0), field(interior.free_to_node_dof[static_cast<std::size_t>(i)]),
                1e-10 * field.cwiseAbs().maxCoeff());
  }
  // And the full K applied to the field leaves no force on interior nodes (equilibrium).
  const Eigen::VectorXd residual = full->stiffness_free * field;
  for (int i = 0; i < interior.free_count; ++i) {
    EXPECT_LE(std::abs(residual(interior.free_to_node_dof[static_cast<std::size_t>(i)])),
              1e-10 * full_forces.cwiseAbs().maxCoeff());
  }
}

TEST(TetAssembly, MassVolumeAndCounts) {
  auto mesh = make_tet_box(0.03, 0.02, 0.01, 3, 2, 2);
  ASSERT_TRUE(mesh);
  auto assembled = assemble_tet(*mesh, {kYoung, kPoisson, 1100.0},
                                {{mesh->node_sets.at("x0"), {true, false, true}}});
  ASSERT_TRUE(assembled) << assembled.error().message;
  const double volume = 0.03 * 0.02 * 0.01;
  EXPECT_NEAR(assembled->volume_m3, volume, 1e-15 * volume * 100);
  EXPECT_NEAR(assembled->lumped_mass_kg.sum(), 1100.0 * volume, 1e-12 * 1100.0 * volume);
  EXPECT_EQ(assembled->element_count, 6 * 3 * 2 * 2);
  const int x0_nodes = static_cast<int>(mesh->node_sets.at("x0").size());
  EXPECT_EQ(assembled->dofs.free_count, 3 * static_cast<int>(mesh->nodes.rows()) - 2 * x0_nodes);
  EXPECT_EQ(assembled->stiffness_free.rows(), assembled->dofs.free_count);
  const Eigen::SparseMatrix<double> transpose = assembled->stiffness_free.transpose();
  EXPECT_LE((assembled->stiffness_free - transpose).norm(),
            1e-14 * assembled->stiffness_free.norm());
  const int node = mesh->node_sets.at("x0").front();
  EXPECT_EQ(assembled->dofs.free_index[static_cast<std::size_t>(3 * node)], -1);
  EXPECT_GE(assembled->dofs.free_index[static_cast<std::size_t>(3 * node + 1)], 0);
}

TEST(TetAssembly, ErrorsNameTheElementOrNode) {
  auto mesh = make_tet_box(0.01, 0.01, 0.01, 1, 1, 1);
  ASSERT_TRUE(mesh);
  const TetMaterial material{kYoung, kPoisson, 1000.0};
  TetMesh inverted = *mesh;
  std::swap(inverted.tetrahedra(4, 2), inverted.tetrahedra(4, 3));
  auto refused = assemble_tet(inverted, material, {});
  ASSERT_FALSE(refused);
  const std::string& message = refused.error().message;
  EXPECT_NE(message.find("tetrahedron 4 (nodes " + std::to_string(inverted.tetrahedra(4, 0))),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("inverted"), std::string::npos) << message;
  auto invalid = validate_tet_mesh(inverted);
  ASSERT_FALSE(invalid);
  EXPECT_NE(invalid.error().message.find("tetrahedron 4"), std::string::npos);

  auto out_of_range = assemble_tet(*mesh, material, {{{0, 99}, {true, true, true}}});
  ASSERT_FALSE(out_of_range);
  EXPECT_NE(out_of_range.error().message.find("node 99"), std::string::npos);

  TetMesh extra_node = *mesh;
  extra_node.nodes.conservativeResize(extra_node.nodes.rows() + 1, 3);
  extra_node.nodes.row(extra_node.nodes.rows() - 1) << 1.0, 1.0, 1.0;
  auto unused = assemble_tet(extra_node, material, {});
  ASSERT_FALSE(unused);
  EXPECT_NE(unused.error().message.find("node 8 is used by no tetrahedron"), std::string::npos)
      << unused.error().message;

  auto nothing_free =
      assemble_tet(*mesh, material, {{mesh->node_sets.at("all"), {true, true, true}}});
  ASSERT_FALSE(nothing_free);
  EXPECT_NE(nothing_free.error().message.find("no free dof"), std::string::npos);
}

// Uniaxial tension of a bar with symmetry-plane rollers (x0: x, y0: y, z0: z) and the force on
// x1 spread over its area: the exact solution u = (σ/E)(x, −ν y, −ν z) is linear, hence in the
// element space, and the area-weighted load is the consistent load of a uniform traction: the FE
// answer is exact to rounding (tolerance 1e-9 relative). The equal-per-node split is not
// consistent (corner and edge nodes get too much) and is only checked on the mean.
TEST(TetStaticSolver, BarInTensionIsExact) {
  const double length = 0.1, side = 0.01, force = 0.5;
  auto mesh = make_tet_box(length, side, side, 20, 2, 2);
  ASSERT_TRUE(mesh);
  auto assembled = assemble_tet(*mesh, {kYoung, kPoisson, 1000.0},
                                {{mesh->node_sets.at("x0"), {true, false, false}},
                                 {mesh->node_sets.at("y0"), {false, true, false}},
                                 {mesh->node_sets.at("z0"), {false, false, true}}});
  ASSERT_TRUE(assembled) << assembled.error().message;
  auto solver = TetStaticSolver::create(*assembled);
  ASSERT_TRUE(solver) << solver.error().message;
  TetNodalLoads loads = TetNodalLoads::Zero(mesh->nodes.rows(), 3);
  auto distribution = add_tet_group_force(*mesh, "x1", Eigen::Vector3d(force, 0, 0), loads);
  ASSERT_TRUE(distribution) << distribution.error().message;
  EXPECT_EQ(*distribution, TetLoadDistribution::area_weighted);
  EXPECT_NEAR(loads.col(0).sum(), force, 1e-15);
  auto u = solver->solve_nodal(loads);
  ASSERT_TRUE(u) << u.error().message;
  const double strain = force / (side * side * kYoung);
  for (Eigen::Index n = 0; n < mesh->nodes.rows(); ++n) {
    const Eigen::RowVector3d expected =
        strain * Eigen::RowVector3d(mesh->nodes(n, 0), -kPoisson * mesh->nodes(n, 1),
                                    -kPoisson * mesh->nodes(n, 2));
    EXPECT_LE((u->row(n) - expected).cwiseAbs().maxCoeff(), 1e-9 * strain * length) << n;
  }

  // Equal split over the 9 x1 nodes: the mean end displacement is still within 1 % of F L/(E A)
  // (the load's resultant is right, its distribution only disturbs the end region).
  TetNodalLoads equal = TetNodalLoads::Zero(mesh->nodes.rows(), 3);
  TetMesh nodes_only = *mesh;
  nodes_only.triangle_sets.erase("x1");
  auto split = add_tet_group_force(nodes_only, "x1", Eigen::Vector3d(force, 0, 0), equal);
  ASSERT_TRUE(split);
  EXPECT_EQ(*split, TetLoadDistribution::equal_per_node);
  auto u_equal = solver->solve_nodal(equal);
  ASSERT_TRUE(u_equal);
  double mean = 0.0;
  for (const int node : mesh->node_sets.at("x1")) mean += (*u_equal)(node, 0);
  mean /= static_cast<double>(mesh->node_sets.at("x1").size());
  EXPECT_NEAR(mean, strain * length, 0.01 * strain * length);
}

// Cantilever L × h × h (L/h = 10) clamped at x = 0, transverse force F on the end face
// (area-weighted, i.e. a uniform end shear). Reference: Timoshenko δ = F L³/(3 E I) +
// F L/(κ G A), κ = 5/6. Linear tetrahedra lock in bending, so they converge from below, slowly:
// measured errors 78, 50, 21, 7.0 % for 1, 2, 4, 8 cells across. Asserted: monotone convergence
// from below, < 8 % at 8 cells across, and the Richardson extrapolation of the last two meshes
// (displacement error O(h²)) within 3 % — the remainder is the 3-D clamp, which also stops the
// Poisson contraction at the root and so is a little stiffer than the beam's clamp.
TEST(TetStaticSolver, CantileverConvergesToTimoshenko) {
  const double length = 0.1, side = 0.01, force = 1e-3;
  const double inertia = side * side * side * side / 12.0, area = side * side;
  const double shear_modulus = kYoung / (2.0 * (1.0 + kPoisson));
  const double reference = force * length * length * length / (3.0 * kYoung * inertia) +
                           force * length / (5.0 / 6.0 * shear_modulus * area);
  double previous_error = 1.0, previous_tip = 0.0, tip = 0.0;
  for (const int across : {1, 2, 4, 8}) {
    auto mesh = make_tet_box(length, side, side, 10 * across, across, across);
    ASSERT_TRUE(mesh);
    auto assembled = assemble_tet(*mesh, {kYoung, kPoisson, 1000.0},
                                  {{mesh->node_sets.at("x0"), {true, true, true}}});
    ASSERT_TRUE(assembled) << assembled.error().message;
    auto solver = TetStaticSolver::create(*assembled);
    ASSERT_TRUE(solver) << solver.error().message;
    TetNodalLoads loads = TetNodalLoads::Zero(mesh->nodes.rows(), 3);
    ASSERT_TRUE(add_tet_group_force(*mesh, "x1", Eigen::Vector3d(0, 0, force), loads));
    auto u = solver->solve_nodal(loads);
    ASSERT_TRUE(u);
    previous_tip = tip;
    tip = 0.0;
    for (const int node : mesh->node_sets.at("x1")) tip += (*u)(node, 2);
    tip /= static_cast<double>(mesh->node_sets.at("x1").size());
    const double error = std::abs(tip - reference) / reference;
    std::printf("cantilever %3d x %d x %d: mean tip %.6e m, Timoshenko %.6e m, error %.2f %%\n",
                10 * across, across, across, tip, reference, 100.0 * error);
    EXPECT_LT(tip, reference) << "linear tetrahedra are too stiff, never too soft";
    EXPECT_LT(error, previous_error) << across;
    previous_error = error;
  }
  EXPECT_LT(previous_error, 0.08);
  const double extrapolated = tip + (tip - previous_tip) / 3.0;
  std::printf("cantilever Richardson extrapolation %.6e m, error %.2f %%\n", extrapolated,
              100.0 * std::abs(extrapolated - reference) / reference);
  EXPECT_NEAR(extrapolated, reference, 0.03 * reference);
}

TEST(TetStaticSolver, TooFewFixesIsRefused) {
  auto mesh = make_tet_box(0.02, 0.01, 0.01, 4, 2, 2);
  ASSERT_TRUE(mesh);
  const TetMaterial material{kYoung, kPoisson, 1000.0};
  // x0 fixed along x only: translations in y and z (and a rotation about x) remain free.
  auto rollers = assemble_tet(*mesh, material, {{mesh->node_sets.at("x0"), {true, false, false}}});
  ASSERT_TRUE(rollers);
  auto refused = TetStaticSolver::create(*rollers);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("rigid-body motion"), std::string::npos)
      << refused.error().message;
  auto floating = assemble_tet(*mesh, material, {});
  ASSERT_TRUE(floating);
  EXPECT_FALSE(TetStaticSolver::create(*floating));
}

// Many right-hand sides in one call give the same answer as one at a time, and satisfy K u = f.
TEST(TetStaticSolver, BlockSolveMatchesColumnSolves) {
  auto mesh = make_tet_cylinder(0.01, 0.02, 3, 4);
  ASSERT_TRUE(mesh) << mesh.error().message;
  auto assembled = assemble_tet(*mesh, {kYoung, kPoisson, 1000.0},
                                {{mesh->node_sets.at("bottom"), {true, true, true}}});
  ASSERT_TRUE(assembled);
  auto solver = TetStaticSolver::create(*assembled);
  ASSERT_TRUE(solver) << solver.error().message;
  EXPECT_GT(solver->reciprocal_condition_estimate(), kSingularReciprocalCondition);
  EXPECT_EQ(solver->dofs().free_count, assembled->dofs.free_count);
  EXPECT_GE(solver->factorization_time_s(), 0.0);
  const int columns = 7;
  const Eigen::MatrixXd rhs = Eigen::MatrixXd::Random(assembled->dofs.free_count, columns);
  auto block = solver->solve_free(rhs);
  ASSERT_TRUE(block) << block.error().message;
  ASSERT_EQ(block->cols(), columns);
  const Eigen::MatrixXd residual = assembled->stiffness_free * *block - rhs;
  EXPECT_LE(residual.cwiseAbs().maxCoeff(), 1e-9 * rhs.cwiseAbs().maxCoeff());
  for (int c = 0; c < columns; ++c) {
    auto single = solver->solve_free(rhs.col(c));
    ASSERT_TRUE(single);
    EXPECT_LE((single->col(0) - block->col(c)).cwiseAbs().maxCoeff(),
              1e-12 * block->cwiseAbs().maxCoeff());
  }
  // A block view with an outer stride (every other column) is accepted too.
  const Eigen::MatrixXd wide = Eigen::MatrixXd::Random(assembled->dofs.free_count + 5, 3);
  auto strided = solver->solve_free(wide.topRows(assembled->dofs.free_count));
  ASSERT_TRUE(strided);
  const Eigen::MatrixXd compact = wide.topRows(assembled->dofs.free_count);
  auto contiguous = solver->solve_free(compact);
  ASSERT_TRUE(contiguous);
  EXPECT_EQ((*strided - *contiguous).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_FALSE(solver->solve_free(Eigen::MatrixXd::Zero(3, 1)));
  EXPECT_FALSE(solver->solve_nodal(TetNodalLoads::Zero(2, 3)));
}

// The Gmsh path: a generated box written as MSH 4.1 and read back assembles to the same K and the
// same answer as the generator's own mesh.
TEST(TetStaticSolver, GmshTetMeshAssemblesLikeTheGenerator) {
  auto box = make_tet_box(0.04, 0.01, 0.02, 8, 2, 4);
  ASSERT_TRUE(box);
  const std::string text = testing::write_gmsh_tet(*box, {"x0", "x1"});
  auto read = parse_gmsh_tet(text, "box.msh");
  ASSERT_TRUE(read) << read.error().message;
  ASSERT_EQ(read->nodes.rows(), box->nodes.rows());
  ASSERT_EQ(read->tetrahedra.rows(), box->tetrahedra.rows());
  ASSERT_TRUE(validate_tet_mesh(*read));
  const TetMaterial material{kYoung, kPoisson, 1000.0};
  auto from_file = assemble_tet(*read, material, {{read->node_sets.at("x0"), {true, true, true}}});
  auto from_generator =
      assemble_tet(*box, material, {{box->node_sets.at("x0"), {true, true, true}}});
  ASSERT_TRUE(from_file) << from_file.error().message;
  ASSERT_TRUE(from_generator);
  EXPECT_LE((from_file->stiffness_free - from_generator->stiffness_free).norm(),
            1e-12 * from_generator->stiffness_free.norm());
  auto solver = TetStaticSolver::create(*from_file);
  ASSERT_TRUE(solver);
  TetNodalLoads file_loads = TetNodalLoads::Zero(read->nodes.rows(), 3);
  TetNodalLoads generator_loads = TetNodalLoads::Zero(box->nodes.rows(), 3);
  ASSERT_TRUE(add_tet_group_force(*read, "x1", Eigen::Vector3d(0.01, 0, -0.02), file_loads));
  ASSERT_TRUE(add_tet_group_force(*box, "x1", Eigen::Vector3d(0.01, 0, -0.02), generator_loads));
  EXPECT_LE((file_loads - generator_loads).cwiseAbs().maxCoeff(), 1e-15);
  auto u = solver->solve_nodal(file_loads);
  ASSERT_TRUE(u);
  EXPECT_GT(u->cwiseAbs().maxCoeff(), 0.0);
}

// Timings for the report (docs/model-verification.md): assembly and CHOLMOD factorisation of a
// cube clamped on one face, ~2,000 nodes always and ~10,000 nodes when TRAINER_TET_LARGE_TIMING
// is set (≈ 1.6e10 flops: ~10 s with the reference BLAS, too slow for every unit run). The check
// is that the solve is sound (relative residual 1e-10).
TEST(TetStaticSolver, AssemblyAndFactorisationTimes) {
  std::vector<int> sizes{12};
  if (std::getenv("TRAINER_TET_LARGE_TIMING") != nullptr) sizes.push_back(21);
  for (const int cells : sizes) {
    auto mesh = make_tet_box(0.05, 0.05, 0.05, cells, cells, cells);
    ASSERT_TRUE(mesh);
    const auto start = std::chrono::steady_clock::now();
    auto assembled = assemble_tet(*mesh, {kYoung, kPoisson, 1000.0},
                                  {{mesh->node_sets.at("z0"), {true, true, true}}});
    const double assembly_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ASSERT_TRUE(assembled);
    auto solver = TetStaticSolver::create(*assembled);
    ASSERT_TRUE(solver) << solver.error().message;
    const int columns = 100;
    const Eigen::MatrixXd rhs = Eigen::MatrixXd::Random(assembled->dofs.free_count, columns);
    const auto solve_start = std::chrono::steady_clock::now();
    auto u = solver->solve_free(rhs);
    const double solve_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - solve_start).count();
    ASSERT_TRUE(u);
    const Eigen::MatrixXd residual = assembled->stiffness_free * *u - rhs;
    EXPECT_LE(residual.cwiseAbs().maxCoeff(), 1e-10 * rhs.cwiseAbs().maxCoeff());
    std::printf(
        "tet box %d^3: %ld nodes, %ld tets, %d free dofs: assembly %.3f s, "
        "factorisation %.3f s, %d-column solve %.3f s\n",
        cells, static_cast<long>(mesh->nodes.rows()), static_cast<long>(mesh->tetrahedra.rows()),
        assembled->dofs.free_count, assembly_s, solver->factorization_time_s(), columns, solve_s);
  }
}

}  // namespace
}  // namespace trainer::model::offline
