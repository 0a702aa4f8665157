// Linear tetrahedral elasticity: element, assembly, CHOLMOD solver, mesh check.
#include "trainer/model_offline/tet_elasticity.hpp"
#include "trainer/model_offline/mesh_validation.hpp"

#include <cholmod.h>

#include <Eigen/Dense>
#include <Eigen/SparseCore>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <numeric>
#include <set>
#include <sstream>
#include <string>
#include <utility>

namespace trainer::model::offline {
namespace {

using Clock = std::chrono::steady_clock;

constexpr int kMaxReportedProblems = 8;
const char* const kAxisNames[3] = {"x", "y", "z"};

std::string tet_description(int index, const Eigen::RowVector4i& corners) {
  std::ostringstream out;
  out << "tetrahedron " << index << " (nodes " << corners(0) << ", " << corners(1) << ", "
      << corners(2) << ", " << corners(3) << ")";
  return out.str();
}

std::string node_dof_name(int node_dof) {
  return "node " + std::to_string(node_dof / kTetDofsPerNode) + " axis " +
         kAxisNames[node_dof % kTetDofsPerNode];
}

double longest_edge(const Eigen::Matrix<double, 4, 3>& corners_m) {
  double longest = 0.0;
  for (int a = 0; a < 4; ++a) {
    for (int b = a + 1; b < 4; ++b) {
      longest = std::max(longest, (corners_m.row(a) - corners_m.row(b)).norm());
    }
  }
  return longest;
}

// Empty when the geometry is acceptable, else what is wrong with it.
std::string geometry_problem(const Eigen::Matrix<double, 4, 3>& corners_m) {
  if (!corners_m.allFinite()) return "has non-finite node coordinates";
  const double six_volume = 6.0 * tet_signed_volume(corners_m);
  const double edge = longest_edge(corners_m);
  if (std::abs(six_volume) <= kDegenerateTetRatio * edge * edge * edge) {
    std::ostringstream out;
    out << "is degenerate (volume " << six_volume / 6.0 << " m^3 with longest edge " << edge
        << " m; expected |6V| > " << kDegenerateTetRatio << " x edge^3)";
    return out.str();
  }
  if (six_volume < 0.0) {
    std::ostringstream out;
    out << "is inverted (volume " << six_volume / 6.0
        << " m^3; expected > 0 with (x1-x0).((x2-x0)x(x3-x0)) > 0)";
    return out.str();
  }
  return {};
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / std::numbers::pi;
}

// Empty when every dihedral and face angle of a valid (positive, non-degenerate) tetrahedron is
// at least kMinTetAngleDeg, else the smallest offender. `corners` gives node numbers for the
// message.
std::string shape_problem(const Eigen::Matrix<double, 4, 3>& corners_m,
                          const Eigen::RowVector4i& corners) {
  double smallest_dihedral = 180.0;
  double smallest_face = 180.0;
  std::string dihedral_where;
  std::string face_where;
  for (int a = 0; a < 4; ++a) {
    for (int b = a + 1; b < 4; ++b) {
      // The two other corners c, d: the faces (a, b, c) and (a, b, d) meet at edge a–b.
      int others[2];
      int count = 0;
      for (int k = 0; k < 4; ++k) {
        if (k != a && k != b) others[count++] = k;
      }
      const Eigen::Vector3d origin = corners_m.row(a).transpose();
      const Eigen::Vector3d edge = (corners_m.row(b).transpose() - origin).normalized();
      Eigen::Vector3d across[2];
      for (int i = 0; i < 2; ++i) {
        const Eigen::Vector3d to_other = corners_m.row(others[i]).transpose() - origin;
        across[i] = to_other - to_other.dot(edge) * edge;
      }
      const double dihedral = angle_deg(across[0], across[1]);
      if (dihedral < smallest_dihedral) {
        smallest_dihedral = dihedral;
        dihedral_where = "at edge " + std::to_string(corners(a)) + "-" + std::to_string(corners(b));
      }
    }
  }
  for (int at = 0; at < 4; ++at) {
    for (int b = 0; b < 4; ++b) {
      for (int c = b + 1; c < 4; ++c) {
        if (b == at || c == at) continue;
        const Eigen::Vector3d origin = corners_m.row(at).transpose();
        const double face = angle_deg(corners_m.row(b).transpose() - origin,
                                      corners_m.row(c).transpose() - origin);
        if (face < smallest_face) {
          smallest_face = face;
          face_where = "at node " + std::to_string(corners(at)) + " between nodes " +
                       std::to_string(corners(b)) + " and " + std::to_string(corners(c));
        }
      }
    }
  }
  std::ostringstream out;
  if (smallest_dihedral < kMinTetAngleDeg && smallest_dihedral <= smallest_face) {
    out << "is a sliver (smallest dihedral angle " << smallest_dihedral << " deg " << dihedral_where
        << "; expected every dihedral and face angle >= " << kMinTetAngleDeg << " deg: remesh)";
  } else if (smallest_face < kMinTetAngleDeg) {
    out << "is a needle (smallest face angle " << smallest_face << " deg " << face_where
        << "; expected every dihedral and face angle >= " << kMinTetAngleDeg << " deg: remesh)";
  }
  return out.str();
}

}  // namespace

double tet_signed_volume(const Eigen::Matrix<double, 4, 3>& corners_m) {
  const Eigen::Vector3d e1 = (corners_m.row(1) - corners_m.row(0)).transpose();
  const Eigen::Vector3d e2 = (corners_m.row(2) - corners_m.row(0)).transpose();
  const Eigen::Vector3d e3 = (corners_m.row(3) - corners_m.row(0)).transpose();
  return e1.dot(e2.cross(e3)) / 6.0;
}

double tet_quality(const Eigen::Matrix<double, 4, 3>& corners_m) {
  double edge_squares = 0.0;
  for (int a = 0; a < 4; ++a) {
    for (int b = a + 1; b < 4; ++b)
      edge_squares += (corners_m.row(a) - corners_m.row(b)).squaredNorm();
  }
  if (!(edge_squares > 0.0)) return 0.0;
  const double volume = tet_signed_volume(corners_m);
  const double magnitude = 12.0 * std::cbrt(9.0 * volume * volume) / edge_squares;
  return volume < 0.0 ? -magnitude : magnitude;
}

core::Expected<Eigen::Matrix<double, 12, 12>> tet4_stiffness(
    const Eigen::Matrix<double, 4, 3>& corners_m, double young_modulus_pa, double poisson_ratio) {
  if (!(young_modulus_pa > 0.0) || !std::isfinite(young_modulus_pa)) {
    return core::make_error("tet4 element: young_modulus_pa is " +
                            std::to_string(young_modulus_pa) + "; expected a finite value > 0");
  }
  if (!(poisson_ratio > -1.0 && poisson_ratio < 0.5)) {
    return core::make_error("tet4 element: poisson_ratio is " + std::to_string(poisson_ratio) +
                            "; expected -1 < nu < 0.5");
  }
  const std::string problem = geometry_problem(corners_m);
  if (!problem.empty()) return core::make_error("tet4 element: the tetrahedron " + problem);

  // Rows of `edges` are x_i − x_0; the barycentric gradients ∇λ_i (i = 1..3) are the columns of
  // edges⁻¹ and ∇λ_0 = −Σ ∇λ_i.
  Eigen::Matrix3d edges;
  for (int i = 0; i < 3; ++i) edges.row(i) = corners_m.row(i + 1) - corners_m.row(0);
  const Eigen::Matrix3d inverse = edges.inverse();
  Eigen::Matrix<double, 3, 4> gradients;
  gradients.rightCols<3>() = inverse;
  gradients.col(0) = -inverse.rowwise().sum();

  // Voigt order xx, yy, zz, yz, xz, xy with engineering shear strains.
  Eigen::Matrix<double, 6, 12> strain = Eigen::Matrix<double, 6, 12>::Zero();
  for (int node = 0; node < 4; ++node) {
    const double bx = gradients(0, node), by = gradients(1, node), bz = gradients(2, node);
    const int c = 3 * node;
    strain(0, c) = bx;
    strain(1, c + 1) = by;
    strain(2, c + 2) = bz;
    strain(3, c + 1) = bz;
    strain(3, c + 2) = by;
    strain(4, c) = bz;
    strain(4, c + 2) = bx;
    strain(5, c) = by;
    strain(5, c + 1) = bx;
  }
  const double lame_lambda =
      young_modulus_pa * poisson_ratio / ((1.0 + poisson_ratio) * (1.0 - 2.0 * poisson_ratio));
  const double shear_modulus = young_modulus_pa / (2.0 * (1.0 + poisson_ratio));
  Eigen::Matrix<double, 6, 6> elasticity = Eigen::Matrix<double, 6, 6>::Zero();
  elasticity.topLeftCorner<3, 3>().setConstant(lame_lambda);
  elasticity.topLeftCorner<3, 3>().diagonal().array() += 2.0 * shear_modulus;
  elasticity.bottomRightCorner<3, 3>().diagonal().setConstant(shear_modulus);

  const double volume = tet_signed_volume(corners_m);
  Eigen::Matrix<double, 12, 12> stiffness = volume * strain.transpose() * elasticity * strain;
  // Exact symmetry (the triple product rounds differently on the two triangles).
  stiffness = (0.5 * (stiffness + stiffness.transpose())).eval();
  return stiffness;
}

core::Expected<AssembledTet> assemble_tet(const TetMesh& mesh, const TetMaterial& material,
                                          const std::vector<TetNodeFix>& fixes) {
  const int node_count = static_cast<int>(mesh.nodes.rows());
  const int element_count = static_cast<int>(mesh.tetrahedra.rows());
  if (node_count == 0 || element_count == 0) {
    return core::make_error("tet assembly: the mesh has " + std::to_string(node_count) +
                            " nodes and " + std::to_string(element_count) +
                            " tetrahedra; expected at least one of each");
  }
  if (!(material.density_kg_per_m3 > 0.0) || !std::isfinite(material.density_kg_per_m3)) {
    return core::make_error("tet assembly: density_kg_per_m3 is " +
                            std::to_string(material.density_kg_per_m3) +
                            "; expected a finite value > 0");
  }

  AssembledTet result;
  TetDofMap& dofs = result.dofs;
  dofs.node_count = node_count;
  dofs.free_index.assign(static_cast<std::size_t>(kTetDofsPerNode * node_count), 0);
  for (std::size_t f = 0; f < fixes.size(); ++f) {
    for (const int node : fixes[f].nodes) {
      if (node < 0 || node >= node_count) {
        return core::make_error("tet assembly: fix " + std::to_string(f) + " names node " +
                                std::to_string(node) + "; expected 0.." +
                                std::to_string(node_count - 1));
      }
      for (int axis = 0; axis < kTetDofsPerNode; ++axis) {
        if (fixes[f].axes[static_cast<std::size_t>(axis)]) {
          dofs.free_index[static_cast<std::size_t>(kTetDofsPerNode * node + axis)] = -1;
        }
      }
    }
  }
  for (std::size_t d = 0; d < dofs.free_index.size(); ++d) {
    if (dofs.free_index[d] < 0) continue;
    dofs.free_index[d] = dofs.free_count++;
    dofs.free_to_node_dof.push_back(static_cast<int>(d));
  }
  if (dofs.free_count == 0) {
    return core::make_error("tet assembly: the fixes leave no free dof (all " +
                            std::to_string(kTetDofsPerNode * node_count) +
                            " dofs fixed); expected something to solve for");
  }

  result.lumped_mass_kg = Eigen::VectorXd::Zero(node_count);
  std::vector<bool> node_used(static_cast<std::size_t>(node_count), false);
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<std::size_t>(element_count) * 144);
  for (int e = 0; e < element_count; ++e) {
    const Eigen::RowVector4i corners = mesh.tetrahedra.row(e);
    Eigen::Matrix<double, 4, 3> corners_m;
    for (int c = 0; c < 4; ++c) {
      if (corners(c) < 0 || corners(c) >= node_count) {
        return core::make_error("tet assembly: " + tet_description(e, corners) + " names node " +
                                std::to_string(corners(c)) + "; expected 0.." +
                                std::to_string(node_count - 1));
      }
      corners_m.row(c) = mesh.nodes.row(corners(c));
    }
    auto element = tet4_stiffness(corners_m, material.young_modulus_pa, material.poisson_ratio);
    if (!element) {
      return core::make_error("tet assembly: " + tet_description(e, corners) + ": " +
                              element.error().message);
    }
    const double volume = tet_signed_volume(corners_m);
    result.volume_m3 += volume;
    for (int c = 0; c < 4; ++c) {
      result.lumped_mass_kg(corners(c)) += material.density_kg_per_m3 * volume / 4.0;
      node_used[static_cast<std::size_t>(corners(c))] = true;
    }
    for (int a = 0; a < 12; ++a) {
      const int row =
          dofs.free_index[static_cast<std::size_t>(kTetDofsPerNode * corners(a / 3) + a % 3)];
      if (row < 0) continue;
      for (int b = 0; b < 12; ++b) {
        const int col =
            dofs.free_index[static_cast<std::size_t>(kTetDofsPerNode * corners(b / 3) + b % 3)];
        if (col >= 0) triplets.emplace_back(row, col, (*element)(a, b));
      }
    }
  }
  for (int node = 0; node < node_count; ++node) {
    if (node_used[static_cast<std::size_t>(node)]) continue;
    for (int axis = 0; axis < kTetDofsPerNode; ++axis) {
      if (dofs.free_index[static_cast<std::size_t>(kTetDofsPerNode * node + axis)] >= 0) {
        return core::make_error("tet assembly: node " + std::to_string(node) +
                                " is used by no tetrahedron but its " + kAxisNames[axis] +
                                " dof is free, so it has no stiffness; expected every free node "
                                "to belong to a tetrahedron (or fix it)");
      }
    }
  }
  result.stiffness_free.resize(dofs.free_count, dofs.free_count);
  result.stiffness_free.setFromTriplets(triplets.begin(), triplets.end());
  result.stiffness_free.makeCompressed();
  result.element_count = element_count;
  return result;
}

