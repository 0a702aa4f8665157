// The stage runner: stages run in DESIGN.md's order and only in it, each timed into its own
// phase on the runner's clock; the wall scene's app runs exactly the stages it needs.
#include <array>
#include <memory>
#include <vector>

#include <gtest/gtest.h>

#include "trainer/app/haptic_app.hpp"
#include "trainer/app/device_wiring.hpp"
#include "trainer/app/stage_runner.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/hal_sim/sim_device.hpp"

namespace trainer::app {
namespace {

// Records its turn and advances the runner's clock by a known cost.
class CountingStage final : public CycleStage {
 public:
  CountingStage(core::ManualClock& clock, std::vector<int>& order, int id, std::int64_t cost_ns)
      : clock_(clock), order_(order), id_(id), cost_ns_(cost_ns) {}
  void run(CycleFrame& /*frame*/) noexcept override {
    order_.push_back(id_);
    clock_.advance_ns(cost_ns_);
  }

 private:
  core::ManualClock& clock_;
  std::vector<int>& order_;
  int id_;
  std::int64_t cost_ns_;
};

TEST(StageRunner, RunsStagesInOrderAndTimesEachIntoItsPhase) {
  core::ManualClock clock(0);
  std::vector<int> order;
  order.reserve(16);
  CountingStage read(clock, order, 0, 1000);
  CountingStage forces(clock, order, 1, 5000);
  CountingStage publish(clock, order, 2, 300);
  StageRunner runner(clock);
  ASSERT_TRUE(runner.add(CyclePhase::hal_read, read));
  ASSERT_TRUE(runner.add(CyclePhase::forces, forces));
  ASSERT_TRUE(runner.add(CyclePhase::publish, publish));
  EXPECT_EQ(runner.stage_count(), 3U);
  EXPECT_TRUE(runner.has(CyclePhase::forces));
  EXPECT_FALSE(runner.has(CyclePhase::modal_models));

  CycleFrame frame;
  auto stats = std::make_unique<AppStats>();
  for (int cycle = 0; cycle < 4; ++cycle) runner.run(frame, *stats);
  EXPECT_EQ(order, (std::vector<int>{0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2}));
  const auto phase = [&](CyclePhase p) -> const core::LatencyHistogram& {
    return stats->phase_ns[static_cast<std::size_t>(p)];
  };
  EXPECT_EQ(phase(CyclePhase::hal_read).count(), 4U);
  EXPECT_EQ(phase(CyclePhase::hal_read).max_ns(), 1000);
  EXPECT_EQ(phase(CyclePhase::forces).min_ns(), 5000);
  EXPECT_EQ(phase(CyclePhase::publish).max_ns(), 300);
  EXPECT_EQ(phase(CyclePhase::modal_models).count(), 0U);  // not run, nothing recorded
  for (const core::LatencyHistogram& substage : stats->substage_ns)
    EXPECT_EQ(substage.count(), 0U);  // no stage with sub-stages ran
}

// A stage with sub-stages: each lap takes the time since the stage's start or the previous
// lap; laps of one sub-stage add up within a cycle; a sub-stage skipped in a cycle records 0.
class LappingStage final : public CycleStage {
 public:
  LappingStage(core::ManualClock& clock, AppStats& stats) : clock_(clock), stats_(stats) {}
  void run(CycleFrame& /*frame*/) noexcept override {
    clock_.advance_ns(100);
    stats_.laps.lap(Substage::modal_near);
    if (with_collision_) {
      clock_.advance_ns(700);
      stats_.laps.lap(Substage::modal_collision);
    }
    clock_.advance_ns(200);
    stats_.laps.lap(Substage::modal_reconstruct);
    clock_.advance_ns(50);
    stats_.laps.lap(Substage::modal_reconstruct);
    clock_.advance_ns(30);  // after the last lap: in the stage's time only
  }
  bool with_collision_ = true;

