// Structured tetrahedral meshes made from a few parameters (a box and a solid cylinder) for the
// precomputed-elasticity model, its tests and `modelc static --element tet4`, plus the
// extraction of a tet mesh's outward boundary faces.
//
// Every generator returns positive-volume tetrahedra (corner order with
// (x1−x0)·((x2−x0)×(x3−x0)) > 0), its boundary triangles oriented outward in mesh.triangles,
// triangle set "surface" (every boundary face) and the named sets listed below, node sets
// "surface" (every boundary node) and "all", and source_hash = XXH64 of the parameters.
#pragma once

#include <Eigen/Core>

#include "trainer/core/expected.hpp"
#include "trainer/model_offline/gmsh_reader.hpp"

namespace trainer::model::offline {

// Box [0,lx]×[0,ly]×[0,lz] (m), nx×ny×nz hexahedra (each ≥ 1), each split into 6 tetrahedra
// around its (0,0,0)–(1,1,1) body diagonal (the Kuhn split, conforming between neighbours);
// node (i, j, k) at index (k·(ny+1) + j)·(nx+1) + i. Node sets and triangle sets "x0", "x1",
// "y0", "y1", "z0", "z1" (the six faces).
core::Expected<TetMesh> make_tet_box(double lx_m, double ly_m, double lz_m, int nx, int ny, int nz);

// Solid cylinder of radius R about the z axis, z from 0 to height (m). Cross-section: a centre
// node and `radial` (≥ 1) concentric rings, ring r holding 6r nodes at radius r·R/radial (so
// the triangles are near-equilateral everywhere); `axial` (≥ 1) layers along z; each triangular
// prism split into 3 tetrahedra by the lowest-global-index rule (conforming). Node sets and
// triangle sets "bottom" (z = 0), "top" (z = h), "side" (r = R); node set "top_center" = the
// single node at (0, 0, h).
core::Expected<TetMesh> make_tet_cylinder(double radius_m, double height_m, int radial, int axial);

// Outward boundary faces of any tet mesh: the faces used by exactly one tetrahedron, oriented so
// that (p1 − p0) × (p2 − p0) points out of that tetrahedron. Used by the generators and for Gmsh
// meshes whose surface was not tagged. Assumes valid node indices (see validate_tet_mesh).
Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor> boundary_triangles(const TetMesh& mesh);

}  // namespace trainer::model::offline