// CHOLMOD through its C interface (Eigen's wrapper trips GCC 12's -Wnull-dereference and hides
// the factor's failing column). The common block holds CHOLMOD's workspace, so one solver must
// not be used by two threads at once.
struct TetStaticSolver::Factorization {
  cholmod_common common{};
  cholmod_factor* factor = nullptr;
  Factorization() {
    cholmod_start(&common);
    common.print = 0;  // errors are reported by us, with the node named
    common.supernodal = CHOLMOD_SUPERNODAL;
  }
  ~Factorization() {
    if (factor != nullptr) cholmod_free_factor(&factor, &common);
    cholmod_finish(&common);
  }
  Factorization(const Factorization&) = delete;
  Factorization& operator=(const Factorization&) = delete;
};

TetStaticSolver::TetStaticSolver() = default;
TetStaticSolver::TetStaticSolver(TetStaticSolver&&) noexcept = default;
TetStaticSolver& TetStaticSolver::operator=(TetStaticSolver&&) noexcept = default;
TetStaticSolver::~TetStaticSolver() = default;

core::Expected<TetStaticSolver> TetStaticSolver::create(const AssembledTet& assembled) {
  const Eigen::SparseMatrix<double>& stiffness = assembled.stiffness_free;
  const auto free_count = stiffness.rows();
  if (free_count == 0 || stiffness.cols() != free_count ||
      free_count != assembled.dofs.free_count ||
      assembled.dofs.free_to_node_dof.size() != static_cast<std::size_t>(free_count) ||
      !stiffness.isCompressed()) {
    return core::make_error("tet static solve: the stiffness is " +
                            std::to_string(stiffness.rows()) + " x " +
                            std::to_string(stiffness.cols()) + " but the dof map has " +
                            std::to_string(assembled.dofs.free_count) +
                            " free dofs; expected a non-empty compressed square system that "
                            "matches");
  }
  TetStaticSolver solver;
  solver.factorization_ = std::make_unique<Factorization>();
  solver.dofs_ = assembled.dofs;
  Factorization& cholesky = *solver.factorization_;

  // A view of K_ff (column-major CSC, int indices); stype −1: only the lower triangle is read.
  cholmod_sparse matrix{};
  matrix.nrow = static_cast<std::size_t>(free_count);
  matrix.ncol = static_cast<std::size_t>(free_count);
  matrix.nzmax = static_cast<std::size_t>(stiffness.nonZeros());
  matrix.p = const_cast<int*>(stiffness.outerIndexPtr());
  matrix.i = const_cast<int*>(stiffness.innerIndexPtr());
  matrix.x = const_cast<double*>(stiffness.valuePtr());
  matrix.stype = -1;
  matrix.itype = CHOLMOD_INT;
  matrix.xtype = CHOLMOD_REAL;
  matrix.dtype = CHOLMOD_DOUBLE;
  matrix.sorted = 1;
  matrix.packed = 1;

  const auto start = Clock::now();
  cholesky.factor = cholmod_analyze(&matrix, &cholesky.common);
  if (cholesky.factor == nullptr) {
    return core::make_error("tet static solve: CHOLMOD could not analyse K_ff (status " +
                            std::to_string(cholesky.common.status) + ")");
  }
  const int factorized = cholmod_factorize(&matrix, cholesky.factor, &cholesky.common);
  solver.factorization_time_s_ = std::chrono::duration<double>(Clock::now() - start).count();
  cholmod_factor* factor = cholesky.factor;
  if (cholesky.common.status == CHOLMOD_NOT_POSDEF || factor->minor < factor->n) {
    // `minor` is the column, in the fill-reducing order, where a pivot was not positive.
    std::string where = "an unknown dof";
    const auto minor = static_cast<Eigen::Index>(factor->minor);
    if (minor >= 0 && minor < free_count) {
      const int* permutation = static_cast<const int*>(factor->Perm);
      const int free_dof = permutation != nullptr ? permutation[minor] : static_cast<int>(minor);
      where = node_dof_name(solver.dofs_.free_to_node_dof[static_cast<std::size_t>(free_dof)]);
    }
    return core::make_error(
        "tet static solve: K_ff is not positive definite: the Cholesky factorisation broke down "
        "at " +
        where +
        " (a rigid-body motion is left free: fix enough axes to stop translation and rotation)");
  }
  if (factorized == 0 || cholesky.common.status < CHOLMOD_OK) {
    return core::make_error("tet static solve: CHOLMOD could not factorise K_ff (status " +
                            std::to_string(cholesky.common.status) + ")");
  }
  solver.reciprocal_condition_ = cholmod_rcond(factor, &cholesky.common);
  if (!(solver.reciprocal_condition_ > kSingularReciprocalCondition)) {
    std::ostringstream out;
    out << "tet static solve: K_ff is singular to rounding: reciprocal condition estimate "
        << solver.reciprocal_condition_ << " (expected > " << kSingularReciprocalCondition
        << "); a rigid-body motion is left free: fix enough axes to stop translation and "
           "rotation";
    return core::make_error(out.str());
  }
  return solver;
}

