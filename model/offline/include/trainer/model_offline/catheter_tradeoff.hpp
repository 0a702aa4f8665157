// The speed/accuracy trade of the particle catheter, measured: the knob is the particle count N
// (the chain's resolution; its substeps per haptic period grow as N and its cost per period as
// N², docs/catheter.md). For each N the runtime trainer::model::Catheter is driven through
// deterministic scripts exactly as the trainer drives it — hold()/release(), clamp_start(),
// add_force(), set_contact_planes() with the planes of a rigid wall found once per period,
// step(haptic period) — and compared with the same script run at a fine reference N:
//
//   * insertion: two neighbouring particles at a grasp arc length are held (the forceps' jaws
//     hold a segment's two particles) and driven forward along the rest axis on a smooth ramp,
//     then held; the tip meets a rigid wall inclined to the axis and the free part bends. Out:
//     the force the grasp feels (sum of the two held particles' hold_forces_n) and the shape of
//     the free part (the tip and three more stations along it);
//   * cantilever: clamp_start() at the root, a transverse tip force ramped to a large
//     deflection (F L²/EI of order 1) and held. Out: the shape (the tip and three stations).
//
// Every quantity is compared at the same arc length for every N: positions between particles
// are interpolated linearly along the chain (the tip is the last particle for every N). The
// grasp's front held particle is the particle nearest the grasp arc length; the defaults put it
// on a multiple of L/5, a particle for N = 6, 11, 16, 21, 31, 41, 81, 161.
//
// The reference: the same chain (springs, damping, holds, contact law, substeps) integrated in
// double at N_ref — in float32 the stiff axial springs turn a position's rounding into
// period-to-period grasp-force noise that grows with N (cbd catheter, insertion at 45°: 1 %, 2 %
// and 4 % of the peak at N = 11, 41, 81) — and by default extrapolated (Richardson, first
// order observed from N_ref, N_ref/2 and N_ref/4, per scenario and output family). The grasp
// force converges at second order since the grasp hinges (hinge_stiffness in catheter.hpp:
// the free part's first hinge gets the clamped root's 2 k_b); before them it converged at
// first order and was 44 % low at N = 11. Shapes converge at first to second order (the mass
// ends are not halved).
//
// Errors: the grasp force also chatters from period to period while the tip slides on the
// penalty wall (in double too; up to ~2 % of the peak), and that chatter does not converge
// sample by sample, so the force error compares forces averaged over a sliding window (10 ms,
// centred, by default); the per-period error is reported beside it. Positions are compared
// per period.
//
// Same physics at every N: the definition's damping b is per particle (force −b v), given for
// its own particle count N_def; the study uses b_N = b · N_def / N at N particles, which keeps
// b/m — the decay rate of every mode, docs/catheter.md — and the damping per metre of catheter
// the same for every N. Wall contact: particle spheres (outer radius) against the plane, one
// ContactPlane per particle within radius + margin of it, found once per period from the
// positions (as the trainer finds wall contacts), with the [contact] table's stiffness,
// damping and force clamp.
//
// Cost: the catheter's cycle in the first insertion scenario's loaded state (push done, tip on
// the wall), warm-up then repetitions: CycleCost::median/p99 = wall search + set_contact_planes
// + holds + step(period); haptic_median/p99 = step(period) alone.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "trainer/core/expected.hpp"
#include "trainer/model/catheter.hpp"
#include "trainer/model_offline/modal_tradeoff.hpp"  // CycleCostOptions, CycleCost

