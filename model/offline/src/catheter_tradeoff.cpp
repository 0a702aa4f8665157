// The particle catheter's trade study: scripted scenarios through the runtime Catheter, the
// fine-N reference, per-N errors and the cycle cost (catheter_tradeoff.hpp).
#include "trainer/model_offline/catheter_tradeoff.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <utility>

#include "catheter_reference_substep.hpp"
#include "cycle_cost_summary.hpp"
#include "trainer/core/arena.hpp"

namespace trainer::model::offline {

namespace {

using Clock = cycle_cost::Clock;
using Vec3 = Eigen::Vector3f;

// The reference and the configurations measured beyond the budget run with no budget at all.
constexpr std::uint32_t kUnboundedSubsteps = std::numeric_limits<std::uint32_t>::max();
// Catheter state is a few arrays of N vectors and the planes: far below this.
constexpr std::size_t kArenaBytes = std::size_t{1} << 20;

std::string significant_text(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", value);
  return text;
}

// 0 → 1 with zero slope at both ends (no velocity jump where a script starts or stops).
double cosine_ramp(double t_s, double ramp_s) {
  if (t_s >= ramp_s) return 1.0;
  if (t_s <= 0.0) return 0.0;
  return 0.5 - 0.5 * std::cos(M_PI * t_s / ramp_s);
}

core::Expected<int> periods_of(const CatheterScenario& scenario, double period_s) {
  const double periods = scenario.duration_s / period_s;
  if (!(periods >= 1.0) || std::abs(periods - std::round(periods)) > 1e-6) {
    return core::make_error("catheter trade study: scenario '" + scenario.name + "': duration " +
                            significant_text(scenario.duration_s) +
                            " s, expected a whole number (>= 1) of haptic periods of " +
                            significant_text(period_s) + " s");
  }
  return static_cast<int>(std::lround(periods));
}

// The four stations of a scenario: quarter points of the free part, the last one the tip.
std::array<double, 4> station_arc_lengths(const CatheterScenario& scenario, double length_m) {
  const double start_m =
      scenario.kind == CatheterScenarioKind::insertion ? scenario.grasp_arc_length_m : 0.0;
  std::array<double, 4> stations{};
  for (std::size_t j = 0; j < stations.size(); ++j) {
    stations[j] = start_m + (length_m - start_m) * static_cast<double>(j + 1) / 4.0;
  }
  return stations;
}

// The definition's parameters at N particles, with the damping that keeps b/m (see header).
CatheterParams params_at(const CatheterStudySpec& spec, std::uint32_t particle_count) {
  CatheterParams params = spec.params;
  params.particle_count = particle_count;
  // The contact stiffness as modelc passes it from the definition's [contact] (it no longer
  // enters the substep: contacts are linearly implicit).
  params.contact_stiffness_n_per_m = std::max(params.contact_stiffness_n_per_m,
                                              static_cast<float>(spec.contact.stiffness_n_per_m));
  params.damping_n_s_per_m = static_cast<float>(
      static_cast<double>(spec.params.damping_n_s_per_m) *
      static_cast<double>(spec.params.particle_count) / static_cast<double>(particle_count));
  return params;
}

CatheterSetup setup_for(const CatheterStudySpec& spec, std::uint32_t particle_count,
                        std::uint32_t max_substeps) {
  CatheterSetup setup;
  setup.start_position_m = Vec3::Zero();
  setup.direction = Vec3::UnitX();
  setup.haptic_period_s = static_cast<float>(spec.haptic_period_s);
  setup.max_substeps = max_substeps;
  setup.max_contact_planes = particle_count;  // every particle may touch the wall
  return setup;
}

// Wall contacts of one period: the particles within reach + margin of the wall plane, with the
// plane's point nearest each (the trainer's ContactPlane fields, in double).
struct WallContact {
  std::uint32_t particle = 0;
  Eigen::Vector3d point_m = Eigen::Vector3d::Zero();
};

// The runtime chain: trainer::model::Catheter, float, as the trainer steps it.
class RuntimeChain {
 public:
  static core::Expected<RuntimeChain> create(const CatheterStudySpec& spec,
                                             std::uint32_t particle_count) {
    auto arena = core::Arena::create(kArenaBytes);
    if (!arena) return std::move(arena).error();
    auto catheter = Catheter::create(params_at(spec, particle_count),
                                     setup_for(spec, particle_count, kUnboundedSubsteps), *arena);
    if (!catheter) return std::move(catheter).error();
    return RuntimeChain(spec, std::move(*arena), std::move(*catheter));
  }

  std::span<const Vec3> positions_m() const { return catheter_.positions_m(); }
  double radius_m() const { return static_cast<double>(catheter_.radius_m()); }
  std::uint32_t substeps_per_period() const { return catheter_.substeps_per_period(); }
  void clamp_start() { catheter_.clamp_start(true); }
  core::Status set_wall(std::span<const WallContact> contacts, const Eigen::Vector3d& normal) {
    planes_.clear();
    for (const WallContact& contact : contacts) {
      ContactPlane plane;
      plane.particle_a = plane.particle_b = contact.particle;
      plane.weight_b = 0.0F;
      plane.point_m = contact.point_m.cast<float>();
      plane.normal = normal.cast<float>();
      plane.reach_m = catheter_.radius_m();
      plane.stiffness_n_per_m = static_cast<float>(contact_.stiffness_n_per_m);
      plane.damping_n_s_per_m = static_cast<float>(contact_.damping_n_s_per_m);
      plane.max_force_n = static_cast<float>(contact_.max_force_n);
      planes_.push_back(plane);
    }
    return catheter_.set_contact_planes(planes_);
  }
  core::Status hold(std::uint32_t particle, const Eigen::Vector3d& target_m) {
    return catheter_.hold(particle, target_m.cast<float>());
  }
  void clear_forces() { catheter_.clear_forces(); }
  core::Status add_force(std::uint32_t particle, const Eigen::Vector3d& force_n) {
    return catheter_.add_force(particle, force_n.cast<float>());
  }
  core::Status step(double period_s) { return catheter_.step(static_cast<float>(period_s)); }
  Eigen::Vector3d hold_force_n(std::uint32_t particle) const {
    return catheter_.hold_forces_n()[particle].cast<double>();
  }

