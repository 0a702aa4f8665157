// Test structures for the modal tests, independent of the shell assembly: a spring chain
// with analytic eigenvalues whose rotational dofs are coupled to the translations (so
// condensation has real work to do), and a space frame of 3-D Euler–Bernoulli beams on a
// tube (6 dofs per node, zero rotational mass, like the shell). Plus comparison helpers and
// the conversion of an offline basis to the runtime model's arrays.
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include <Eigen/Dense>
#include <Eigen/SparseCore>

#include "trainer/model/modal_model.hpp"
#include "trainer/model_offline/modal_analysis.hpp"
#include "trainer/model_offline/residual.hpp"
#include "trainer/model_offline/shell_model.hpp"

namespace trainer::model::offline::testing {

// Node-major free numbering of every dof of the nodes not in `fixed_nodes` (all six fixed).
inline DofMap dof_map_with_fixed_nodes(int node_count, const std::vector<int>& fixed_nodes) {
  DofMap dofs;
  dofs.node_count = node_count;
  dofs.free_index.assign(static_cast<std::size_t>(6 * node_count), -1);
  for (int node = 0; node < node_count; ++node) {
    if (std::find(fixed_nodes.begin(), fixed_nodes.end(), node) != fixed_nodes.end()) continue;
    for (int dof = 0; dof < 6; ++dof) {
      dofs.free_index[static_cast<std::size_t>(6 * node + dof)] = dofs.free_count();
      dofs.free_to_node_dof.push_back(6 * node + dof);
    }
  }
  return dofs;
}

struct CoupledChain {
  AssembledShell shell;
  std::vector<double> analytic_omega_squared;  // ascending
};

// Node 0 clamped, nodes 1..N free, mass m on each translation. Along each axis a a
// fixed–free chain of springs k_a, whose eigenvalues are
//   ω_j² = 4 k_a/m sin²((2j − 1)π / (2(2N + 1))), j = 1..N.
// Each node's rotations get an SPD 3×3 stiffness and random couplings to its own and its
// neighbour's translations; K_tt is then built as K_chain + K_tr K_rr⁻¹ K_rt so that the
// condensed matrix (eq. 15–16) is exactly the chain's.
inline CoupledChain coupled_chain(int free_nodes, double mass_kg, const Eigen::Vector3d& k_n_per_m,
                                  unsigned seed) {
  const int n = free_nodes;
  const int nt = 3 * n;
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  Eigen::MatrixXd chain = Eigen::MatrixXd::Zero(nt, nt);  // translational, index 3(i−1)+a
  for (int i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      const int row = 3 * i + a;
      chain(row, row) = (i == n - 1 ? 1.0 : 2.0) * k_n_per_m[a];
      if (i + 1 < n) {
        chain(row, row + 3) = -k_n_per_m[a];
        chain(row + 3, row) = -k_n_per_m[a];
      }
    }
  }
  const double kappa = k_n_per_m.mean() * 1e-4;  // rotational stiffness scale (N·m/rad)
  Eigen::MatrixXd k_rr = Eigen::MatrixXd::Zero(nt, nt);
  Eigen::MatrixXd k_rt = Eigen::MatrixXd::Zero(nt, nt);
  // Couplings of order sqrt(κ k): K_tr K_rr⁻¹ K_rt is then a sizeable fraction of K_chain, so
  // leaving out the condensation would visibly shift the eigenvalues.
  const double coupling = 0.5 * std::sqrt(kappa * k_n_per_m.mean());
  for (int i = 0; i < n; ++i) {
    Eigen::Matrix3d perturbation;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) perturbation(r, c) = uniform(random);
    }
    k_rr.block<3, 3>(3 * i, 3 * i) = kappa * (2.0 * Eigen::Matrix3d::Identity() +
                                              0.3 * (perturbation + perturbation.transpose()));
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        k_rt(3 * i + r, 3 * i + c) = coupling * uniform(random);
        if (i > 0) k_rt(3 * i + r, 3 * (i - 1) + c) = coupling * uniform(random);
      }
    }
  }
  const Eigen::MatrixXd k_tt = chain + k_rt.transpose() * k_rr.ldlt().solve(k_rt);
  CoupledChain result;
  result.shell.dofs = dof_map_with_fixed_nodes(n + 1, {0});
  const int free_count = result.shell.dofs.free_count();
  // Free dof of node i+1 dof d: 6 i + d.
  const auto t = [](int index) { return 6 * (index / 3) + index % 3; };
  const auto r = [](int index) { return 6 * (index / 3) + 3 + index % 3; };
  Eigen::MatrixXd full = Eigen::MatrixXd::Zero(free_count, free_count);
  for (int a = 0; a < nt; ++a) {
    for (int b = 0; b < nt; ++b) {
      full(t(a), t(b)) = k_tt(a, b);
      full(r(a), r(b)) = k_rr(a, b);
      full(r(a), t(b)) = k_rt(a, b);
      full(t(b), r(a)) = k_rt(a, b);
    }
  }
  result.shell.stiffness = full.sparseView(0.0, 0.0);
  result.shell.lumped_mass = Eigen::VectorXd::Zero(free_count);
  for (int a = 0; a < nt; ++a) result.shell.lumped_mass[t(a)] = mass_kg;
  for (int a = 0; a < 3; ++a) {
    for (int j = 1; j <= n; ++j) {
      const double s = std::sin((2.0 * j - 1.0) * std::numbers::pi / (2.0 * (2.0 * n + 1.0)));
      result.analytic_omega_squared.push_back(4.0 * k_n_per_m[a] / mass_kg * s * s);
    }
  }
  std::sort(result.analytic_omega_squared.begin(), result.analytic_omega_squared.end());
  return result;
}