core::Expected<Eigen::MatrixXd> TetStaticSolver::solve_free(
    const Eigen::Ref<const Eigen::MatrixXd>& free_rhs) const {
  if (free_rhs.rows() != dofs_.free_count || free_rhs.cols() < 1) {
    return core::make_error("tet static solve: the right-hand side is " +
                            std::to_string(free_rhs.rows()) + " x " +
                            std::to_string(free_rhs.cols()) + "; expected " +
                            std::to_string(dofs_.free_count) + " (free dofs) x m, m >= 1");
  }
  if (!free_rhs.allFinite()) {
    return core::make_error("tet static solve: the right-hand side has non-finite entries");
  }
  // All columns in one call: CHOLMOD's supernodal solve is then BLAS-3.
  cholmod_dense rhs{};
  rhs.nrow = static_cast<std::size_t>(free_rhs.rows());
  rhs.ncol = static_cast<std::size_t>(free_rhs.cols());
  rhs.d = static_cast<std::size_t>(free_rhs.outerStride());
  rhs.nzmax = rhs.d * rhs.ncol;
  rhs.x = const_cast<double*>(free_rhs.data());
  rhs.xtype = CHOLMOD_REAL;
  rhs.dtype = CHOLMOD_DOUBLE;
  cholmod_common& common = factorization_->common;
  cholmod_dense* solution = cholmod_solve(CHOLMOD_A, factorization_->factor, &rhs, &common);
  if (solution == nullptr) {
    return core::make_error("tet static solve: CHOLMOD back-substitution failed (status " +
                            std::to_string(common.status) + ")");
  }
  Eigen::MatrixXd displacements = Eigen::Map<const Eigen::MatrixXd, 0, Eigen::OuterStride<>>(
      static_cast<const double*>(solution->x), free_rhs.rows(), free_rhs.cols(),
      Eigen::OuterStride<>(static_cast<Eigen::Index>(solution->d)));
  cholmod_free_dense(&solution, &common);
  if (!displacements.allFinite()) {
    return core::make_error("tet static solve: back-substitution gave non-finite values");
  }
  return displacements;
}

