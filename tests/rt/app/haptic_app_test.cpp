// The haptic cycle on the simulated bench, driven cycle by cycle on a manual clock:
// the wall scene's physics, and the safety chain's "zero force in the same cycle".
#include "trainer/app/haptic_app.hpp"

#include <cmath>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <gtest/gtest.h>

#include "trainer/app/device_wiring.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/hal_sim/sim_device.hpp"

namespace trainer::app {
namespace {

class WallSceneFixture : public ::testing::Test {
 protected:
  void SetUp() override {
    auto scene = config::load_scene(std::string(TRAINER_SOURCE_DIR) + "/config/scenes/wall.toml");
    ASSERT_TRUE(scene) << scene.error().message;
    scene_ = std::move(*scene);
    device_ = std::make_unique<hal::sim::SimDevice>(clock_, sim_params_from(scene_));
    ASSERT_TRUE(device_->configure());
    ASSERT_TRUE(device_->activate());
    auto arena = core::Arena::create(scene_.memory.arena_bytes);
    ASSERT_TRUE(arena);
    arena_ = std::make_unique<core::Arena>(std::move(*arena));
    auto app = HapticApp::create(scene_,
                                 {device_->encoders(), device_->actuators(),
                                  device_->digital_inputs(), device_->digital_outputs()},
                                 *arena_, log_, telemetry_, clock_);
    ASSERT_TRUE(app) << app.error().message;
    app_ = std::move(*app);
    arena_->seal();
  }

  // Runs one cycle at the scene's period on the manual clock.
  void step() {
    const std::int64_t period = scene_.loop.period_ns;
    clock_.advance_ns(period);
    loop::CycleTiming timing{};
    timing.cycle_index = cycle_++;
    timing.deadline_ns = clock_.now_ns();
    timing.wake_ns = clock_.now_ns();
    timing.dt_s = static_cast<double>(period) * 1e-9;
    (void)app_->run_cycle(timing);
  }
  void run_until_time(double seconds) {
    while (static_cast<double>(clock_.now_ns()) * 1e-9 < seconds) step();
  }
  double total_applied_effort() const {
    double sum = 0.0;
    for (std::size_t c = 0; c < device_->actuator_count(); ++c) {
      sum += std::fabs(device_->applied_effort(c));
    }
    return sum;
  }
  float latest_force_norm() {
    (void)telemetry_.update();
    const auto& f = telemetry_.latest().instruments[0].force_n;
    return std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
  }