 private:
  RuntimeChain(const CatheterStudySpec& spec, core::Arena arena, Catheter catheter)
      : contact_(spec.contact), arena_(std::move(arena)), catheter_(std::move(catheter)) {
    planes_.reserve(catheter_.particle_count());
  }
  CatheterWallContact contact_;
  core::Arena arena_;  // owns the catheter's state (its memory does not move with the Arena)
  Catheter catheter_;
  std::vector<ContactPlane> planes_;
};

// The reference chain: the same model as the runtime Catheter — the same springs
// (add_chain_forces<double>), damping, held particles (interpolated targets, hold forces
// averaged over the step), contact law and linearly implicit substeps (axial springs and
// damping implicit, Catheter::solve_velocities), the substep count the runtime computes — in
// double, so the reference carries no float32 rounding. (In float the
// stiff axial springs turn a position's rounding, ~1e-8 m, into ~1e-4 N of chatter at N = 81.)
class ReferenceChain {
 public:
  using Vector = Eigen::Vector3d;

  static core::Expected<ReferenceChain> create(const CatheterStudySpec& spec,
                                               std::uint32_t particle_count) {
    auto runtime = RuntimeChain::create(spec, particle_count);  // validates, gives the substeps
    if (!runtime) return std::move(runtime).error();
    ReferenceChain chain;
    const CatheterParams params = params_at(spec, particle_count);
    const double count = static_cast<double>(particle_count);
    const double length_m = static_cast<double>(params.length_m);
    chain.stiffness_.rest_length_m = length_m / (count - 1.0);
    chain.stiffness_.axial_n_per_m =
        static_cast<double>(params.axial_stiffness_n) / chain.stiffness_.rest_length_m;
    chain.stiffness_.bending_n_m_per_rad =
        static_cast<double>(params.bending_stiffness_n_m2) / chain.stiffness_.rest_length_m;
    chain.stiffness_.root_tangent = Vector::UnitX();
    chain.mass_kg_ = static_cast<double>(params.linear_density_kg_per_m) * length_m / count;
    chain.bending_omega_squared_ =
        20.0 * chain.stiffness_.bending_n_m_per_rad /
        (chain.mass_kg_ * chain.stiffness_.rest_length_m * chain.stiffness_.rest_length_m);
    chain.damping_n_s_per_m_ = static_cast<double>(params.damping_n_s_per_m);
    chain.radius_m_ = static_cast<double>(params.outer_radius_m);
    chain.substeps_ = runtime->substeps_per_period();
    chain.contact_ = spec.contact;
    const auto n = static_cast<std::size_t>(particle_count);
    chain.positions_.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      chain.positions_[i] = Vector(static_cast<double>(i) * chain.stiffness_.rest_length_m, 0, 0);
    }
    chain.velocities_.assign(n, Vector::Zero());
    chain.forces_.assign(n, Vector::Zero());
    chain.external_n_.assign(n, Vector::Zero());
    chain.targets_m_.assign(n, Vector::Zero());
    chain.saved_positions_.assign(n, Vector::Zero());
    chain.hold_forces_n_.assign(n, Vector::Zero());
    chain.held_.assign(n, 0);
    return chain;
  }

  std::span<const Vector> positions_m() const { return positions_; }
  double radius_m() const { return radius_m_; }
  void clamp_start() {
    stiffness_.root_clamped = true;
    held_[0] = 1;
    targets_m_[0] = Vector::Zero();
  }
  core::Status set_wall(std::span<const WallContact> contacts, const Eigen::Vector3d& normal) {
    wall_.assign(contacts.begin(), contacts.end());
    wall_normal_ = normal;
    return core::Status::ok();
  }
  core::Status hold(std::uint32_t particle, const Vector& target_m) {
    held_[particle] = 1;
    targets_m_[particle] = target_m;
    return core::Status::ok();
  }
  void clear_forces() {
    for (Vector& force : external_n_) force.setZero();
  }
  core::Status add_force(std::uint32_t particle, const Vector& force_n) {
    external_n_[particle] += force_n;
    return core::Status::ok();
  }
  Vector hold_force_n(std::uint32_t particle) const { return hold_forces_n_[particle]; }

