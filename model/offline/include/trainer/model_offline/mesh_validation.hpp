// Checks a shell mesh before assembly, so a bad mesh is refused with the element or node at
// fault instead of producing a singular or silently wrong stiffness matrix.
#pragma once

#include "trainer/core/expected.hpp"
#include "trainer/model_offline/shell_model.hpp"

namespace trainer::model::offline {

// Relative tolerances of the checks (dimensionless).
inline constexpr double kDegenerateAreaRatio = 1e-12;  // of the mean triangle area
inline constexpr double kCoincidentNodeRatio = 1e-12;  // of the bounding-box diagonal

// Refuses, naming the offending index and the problem (up to the first 8 problems, one per
// line after the first):
//   * an empty mesh, non-finite node coordinates;
//   * triangles with node indices out of range or repeated within the triangle;
//   * degenerate triangles (area < kDegenerateAreaRatio × the mean area);
//   * duplicate triangles (the same three nodes in any order);
//   * duplicate nodes (closer than kCoincidentNodeRatio × the bounding-box diagonal);
//   * nodes no triangle uses (they would have no stiffness);
//   * node or triangle sets with out-of-range indices, and empty sets.
core::Expected<void> validate_shell_mesh(const ShellMesh& mesh);

}  // namespace trainer::model::offline
