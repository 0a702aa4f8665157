// One flat triangular shell element: its local frame, the constant-strain membrane, the two
// plate-bending choices (Rao's 9-term cubic as in the paper, and DKT), the fictitious drilling
// stiffness, and the 18×18 global stiffness that assembly adds up. METHODS.md §1 steps 2–3,
// Basdogan eq. 1–13 and Appendix A.
//
// Frames and sign conventions (used everywhere in the offline shell code):
//   * local frame (eq. 8–11): origin at the element's first node, local y along side 1→2,
//     local z = unit normal of (p2 − p1) × (p3 − p1), local x = y × z (right-handed). The
//     nodes' local coordinates are therefore (0, 0), (0, y2 > 0), (x3, y3) with x3 < 0
//     (z follows the listed node order, so node 3 always lies on the −x side of side 1–2).
//   * local dofs per node: u, v, w (m) along local x, y, z; θx, θy, θz (rad), right-handed
//     rotations about local x, y, z. For the plate part θx = ∂w/∂y and θy = −∂w/∂x (the
//     paper's convention, and exactly the rigid rotation components about x and y).
//   * global dofs per node: ux, uy, uz, rx, ry, rz (kShellDofsPerNode order), with
//     local = λ · global for both translations and rotations, so K_e = Lᵀ k L with
//     L = blockdiag(λ × 6) (eq. 12–13).
#pragma once

#include <Eigen/Core>

#include "trainer/core/expected.hpp"
#include "trainer/model_offline/shell_model.hpp"

namespace trainer::model::offline {

using Matrix18d = Eigen::Matrix<double, 18, 18>;
using Matrix9d = Eigen::Matrix<double, 9, 9>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;
// Node local coordinates, one row per node: (x, y) in m.
using LocalTriangle = Eigen::Matrix<double, 3, 2>;
// Corner positions in the global frame, one row per node: (X, Y, Z) in m.
using TriangleCorners = Eigen::Matrix3d;

struct TriangleFrame {
  Eigen::Matrix3d
      direction_cosines;   // λ (eq. 8): rows are local x, y, z unit vectors, global coords
  LocalTriangle local_xy;  // node 1 at (0,0), node 2 at (0, y2), node 3 at (x3, y3)
  double area_m2 = 0.0;
};

// Local frame of a triangle. Fails when the triangle is degenerate (an edge or the area is
// zero relative to its size), since the frame is then undefined.
core::Expected<TriangleFrame> make_triangle_frame(const TriangleCorners& corners_m);

// Constant-strain membrane (eq. 1–2, Appendix A): K_m = t A Bᵀ D B with the plane-stress
// D = E/(1−ν²)[[1,ν,0],[ν,1,0],[0,0,(1−ν)/2]]. Dofs u1 v1 u2 v2 u3 v3. Any local in-plane
// frame works (the CST is frame-invariant).
Matrix6d membrane_stiffness(const LocalTriangle& local_xy, const ShellMaterial& material);

// Condition number (2-norm) of Rao's 9×9 interpolation matrix N for this node order, computed
// on coordinates scaled by the longest edge so that it measures shape, not size or units.
double rao_interpolation_condition(const LocalTriangle& local_xy);

// Rao's non-conforming cubic (Appendix A): k_b = N⁻ᵀ (∫ Qᵀ D_b Q dA) N⁻¹, with
// D_b = E t³/(12(1−ν²))[[1,ν,0],[ν,1,0],[0,0,(1−ν)/2]], Q the curvatures (w,xx, w,yy, 2w,xy)
// of w = a1 + a2x + a3y + a4x² + a5xy + a6y² + a7x³ + a8(x²y + xy²) + a9y³, integrated with a
// 3-point rule that is exact for the quadratic integrand. Dofs w1 θx1 θy1 … w3 θx3 θy3 in the
// node order given. Refuses the node order when N is singular (condition > 1e8), which
// happens when y3 = (y2 − x3)/2 in the frame above — e.g. a right isosceles triangle with
// the right angle at node 2. No reordering here: shell_element_stiffness() picks the order.
core::Expected<Matrix9d> rao_bending_stiffness(const LocalTriangle& local_xy,
                                               const ShellMaterial& material);

// Discrete Kirchhoff triangle (Batoz, Bathe & Ho 1980): quadratic rotation fields with the
// Kirchhoff constraint imposed at the corners and mid-sides, 3-point quadrature (exact: B is
// linear). Same dofs and order as rao_bending_stiffness(). Requires a non-degenerate triangle.
Matrix9d dkt_bending_stiffness(const LocalTriangle& local_xy, const ShellMaterial& material);

// Ratio of the fictitious drilling stiffness to the smallest rotational diagonal term of the
// bending matrix (METHODS.md §1 step 2).
inline constexpr double kDrillingStiffnessRatio = 1e-4;
// Rao orderings whose N has a larger condition number are refused as singular.
inline constexpr double kRaoMaxCondition = 1e8;

// The element's 18×18 stiffness in the global frame (K_e = Lᵀ k L), node dofs
// ux uy uz rx ry rz in the node order of `corners_m`. The local matrix is membrane + bending +
// drilling, where the drilling term is k_d Σ_i (θz_i − ω)² with ω = ½(∂v/∂x − ∂u/∂y) the
// membrane's in-plane rotation and k_d = kDrillingStiffnessRatio × the smallest θx/θy diagonal
// bending term: tying θz to the membrane rotation (rather than to nothing) keeps rigid in-plane
// rotations force-free and still removes the otherwise singular θz.
// For BendingElement::rao the best-conditioned of the three cyclic node orders is used and the
// result mapped back; the call fails when all three are singular.
core::Expected<Matrix18d> shell_element_stiffness(const TriangleCorners& corners_m,
                                                  const ShellMaterial& material,
                                                  BendingElement bending);

}  // namespace trainer::model::offline