  // Catheter::step and its substeps, line for line, in double.
  core::Status step(double period_s) {
    saved_positions_ = positions_;
    for (Vector& force : hold_forces_n_) force.setZero();
    const double dt_s = period_s / static_cast<double>(substeps_);
    const double fraction = 1.0 / static_cast<double>(substeps_);
    const std::size_t n = positions_.size();
    // Catheter::step's choice: the explicit-bending substep while it resolves bending and the
    // planes explicitly, else the implicit one (catheter_reference_substep.cpp).
    const double stiffest_plane = wall_.empty() ? 0.0 : contact_.stiffness_n_per_m;
    const bool explicit_path =
        dt_s * dt_s * (bending_omega_squared_ + stiffest_plane / mass_kg_) <= 1.0;
    if (!explicit_path) {
      std::vector<std::size_t> particles(wall_.size());
      std::vector<Vector> points(wall_.size());
      for (std::size_t k = 0; k < wall_.size(); ++k) {
        particles[k] = wall_[k].particle;
        points[k] = wall_[k].point_m;
      }
      detail::ReferenceChainState state;
      state.stiffness = &stiffness_;
      state.mass_kg = mass_kg_;
      state.damping_n_s_per_m = damping_n_s_per_m_;
      state.radius_m = radius_m_;
      state.contact = contact_;
      state.wall_particles = particles;
      state.wall_points_m = points;
      state.wall_normal = wall_normal_;
      state.positions = &positions_;
      state.velocities = &velocities_;
      state.external_n = external_n_;
      state.targets_m = targets_m_;
      state.saved_positions_m = saved_positions_;
      state.hold_forces_n = hold_forces_n_;
      state.held = held_;
      for (std::uint32_t k = 0; k < substeps_; ++k) {
        detail::reference_implicit_substep(state, dt_s, period_s, fraction,
                                           static_cast<double>(k + 1) * fraction);
      }
    }
    for (std::uint32_t k = 0; k < substeps_ && explicit_path; ++k) {
      const double hold_step = static_cast<double>(k + 1) * fraction;
      for (std::size_t i = 0; i < n; ++i) forces_[i] = external_n_[i];  // damping: implicit
      add_chain_forces<double>(positions_, stiffness_, forces_, held_);
      for (const WallContact& contact : wall_) {
        const std::size_t i = contact.particle;
        const double depth_m = radius_m_ - (positions_[i] - contact.point_m).dot(wall_normal_);
        if (!(depth_m > 0.0)) continue;
        const double magnitude =
            std::clamp(contact_.stiffness_n_per_m * depth_m -
                           contact_.damping_n_s_per_m * velocities_[i].dot(wall_normal_),
                       0.0, contact_.max_force_n);
        forces_[i] += magnitude * wall_normal_;
      }
      solve_velocities(dt_s, period_s);
      for (std::size_t i = 0; i < n; ++i) {
        if (held_[i] != 0) {
          Vector force = forces_[i] - damping_n_s_per_m_ * solution_[i];
          if (i > 0) force -= coupling_[i - 1] * (solution_[i] - solution_[i - 1]) / dt_s;
          if (i + 1 < n) force -= coupling_[i] * (solution_[i] - solution_[i + 1]) / dt_s;
          hold_forces_n_[i] += fraction * force;
          const Vector start = saved_positions_[i];
          positions_[i] = hold_step >= 1.0 ? targets_m_[i]
                                           : Vector(start + hold_step * (targets_m_[i] - start));
          velocities_[i] = (targets_m_[i] - start) / period_s;
          continue;
        }
        velocities_[i] = solution_[i];
        positions_[i] += dt_s * velocities_[i];
      }
    }
    for (const Vector& position : positions_) {
      if (!position.allFinite()) {
        return {core::StatusCode::numeric_error, "reference chain: state became non-finite"};
      }
    }
    return core::Status::ok();
  }

 private:
  ReferenceChain() = default;

  // Catheter::solve_velocities in double: ((m + h b) I + h² H_axial) v' = m v + h F, held
  // particles eliminated, block Thomas elimination into solution_.
  void solve_velocities(double h, double period_s) {
    using Matrix = Eigen::Matrix3d;
    const std::size_t n = positions_.size();
    coupling_.resize(n - 1);
    block_inverse_.resize(n);
    solution_.resize(n);
    const double h2k = h * h * stiffness_.axial_n_per_m;
    for (std::size_t s = 0; s + 1 < n; ++s) {
      const Vector segment = positions_[s + 1] - positions_[s];
      const double length = segment.norm();
      if (!(length > 0.0)) {
        coupling_[s].setZero();
        continue;
      }
      const Vector unit = segment / length;
      const double g = std::clamp(1.0 - stiffness_.rest_length_m / length, 0.0, 1.0);
      coupling_[s] = (h2k * (1.0 - g)) * (unit * unit.transpose());
      coupling_[s].diagonal().array() += h2k * g;
    }
    const auto hold_velocity = [&](std::size_t i) {
      return Vector((targets_m_[i] - saved_positions_[i]) / period_s);
    };
    for (std::size_t i = 0; i < n; ++i) {
      if (held_[i] != 0) {
        solution_[i] = hold_velocity(i);
        block_inverse_[i].setIdentity();
        continue;
      }
      Matrix block = Matrix::Identity() * (mass_kg_ + h * damping_n_s_per_m_);
      Vector rhs = mass_kg_ * velocities_[i] + h * forces_[i];
      if (i > 0) {
        block += coupling_[i - 1];
        if (held_[i - 1] != 0) {
          rhs += coupling_[i - 1] * solution_[i - 1];
        } else {
          const Matrix factor = coupling_[i - 1] * block_inverse_[i - 1];
          block -= factor * coupling_[i - 1];
          rhs += factor * solution_[i - 1];
        }
      }
      if (i + 1 < n) {
        block += coupling_[i];
        if (held_[i + 1] != 0) rhs += coupling_[i] * hold_velocity(i + 1);
      }
      block_inverse_[i] = block.inverse();
      solution_[i] = rhs;
    }
    for (std::size_t k = n; k-- > 0;) {
      if (held_[k] != 0) continue;
      if (k + 1 < n && held_[k + 1] == 0) solution_[k] += coupling_[k] * solution_[k + 1];
      solution_[k] = block_inverse_[k] * solution_[k];
    }
  }

