// Contacts driven through their whole object (docs/stability.md): a tool point through a rigid
// sphere's centre and 10 m past a rigid plane, a catheter particle across a duct-sized tube's
// whole diameter and out through its wall, a shaft capsule pushed through the tube from one
// side to the other, each at the configuration's largest stiffness and contact force.
// For every position: no NaN or Inf, every force within its configured cap (max_force_n of the
// particle and segment contacts; the rigid penalty, which has no cap, finite and as the spring
// law says), action = reaction where the contact reports node forces, and after the safety
// chain the tool force within max_force_n and its slew limit.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <span>
#include <vector>

#include "trainer/core/arena.hpp"
#include "trainer/model/bucket_grid.hpp"
#include "trainer/model/particle_contact.hpp"
#include "trainer/model/rigid_contact.hpp"
#include "trainer/model/segment_contact.hpp"
#include "safety_chain_probe.hpp"  // tests/support

namespace trainer::model {
namespace {

// The largest values the scene configuration accepts (rt/config: object stiffness (0, 1e6]
// N/m, damping [0, 1e4] N·s/m; catheter wall stiffness (0, 1e6] N/m, max contact force
// (0, 100] N).
constexpr float kMaxStiffness = 1e6F;
constexpr float kMaxDamping = 1e4F;
constexpr float kMaxContactForce = 100.0F;
constexpr float kDt = 1e-3F;


TEST(RigidContactStability, ThroughTheSphereCentreAndMetresIntoThePlane) {
  // A point from 1 cm outside a 5 cm sphere straight through its centre (depth = R there, and
  // the normal is undefined: +z by convention) to the far side, at 1 m/s; and from above a
  // plane to 10 m below it (the configuration's coordinate bound). Force = max(0, k d − b v·n)
  // exactly (the damper never pulls), finite; after the safety chain within 8 N.
  const PenaltyMaterial material{kMaxStiffness, kMaxDamping};
  const float radius = 0.05F;
  const RigidSphere sphere(Vec3::Zero(), radius, material);
  const Vec3 velocity(0.0F, 0.0F, -1.0F);
  test::SafetyChainProbe safety;
  float deepest = 0.0F;
  for (int i = 0; i <= 1200; ++i) {
    const Vec3 point(0.0F, 0.0F, radius + 0.01F - 1e-4F * static_cast<float>(i));
    const PointContact contact = sphere.contact(point, velocity);
    ASSERT_TRUE(contact.force_n.allFinite()) << point.z();
    if (contact.in_contact) {
      ASSERT_NEAR(contact.normal.norm(), 1.0F, 1e-6F);
      const float expected = std::max(0.0F, kMaxStiffness * contact.depth_m -
                                                kMaxDamping * velocity.dot(contact.normal));
      ASSERT_NEAR(contact.force_n.norm(), expected, 1e-5F * expected + 1e-6F) << point.z();
      deepest = std::max(deepest, contact.depth_m);
    }
    safety.pass(contact.force_n, kDt);
  }
  // At the exact centre: depth R, pushed along +z.
  const PointContact centre = sphere.contact(Vec3::Zero(), Vec3::Zero());
  EXPECT_TRUE(centre.in_contact);
  EXPECT_FLOAT_EQ(centre.depth_m, radius);
  EXPECT_EQ(centre.normal, Vec3::UnitZ());
  EXPECT_FLOAT_EQ(centre.force_n.z(), kMaxStiffness * radius);
  EXPECT_NEAR(deepest, radius, 1e-4F);
  const RigidPlane plane(Vec3::Zero(), Vec3::UnitZ(), material);
  for (const float depth : {1e-3F, 0.1F, 1.0F, 10.0F}) {
    const PointContact contact = plane.contact(Vec3(0.0F, 0.0F, -depth), velocity);
    ASSERT_TRUE(contact.force_n.allFinite());
    EXPECT_FLOAT_EQ(contact.force_n.z(), kMaxStiffness * depth + kMaxDamping * 1.0F);
    safety.pass(contact.force_n, kDt);
  }
  std::printf("rigid: sphere force at the centre %.3g N, plane at 10 m %.3g N; after safety %.3f N\n",
              static_cast<double>(centre.force_n.norm()),
              static_cast<double>(kMaxStiffness * 10.0F + kMaxDamping),
              static_cast<double>(safety.peak_n));
  safety.expect_within_limits(kDt);
}

struct Mesh {
  std::vector<float> positions;
  std::vector<std::uint32_t> triangles;
};

// The duct's size: radius 4.3 mm, 24.4 mm long along z, 16 nodes a ring, outward normals.
constexpr float kTubeRadius = 0.0043F;
constexpr float kTubeLength = 0.0244F;
Mesh make_tube() {
  constexpr std::uint32_t kRings = 13;
  constexpr std::uint32_t kSegments = 16;
  Mesh mesh;
  for (std::uint32_t r = 0; r < kRings; ++r) {
    const float z = kTubeLength * static_cast<float>(r) / static_cast<float>(kRings - 1);
    for (std::uint32_t s = 0; s < kSegments; ++s) {
      const float angle = 2.0F * std::numbers::pi_v<float> * static_cast<float>(s) / kSegments;
      mesh.positions.insert(mesh.positions.end(),
                            {kTubeRadius * std::cos(angle), kTubeRadius * std::sin(angle), z});
    }
  }
  for (std::uint32_t r = 0; r + 1 < kRings; ++r) {
    for (std::uint32_t s = 0; s < kSegments; ++s) {
      const std::uint32_t i = r * kSegments + s;
      const std::uint32_t j = r * kSegments + (s + 1) % kSegments;
      mesh.triangles.insert(mesh.triangles.end(), {i, j, i + kSegments, j, j + kSegments, i + kSegments});
    }
  }
  return mesh;
}

// Σ forces on the particles / tool plus Σ node forces: zero to float rounding.
void expect_balanced(const Vec3& on_tool_or_particles, std::span<const NodeForce> node_forces) {
  Vec3 sum = on_tool_or_particles;
  float scale = on_tool_or_particles.norm();
  for (const NodeForce& entry : node_forces) {
    ASSERT_TRUE(entry.force_n.allFinite());
    sum += entry.force_n;
    scale += entry.force_n.norm();
  }
  EXPECT_LE(sum.norm(), 1e-5F * scale + 1e-9F);
}

TEST(ParticleContactStability, ParticleAcrossTheWholeTubeAndThroughTheWall) {
  // A catheter particle (radius 1.25 mm, the cbd catheter's) from the axis of a duct-sized
  // tube out through the wall to twice the radius, and back across the whole diameter, at the
  // largest wall stiffness and contact force the configuration accepts, both sides. Inside,
  // the wall pushes it back in until its centre crosses the mid-surface (the documented limit:
  // then it is on the other side); every force is finite, within max_force_n, and balanced by
  // the node reactions.
  const Mesh mesh = make_tube();
  core::Arena arena = core::Arena::create(std::size_t{4} << 20).value();
  auto grid = BucketGrid::create({4096, 4096, 0.002F, 4096, 1U << 16}, arena);
  ASSERT_TRUE(grid) << grid.error().message;
  ASSERT_TRUE(grid->rebuild(mesh.positions, mesh.triangles).is_ok());
  constexpr float kParticleRadius = 1.25e-3F;
  for (const ContactSide side : {ContactSide::inner, ContactSide::both}) {
    ParticleContactSettings settings;
    settings.max_particles = 4;
    settings.max_contacts = 64;
    settings.max_nodes = 4096;
    settings.stiffness_n_per_m = kMaxStiffness;
    settings.damping_n_s_per_m = 1e3F;
    settings.surface_offset_m = 5e-4F;
    settings.max_force_n = kMaxContactForce;
    settings.side = side;
    auto contact = ParticleSurfaceContact::create(settings, arena);
    ASSERT_TRUE(contact) << contact.error().message;
    ParticleContactOutput out;
    float peak_n = 0.0F;
    int pushing = 0;
    for (int i = -200; i <= 200; ++i) {
      // Along +x through the axis, from x = −2R to +2R, at mid-length; moving at 1 m/s.
      const std::vector<Vec3> particle{Vec3(2.0F * kTubeRadius * static_cast<float>(i) / 200.0F,
                                            1e-5F, kTubeLength / 2.0F)};
      const std::vector<Vec3> velocity{Vec3(1.0F, 0.0F, 0.0F)};
      const core::Status status = contact->compute(particle, velocity, kParticleRadius,
                                                   {mesh.positions, mesh.triangles}, {}, *grid, out);
      ASSERT_TRUE(status.is_ok()) << status.detail();
      const Vec3 force = out.particle_forces_n[0];
      ASSERT_TRUE(force.allFinite()) << particle[0].x();
      ASSERT_LE(force.norm(), kMaxContactForce * (1.0F + 1e-6F)) << particle[0].x();
      peak_n = std::max(peak_n, force.norm());
      if (force.norm() > 0.0F) ++pushing;
      expect_balanced(force, out.node_forces);
    }
    std::printf("particle across the tube (%s side): %d of 401 positions pushed, peak %.3f N "
                "(cap %.0f N)\n",
                side == ContactSide::inner ? "inner" : "both", pushing, static_cast<double>(peak_n),
                static_cast<double>(kMaxContactForce));
    EXPECT_GT(pushing, 0);
    EXPECT_GT(peak_n, 0.99F * kMaxContactForce);  // the cap is reached, and holds
  }
}

TEST(SegmentContactStability, ShaftPushedThroughTheWholeTube) {
  // A 2.5 mm-radius shaft lying across the tube (along y) pushed down along −z from above the
  // top wall, through the top wall, the lumen and the bottom wall, to below the tube: depths up
  // to the whole diameter. The side memory keeps pushing it back out the way it came; every
  // force finite, within max_force_n, balanced by the node reactions; after the safety chain
  // within 8 N and its slew.
  const Mesh mesh = make_tube();
  core::Arena arena = core::Arena::create(std::size_t{4} << 20).value();
  auto grid = BucketGrid::create({4096, 4096, 0.002F, 4096, 1U << 16}, arena);
  ASSERT_TRUE(grid) << grid.error().message;
  ASSERT_TRUE(grid->rebuild(mesh.positions, mesh.triangles).is_ok());
  SegmentContactSettings settings;
  settings.surface_half_thickness_m = 5e-4F;
  settings.stiffness_n_per_m = kMaxStiffness;
  settings.damping_n_s_per_m = 1e3F;
  settings.max_force_n = kMaxContactForce;
  settings.max_candidates = 512;
  auto contact = SegmentSurfaceContact::create(settings, arena);
  ASSERT_TRUE(contact) << contact.error().message;
  test::SafetyChainProbe safety;
  float peak_n = 0.0F;
  int touching = 0;
  std::array<NodeForce, SegmentSurfaceContact::kMaxNodeForces> node_forces{};
  for (int i = 0; i <= 400; ++i) {
    const float z = 2.0F * kTubeRadius - 4.0F * kTubeRadius * static_cast<float>(i) / 400.0F;
    ToolCapsule shaft;
    shaft.segment = ToolSegment::shaft;
    shaft.start_m = Vec3(1e-5F, -0.02F, z);  // across the tube, its middle over the axis
    shaft.end_m = Vec3(1e-5F, 0.02F, z);
    shaft.radius_m = 2.5e-3F;
    shaft.start_velocity_m_per_s = shaft.end_velocity_m_per_s = Vec3(0.0F, 0.0F, -0.1F);
    const core::Status status =
        contact->update(std::span(&shaft, 1), {mesh.positions, mesh.triangles}, {}, *grid);
    ASSERT_TRUE(status.is_ok()) << status.detail() << " at z " << z;
    Vec3 on_tool = Vec3::Zero();
    for (const ToolForce& force : contact->tool_forces()) on_tool += force.force_n;
    ASSERT_TRUE(on_tool.allFinite()) << z;
    ASSERT_LE(on_tool.norm(), kMaxContactForce * (1.0F + 1e-6F)) << z;
    peak_n = std::max(peak_n, on_tool.norm());
    if (contact->contact_count() > 0) ++touching;
    const std::size_t count = contact->write_node_forces(node_forces);
    expect_balanced(on_tool, std::span(node_forces.data(), count));
    safety.pass(on_tool, kDt);
  }
  std::printf("shaft through the tube: %d of 401 positions in contact, peak %.3f N (cap %.0f N), "
              "after safety %.3f N\n",
              touching, static_cast<double>(peak_n), static_cast<double>(kMaxContactForce),
              static_cast<double>(safety.peak_n));
  EXPECT_GT(touching, 100);
  EXPECT_GT(peak_n, 0.99F * kMaxContactForce);
  safety.expect_within_limits(kDt);
}

}  // namespace
}  // namespace trainer::model
