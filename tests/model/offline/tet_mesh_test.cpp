// Tet mesh generators (box, cylinder), boundary-face extraction and tet mesh validation:
// positive volumes, exact volumes, shape quality, closed and outward boundaries, named sets,
// and one refusal per validation problem naming the element or node at fault.
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <string>
#include <utility>

#include "trainer/model_offline/tet_elasticity.hpp"
#include "trainer/model_offline/tet_mesh_generators.hpp"

namespace trainer::model::offline {
namespace {

Eigen::Matrix<double, 4, 3> tet_corners(const TetMesh& mesh, Eigen::Index e) {
  Eigen::Matrix<double, 4, 3> corners;
  for (int c = 0; c < 4; ++c) corners.row(c) = mesh.nodes.row(mesh.tetrahedra(e, c));
  return corners;
}

Eigen::Vector3d face_normal(const TetMesh& mesh, Eigen::Index f) {  // |n| = 2 × area
  const Eigen::Vector3d p0 = mesh.nodes.row(mesh.triangles(f, 0)).transpose();
  const Eigen::Vector3d p1 = mesh.nodes.row(mesh.triangles(f, 1)).transpose();
  const Eigen::Vector3d p2 = mesh.nodes.row(mesh.triangles(f, 2)).transpose();
  return (p1 - p0).cross(p2 - p0);
}

Eigen::Vector3d face_centroid(const TetMesh& mesh, Eigen::Index f) {
  return (mesh.nodes.row(mesh.triangles(f, 0)) + mesh.nodes.row(mesh.triangles(f, 1)) +
          mesh.nodes.row(mesh.triangles(f, 2)))
             .transpose() /
         3.0;
}

struct VolumeStats {
  double total_m3 = 0.0;
  double smallest_m3 = 1e300;
  double worst_quality = 1.0;
};

VolumeStats volume_stats(const TetMesh& mesh) {
  VolumeStats stats;
  for (Eigen::Index e = 0; e < mesh.tetrahedra.rows(); ++e) {
    const double volume = tet_signed_volume(tet_corners(mesh, e));
    stats.total_m3 += volume;
    stats.smallest_m3 = std::min(stats.smallest_m3, volume);
    stats.worst_quality = std::min(stats.worst_quality, tet_quality(tet_corners(mesh, e)));
  }
  return stats;
}

// Closed: every boundary edge is shared by exactly two boundary faces, once in each direction
// (consistent orientation). Outward: Σ (centroid · n A) / 3 = +V (divergence theorem with
// div x = 3; inward faces would give −V).
void expect_closed_outward_boundary(const TetMesh& mesh, double volume_m3) {
  std::map<std::pair<int, int>, int> directed;
  for (Eigen::Index f = 0; f < mesh.triangles.rows(); ++f) {
    for (int c = 0; c < 3; ++c) ++directed[{mesh.triangles(f, c), mesh.triangles(f, (c + 1) % 3)}];
  }
  for (const auto& [edge, count] : directed) {
    EXPECT_EQ(count, 1) << edge.first << "-" << edge.second;
    const auto reverse = directed.find({edge.second, edge.first});
    EXPECT_TRUE(reverse != directed.end())
        << "edge " << edge.first << "-" << edge.second << " has one boundary face";
  }
  double flux = 0.0;
  for (Eigen::Index f = 0; f < mesh.triangles.rows(); ++f) {
    flux += face_centroid(mesh, f).dot(face_normal(mesh, f)) / 2.0 / 3.0;
  }
  EXPECT_NEAR(flux, volume_m3, 1e-10 * volume_m3);
}

TEST(MakeTetBox, CountsVolumesSetsAndBoundary) {
  const double lx = 0.03, ly = 0.02, lz = 0.01;
  const int nx = 3, ny = 4, nz = 2;
  auto mesh = make_tet_box(lx, ly, lz, nx, ny, nz);
  ASSERT_TRUE(mesh) << mesh.error().message;
  EXPECT_EQ(mesh->nodes.rows(), (nx + 1) * (ny + 1) * (nz + 1));
  EXPECT_EQ(mesh->tetrahedra.rows(), 6 * nx * ny * nz);
  // Node (i, j, k) at (k (ny+1) + j)(nx+1) + i.
  EXPECT_EQ(mesh->nodes.row((2 * (ny + 1) + 1) * (nx + 1) + 3), Eigen::RowVector3d(lx, 0.005, lz));
  const VolumeStats stats = volume_stats(*mesh);
  EXPECT_GT(stats.smallest_m3, 0.0);
  EXPECT_NEAR(stats.total_m3, lx * ly * lz, 1e-14 * lx * ly * lz);
  ASSERT_TRUE(validate_tet_mesh(*mesh)) << validate_tet_mesh(*mesh).error().message;
  // 2 triangles per boundary quad.
  EXPECT_EQ(mesh->triangles.rows(), 4 * (nx * ny + ny * nz + nx * nz));
  expect_closed_outward_boundary(*mesh, lx * ly * lz);
  const std::map<std::string, std::pair<Eigen::Vector3d, double>> faces{
      {"x0", {-Eigen::Vector3d::UnitX(), ly * lz}}, {"x1", {Eigen::Vector3d::UnitX(), ly * lz}},
      {"y0", {-Eigen::Vector3d::UnitY(), lx * lz}}, {"y1", {Eigen::Vector3d::UnitY(), lx * lz}},
      {"z0", {-Eigen::Vector3d::UnitZ(), lx * ly}}, {"z1", {Eigen::Vector3d::UnitZ(), lx * ly}}};
  std::size_t named_faces = 0;
  for (const auto& [name, expected] : faces) {
    double area = 0.0;
    for (const int f : mesh->triangle_sets.at(name)) {
      const Eigen::Vector3d normal = face_normal(*mesh, f);
      EXPECT_NEAR(normal.normalized().dot(expected.first), 1.0, 1e-12) << name;
      area += normal.norm() / 2.0;
    }
    named_faces += mesh->triangle_sets.at(name).size();
    EXPECT_NEAR(area, expected.second, 1e-12 * expected.second) << name;
  }
  EXPECT_EQ(named_faces, static_cast<std::size_t>(mesh->triangles.rows()));
  EXPECT_EQ(mesh->node_sets.at("x1").size(), static_cast<std::size_t>((ny + 1) * (nz + 1)));
  for (const int node : mesh->node_sets.at("x1")) EXPECT_EQ(mesh->nodes(node, 0), lx);
  EXPECT_EQ(mesh->node_sets.at("all").size(), static_cast<std::size_t>(mesh->nodes.rows()));
  // Every node of a 3 × 4 × 2 box is on the surface except the (nx−1)(ny−1)(nz−1) inside.
  EXPECT_EQ(mesh->node_sets.at("surface").size(),
            static_cast<std::size_t>(mesh->nodes.rows() - (nx - 1) * (ny - 1) * (nz - 1)));
  // Kuhn split: all 6 tets of a cell are quality ≥ 0.7 on a cubic cell (the split's own shape).
  auto cube = make_tet_box(1.0, 1.0, 1.0, 2, 2, 2);
  ASSERT_TRUE(cube);
  EXPECT_GT(volume_stats(*cube).worst_quality, 0.7);
}

TEST(MakeTetBox, HashAndRefusals) {
  auto a = make_tet_box(0.01, 0.01, 0.01, 2, 2, 2);
  auto b = make_tet_box(0.01, 0.01, 0.01, 2, 2, 3);
  auto c = make_tet_box(0.01, 0.01, 0.01, 2, 2, 2);
  ASSERT_TRUE(a && b && c);
  EXPECT_NE(a->source_hash, b->source_hash);
  EXPECT_EQ(a->source_hash, c->source_hash);
  auto negative = make_tet_box(-0.01, 0.01, 0.01, 2, 2, 2);
  ASSERT_FALSE(negative);
  EXPECT_NE(negative.error().message.find("expected finite values > 0"), std::string::npos);
  auto zero_cells = make_tet_box(0.01, 0.01, 0.01, 2, 0, 2);
  ASSERT_FALSE(zero_cells);
  EXPECT_NE(zero_cells.error().message.find("expected each >= 1"), std::string::npos);
  EXPECT_FALSE(make_tet_box(0.01, 0.01, 0.01, 10000, 10000, 10000));
}

// Cylinder: the cross-section is a regular polygon of 6·radial sides (ring nodes on the circle),
// so the mesh volume equals the prism volume (3 radial sin(π/(3 radial))·R²·h) to rounding and
// approaches πR²h as radial grows (discretisation error 1 − sin θ/θ, θ = π/(3 radial)).
TEST(MakeTetCylinder, VolumesQualitySetsAndBoundary) {
  const double radius = 0.01, height = 0.03;
  double previous_error = 1.0;
  for (const int radial : {2, 4, 8}) {
    const int axial = 3 * radial;  // layer height ≈ ring spacing: near-equilateral prisms
    auto mesh = make_tet_cylinder(radius, height, radial, axial);
    ASSERT_TRUE(mesh) << mesh.error().message;
    ASSERT_TRUE(validate_tet_mesh(*mesh)) << validate_tet_mesh(*mesh).error().message;
    const int section = 1 + 3 * radial * (radial + 1);
    EXPECT_EQ(mesh->nodes.rows(), section * (axial + 1));
    EXPECT_EQ(mesh->tetrahedra.rows(), 3 * 6 * radial * radial * axial);
    const VolumeStats stats = volume_stats(*mesh);
    EXPECT_GT(stats.smallest_m3, 0.0);
    const double angle = std::numbers::pi / (3.0 * radial);
    const double polygon = 3.0 * radial * std::sin(angle) * radius * radius * height;
    EXPECT_NEAR(stats.total_m3, polygon, 1e-12 * polygon);
    const double exact = std::numbers::pi * radius * radius * height;
    const double error = (exact - stats.total_m3) / exact;
    EXPECT_GT(error, 0.0);
    EXPECT_LT(error, previous_error);
    previous_error = error;
    // Shape: the worst tetrahedron keeps a mean-ratio quality above 0.3 at every resolution
    // (measured ≈ 0.4; 0.3 leaves margin while still catching slivers, which fall below 0.1).
    EXPECT_GT(stats.worst_quality, 0.3) << radial;
    expect_closed_outward_boundary(*mesh, stats.total_m3);

    for (const int f : mesh->triangle_sets.at("bottom")) {
      EXPECT_NEAR(face_normal(*mesh, f).normalized().z(), -1.0, 1e-12);
    }
    for (const int f : mesh->triangle_sets.at("top")) {
      EXPECT_NEAR(face_normal(*mesh, f).normalized().z(), 1.0, 1e-12);
    }
    for (const int f : mesh->triangle_sets.at("side")) {
      const Eigen::Vector3d radial_direction(face_centroid(*mesh, f).x(),
                                             face_centroid(*mesh, f).y(), 0.0);
      EXPECT_GT(face_normal(*mesh, f).normalized().dot(radial_direction.normalized()), 0.9);
    }
    EXPECT_EQ(mesh->triangle_sets.at("bottom").size() + mesh->triangle_sets.at("top").size() +
                  mesh->triangle_sets.at("side").size(),
              static_cast<std::size_t>(mesh->triangles.rows()));
    EXPECT_EQ(mesh->triangle_sets.at("side").size(),
              static_cast<std::size_t>(2 * 6 * radial * axial));
    for (const int node : mesh->node_sets.at("side")) {
      EXPECT_NEAR(mesh->nodes.row(node).head<2>().norm(), radius, 1e-15);
    }
    EXPECT_EQ(mesh->node_sets.at("top").size(), static_cast<std::size_t>(section));
    ASSERT_EQ(mesh->node_sets.at("top_center").size(), 1u);
    EXPECT_EQ(mesh->nodes.row(mesh->node_sets.at("top_center").front()),
              Eigen::RowVector3d(0.0, 0.0, height));
  }
  EXPECT_LT(previous_error, 0.01);
  EXPECT_FALSE(make_tet_cylinder(0.01, 0.0, 2, 2));
  EXPECT_FALSE(make_tet_cylinder(0.01, 0.01, 0, 2));
}

TEST(BoundaryTriangles, SingleTetrahedronHasFourOutwardFaces) {
  TetMesh mesh;
  mesh.nodes.resize(4, 3);
  mesh.nodes << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  mesh.tetrahedra.resize(1, 4);
  mesh.tetrahedra << 0, 1, 2, 3;
  mesh.triangles = boundary_triangles(mesh);
  ASSERT_EQ(mesh.triangles.rows(), 4);
  expect_closed_outward_boundary(mesh, 1.0 / 6.0);
  // An inverted tetrahedron gets the same outward faces.
  mesh.tetrahedra << 0, 1, 3, 2;
  mesh.triangles = boundary_triangles(mesh);
  expect_closed_outward_boundary(mesh, 1.0 / 6.0);
}

TEST(ValidateTetMesh, EachProblemNamesTheElementOrNode) {
  auto box = make_tet_box(0.01, 0.01, 0.01, 1, 1, 1);
  ASSERT_TRUE(box);
  const auto expect_refused = [](const TetMesh& mesh, const std::string& text) {
    auto result = validate_tet_mesh(mesh);
    ASSERT_FALSE(result) << text;
    EXPECT_NE(result.error().message.find(text), std::string::npos) << result.error().message;
  };
  TetMesh inverted = *box;
  std::swap(inverted.tetrahedra(2, 0), inverted.tetrahedra(2, 1));
  expect_refused(inverted, "tetrahedron 2 (nodes");
  expect_refused(inverted, "is inverted");

  TetMesh flat = *box;
  flat.nodes.row(flat.tetrahedra(3, 3)) = flat.nodes.row(flat.tetrahedra(3, 0));
  expect_refused(flat, "is degenerate");

  TetMesh duplicate = *box;
  duplicate.tetrahedra.conservativeResize(7, 4);
  duplicate.tetrahedra.row(6) = duplicate.tetrahedra.row(0).reverse();
  expect_refused(duplicate, "tetrahedron 6");
  expect_refused(duplicate, "duplicates an earlier tetrahedron");

  TetMesh repeated = *box;
  repeated.tetrahedra(1, 3) = repeated.tetrahedra(1, 0);
  expect_refused(repeated, "tetrahedron 1");

  TetMesh out_of_range = *box;
  out_of_range.tetrahedra(5, 2) = 42;
  expect_refused(out_of_range, "names node 42");

  TetMesh unused = *box;
  unused.nodes.conservativeResize(9, 3);
  unused.nodes.row(8) << 0.5, 0.5, 0.5;
  expect_refused(unused, "node 8 is used by no tetrahedron");

  TetMesh not_finite = *box;
  not_finite.nodes(3, 1) = std::nan("");
  expect_refused(not_finite, "node 3 has non-finite coordinates");

  TetMesh bad_set = *box;
  bad_set.node_sets["tip"] = {0, 17};
  expect_refused(bad_set, "node set 'tip' has index 17");

  expect_refused(TetMesh{}, "expected at least one of each");
}

// One tetrahedron from four corners (positive orientation expected by the caller).
TetMesh single_tet(const Eigen::Matrix<double, 4, 3>& corners_m) {
  TetMesh mesh;
  mesh.nodes = corners_m;
  mesh.tetrahedra.resize(1, 4);
  mesh.tetrahedra << 0, 1, 2, 3;
  return mesh;
}

std::string refusal(const TetMesh& mesh) {
  auto result = validate_tet_mesh(mesh);
  return result ? std::string() : result.error().message;
}

TEST(ValidateTetMesh, SliversAndNeedlesAreRefusedWithTheirAngle) {
  // Sliver: the corners of a unit square, one lifted by h: its smallest dihedral angle is
  // ≈ h rad (0.57 deg at h = 0.01, 2.9 deg at h = 0.05), the one opposite ≈ 180 deg.
  const auto sliver = [](double h) {
    Eigen::Matrix<double, 4, 3> corners;
    corners << 0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, h;
    return single_tet(corners);
  };
  const std::string thin = refusal(sliver(0.01));
  EXPECT_NE(thin.find("tetrahedron 0 (nodes 0, 1, 2, 3) is a sliver (smallest dihedral angle "),
            std::string::npos)
      << thin;
  EXPECT_NE(thin.find("expected every dihedral and face angle >= 1 deg: remesh"), std::string::npos)
      << thin;
  EXPECT_EQ(refusal(sliver(0.05)), "");
  // Needle: a small right triangle of legs d and a far apex: face angles atan(d/L) at the apex.
  const auto needle = [](double angle_deg) {
    const double d = std::tan(angle_deg * std::numbers::pi / 180.0);
    Eigen::Matrix<double, 4, 3> corners;
    corners << 0, 0, 0, d, 0, 0, 0, d, 0, 0, 0, 1;
    return single_tet(corners);
  };
  EXPECT_EQ(refusal(needle(1.01 * kMinTetAngleDeg)), "");
  const std::string sharp = refusal(needle(0.99 * kMinTetAngleDeg));
  EXPECT_NE(sharp.find("is a needle (smallest face angle 0.99 deg at node 3 between nodes"),
            std::string::npos)
      << sharp;
  // Every generated mesh passes with margin (its worst angle is tens of degrees).
  EXPECT_TRUE(validate_tet_mesh(*make_tet_box(0.15, 0.10, 0.07, 16, 12, 8)));
  EXPECT_TRUE(validate_tet_mesh(*make_tet_cylinder(0.02, 0.05, 4, 12)));
}

// What the 1 deg threshold does not guard (docs/stability.md): a 1 m tet4 box of 3 × 3 × 3
// cells clamped at its base, with the z = 2/3 plane of nodes moved down to 1/3 + h, so one
// layer of tetrahedra flattens (mean-ratio quality 0.76 → 5e-5). CHOLMOD's reciprocal
// condition estimate falls in proportion to h below 1 mm (3e-4, 3e-6, 3e-8 at h = 1e-3, 1e-5,
// 1e-7 m), yet the static deflections converge: the solve is sound in double far below
// anything validate_tet_mesh lets through, which refuses the layer from h = 1 mm (needles).
TEST(ValidateTetMesh, SliverThresholdRationaleOnABox) {
  double previous_shear = 0.0;
  double previous_rcond = 0.0;
  for (const double h : {1.0 / 3.0, 1e-2, 1e-3, 1e-5, 1e-7}) {
    SCOPED_TRACE(h);
    TetMesh mesh = *make_tet_box(1.0, 1.0, 1.0, 3, 3, 3);
    for (Eigen::Index n = 0; n < mesh.nodes.rows(); ++n) {
      if (std::abs(mesh.nodes(n, 2) - 2.0 / 3.0) < 1e-9) mesh.nodes(n, 2) = 1.0 / 3.0 + h;
    }
    double quality = 1.0;
    for (Eigen::Index e = 0; e < mesh.tetrahedra.rows(); ++e) {
      Eigen::Matrix<double, 4, 3> corners;
      for (int c = 0; c < 4; ++c) corners.row(c) = mesh.nodes.row(mesh.tetrahedra(e, c));
      quality = std::min(quality, tet_quality(corners));
    }
    auto assembled = assemble_tet(mesh, {1e6, 0.45, 1000.0},
                                  {{mesh.node_sets.at("z0"), {true, true, true}}});
    ASSERT_TRUE(assembled) << assembled.error().message;
    auto solver = TetStaticSolver::create(*assembled);
    ASSERT_TRUE(solver) << solver.error().message;
    TetNodalLoads loads = TetNodalLoads::Zero(mesh.nodes.rows(), 3);
    ASSERT_TRUE(add_tet_group_force(mesh, "z1", Eigen::Vector3d(10.0, 0.0, 0.0), loads));
    const double shear = solver->solve_nodal(loads)->col(0).cwiseAbs().maxCoeff();
    std::printf("layer %.0e m: worst quality %.2e, condition estimate %.2e, top shear %.7e m\n", h,
                quality, solver->reciprocal_condition_estimate(), shear);
    const double rcond = solver->reciprocal_condition_estimate();
    if (h < 1e-3) {
      // Two decades thinner: the estimate falls by about a hundred.
      EXPECT_LT(rcond, 2e-2 * previous_rcond);
      EXPECT_GT(rcond, 5e-3 * previous_rcond);
    }
    if (h == 1e-7) {
      EXPECT_NEAR(shear, previous_shear, 1e-4 * shear);  // converged
    }
    previous_shear = shear;
    previous_rcond = rcond;
    const auto validated = validate_tet_mesh(mesh);
    if (h <= 1e-3) {
      ASSERT_FALSE(validated);
      EXPECT_NE(validated.error().message.find("expected every dihedral and face angle >= 1 deg"),
                std::string::npos)
          << validated.error().message;
    } else if (h > 1e-2) {
      EXPECT_TRUE(validated) << validated.error().message;
    }
  }
}

TEST(ValidateTetMesh, CoincidentNodesAreRefused) {
  auto box = make_tet_box(0.01, 0.01, 0.01, 2, 1, 1);
  ASSERT_TRUE(box);
  ASSERT_TRUE(validate_tet_mesh(*box));
  // Give node 1 (the middle of the bottom front edge) a twin used by the second cell's
  // tetrahedra: a crack through the mesh, each tetrahedron still well shaped.
  TetMesh cracked = *box;
  const int twin = static_cast<int>(cracked.nodes.rows());
  cracked.nodes.conservativeResize(twin + 1, 3);
  cracked.nodes.row(twin) = cracked.nodes.row(1);
  for (Eigen::Index e = 6; e < cracked.tetrahedra.rows(); ++e) {
    for (int c = 0; c < 4; ++c) {
      if (cracked.tetrahedra(e, c) == 1) cracked.tetrahedra(e, c) = twin;
    }
  }
  const std::string message = refusal(cracked);
  EXPECT_NE(message.find("node " + std::to_string(twin) + " is a duplicate of node 1"),
            std::string::npos)
      << message;
}

}  // namespace
}  // namespace trainer::model::offline
