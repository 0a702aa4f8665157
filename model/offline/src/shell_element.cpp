// Flat shell triangle: local frame, CST membrane, Rao and DKT bending, drilling, transform.
// Conventions are stated in shell_element.hpp.
#include "trainer/model_offline/shell_element.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>

namespace trainer::model::offline {
namespace {

// Plane-stress constitutive matrix without the thickness factor:
// E/(1−ν²)[[1,ν,0],[ν,1,0],[0,0,(1−ν)/2]].
Eigen::Matrix3d plane_stress_matrix(const ShellMaterial& material) {
  const double nu = material.poisson_ratio;
  const double factor = material.young_modulus_pa / (1.0 - nu * nu);
  Eigen::Matrix3d d;
  d << 1.0, nu, 0.0, nu, 1.0, 0.0, 0.0, 0.0, 0.5 * (1.0 - nu);
  return factor * d;
}

// Bending rigidity matrix D_b = t³/12 × plane stress (N·m).
Eigen::Matrix3d bending_matrix(const ShellMaterial& material) {
  const double t = material.thickness_m;
  return (t * t * t / 12.0) * plane_stress_matrix(material);
}

// Twice the signed area of the local triangle.
double twice_signed_area(const LocalTriangle& p) {
  return (p(1, 0) - p(0, 0)) * (p(2, 1) - p(0, 1)) - (p(2, 0) - p(0, 0)) * (p(1, 1) - p(0, 1));
}

// 3-point interior rule on the reference triangle (area coordinates of node 2 and 3), exact
// for quadratics. Weights sum to 1: multiply by the physical area.
constexpr std::array<std::array<double, 2>, 3> kQuadraturePoints{
    {{1.0 / 6.0, 1.0 / 6.0}, {2.0 / 3.0, 1.0 / 6.0}, {1.0 / 6.0, 2.0 / 3.0}}};
constexpr double kQuadratureWeight = 1.0 / 3.0;

double longest_edge(const LocalTriangle& p) {
  double longest = 0.0;
  for (int i = 0; i < 3; ++i) {
    longest = std::max(longest, (p.row((i + 1) % 3) - p.row(i)).norm());
  }
  return longest;
}

// Rao's interpolation matrix: rows (w, ∂w/∂y, −∂w/∂x) of the 9-term cubic at each node.
Matrix9d rao_interpolation_matrix(const LocalTriangle& p) {
  Matrix9d n;
  for (int i = 0; i < 3; ++i) {
    const double x = p(i, 0);
    const double y = p(i, 1);
    n.row(3 * i) << 1.0, x, y, x * x, x * y, y * y, x * x * x, x * x * y + x * y * y, y * y * y;
    n.row(3 * i + 1) << 0.0, 0.0, 1.0, 0.0, x, 2.0 * y, 0.0, x * x + 2.0 * x * y, 3.0 * y * y;
    n.row(3 * i + 2) << 0.0, -1.0, 0.0, -2.0 * x, -y, 0.0, -3.0 * x * x, -(2.0 * x * y + y * y),
        0.0;
  }
  return n;
}

// Rotates global dofs into the element frame: every node's translation and rotation triple
// uses the same λ (eq. 7, 13).
Matrix18d frame_transformation(const Eigen::Matrix3d& lambda) {
  Matrix18d transformation = Matrix18d::Zero();
  for (int block = 0; block < 6; ++block) {
    transformation.block<3, 3>(3 * block, 3 * block) = lambda;
  }
  return transformation;
}

std::string format_point(const Eigen::RowVector3d& p) {
  std::ostringstream out;
  out.precision(6);
  out << "(" << p(0) << ", " << p(1) << ", " << p(2) << ")";
  return out.str();
}

// Local 18×18 matrix for the node order of `frame`.
core::Expected<Matrix18d> local_stiffness(const TriangleFrame& frame, const ShellMaterial& material,
                                          BendingElement bending) {
  Matrix9d bending_matrix_local;
  if (bending == BendingElement::rao) {
    auto rao = rao_bending_stiffness(frame.local_xy, material);
    if (!rao) return rao.error();
    bending_matrix_local = *rao;
  } else {
    bending_matrix_local = dkt_bending_stiffness(frame.local_xy, material);
  }
  const Matrix6d membrane = membrane_stiffness(frame.local_xy, material);

  Matrix18d k = Matrix18d::Zero();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      k.block<2, 2>(6 * i, 6 * j) = membrane.block<2, 2>(2 * i, 2 * j);
      k.block<3, 3>(6 * i + 2, 6 * j + 2) = bending_matrix_local.block<3, 3>(3 * i, 3 * j);
    }
  }

