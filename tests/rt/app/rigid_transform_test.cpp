// Model placement: RigidTransform against hand-worked rotations (90° about each axis, the
// intrinsic X-then-Y order), exact round trips for random placements, and the transform the
// app builds per model from the scene, reported in the JSON report.
#include "trainer/app/rigid_transform.hpp"
#include "catheter_images.hpp"

#include <array>
#include <cmath>
#include <memory>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "trainer/app/haptic_app.hpp"
#include "trainer/app/report.hpp"
#include "trainer/app/device_wiring.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/hal_sim/sim_device.hpp"

namespace trainer::app {
namespace {

using Vec3 = RigidTransform::Vec3;

// Float rounding of cos/sin of a right angle leaves ~1e-8; 1e-6 m is far below any geometry.
constexpr float kTolerance = 1e-6F;

void expect_near(const Vec3& actual, const Vec3& expected, float tolerance = kTolerance) {
  EXPECT_LT((actual - expected).norm(), tolerance)
      << "actual [" << actual.transpose() << "] expected [" << expected.transpose() << "]";
}

TEST(RigidTransform, DefaultIsIdentity) {
  const RigidTransform identity;
  const Vec3 p(0.1F, -0.2F, 0.3F);
  expect_near(identity.to_world(p), p, 1e-12F);
  expect_near(identity.to_model(p), p, 1e-12F);
}

TEST(RigidTransform, QuarterTurnsAboutEachAxisFollowTheRightHand) {
  const std::array<double, 3> origin{0.0, 0.0, 0.0};
  const RigidTransform about_z = RigidTransform::from_placement(origin, {0.0, 0.0, 90.0});
  expect_near(about_z.to_world(Vec3::UnitX()), Vec3::UnitY());
  expect_near(about_z.to_world(Vec3::UnitY()), -Vec3::UnitX());
  const RigidTransform about_x = RigidTransform::from_placement(origin, {90.0, 0.0, 0.0});
  expect_near(about_x.to_world(Vec3::UnitY()), Vec3::UnitZ());
  const RigidTransform about_y = RigidTransform::from_placement(origin, {0.0, 90.0, 0.0});
  expect_near(about_y.to_world(Vec3::UnitZ()), Vec3::UnitX());
}

TEST(RigidTransform, AnglesComposeIntrinsicallyXThenY) {
  // [90, 90, 0]: turn 90° about x (the model's y becomes the trainer's z), then 90° about the
  // TURNED y, i.e. about the trainer's z: the model's x goes to the trainer's +y.
  // (Extrinsic x-then-y would send it to −z instead.)
  const RigidTransform placed = RigidTransform::from_placement({0.0, 0.0, 0.0}, {90.0, 90.0, 0.0});
  expect_near(placed.to_world(Vec3::UnitX()), Vec3::UnitY());
  expect_near(placed.to_world(Vec3::UnitY()), Vec3::UnitZ());
  expect_near(placed.to_world(Vec3::UnitZ()), Vec3::UnitX());
}

TEST(RigidTransform, TranslationMovesPointsButNotVectors) {
  const RigidTransform placed =
      RigidTransform::from_placement({0.01, -0.02, -0.08}, {0.0, 0.0, 90.0});
  // The duct's start (model origin) lands at position_m; its axis (+x) points along +y.
  expect_near(placed.to_world(Vec3::Zero()), Vec3(0.01F, -0.02F, -0.08F));
  expect_near(placed.to_world(Vec3(0.05F, 0.0F, 0.0F)), Vec3(0.01F, 0.03F, -0.08F));
  expect_near(placed.vector_to_world(Vec3(2.0F, 0.0F, 0.0F)), Vec3(0.0F, 2.0F, 0.0F));
  expect_near(placed.vector_to_model(Vec3(0.0F, 2.0F, 0.0F)), Vec3(2.0F, 0.0F, 0.0F));
}

TEST(RigidTransform, RandomPlacementsRoundTripAndStayRigid) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> angle_deg(-360.0, 360.0);
  std::uniform_real_distribution<double> offset_m(-1.0, 1.0);
  std::uniform_real_distribution<float> coordinate_m(-0.3F, 0.3F);
  for (int trial = 0; trial < 200; ++trial) {
    const RigidTransform placed =
        RigidTransform::from_placement({offset_m(rng), offset_m(rng), offset_m(rng)},
                                       {angle_deg(rng), angle_deg(rng), angle_deg(rng)});
    EXPECT_TRUE((placed.rotation() * placed.rotation().transpose())
                    .isApprox(RigidTransform::Mat3::Identity(), 1e-6F));
    EXPECT_NEAR(placed.rotation().determinant(), 1.0F, 1e-6F);
    const Vec3 a(coordinate_m(rng), coordinate_m(rng), coordinate_m(rng));
    const Vec3 b(coordinate_m(rng), coordinate_m(rng), coordinate_m(rng));
    // Round trip in both directions; float error of |x| ≤ 1.6 m after two maps ≈ 4e-7 m.
    expect_near(placed.to_model(placed.to_world(a)), a);
    expect_near(placed.to_world(placed.to_model(a)), a);
    // Distances are kept (a rigid motion).
    EXPECT_NEAR((placed.to_world(a) - placed.to_world(b)).norm(), (a - b).norm(), kTolerance);
  }
}

// The app builds one transform per [[model]] from the scene and reports the placement.
TEST(ModelPlacement, AppBuildsAndReportsEachModelsTransform) {
  ASSERT_EQ(
      test::build_catheter_images(std::string(TRAINER_SOURCE_DIR) + "/config/scenes/catheter.toml"),
      "");
  auto loaded =
      config::load_scene(std::string(TRAINER_SOURCE_DIR) + "/config/scenes/catheter.toml");
  ASSERT_TRUE(loaded) << loaded.error().message;
  config::SceneConfig scene = std::move(*loaded);
  ASSERT_EQ(scene.models.size(), 1U);
  scene.models[0].position_m = {0.01, 0.02, -0.05};
  scene.models[0].rotation_deg = {0.0, 0.0, 90.0};

  core::ManualClock clock{0};
  hal::sim::SimDevice device(clock, sim_params_from(scene));
  ASSERT_TRUE(device.configure());
  ASSERT_TRUE(device.activate());
  auto arena = core::Arena::create(scene.memory.arena_bytes);
  ASSERT_TRUE(arena);
  core::LogRing log;
  core::TripleBuffer<TelemetrySnapshot> telemetry;
  auto app = HapticApp::create(
      scene,
      {device.encoders(), device.actuators(), device.digital_inputs(), device.digital_outputs()},
      *arena, log, telemetry, clock);
  ASSERT_TRUE(app) << app.error().message;

  const std::string name = scene.models[0].name;
  const std::optional<RigidTransform> placed = (*app)->model_transform(name);
  ASSERT_TRUE(placed.has_value());
  expect_near(placed->to_world(Vec3::Zero()), Vec3(0.01F, 0.02F, -0.05F));
  expect_near(placed->vector_to_world(Vec3::UnitX()), Vec3::UnitY());
  expect_near((*app)->model_transform(std::size_t{0}).translation_m(), Vec3(0.01F, 0.02F, -0.05F));
  EXPECT_FALSE((*app)->model_transform(std::string("no_such_model")).has_value());

  RunResult result;
  result.models = (*app)->models();
  const nlohmann::json report = report_json(result);
  ASSERT_EQ(report["models"].size(), 1U);
  EXPECT_EQ(report["models"][0]["position_m"], nlohmann::json({0.01, 0.02, -0.05}));
  EXPECT_EQ(report["models"][0]["rotation_deg"], nlohmann::json({0.0, 0.0, 90.0}));
}

}  // namespace
}  // namespace trainer::app
