// What the haptic cycle counts over a run, for the report (docs/report.md): per instrument,
// per model, per stage. Every stage adds to its own part; nothing here is read back by the
// cycle. Plain data, no heap (fixed arrays sized by the scene limits).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "trainer/app/substage_timer.hpp"
#include "trainer/app/telemetry.hpp"  // kMaxInstruments
#include "trainer/core/histogram.hpp"

namespace trainer::app {

// Models one scene may name (the per-model statistics are sized by it).
inline constexpr std::size_t kMaxSceneModels = 4;

struct InstrumentStats {
  float peak_force_n = 0.0F;
  float peak_depth_m = 0.0F;
  double force_sum_n = 0.0;  // over contact cycles, for the mean
  std::uint64_t contact_cycles = 0;
  std::uint64_t contact_onsets = 0;
  std::array<float, 5> peak_joint_effort{};
  // Against catheters: grasps started, slips (pulled out of the jaws), cycles holding one,
  // and the largest squeeze on both jaws together.
  std::uint64_t grasps = 0;
  std::uint64_t slips = 0;
  std::uint64_t grasping_cycles = 0;
  float peak_squeeze_n = 0.0F;
  std::uint64_t catheter_contact_cycles = 0;      // the shaft or a jaw pushed a catheter
  std::uint64_t wall_segment_contact_cycles = 0;  // the shaft or a jaw held a duct's wall
};

// What a modal model (the duct) took from the tools and catheters over the run.
struct ModalModelStats {
  float peak_force_n = 0.0F;  // |total force on the model| in one cycle
  double force_sum_n = 0.0;   // over cycles with any load, for the mean
  std::uint64_t loaded_cycles = 0;
  std::uint64_t tool_contact_cycles = 0;
  std::uint64_t catheter_contact_cycles = 0;
  std::uint32_t peak_catheter_contacts = 0;  // particle–wall contacts in one cycle
  float peak_catheter_force_n = 0.0F;        // |total catheter force on the model|
};

// What a tensor model (Cotin's liver) took from the tools over the run.
struct TensorModelStats {
  float peak_force_n = 0.0F;             // |total force on the model| in one cycle
  double force_sum_n = 0.0;              // over loaded cycles, for the mean
  std::uint64_t loaded_cycles = 0;       // cycles with at least one tool contact
  std::uint64_t contact_onsets = 0;      // tool contacts started
  std::uint32_t peak_contact_nodes = 0;  // nodes imposed in one solve
  float peak_indentation_m = 0.0F;       // largest imposed node displacement
  std::uint64_t refused_solves = 0;      // solves the model refused (contacts released)
};

// Catheter progress against its [model.insertion] goal.
struct CatheterStats {
  float insertion_depth_m = 0.0F;  // at the last cycle
  float peak_insertion_depth_m = 0.0F;
  std::uint64_t first_target_cycle = 0;  // the first cycle at or past the target depth
  float peak_held_depth_m = 0.0F;        // the peak while an instrument grasped the catheter
  bool target_reached = false;
  std::uint64_t wall_contact_cycles = 0;
  std::uint64_t dropped_contacts = 0;  // beyond a capacity (counted, not applied)
};

// The stages of one cycle, in the order they run (shared/DESIGN.md "One cycle"); the stage
// runner times each (ns per cycle, real clock, also in simulated time). A stage the scene does
// not need (no modal model, no tensor model, no catheter) is not run and records nothing.
enum class CyclePhase : std::uint8_t {
  hal_read = 0,   // encoders, digital inputs, drive status; the safety chain's input checks
  kinematics,     // joint positions and rates, forward kinematics of every instrument
  modal_models,   // tool–duct contact (grid query, contact solve), the duct's step, its surface
  tensor_models,  // tool–tissue contact on Cotin's tensor models (solve, field, surface)
  catheters,  // catheter–wall and tool–catheter collision, grasping, the catheter's substeps
  forces,     // rigid objects, the safety chain's force limits, Jᵀ efforts
  hal_write,  // actuator commands, digital outputs
  publish,    // fault log, telemetry snapshot
};
inline constexpr std::size_t kCyclePhaseCount = 8;
inline constexpr std::array<const char*, kCyclePhaseCount> kCyclePhaseNames = {
    "hal_read",  "kinematics", "modal_models", "tensor_models",
    "catheters", "forces",     "hal_write",    "publish"};

struct AppStats {
  std::uint64_t cycles = 0;
  std::array<core::LatencyHistogram, kCyclePhaseCount> phase_ns{};
  // Finer than the phases (substage_timer.hpp): one sample per cycle for each sub-stage of the
  // stages the scene runs, none for the others.
  std::array<core::LatencyHistogram, kSubstageCount> substage_ns{};
  // The live lap timer the stages call (stats_->laps.lap(Substage::x)); the stage runner
  // marks each stage's start and records the cycle's laps into substage_ns. Not a statistic.
  SubstageTimer laps;
  std::uint64_t hal_read_errors = 0;
  std::uint64_t hal_write_errors = 0;
  std::uint64_t invalid_encoder_cycles = 0;
  std::uint64_t saturated_actuator_cycles = 0;
  // Instrument-cycles whose efforts the actuators' effort limits scaled or clamped
  // (force_command.hpp); the drives then never clip.
  std::uint64_t effort_limited_cycles = 0;
  std::uint64_t armed_cycles = 0;
  std::uint64_t model_step_errors = 0;
  std::array<InstrumentStats, kMaxInstruments> instruments{};
  std::array<ModalModelStats, kMaxSceneModels> modal_models{};    // modal models in scene order
  std::array<TensorModelStats, kMaxSceneModels> tensor_models{};  // tensor models in scene order
  std::array<CatheterStats, kMaxSceneModels> catheters{};         // catheters in scene order
};

}  // namespace trainer::app
