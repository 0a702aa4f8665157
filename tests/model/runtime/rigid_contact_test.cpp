// Penalty contact against its closed-form response, and the energy it can return.
#include "trainer/model/rigid_contact.hpp"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

namespace trainer::model {
namespace {

constexpr PenaltyMaterial kMaterial{400.0F, 2.0F};

TEST(RigidPlane, SpringForceAlongNormal) {
  const RigidPlane wall(Vec3(0, 0, 0.1F), Vec3(0, 0, -2.0F), kMaterial);  // normal normalised
  const PointContact free = wall.contact(Vec3(0, 0, 0.09F), Vec3::Zero());
  EXPECT_FALSE(free.in_contact);
  EXPECT_EQ(free.force_n, Vec3::Zero());
  const PointContact pressed = wall.contact(Vec3(0.3F, -0.2F, 0.105F), Vec3::Zero());
  ASSERT_TRUE(pressed.in_contact);
  EXPECT_NEAR(pressed.depth_m, 0.005F, 1e-6F);
  EXPECT_TRUE(pressed.force_n.isApprox(Vec3(0, 0, -400.0F * 0.005F), 1e-5F));
}

TEST(RigidPlane, DamperResistsMotionButNeverPulls) {
  const RigidPlane wall(Vec3(0, 0, 0.1F), Vec3(0, 0, -1.0F), kMaterial);
  const Vec3 inside(0, 0, 0.101F);  // 1 mm deep: spring 0.4 N
  const PointContact pressing = wall.contact(inside, Vec3(0, 0, 0.1F));  // moving in
  EXPECT_NEAR(pressing.force_n.z(), -(0.4F + 2.0F * 0.1F), 1e-5F);
  const PointContact leaving_fast = wall.contact(inside, Vec3(0, 0, -1.0F));  // damper > spring
  EXPECT_TRUE(leaving_fast.in_contact);
  EXPECT_EQ(leaving_fast.force_n, Vec3::Zero());
}

TEST(RigidPlane, NonFiniteInputGivesNoForce) {
  const RigidPlane wall(Vec3(0, 0, 0.1F), Vec3(0, 0, -1.0F), kMaterial);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(wall.contact(Vec3(0, 0, nan), Vec3::Zero()).in_contact);
}

TEST(RigidSphere, PushesOutRadially) {
  const RigidSphere ball(Vec3(1, 2, 3), 0.05F, kMaterial);
  const PointContact c = ball.contact(Vec3(1, 2, 3.04F), Vec3::Zero());
  ASSERT_TRUE(c.in_contact);
  EXPECT_NEAR(c.depth_m, 0.01F, 1e-5F);
  EXPECT_TRUE(c.normal.isApprox(Vec3::UnitZ(), 1e-6F));
  EXPECT_NEAR(c.force_n.z(), 4.0F, 1e-3F);
  // At the exact centre: a finite force, not NaN.
  const PointContact centre = ball.contact(Vec3(1, 2, 3), Vec3::Zero());
  EXPECT_TRUE(centre.force_n.allFinite());
  EXPECT_FALSE(ball.contact(Vec3(1, 2, 3.06F), Vec3::Zero()).in_contact);
}

TEST(RigidPlane, CompressReleaseCycleDissipatesEnergy) {
  // Drive the point sinusoidally into the wall and back; the work the contact force does on
  // the point over a full cycle must be <= 0 (spring conservative, damper dissipative).
  const RigidPlane wall(Vec3(0, 0, 0.1F), Vec3(0, 0, -1.0F), kMaterial);
  const double dt = 1e-4;
  double work_j = 0.0;
  for (int step = 0; step < 10000; ++step) {
    const double t = step * dt;
    const double z = 0.1 + 0.01 * std::sin(2.0 * 3.14159265358979 * t);  // 1 s period
    const double vz = 0.01 * 2.0 * 3.14159265358979 * std::cos(2.0 * 3.14159265358979 * t);
    const PointContact c = wall.contact(Vec3(0, 0, static_cast<float>(z)),
                                        Vec3(0, 0, static_cast<float>(vz)));
    work_j += static_cast<double>(c.force_n.z()) * vz * dt;
  }
  EXPECT_LT(work_j, 0.0);
  EXPECT_GT(work_j, -0.01);  // damping 2 N·s/m over this path dissipates only a little
}

}  // namespace
}  // namespace trainer::model