 private:
  core::ManualClock& clock_;
  AppStats& stats_;
};

TEST(StageRunner, LapsSplitAStageIntoItsSubstages) {
  core::ManualClock clock(0);
  auto stats = std::make_unique<AppStats>();
  LappingStage modal(clock, *stats);
  StageRunner runner(clock);
  ASSERT_TRUE(runner.add(CyclePhase::modal_models, modal));
  EXPECT_EQ(phase_of(Substage::modal_refit), CyclePhase::modal_models);
  EXPECT_EQ(phase_of(Substage::catheter_step), CyclePhase::catheters);
  CycleFrame frame;
  runner.run(frame, *stats);
  const auto substage = [&](Substage s) -> const core::LatencyHistogram& {
    return stats->substage_ns[static_cast<std::size_t>(s)];
  };
  EXPECT_EQ(stats->laps.last_ns(Substage::modal_near), 100);
  EXPECT_EQ(stats->laps.last_ns(Substage::modal_collision), 700);
  EXPECT_EQ(stats->laps.last_ns(Substage::modal_reconstruct), 250);
  EXPECT_EQ(stats->laps.last_ns(Substage::modal_solve), 0);
  EXPECT_EQ(runner.last_ns(CyclePhase::modal_models), 1080);
  modal.with_collision_ = false;
  runner.run(frame, *stats);
  EXPECT_EQ(stats->laps.last_ns(Substage::modal_collision), 0);
  // Every modal sub-stage has one sample per cycle; the catheter's none (no catheter stage).
  EXPECT_EQ(substage(Substage::modal_collision).count(), 2U);
  EXPECT_EQ(substage(Substage::modal_collision).max_ns(), 700);
  EXPECT_EQ(substage(Substage::modal_collision).min_ns(), 0);
  EXPECT_EQ(substage(Substage::modal_refit).count(), 2U);
  EXPECT_EQ(substage(Substage::modal_refit).max_ns(), 0);
  EXPECT_EQ(substage(Substage::catheter_step).count(), 0U);
  // A lap outside a runner (a stage run directly) does nothing.
  stats->laps.begin_cycle();
  modal.run(frame);
  EXPECT_EQ(stats->laps.touched(), 0U);
}

TEST(StageRunner, RefusesAPhaseOutOfOrderOrTwice) {
  core::ManualClock clock(0);
  std::vector<int> order;
  CountingStage stage(clock, order, 0, 1);
  StageRunner runner(clock);
  ASSERT_TRUE(runner.add(CyclePhase::kinematics, stage));
  EXPECT_FALSE(runner.add(CyclePhase::kinematics, stage));
  EXPECT_FALSE(runner.add(CyclePhase::hal_read, stage));
  EXPECT_TRUE(runner.add(CyclePhase::catheters, stage));
  EXPECT_EQ(runner.stage_count(), 2U);
}

// A scene runs only the model stages it has models for: the wall scene (rigid objects only)
// none, so a cycle there costs no model stage at all.
TEST(StageRunner, TheWallSceneRunsNoModelStage) {
  auto scene = config::load_scene(std::string(TRAINER_SOURCE_DIR) + "/config/scenes/wall.toml");
  ASSERT_TRUE(scene) << scene.error().message;
  core::ManualClock clock(0);
  hal::sim::SimDevice device(clock, sim_params_from(*scene));
  ASSERT_TRUE(device.configure());
  ASSERT_TRUE(device.activate());
  auto arena = core::Arena::create(scene->memory.arena_bytes);
  ASSERT_TRUE(arena);
  core::LogRing log;
  core::TripleBuffer<TelemetrySnapshot> telemetry;
  auto app = HapticApp::create(
      *scene,
      {device.encoders(), device.actuators(), device.digital_inputs(), device.digital_outputs()},
      *arena, log, telemetry, clock);
  ASSERT_TRUE(app) << app.error().message;
  EXPECT_EQ(
      (*app)->stage_phases(),
      (std::vector<CyclePhase>{CyclePhase::hal_read, CyclePhase::kinematics, CyclePhase::forces,
                               CyclePhase::hal_write, CyclePhase::publish}));
  loop::CycleTiming timing{};
  timing.dt_s = 1e-3;
  for (std::uint64_t i = 0; i < 10; ++i) {
    clock.advance_ns(1'000'000);
    timing.cycle_index = i;
    timing.wake_ns = timing.deadline_ns = clock.now_ns();
    (void)(*app)->run_cycle(timing);
  }
  const AppStats& stats = (*app)->stats();
  EXPECT_EQ(stats.phase_ns[static_cast<std::size_t>(CyclePhase::forces)].count(), 10U);
  EXPECT_EQ(stats.phase_ns[static_cast<std::size_t>(CyclePhase::modal_models)].count(), 0U);
  EXPECT_EQ(stats.phase_ns[static_cast<std::size_t>(CyclePhase::catheters)].count(), 0U);
}

}  // namespace
}  // namespace trainer::app