core::Expected<Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>
TetStaticSolver::solve_nodal(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>&
        nodal_loads_n) const {
  if (nodal_loads_n.rows() != dofs_.node_count) {
    return core::make_error("tet static solve: the nodal loads have " +
                            std::to_string(nodal_loads_n.rows()) + " rows; expected " +
                            std::to_string(dofs_.node_count) + " (one per node)");
  }
  Eigen::VectorXd free_loads(dofs_.free_count);
  for (int i = 0; i < dofs_.free_count; ++i) {
    const int node_dof = dofs_.free_to_node_dof[static_cast<std::size_t>(i)];
    free_loads(i) = nodal_loads_n(node_dof / kTetDofsPerNode, node_dof % kTetDofsPerNode);
  }
  auto free_displacements = solve_free(free_loads);
  if (!free_displacements) return free_displacements.error();
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> displacements =
      Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>::Zero(dofs_.node_count, 3);
  for (int i = 0; i < dofs_.free_count; ++i) {
    const int node_dof = dofs_.free_to_node_dof[static_cast<std::size_t>(i)];
    displacements(node_dof / kTetDofsPerNode, node_dof % kTetDofsPerNode) =
        (*free_displacements)(i, 0);
  }
  return displacements;
}

namespace {

core::Expected<void> check_loads_size(const TetMesh& mesh, const TetNodalLoads& nodal_loads_n) {
  if (nodal_loads_n.rows() != mesh.nodes.rows()) {
    return core::make_error("tet loads: the load matrix has " +
                            std::to_string(nodal_loads_n.rows()) + " rows; expected " +
                            std::to_string(mesh.nodes.rows()) + " (one per node)");
  }
  return {};
}

// Area (m²) of triangle `index` of mesh.triangles, or −1 when it names a missing node.
double triangle_area(const TetMesh& mesh, int index) {
  if (index < 0 || index >= mesh.triangles.rows()) return -1.0;
  Eigen::Matrix3d corners;
  for (int c = 0; c < 3; ++c) {
    const int node = mesh.triangles(index, c);
    if (node < 0 || node >= mesh.nodes.rows()) return -1.0;
    corners.row(c) = mesh.nodes.row(node);
  }
  const Eigen::Vector3d edge1 = (corners.row(1) - corners.row(0)).transpose();
  const Eigen::Vector3d edge2 = (corners.row(2) - corners.row(0)).transpose();
  return 0.5 * edge1.cross(edge2).norm();
}

// Adds traction·A/3 to each corner of every triangle of the set; returns the set's area.
core::Expected<double> spread_traction(const TetMesh& mesh, const std::string& triangle_set,
                                       const std::vector<int>& triangles,
                                       const Eigen::Vector3d& traction_pa,
                                       TetNodalLoads& nodal_loads_n) {
  double total_area = 0.0;
  for (const int triangle : triangles) {
    const double area = triangle_area(mesh, triangle);
    if (area < 0.0) {
      return core::make_error("tet loads: triangle set '" + triangle_set + "' names triangle " +
                              std::to_string(triangle) +
                              ", which is out of range or names a "
                              "missing node");
    }
    total_area += area;
    for (int c = 0; c < 3; ++c) {
      nodal_loads_n.row(mesh.triangles(triangle, c)) += (traction_pa * area / 3.0).transpose();
    }
  }
  return total_area;
}

}  // namespace