  double smallest_rotation_term = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 3; ++i) {
    smallest_rotation_term =
        std::min({smallest_rotation_term, bending_matrix_local(3 * i + 1, 3 * i + 1),
                  bending_matrix_local(3 * i + 2, 3 * i + 2)});
  }
  const double drilling = kDrillingStiffnessRatio * smallest_rotation_term;

  // ω = ½(∂v/∂x − ∂u/∂y) of the CST field, as a row over the 18 local dofs.
  const LocalTriangle& p = frame.local_xy;
  const double twice_area = twice_signed_area(p);
  Eigen::Matrix<double, 1, 18> rotation_row = Eigen::Matrix<double, 1, 18>::Zero();
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3;
    const int m = (i + 2) % 3;
    const double dn_dx = (p(j, 1) - p(m, 1)) / twice_area;  // ∂N_i/∂x
    const double dn_dy = (p(m, 0) - p(j, 0)) / twice_area;  // ∂N_i/∂y
    rotation_row(6 * i) = -0.5 * dn_dy;
    rotation_row(6 * i + 1) = 0.5 * dn_dx;
  }
  for (int i = 0; i < 3; ++i) {
    Eigen::Matrix<double, 1, 18> relative = -rotation_row;
    relative(6 * i + 5) += 1.0;
    k += drilling * relative.transpose() * relative;
  }
  return k;
}

core::Expected<Matrix18d> global_stiffness_in_order(const TriangleCorners& corners_m,
                                                    const ShellMaterial& material,
                                                    BendingElement bending) {
  auto frame = make_triangle_frame(corners_m);
  if (!frame) return frame.error();
  auto local = local_stiffness(*frame, material, bending);
  if (!local) return local.error();
  const Matrix18d transformation = frame_transformation(frame->direction_cosines);
  Matrix18d global = transformation.transpose() * (*local) * transformation;
  // Symmetric by construction; remove round-off asymmetry so the assembled K is exactly so.
  return Matrix18d(0.5 * (global + global.transpose()));
}

}  // namespace

core::Expected<TriangleFrame> make_triangle_frame(const TriangleCorners& corners_m) {
  const Eigen::RowVector3d p1 = corners_m.row(0);
  const Eigen::RowVector3d side12 = corners_m.row(1) - p1;
  const Eigen::RowVector3d side13 = corners_m.row(2) - p1;
  const double length12 = side12.norm();
  const double length13 = side13.norm();
  const double length23 = (corners_m.row(2) - corners_m.row(1)).norm();
  const double longest = std::max({length12, length13, length23});
  const Eigen::RowVector3d normal = side12.cross(side13);
  const double twice_area = normal.norm();
  if (!(longest > 0.0) || !std::isfinite(twice_area) || twice_area <= 1e-12 * longest * longest ||
      length12 <= 1e-12 * longest) {
    return core::make_error("degenerate triangle " + format_point(corners_m.row(0)) + ", " +
                            format_point(corners_m.row(1)) + ", " + format_point(corners_m.row(2)) +
                            ": area is zero relative to its edge lengths, no local frame");
  }
  TriangleFrame frame;
  const Eigen::RowVector3d axis_y = side12 / length12;
  const Eigen::RowVector3d axis_z = normal / twice_area;
  const Eigen::RowVector3d axis_x = axis_y.cross(axis_z);
  frame.direction_cosines.row(0) = axis_x;
  frame.direction_cosines.row(1) = axis_y;
  frame.direction_cosines.row(2) = axis_z;
  frame.local_xy << 0.0, 0.0, 0.0, length12, side13.dot(axis_x), side13.dot(axis_y);
  frame.area_m2 = 0.5 * twice_area;
  return frame;
}

Matrix6d membrane_stiffness(const LocalTriangle& p, const ShellMaterial& material) {
  const double twice_area = twice_signed_area(p);
  Eigen::Matrix<double, 3, 6> strain = Eigen::Matrix<double, 3, 6>::Zero();
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3;
    const int m = (i + 2) % 3;
    const double dn_dx = (p(j, 1) - p(m, 1)) / twice_area;
    const double dn_dy = (p(m, 0) - p(j, 0)) / twice_area;
    strain(0, 2 * i) = dn_dx;
    strain(1, 2 * i + 1) = dn_dy;
    strain(2, 2 * i) = dn_dy;
    strain(2, 2 * i + 1) = dn_dx;
  }
  const double volume = material.thickness_m * 0.5 * std::abs(twice_area);
  return volume * strain.transpose() * plane_stress_matrix(material) * strain;
}

