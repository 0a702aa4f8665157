// Element-level tests of the flat shell triangle: rigid-body motions, rank, energy of exact
// strain/curvature fields (which sees the thickness factors), patch tests on an irregular patch
// in a tilted plane, and Rao's singular node orders.
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <iostream>
#include <random>

#include "shell_test_support.hpp"
#include "trainer/model_offline/shell_element.hpp"

namespace trainer::model::offline {
namespace {

using test::element_test_name;
using test::dense_stiffness;
using test::random_rotation;
using test::rigid_motion;
using test::solve_prescribed;
using test::test_material;

class ShellElementBothBendings : public ::testing::TestWithParam<BendingElement> {};


INSTANTIATE_TEST_SUITE_P(Bending, ShellElementBothBendings,
                         ::testing::Values(BendingElement::dkt, BendingElement::rao),
                         element_test_name);

// Random, reasonably shaped triangles placed anywhere in 3-D.
TriangleCorners random_triangle(std::mt19937& random) {
  std::uniform_real_distribution<double> coordinate(-1.0, 1.0);
  std::uniform_real_distribution<double> offset(-10.0, 10.0);
  const Eigen::Matrix3d rotation = random_rotation(random);
  const Eigen::Vector3d origin(offset(random), offset(random), offset(random));
  while (true) {
    Eigen::Matrix<double, 3, 2> flat;
    for (int i = 0; i < 3; ++i) flat.row(i) << coordinate(random), coordinate(random);
    const double twice_area = std::abs((flat(1, 0) - flat(0, 0)) * (flat(2, 1) - flat(0, 1)) -
                                       (flat(2, 0) - flat(0, 0)) * (flat(1, 1) - flat(0, 1)));
    double longest = 0.0;
    for (int i = 0; i < 3; ++i)
      longest = std::max(longest, (flat.row((i + 1) % 3) - flat.row(i)).norm());
    if (twice_area < 0.2 * longest * longest) continue;  // no slivers
    TriangleCorners corners;
    for (int i = 0; i < 3; ++i) {
      corners.row(i) =
          (origin + rotation * Eigen::Vector3d(flat(i, 0), flat(i, 1), 0.0)).transpose();
    }
    return corners;
  }
}

double operator_norm(const Eigen::MatrixXd& m) {
  return Eigen::JacobiSVD<Eigen::MatrixXd>(m).singularValues()(0);
}

TEST_P(ShellElementBothBendings, RigidBodyMotionsInAnyOrientationGiveZeroForce) {
  std::mt19937 random(1234);
  std::normal_distribution<double> normal(0.0, 1.0);
  const ShellMaterial material = test_material(2.0e11, 0.3, 0.05);
  for (int trial = 0; trial < 50; ++trial) {
    const TriangleCorners corners = random_triangle(random);
    auto k = shell_element_stiffness(corners, material, GetParam());
    ASSERT_TRUE(k) << k.error().message;
    const double k_norm = operator_norm(*k);
    for (int mode = 0; mode < 6; ++mode) {
      Eigen::Vector3d translation = Eigen::Vector3d::Zero();
      Eigen::Vector3d rotation = Eigen::Vector3d::Zero();
      (mode < 3 ? translation : rotation)(mode % 3) = 1.0;
      const Eigen::Matrix<double, 18, 1> r = rigid_motion(corners, translation, rotation);
      EXPECT_LE(((*k) * r).norm(), 1e-9 * k_norm * r.norm())
          << "trial " << trial << " mode " << mode;
    }
    // A random combination too, about a random axis.
    const Eigen::Matrix<double, 18, 1> r =
        rigid_motion(corners, Eigen::Vector3d(normal(random), normal(random), normal(random)),
                     Eigen::Vector3d(normal(random), normal(random), normal(random)));
    EXPECT_LE(((*k) * r).norm(), 1e-9 * k_norm * r.norm()) << "trial " << trial;
  }
}

TEST_P(ShellElementBothBendings, StiffnessIsSymmetricWithExactlySixZeroEnergyModes) {
  std::mt19937 random(99);
  // Thick enough (t/size ~ 0.1) that the drilling terms (1e-4 of bending) stand clear of zero.
  const ShellMaterial material = test_material(2.0e11, 0.3, 0.1);
  for (int trial = 0; trial < 20; ++trial) {
    const TriangleCorners corners = random_triangle(random);
    auto k = shell_element_stiffness(corners, material, GetParam());
    ASSERT_TRUE(k) << k.error().message;
    EXPECT_LE(((*k) - k->transpose()).norm(), 1e-14 * k->norm());
    const Eigen::SelfAdjointEigenSolver<Matrix18d> eigen(*k);
    const auto& values = eigen.eigenvalues();
    const double largest = values.maxCoeff();
    int zero = 0;
    for (int i = 0; i < 18; ++i) {
      if (std::abs(values(i)) < 1e-12 * largest) {
        ++zero;
      } else {
        EXPECT_GT(values(i), 0.0);
      }
    }
    EXPECT_EQ(zero, 6) << "trial " << trial << " eigenvalues " << values.transpose();
  }
}

// ½ uᵀ K u for a uniform membrane strain must equal ½ t A εᵀ D ε: this sees the membrane's
// thickness factor and plane-stress matrix, which rigid-body and patch tests cannot.
TEST_P(ShellElementBothBendings, UniformMembraneStrainStoresExactEnergy) {
  std::mt19937 random(7);
  std::normal_distribution<double> normal(0.0, 1e-3);
  const ShellMaterial material = test_material(3.0e9, 0.25, 0.02);
  const double e = material.young_modulus_pa / (1.0 - 0.25 * 0.25);
  Eigen::Matrix3d d;
  d << e, 0.25 * e, 0.0, 0.25 * e, e, 0.0, 0.0, 0.0, 0.5 * (1.0 - 0.25) * e;
  for (int trial = 0; trial < 10; ++trial) {
    const TriangleCorners corners = random_triangle(random);
    auto frame = make_triangle_frame(corners);
    ASSERT_TRUE(frame);
    const Eigen::Vector3d strain(normal(random), normal(random), normal(random));  // εxx εyy γxy
    Eigen::Matrix<double, 18, 1> u = Eigen::Matrix<double, 18, 1>::Zero();
    for (int node = 0; node < 3; ++node) {
      const double x = frame->local_xy(node, 0);
      const double y = frame->local_xy(node, 1);
      const Eigen::Vector3d local(strain(0) * x + 0.5 * strain(2) * y,
                                  0.5 * strain(2) * x + strain(1) * y, 0.0);
      u.segment<3>(6 * node) = frame->direction_cosines.transpose() * local;
    }
    auto k = shell_element_stiffness(corners, material, GetParam());
    ASSERT_TRUE(k);
    const double energy = 0.5 * u.dot((*k) * u);
    const double expected = 0.5 * material.thickness_m * frame->area_m2 * strain.dot(d * strain);
    EXPECT_NEAR(energy, expected, 1e-10 * expected);
  }
}

// ½ uᵀ K u for a uniform curvature must equal ½ A κᵀ D_b κ with D_b = E t³/(12(1−ν²))[...]:
// sees the bending thickness factor. Both elements represent quadratic w exactly.
TEST_P(ShellElementBothBendings, UniformCurvatureStoresExactBendingEnergy) {
  std::mt19937 random(11);
  std::normal_distribution<double> normal(0.0, 1e-2);
  const double nu = 0.3;
  const ShellMaterial material = test_material(7.0e10, nu, 0.004);
  const double rigidity =
      material.young_modulus_pa * std::pow(material.thickness_m, 3) / (12.0 * (1.0 - nu * nu));
  Eigen::Matrix3d d;
  d << 1.0, nu, 0.0, nu, 1.0, 0.0, 0.0, 0.0, 0.5 * (1.0 - nu);
  d *= rigidity;
  for (int trial = 0; trial < 10; ++trial) {
    const TriangleCorners corners = random_triangle(random);
    auto frame = make_triangle_frame(corners);
    ASSERT_TRUE(frame);
    const double kxx = normal(random), kyy = normal(random), kxy = normal(random);
    Eigen::Matrix<double, 18, 1> u = Eigen::Matrix<double, 18, 1>::Zero();
    for (int node = 0; node < 3; ++node) {
      const double x = frame->local_xy(node, 0);
      const double y = frame->local_xy(node, 1);
      const double w = 0.5 * (kxx * x * x + 2.0 * kxy * x * y + kyy * y * y);
      const Eigen::Vector3d rotation(kxy * x + kyy * y, -(kxx * x + kxy * y), 0.0);  // w,y; −w,x
      u.segment<3>(6 * node) = frame->direction_cosines.transpose() * Eigen::Vector3d(0.0, 0.0, w);
      u.segment<3>(6 * node + 3) = frame->direction_cosines.transpose() * rotation;
    }
    auto k = shell_element_stiffness(corners, material, GetParam());
    ASSERT_TRUE(k);
    const Eigen::Vector3d curvature(kxx, kyy, 2.0 * kxy);
    const double energy = 0.5 * u.dot((*k) * u);
    const double expected = 0.5 * frame->area_m2 * curvature.dot(d * curvature);
    EXPECT_NEAR(energy, expected, 1e-9 * expected) << "trial " << trial;
  }
}

// MacNeal–Harder irregular patch (0.24 × 0.12, four interior nodes), split into 10 triangles,
// placed in a tilted plane away from the origin.
struct Patch {
  ShellMesh mesh;
  Eigen::Matrix3d rotation;  // columns: patch s axis, t axis, normal
  Eigen::Matrix<double, 8, 2> flat;
};

Patch make_patch() {
  Patch patch;
  patch.flat << 0.0, 0.0, 0.24, 0.0, 0.24, 0.12, 0.0, 0.12, 0.04, 0.02, 0.18, 0.03, 0.16, 0.08,
      0.08, 0.08;
  std::mt19937 random(5);
  patch.rotation = random_rotation(random);
  const Eigen::Vector3d origin(0.3, -0.7, 1.1);
  patch.mesh.nodes.resize(8, 3);
  for (int n = 0; n < 8; ++n) {
    patch.mesh.nodes.row(n) =
        (origin + patch.rotation * Eigen::Vector3d(patch.flat(n, 0), patch.flat(n, 1), 0.0))
            .transpose();
  }
  patch.mesh.triangles.resize(10, 3);
  patch.mesh.triangles << 0, 1, 5, 0, 5, 4, 1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7, 4,
      5, 6, 4, 6, 7;
  return patch;
}

TEST_P(ShellElementBothBendings, IrregularPatchReproducesConstantMembraneStrainExactly) {
  const Patch patch = make_patch();
  // t/h ≈ 0.1: with much thinner plates round-off in the membrane terms (∝ t) leaks into the
  // bending dofs (∝ t³) at the 1e-10 level, which is conditioning, not the patch test.
  const ShellMaterial material = test_material(2.0e11, 0.3, 0.01);
  const Eigen::MatrixXd k = dense_stiffness(patch.mesh, material, GetParam());
  // u = a + A·(s, t) in the patch plane, with a rotation part (A not symmetric).
  Eigen::Matrix2d gradient;
  gradient << 1e-3, 4e-4, -2e-4, -5e-4;
  const Eigen::Vector2d offset(1e-4, -3e-4);
  const double in_plane_rotation = 0.5 * (gradient(1, 0) - gradient(0, 1));
  Eigen::VectorXd exact = Eigen::VectorXd::Zero(48);
  for (int n = 0; n < 8; ++n) {
    const Eigen::Vector2d displacement = offset + gradient * patch.flat.row(n).transpose();
    exact.segment<3>(6 * n) =
        patch.rotation * Eigen::Vector3d(displacement(0), displacement(1), 0.0);
    exact.segment<3>(6 * n + 3) = patch.rotation * Eigen::Vector3d(0.0, 0.0, in_plane_rotation);
  }
  std::vector<bool> prescribed(48, false);
  for (int n = 0; n < 4; ++n) {
    for (int d = 0; d < 6; ++d) prescribed[static_cast<std::size_t>(6 * n + d)] = true;
  }
  Eigen::VectorXd start = exact;
  start.tail(24).setZero();
  const Eigen::VectorXd solved = solve_prescribed(k, prescribed, start);
  double largest_translation = 0.0;
  for (int n = 0; n < 8; ++n)
    largest_translation = std::max(largest_translation, exact.segment<3>(6 * n).norm());
  for (int n = 4; n < 8; ++n) {
    EXPECT_LE((solved - exact).segment<3>(6 * n).norm(), 1e-10 * largest_translation)
        << "interior node " << n << " translation error";
    // The rotations are set only by the fictitious drilling spring (1e-4 of bending), so
    // round-off in the far stiffer membrane terms moves them at the ~1e-10 relative level.
    EXPECT_LE((solved - exact).segment<3>(6 * n + 3).norm(), 1e-8 * std::abs(in_plane_rotation))
        << "interior node " << n << " rotation error";
  }
}

// Constant-curvature bending patch test. DKT passes it exactly; Rao's non-conforming cubic
// does not on an irregular patch (METHODS.md §1): its error is measured and printed.
TEST_P(ShellElementBothBendings, IrregularPatchConstantCurvature) {
  const Patch patch = make_patch();
  const ShellMaterial material = test_material(2.0e11, 0.3, 0.001);
  const Eigen::MatrixXd k = dense_stiffness(patch.mesh, material, GetParam());
  const double kss = 2e-2, ktt = -1e-2, kst = 5e-3;
  Eigen::VectorXd exact = Eigen::VectorXd::Zero(48);
  for (int n = 0; n < 8; ++n) {
    const double s = patch.flat(n, 0), t = patch.flat(n, 1);
    const double w =
        1e-4 + 2e-3 * s - 1e-3 * t + 0.5 * (kss * s * s + 2.0 * kst * s * t + ktt * t * t);
    const double dw_ds = 2e-3 + kss * s + kst * t;
    const double dw_dt = -1e-3 + kst * s + ktt * t;
    exact.segment<3>(6 * n) = patch.rotation * Eigen::Vector3d(0.0, 0.0, w);
    exact.segment<3>(6 * n + 3) = patch.rotation * Eigen::Vector3d(dw_dt, -dw_ds, 0.0);
  }
  std::vector<bool> prescribed(48, false);
  for (int n = 0; n < 4; ++n) {
    for (int d = 0; d < 6; ++d) prescribed[static_cast<std::size_t>(6 * n + d)] = true;
  }
  Eigen::VectorXd start = exact;
  start.tail(24).setZero();
  const Eigen::VectorXd solved = solve_prescribed(k, prescribed, start);
  const double error = (solved - exact).cwiseAbs().maxCoeff() / exact.cwiseAbs().maxCoeff();
  std::cout << "[measured] constant-curvature patch, "
            << (GetParam() == BendingElement::dkt ? "DKT" : "Rao")
            << ": max interior error / max dof = " << error << "\n";
  if (GetParam() == BendingElement::dkt) {
    EXPECT_LE(error, 1e-10);
  } else {
    // Rao fails this patch test (measured 2.2 %): asserted, so the documentation's claim that
    // it passes only for some mesh patterns stays checked, and bounded so a broken element
    // (rather than a non-conforming one) still fails.
    EXPECT_GT(error, 1e-3);
    EXPECT_LT(error, 0.05);
  }
}

TEST(RaoOrdering, RightAngleAtSecondNodeIsSingularInThatOrderButReordered) {
  // Right isosceles triangle with the right angle at node 2: in the element frame nodes are
  // (0,0), (0,1), (−1,1), so y3 = (y2 − x3)/2 and N is singular for this order.
  TriangleCorners corners;
  corners << 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 1.0, 0.0;
  const ShellMaterial material = test_material(1e9, 0.3, 0.01);
  auto frame = make_triangle_frame(corners);
  ASSERT_TRUE(frame);
  EXPECT_NEAR(frame->local_xy(2, 1), 0.5 * (frame->local_xy(1, 1) - frame->local_xy(2, 0)), 1e-15);
  auto fixed_order = rao_bending_stiffness(frame->local_xy, material);
  ASSERT_FALSE(fixed_order);
  EXPECT_NE(fixed_order.error().message.find("singular"), std::string::npos)
      << fixed_order.error().message;
  EXPECT_NE(fixed_order.error().message.find("y3 = (y2 - x3)/2"), std::string::npos);

  auto element = shell_element_stiffness(corners, material, BendingElement::rao);
  ASSERT_TRUE(element) << element.error().message;
  EXPECT_TRUE(element->allFinite());
  const Eigen::Matrix<double, 18, 1> r =
      rigid_motion(corners, Eigen::Vector3d(0.3, -1.0, 2.0), Eigen::Vector3d(1.0, 0.5, -0.7));
  EXPECT_LE(((*element) * r).norm(), 1e-9 * operator_norm(*element) * r.norm());
  // And the same triangle listed from another corner gives the same matrix (node blocks moved).
  TriangleCorners shifted;
  shifted << corners.row(1), corners.row(2), corners.row(0);
  auto element_shifted = shell_element_stiffness(shifted, material, BendingElement::rao);
  ASSERT_TRUE(element_shifted);
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      EXPECT_LE((element_shifted->block<6, 6>(6 * a, 6 * b) -
                 element->block<6, 6>(6 * ((a + 1) % 3), 6 * ((b + 1) % 3)))
                    .norm(),
                1e-12 * element->norm());
    }
  }
}

