// Checks a shell mesh before assembly, so a bad mesh is refused with the element or node at
// fault instead of producing a singular or silently wrong stiffness matrix.
#pragma once

#include <cstddef>
#include <utility>
#include <vector>

#include "trainer/core/expected.hpp"
#include "trainer/model_offline/shell_model.hpp"

namespace trainer::model::offline {

// Relative tolerances of the checks (dimensionless).
inline constexpr double kDegenerateAreaRatio = 1e-12;  // of the mean triangle area
inline constexpr double kCoincidentNodeRatio = 1e-12;  // of the bounding-box diagonal
// Smallest interior angle (degrees) a triangle may have. Below it the triangle is a sliver (a
// needle, or a cap with one angle near 180 deg): aspect ratio above ~57. Measured on a DKT plate
// (docs/stability.md): results stay accurate well below 1 deg, but the stiffness's smallest
// pivot falls ~1000x per decade of angle and at ~0.002 deg assembly calls the mesh a
// mechanism; the Rao element refuses ~0.2 deg. Every mesh the project generates or ships
// keeps above 11 deg, so 1 deg only refuses meshing defects, with a message naming them.
inline constexpr double kMinTriangleAngleDeg = 1.0;

// Refuses, naming the offending index and the problem (up to the first 8 problems, one per
// line after the first):
//   * an empty mesh, non-finite node coordinates;
//   * triangles with node indices out of range or repeated within the triangle;
//   * degenerate triangles (area < kDegenerateAreaRatio × the mean area);
//   * slivers: a smallest interior angle below kMinTriangleAngleDeg (the message gives the
//     angle and the node it is at);
//   * inconsistent orientation: two triangles sharing an edge (and only they) that run along
//     it in the same direction, so one's normal points to the other side of the surface (the
//     contact code's "outward" side would flip there); both triangles are named, since which
//     one is inverted is a matter of the majority;
//   * duplicate triangles (the same three nodes in any order);
//   * duplicate nodes (closer than kCoincidentNodeRatio × the bounding-box diagonal);
//   * nodes no triangle uses (they would have no stiffness);
//   * node or triangle sets with out-of-range indices, and empty sets.
core::Expected<void> validate_shell_mesh(const ShellMesh& mesh);

// Pairs of nodes (rows of `nodes`, all finite) closer than `ratio` × the bounding-box diagonal,
// found by a sweep along x that compares only nodes within the tolerance in x; each pair as
// (earlier, later) index, at most `max_pairs`. Used by the shell and the tet mesh checks.
struct CoincidentNodes {
  double tolerance_m = 0.0;
  std::vector<std::pair<int, int>> pairs;
};
CoincidentNodes find_coincident_nodes(
    const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>& nodes, double ratio,
    std::size_t max_pairs);

}  // namespace trainer::model::offline