namespace trainer::model::offline {

enum class CatheterScenarioKind : std::uint8_t { insertion, cantilever };
const char* to_string(CatheterScenarioKind kind);

// One deterministic script. The catheter's rest shape is straight along +x from the origin;
// the wall tilts towards +y and the cantilever's force is along +y, so the catheter bends in
// the x–y plane.
struct CatheterScenario {
  std::string name;
  std::string description;
  bool tuning = false;  // true: a configuration is chosen on it; false: held out (validation)
  CatheterScenarioKind kind = CatheterScenarioKind::insertion;
  double duration_s = 1.5;  // a whole number of haptic periods
  // insertion
  double grasp_arc_length_m = 0.0;  // the front held particle (the nearest); the one behind too
  double push_m = 0.0;              // how far the grasp advances along +x …
  double push_time_s = 1.0;         // … on a cosine ramp (zero velocity at both ends), then held
  double wall_angle_deg = 45.0;     // between the rest axis and the wall plane (90 = head-on)
  double wall_gap_m = 0.0;          // the tip's sphere touches the wall after this much travel
  // cantilever
  double tip_load = 0.0;      // F L² / EI of the transverse tip force once ramped
  double load_time_s = 0.5;   // cosine ramp of the force, then held
};

// The defaults for a catheter of length L (every length scales with it): tuning — an
// insertion grasped at 0.8 L (as the cbd scene's forceps hold its catheter near the tip),
// pushed 0.06 L in 1 s against a wall at 45° whose gap is 0.01 L, held to 1.5 s, and a
// cantilever loaded to F L²/EI = 2 in 0.5 s, held to 1.5 s; held out — the same insertion
// against a steeper wall (60°, nearer head-on, the free part nearer buckling).
std::vector<CatheterScenario> default_catheter_scenarios(double length_m);

// The rigid wall's contact (the definition's [contact] table; defaults as docs/config.md).
struct CatheterWallContact {
  double stiffness_n_per_m = 500.0;
  double damping_n_s_per_m = 0.02;
  double max_force_n = 4.0;
  double detection_margin_m = 0.001;  // a plane is set for particles within radius + this
};

struct CatheterStudySpec {
  CatheterParams params;              // the definition; params.particle_count = N_def (damping)
  std::uint32_t max_substeps = 64;    // the definition's budget: larger N is refused
  double haptic_period_s = 1e-3;
  std::uint32_t reference_particle_count = 81;  // run in double, without a budget
  // Richardson extrapolation with the observed order from N_ref, N_half = (N_ref − 1)/2 + 1 and
  // N_quarter = (N_half − 1)/2 + 1 (N_ref = 4k + 1; the grasp must be a particle of all three):
  // H(N_ref) + (H(N_ref) − H(N_half)) / (2^p − 1); false: the plain N_ref run.
  bool extrapolate_reference = true;
  double force_window_s = 0.01;  // sliding mean of the grasp force before comparing (centred)
  CatheterWallContact contact;
};

struct CatheterTradeConfig {
  std::uint32_t particle_count = 21;
  std::string label() const;  // e.g. "N21"
};

struct CatheterScenarioError {
  std::string scenario;
  bool tuning = false;
  CatheterScenarioKind kind = CatheterScenarioKind::insertion;
  double grasp_arc_length_m = 0.0;  // where this N's front held particle is (insertion)
  // max_t |F − F_ref| / max_t |F_ref| of the grasp force, both averaged over the force window
  // (insertion only; 0 for a cantilever, where the force is imposed and the clamp's reaction is
  // not a physical point force).
  double force_error = 0.0;
  double force_error_per_period = 0.0;  // the same without the window
  double tip_error = 0.0;    // max_t |x_tip − x_tip,ref| / L
  double shape_error = 0.0;  // max over t and the four stations of |x(s) − x_ref(s)| / L
  double error = 0.0;        // the scenario's figure: max(force_error, shape_error)
  double reference_peak_force_n = 0.0;  // max_t |F_ref| over the window (insertion)
  double reference_peak_tip_travel_m = 0.0;  // max_t |x_tip,ref(t) − x_tip(0)|
};

struct CatheterTradePoint {
  CatheterTradeConfig config;
  // Catheter::create refused this N within the study's max_substeps: `refusal` is its message.
  // stable_substep_s and substeps_per_period are still what it would need; errors and cost are
  // measured only when measure() was asked to go beyond the budget.
  bool refused = false;
  std::string refusal;
  bool measured = false;  // errors and cost below are valid
  double stable_substep_s = 0.0;
  std::uint32_t substeps_per_period = 0;
  double damping_n_s_per_m = 0.0;  // b at this N
  std::size_t state_bytes = 0;     // arena bytes Catheter::create took
  CycleCost cost;
  std::vector<CatheterScenarioError> errors;
  double tuning_error = 0.0;      // worst scenario error over the tuning scenarios
  double validation_error = 0.0;  // worst over the held-out scenarios
  double worst_error = 0.0;       // worst over all
};

class CatheterTradeStudy {
 public:
  // Checks the definition (Catheter::create at its own N, the budget ignored), the scenarios
  // (durations whole numbers of periods, grasp within the chain, positive loads) and runs every
  // scenario at the reference N in double (and at N_half when extrapolating).
  static core::Expected<std::unique_ptr<CatheterTradeStudy>> create(
      CatheterStudySpec spec, std::vector<CatheterScenario> scenarios);