core::Expected<TetLoadDistribution> add_tet_group_force(const TetMesh& mesh,
                                                        const std::string& group,
                                                        const Eigen::Vector3d& total_force_n,
                                                        TetNodalLoads& nodal_loads_n) {
  if (auto size = check_loads_size(mesh, nodal_loads_n); !size) return size.error();
  if (!total_force_n.allFinite()) {
    return core::make_error("tet loads: the force on '" + group + "' is not finite");
  }
  if (const auto found = mesh.triangle_sets.find(group); found != mesh.triangle_sets.end()) {
    double total_area = 0.0;
    for (const int triangle : found->second) {
      const double area = triangle_area(mesh, triangle);
      if (area < 0.0) {
        return core::make_error("tet loads: triangle set '" + group + "' names triangle " +
                                std::to_string(triangle) +
                                ", which is out of range or names a "
                                "missing node");
      }
      total_area += area;
    }
    if (!(total_area > 0.0)) {
      return core::make_error("tet loads: triangle set '" + group +
                              "' has no area; expected a non-empty surface to spread the force on");
    }
    auto spread =
        spread_traction(mesh, group, found->second, total_force_n / total_area, nodal_loads_n);
    if (!spread) return spread.error();
    return TetLoadDistribution::area_weighted;
  }
  const auto found = mesh.node_sets.find(group);
  if (found == mesh.node_sets.end() || found->second.empty()) {
    std::string known;
    for (const auto& [name, members] : mesh.node_sets) known += (known.empty() ? "" : ", ") + name;
    return core::make_error("tet loads: unknown or empty node set '" + group +
                            "' (known: " + known + ")");
  }
  for (const int node : found->second) {
    if (node < 0 || node >= mesh.nodes.rows()) {
      return core::make_error("tet loads: node set '" + group + "' names node " +
                              std::to_string(node) + ", which is out of range");
    }
  }
  const double share = 1.0 / static_cast<double>(found->second.size());
  for (const int node : found->second) nodal_loads_n.row(node) += share * total_force_n.transpose();
  return TetLoadDistribution::equal_per_node;
}