  std::vector<Eigen::Matrix3d> coupling_, block_inverse_;
  std::vector<Vector> solution_;
  ChainStiffness<double> stiffness_{};
  double mass_kg_ = 0.0;
  double bending_omega_squared_ = 0.0;  // 20 k_b/(m l0²)
  double damping_n_s_per_m_ = 0.0;
  double radius_m_ = 0.0;
  std::uint32_t substeps_ = 1;
  CatheterWallContact contact_;
  std::vector<Vector> positions_, velocities_, forces_, external_n_, targets_m_, saved_positions_,
      hold_forces_n_;
  std::vector<std::uint8_t> held_;
  std::vector<WallContact> wall_;
  Vector wall_normal_ = Vector::UnitY();
};

// One chain running one scenario, one haptic period per cycle(), as the trainer's
// step_catheter does it: wall contacts from the positions at the start of the period, holds
// or loads, clear, step.
template <class Chain>
class ScenarioDriver {
 public:
  static core::Expected<std::unique_ptr<ScenarioDriver>> create(const CatheterStudySpec& spec,
                                                                const CatheterScenario& scenario,
                                                                std::uint32_t particle_count) {
    auto chain = Chain::create(spec, particle_count);
    if (!chain) return std::move(chain).error();
    std::unique_ptr<ScenarioDriver> driver(new ScenarioDriver(spec, scenario, std::move(*chain)));
    const double length_m = static_cast<double>(spec.params.length_m);
    driver->segment_m_ = length_m / static_cast<double>(particle_count - 1);
    if (scenario.kind == CatheterScenarioKind::insertion) {
      const long front = std::lround(scenario.grasp_arc_length_m / driver->segment_m_);
      if (front < 1 || front > static_cast<long>(particle_count) - 2) {
        return core::make_error("catheter trade study: scenario '" + scenario.name +
                                "': grasp at " + significant_text(scenario.grasp_arc_length_m) +
                                " m is particle " + std::to_string(front) + " of N = " +
                                std::to_string(particle_count) +
                                ", expected 1..N-2 (a held segment and a free tip)");
      }
      driver->front_ = static_cast<std::uint32_t>(front);
      const double angle = scenario.wall_angle_deg * M_PI / 180.0;
      driver->wall_normal_ = Eigen::Vector3d(-std::sin(angle), std::cos(angle), 0.0);
      driver->wall_point_ = Eigen::Vector3d(
          length_m + scenario.wall_gap_m + driver->chain_.radius_m() / std::sin(angle), 0.0, 0.0);
      driver->contacts_.reserve(particle_count);
    } else {
      driver->chain_.clamp_start();
      driver->tip_force_n_ = scenario.tip_load *
                             static_cast<double>(spec.params.bending_stiffness_n_m2) /
                             (length_m * length_m);
    }
    return driver;
  }

  // Period k (ending at (k + 1)·period; past the scenario's end the script stays at its end).
  // step_ns: the wall time of step() alone.
  core::Status cycle(int period_index, double& step_ns) {
    const double period_s = spec_.haptic_period_s;
    const double t_end_s = static_cast<double>(period_index + 1) * period_s;
    core::Status status = core::Status::ok();
    const auto keep = [&status](const core::Status& s) {
      if (status.is_ok() && !s.is_ok()) status = s;
    };
    if (scenario_.kind == CatheterScenarioKind::insertion) {
      const auto positions = chain_.positions_m();
      const double reach_m = chain_.radius_m() + spec_.contact.detection_margin_m;
      contacts_.clear();
      for (std::uint32_t i = 0; i < positions.size(); ++i) {
        const Eigen::Vector3d p = positions[i].template cast<double>();
        const double distance_m = (p - wall_point_).dot(wall_normal_);
        if (distance_m < reach_m) contacts_.push_back({i, p - distance_m * wall_normal_});
      }
      keep(chain_.set_wall(contacts_, wall_normal_));
      const double advance_m = scenario_.push_m * cosine_ramp(t_end_s, scenario_.push_time_s);
      for (std::uint32_t i = front_ - 1; i <= front_; ++i) {
        keep(chain_.hold(i, Eigen::Vector3d(static_cast<double>(i) * segment_m_ + advance_m, 0, 0)));
      }
      chain_.clear_forces();
    } else {
      chain_.clear_forces();
      const double force_n = tip_force_n_ * cosine_ramp(t_end_s, scenario_.load_time_s);
      keep(chain_.add_force(static_cast<std::uint32_t>(chain_.positions_m().size() - 1),
                            Eigen::Vector3d(0.0, force_n, 0.0)));
    }
    const auto start = Clock::now();
    keep(chain_.step(period_s));
    step_ns = cycle_cost::nanoseconds(Clock::now() - start);
    return status;
  }

  Eigen::Vector3d grasp_force_n() const {
    return chain_.hold_force_n(front_ - 1) + chain_.hold_force_n(front_);
  }
  std::array<Eigen::Vector3d, 4> stations_m(const std::array<double, 4>& arc_lengths_m) const {
    std::array<Eigen::Vector3d, 4> points;
    for (std::size_t j = 0; j < points.size(); ++j) {
      points[j] = chain_point_at(chain_.positions_m(), segment_m_, arc_lengths_m[j]);
    }
    return points;
  }
  double grasp_arc_length_m() const { return static_cast<double>(front_) * segment_m_; }

