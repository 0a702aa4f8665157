#include "trainer/model_offline/modal_accuracy.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "trainer/core/arena.hpp"
#include "trainer/model/modal_model.hpp"
#include "trainer/model_offline/dnios.hpp"

namespace trainer::model::offline {

namespace {

using Clock = std::chrono::steady_clock;

double median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

int nearest_surface_node(const ModalBuildSpec& spec, const ModalBuildResult& build,
                         const Eigen::Vector3d& point) {
  int best = -1;
  double best_distance = std::numeric_limits<double>::infinity();
  for (int node : build.surface_nodes) {
    const double d = (spec.mesh.nodes.row(node).transpose() - point).norm();
    if (d < best_distance) {
      best_distance = d;
      best = node;
    }
  }
  return best;
}

double ramp(double t, double ramp_s) {
  return ramp_s > 0.0 ? std::min(1.0, t / ramp_s) : 1.0;
}

}  // namespace

core::Expected<std::vector<AccuracyPoint>> measure_modal_accuracy(
    const ModalBuildSpec& spec, const ModalBuildResult& build, std::span<const int> mode_counts,
    const AccuracyScenario& scenario) {
  const int load_node = nearest_surface_node(spec, build, scenario.load_point_m);
  if (load_node < 0) return core::make_error("accuracy: the model has no surface node");
  const double dt = spec.time_step_s;
  const int steps = static_cast<int>(std::lround(scenario.duration_s / dt));
  const auto node_count = static_cast<std::uint32_t>(spec.mesh.nodes.rows());

  // Reference history (double, every dof).
  auto reference = FullNewmark::create(build.shell, build.rayleigh, dt);
  if (!reference) return std::move(reference).error();
  std::vector<Eigen::Vector3d> reference_local;
  std::vector<Eigen::VectorXd> reference_field;
  std::vector<double> reference_times;
  for (int step = 1; step <= steps; ++step) {
    const double t = step * dt;
    const auto start = Clock::now();
    reference->clear_forces();
    if (auto added =
            reference->add_node_force(load_node, ramp(t, scenario.ramp_s) * scenario.force_n);
        !added) {
      return std::move(added).error();
    }
    reference->step();
    const Eigen::Vector3d local = reference->displacement(load_node);
    reference_times.push_back(
        std::chrono::duration<double, std::nano>(Clock::now() - start).count());
    reference_local.push_back(local);
    reference_field.push_back(reference->translational_field());
  }
  double reference_local_max = 0.0;
  double reference_field_sq = 0.0;
  for (int step = 0; step < steps; ++step) {
    reference_local_max =
        std::max(reference_local_max, reference_local[static_cast<std::size_t>(step)].norm());
    reference_field_sq += reference_field[static_cast<std::size_t>(step)].squaredNorm();
  }
  if (!(reference_local_max > 0.0)) return core::make_error("accuracy: the reference did not move");

  const FloatModalData data(spec, build);
  const auto stored = static_cast<std::uint32_t>(build.basis.mode_count());
  std::vector<AccuracyPoint> points;
  std::vector<float> field(3 * static_cast<std::size_t>(node_count));
  for (int modes : mode_counts) {
    if (modes <= 0 || modes > static_cast<int>(stored)) {
      return core::make_error("accuracy: " + std::to_string(modes) +
                              " modes requested, the build has " + std::to_string(stored));
    }
    for (bool correction : {false, true}) {
      if (correction && !build.residual) continue;
      auto arena = core::Arena::create(std::size_t{1} << 20);
      if (!arena) return std::move(arena).error();
      model::ModalSettings settings;
      settings.time_step_s = static_cast<float>(dt);
      settings.active_modes = static_cast<std::uint32_t>(modes);
      settings.static_correction = correction;
      auto modal = model::ModalModel::create(data.view(), *arena, settings);
      if (!modal) return std::move(modal).error();

      AccuracyPoint point;
      point.scenario = scenario.name;
      point.load_node = load_node;
      point.modes = modes;
      point.static_correction = correction;
      std::vector<double> times;
      double local_error_max = 0.0;
      double field_error_sq = 0.0;
      for (int step = 1; step <= steps; ++step) {
        const double t = step * dt;
        const Eigen::Vector3f force = (ramp(t, scenario.ramp_s) * scenario.force_n).cast<float>();
        const auto start = Clock::now();
        modal->clear_forces();
        (void)modal->add_node_force(static_cast<std::uint32_t>(load_node), force);
        (void)modal->step();
        const Eigen::Vector3f local = modal->displacement(static_cast<std::uint32_t>(load_node));
        times.push_back(std::chrono::duration<double, std::nano>(Clock::now() - start).count());

        const auto index = static_cast<std::size_t>(step - 1);
        const double local_error = (local.cast<double>() - reference_local[index]).norm();
        local_error_max = std::max(local_error_max, local_error);
        if (step == steps)
          point.final_local_error = local_error / std::max(reference_local[index].norm(), 1e-300);
        // Field: every node's displacement as the runtime reports it (with R·F where corrected).
        for (std::uint32_t node = 0; node < node_count; ++node) {
          const Eigen::Vector3f u = modal->displacement(node);
          for (int axis = 0; axis < 3; ++axis) {
            const double diff = static_cast<double>(u[axis]) -
                                reference_field[index](static_cast<Eigen::Index>(node) * 3 + axis);
            field_error_sq += diff * diff;
          }
        }
      }
      point.local_error = local_error_max / reference_local_max;
      point.field_error = std::sqrt(field_error_sq / reference_field_sq);
      point.modal_step_ns = median(times);
      point.reference_step_ns = median(reference_times);
      point.speedup = point.reference_step_ns / point.modal_step_ns;
      points.push_back(point);
    }
  }
  return points;
}

}  // namespace trainer::model::offline
