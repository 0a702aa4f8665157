// Synthetic reduced-modal models for the runtime modal tests, in either stored precision: the
// arrays a loaded image (float) or an in-memory build (double) would hold, random but seeded,
// and an independent double-precision NIRMS written out again for the models to be compared
// against. A double model rounded to float (rounded_to_float) is the same model as the
// appliance would store it, so float and double runtimes can be run on one model.
#pragma once

#include <cstdint>
#include <numbers>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include <Eigen/Core>

#include "trainer/core/arena.hpp"

#include "trainer/model/modal_model.hpp"

namespace trainer::model {

// A 1 MiB arena for one test's models.
inline core::Arena make_arena() {
  auto arena = core::Arena::create(1 << 20);
  EXPECT_TRUE(arena.has_value());
  return std::move(arena).value();
}

// Owns the arrays a BasicModalModelData views (as a loaded model image would).
template <typename Scalar>
struct SyntheticModalModel {
  std::uint32_t node_count = 0;
  std::uint32_t mode_count = 0;
  std::vector<Scalar> rest_positions;
  std::vector<Scalar> mode_shapes;  // 3n × r row-major
  std::vector<Scalar> omega_squared;
  std::vector<Scalar> modal_damping;
  std::vector<std::uint32_t> surface_nodes;
  std::vector<Scalar> residual_compliance;

  BasicModalModelData<Scalar> data() const {
    return {node_count,    mode_count,    rest_positions, mode_shapes,
            omega_squared, modal_damping, surface_nodes,  residual_compliance};
  }
  Scalar shape(std::uint32_t node, int axis, std::uint32_t mode) const {
    return mode_shapes[(node * 3 + static_cast<std::uint32_t>(axis)) * mode_count + mode];
  }
};

// One node, one mode moving along x with unit modal mass: the single-dof oscillator.
template <typename Scalar>
SyntheticModalModel<Scalar> single_dof(Scalar omega_rad_per_s, Scalar alpha_per_s) {
  SyntheticModalModel<Scalar> model;
  model.node_count = 1;
  model.mode_count = 1;
  model.rest_positions = {Scalar{0}, Scalar{0}, Scalar{0}};
  model.mode_shapes = {Scalar{1}, Scalar{0}, Scalar{0}};
  model.omega_squared = {omega_rad_per_s * omega_rad_per_s};
  model.modal_damping = {alpha_per_s};
  return model;
}

// Random shapes (entries ~N(0, 1)), ω from 2π·5 Hz upwards, damping ratios 2–10 %, and — if
// asked — an SPD residual compliance (A Aᵀ/s + small diagonal) over every node. Drawn in
// Scalar: a double model's values are not float-representable, so rounding it to float
// changes it by float rounding (what an image does to a build).
template <typename Scalar = float>
SyntheticModalModel<Scalar> random_model(std::uint32_t nodes, std::uint32_t modes,
                                         bool with_residual, unsigned seed) {
  std::mt19937 random(seed);
  std::normal_distribution<Scalar> normal(Scalar{0}, Scalar{1});
  std::uniform_real_distribution<Scalar> uniform(Scalar{0}, Scalar{1});
  SyntheticModalModel<Scalar> model;
  model.node_count = nodes;
  model.mode_count = modes;
  for (std::uint32_t i = 0; i < 3 * nodes; ++i)
    model.rest_positions.push_back(static_cast<Scalar>(0.01) * normal(random));
  for (std::uint32_t i = 0; i < 3 * nodes * modes; ++i) model.mode_shapes.push_back(normal(random));
  Scalar omega = Scalar{2} * std::numbers::pi_v<Scalar> * Scalar{5};
  for (std::uint32_t i = 0; i < modes; ++i) {
    omega *= Scalar{1} + static_cast<Scalar>(0.5) * uniform(random);
    model.omega_squared.push_back(omega * omega);
    const Scalar damping_ratio =
        static_cast<Scalar>(0.02) + static_cast<Scalar>(0.08) * uniform(random);
    model.modal_damping.push_back(Scalar{2} * damping_ratio * omega);
  }
  for (std::uint32_t node = 0; node < nodes; ++node) model.surface_nodes.push_back(node);
  if (with_residual) {
    const std::uint32_t rows = 3 * nodes;
    std::vector<double> a(rows * rows);
    for (auto& value : a) value = static_cast<double>(normal(random));
    model.residual_compliance.resize(rows * rows);
    for (std::uint32_t i = 0; i < rows; ++i) {
      for (std::uint32_t j = 0; j < rows; ++j) {
        double sum = i == j ? 0.1 : 0.0;
        for (std::uint32_t k = 0; k < rows; ++k) sum += a[i * rows + k] * a[j * rows + k];
        // Scale to ~1e-4 m/N, comparable to the modal compliance 1/ω² of these modes.
        model.residual_compliance[i * rows + j] = static_cast<Scalar>(1e-4 * sum / rows);
      }
    }
  }
  return model;
}

// The same model stored in float32, as an image holds a build.
inline SyntheticModalModel<float> rounded_to_float(const SyntheticModalModel<double>& model) {
  const auto round = [](const std::vector<double>& values) {
    std::vector<float> rounded;
    for (const double value : values) rounded.push_back(static_cast<float>(value));
    return rounded;
  };
  SyntheticModalModel<float> result;
  result.node_count = model.node_count;
  result.mode_count = model.mode_count;
  result.rest_positions = round(model.rest_positions);
  result.mode_shapes = round(model.mode_shapes);
  result.omega_squared = round(model.omega_squared);
  result.modal_damping = round(model.modal_damping);
  result.surface_nodes = model.surface_nodes;
  result.residual_compliance = round(model.residual_compliance);
  return result;
}

// Independent double-precision NIRMS (same equations, written out again) on the model's
// stored values, for the runtime models to be compared against. With `static_correction`, a
// surface node's displacement adds R F over the loads of the last step (every node of a
// random_model is a surface node, in order).
template <typename Scalar>
struct DoubleReference {
  using Loads = std::vector<std::pair<std::uint32_t, Eigen::Matrix<Scalar, 3, 1>>>;

