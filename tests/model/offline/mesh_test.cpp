// Mesh generators (tube, plate, cylindrical panel) and mesh validation: one test per
// validation error, each message naming the element or node at fault.
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <set>

#include "trainer/model_offline/mesh_generators.hpp"
#include "trainer/model_offline/mesh_validation.hpp"
#include "trainer/model_offline/loads.hpp"
#include "trainer/model_offline/shell_assembly.hpp"
#include "trainer/model_offline/static_solve.hpp"

namespace trainer::model::offline {
namespace {

Eigen::Vector3d triangle_normal(const ShellMesh& mesh, Eigen::Index t) {
  const Eigen::Vector3d p0 = mesh.nodes.row(mesh.triangles(t, 0)).transpose();
  const Eigen::Vector3d p1 = mesh.nodes.row(mesh.triangles(t, 1)).transpose();
  const Eigen::Vector3d p2 = mesh.nodes.row(mesh.triangles(t, 2)).transpose();
  return (p1 - p0).cross(p2 - p0);
}

Eigen::Vector3d triangle_centroid(const ShellMesh& mesh, Eigen::Index t) {
  return (mesh.nodes.row(mesh.triangles(t, 0)) + mesh.nodes.row(mesh.triangles(t, 1)) +
          mesh.nodes.row(mesh.triangles(t, 2)))
             .transpose() /
         3.0;
}

TEST(MakeTube, GeometrySetsNormalsAndAlternatingDiagonals) {
  const double radius = 0.004, length = 0.05;
  const int rings = 11, segments = 16;
  auto mesh = make_tube(radius, length, rings, segments);
  ASSERT_TRUE(mesh) << mesh.error().message;
  EXPECT_EQ(mesh->nodes.rows(), rings * segments);
  EXPECT_EQ(mesh->triangles.rows(), 2 * (rings - 1) * segments);
  for (Eigen::Index n = 0; n < mesh->nodes.rows(); ++n) {
    EXPECT_NEAR(std::hypot(mesh->nodes(n, 1), mesh->nodes(n, 2)), radius, 1e-15);
    EXPECT_GE(mesh->nodes(n, 0), 0.0);
    EXPECT_LE(mesh->nodes(n, 0), length);
  }
  ASSERT_EQ(mesh->node_sets.at("clamped").size(), static_cast<std::size_t>(segments));
  ASSERT_EQ(mesh->node_sets.at("free_end").size(), static_cast<std::size_t>(segments));
  for (const int n : mesh->node_sets.at("clamped")) EXPECT_EQ(mesh->nodes(n, 0), 0.0);
  for (const int n : mesh->node_sets.at("free_end")) EXPECT_NEAR(mesh->nodes(n, 0), length, 1e-15);
  EXPECT_EQ(mesh->node_sets.at("all").size(), static_cast<std::size_t>(rings * segments));
  EXPECT_EQ(mesh->triangle_sets.at("wall").size(),
            static_cast<std::size_t>(mesh->triangles.rows()));

  // Outward normals; diagonals alternate: half the quads use each direction. A diagonal joins
  // two nodes on different rings and different segments; classify by the sign of the
  // segment step when going up one ring.
  int rising = 0, falling = 0;
  std::set<std::pair<int, int>> diagonals;
  for (Eigen::Index t = 0; t < mesh->triangles.rows(); ++t) {
    const Eigen::Vector3d centroid = triangle_centroid(*mesh, t);
    const Eigen::Vector3d radial(0.0, centroid.y(), centroid.z());
    EXPECT_GT(triangle_normal(*mesh, t).dot(radial), 0.0) << "triangle " << t;
    for (int a = 0; a < 3; ++a) {
      const int p = mesh->triangles(t, a), q = mesh->triangles(t, (a + 1) % 3);
      const int ring_p = p / segments, ring_q = q / segments;
      if (ring_p == ring_q || p % segments == q % segments) continue;
      diagonals.insert({std::min(p, q), std::max(p, q)});
    }
  }
  for (const auto& [p, q] : diagonals) {
    const int step = (q % segments - p % segments + segments) % segments;
    (step == 1 ? rising : falling) += 1;
  }
  EXPECT_EQ(rising + falling, (rings - 1) * segments);
  EXPECT_EQ(rising, falling);
  EXPECT_TRUE(validate_shell_mesh(*mesh));
}

TEST(MakeTube, HashFollowsParametersAndBadParametersAreRefused) {
  auto a = make_tube(0.004, 0.05, 11, 16);
  auto b = make_tube(0.004, 0.05, 11, 16);
  auto c = make_tube(0.004, 0.05, 11, 17);
  auto d = make_tube(0.0040000000001, 0.05, 11, 16);
  ASSERT_TRUE(a && b && c && d);
  EXPECT_EQ(a->source_hash, b->source_hash);
  EXPECT_NE(a->source_hash, c->source_hash);
  EXPECT_NE(a->source_hash, d->source_hash);
  EXPECT_NE(a->source_hash, 0u);
  for (auto bad : {make_tube(0.0, 1.0, 3, 8), make_tube(1.0, -1.0, 3, 8), make_tube(1.0, 1.0, 1, 8),
                   make_tube(1.0, 1.0, 3, 2)}) {
    ASSERT_FALSE(bad);
    EXPECT_NE(bad.error().message.find("make_tube"), std::string::npos);
  }
}

TEST(MakeRectanglePlate, EdgesSetsAndPatterns) {
  for (const TrianglePattern pattern :
       {TrianglePattern::alternating, TrianglePattern::right, TrianglePattern::left}) {
    auto mesh = make_rectangle_plate(2.0, 1.0, 4, 3, pattern);
    ASSERT_TRUE(mesh);
    EXPECT_EQ(mesh->nodes.rows(), 5 * 4);
    EXPECT_EQ(mesh->triangles.rows(), 2 * 4 * 3);
    for (const int n : mesh->node_sets.at("x0")) EXPECT_EQ(mesh->nodes(n, 0), 0.0);
    for (const int n : mesh->node_sets.at("x1")) EXPECT_EQ(mesh->nodes(n, 0), 2.0);
    for (const int n : mesh->node_sets.at("y0")) EXPECT_EQ(mesh->nodes(n, 1), 0.0);
    for (const int n : mesh->node_sets.at("y1")) EXPECT_EQ(mesh->nodes(n, 1), 1.0);
    EXPECT_EQ(mesh->node_sets.at("x0").size(), 4u);
    EXPECT_EQ(mesh->node_sets.at("y1").size(), 5u);
    double area = 0.0;
    for (Eigen::Index t = 0; t < mesh->triangles.rows(); ++t) {
      const Eigen::Vector3d normal = triangle_normal(*mesh, t);
      EXPECT_GT(normal.z(), 0.0);
      area += 0.5 * normal.norm();
    }
    EXPECT_NEAR(area, 2.0, 1e-14);
    EXPECT_TRUE(validate_shell_mesh(*mesh));
  }
  // Node 0's diagonal depends on the pattern: "right" joins (0,0)–(1,1), "left" does not.
  auto right = make_rectangle_plate(1.0, 1.0, 1, 1, TrianglePattern::right);
  auto left = make_rectangle_plate(1.0, 1.0, 1, 1, TrianglePattern::left);
  ASSERT_TRUE(right && left);
  auto uses_edge = [](const ShellMesh& mesh, int p, int q) {
    for (Eigen::Index t = 0; t < mesh.triangles.rows(); ++t) {
      for (int a = 0; a < 3; ++a) {
        const int u = mesh.triangles(t, a), v = mesh.triangles(t, (a + 1) % 3);
        if ((u == p && v == q) || (u == q && v == p)) return true;
      }
    }
    return false;
  };
  EXPECT_TRUE(uses_edge(*right, 0, 3));
  EXPECT_FALSE(uses_edge(*left, 0, 3));
  EXPECT_TRUE(uses_edge(*left, 1, 2));
  EXPECT_FALSE(make_rectangle_plate(1.0, 1.0, 0, 1, TrianglePattern::right));
}

TEST(MakeCylindricalPanel, ArcSetsAndOutwardNormals) {
  const double radius = 25.0, angle = 40.0 * std::numbers::pi / 180.0;
  auto mesh = make_cylindrical_panel(radius, 25.0, 0.0, angle, 6, 4, TrianglePattern::alternating);
  ASSERT_TRUE(mesh) << mesh.error().message;
  for (const int n : mesh->node_sets.at("arc0")) {
    EXPECT_NEAR(mesh->nodes(n, 1), 0.0, 1e-12);
    EXPECT_NEAR(mesh->nodes(n, 2), radius, 1e-12);
  }
  for (const int n : mesh->node_sets.at("arc1")) {
    EXPECT_NEAR(mesh->nodes(n, 1), radius * std::sin(angle), 1e-12);
  }
  for (const int n : mesh->node_sets.at("x1")) EXPECT_NEAR(mesh->nodes(n, 0), 25.0, 1e-12);
  for (Eigen::Index t = 0; t < mesh->triangles.rows(); ++t) {
    const Eigen::Vector3d c = triangle_centroid(*mesh, t);
    EXPECT_GT(triangle_normal(*mesh, t).dot(Eigen::Vector3d(0.0, c.y(), c.z())), 0.0);
  }
  EXPECT_FALSE(make_cylindrical_panel(1.0, 1.0, 0.5, 0.5, 2, 2, TrianglePattern::right));
}

// A valid 2 × 1 strip of 4 triangles to break one way at a time.
ShellMesh strip() {
  auto mesh = make_rectangle_plate(2.0, 1.0, 2, 1, TrianglePattern::right);
  return *mesh;
}

void expect_invalid(const ShellMesh& mesh, const std::string& expected) {
  auto result = validate_shell_mesh(mesh);
  ASSERT_FALSE(result) << "expected: " << expected;
  EXPECT_NE(result.error().message.find(expected), std::string::npos) << result.error().message;
}

TEST(MeshValidation, EachProblemIsNamed) {
  ASSERT_TRUE(validate_shell_mesh(strip()));
  {
    ShellMesh mesh = strip();
    mesh.triangles(2, 1) = 17;
    expect_invalid(mesh, "triangle 2: node index 17 out of range 0..5");
  }
  {
    ShellMesh mesh = strip();
    mesh.triangles(1, 2) = mesh.triangles(1, 0);
    expect_invalid(mesh, "triangle 1: repeats a node");
  }
  {
    ShellMesh mesh = strip();
    mesh.triangles.row(3) << mesh.triangles(0, 2), mesh.triangles(0, 0), mesh.triangles(0, 1);
    // Triangle 3 now duplicates triangle 0 (nodes rotated), and node 5 is left unused.
    expect_invalid(mesh, "triangle 3: duplicate of triangle 0 (same nodes)");
  }
  {
    ShellMesh mesh = strip();
    mesh.nodes.row(4) = mesh.nodes.row(3);  // node 4 collapses onto node 3
    expect_invalid(mesh, "node 4: duplicate of node 3");
  }
  {
    ShellMesh mesh = strip();
    // Triangle 2 is (1, 2, 5): put node 5 on the midpoint of side 1–2.
    ASSERT_EQ(mesh.triangles.row(2), Eigen::RowVector3i(1, 2, 5));
    mesh.nodes.row(5) = 0.5 * (mesh.nodes.row(1) + mesh.nodes.row(2));
    expect_invalid(mesh, "triangle 2 (nodes 1, 2, 5): degenerate");
  }
  {
    ShellMesh mesh = strip();
    mesh.nodes.conservativeResize(7, 3);
    mesh.nodes.row(6) << 9.0, 9.0, 9.0;
    expect_invalid(mesh, "node 6: used by no triangle");
  }
  {
    ShellMesh mesh = strip();
    mesh.node_sets["x0"].push_back(40);
    expect_invalid(mesh, "node set 'x0' lists node 40, outside 0..5");
  }
  {
    ShellMesh mesh = strip();
    mesh.triangle_sets["plate"].push_back(-1);
    expect_invalid(mesh, "triangle set 'plate' lists triangle -1");
  }
  {
    ShellMesh mesh = strip();
    mesh.node_sets["empty"] = {};
    expect_invalid(mesh, "node set 'empty' is empty");
  }
  {
    ShellMesh mesh = strip();
    mesh.nodes(2, 1) = std::nan("");
    expect_invalid(mesh, "node 2: non-finite coordinates");
  }
  expect_invalid(ShellMesh{}, "0 nodes and 0 triangles");
}

// One row of quads of height h and width 1: every triangle's smallest angle is atan(h).
ShellMesh thin_strip(double smallest_angle_deg) {
  const double height = std::tan(smallest_angle_deg * std::numbers::pi / 180.0);
  return *make_rectangle_plate(2.0, height, 2, 1, TrianglePattern::right);
}

TEST(MeshValidation, SliversAreRefusedWithTheirAngleAndNode) {
  EXPECT_TRUE(validate_shell_mesh(thin_strip(1.01 * kMinTriangleAngleDeg)));
  const ShellMesh needle = thin_strip(0.99 * kMinTriangleAngleDeg);
  // Triangle 0 of the right split is (0, 1, 4) = (0, 0), (1, 0), (1, h): its smallest angle,
  // atan(h), is at node 0.
  ASSERT_EQ(needle.triangles.row(0), Eigen::RowVector3i(0, 1, 4));
  expect_invalid(needle, "triangle 0 (nodes 0, 1, 4): sliver, smallest angle 0.99 deg at node 0");
  expect_invalid(needle, "expected >= 1 deg (remesh)");
  // A cap: node 1, the middle of the bottom edge, pushed up almost onto the diagonal 0–4 of
  // the unit square leaves triangle (0, 1, 4) with an angle near 180 deg at node 1 and two tiny
  // ones.
  ShellMesh cap = strip();
  cap.nodes.row(1) << 0.5005, 0.4995, 0.0;
  auto result = validate_shell_mesh(cap);
  ASSERT_FALSE(result);
  EXPECT_NE(result.error().message.find("triangle 0 (nodes 0, 1, 4): sliver, smallest angle "),
            std::string::npos)
      << result.error().message;
  // A zero-area triangle is reported as degenerate, not as a sliver.
  ShellMesh flat = strip();
  flat.nodes.row(1) << 0.5, 0.5, 0.0;  // exactly on the diagonal 0–4
  result = validate_shell_mesh(flat);
  ASSERT_FALSE(result);
  EXPECT_NE(result.error().message.find("triangle 0 (nodes 0, 1, 4): degenerate"),
            std::string::npos)
      << result.error().message;
  EXPECT_EQ(result.error().message.find("sliver"), std::string::npos) << result.error().message;
}

// What the 1 deg threshold guards (docs/stability.md): a 1 m DKT plate of 4 × 4 quads,
// clamped at x = 0, end loads at x = 1 m, with row 2 of nodes moved down to y = 0.25 + h so
// the row of quads between y = 0.25 and 0.25 + h thins to slivers of smallest angle
// atan(h / 0.25 m). The deflections converge as the row thins (the geometry is the same
// plate), but the smallest LDLᵀ pivot of K falls ~1000× per decade of angle; below the
// threshold the mesh is refused. (Before the check, 0.23 deg still assembled with a pivot
// ratio of 6e-8, 0.023 deg with 6e-11, and 0.0023 deg failed assembly as a "mechanism".)
TEST(MeshValidation, SliverThresholdRationaleOnAPlate) {
  double previous_pivot = 0.0;
  double previous_tip = 0.0;
  for (const double angle_deg : {45.0, 21.8, 2.3, 1.01, 0.99}) {
    SCOPED_TRACE(angle_deg);
    ShellMesh mesh = *make_rectangle_plate(1.0, 1.0, 4, 4, TrianglePattern::alternating);
    const double h = 0.25 * std::tan(angle_deg * std::numbers::pi / 180.0);
    for (int i = 0; i <= 4; ++i) mesh.nodes(2 * 5 + i, 1) = 0.25 + h;
    auto shell = assemble_shell(mesh, ShellMaterial{2e11, 0.3, 0.01, 7800.0}, BendingElement::dkt,
                                {{"x0", {kUx, kUy, kUz, kRx, kRy, kRz}}});
    if (angle_deg < kMinTriangleAngleDeg) {
      ASSERT_FALSE(shell);
      EXPECT_NE(shell.error().message.find("sliver, smallest angle 0.99"), std::string::npos)
          << shell.error().message;
      continue;
    }
    ASSERT_TRUE(shell) << shell.error().message;
    auto solver = ShellStaticSolver::create(*shell);
    ASSERT_TRUE(solver) << solver.error().message;
    Eigen::VectorXd loads = make_zero_loads(mesh);
    ASSERT_TRUE(add_node_set_force(mesh, "x1", {0.0, 0.0, -100.0}, loads));
    const double tip = solver->solve(loads)->node_displacements.col(kUz).cwiseAbs().maxCoeff();
    std::printf("smallest angle %5.2f deg: pivot ratio %.2e, bending tip %.6e m\n", angle_deg,
                solver->smallest_pivot_ratio(), tip);
    if (angle_deg == 2.3) {
      EXPECT_LT(solver->smallest_pivot_ratio(), 1e-2 * previous_pivot);  // 21.8 → 2.3 deg
    }
    if (angle_deg == 1.01) {
      EXPECT_NEAR(tip, previous_tip, 5e-3 * previous_tip);  // converged against 2.3 deg
    }
    previous_pivot = solver->smallest_pivot_ratio();
    previous_tip = tip;
  }
}

TEST(MeshValidation, InconsistentOrientationNamesBothTriangles) {
  ShellMesh mesh = strip();
  ASSERT_EQ(mesh.triangles.row(0), Eigen::RowVector3i(0, 1, 4));
  ASSERT_EQ(mesh.triangles.row(1), Eigen::RowVector3i(0, 4, 3));
  mesh.triangles.row(1) << 0, 3, 4;  // reversed: its normal now points to −z
  expect_invalid(mesh, "triangles 0 and 1: inconsistent orientation, both run along their shared "
                       "edge 4->0");
  // A consistently reversed mesh (every normal flipped) is valid.
  ShellMesh reversed = strip();
  for (Eigen::Index t = 0; t < reversed.triangles.rows(); ++t) {
    std::swap(reversed.triangles(t, 1), reversed.triangles(t, 2));
  }
  EXPECT_TRUE(validate_shell_mesh(reversed));
}

TEST(MeshValidation, AssemblyRefusesAnInvalidMesh) {
  ShellMesh mesh = strip();
  mesh.nodes.row(4) = mesh.nodes.row(3);
  auto shell = assemble_shell(mesh, ShellMaterial{1e6, 0.3, 1e-3, 1000.0}, BendingElement::dkt,
                              {{"x0", {kUx, kUy, kUz, kRx, kRy, kRz}}});
  ASSERT_FALSE(shell);
  EXPECT_NE(shell.error().message.find("invalid shell mesh"), std::string::npos);
}

TEST(MeshValidation, CoincidenceIsRelativeToTheMeshSize) {
  // No absolute tolerance: a 1 µm plate is valid, but nodes 1e-20 m apart are duplicates.
  auto mesh = make_rectangle_plate(1e-6, 1e-6, 2, 2, TrianglePattern::alternating);
  ASSERT_TRUE(mesh);
  EXPECT_TRUE(validate_shell_mesh(*mesh));
  ShellMesh close = *mesh;
  close.nodes.row(4) = close.nodes.row(3) + Eigen::RowVector3d(1e-20, 0.0, 0.0);
  expect_invalid(close, "node 4: duplicate of node 3");
}

}  // namespace
}  // namespace trainer::model::offline
