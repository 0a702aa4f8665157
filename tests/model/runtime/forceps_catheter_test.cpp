// Forceps segments against the particle catheter (forceps_catheter.hpp): the shaft pushing the
// catheter (action = reaction through the catheter's holders), one plane per touched particle,
// grasping as the jaws close (squeeze = k_g × overlap), carrying the grasped catheter, release
// on opening, slipping under a pull beyond friction, non-finite poses and bad settings.
#include "trainer/model/forceps_catheter.hpp"

#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/arena.hpp"

namespace trainer::model {
namespace {

constexpr float kPeriodS = 1e-3F;
constexpr float kJawLengthM = 0.015F;
constexpr float kCatheterRadiusM = 1.25e-3F;

// A 0.15 m, 11-particle catheter along +x from x = −0.1, at y = z = 0, no gravity.
Catheter make_catheter(core::Arena& arena) {
  CatheterParams params;
  params.length_m = 0.15F;
  params.outer_radius_m = kCatheterRadiusM;
  params.bending_stiffness_n_m2 = 3.9e-5F;
  params.axial_stiffness_n = 157.0F;
  params.linear_density_kg_per_m = 1.65e-3F;
  params.damping_n_s_per_m = 5e-4F;
  params.particle_count = 11;
  params.contact_stiffness_n_per_m = 300.0F;  // the forceps' contact (catheter_cbd's tool stiffness)
  CatheterSetup setup;
  setup.start_position_m = Vec3(-0.1F, 0.0F, 0.0F);
  setup.direction = Vec3::UnitX();
  auto catheter = Catheter::create(params, setup, arena);
  EXPECT_TRUE(catheter.has_value()) << (catheter ? "" : catheter.error().message);
  return std::move(catheter).value();
}

// Forceps coming down −z onto the catheter, jaws opening along ±y (n = +y), the hinge at
// `hinge`: the jaws close around a catheter lying along x.
ForcepsShape forceps_at(const Vec3& hinge, float grip_rad) {
  ForcepsShape shape;
  shape.direction = -Vec3::UnitZ();
  shape.opening_direction = Vec3::UnitY();
  shape.hinge_m = hinge;
  shape.shaft_start_m = hinge - 0.3F * shape.direction;
  shape.grip_rad = grip_rad;
  for (int jaw = 0; jaw < 2; ++jaw) {
    const float side = jaw == 0 ? 1.0F : -1.0F;
    shape.jaw_tips_m[static_cast<std::size_t>(jaw)] =
        hinge + kJawLengthM * (std::cos(0.5F * grip_rad) * shape.direction +
                               side * std::sin(0.5F * grip_rad) * shape.opening_direction);
  }
  return shape;
}

struct Rig {
  core::Arena arena = std::move(core::Arena::create(1 << 20)).value();
  Catheter catheter = make_catheter(arena);
  ForcepsCatheterContact contact = std::move(ForcepsCatheterContact::create({})).value();
  std::array<ContactPlane, ForcepsCatheterContact::kMaxPlanes> planes{};

