// The offline shell FEM's shared types: a triangulated surface with named node and element
// sets, the material, the bending element choice, boundary conditions per node set and dof,
// and the assembled free-dof system that modal analysis, static solves and the full-system
// reference (DNIOS) all start from. Double precision, SI units. METHODS.md §1.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace trainer::model::offline {

// Node dof order: ux, uy, uz, rx, ry, rz (translations m, rotations rad).
constexpr int kShellDofsPerNode = 6;
enum ShellDof : int { kUx = 0, kUy = 1, kUz = 2, kRx = 3, kRy = 4, kRz = 5 };

struct ShellMesh {
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> nodes;       // m
  Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor> triangles;      // node indices
  std::map<std::string, std::vector<int>> node_sets;      // physical groups → node indices
  std::map<std::string, std::vector<int>> triangle_sets;  // physical groups of 2-D elements
  std::uint64_t source_hash = 0;                          // XXH64 of the source (file or generator parameters)
};

struct ShellMaterial {
  double young_modulus_pa = 0.0;
  double poisson_ratio = 0.0;
  double thickness_m = 0.0;
  double density_kg_per_m3 = 0.0;
};

enum class BendingElement : std::uint8_t {
  rao,  // the paper's 9-term cubic (Rao), non-conforming
  dkt,  // discrete Kirchhoff triangle (Batoz, Bathe & Ho 1980), the default
};

// Fix the listed dofs (kUx..kRz) of every node in a node set.
struct DofFix {
  std::string node_set;
  std::vector<int> dofs;
};

// Maps the 6n node dofs to the free (unconstrained) dofs that remain after elimination.
struct DofMap {
  int node_count = 0;
  std::vector<int> free_index;  // size 6n: free dof index, or -1 when fixed
  std::vector<int> free_to_node_dof;  // size free_count: node*6 + dof
  int free_count() const { return static_cast<int>(free_to_node_dof.size()); }
};

struct AssembledShell {
  Eigen::SparseMatrix<double> stiffness;  // free × free, symmetric (full storage), N/m, N/rad…
  Eigen::VectorXd lumped_mass;            // free, diagonal mass: kg on translations, 0 on rotations
  DofMap dofs;
};

}  // namespace trainer::model::offline