core::Expected<void> add_tet_surface_traction(const TetMesh& mesh, const std::string& triangle_set,
                                              const Eigen::Vector3d& traction_pa,
                                              TetNodalLoads& nodal_loads_n) {
  if (auto size = check_loads_size(mesh, nodal_loads_n); !size) return size;
  if (!traction_pa.allFinite()) {
    return core::make_error("tet loads: the traction on '" + triangle_set + "' is not finite");
  }
  const auto found = mesh.triangle_sets.find(triangle_set);
  if (found == mesh.triangle_sets.end() || found->second.empty()) {
    std::string known;
    for (const auto& [name, members] : mesh.triangle_sets) {
      known += (known.empty() ? "" : ", ") + name;
    }
    return core::make_error("tet loads: unknown or empty triangle set '" + triangle_set +
                            "' (known: " + known + ")");
  }
  // Validate every index before touching the loads, so a failure leaves them unchanged.
  for (const int triangle : found->second) {
    if (triangle_area(mesh, triangle) < 0.0) {
      return core::make_error("tet loads: triangle set '" + triangle_set + "' names triangle " +
                              std::to_string(triangle) +
                              ", which is out of range or names a "
                              "missing node");
    }
  }
  auto spread = spread_traction(mesh, triangle_set, found->second, traction_pa, nodal_loads_n);
  if (!spread) return spread.error();
  return {};
}