 private:
  ScenarioDriver(const CatheterStudySpec& spec, const CatheterScenario& scenario, Chain chain)
      : spec_(spec), scenario_(scenario), chain_(std::move(chain)) {}

  const CatheterStudySpec& spec_;
  const CatheterScenario& scenario_;
  Chain chain_;
  double segment_m_ = 0.0;
  std::uint32_t front_ = 0;
  Eigen::Vector3d wall_normal_ = Eigen::Vector3d::UnitY();
  Eigen::Vector3d wall_point_ = Eigen::Vector3d::Zero();
  double tip_force_n_ = 0.0;
  std::vector<WallContact> contacts_;
};

template <class Chain>
core::Expected<CatheterTradeStudy::History> run_scenario(const CatheterStudySpec& spec,
                                                         const CatheterScenario& scenario,
                                                         std::uint32_t particle_count) {
  auto periods = periods_of(scenario, spec.haptic_period_s);
  if (!periods) return std::move(periods).error();
  auto driver = ScenarioDriver<Chain>::create(spec, scenario, particle_count);
  if (!driver) return std::move(driver).error();
  const std::array<double, 4> stations =
      station_arc_lengths(scenario, static_cast<double>(spec.params.length_m));
  CatheterTradeStudy::History history;
  if (scenario.kind == CatheterScenarioKind::insertion) {
    history.grasp_arc_length_m = (*driver)->grasp_arc_length_m();
    history.grasp_force_n.reserve(static_cast<std::size_t>(*periods));
  }
  history.stations_m.reserve(static_cast<std::size_t>(*periods));
  for (int k = 0; k < *periods; ++k) {
    double step_ns = 0.0;
    if (const core::Status status = (*driver)->cycle(k, step_ns); !status.is_ok()) {
      return core::make_error("catheter trade study: scenario '" + scenario.name + "', N = " +
                              std::to_string(particle_count) + ", period " + std::to_string(k) +
                              ": " + status.detail());
    }
    if (scenario.kind == CatheterScenarioKind::insertion) {
      history.grasp_force_n.push_back((*driver)->grasp_force_n());
    }
    history.stations_m.push_back((*driver)->stations_m(stations));
  }
  return history;
}

core::Expected<void> check_scenario(const CatheterScenario& scenario, double length_m,
                                    double period_s) {
  auto periods = periods_of(scenario, period_s);
  if (!periods) return std::move(periods).error();
  const auto refuse = [&](const std::string& what) {
    return core::make_error("catheter trade study: scenario '" + scenario.name + "': " + what);
  };
  if (scenario.kind == CatheterScenarioKind::insertion) {
    if (!(scenario.grasp_arc_length_m > 0.0 && scenario.grasp_arc_length_m < length_m)) {
      return refuse("grasp arc length " + significant_text(scenario.grasp_arc_length_m) +
                    " m, expected inside (0, " + significant_text(length_m) + ") m");
    }
    if (!(scenario.push_m > 0.0) || !std::isfinite(scenario.push_m) ||
        !(scenario.push_time_s > 0.0) || !std::isfinite(scenario.push_time_s)) {
      return refuse("push " + significant_text(scenario.push_m) + " m over " +
                    significant_text(scenario.push_time_s) + " s, expected both finite and > 0");
    }
    if (!(scenario.wall_angle_deg > 0.0 && scenario.wall_angle_deg <= 90.0)) {
      return refuse("wall angle " + significant_text(scenario.wall_angle_deg) +
                    " degrees, expected in (0, 90]");
    }
    if (!(scenario.wall_gap_m >= 0.0) || !std::isfinite(scenario.wall_gap_m)) {
      return refuse("wall gap " + significant_text(scenario.wall_gap_m) + " m, expected finite and >= 0");
    }
  } else {
    if (!(scenario.tip_load > 0.0) || !std::isfinite(scenario.tip_load) ||
        !(scenario.load_time_s > 0.0) || !std::isfinite(scenario.load_time_s)) {
      return refuse("tip load F L^2/EI = " + significant_text(scenario.tip_load) + " over " +
                    significant_text(scenario.load_time_s) + " s, expected both finite and > 0");
    }
  }
  return {};
}

// Centred sliding mean over 2·half_window + 1 samples (fewer at the ends).
std::vector<Eigen::Vector3d> window_mean(const std::vector<Eigen::Vector3d>& samples,
                                         int half_window) {
  const auto count = static_cast<std::ptrdiff_t>(samples.size());
  std::vector<Eigen::Vector3d> means(samples.size(), Eigen::Vector3d::Zero());
  for (std::ptrdiff_t k = 0; k < count; ++k) {
    const std::ptrdiff_t first = std::max<std::ptrdiff_t>(0, k - half_window);
    const std::ptrdiff_t last = std::min<std::ptrdiff_t>(count - 1, k + half_window);
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (std::ptrdiff_t j = first; j <= last; ++j) sum += samples[static_cast<std::size_t>(j)];
    means[static_cast<std::size_t>(k)] = sum / static_cast<double>(last - first + 1);
  }
  return means;
}

}  // namespace

const char* to_string(CatheterScenarioKind kind) {
  return kind == CatheterScenarioKind::insertion ? "insertion" : "cantilever";
}

std::string CatheterTradeConfig::label() const {
  char text[16];
  std::snprintf(text, sizeof text, "N%u", particle_count);
  return text;
}