TEST(RaoOrdering, TriangleIllConditionedInEveryOrderIsRefusedClearly) {
  // A sliver (height 1e-4 of its base) passes mesh validation but N's condition number is
  // ~1e12 in all three orders.
  TriangleCorners corners;
  corners << 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.5, 1e-4, 0.0;
  auto element = shell_element_stiffness(corners, test_material(), BendingElement::rao);
  ASSERT_FALSE(element);
  EXPECT_NE(element.error().message.find("all three node orders"), std::string::npos)
      << element.error().message;
  // DKT has no such restriction.
  EXPECT_TRUE(shell_element_stiffness(corners, test_material(), BendingElement::dkt));
}

TEST(TriangleFrame, FollowsThePapersConvention) {
  TriangleCorners corners;
  corners << 1.0, 1.0, 1.0, 1.0, 3.0, 1.0, 0.0, 2.0, 1.0;
  auto frame = make_triangle_frame(corners);
  ASSERT_TRUE(frame);
  // y along side 1→2, z the normal of (p2−p1)×(p3−p1), x = y × z.
  EXPECT_TRUE(frame->direction_cosines.row(1).isApprox(Eigen::RowVector3d(0, 1, 0)));
  EXPECT_TRUE(frame->direction_cosines.row(2).isApprox(Eigen::RowVector3d(0, 0, 1)));
  EXPECT_TRUE(frame->direction_cosines.row(0).isApprox(Eigen::RowVector3d(1, 0, 0)));
  EXPECT_NEAR(frame->local_xy(1, 1), 2.0, 1e-15);
  EXPECT_NEAR(frame->local_xy(2, 0), -1.0, 1e-15);
  EXPECT_NEAR(frame->local_xy(2, 1), 1.0, 1e-15);
  EXPECT_NEAR(frame->area_m2, 1.0, 1e-15);

  TriangleCorners degenerate;
  degenerate << 0, 0, 0, 1, 0, 0, 2, 0, 0;
  auto bad = make_triangle_frame(degenerate);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("degenerate"), std::string::npos);
}

}  // namespace
}  // namespace trainer::model::offline