core::Expected<void> validate_tet_mesh(const TetMesh& mesh) {
  std::vector<std::string> problems;
  const auto report = [&problems](std::string text) {
    if (static_cast<int>(problems.size()) < kMaxReportedProblems)
      problems.push_back(std::move(text));
  };
  const int node_count = static_cast<int>(mesh.nodes.rows());
  const int element_count = static_cast<int>(mesh.tetrahedra.rows());
  if (node_count == 0 || element_count == 0) {
    return core::make_error("tet mesh: it has " + std::to_string(node_count) + " nodes and " +
                            std::to_string(element_count) +
                            " tetrahedra; expected at least one of each");
  }
  for (int node = 0; node < node_count; ++node) {
    if (!mesh.nodes.row(node).allFinite()) {
      report("node " + std::to_string(node) + " has non-finite coordinates");
    }
  }
  std::vector<bool> node_used(static_cast<std::size_t>(node_count), false);
  std::set<std::array<int, 4>> seen;
  for (int e = 0; e < element_count; ++e) {
    const Eigen::RowVector4i corners = mesh.tetrahedra.row(e);
    bool indices_ok = true;
    for (int c = 0; c < 4; ++c) {
      if (corners(c) < 0 || corners(c) >= node_count) {
        report(tet_description(e, corners) + " names node " + std::to_string(corners(c)) +
               "; expected 0.." + std::to_string(node_count - 1));
        indices_ok = false;
      }
    }
    if (!indices_ok) continue;
    std::array<int, 4> sorted{corners(0), corners(1), corners(2), corners(3)};
    std::sort(sorted.begin(), sorted.end());
    if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) {
      report(tet_description(e, corners) + " repeats a node");
      continue;
    }
    if (!seen.insert(sorted).second) {
      report(tet_description(e, corners) + " duplicates an earlier tetrahedron");
    }
    Eigen::Matrix<double, 4, 3> corners_m;
    for (int c = 0; c < 4; ++c) {
      corners_m.row(c) = mesh.nodes.row(corners(c));
      node_used[static_cast<std::size_t>(corners(c))] = true;
    }
    std::string problem = geometry_problem(corners_m);
    if (problem.empty()) problem = shape_problem(corners_m, corners);
    if (!problem.empty()) report(tet_description(e, corners) + " " + problem);
  }
  // Duplicate nodes (when every coordinate is finite).
  if (mesh.nodes.allFinite()) {
    const CoincidentNodes coincident =
        find_coincident_nodes(mesh.nodes, kCoincidentTetNodeRatio, 8);
    for (const auto& [first, second] : coincident.pairs) {
      std::ostringstream out;
      out << "node " << second << " is a duplicate of node " << first << " (coincident within "
          << coincident.tolerance_m << " m: the mesh is split there; merge them)";
      report(out.str());
    }
  }
  for (int node = 0; node < node_count; ++node) {
    if (!node_used[static_cast<std::size_t>(node)]) {
      report("node " + std::to_string(node) + " is used by no tetrahedron");
    }
  }
  const auto check_set = [&report](const char* kind, const std::string& name,
                                   const std::vector<int>& members, int limit) {
    for (const int index : members) {
      if (index < 0 || index >= limit) {
        report(std::string(kind) + " set '" + name + "' has index " + std::to_string(index) +
               "; expected 0.." + std::to_string(limit - 1));
        return;
      }
    }
  };
  for (const auto& [name, members] : mesh.node_sets) check_set("node", name, members, node_count);
  for (const auto& [name, members] : mesh.triangle_sets) {
    check_set("triangle", name, members, static_cast<int>(mesh.triangles.rows()));
  }
  for (const auto& [name, members] : mesh.tetrahedron_sets) {
    check_set("tetrahedron", name, members, element_count);
  }
  if (problems.empty()) return {};
  std::string message = "tet mesh: " + problems.front();
  for (std::size_t i = 1; i < problems.size(); ++i) message += "\n  " + problems[i];
  return core::make_error(message);
}

}  // namespace trainer::model::offline