double rao_interpolation_condition(const LocalTriangle& local_xy) {
  const double scale = longest_edge(local_xy);
  if (!(scale > 0.0)) return std::numeric_limits<double>::infinity();
  // Dynamic size: the fixed-size 9×9 SVD trips a false GCC 12 maybe-uninitialized warning.
  const Eigen::MatrixXd n = rao_interpolation_matrix(local_xy / scale);
  const Eigen::VectorXd singular = Eigen::JacobiSVD<Eigen::MatrixXd>(n).singularValues();
  const double smallest = singular.minCoeff();
  if (!(smallest > 0.0)) return std::numeric_limits<double>::infinity();
  return singular.maxCoeff() / smallest;
}

core::Expected<Matrix9d> rao_bending_stiffness(const LocalTriangle& local_xy,
                                               const ShellMaterial& material) {
  const double condition = rao_interpolation_condition(local_xy);
  if (!(condition <= kRaoMaxCondition)) {
    std::ostringstream message;
    message << "Rao bending element: the cubic's interpolation matrix N is singular for node "
               "order (0,0), ("
            << local_xy(1, 0) << ", " << local_xy(1, 1) << "), (" << local_xy(2, 0) << ", "
            << local_xy(2, 1) << ") (condition number " << condition << " > " << kRaoMaxCondition
            << "; singular when y3 = (y2 - x3)/2)";
    return core::make_error(message.str());
  }
  const Matrix9d n = rao_interpolation_matrix(local_xy);
  const Eigen::Matrix3d rigidity = bending_matrix(material);
  const double area = 0.5 * std::abs(twice_signed_area(local_xy));

  Matrix9d coefficient_stiffness = Matrix9d::Zero();
  for (const auto& point : kQuadraturePoints) {
    const double l2 = point[0];
    const double l3 = point[1];
    const double l1 = 1.0 - l2 - l3;
    const double x = l1 * local_xy(0, 0) + l2 * local_xy(1, 0) + l3 * local_xy(2, 0);
    const double y = l1 * local_xy(0, 1) + l2 * local_xy(1, 1) + l3 * local_xy(2, 1);
    Eigen::Matrix<double, 3, 9> curvature;
    curvature << 0, 0, 0, 2, 0, 0, 6 * x, 2 * y, 0,  //
        0, 0, 0, 0, 0, 2, 0, 2 * x, 6 * y,           //
        0, 0, 0, 0, 2, 0, 0, 4 * x + 4 * y, 0;
    coefficient_stiffness +=
        (kQuadratureWeight * area) * curvature.transpose() * rigidity * curvature;
  }
  const Eigen::FullPivLU<Matrix9d> lu(n);
  const Matrix9d n_inverse = lu.inverse();
  Matrix9d k = n_inverse.transpose() * coefficient_stiffness * n_inverse;
  return Matrix9d(0.5 * (k + k.transpose()));
}