  // One haptic period: planes, step, tool forces. `extra` is added to every particle.
  void cycle(const ForcepsShape& shape, const Vec3& pull_on_last = Vec3::Zero()) {
    std::size_t count = 0;
    ASSERT_TRUE(contact.prepare(shape, catheter, planes, count).is_ok());
    ASSERT_TRUE(catheter.set_contact_planes(std::span(planes.data(), count)).is_ok());
    catheter.clear_forces();
    if (!pull_on_last.isZero()) {
      ASSERT_TRUE(catheter.add_force(catheter.particle_count() - 1, pull_on_last).is_ok());
    }
    ASSERT_TRUE(catheter.step(kPeriodS).is_ok());
    ASSERT_TRUE(contact.collect(catheter, catheter.contact_plane_forces_n()).is_ok());
  }
  Vec3 total_tool_force() const {
    Vec3 total = Vec3::Zero();
    for (const ToolForce& force : contact.tool_forces()) total += force.force_n;
    return total;
  }
};

TEST(ForcepsCatheter, ShaftPushesTheCatheterAndFeelsWhatItsHoldersFeel) {
  // Catheter held at both ends; the shaft (vertical, beside particle 5 at x = −0.025) is moved
  // 2 mm into it. At rest the catheter's force balance says: what the shaft pushes with is what
  // the two holders take, so the tool's force is minus the sum of the hold forces.
  Rig rig;
  ASSERT_TRUE(rig.catheter.hold(0, rig.catheter.positions_m()[0]).is_ok());
  ASSERT_TRUE(rig.catheter.hold(10, rig.catheter.positions_m()[10]).is_ok());
  const float touching_y = kCatheterRadiusM + 2.5e-3F;  // catheter + shaft radius
  // The hinge far below: only the shaft crosses the catheter's height.
  for (int period = 0; period < 3000; ++period) {
    const float y = touching_y - 2e-3F * std::min(1.0F, static_cast<float>(period) / 500.0F);
    rig.cycle(forceps_at(Vec3(-0.0245F, y, -0.05F), 0.0F));
  }
  const Vec3 tool = rig.total_tool_force();
  const Vec3 holders = rig.catheter.hold_forces_n()[0] + rig.catheter.hold_forces_n()[10];
  EXPECT_GT(tool.y(), 1e-3F);  // the catheter pushes the shaft back, along +y
  EXPECT_LT((tool + holders).norm(), 0.02F * tool.norm()) << "tool " << tool.transpose()
                                                          << " holders " << holders.transpose();
  // Every force acts on the shaft, at the height of the catheter (z = 0: 0.3 − 0.05 m from its start).
  ASSERT_FALSE(rig.contact.tool_forces().empty());
  for (const ToolForce& force : rig.contact.tool_forces()) {
    EXPECT_EQ(force.segment, ToolSegment::shaft);
    EXPECT_NEAR(force.along_m, 0.25F, 2e-3F);
  }
  EXPECT_FALSE(rig.contact.grasping());
}

TEST(ForcepsCatheter, AJawOnAParticleMakesOnePlaneNotTwo) {
  // A jaw crossing the catheter exactly at particle 4 (x = −0.04) is closest to both segments
  // 3 and 4 there; only one plane may push particle 4.
  Rig rig;
  ForcepsShape shape = forceps_at(Vec3(-0.04F, 0.0F, 0.012F), 0.0F);  // jaw tip at z = −3 mm
  shape.jaw_tips_m[1] = shape.hinge_m;  // only jaw 0 (a zero-length jaw 1 at the hinge, above)
  shape.shaft_start_m = shape.hinge_m + Vec3(0.0F, 0.0F, 0.3F);
  std::size_t count = 0;
  ASSERT_TRUE(rig.contact.prepare(shape, rig.catheter, rig.planes, count).is_ok());
  ASSERT_EQ(count, 1U);
  const ContactPlane& plane = rig.planes[0];
  const Vec3 point = (1.0F - plane.weight_b) * rig.catheter.positions_m()[plane.particle_a] +
                     plane.weight_b * rig.catheter.positions_m()[plane.particle_b];
  EXPECT_LT((point - Vec3(-0.04F, 0.0F, 0.0F)).norm(), 1e-6F);
}

TEST(ForcepsCatheter, ClosingJawsGraspAtTouchAndSqueezeByOverlap) {
  Rig rig;
  // The catheter at 10 mm along the jaws (hinge 10 mm above it), between particles 4 and 5.
  const Vec3 hinge(-0.032F, 0.0F, 0.01F);
  const float along = 0.01F;
  const float touch_grip = 2.0F * std::asin((kCatheterRadiusM + 1e-3F) / along);
  float grasped_at = -1.0F;
  for (float grip = 0.8F; grip > 0.2F; grip -= 0.002F) {
    rig.cycle(forceps_at(hinge, grip));
    if (rig.contact.grasping() && grasped_at < 0.0F) grasped_at = grip;
  }
  ASSERT_TRUE(rig.contact.grasping());
  EXPECT_EQ(rig.contact.grasp_count(), 1U);
  EXPECT_EQ(rig.contact.grasped_segment(), 4U);
  // Grasped where the jaws' surfaces reach the catheter: a point `along` the axis is
  // along·sin(g/2) from each jaw's axis, touching when that equals r_c + r_j.
  EXPECT_NEAR(grasped_at, touch_grip, 0.01F);
  // Squeeze per jaw at the final grip 0.2 rad: k_g × overlap, overlap = reach − along·sin(g/2)
  // measured perpendicular to each jaw.
  const ForcepsShape final_shape = forceps_at(hinge, 0.2F);
  rig.cycle(final_shape);
  const float distance = along * std::sin(0.1F);  // from the held point to each jaw's axis
  const float overlap = kCatheterRadiusM + 1e-3F - distance;
  const float expected = std::min(3000.0F * overlap, 10.0F);
  EXPECT_NEAR(rig.contact.squeeze_force_n(), 2.0F * expected, 0.05F * 2.0F * expected);
  // The squeeze forces on the two jaws are opposite across n: they load the grip, not the tool.
  const auto forces = rig.contact.tool_forces();
  ASSERT_GE(forces.size(), 2U);
  EXPECT_GT(forces[forces.size() - 2].force_n.y(), 0.0F);  // jaw 0 pushed open (+n)
  EXPECT_LT(forces[forces.size() - 1].force_n.y(), 0.0F);

  // Carry it 20 mm along +y: the held particles follow the jaws exactly.
  const Vec3 before4 = rig.catheter.positions_m()[4];
  for (int period = 1; period <= 400; ++period) {
    const float shift = 0.02F * std::min(1.0F, static_cast<float>(period) / 300.0F);
    rig.cycle(forceps_at(hinge + Vec3(0.0F, shift, 0.0F), 0.2F));
  }
  ASSERT_TRUE(rig.contact.grasping());
  EXPECT_LT((rig.catheter.positions_m()[4] - (before4 + Vec3(0.0F, 0.02F, 0.0F))).norm(), 1e-5F);
  // The rest of the free catheter was dragged along by its springs.
  EXPECT_GT(rig.catheter.positions_m()[0].y(), 0.002F);

  // Opening the jaws releases it.
  for (float grip = 0.2F; grip < 0.8F; grip += 0.01F) rig.cycle(forceps_at(hinge + Vec3(0.0F, 0.02F, 0.0F), grip));
  EXPECT_FALSE(rig.contact.grasping());
  EXPECT_EQ(rig.contact.slip_count(), 0U);
}

TEST(ForcepsCatheter, APullBeyondFrictionSlipsOutAndWaitsBeforeRegrasping) {
  Rig rig;
  const Vec3 hinge(-0.032F, 0.0F, 0.01F);
  for (float grip = 0.8F; grip > 0.45F; grip -= 0.002F) rig.cycle(forceps_at(hinge, grip));
  ASSERT_TRUE(rig.contact.grasping());
  const float squeeze = rig.contact.squeeze_force_n();
  ASSERT_GT(squeeze, 0.0F);
  // A pull on the far end well under μ × squeeze holds; well over it slips.
  for (int period = 0; period < 200; ++period) rig.cycle(forceps_at(hinge, 0.45F), Vec3(0.2F * 0.6F * squeeze, 0, 0));
  EXPECT_TRUE(rig.contact.grasping());
  for (int period = 0; period < 200 && rig.contact.grasping(); ++period) {
    rig.cycle(forceps_at(hinge, 0.45F), Vec3(3.0F * 0.6F * squeeze, 0, 0));
  }
  EXPECT_FALSE(rig.contact.grasping());
  EXPECT_EQ(rig.contact.slip_count(), 1U);
  // Within the delay it does not grasp again although both jaws still touch.
  rig.cycle(forceps_at(hinge, 0.45F));
  EXPECT_FALSE(rig.contact.grasping());
}

TEST(ForcepsCatheter, NonFinitePoseReleasesAndAddsNothing) {
  Rig rig;
  const Vec3 hinge(-0.032F, 0.0F, 0.01F);
  for (float grip = 0.8F; grip > 0.4F; grip -= 0.002F) rig.cycle(forceps_at(hinge, grip));
  ASSERT_TRUE(rig.contact.grasping());
  ForcepsShape bad = forceps_at(hinge, 0.4F);
  bad.hinge_m.x() = std::numeric_limits<float>::quiet_NaN();
  std::size_t count = 7;
  EXPECT_EQ(rig.contact.prepare(bad, rig.catheter, rig.planes, count).code(), core::StatusCode::numeric_error);
  EXPECT_EQ(count, 0U);
  EXPECT_FALSE(rig.contact.grasping());
  // The catheter is free again: a step moves the formerly held particles under a force.
  rig.catheter.clear_forces();
  ASSERT_TRUE(rig.catheter.add_force(4, Vec3(0, 0, 1e-3F)).is_ok());
  const Vec3 before = rig.catheter.positions_m()[4];
  ASSERT_TRUE(rig.catheter.step(kPeriodS).is_ok());
  EXPECT_NE(rig.catheter.positions_m()[4], before);
}

TEST(ForcepsCatheter, BadSettingsAreRefusedByName) {
  ForcepsContactSettings settings;
  settings.stiffness_n_per_m = 0.0F;
  auto refused = ForcepsCatheterContact::create(settings);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("stiffness_n_per_m"), std::string::npos);
  settings = {};
  settings.friction_coefficient = -1.0F;
  refused = ForcepsCatheterContact::create(settings);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("friction_coefficient"), std::string::npos);
}

TEST(ForcepsCatheter, GraspAndCarryAllocateNothing) {
  Rig rig;
  const Vec3 hinge(-0.032F, 0.0F, 0.01F);
  rig.cycle(forceps_at(hinge, 0.8F));
  ASSERT_TRUE(core::alloc::hooks_installed());
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (int period = 0; period < 1000; ++period) {
    const float grip = std::max(0.3F, 0.8F - 0.002F * static_cast<float>(period));
    rig.cycle(forceps_at(hinge + Vec3(0.0F, 1e-5F * static_cast<float>(period), 0.0F), grip));
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
  EXPECT_TRUE(rig.contact.grasping());
}

}  // namespace
}  // namespace trainer::model
