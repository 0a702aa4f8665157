// The speed/accuracy trade of the reduced-modal duct, measured: for a configuration (mode
// count r, static correction, bending element, runtime precision, time step) it builds the
// image data as `modelc build` would, runs the runtime model through contact scenarios the way
// the trainer's tool tips load it (displacement-driven contact: the touched node is put at an
// imposed displacement, the model returns the force the tool feels), and compares that force
// with the full-FEM reference (DNIOS: Newmark on every free dof, double, same imposed
// displacement, a finer time step); and it times the runtime's per-cycle work (contact solve,
// step, surface reconstruction) with warm-up and repetitions. `tradeoff` sweeps it and plots
// the Pareto front; `modelc build --error-budget` picks the cheapest configuration from it.
//
// Errors are of the force felt, sampled at the configuration's own step times (the reference is
// interpolated linearly in time between its finer steps): the error of a scenario is the RMS
// over its samples of |F − F_ref(t)| over the RMS of |F_ref| (what the budget is checked
// against); the peak error, max_t |F − F_ref| / max_t |F_ref|, is reported beside it. A
// configuration's error is its worst scenario's. The RMS is the budget's measure because the
// peak is set by one or two samples of the transient at a fast press, where the 1 ms step's
// own ringing (Newmark's period error for ω Δt > 1, common to every r) dominates whatever r is.
#pragma once

#include <cstddef>
#include <map>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include <Eigen/Core>

#include "trainer/core/expected.hpp"
#include "trainer/model_offline/modal_build.hpp"

namespace trainer::model::offline {

// Depth and drag of the imposed displacement at one instant (piecewise linear in between).
struct ContactKeyframe {
  double time_s = 0.0;
  double depth_m = 0.0;                           // along the node's inward normal
  Eigen::Vector3d drag_m = Eigen::Vector3d::Zero();  // tangential: the sticking tip drags
};

// One tool tip on the duct: the surface node nearest `point_m` is the contact node for the whole
// scenario (the trainer's tip contact sticks to the material point it touched).
struct ContactScenario {
  std::string name;
  std::string description;
  bool tuning = false;  // true: a configuration is chosen on it; false: held out (validation)
  Eigen::Vector3d point_m = Eigen::Vector3d::Zero();
  std::vector<ContactKeyframe> keyframes;  // strictly increasing times, first at 0
  double duration_s() const { return keyframes.empty() ? 0.0 : keyframes.back().time_s; }
};

enum class RuntimePrecision : std::uint8_t { float32, float64 };
const char* to_string(RuntimePrecision precision);

struct ModalTradeConfig {
  int modes = 40;
  bool static_correction = true;
  BendingElement element = BendingElement::dkt;
  RuntimePrecision precision = RuntimePrecision::float32;
  double time_step_s = 0.001;
  std::string label() const;  // e.g. "r40 sc dkt f32 dt1000us"
};

struct CycleCostOptions {
  int warmup_cycles = 1000;
  int repetitions = 5;
  int cycles_per_repetition = 2000;
};

// Per-cycle wall time of the runtime's work for one tool in contact: solve_imposed + step +
// reconstruct of the whole surface (the trainer refreshes the duct's collision surface every
// cycle a tool is near). Percentiles over all timed cycles of all repetitions.
struct CycleCost {
  double median_ns = 0.0;
  double p99_ns = 0.0;
  double haptic_median_ns = 0.0;  // solve_imposed + step only (what the force needs)
  double haptic_p99_ns = 0.0;
  double repetition_median_min_ns = 0.0;  // spread of the repetitions' medians
  double repetition_median_max_ns = 0.0;
  int warmup_cycles = 0;
  int repetitions = 0;
  int cycles_per_repetition = 0;
};

struct ScenarioError {
  std::string scenario;
  bool tuning = false;
  int contact_node = -1;
  double peak_error = 0.0;  // max_t |F − F_ref| / max_t |F_ref|
  double rms_error = 0.0;   // RMS over samples of |F − F_ref| / RMS of |F_ref|
  double reference_peak_force_n = 0.0;
};

struct ModalTradePoint {
  ModalTradeConfig config;
  double precompute_s = 0.0;     // build_modal_model of this configuration's image
  std::size_t data_bytes = 0;    // mode shapes + ω² + damping + residual compliance as stored
  CycleCost cost;
  std::vector<ScenarioError> errors;
  double tuning_error = 0.0;      // worst RMS error over the tuning scenarios
  double validation_error = 0.0;  // worst RMS error over the held-out scenarios
  double worst_error = 0.0;       // worst RMS error over all
  double worst_peak_error = 0.0;  // worst peak error over all
};

// The reference scenarios for a duct-like model (any shell mesh: positions are taken from the
// mesh's bounding box, along its longest axis, depths from its smaller half-extent ρ):
// two tuning indentations (mid-length top 0.25 ρ slow, near the free end 0.5 ρ fast) and three
// held out (quarter-length bottom 0.35 ρ, a deep 0.7 ρ press, and a press-and-drag 0.25 ρ deep
// dragged 0.3 ρ along the axis), 0.2 s each.
std::vector<ContactScenario> default_duct_scenarios(const ShellMesh& mesh);

class DuctTradeStudy {
 public:
  // Builds the definition once (its element, mode count and damping ratio fix the physical
  // Rayleigh damping every configuration then shares) and integrates every scenario with
  // DNIOS at `reference_time_step_s` (it must divide every configuration's step).
  static core::Expected<std::unique_ptr<DuctTradeStudy>> create(
      ModalBuildSpec definition, std::vector<ContactScenario> scenarios,
      double reference_time_step_s);