std::vector<CatheterScenario> default_catheter_scenarios(double length_m) {
  CatheterScenario insertion;
  insertion.kind = CatheterScenarioKind::insertion;
  insertion.duration_s = 1.5;
  insertion.grasp_arc_length_m = 0.8 * length_m;
  insertion.push_m = 0.06 * length_m;
  insertion.push_time_s = 1.0;
  insertion.wall_gap_m = 0.01 * length_m;

  std::vector<CatheterScenario> scenarios;
  CatheterScenario wall45 = insertion;
  wall45.name = "insertion-wall-45";
  wall45.description =
      "grasp at 0.8 L pushed 0.06 L in 1 s (cosine ramp), tip onto a wall at 45 degrees to the "
      "axis after 0.01 L, held to 1.5 s";
  wall45.tuning = true;
  wall45.wall_angle_deg = 45.0;
  scenarios.push_back(std::move(wall45));

  CatheterScenario cantilever;
  cantilever.name = "cantilever-large";
  cantilever.description =
      "root clamped, transverse tip force ramped to F L^2/EI = 2 in 0.5 s, held to 1.5 s";
  cantilever.tuning = true;
  cantilever.kind = CatheterScenarioKind::cantilever;
  cantilever.duration_s = 1.5;
  cantilever.tip_load = 2.0;
  cantilever.load_time_s = 0.5;
  scenarios.push_back(std::move(cantilever));

  CatheterScenario wall60 = insertion;
  wall60.name = "insertion-wall-60";
  wall60.description =
      "as insertion-wall-45 against a steeper wall, 60 degrees to the axis (held out)";
  wall60.tuning = false;
  wall60.wall_angle_deg = 60.0;
  scenarios.push_back(std::move(wall60));
  return scenarios;
}

core::Expected<CatheterTradeStudy::History> CatheterTradeStudy::run(
    const CatheterScenario& scenario, std::uint32_t particle_count,
    RuntimePrecision precision) const {
  return precision == RuntimePrecision::float32
             ? run_scenario<RuntimeChain>(spec_, scenario, particle_count)
             : run_scenario<ReferenceChain>(spec_, scenario, particle_count);
}

