// Stage kinematics: joint positions and rates, then each instrument's pose about its trocar.
// Owns: per instrument, the last good joint reading and the low-passed joint rates.
// Reads: frame.encoder_samples (joint-side SI, HAL contract), frame.newly_armed (rates restart
// from zero when the chain arms), the instruments' rigs.
// Writes: frame.instruments[i] joints, pose, tip velocity, last tip; clears the model stages'
// per-instrument outputs; the supervisor's encoder-jump and non-finite checks.
#pragma once

#include <span>

#include "stages/instrument_rig.hpp"
#include "trainer/app/app_stats.hpp"
#include "trainer/app/stage_runner.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/safety/safety_supervisor.hpp"

namespace trainer::app {

class KinematicsStage final : public CycleStage {
 public:
  // Joint rates come from differentiated encoder positions, low-passed at this cutoff: high
  // enough not to lag the hand (human motion < 10 Hz), low enough to tame quantisation noise
  // (one count per cycle at 1 kHz would otherwise read as several rad/s).
  static constexpr double kVelocityCutoffHz = 150.0;

  static core::Expected<KinematicsStage> create(std::span<const InstrumentRig> rigs,
                                                safety::SafetySupervisor& safety, AppStats& stats,
                                                core::Arena& arena);

  void run(CycleFrame& frame) noexcept override;

 private:
  struct JointState {
    kinematics::JointVector position{};
    kinematics::JointVector velocity{};
    bool has_position = false;
  };
  KinematicsStage(std::span<const InstrumentRig> rigs, std::span<JointState> joints,
                  safety::SafetySupervisor& safety, AppStats& stats) noexcept
      : rigs_(rigs), joints_(joints), safety_(&safety), stats_(&stats) {}
  // The joint reading of one instrument: checked, filtered, held when invalid.
  void sense_joints(std::size_t index, const CycleFrame& frame) noexcept;

  std::span<const InstrumentRig> rigs_;
  std::span<JointState> joints_;
  safety::SafetySupervisor* safety_;
  AppStats* stats_;
};

}  // namespace trainer::app
