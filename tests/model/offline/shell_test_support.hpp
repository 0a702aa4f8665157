// Helpers shared by the offline shell tests: a small dense assembler over the element
// matrices (for patch tests that prescribe non-zero displacements, which the production
// assembly's elimination of fixed dofs does not do), rigid-body vectors and random frames.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include <random>
#include <string>
#include <vector>

#include "trainer/model_offline/shell_element.hpp"
#include "trainer/model_offline/shell_model.hpp"

namespace trainer::model::offline::test {

// The parameterised tests' names: "Dkt" or "Rao".
inline std::string element_test_name(const ::testing::TestParamInfo<BendingElement>& element) {
  return element.param == BendingElement::dkt ? "Dkt" : "Rao";
}

// Dense 6n × 6n global stiffness from shell_element_stiffness() (fails the test on error).
inline Eigen::MatrixXd dense_stiffness(const ShellMesh& mesh, const ShellMaterial& material,
                                       BendingElement bending) {
  const Eigen::Index size = mesh.nodes.rows() * kShellDofsPerNode;
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(size, size);
  for (Eigen::Index t = 0; t < mesh.triangles.rows(); ++t) {
    TriangleCorners corners;
    for (int c = 0; c < 3; ++c) corners.row(c) = mesh.nodes.row(mesh.triangles(t, c));
    auto element = shell_element_stiffness(corners, material, bending);
    if (!element) throw std::runtime_error(element.error().message);
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) {
        k.block<6, 6>(mesh.triangles(t, a) * kShellDofsPerNode,
                      mesh.triangles(t, b) * kShellDofsPerNode) +=
            element->block<6, 6>(6 * a, 6 * b);
      }
    }
  }
  return k;
}

// Solves K u = 0 with u prescribed on `prescribed` dofs (entries of `u` there), the rest free.
inline Eigen::VectorXd solve_prescribed(const Eigen::MatrixXd& k,
                                        const std::vector<bool>& prescribed, Eigen::VectorXd u) {
  std::vector<Eigen::Index> free_dofs;
  std::vector<Eigen::Index> fixed_dofs;
  for (Eigen::Index i = 0; i < k.rows(); ++i) {
    (prescribed[static_cast<std::size_t>(i)] ? fixed_dofs : free_dofs).push_back(i);
  }
  const auto nf = static_cast<Eigen::Index>(free_dofs.size());
  const auto np = static_cast<Eigen::Index>(fixed_dofs.size());
  Eigen::MatrixXd kff(nf, nf), kfp(nf, np);
  Eigen::VectorXd up(np);
  for (Eigen::Index i = 0; i < nf; ++i) {
    for (Eigen::Index j = 0; j < nf; ++j)
      kff(i, j) = k(free_dofs[static_cast<std::size_t>(i)], free_dofs[static_cast<std::size_t>(j)]);
    for (Eigen::Index j = 0; j < np; ++j)
      kfp(i, j) =
          k(free_dofs[static_cast<std::size_t>(i)], fixed_dofs[static_cast<std::size_t>(j)]);
  }
  for (Eigen::Index j = 0; j < np; ++j) up(j) = u(fixed_dofs[static_cast<std::size_t>(j)]);
  const Eigen::VectorXd uf = kff.ldlt().solve(-kfp * up);
  for (Eigen::Index i = 0; i < nf; ++i) u(free_dofs[static_cast<std::size_t>(i)]) = uf(i);
  return u;
}

// Rigid motion of 3 nodes as an 18-vector: translation t plus rotation ω about the origin.
inline Eigen::Matrix<double, 18, 1> rigid_motion(const TriangleCorners& corners,
                                                 const Eigen::Vector3d& translation,
                                                 const Eigen::Vector3d& rotation) {
  Eigen::Matrix<double, 18, 1> r;
  for (int node = 0; node < 3; ++node) {
    const Eigen::Vector3d p = corners.row(node).transpose();
    r.segment<3>(6 * node) = translation + rotation.cross(p);
    r.segment<3>(6 * node + 3) = rotation;
  }
  return r;
}

inline Eigen::Matrix3d random_rotation(std::mt19937& random) {
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Quaterniond q(normal(random), normal(random), normal(random), normal(random));
  return q.normalized().toRotationMatrix();
}

inline ShellMaterial test_material(double young_pa = 2.0e11, double poisson = 0.3,
                                   double thickness_m = 0.01, double density = 7800.0) {
  return ShellMaterial{young_pa, poisson, thickness_m, density};
}

}  // namespace trainer::model::offline::test
