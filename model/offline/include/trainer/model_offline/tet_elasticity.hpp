// Linear tetrahedral elasticity for the precomputed-elasticity model (METHODS.md §3): the
// 4-node constant-strain tetrahedron, assembly of the free-dof stiffness K_ff with nodes fixed
// per axis, a sparse Cholesky solver reused for many right-hand sides, and a tet mesh check.
// Double precision, SI units (m, Pa, N, kg); 3 dofs per node (ux, uy, uz), global frame.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "trainer/core/expected.hpp"
#include "trainer/model_offline/gmsh_reader.hpp"

namespace trainer::model::offline {

inline constexpr int kTetDofsPerNode = 3;

// A tetrahedron is degenerate when |6V| ≤ kDegenerateTetRatio × (longest edge)³ (a regular
// tetrahedron has 6V ≈ 0.707 a³, so this only refuses flat or collapsed elements).
inline constexpr double kDegenerateTetRatio = 1e-12;
// validate_tet_mesh refuses a tetrahedron with a dihedral angle or a face angle below this
// (degrees): a sliver (four nearly coplanar corners, dihedral angles near 0 and 180 deg), a
// needle or a flat cap. The same threshold as the shell's kMinTriangleAngleDeg. Measured on a
// 3 x 3 x 3 box with a squeezed layer (docs/stability.md): CHOLMOD's condition estimate falls
// in proportion to the mean-ratio quality and the static solution stays accurate far below
// the threshold; what it refuses is a meshing defect, named with its angle. The generated
// meshes keep every angle above 30 deg.
inline constexpr double kMinTetAngleDeg = 1.0;
// Nodes closer than this fraction of the bounding-box diagonal are duplicates (as the shell's
// kCoincidentNodeRatio): two coincident nodes split the mesh along a crack.
inline constexpr double kCoincidentTetNodeRatio = 1e-12;
// TetStaticSolver refuses a factor whose reciprocal condition estimate (CHOLMOD's
// (min L_ii / max L_ii)², a cheap lower-quality estimate) is below this: K_ff is then singular
// to rounding, i.e. a rigid-body motion was left free. A well-posed mesh of 10⁵ nodes stays
// many orders of magnitude above it.
inline constexpr double kSingularReciprocalCondition = 1e-13;

struct TetMaterial {
  double young_modulus_pa = 0.0;
  double poisson_ratio = 0.0;
  double density_kg_per_m3 = 1000.0;  // enters only the lumped mass
};

// Fix the listed axes (x, y, z) of every node in `nodes`.
struct TetNodeFix {
  std::vector<int> nodes;
  std::array<bool, 3> axes{};
};

// Node dof d = 3·node + axis, mapped to the free dofs that remain after elimination.
struct TetDofMap {
  std::vector<int> free_index;  // size 3n: index among free dofs, −1 when fixed
  int free_count = 0;
  int node_count = 0;
  std::vector<int> free_to_node_dof;  // size free_count: the node dof of each free dof
};

struct AssembledTet {
  TetDofMap dofs;
  Eigen::SparseMatrix<double> stiffness_free;  // K_ff (free × free), full symmetric storage, N/m
  Eigen::VectorXd lumped_mass_kg;              // per node (n), ρ V / 4 per element corner
  double volume_m3 = 0.0;
  int element_count = 0;
};

// Signed volume (m³) of the tetrahedron: (x1−x0)·((x2−x0)×(x3−x0)) / 6, positive for the
// corner order every function here expects.
double tet_signed_volume(const Eigen::Matrix<double, 4, 3>& corners_m);

// Mean-ratio shape quality in [0, 1]: 12 (3V)^(2/3) / Σ edge², 1 for the regular tetrahedron,
// → 0 as it flattens; negative for an inverted one.
double tet_quality(const Eigen::Matrix<double, 4, 3>& corners_m);

// 12×12 element stiffness V Bᵀ D B (N/m), dof order (node0 x,y,z, node1 x,y,z, ...). Refuses
// (error naming the problem) a non-positive or degenerate volume, non-finite coordinates,
// E ≤ 0 or non-finite, ν outside (−1, 0.5).
core::Expected<Eigen::Matrix<double, 12, 12>> tet4_stiffness(
    const Eigen::Matrix<double, 4, 3>& corners_m, double young_modulus_pa, double poisson_ratio);

// Assembles the whole mesh, applies the fixes, returns K_ff. Errors name the tetrahedron index
// and its node indices for a bad element, a node index out of range in a fix, a mesh where some
// free dof has no stiffness (a node no tetrahedron uses) and a fix set that leaves nothing free.
core::Expected<AssembledTet> assemble_tet(const TetMesh& mesh, const TetMaterial& material,
                                          const std::vector<TetNodeFix>& fixes);

// Factorises K_ff once (CHOLMOD supernodal LLᵀ, fill-reducing ordering) and solves many
// right-hand sides in one back-substitution. The solves share CHOLMOD's workspace: one solver
// must not be used by two threads at once (create one per thread).
class TetStaticSolver {
 public:
  // Fails when K_ff is not positive definite — naming the node and axis where the
  // factorisation broke down — or is singular to rounding (reciprocal condition estimate below
  // kSingularReciprocalCondition): both mean too few fixes, a rigid-body motion left free.
  static core::Expected<TetStaticSolver> create(const AssembledTet& assembled);