// 12×12 stiffness of a 3-D Euler–Bernoulli beam from a to b (global frame), section: solid
// circle of radius `section_radius_m`; local y is the component of `reference` normal to
// the axis. Dof order per node: ux uy uz rx ry rz.
inline Eigen::Matrix<double, 12, 12> beam_stiffness(const Eigen::Vector3d& a,
                                                    const Eigen::Vector3d& b,
                                                    const Eigen::Vector3d& reference,
                                                    double young_modulus_pa, double poisson_ratio,
                                                    double section_radius_m) {
  const double length = (b - a).norm();
  const double area = std::numbers::pi * std::pow(section_radius_m, 2);
  const double inertia = std::numbers::pi * std::pow(section_radius_m, 4) / 4.0;
  const double torsion = 2.0 * inertia;
  const double shear_modulus = young_modulus_pa / (2.0 * (1.0 + poisson_ratio));
  const double e = young_modulus_pa;
  const double l = length;
  Eigen::Matrix<double, 12, 12> k = Eigen::Matrix<double, 12, 12>::Zero();
  const auto set = [&k](int i, int j, double value) {
    k(i, j) = value;
    k(j, i) = value;
  };
  set(0, 0, e * area / l);
  set(6, 6, e * area / l);
  set(0, 6, -e * area / l);
  set(3, 3, shear_modulus * torsion / l);
  set(9, 9, shear_modulus * torsion / l);
  set(3, 9, -shear_modulus * torsion / l);
  const double b12 = 12.0 * e * inertia / (l * l * l);
  const double b6 = 6.0 * e * inertia / (l * l);
  const double b4 = 4.0 * e * inertia / l;
  const double b2 = 2.0 * e * inertia / l;
  // clang-format off
  // Bending in the local x–y plane (v, θz).
  set(1, 1, b12);  set(1, 5, b6);   set(1, 7, -b12); set(1, 11, b6);
  set(5, 5, b4);   set(5, 7, -b6);  set(5, 11, b2);
  set(7, 7, b12);  set(7, 11, -b6); set(11, 11, b4);
  // Bending in the local x–z plane (w, θy): θy = −dw/dx flips the coupling signs.
  set(2, 2, b12);  set(2, 4, -b6);  set(2, 8, -b12); set(2, 10, -b6);
  set(4, 4, b4);   set(4, 8, b6);   set(4, 10, b2);
  set(8, 8, b12);  set(8, 10, b6);  set(10, 10, b4);
  // clang-format on
  const Eigen::Vector3d x_axis = (b - a) / length;
  const Eigen::Vector3d y_axis = (reference - reference.dot(x_axis) * x_axis).normalized();
  const Eigen::Vector3d z_axis = x_axis.cross(y_axis);
  Eigen::Matrix3d lambda;
  lambda.row(0) = x_axis.transpose();
  lambda.row(1) = y_axis.transpose();
  lambda.row(2) = z_axis.transpose();
  Eigen::Matrix<double, 12, 12> transform = Eigen::Matrix<double, 12, 12>::Zero();
  for (int block = 0; block < 4; ++block) transform.block<3, 3>(3 * block, 3 * block) = lambda;
  return transform.transpose() * k * transform;
}