  // One configuration, through the float32 runtime Catheter. A refusal of Catheter::create
  // within the budget is a result (refused), not an error; with measure_beyond_budget the
  // refused N is still run (unbudgeted) so a tool can show what the budget costs in accuracy.
  // Errors: an N outside 3..kMaxParticles, a grasp that N cannot resolve, a step that fails
  // (non-finite state), bad cost options.
  core::Expected<CatheterTradePoint> measure(const CatheterTradeConfig& config,
                                             const CycleCostOptions& cost_options,
                                             bool measure_beyond_budget = false) const;

  const CatheterStudySpec& spec() const { return spec_; }
  const std::vector<CatheterScenario>& scenarios() const { return scenarios_; }
  double reference_run_s() const { return reference_run_s_; }  // wall time of the reference runs
  std::uint32_t reference_substeps_per_period() const { return reference_substeps_; }
  // When extrapolating: the plain N_ref run (double) against the extrapolated reference, per
  // scenario — what a plain reference would be off by (empty otherwise).
  const std::vector<CatheterScenarioError>& reference_check() const { return reference_check_; }
  // When extrapolating: the observed convergence order per scenario, of the station positions
  // and of the grasp force (0 without a grasp), each within [1, 2].
  struct ReferenceOrder {
    double shape = 0.0;
    double force = 0.0;
  };
  const std::vector<ReferenceOrder>& reference_orders() const { return reference_orders_; }

  // Per-period outputs of one run of one scenario (period k ends at (k + 1)·period).
  struct History {
    std::vector<Eigen::Vector3d> grasp_force_n;               // insertion; else empty
    std::vector<std::array<Eigen::Vector3d, 4>> stations_m;   // station 3 is the tip
    double grasp_arc_length_m = 0.0;
  };
  // Runs one scenario at N particles, no budget: float32 = the runtime Catheter (what measure()
  // compares), float64 = the reference chain (what create() compares with).
  core::Expected<History> run(const CatheterScenario& scenario, std::uint32_t particle_count,
                              RuntimePrecision precision) const;
  // The errors of a history of scenario `index` against its reference.
  CatheterScenarioError compare(std::size_t index, const History& history) const;

 private:
  CatheterTradeStudy() = default;

  CatheterStudySpec spec_;
  std::vector<CatheterScenario> scenarios_;
  std::vector<History> references_;
  double reference_run_s_ = 0.0;
  std::uint32_t reference_substeps_ = 0;
  std::vector<CatheterScenarioError> reference_check_;
  std::vector<ReferenceOrder> reference_orders_;
};

// Position at arc length s (m, clamped to [0, L]) of a chain of equal rest segments of
// `segment_m`, interpolated linearly between the two particles around it.
template <class Scalar>
Eigen::Vector3d chain_point_at(std::span<const Eigen::Matrix<Scalar, 3, 1>> positions_m,
                               double segment_m, double arc_length_m) {
  if (positions_m.empty()) return Eigen::Vector3d::Zero();
  if (positions_m.size() == 1) return positions_m.front().template cast<double>();
  const double position = std::clamp(arc_length_m / segment_m, 0.0,
                                     static_cast<double>(positions_m.size() - 1));
  const auto lower = static_cast<std::size_t>(
      std::min(std::floor(position), static_cast<double>(positions_m.size() - 2)));
  const double fraction = position - static_cast<double>(lower);
  return (1.0 - fraction) * positions_m[lower].template cast<double>() +
         fraction * positions_m[lower + 1].template cast<double>();
}

}  // namespace trainer::model::offline