  config::SceneConfig scene_;
  core::ManualClock clock_{0};
  std::unique_ptr<hal::sim::SimDevice> device_;
  std::unique_ptr<core::Arena> arena_;
  core::LogRing log_;
  core::TripleBuffer<TelemetrySnapshot> telemetry_;
  std::unique_ptr<HapticApp> app_;
  std::uint64_t cycle_ = 0;
};

TEST_F(WallSceneFixture, UnarmedControllerCommandsNothing) {
  run_until_time(7.0);  // the script presses into the wall by now
  EXPECT_FALSE(app_->safety().armed());
  EXPECT_EQ(total_applied_effort(), 0.0);
  EXPECT_EQ(latest_force_norm(), 0.0F);
  EXPECT_GT(app_->stats().instruments[0].contact_cycles, 0U);  // contact detected regardless
}

TEST_F(WallSceneFixture, WallPushesBackWithSpringForce) {
  app_->request_reset();
  run_until_time(7.0);  // holding pressed into the wall (see wall_press.csv)
  ASSERT_TRUE(app_->safety().armed()) << app_->safety().first_fault_cycle();
  (void)telemetry_.update();
  const TelemetrySnapshot& snapshot = telemetry_.latest();
  ASSERT_TRUE(snapshot.instruments[0].in_contact);
  // Depth of the tip behind the wall plane, from the published tip position.
  const config::ObjectConfig& wall = scene_.objects[0];
  double depth = 0.0;
  for (int k = 0; k < 3; ++k) {
    depth -= (static_cast<double>(snapshot.instruments[0].tip_m[static_cast<std::size_t>(k)]) -
              wall.point_m[static_cast<std::size_t>(k)]) *
             wall.normal[static_cast<std::size_t>(k)];
  }
  ASSERT_GT(depth, 0.002);
  const auto force = static_cast<double>(latest_force_norm());
  // Quasi-static hold: force = k·depth within the damper's share and float rounding (5 %).
  EXPECT_NEAR(force, wall.stiffness_n_per_m * depth, 0.05 * wall.stiffness_n_per_m * depth);
  // The motors push the tool back out of the wall: the insertion axis effort is negative.
  EXPECT_LT(device_->applied_effort(2), -0.1);
}

TEST_F(WallSceneFixture, EstopZeroesForceInTheSameCycle) {
  app_->request_reset();
  run_until_time(7.0);
  ASSERT_GT(total_applied_effort(), 0.0);
  device_->set_estop(true);
  step();
  EXPECT_EQ(total_applied_effort(), 0.0);
  EXPECT_EQ(latest_force_norm(), 0.0F);
  EXPECT_EQ(app_->safety().first_fault(), safety::Fault::estop);
  // Releasing the e-stop does not re-arm.
  device_->set_estop(false);
  for (int i = 0; i < 100; ++i) step();
  EXPECT_FALSE(app_->safety().armed());
  EXPECT_EQ(total_applied_effort(), 0.0);
  // An explicit reset does.
  app_->request_reset();
  step();
  EXPECT_TRUE(app_->safety().armed());
}

TEST_F(WallSceneFixture, DriveFaultLatches) {
  app_->request_reset();
  run_until_time(7.0);
  ASSERT_TRUE(device_->inject_drive_fault(2, true));
  step();
  EXPECT_FALSE(app_->safety().armed());
  EXPECT_TRUE(app_->safety().latched_faults() & safety::bit(safety::Fault::drive_fault));
  EXPECT_EQ(total_applied_effort(), 0.0);
}

TEST_F(WallSceneFixture, ReadFailuresBeyondToleranceLatchDeviceLost) {
  app_->request_reset();
  run_until_time(1.0);
  device_->inject_read_failures(HapticApp::kToleratedErrorStreak);
  for (std::uint32_t i = 0; i < HapticApp::kToleratedErrorStreak + 2; ++i) step();
  EXPECT_TRUE(app_->safety().armed()) << "a short burst of read errors is tolerated";
  device_->inject_read_failures(HapticApp::kToleratedErrorStreak + 1);
  for (std::uint32_t i = 0; i < HapticApp::kToleratedErrorStreak + 1; ++i) step();
  EXPECT_EQ(app_->safety().first_fault(), safety::Fault::device_lost);
  EXPECT_EQ(total_applied_effort(), 0.0);
}

TEST_F(WallSceneFixture, AResetDoesNotClearAFaultTheSameCycleRaised) {
  app_->request_reset();
  run_until_time(1.0);
  device_->inject_read_failures(HapticApp::kToleratedErrorStreak + 3);
  for (std::uint32_t i = 0; i < HapticApp::kToleratedErrorStreak + 1; ++i) step();
  ASSERT_EQ(app_->safety().first_fault(), safety::Fault::device_lost);
  // A reset while the reads still fail: the cycle's read raises device_lost again, and the
  // reset must not clear it (nor arm on a failing device).
  app_->request_reset();
  step();
  EXPECT_FALSE(app_->safety().armed());
  ASSERT_TRUE(telemetry_.update());
  EXPECT_TRUE(telemetry_.latest().latched_faults & safety::bit(safety::Fault::device_lost));
  EXPECT_EQ(total_applied_effort(), 0.0);
  // The request was dropped: the device recovering does not arm by itself; a new reset does.
  for (int i = 0; i < 10; ++i) step();
  EXPECT_FALSE(app_->safety().armed());
  app_->request_reset();
  step();
  EXPECT_TRUE(app_->safety().armed());
}

TEST_F(WallSceneFixture, AResetDoesNotClearAnOverrunFaultNotYetPublished) {
  app_->request_reset();
  run_until_time(1.0);
  // The loop raises the overrun-streak fault between two cycles; a reset arriving for the
  // next cycle must leave it latched so that cycle publishes it.
  app_->on_overrun_fault(10);
  app_->request_reset();
  step();
  EXPECT_FALSE(app_->safety().armed());
  ASSERT_TRUE(telemetry_.update());
  EXPECT_TRUE(telemetry_.latest().latched_faults & safety::bit(safety::Fault::overrun_streak));
  app_->request_reset();
  step();
  EXPECT_TRUE(app_->safety().armed());
}

TEST_F(WallSceneFixture, StuckEncoderDoesNotProduceForceJumpsAndJumpLatches) {
  app_->request_reset();
  run_until_time(6.5);
  // Freeze insertion while the hand keeps moving, then release: the counts jump by the
  // distance travelled meanwhile, faster than max_insertion_speed allows.
  ASSERT_TRUE(device_->inject_stuck_encoder(2, true));
  run_until_time(9.5);  // the script withdraws by ~5 cm meanwhile
  ASSERT_TRUE(device_->inject_stuck_encoder(2, false));
  step();
  EXPECT_EQ(app_->safety().first_fault(), safety::Fault::encoder_jump);
  EXPECT_EQ(total_applied_effort(), 0.0);
}

// The "fault latched" records the cycle wrote, by fault name.
std::vector<std::string> drain_fault_records(core::LogRing& log) {
  std::vector<std::string> faults;
  core::LogRecord record;
  while (log.pop(record)) {
    if (std::string_view(record.format) == "fault latched: {} at cycle {}") {
      faults.emplace_back(record.args[0].s);
    }
  }
  return faults;
}

TEST_F(WallSceneFixture, AFaultLatchedInTheCycleThatArmsIsLoggedAgain) {
  app_->request_reset();
  run_until_time(6.5);
  ASSERT_TRUE(device_->inject_stuck_encoder(2, true));
  run_until_time(9.5);
  ASSERT_TRUE(device_->inject_stuck_encoder(2, false));
  step();
  ASSERT_EQ(app_->safety().first_fault(), safety::Fault::encoder_jump);
  EXPECT_EQ(drain_fault_records(log_), std::vector<std::string>{"encoder_jump"});
  // Stuck again while faulted; the reset arms and the same cycle's reading jumps again.
  ASSERT_TRUE(device_->inject_stuck_encoder(2, true));
  run_until_time(11.0);
  (void)drain_fault_records(log_);
  ASSERT_TRUE(device_->inject_stuck_encoder(2, false));
  app_->request_reset();
  const std::uint32_t arms = app_->safety().arm_count();
  step();
  ASSERT_EQ(app_->safety().arm_count(), arms + 1);
  EXPECT_EQ(app_->safety().first_fault(), safety::Fault::encoder_jump);
  EXPECT_EQ(drain_fault_records(log_), std::vector<std::string>{"encoder_jump"});
}

TEST_F(WallSceneFixture, ShutdownZeroesAndDisablesOutputs) {
  app_->request_reset();
  run_until_time(7.0);
  ASSERT_GT(total_applied_effort(), 0.0);
  app_->shutdown();
  EXPECT_EQ(total_applied_effort(), 0.0);
  std::vector<hal::ActuatorStatus> status(device_->actuator_count());
  ASSERT_EQ(device_->read_actuator_status(status), hal::ReturnCode::ok);
  for (const auto& s : status) {
    EXPECT_FALSE(s.enabled);
    EXPECT_EQ(s.applied_effort, 0.0F);
  }
  EXPECT_TRUE(app_->safety().latched_faults() & safety::bit(safety::Fault::shutdown));
}

TEST_F(WallSceneFixture, OverrunFaultZeroesOutputs) {
  app_->request_reset();
  run_until_time(7.0);
  ASSERT_GT(total_applied_effort(), 0.0);
  app_->on_overrun_fault(10);
  EXPECT_EQ(total_applied_effort(), 0.0);
  EXPECT_EQ(app_->safety().first_fault(), safety::Fault::overrun_streak);
}

}  // namespace
}  // namespace trainer::app