  // free_rhs: free_count × m (any m ≥ 1), forces on the free dofs (N); returns the free
  // displacements (m), free_count × m.
  core::Expected<Eigen::MatrixXd> solve_free(
      const Eigen::Ref<const Eigen::MatrixXd>& free_rhs) const;

  // nodal_loads_n: n × 3 (rows = nodes, N); loads on fixed dofs are carried by the supports and
  // ignored. Returns n × 3 displacements (m) with the fixed dofs 0.
  core::Expected<Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>> solve_nodal(
      const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>&
          nodal_loads_n) const;

  const TetDofMap& dofs() const { return dofs_; }
  double factorization_time_s() const { return factorization_time_s_; }
  // CHOLMOD's reciprocal condition estimate of K_ff (see kSingularReciprocalCondition).
  double reciprocal_condition_estimate() const { return reciprocal_condition_; }

  TetStaticSolver(TetStaticSolver&&) noexcept;
  TetStaticSolver& operator=(TetStaticSolver&&) noexcept;
  ~TetStaticSolver();

 private:
  struct Factorization;
  TetStaticSolver();
  std::unique_ptr<Factorization> factorization_;
  TetDofMap dofs_;
  double factorization_time_s_ = 0.0;
  double reciprocal_condition_ = 0.0;
};

// Nodal loads on a tet mesh: n × 3 (rows = nodes, N, global frame), as solve_nodal() takes.
using TetNodalLoads = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

enum class TetLoadDistribution : std::uint8_t {
  area_weighted,   // over the triangle set of that name: the consistent load of a uniform traction
  equal_per_node,  // over the node set of that name (no triangle set of that name exists)
};

// Adds a total force (N) on group `group`. When a triangle set `group` exists the force is spread
// as a uniform traction F / A_total over its triangles (each corner gets F·A_t / (3 A_total)), the
// consistent load, which reproduces a uniform stress exactly; otherwise it is split equally over
// node set `group`. Returns which was used. Fails on an unknown group, an empty or zero-area set,
// out-of-range indices, a non-finite force or a load matrix of the wrong size.
core::Expected<TetLoadDistribution> add_tet_group_force(const TetMesh& mesh,
                                                        const std::string& group,
                                                        const Eigen::Vector3d& total_force_n,
                                                        TetNodalLoads& nodal_loads_n);

// Adds a constant traction (Pa, global frame) over triangle set `triangle_set` as consistent
// nodal loads: traction·A/3 on each corner of each triangle.
core::Expected<void> add_tet_surface_traction(const TetMesh& mesh, const std::string& triangle_set,
                                              const Eigen::Vector3d& traction_pa,
                                              TetNodalLoads& nodal_loads_n);

// Checks a tet mesh before use, naming the offending index (up to the first 8 problems, one per
// line after the first): an empty mesh, non-finite coordinates, node indices out of range or
// repeated within a tetrahedron, inverted (negative volume) or degenerate tetrahedra, slivers
// (a dihedral or face angle below kMinTetAngleDeg, the angle and where it is named), duplicate
// tetrahedra (same four nodes in any order), duplicate nodes (coincident within
// kCoincidentTetNodeRatio of the bounding-box diagonal), nodes no tetrahedron uses, and
// node/triangle/tetrahedron sets with out-of-range indices.
core::Expected<void> validate_tet_mesh(const TetMesh& mesh);

}  // namespace trainer::model::offline