core::Expected<std::unique_ptr<CatheterTradeStudy>> CatheterTradeStudy::create(
    CatheterStudySpec spec, std::vector<CatheterScenario> scenarios) {
  if (!(spec.haptic_period_s > 0.0) || !std::isfinite(spec.haptic_period_s)) {
    return core::make_error("catheter trade study: haptic period " +
                            significant_text(spec.haptic_period_s) + " s, expected finite and > 0");
  }
  if (spec.max_substeps == 0) {
    return core::make_error("catheter trade study: max_substeps = 0, expected >= 1");
  }
  if (scenarios.empty()) return core::make_error("catheter trade study: no scenarios");
  if (!(spec.force_window_s >= 0.0) || !std::isfinite(spec.force_window_s)) {
    return core::make_error("catheter trade study: force window " + significant_text(spec.force_window_s) +
                            " s, expected finite and >= 0 (0: compare every period)");
  }
  if (!(spec.contact.stiffness_n_per_m > 0.0) || !(spec.contact.damping_n_s_per_m >= 0.0) ||
      !(spec.contact.max_force_n > 0.0) || !(spec.contact.detection_margin_m >= 0.0)) {
    return core::make_error(
        "catheter trade study: wall contact stiffness " + significant_text(spec.contact.stiffness_n_per_m) +
        " N/m, damping " + significant_text(spec.contact.damping_n_s_per_m) + " N*s/m, max force " +
        significant_text(spec.contact.max_force_n) + " N, margin " +
        significant_text(spec.contact.detection_margin_m) +
        " m: expected stiffness > 0, damping >= 0, max force > 0, margin >= 0");
  }
  // The definition itself must make a catheter (its budget is checked per configuration).
  if (auto definition = RuntimeChain::create(spec, spec.params.particle_count); !definition) {
    return core::make_error("catheter trade study: the definition: " + definition.error().message);
  }
  const double length_m = static_cast<double>(spec.params.length_m);
  for (const CatheterScenario& scenario : scenarios) {
    auto checked = check_scenario(scenario, length_m, spec.haptic_period_s);
    if (!checked) return std::move(checked).error();
  }
  std::unique_ptr<CatheterTradeStudy> study(new CatheterTradeStudy());
  study->spec_ = std::move(spec);
  study->scenarios_ = std::move(scenarios);
  const std::uint32_t n = study->spec_.reference_particle_count;
  {
    auto reference = RuntimeChain::create(study->spec_, n);
    if (!reference) {
      return core::make_error("catheter trade study: reference N = " + std::to_string(n) + ": " +
                              reference.error().message);
    }
    study->reference_substeps_ = reference->substeps_per_period();
  }
  const auto start = Clock::now();
  // Richardson extrapolation with the observed order: N_ref, N_half and N_quarter share every
  // other particle (segment counts n, n/2, n/4).
  const std::uint32_t half = (n - 1) / 2 + 1;
  const std::uint32_t quarter = (half - 1) / 2 + 1;
  if (study->spec_.extrapolate_reference && (n % 2 == 0 || half % 2 == 0 || quarter < 3)) {
    return core::make_error("catheter trade study: an extrapolated reference needs N_ref = 4k + 1 >= 9 "
                            "(N_ref/2 and N_ref/4 on every other particle), got N_ref = " +
                            std::to_string(n));
  }
  std::vector<History> plain;
  for (const CatheterScenario& scenario : study->scenarios_) {
    auto fine = study->run(scenario, n, RuntimePrecision::float64);
    if (!fine) return std::move(fine).error();
    if (!study->spec_.extrapolate_reference) {
      study->references_.push_back(std::move(*fine));
      continue;
    }
    auto middle = study->run(scenario, half, RuntimePrecision::float64);
    if (!middle) return std::move(middle).error();
    auto coarse = study->run(scenario, quarter, RuntimePrecision::float64);
    if (!coarse) return std::move(coarse).error();
    for (const auto& [count, history] :
         {std::pair<std::uint32_t, const History*>{half, &*middle}, {quarter, &*coarse}}) {
      if (std::abs(fine->grasp_arc_length_m - history->grasp_arc_length_m) > 1e-9) {
        return core::make_error(
            "catheter trade study: scenario '" + scenario.name + "': the grasp at " +
            significant_text(scenario.grasp_arc_length_m) + " m is held at " +
            significant_text(fine->grasp_arc_length_m) + " m by N = " + std::to_string(n) + " but at " +
            significant_text(history->grasp_arc_length_m) + " m by N = " + std::to_string(count) +
            ": extrapolation needs a grasp on a particle of all three (or a plain reference)");
      }
    }
    // The observed order p of each output family from the three runs, |H(n/2) − H(n/4)| /
    // |H(n) − H(n/2)| = 2^p, kept within [1, 2] (the chain's outputs converge at first or
    // second order: docs/tradeoff-models.md); then H(n) + (H(n) − H(n/2)) / (2^p − 1).
    const auto observed_order = [](double coarse_difference, double fine_difference) {
      if (!(fine_difference > 0.0) || !(coarse_difference > 0.0)) return 2.0;
      return std::clamp(std::log2(coarse_difference / fine_difference), 1.0, 2.0);
    };
    // The grasp force through the comparison's window: its period-to-period chatter does not
    // converge and would hide the order.
    const int half_window = static_cast<int>(
        std::lround(0.5 * study->spec_.force_window_s / study->spec_.haptic_period_s));
    const std::vector<Eigen::Vector3d> force_fine_mean = window_mean(fine->grasp_force_n, half_window);
    const std::vector<Eigen::Vector3d> force_middle_mean =
        window_mean(middle->grasp_force_n, half_window);
    const std::vector<Eigen::Vector3d> force_coarse_mean =
        window_mean(coarse->grasp_force_n, half_window);
    double force_coarse = 0.0;
    double force_fine = 0.0;
    double shape_coarse = 0.0;
    double shape_fine = 0.0;
    for (std::size_t k = 0; k < fine->stations_m.size(); ++k) {
      for (std::size_t j = 0; j < 4; ++j) {
        shape_coarse += (middle->stations_m[k][j] - coarse->stations_m[k][j]).squaredNorm();
        shape_fine += (fine->stations_m[k][j] - middle->stations_m[k][j]).squaredNorm();
      }
    }
    for (std::size_t k = 0; k < force_fine_mean.size(); ++k) {
      force_coarse += (force_middle_mean[k] - force_coarse_mean[k]).squaredNorm();
      force_fine += (force_fine_mean[k] - force_middle_mean[k]).squaredNorm();
    }
    ReferenceOrder order;
    order.shape = observed_order(std::sqrt(shape_coarse), std::sqrt(shape_fine));
    order.force = fine->grasp_force_n.empty()
                      ? 0.0
                      : observed_order(std::sqrt(force_coarse), std::sqrt(force_fine));
    const double shape_factor = 1.0 / (std::exp2(order.shape) - 1.0);
    const double force_factor = 1.0 / (std::exp2(order.force) - 1.0);
    History extrapolated = *fine;
    for (std::size_t k = 0; k < extrapolated.stations_m.size(); ++k) {
      for (std::size_t j = 0; j < 4; ++j) {
        extrapolated.stations_m[k][j] +=
            shape_factor * (fine->stations_m[k][j] - middle->stations_m[k][j]);
      }
      if (!extrapolated.grasp_force_n.empty()) {
        extrapolated.grasp_force_n[k] +=
            force_factor * (fine->grasp_force_n[k] - middle->grasp_force_n[k]);
      }
    }
    study->reference_orders_.push_back(order);
    study->references_.push_back(std::move(extrapolated));
    plain.push_back(std::move(*fine));
  }
  study->reference_run_s_ = std::chrono::duration<double>(Clock::now() - start).count();
  for (std::size_t index = 0; index < plain.size(); ++index) {
    study->reference_check_.push_back(study->compare(index, plain[index]));
  }
  return study;
}

