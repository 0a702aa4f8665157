#include "trainer/model_offline/modal_tradeoff.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>

#include <Eigen/Geometry>

#include "trainer/core/arena.hpp"
#include "trainer/model/modal_model.hpp"
#include "trainer/model_offline/dnios.hpp"
#include "cycle_cost_summary.hpp"

namespace trainer::model::offline {

namespace {

using cycle_cost::Clock;
using cycle_cost::nanoseconds;
using cycle_cost::percentile;

// Area-weighted vertex normal of `node`, oriented towards the mesh's centroid (inward for a
// tube or any shell around its centroid).
Eigen::Vector3d inward_normal(const ShellMesh& mesh, int node) {
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  for (Eigen::Index t = 0; t < mesh.triangles.rows(); ++t) {
    const auto tri = mesh.triangles.row(t);
    if (tri(0) != node && tri(1) != node && tri(2) != node) continue;
    const Eigen::Vector3d a = mesh.nodes.row(tri(0)).transpose();
    const Eigen::Vector3d b = mesh.nodes.row(tri(1)).transpose();
    const Eigen::Vector3d c = mesh.nodes.row(tri(2)).transpose();
    normal += (b - a).cross(c - a);  // twice the area times the unit normal
  }
  if (normal.norm() == 0.0) return normal;
  normal.normalize();
  const Eigen::Vector3d centroid = mesh.nodes.colwise().mean().transpose();
  const Eigen::Vector3d to_centroid = centroid - mesh.nodes.row(node).transpose();
  return normal.dot(to_centroid) < 0.0 ? Eigen::Vector3d(-normal) : normal;
}

int nearest_node(const ShellMesh& mesh, const std::vector<int>& candidates,
                 const Eigen::Vector3d& point) {
  int best = -1;
  double best_distance = std::numeric_limits<double>::infinity();
  for (int node : candidates) {
    const double d = (mesh.nodes.row(node).transpose() - point).squaredNorm();
    if (d < best_distance) {
      best_distance = d;
      best = node;
    }
  }
  return best;
}

core::Expected<int> steps_for(const ContactScenario& scenario, double time_step_s) {
  const double steps = scenario.duration_s() / time_step_s;
  if (!(steps >= 1.0) || std::abs(steps - std::round(steps)) > 1e-6) {
    return core::make_error("scenario '" + scenario.name + "': duration " +
                            std::to_string(scenario.duration_s()) +
                            " s is not a whole number of steps of " +
                            std::to_string(time_step_s) + " s");
  }
  return static_cast<int>(std::lround(steps));
}

// The reference force at time t (linear between its samples at (k + 1) Δt_ref; zero at 0).
Eigen::Vector3d reference_force_at(const std::vector<Eigen::Vector3d>& forces,
                                   double time_step_s, double t) {
  const double position = t / time_step_s - 1.0;
  if (position <= -1.0) return Eigen::Vector3d::Zero();
  const auto last = static_cast<double>(forces.size() - 1);
  const double clamped = std::min(position, last);
  const auto lower = static_cast<std::ptrdiff_t>(std::floor(clamped));
  const double fraction = clamped - static_cast<double>(lower);
  const Eigen::Vector3d before =
      lower < 0 ? Eigen::Vector3d::Zero() : forces[static_cast<std::size_t>(lower)];
  if (fraction <= 0.0 || lower + 1 > static_cast<std::ptrdiff_t>(last)) return before;
  return (1.0 - fraction) * before + fraction * forces[static_cast<std::size_t>(lower + 1)];
}

// The reference's force with its two-step ringing removed: average-acceleration Newmark has no
// algorithmic damping, so where the displacement is imposed (and on the massless rotations)
// the stiff, physically overdamped high modes of the full mesh keep a step-to-step alternation
// (v_{n+1} = 2 Δu/Δt − v_n once Δu = 0, and then a_{n+1} = −a_n − a2 v_n: an alternation
// (−1)^n (A + B n) growing linearly after any kink in the imposed motion) that can exceed the
// force itself. The centred [1 2 1]/4 average removes (−1)^n (A + B n) exactly (the test
// DniosImposed.ReachesTheTargetAndHoldsItWithTheStaticForce checks it) and, centred, adds no lag;
// its smoothing error is O(Δt_ref²) on the physical signal. The runtime model is compared raw:
// ringing it shows is an error the user would feel.
// `forces` holds one sample beyond the scenario (dropped here) so the last kept sample is
// centred too; before the first sample the force is zero (rest, nothing imposed at t = 0).
std::vector<Eigen::Vector3d> smooth_nyquist(std::vector<Eigen::Vector3d> forces) {
  const std::size_t count = forces.size();
  if (count < 2) return forces;
  Eigen::Matrix3Xd raw(3, static_cast<Eigen::Index>(count));
  for (std::size_t k = 0; k < count; ++k) raw.col(static_cast<Eigen::Index>(k)) = forces[k];
  forces.pop_back();
  forces.front() = 0.25 * (2.0 * raw.col(0) + raw.col(1));
  for (Eigen::Index k = 1; k + 1 < static_cast<Eigen::Index>(count); ++k) {
    forces[static_cast<std::size_t>(k)] = 0.25 * (raw.col(k - 1) + 2.0 * raw.col(k) + raw.col(k + 1));
  }
  return forces;
}

std::size_t stored_data_bytes(const ModalBuildSpec& spec, const ModalBuildResult& build,
                              bool static_correction, RuntimePrecision precision) {
  const auto n = static_cast<std::size_t>(spec.mesh.nodes.rows());
  const auto r = static_cast<std::size_t>(build.basis.mode_count());
  const auto s = build.surface_nodes.size();
  std::size_t values = 3 * n * r + 2 * r + 3 * n;
  if (static_correction) values += 9 * s * s;
  return values * (precision == RuntimePrecision::float32 ? sizeof(float) : sizeof(double));
}

}  // namespace

const char* to_string(RuntimePrecision precision) {
  return precision == RuntimePrecision::float32 ? "f32" : "f64";
}

std::string ModalTradeConfig::label() const {
  char buffer[96];
  std::snprintf(buffer, sizeof buffer, "r%d %s %s %s dt%.0fus", modes,
                static_correction ? "sc" : "nosc",
                element == BendingElement::dkt ? "dkt" : "rao", to_string(precision),
                time_step_s * 1e6);
  return buffer;
}

Eigen::Vector3d scenario_target(const ContactScenario& scenario, const Eigen::Vector3d& inward,
                                double time_s) {
  const auto& keys = scenario.keyframes;
  if (keys.empty()) return Eigen::Vector3d::Zero();
  if (time_s <= keys.front().time_s) {
    return keys.front().depth_m * inward + keys.front().drag_m;
  }
  for (std::size_t k = 1; k < keys.size(); ++k) {
    if (time_s <= keys[k].time_s) {
      const double span = keys[k].time_s - keys[k - 1].time_s;
      const double w = span > 0.0 ? (time_s - keys[k - 1].time_s) / span : 1.0;
      const double depth = (1.0 - w) * keys[k - 1].depth_m + w * keys[k].depth_m;
      const Eigen::Vector3d drag = (1.0 - w) * keys[k - 1].drag_m + w * keys[k].drag_m;
      return depth * inward + drag;
    }
  }
  return keys.back().depth_m * inward + keys.back().drag_m;
}

std::vector<ContactScenario> default_duct_scenarios(const ShellMesh& mesh) {
  const Eigen::Vector3d low = mesh.nodes.colwise().minCoeff().transpose();
  const Eigen::Vector3d high = mesh.nodes.colwise().maxCoeff().transpose();
  const Eigen::Vector3d extent = high - low;
  Eigen::Index axis = 0;
  extent.maxCoeff(&axis);
  const auto b = (axis + 1) % 3;
  const auto c = (axis + 2) % 3;
  const double rho = 0.5 * std::min(extent[b], extent[c]);
  // A point on the bounding cylinder: fraction `along` of the length, angle θ around the axis.
  const auto point = [&](double along, double theta_deg) {
    const double theta = theta_deg * M_PI / 180.0;
    Eigen::Vector3d p = 0.5 * (low + high);
    p[axis] = low[axis] + along * extent[axis];
    p[b] += 0.5 * extent[b] * std::cos(theta);
    p[c] += 0.5 * extent[c] * std::sin(theta);
    return p;
  };
  Eigen::Vector3d along_axis = Eigen::Vector3d::Zero();
  along_axis[axis] = 1.0;
  const auto press = [&](std::string name, std::string description, bool tuning, double along,
                         double theta_deg, double depth_fraction, double ramp_s) {
    ContactScenario s;
    s.name = std::move(name);
    s.description = std::move(description);
    s.tuning = tuning;
    s.point_m = point(along, theta_deg);
    s.keyframes = {{0.0, 0.0, Eigen::Vector3d::Zero()},
                   {ramp_s, depth_fraction * rho, Eigen::Vector3d::Zero()},
                   {0.2, depth_fraction * rho, Eigen::Vector3d::Zero()}};
    return s;
  };
  std::vector<ContactScenario> scenarios;
  scenarios.push_back(press("press-mid-top", "mid-length, 0.25 rho deep, 30 ms ramp, hold", true,
                            0.5, 90.0, 0.25, 0.03));
  scenarios.push_back(press("press-end-fast", "near the free end, 0.5 rho deep, 10 ms ramp, hold",
                            true, 0.9, 0.0, 0.5, 0.01));
  scenarios.push_back(press("press-quarter-bottom",
                            "quarter length, 0.35 rho deep, 20 ms ramp, hold", false, 0.3, 270.0,
                            0.35, 0.02));
  scenarios.push_back(press("press-deep", "60 % of the length, 0.7 rho deep, 50 ms ramp, hold",
                            false, 0.6, 200.0, 0.7, 0.05));
  ContactScenario drag = press("press-and-drag",
                               "45 % of the length, 0.25 rho deep in 20 ms, then dragged "
                               "0.3 rho along the axis over 100 ms (the sticking tip), hold",
                               false, 0.45, 90.0, 0.25, 0.02);
  drag.keyframes = {{0.0, 0.0, Eigen::Vector3d::Zero()},
                    {0.02, 0.25 * rho, Eigen::Vector3d::Zero()},
                    {0.12, 0.25 * rho, 0.3 * rho * along_axis},
                    {0.2, 0.25 * rho, 0.3 * rho * along_axis}};
  scenarios.push_back(std::move(drag));
  return scenarios;
}

ModalBuildSpec DuctTradeStudy::spec_for(const ModalTradeConfig& config) const {
  ModalBuildSpec spec = definition_;
  spec.mode_count = config.modes;
  spec.static_correction = config.static_correction;
  spec.bending = config.element;
  spec.time_step_s = config.time_step_s;
  spec.damping_override = damping_;
  return spec;
}

core::Expected<std::shared_ptr<const ModalBuildResult>> DuctTradeStudy::build_for(
    const ModalTradeConfig& config, double* build_s) {
  const auto key = std::make_tuple(static_cast<int>(config.element), config.modes,
                                   config.static_correction);
  auto found = builds_.find(key);
  if (found == builds_.end()) {
    const auto start = Clock::now();
    auto built = build_modal_model(spec_for(config));
    if (!built) return std::move(built).error();
    const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
    found = builds_
                .emplace(key, std::make_pair(std::make_shared<const ModalBuildResult>(
                                                 std::move(*built)),
                                             seconds))
                .first;
  }
  if (build_s != nullptr) *build_s = found->second.second;
  return found->second.first;
}

core::Expected<std::unique_ptr<DuctTradeStudy>> DuctTradeStudy::create(
    ModalBuildSpec definition, std::vector<ContactScenario> scenarios,
    double reference_time_step_s) {
  if (!(reference_time_step_s > 0.0)) {
    return core::make_error("trade study: reference time step " +
                            std::to_string(reference_time_step_s) + " s, expected > 0");
  }
  if (scenarios.empty()) return core::make_error("trade study: no scenarios");
  std::unique_ptr<DuctTradeStudy> study(new DuctTradeStudy());
  study->definition_ = std::move(definition);
  study->scenarios_ = std::move(scenarios);
  study->reference_time_step_s_ = reference_time_step_s;

  const auto start = Clock::now();
  ModalBuildSpec reference_spec = study->definition_;
  reference_spec.static_correction = false;  // the reference needs the assembly and ω_1..ω_r
  auto reference_build = build_modal_model(reference_spec);
  if (!reference_build) return std::move(reference_build).error();
  study->damping_ = reference_build->rayleigh;
  study->reference_build_s_ = std::chrono::duration<double>(Clock::now() - start).count();

  std::vector<double> step_times;
  for (const ContactScenario& scenario : study->scenarios_) {
    auto steps = steps_for(scenario, reference_time_step_s);
    if (!steps) return std::move(steps).error();
    ReferenceHistory history;
    history.contact_node =
        nearest_node(study->definition_.mesh, reference_build->surface_nodes, scenario.point_m);
    if (history.contact_node < 0) return core::make_error("trade study: no surface node");
    history.inward = inward_normal(study->definition_.mesh, history.contact_node);
    auto dnios = FullNewmark::create(reference_build->shell, study->damping_,
                                     reference_time_step_s);
    if (!dnios) return std::move(dnios).error();
    for (int step = 1; step <= *steps + 1; ++step) {  // one beyond the end: see smooth_nyquist
      const double t = step * reference_time_step_s;
      const auto step_start = Clock::now();
      auto force = dnios->step_imposed(history.contact_node,
                                       scenario_target(scenario, history.inward, t));
      step_times.push_back(nanoseconds(Clock::now() - step_start));
      if (!force) return core::make_error("scenario '" + scenario.name + "': " +
                                          force.error().message);
      history.forces.push_back(*force);
    }
    history.forces = smooth_nyquist(std::move(history.forces));
    study->references_.push_back(std::move(history));
  }
  study->reference_step_ns_ = percentile(std::move(step_times), 0.5);
  return study;
}

core::Expected<ModalTradePoint> DuctTradeStudy::measure(const ModalTradeConfig& config,
                                                        const CycleCostOptions& cost_options) {
  const double ratio = config.time_step_s / reference_time_step_s_;
  if (!(ratio >= 1.0 - 1e-9) || std::abs(ratio - std::round(ratio)) > 1e-6) {
    return core::make_error("trade study: time step " + std::to_string(config.time_step_s) +
                            " s is not a multiple of the reference step " +
                            std::to_string(reference_time_step_s_) + " s");
  }
  ModalTradePoint point;
  point.config = config;
  auto built = build_for(config, &point.precompute_s);
  if (!built) return std::move(built).error();
  const ModalBuildSpec spec = spec_for(config);
  point.data_bytes = stored_data_bytes(spec, **built, config.static_correction, config.precision);
  const core::Expected<void> measured =
      config.precision == RuntimePrecision::float32
          ? measure_runtime<float>(config, cost_options, spec, **built, point)
          : measure_runtime<double>(config, cost_options, spec, **built, point);
  if (!measured) return measured.error();
  return point;
}

template <typename Scalar>
core::Expected<void> DuctTradeStudy::measure_runtime(const ModalTradeConfig& config,
                                                     const CycleCostOptions& cost_options,
                                                     const ModalBuildSpec& spec,
                                                     const ModalBuildResult& build,
                                                     ModalTradePoint& point) const {
  using Vector3 = Eigen::Matrix<Scalar, 3, 1>;
  const ModalDataCopy<Scalar> data(spec, build);
  BasicModalSettings<Scalar> settings;
  settings.time_step_s = static_cast<Scalar>(config.time_step_s);
  settings.active_modes = static_cast<std::uint32_t>(config.modes);
  settings.static_correction = config.static_correction;
  auto arena = core::Arena::create(std::size_t{8} << 20);
  if (!arena) return std::move(arena).error();
  auto model = BasicModalModel<Scalar>::create(data.view(), *arena, settings);
  if (!model) return std::move(model).error();

  // Accuracy: every scenario against its reference.
  for (std::size_t index = 0; index < scenarios_.size(); ++index) {
    const ContactScenario& scenario = scenarios_[index];
    const ReferenceHistory& reference = references_[index];
    auto steps = steps_for(scenario, config.time_step_s);
    if (!steps) return std::move(steps).error();
    model->reset();
    double reference_peak = 0.0;
    double difference_peak = 0.0;
    double reference_sq = 0.0;
    double difference_sq = 0.0;
    for (int step = 1; step <= *steps; ++step) {
      const double t = step * config.time_step_s;
      const BasicImposedDisplacement<Scalar> target{
          static_cast<std::uint32_t>(reference.contact_node),
          scenario_target(scenario, reference.inward, t).template cast<Scalar>()};
      Vector3 force = Vector3::Zero();
      model->clear_forces();
      if (const core::Status solved = model->solve_imposed({&target, 1}, {&force, 1}); !solved) {
        return core::make_error("scenario '" + scenario.name + "', " + config.label() +
                                ": solve_imposed refused: " + solved.detail());
      }
      (void)model->step();
      const Eigen::Vector3d expected =
          reference_force_at(reference.forces, reference_time_step_s_, t);
      const double difference = (force.template cast<double>() - expected).norm();
      reference_peak = std::max(reference_peak, expected.norm());
      difference_peak = std::max(difference_peak, difference);
      reference_sq += expected.squaredNorm();
      difference_sq += difference * difference;
    }
    ScenarioError error;
    error.scenario = scenario.name;
    error.tuning = scenario.tuning;
    error.contact_node = reference.contact_node;
    error.reference_peak_force_n = reference_peak;
    error.peak_error = reference_peak > 0.0 ? difference_peak / reference_peak : 0.0;
    error.rms_error = reference_sq > 0.0 ? std::sqrt(difference_sq / reference_sq) : 0.0;
    double& group_error = error.tuning ? point.tuning_error : point.validation_error;
    group_error = std::max(group_error, error.rms_error);
    point.worst_error = std::max(point.worst_error, error.rms_error);
    point.worst_peak_error = std::max(point.worst_peak_error, error.peak_error);
    point.errors.push_back(std::move(error));
  }

  // Cost: one tool pressing and releasing at the first scenario's node, a 4 Hz depth cycle.
  const ReferenceHistory& reference = references_.front();
  const double depth_m = scenarios_.front().keyframes.back().depth_m;
  std::vector<Scalar> surface(3 * static_cast<std::size_t>(model->node_count()));
  if (auto valid = cycle_cost::check_options(cost_options, "duct trade study"); !valid) {
    return valid;
  }
  std::vector<double> total_ns;
  std::vector<double> haptic_ns;
  model->reset();
  const int total_cycles =
      cost_options.warmup_cycles + cost_options.repetitions * cost_options.cycles_per_repetition;
  for (int cycle = 0; cycle < total_cycles; ++cycle) {
    const double t = cycle * config.time_step_s;
    const double depth = depth_m * (0.5 - 0.5 * std::cos(2.0 * M_PI * 4.0 * t));
    const BasicImposedDisplacement<Scalar> target{
        static_cast<std::uint32_t>(reference.contact_node),
        (depth * reference.inward).template cast<Scalar>()};
    Vector3 force;
    const auto start = Clock::now();
    model->clear_forces();
    (void)model->solve_imposed({&target, 1}, {&force, 1});
    (void)model->step();
    const auto stepped = Clock::now();
    (void)model->reconstruct(surface);
    const auto end = Clock::now();
    if (cycle < cost_options.warmup_cycles) continue;
    total_ns.push_back(nanoseconds(end - start));
    haptic_ns.push_back(nanoseconds(stepped - start));
  }
  point.cost = cycle_cost::summarize(cost_options, total_ns, haptic_ns);
  return {};
}

double selection_cost_ns(const ModalTradePoint& point) {
  const double per_cycle = point.cost.repetition_median_min_ns > 0.0
                               ? point.cost.repetition_median_min_ns
                               : point.cost.median_ns;
  return per_cycle * (1e-3 / point.config.time_step_s);
}

core::Expected<std::size_t> select_for_budget(const std::vector<ModalTradePoint>& points,
                                              double budget, std::vector<std::string>* log) {
  if (!(budget > 0.0) || !std::isfinite(budget)) {
    return core::make_error("error budget " + std::to_string(100.0 * budget) +
                            " %, expected a finite value > 0");
  }
  if (points.empty()) return core::make_error("error budget: no configurations measured");
  std::vector<std::size_t> order(points.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  const auto cost = [&](std::size_t i) { return selection_cost_ns(points[i]); };
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return cost(a) < cost(b); });
  const auto simpler = [](const ModalTradePoint& a, const ModalTradePoint& b) {
    if (a.config.time_step_s != b.config.time_step_s) return a.config.time_step_s > b.config.time_step_s;
    if (a.config.modes != b.config.modes) return a.config.modes < b.config.modes;
    return !a.config.static_correction && b.config.static_correction;
  };
  const auto note = [&](const std::string& line) {
    if (log != nullptr) log->push_back(line);
  };
  std::optional<std::size_t> chosen;
  for (std::size_t index : order) {
    const ModalTradePoint& point = points[index];
    char line[320];
    if (point.tuning_error > budget) {
      std::snprintf(line, sizeof line, "%s: tuning error %.3f %% > budget %.3f %%",
                    point.config.label().c_str(), 100.0 * point.tuning_error, 100.0 * budget);
      if (!chosen) note(line);
      continue;
    }
    if (point.validation_error > budget) {
      std::snprintf(line, sizeof line,
                    "%s: tuning error %.3f %% within budget but held-out error %.3f %% > budget",
                    point.config.label().c_str(), 100.0 * point.tuning_error,
                    100.0 * point.validation_error);
      if (!chosen) note(line);
      continue;
    }
    if (!chosen) {
      chosen = index;
    } else if (cost(index) <= 1.05 * cost(*chosen) && simpler(point, points[*chosen])) {
      std::snprintf(line, sizeof line, "%s preferred to %s: within 5 %% of its cost, simpler",
                    point.config.label().c_str(), points[*chosen].config.label().c_str());
      note(line);
      chosen = index;
    }
  }
  if (!chosen) {
    const auto best = std::min_element(
        points.begin(), points.end(), [](const ModalTradePoint& a, const ModalTradePoint& b) {
          return std::max(a.tuning_error, a.validation_error) <
                 std::max(b.tuning_error, b.validation_error);
        });
    char line[320];
    std::snprintf(line, sizeof line,
                  "no configuration meets the error budget %.3f %%: the most accurate, %s, has "
                  "tuning error %.3f %% and held-out error %.3f %%",
                  100.0 * budget, best->config.label().c_str(), 100.0 * best->tuning_error,
                  100.0 * best->validation_error);
    return core::make_error(line);
  }
  return *chosen;
}

core::Expected<BudgetChoice> choose_for_budget(DuctTradeStudy& study, double budget,
                                               const std::vector<ModalTradeConfig>& candidates,
                                               const CycleCostOptions& cost_options) {
  if (candidates.empty()) return core::make_error("error budget: no candidate configurations");
  BudgetChoice choice;
  for (const ModalTradeConfig& config : candidates) {
    auto point = study.measure(config, cost_options);
    if (!point) return std::move(point).error();
    choice.candidates.push_back(std::move(*point));
  }
  std::sort(choice.candidates.begin(), choice.candidates.end(),
            [](const ModalTradePoint& a, const ModalTradePoint& b) {
              return selection_cost_ns(a) < selection_cost_ns(b);
            });
  auto selected = select_for_budget(choice.candidates, budget, &choice.log);
  if (!selected) return std::move(selected).error();
  choice.chosen = choice.candidates[*selected];
  return choice;
}

}  // namespace trainer::model::offline