  core::Expected<ModalTradePoint> measure(const ModalTradeConfig& config,
                                          const CycleCostOptions& cost_options);

  const std::vector<ContactScenario>& scenarios() const { return scenarios_; }
  const ModalBuildSpec& definition() const { return definition_; }
  double reference_time_step_s() const { return reference_time_step_s_; }
  double reference_build_s() const { return reference_build_s_; }
  double reference_step_ns() const { return reference_step_ns_; }  // median DNIOS step
  const RayleighDamping& damping() const { return damping_; }
  // The build of a configuration (cached per element, modes, correction).
  core::Expected<std::shared_ptr<const ModalBuildResult>> build_for(const ModalTradeConfig& config,
                                                                    double* build_s = nullptr);
  ModalBuildSpec spec_for(const ModalTradeConfig& config) const;

 private:
  struct ReferenceHistory {
    int contact_node = -1;
    Eigen::Vector3d inward = Eigen::Vector3d::Zero();
    std::vector<Eigen::Vector3d> forces;  // at t = (k + 1) Δt_ref
  };
  DuctTradeStudy() = default;
  // Accuracy over every scenario and cycle cost of one configuration, on the runtime model
  // instantiated for `Scalar` (float: as the appliance runs an image; double: the same build).
  template <typename Scalar>
  core::Expected<void> measure_runtime(const ModalTradeConfig& config,
                                       const CycleCostOptions& cost_options,
                                       const ModalBuildSpec& spec, const ModalBuildResult& build,
                                       ModalTradePoint& point) const;

  ModalBuildSpec definition_;
  std::vector<ContactScenario> scenarios_;
  std::vector<ReferenceHistory> references_;
  double reference_time_step_s_ = 0.0;
  double reference_build_s_ = 0.0;
  double reference_step_ns_ = 0.0;
  RayleighDamping damping_;
  std::map<std::tuple<int, int, bool>, std::pair<std::shared_ptr<const ModalBuildResult>, double>>
      builds_;
};

// Target displacement (m) of a scenario at time t for a node with inward unit normal `inward`.
Eigen::Vector3d scenario_target(const ContactScenario& scenario, const Eigen::Vector3d& inward,
                                double time_s);

struct BudgetChoice {
  ModalTradePoint chosen;
  std::vector<ModalTradePoint> candidates;  // every configuration measured, cheapest first
  std::vector<std::string> log;             // why each cheaper candidate was passed over
};

// The cost a budget choice compares: the smallest of the repetitions' median cycle times (the
// least disturbed repetition: on a shared machine other work only ever adds time), per
// millisecond of simulated time (a 4 kHz configuration runs four cycles where a 1 kHz one runs
// one). Falls back to the overall median when there are no repetition medians.
double selection_cost_ns(const ModalTradePoint& point);

// Index into `points` of the cheapest one meeting `budget` (rules of choose_for_budget below),
// appending to `log` why each cheaper point was passed over; an error names the most accurate
// point when none meets it.
core::Expected<std::size_t> select_for_budget(const std::vector<ModalTradePoint>& points,
                                              double budget, std::vector<std::string>* log);

// The cheapest configuration among `candidates` whose worst RMS error on the tuning scenarios
// is within `budget` (a fraction, 0.02 = 2 %) and which then also meets it on the held-out
// scenarios. "Cheapest" is selection_cost_ns; candidates within 5 % of each other count as
// equally cheap and the simpler wins (longer step, then fewer modes, then correction off), so
// noise does not pick a larger model. Refuses when no candidate meets the budget, naming the best one.
core::Expected<BudgetChoice> choose_for_budget(DuctTradeStudy& study, double budget,
                                               const std::vector<ModalTradeConfig>& candidates,
                                               const CycleCostOptions& cost_options);

}  // namespace trainer::model::offline
