// Reader for Gmsh MSH 4.1 ASCII meshes: the shell model's triangles and the tetrahedral
// model's tetrahedra, with Gmsh physical groups turned into named node and element sets.
//
// What is read: $MeshFormat (must be 4.1, ASCII), $PhysicalNames, $Entities (which entity
// belongs to which physical groups), $Nodes, $Elements; other sections are skipped. Element
// types: 15 (point), 1 (2-node line), 2 (3-node triangle), 4 (4-node tetrahedron). Any other
// element type is refused when a physical group uses it or when it is a surface or volume
// element (it would silently leave a hole); other unknown lines/points are ignored.
//
// Physical groups become sets named by their $PhysicalNames name (or the group's number when
// unnamed; groups of different dimensions with the same name are merged):
//   * node set: every node of the group's elements, whatever their dimension;
//   * triangle set (2-D groups) / tetrahedron set (3-D groups): indices into the element list.
// Nodes no kept element uses are dropped and the rest renumbered 0..n−1 in file order; a
// group that names a dropped node is an error. Every error starts with "file:line: ".
// source_hash = XXH64 (seed 0) of the file's bytes.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "trainer/core/expected.hpp"
#include "trainer/model_offline/shell_model.hpp"

namespace trainer::model::offline {

// Linear tetrahedral mesh for the precomputed-elasticity model (METHODS.md §3).
struct TetMesh {
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> nodes;    // m
  Eigen::Matrix<int, Eigen::Dynamic, 4, Eigen::RowMajor> tetrahedra;  // node indices
  Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>
      triangles;  // surface triangles of 2-D groups
  std::map<std::string, std::vector<int>> node_sets;
  std::map<std::string, std::vector<int>> triangle_sets;     // indices into `triangles`
  std::map<std::string, std::vector<int>> tetrahedron_sets;  // indices into `tetrahedra`
  std::uint64_t source_hash = 0;
};

// Shell mesh: keeps every 3-node triangle (type 2) and the nodes they use; groups of
// dimension 0–2 give node sets, 2-D groups triangle sets, 3-D groups are ignored.
// Fails when the file has no triangles.
core::Expected<ShellMesh> read_gmsh_shell(const std::string& path);

// Tetrahedral mesh: keeps every 4-node tetrahedron (type 4) and the nodes they use; groups of
// every dimension give node sets, 2-D groups their triangles (which must lie on tetrahedron
// nodes) and triangle sets, 3-D groups tetrahedron sets. Fails when the file has no tetrahedra.
core::Expected<TetMesh> read_gmsh_tet(const std::string& path);

// The same from text already in memory; `source_name` prefixes the error messages.
core::Expected<ShellMesh> parse_gmsh_shell(std::string_view text, const std::string& source_name);
core::Expected<TetMesh> parse_gmsh_tet(std::string_view text, const std::string& source_name);

}  // namespace trainer::model::offline