CatheterScenarioError CatheterTradeStudy::compare(std::size_t index,
                                                  const History& history) const {
  const CatheterScenario& scenario = scenarios_[index];
  const History& reference = references_[index];
  const double length_m = static_cast<double>(spec_.params.length_m);
  CatheterScenarioError error;
  error.scenario = scenario.name;
  error.tuning = scenario.tuning;
  error.kind = scenario.kind;
  error.grasp_arc_length_m = history.grasp_arc_length_m;
  const Eigen::Vector3d tip_start(length_m, 0.0, 0.0);  // the rest shape's tip
  for (std::size_t k = 0; k < reference.stations_m.size(); ++k) {
    for (std::size_t j = 0; j < 4; ++j) {
      const double difference =
          (history.stations_m[k][j] - reference.stations_m[k][j]).norm() / length_m;
      error.shape_error = std::max(error.shape_error, difference);
      if (j == 3) error.tip_error = std::max(error.tip_error, difference);
    }
    error.reference_peak_tip_travel_m = std::max(error.reference_peak_tip_travel_m,
                                                 (reference.stations_m[k][3] - tip_start).norm());
  }
  if (!reference.grasp_force_n.empty()) {
    const int half_window = static_cast<int>(
        std::lround(0.5 * spec_.force_window_s / spec_.haptic_period_s));
    const std::vector<Eigen::Vector3d> reference_mean =
        window_mean(reference.grasp_force_n, half_window);
    const std::vector<Eigen::Vector3d> history_mean = window_mean(history.grasp_force_n, half_window);
    double raw_peak = 0.0;
    double raw_difference = 0.0;
    double mean_difference = 0.0;
    for (std::size_t k = 0; k < reference.grasp_force_n.size(); ++k) {
      raw_peak = std::max(raw_peak, reference.grasp_force_n[k].norm());
      raw_difference =
          std::max(raw_difference, (history.grasp_force_n[k] - reference.grasp_force_n[k]).norm());
      error.reference_peak_force_n = std::max(error.reference_peak_force_n, reference_mean[k].norm());
      mean_difference = std::max(mean_difference, (history_mean[k] - reference_mean[k]).norm());
    }
    if (raw_peak > 0.0) error.force_error_per_period = raw_difference / raw_peak;
    if (error.reference_peak_force_n > 0.0) {
      error.force_error = mean_difference / error.reference_peak_force_n;
    }
  }
  error.error = std::max(error.force_error, error.shape_error);
  return error;
}

core::Expected<CatheterTradePoint> CatheterTradeStudy::measure(
    const CatheterTradeConfig& config, const CycleCostOptions& cost_options,
    bool measure_beyond_budget) const {
  auto options_ok = cycle_cost::check_options(cost_options, "catheter trade study");
  if (!options_ok) return std::move(options_ok).error();
  const std::uint32_t n = config.particle_count;
  CatheterTradePoint point;
  point.config = config;
  {
    // What this N needs (no budget), then whether the definition's budget takes it.
    auto arena = core::Arena::create(kArenaBytes);
    if (!arena) return std::move(arena).error();
    auto unbounded = Catheter::create(params_at(spec_, n), setup_for(spec_, n, kUnboundedSubsteps),
                                      *arena);
    if (!unbounded) {
      return core::make_error("catheter trade study: " + config.label() + ": " +
                              unbounded.error().message);
    }
    point.stable_substep_s = static_cast<double>(unbounded->stable_substep_s());
    point.substeps_per_period = unbounded->substeps_per_period();
    point.damping_n_s_per_m = static_cast<double>(params_at(spec_, n).damping_n_s_per_m);
    point.state_bytes = arena->used_bytes();
    auto budget_arena = core::Arena::create(kArenaBytes);
    if (!budget_arena) return std::move(budget_arena).error();
    auto budgeted = Catheter::create(params_at(spec_, n), setup_for(spec_, n, spec_.max_substeps),
                                     *budget_arena);
    if (!budgeted) {
      point.refused = true;
      point.refusal = budgeted.error().message;
    }
  }
  if (point.refused && !measure_beyond_budget) return point;

  for (std::size_t index = 0; index < scenarios_.size(); ++index) {
    auto history = run(scenarios_[index], n, RuntimePrecision::float32);
    if (!history) return std::move(history).error();
    CatheterScenarioError error = compare(index, *history);
    double& bucket = error.tuning ? point.tuning_error : point.validation_error;
    bucket = std::max(bucket, error.error);
    point.worst_error = std::max(point.worst_error, error.error);
    point.errors.push_back(std::move(error));
  }

  // Cost: the first insertion scenario (else the first scenario) in its loaded state.
  const auto loaded = std::find_if(scenarios_.begin(), scenarios_.end(), [](const auto& s) {
    return s.kind == CatheterScenarioKind::insertion;
  });
  const CatheterScenario& cost_scenario = loaded != scenarios_.end() ? *loaded : scenarios_.front();
  auto driver = ScenarioDriver<RuntimeChain>::create(spec_, cost_scenario, n);
  if (!driver) return std::move(driver).error();
  const double loaded_s = cost_scenario.kind == CatheterScenarioKind::insertion
                              ? cost_scenario.push_time_s
                              : cost_scenario.load_time_s;
  const int first_timed = static_cast<int>(std::ceil(loaded_s / spec_.haptic_period_s));
  double step_ns = 0.0;
  for (int k = 0; k < first_timed; ++k) (void)(*driver)->cycle(k, step_ns);
  const int timed = cost_options.repetitions * cost_options.cycles_per_repetition;
  std::vector<double> total_ns;
  std::vector<double> haptic_ns;
  total_ns.reserve(static_cast<std::size_t>(timed));
  haptic_ns.reserve(static_cast<std::size_t>(timed));
  for (int c = 0; c < cost_options.warmup_cycles + timed; ++c) {
    const auto start = Clock::now();
    const core::Status status = (*driver)->cycle(first_timed + c, step_ns);
    const double cycle_ns = cycle_cost::nanoseconds(Clock::now() - start);
    if (!status.is_ok()) {
      return core::make_error("catheter trade study: " + config.label() +
                              ": cost loop: " + status.detail());
    }
    if (c < cost_options.warmup_cycles) continue;
    total_ns.push_back(cycle_ns);
    haptic_ns.push_back(step_ns);
  }
  point.cost = cycle_cost::summarize(cost_options, total_ns, haptic_ns);
  point.measured = true;
  return point;
}

}  // namespace trainer::model::offline