  const SyntheticModalModel<Scalar>& model;
  double dt;
  bool static_correction = false;
  std::vector<double> x, v, a;
  Loads last_loads;

  DoubleReference(const SyntheticModalModel<Scalar>& m, double time_step_s,
                  bool with_static_correction = false)
      : model(m),
        dt(time_step_s),
        static_correction(with_static_correction),
        x(m.mode_count),
        v(m.mode_count),
        a(m.mode_count) {}

  void step(const Loads& loads) {
    for (std::uint32_t i = 0; i < model.mode_count; ++i) {
      double f = 0.0;
      for (const auto& [node, force] : loads) {
        for (int b = 0; b < 3; ++b) {
          f += static_cast<double>(model.shape(node, b, i)) * static_cast<double>(force[b]);
        }
      }
      const auto alpha = static_cast<double>(model.modal_damping[i]);
      const double a0 = (4.0 + 2.0 * alpha * dt) / (dt * dt);
      const double a2 = 4.0 / dt + alpha;
      const double next =
          (f + a0 * x[i] + a2 * v[i] + a[i]) / (static_cast<double>(model.omega_squared[i]) + a0);
      const double next_a = 4.0 / (dt * dt) * (next - x[i]) - 4.0 / dt * v[i] - a[i];
      v[i] += dt / 2.0 * (a[i] + next_a);
      a[i] = next_a;
      x[i] = next;
    }
    last_loads = loads;
  }

  double displacement(std::uint32_t node, int axis) const {
    double sum = 0.0;
    for (std::uint32_t i = 0; i < model.mode_count; ++i)
      sum += static_cast<double>(model.shape(node, axis, i)) * x[i];
    return static_correction ? sum + static_displacement(node, axis) : sum;
  }

  // Σ_l R_{node,l} F_l over the last step's loads (m), whether or not it is applied.
  double static_displacement(std::uint32_t node, int axis) const {
    const std::uint32_t rows = 3 * model.node_count;
    const std::uint32_t row = 3 * node + static_cast<std::uint32_t>(axis);
    double sum = 0.0;
    for (const auto& [loaded, force] : last_loads) {
      for (int b = 0; b < 3; ++b) {
        const std::uint32_t column = 3 * loaded + static_cast<std::uint32_t>(b);
        sum += static_cast<double>(model.residual_compliance[row * rows + column]) *
               static_cast<double>(force[b]);
      }
    }
    return sum;
  }
};

}  // namespace trainer::model