Matrix9d dkt_bending_stiffness(const LocalTriangle& p, const ShellMaterial& material) {
  // Mid-side k = 3, 4, 5 (Batoz's 4, 5, 6) lies on side (i, j) = (1,2), (2,0), (0,1).
  constexpr std::array<std::array<int, 2>, 3> kSides{{{1, 2}, {2, 0}, {0, 1}}};
  std::array<double, 3> a{}, b{}, c{}, d{}, e{};
  for (int s = 0; s < 3; ++s) {
    const int i = kSides[static_cast<std::size_t>(s)][0];
    const int j = kSides[static_cast<std::size_t>(s)][1];
    const double xij = p(i, 0) - p(j, 0);
    const double yij = p(i, 1) - p(j, 1);
    const double length_squared = xij * xij + yij * yij;
    const auto k = static_cast<std::size_t>(s);
    a[k] = -xij / length_squared;
    b[k] = 0.75 * xij * yij / length_squared;
    c[k] = (0.25 * xij * xij - 0.5 * yij * yij) / length_squared;
    d[k] = -yij / length_squared;
    e[k] = (0.25 * yij * yij - 0.5 * xij * xij) / length_squared;
  }
  // β_x = Cx · N and β_y = Cy · N with N the six quadratic shape functions (corners 0–2,
  // mid-sides 3–5), where β is the normal's rotation with β_x = −∂w/∂x = θy, β_y = −∂w/∂y = −θx.
  Eigen::Matrix<double, 9, 6> cx = Eigen::Matrix<double, 9, 6>::Zero();
  Eigen::Matrix<double, 9, 6> cy = Eigen::Matrix<double, 9, 6>::Zero();
  for (int node = 0; node < 3; ++node) {
    const int row = 3 * node;
    cx(row + 2, node) = 1.0;
    cy(row + 1, node) = -1.0;
    for (int s = 0; s < 3; ++s) {
      const auto k = static_cast<std::size_t>(s);
      const int i = kSides[k][0];
      const int j = kSides[k][1];
      if (node != i && node != j) continue;
      const int column = 3 + s;
      const double sign = node == i ? 1.0 : -1.0;
      cx(row, column) = 1.5 * sign * a[k];
      cx(row + 1, column) = b[k];
      cx(row + 2, column) = -c[k];
      cy(row, column) = 1.5 * sign * d[k];
      cy(row + 1, column) = e[k];
      cy(row + 2, column) = -b[k];
    }
  }

  const double x21 = p(1, 0) - p(0, 0);
  const double y21 = p(1, 1) - p(0, 1);
  const double x31 = p(2, 0) - p(0, 0);
  const double y31 = p(2, 1) - p(0, 1);
  Eigen::Matrix2d jacobian;  // rows ∂(x, y)/∂ξ and ∂(x, y)/∂η
  jacobian << x21, y21, x31, y31;
  const Eigen::Matrix2d inverse_jacobian = jacobian.inverse();
  const double area = 0.5 * std::abs(jacobian.determinant());
  const Eigen::Matrix3d rigidity = bending_matrix(material);

  Matrix9d k = Matrix9d::Zero();
  for (const auto& point : kQuadraturePoints) {
    const double xi = point[0];
    const double eta = point[1];
    Eigen::Matrix<double, 6, 1> dn_dxi;
    Eigen::Matrix<double, 6, 1> dn_deta;
    dn_dxi << -3.0 + 4.0 * xi + 4.0 * eta, 4.0 * xi - 1.0, 0.0, 4.0 * eta, -4.0 * eta,
        4.0 * (1.0 - 2.0 * xi - eta);
    dn_deta << -3.0 + 4.0 * xi + 4.0 * eta, 0.0, 4.0 * eta - 1.0, 4.0 * xi,
        4.0 * (1.0 - xi - 2.0 * eta), -4.0 * xi;
    const Eigen::Matrix<double, 6, 1> dn_dx =
        inverse_jacobian(0, 0) * dn_dxi + inverse_jacobian(0, 1) * dn_deta;
    const Eigen::Matrix<double, 6, 1> dn_dy =
        inverse_jacobian(1, 0) * dn_dxi + inverse_jacobian(1, 1) * dn_deta;
    Eigen::Matrix<double, 3, 9> curvature;
    curvature.row(0) = (cx * dn_dx).transpose();
    curvature.row(1) = (cy * dn_dy).transpose();
    curvature.row(2) = (cx * dn_dy + cy * dn_dx).transpose();
    k += (kQuadratureWeight * area) * curvature.transpose() * rigidity * curvature;
  }
  return Matrix9d(0.5 * (k + k.transpose()));
}

core::Expected<Matrix18d> shell_element_stiffness(const TriangleCorners& corners_m,
                                                  const ShellMaterial& material,
                                                  BendingElement bending) {
  if (bending != BendingElement::rao) {
    return global_stiffness_in_order(corners_m, material, bending);
  }
  // Rao's cubic is not invariant to the node order: use the best-conditioned cyclic order.
  int best_shift = -1;
  double best_condition = std::numeric_limits<double>::infinity();
  for (int shift = 0; shift < 3; ++shift) {
    TriangleCorners rotated;
    for (int i = 0; i < 3; ++i) rotated.row(i) = corners_m.row((i + shift) % 3);
    auto frame = make_triangle_frame(rotated);
    if (!frame) return frame.error();
    const double condition = rao_interpolation_condition(frame->local_xy);
    if (condition < best_condition) {
      best_condition = condition;
      best_shift = shift;
    }
  }
  if (best_shift < 0 || !(best_condition <= kRaoMaxCondition)) {
    std::ostringstream message;
    message << "Rao bending element: the cubic's interpolation matrix N is singular (or too "
               "ill-conditioned to invert) for all three node orders of triangle "
            << format_point(corners_m.row(0)) << ", " << format_point(corners_m.row(1)) << ", "
            << format_point(corners_m.row(2)) << " (best condition number " << best_condition
            << " > " << kRaoMaxCondition << "); use the DKT element or remesh";
    return core::make_error(message.str());
  }
  TriangleCorners rotated;
  for (int i = 0; i < 3; ++i) rotated.row(i) = corners_m.row((i + best_shift) % 3);
  auto rotated_stiffness = global_stiffness_in_order(rotated, material, bending);
  if (!rotated_stiffness) return rotated_stiffness.error();
  // Rotated node a is original node (a + shift) % 3.
  Matrix18d k;
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      k.block<6, 6>(6 * ((a + best_shift) % 3), 6 * ((b + best_shift) % 3)) =
          rotated_stiffness->block<6, 6>(6 * a, 6 * b);
    }
  }
  return k;
}

}  // namespace trainer::model::offline