struct FrameTube {
  AssembledShell shell;
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> nodes;  // m
};

// A space frame on a tube along +x: `rings` × `segments` nodes (ring 0 clamped), beams along
// the axis, around the circumference and along one diagonal per quad. `jitter` moves every
// node by up to that fraction of the ring spacing (seeded) to split the symmetric mode pairs.
// `clamped = false` leaves the frame free (six rigid-body modes).
inline FrameTube frame_tube(int rings, int segments, double jitter, unsigned seed = 1,
                            bool clamped = true) {
  const double radius_m = 4e-3;
  const double length_m = 30e-3;
  const double young_modulus_pa = 2e6;
  const double poisson_ratio = 0.45;
  const double section_radius_m = 0.4e-3;
  const double node_mass_kg = 1e-4;
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  const int node_count = rings * segments;
  const double spacing = length_m / (rings - 1);
  FrameTube tube;
  tube.nodes.resize(node_count, 3);
  for (int ring = 0; ring < rings; ++ring) {
    for (int segment = 0; segment < segments; ++segment) {
      const double angle = 2.0 * std::numbers::pi * segment / segments;
      Eigen::Vector3d point(ring * spacing, radius_m * std::cos(angle), radius_m * std::sin(angle));
      if (ring > 0) {
        point +=
            jitter * spacing * Eigen::Vector3d(uniform(random), uniform(random), uniform(random));
      }
      tube.nodes.row(ring * segments + segment) = point.transpose();
    }
  }
  std::vector<int> fixed_nodes;
  for (int segment = 0; clamped && segment < segments; ++segment) fixed_nodes.push_back(segment);
  tube.shell.dofs = dof_map_with_fixed_nodes(node_count, fixed_nodes);
  const DofMap& dofs = tube.shell.dofs;
  std::vector<Eigen::Triplet<double>> triplets;
  const auto add_beam = [&](int a, int b) {
    const Eigen::Vector3d pa = tube.nodes.row(a).transpose();
    const Eigen::Vector3d pb = tube.nodes.row(b).transpose();
    Eigen::Vector3d radial = 0.5 * (pa + pb);
    radial.x() = 0.0;
    const Eigen::Matrix<double, 12, 12> k =
        beam_stiffness(pa, pb, radial, young_modulus_pa, poisson_ratio, section_radius_m);
    const int node_of[2] = {a, b};
    for (int i = 0; i < 12; ++i) {
      const int fi = dofs.free_index[static_cast<std::size_t>(6 * node_of[i / 6] + i % 6)];
      if (fi < 0) continue;
      for (int j = 0; j < 12; ++j) {
        const int fj = dofs.free_index[static_cast<std::size_t>(6 * node_of[j / 6] + j % 6)];
        if (fj >= 0) triplets.emplace_back(fi, fj, k(i, j));
      }
    }
  };
  for (int ring = 0; ring < rings; ++ring) {
    for (int segment = 0; segment < segments; ++segment) {
      const int here = ring * segments + segment;
      const int next_around = ring * segments + (segment + 1) % segments;
      add_beam(here, next_around);
      if (ring + 1 < rings) {
        add_beam(here, here + segments);
        add_beam(here, (ring + 1) * segments + (segment + 1) % segments);
      }
    }
  }
  const int free_count = dofs.free_count();
  tube.shell.stiffness.resize(free_count, free_count);
  tube.shell.stiffness.setFromTriplets(triplets.begin(), triplets.end());
  tube.shell.lumped_mass = Eigen::VectorXd::Zero(free_count);
  for (int f = 0; f < free_count; ++f) {
    if (dofs.free_to_node_dof[static_cast<std::size_t>(f)] % 6 < 3)
      tube.shell.lumped_mass[f] = node_mass_kg;
  }
  return tube;
}

// Translational lumped mass per node row (3n), zero at fixed dofs.
inline Eigen::VectorXd node_row_mass(const AssembledShell& shell) {
  Eigen::VectorXd mass = Eigen::VectorXd::Zero(3 * shell.dofs.node_count);
  for (int f = 0; f < shell.dofs.free_count(); ++f) {
    const int node_dof = shell.dofs.free_to_node_dof[static_cast<std::size_t>(f)];
    if (node_dof % 6 < 3) mass[node_dof / 6 * 3 + node_dof % 6] = shell.lumped_mass[f];
  }
  return mass;
}

