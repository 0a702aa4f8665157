// Catheter::substep's implicit step in double for the trade study's reference chain
// (catheter_reference_substep.hpp).
#include "catheter_reference_substep.hpp"

#include <algorithm>

namespace trainer::model::offline::detail {

namespace {

using Vector = Eigen::Vector3d;
using Matrix = Eigen::Matrix3d;

// Plane states within a substep, as Catheter::update_planes.
struct PlaneState {
  double start = 0.0;        // k d − c v·n at the substep start
  double spring_gain = 0.0;  // h k̃ + c, 0 = explicit for the whole substep
  double gain = 0.0;         // spring_gain while a spring, else 0
  double force = 0.0;        // explicit force, or the spring's start force
};

}  // namespace

void reference_implicit_substep(ReferenceChainState& s, double h, double period_s, double fraction,
                                double hold_step) {
  std::vector<Vector>& positions = *s.positions;
  std::vector<Vector>& velocities = *s.velocities;
  const std::size_t n = positions.size();
  const ChainStiffness<double>& stiffness = *s.stiffness;
  std::vector<Vector> forces(n, Vector::Zero());
  for (std::size_t i = 0; i < n; ++i) forces[i] = s.external_n[i];
  add_chain_forces<double>(positions, stiffness, forces, s.held);
  // Planes at the substep start.
  const Vector& normal = s.wall_normal;
  const double explicit_stiffness = s.mass_kg / (h * h);
  std::vector<PlaneState> planes(s.wall_particles.size());
  for (std::size_t k = 0; k < planes.size(); ++k) {
    const std::size_t i = s.wall_particles[k];
    const double depth = s.radius_m - (positions[i] - s.wall_points_m[k]).dot(normal);
    if (!(depth > 0.0)) continue;
    const double magnitude =
        s.contact.stiffness_n_per_m * depth - s.contact.damping_n_s_per_m * velocities[i].dot(normal);
    PlaneState& plane = planes[k];
    plane.start = magnitude;
    const double implicit_stiffness = s.contact.stiffness_n_per_m - explicit_stiffness;
    if (!(implicit_stiffness > 0.0)) {
      plane.force = std::clamp(magnitude, 0.0, s.contact.max_force_n);
      continue;
    }
    plane.spring_gain = h * implicit_stiffness + s.contact.damping_n_s_per_m;
    if (!(magnitude > 0.0)) continue;
    if (magnitude >= s.contact.max_force_n) {
      plane.force = s.contact.max_force_n;
    } else {
      plane.force = magnitude;
      plane.gain = plane.spring_gain;
    }
  }
  // The matrix's constant part: damped mass, axial Hessian, bending stencil.
  const double l0 = stiffness.rest_length_m;
  const double h2k = h * h * stiffness.axial_n_per_m;
  std::vector<Matrix> chain_diagonal(n, Matrix::Identity() * (s.mass_kg + h * s.damping_n_s_per_m));
  std::vector<Matrix> band1(n > 0 ? n - 1 : 0, Matrix::Zero());
  std::vector<double> band2(n > 1 ? n - 2 : 0, 0.0);
  const double h2_over_l02 = h * h / (l0 * l0);
  for (std::size_t i = 1; i + 1 < n; ++i) {
    const double c = h2_over_l02 * hinge_stiffness<double>(stiffness, s.held, i);
    chain_diagonal[i - 1].diagonal().array() += c;
    chain_diagonal[i].diagonal().array() += 4.0 * c;
    chain_diagonal[i + 1].diagonal().array() += c;
    band1[i - 1].diagonal().array() -= 2.0 * c;
    band1[i].diagonal().array() -= 2.0 * c;
    band2[i - 1] += c;
  }
  if (stiffness.root_clamped) {
    const double c = h2_over_l02 * 2.0 * stiffness.bending_n_m_per_rad;
    chain_diagonal[0].diagonal().array() += c;
    chain_diagonal[1].diagonal().array() += c;
    band1[0].diagonal().array() -= c;
  }
  for (std::size_t seg = 0; seg + 1 < n; ++seg) {
    const Vector segment = positions[seg + 1] - positions[seg];
    const double length = segment.norm();
    if (!(length > 0.0)) continue;
    const Vector unit = segment / length;
    const double g = std::clamp(1.0 - l0 / length, 0.0, 1.0);
    Matrix block = (h2k * (1.0 - g)) * (unit * unit.transpose());
    block.diagonal().array() += h2k * g;
    chain_diagonal[seg] += block;
    chain_diagonal[seg + 1] += block;
    band1[seg] -= block;
  }
  std::vector<Matrix> diagonal(n), inverse(n), lower(n);
  std::vector<Vector> contact(n), solution(n);
  const auto solve = [&] {
    diagonal = chain_diagonal;
    for (std::size_t i = 0; i < n; ++i) contact[i].setZero();
    for (std::size_t k = 0; k < planes.size(); ++k) {
      const std::size_t i = s.wall_particles[k];
      double magnitude = planes[k].force;
      if (planes[k].gain != 0.0) {
        magnitude += s.contact.damping_n_s_per_m * velocities[i].dot(normal);
        diagonal[i] += (h * planes[k].gain) * (normal * normal.transpose());
      }
      contact[i] += magnitude * normal;
    }
    for (std::size_t i = 0; i < n; ++i) {
      solution[i] = s.held[i] != 0 ? Vector((s.targets_m[i] - s.saved_positions_m[i]) / period_s)
                                   : Vector(s.mass_kg * velocities[i] + h * (forces[i] + contact[i]));
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (s.held[i] == 0) continue;
      const Vector v = solution[i];
      if (i >= 1 && s.held[i - 1] == 0) solution[i - 1] -= band1[i - 1] * v;
      if (i + 1 < n && s.held[i + 1] == 0) solution[i + 1] -= band1[i] * v;
      if (i >= 2 && s.held[i - 2] == 0) solution[i - 2] -= band2[i - 2] * v;
      if (i + 2 < n && s.held[i + 2] == 0) solution[i + 2] -= band2[i] * v;
    }
    Matrix previous_g = Matrix::Zero();
    for (std::size_t i = 0; i < n; ++i) {
      if (s.held[i] != 0) {
        inverse[i].setIdentity();
        lower[i].setZero();
        previous_g.setZero();
        continue;
      }
      Matrix d = diagonal[i];
      Vector y = solution[i];
      Matrix g = Matrix::Zero();
      double alpha = 0.0;
      const bool second = i >= 2 && s.held[i - 2] == 0 && band2[i - 2] != 0.0;
      if (second) {
        alpha = band2[i - 2];
        d -= (alpha * alpha) * inverse[i - 2];
        y -= alpha * (inverse[i - 2] * solution[i - 2]);
      }
      if (i >= 1 && s.held[i - 1] == 0) {
        g = band1[i - 1];
        if (second) g -= alpha * (inverse[i - 2] * previous_g.transpose());
        const Matrix l = g * inverse[i - 1];
        d -= l * g.transpose();
        y -= l * solution[i - 1];
        lower[i] = l;
      } else {
        lower[i].setZero();
      }
      previous_g = g;
      inverse[i] = d.inverse();
      solution[i] = y;
    }
    for (std::size_t k = n; k-- > 0;) {
      if (s.held[k] != 0) continue;
      Vector x = inverse[k] * solution[k];
      if (k + 1 < n && s.held[k + 1] == 0) x -= lower[k + 1].transpose() * solution[k + 1];
      if (k + 2 < n && s.held[k + 2] == 0 && band2[k] != 0.0) x -= band2[k] * (inverse[k] * solution[k + 2]);
      solution[k] = x;
    }
  };
  const auto end_force = [&](std::size_t k) {
    const std::size_t i = s.wall_particles[k];
    return planes[k].start + s.contact.damping_n_s_per_m * velocities[i].dot(normal) -
           planes[k].spring_gain * solution[i].dot(normal);
  };
  constexpr int kPlanePasses = 6;
  for (int pass = 0;; ++pass) {
    solve();
    if (pass + 1 == kPlanePasses) break;
    bool changed = false;
    for (std::size_t k = 0; k < planes.size(); ++k) {
      PlaneState& plane = planes[k];
      if (plane.spring_gain == 0.0) continue;
      const bool spring = plane.gain != 0.0;
      const bool clamped = !spring && plane.force == s.contact.max_force_n;
      if (!spring && !clamped) continue;
      const double f = end_force(k);
      if (spring && f > s.contact.max_force_n) {
        plane.gain = 0.0;
        plane.force = s.contact.max_force_n;
        changed = true;
      } else if (spring && f < 0.0) {
        plane.gain = 0.0;
        plane.force = 0.0;
        changed = true;
      } else if (clamped && f < s.contact.max_force_n) {
        plane.gain = plane.spring_gain;
        plane.force = plane.start;
        changed = true;
      }
    }
    if (!changed) break;
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (s.held[i] != 0) {
      Vector implicit = diagonal[i] * solution[i] - s.mass_kg * solution[i];
      if (i >= 1) implicit += band1[i - 1] * solution[i - 1];
      if (i + 1 < n) implicit += band1[i] * solution[i + 1];
      if (i >= 2) implicit += band2[i - 2] * solution[i - 2];
      if (i + 2 < n) implicit += band2[i] * solution[i + 2];
      s.hold_forces_n[i] += fraction * (forces[i] + contact[i] - implicit / h);
      const Vector start = s.saved_positions_m[i];
      positions[i] = hold_step >= 1.0 ? s.targets_m[i] : Vector(start + hold_step * (s.targets_m[i] - start));
      velocities[i] = (s.targets_m[i] - start) / period_s;
      continue;
    }
    velocities[i] = solution[i];
    positions[i] += h * velocities[i];
  }
}

}  // namespace trainer::model::offline::detail