// Largest mismatch between two bases' shapes over their first `count` modes (0 = all): modes
// with a distinct eigenvalue are compared up to sign (relative 2-norm); a cluster of
// eigenvalues closer than `cluster_tolerance` (relative) spans an eigenspace in which any
// M-orthonormal basis is valid, so its two bases are compared by how far the singular values
// of Φ_aᵀ M Φ_b are from 1. A cluster touching the last computed mode may continue beyond it
// and is skipped unless the basis holds every mode (`complete`): compute one mode more than
// `count`.
inline double shape_mismatch(const ModalBasis& a, const ModalBasis& b, const Eigen::VectorXd& mass,
                             int count = 0, bool complete = false, int* compared_modes = nullptr,
                             double cluster_tolerance = 1e-6) {
  double worst = 0.0;
  if (compared_modes != nullptr) *compared_modes = 0;
  const int available = std::min(a.mode_count(), b.mode_count());
  const int compared = count == 0 ? available : std::min(count, available);
  int first = 0;
  while (first < compared) {
    int last = first + 1;
    while (last < available && std::abs(a.omega_squared[last] - a.omega_squared[last - 1]) <
                                   cluster_tolerance * a.omega_squared[last]) {
      ++last;
    }
    if (last == available && !complete) break;
    if (last - first == 1) {
      const Eigen::VectorXd pa = a.node_shapes.col(first);
      const Eigen::VectorXd pb = b.node_shapes.col(first);
      worst = std::max(worst, std::min((pa - pb).norm(), (pa + pb).norm()) / pa.norm());
    } else {
      const Eigen::MatrixXd overlap = a.node_shapes.middleCols(first, last - first).transpose() *
                                      mass.asDiagonal() *
                                      b.node_shapes.middleCols(first, last - first);
      Eigen::JacobiSVD<Eigen::MatrixXd> svd(overlap);
      worst = std::max(worst, (svd.singularValues().array() - 1.0).abs().maxCoeff());
    }
    if (compared_modes != nullptr) *compared_modes = last;
    first = last;
  }
  return worst;
}

// The arrays of a model image built from an offline basis (float, row-major), viewed by
// ModalModelData — what the image writer and loader will do.
struct RuntimeArrays {
  std::uint32_t node_count = 0;
  std::uint32_t mode_count = 0;
  std::vector<float> rest_positions;
  std::vector<float> mode_shapes;
  std::vector<float> omega_squared;
  std::vector<float> modal_damping;
  std::vector<std::uint32_t> surface_nodes;
  std::vector<float> residual_compliance;

  ModalModelData data() const {
    return {node_count,    mode_count,    rest_positions, mode_shapes,
            omega_squared, modal_damping, surface_nodes,  residual_compliance};
  }
};

inline RuntimeArrays to_runtime(const ModalBasis& basis, const Eigen::VectorXd& damping,
                                const ResidualCompliance* residual) {
  RuntimeArrays arrays;
  arrays.node_count = static_cast<std::uint32_t>(basis.node_count);
  arrays.mode_count = static_cast<std::uint32_t>(basis.mode_count());
  arrays.rest_positions.assign(static_cast<std::size_t>(3 * basis.node_count), 0.0F);
  for (Eigen::Index row = 0; row < basis.node_shapes.rows(); ++row) {
    for (Eigen::Index mode = 0; mode < basis.node_shapes.cols(); ++mode) {
      arrays.mode_shapes.push_back(static_cast<float>(basis.node_shapes(row, mode)));
    }
  }
  for (Eigen::Index mode = 0; mode < basis.node_shapes.cols(); ++mode) {
    arrays.omega_squared.push_back(static_cast<float>(basis.omega_squared[mode]));
    arrays.modal_damping.push_back(static_cast<float>(damping[mode]));
  }
  if (residual != nullptr) {
    for (const int node : residual->nodes)
      arrays.surface_nodes.push_back(static_cast<std::uint32_t>(node));
    for (Eigen::Index row = 0; row < residual->compliance.rows(); ++row) {
      for (Eigen::Index column = 0; column < residual->compliance.cols(); ++column) {
        arrays.residual_compliance.push_back(static_cast<float>(residual->compliance(row, column)));
      }
    }
  }
  return arrays;
}

}  // namespace trainer::model::offline::testing
