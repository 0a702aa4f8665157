// Capsule segments (forceps shaft and jaws) vs thin triangle shell (segment_contact.hpp) on
// hand-built meshes with known answers: a flat plate (a segment above, parallel, degenerate,
// beside an open edge; sliding across edges and vertices; pushed through the mid-surface; a
// deformed plate) and a 16-sided tube like the duct (orbiting outside across its convex
// edges, pressing from the lumen). Also action = reaction and its barycentric split, the
// force clamp, damping that never pulls, refusals and counters, and no heap in the RT call.
#include "trainer/model/segment_contact.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/arena.hpp"

namespace trainer::model {
namespace {

constexpr float kStiffness = 1000.0F;    // N/m: 1 mm of depth = 1 N
constexpr float kRadius = 1e-3F;         // jaw radius (m)
constexpr float kHalfThickness = 2e-4F;  // half the wall thickness (m)
constexpr float kReach = kRadius + kHalfThickness;
constexpr float kCell = 0.002F;          // plate grid spacing and bucket cell (m)

constexpr float kTubeRadius = 0.004F;
constexpr float kTubeLength = 0.04F;
constexpr std::uint32_t kSegments = 16;
constexpr std::uint32_t kRings = 21;
const float kApothem = kTubeRadius * std::cos(std::numbers::pi_v<float> / kSegments);

struct Mesh {
  std::vector<float> positions;
  std::vector<std::uint32_t> triangles;
};

// Plate [0, 8 kCell]² at z = 0, normal +z, 8 × 8 quads split along alternating diagonals so
// interior vertices have 4 or 8 triangles.
Mesh make_plate() {
  Mesh mesh;
  for (std::uint32_t y = 0; y <= 8; ++y) {
    for (std::uint32_t x = 0; x <= 8; ++x) {
      mesh.positions.insert(mesh.positions.end(), {kCell * static_cast<float>(x), kCell * static_cast<float>(y), 0.0F});
    }
  }
  for (std::uint32_t y = 0; y < 8; ++y) {
    for (std::uint32_t x = 0; x < 8; ++x) {
      const std::uint32_t a = y * 9 + x;
      const std::uint32_t b = a + 1;
      const std::uint32_t c = a + 10;
      const std::uint32_t d = a + 9;
      if ((x + y) % 2 == 0) {
        mesh.triangles.insert(mesh.triangles.end(), {a, b, c, a, c, d});
      } else {
        mesh.triangles.insert(mesh.triangles.end(), {a, b, d, b, c, d});
      }
    }
  }
  return mesh;
}

// Tube along z with outward normals (like the duct).
Mesh make_tube() {
  Mesh mesh;
  for (std::uint32_t r = 0; r < kRings; ++r) {
    const float z = kTubeLength * static_cast<float>(r) / static_cast<float>(kRings - 1);
    for (std::uint32_t s = 0; s < kSegments; ++s) {
      const float angle = 2.0F * std::numbers::pi_v<float> * static_cast<float>(s) / kSegments;
      mesh.positions.insert(mesh.positions.end(), {kTubeRadius * std::cos(angle), kTubeRadius * std::sin(angle), z});
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

SegmentContactSettings default_settings() {
  SegmentContactSettings settings;
  settings.surface_half_thickness_m = kHalfThickness;
  settings.stiffness_n_per_m = kStiffness;
  settings.damping_n_s_per_m = 0.0F;
  settings.max_force_n = 100.0F;
  settings.max_candidates = 512;
  return settings;
}

ToolCapsule capsule(ToolSegment segment, const Vec3& start, const Vec3& end, float radius_m = kRadius,
                    const Vec3& velocity = Vec3::Zero()) {
  ToolCapsule result;
  result.segment = segment;
  result.start_m = start;
  result.end_m = end;
  result.radius_m = radius_m;
  result.start_velocity_m_per_s = velocity;
  result.end_velocity_m_per_s = velocity;
  return result;
}

struct Scene {
  Mesh mesh;
  core::Arena arena;
  BucketGrid grid;
  SegmentSurfaceContact contact;

  // Rebuilds the grid over the (possibly moved) mesh, then one update.
  core::Status run(const std::vector<ToolCapsule>& capsules, const std::vector<float>& surface_velocities = {}) {
    EXPECT_TRUE(grid.rebuild(mesh.positions, mesh.triangles).is_ok());
    return update(capsules, surface_velocities);
  }
  // One update over the grid as last built (a mesh that has not moved since).
  core::Status update(const std::vector<ToolCapsule>& capsules, const std::vector<float>& surface_velocities = {}) {
    return contact.update(capsules, {mesh.positions, mesh.triangles}, surface_velocities, grid);
  }
  Vec3 node(std::uint32_t index) const {
    return {mesh.positions[3 * index], mesh.positions[3 * index + 1], mesh.positions[3 * index + 2]};
  }
};

Scene make_scene(Mesh mesh, const SegmentContactSettings& settings = default_settings()) {
  auto arena = core::Arena::create(4U << 20);
  EXPECT_TRUE(arena.has_value());
  core::Arena owned = std::move(arena).value();
  auto grid = BucketGrid::create({4096, 4096, kCell, 4096, 1U << 16}, owned);
  EXPECT_TRUE(grid.has_value());
  auto contact = SegmentSurfaceContact::create(settings, owned);
  EXPECT_TRUE(contact.has_value()) << (contact ? "" : contact.error().message);
  return Scene{std::move(mesh), std::move(owned), std::move(grid).value(), std::move(contact).value()};
}

bool finite(const Vec3& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); }

Vec3 sum_tool_forces(const SegmentSurfaceContact& contact) {
  Vec3 sum = Vec3::Zero();
  for (const ToolForce& force : contact.tool_forces()) sum += force.force_n;
  return sum;
}

Vec3 sum_node_forces(const SegmentSurfaceContact& contact) {
  Vec3 sum = Vec3::Zero();
  for (const NodeForce& force : contact.node_forces()) sum += force.force_n;
  return sum;
}

// ---- 1. a segment above the plate ----

TEST(SegmentSurfaceContact, SegmentAbovePlatePushesAlongNormalWithPenaltyForce) {
  Scene scene = make_scene(make_plate());
  const float height = 4e-4F;
  const Vec3 tip(0.0051F, 0.0073F, height);  // inside a face
  // A jaw pointing down at the plate: its tip (the capsule's end) is the closest point.
  ASSERT_TRUE(scene.run({capsule(ToolSegment::jaw0, tip + Vec3(0.002F, 0.0F, 0.01F), tip)}).is_ok());
  ASSERT_EQ(scene.contact.contact_count(), 1U);
  const SegmentContact& contact = scene.contact.contact(0);
  const float expected = kStiffness * (kReach - height);
  EXPECT_NEAR(contact.force_on_tool_n.z(), expected, 1e-4F * expected);
  EXPECT_NEAR(contact.force_on_tool_n.x(), 0.0F, 1e-6F);
  EXPECT_NEAR(contact.force_on_tool_n.y(), 0.0F, 1e-6F);
  EXPECT_NEAR(contact.depth_m, kReach - height, 1e-7F);
  EXPECT_NEAR(contact.distance_m, height, 1e-7F);
  EXPECT_EQ(contact.feature, TriangleFeature::face);
  EXPECT_TRUE((contact.mesh_point_m - Vec3(tip.x(), tip.y(), 0.0F)).norm() < 1e-7F);
  EXPECT_TRUE((contact.segment_point_m - tip).norm() < 1e-7F);
  EXPECT_EQ(contact.side, 1);
  EXPECT_EQ(scene.contact.side(ToolSegment::jaw0), 1);
  // along_m is measured from the capsule's start (the hinge for a jaw): here its length.
  const float length = Vec3(0.002F, 0.0F, 0.01F).norm();
  ASSERT_EQ(scene.contact.tool_forces().size(), 1U);
  EXPECT_EQ(scene.contact.tool_forces()[0].segment, ToolSegment::jaw0);
  EXPECT_NEAR(scene.contact.tool_forces()[0].along_m, length, 1e-6F);
  EXPECT_TRUE((scene.contact.tool_forces()[0].force_n - contact.force_on_tool_n).norm() == 0.0F);

  // Just outside reach: nothing, and the contact's side memory is gone.
  const Vec3 far_tip(tip.x(), tip.y(), kReach + 1e-6F);
  ASSERT_TRUE(scene.run({capsule(ToolSegment::jaw0, far_tip + Vec3(0.0F, 0.0F, 0.01F), far_tip)}).is_ok());
  EXPECT_EQ(scene.contact.contact_count(), 0U);
  EXPECT_TRUE(scene.contact.node_forces().empty());
  EXPECT_TRUE(scene.contact.tool_forces().empty());
  EXPECT_EQ(scene.contact.side(ToolSegment::jaw0), 0);
}

TEST(SegmentSurfaceContact, SegmentBelowPlateIsPushedDownAndRemembersTheInnerSide) {
  Scene scene = make_scene(make_plate());
  const Vec3 tip(0.009F, 0.0051F, -6e-4F);
  ASSERT_TRUE(scene.run({capsule(ToolSegment::shaft, tip - Vec3(0.0F, 0.0F, 0.02F), tip)}).is_ok());
  ASSERT_EQ(scene.contact.contact_count(), 1U);
  const float expected = kStiffness * (kReach - 6e-4F);
  EXPECT_NEAR(scene.contact.contact(0).force_on_tool_n.z(), -expected, 1e-4F * expected);
  EXPECT_EQ(scene.contact.side(ToolSegment::shaft), -1);
  EXPECT_NEAR(scene.contact.contact(0).along_m, 0.02F, 1e-6F);
}

// ---- 2. parallel and degenerate segments ----

TEST(SegmentSurfaceContact, SegmentParallelToPlateGetsTheFullPenaltyForce) {
  Scene scene = make_scene(make_plate());
  for (const float height : {0.0F + 1e-5F, 3e-4F, 1.1e-3F}) {
    ASSERT_TRUE(scene.run({capsule(ToolSegment::shaft, Vec3(0.003F, 0.003F, height), Vec3(0.012F, 0.005F, height))})
                    .is_ok());
    ASSERT_EQ(scene.contact.contact_count(), 1U) << height;
    const SegmentContact& contact = scene.contact.contact(0);
    ASSERT_TRUE(finite(contact.force_on_tool_n));
    const float expected = kStiffness * (kReach - height);
    EXPECT_NEAR(contact.force_on_tool_n.z(), expected, 1e-4F * expected) << height;
    EXPECT_NEAR(contact.force_on_tool_n.head<2>().norm(), 0.0F, 1e-5F * expected) << height;
    EXPECT_GE(contact.along_m, 0.0F);
    EXPECT_LE(contact.along_m, Vec3(0.009F, 0.002F, 0.0F).norm() + 1e-6F);
    // The reported point pair is a real closest pair: on the segment and straight below it.
    EXPECT_NEAR(contact.segment_point_m.z(), height, 1e-7F);
    EXPECT_NEAR((contact.segment_point_m - contact.mesh_point_m).head<2>().norm(), 0.0F, 1e-6F);
  }
}

TEST(SegmentSurfaceContact, DegenerateSegmentBehavesLikeASphere) {
  Scene scene = make_scene(make_plate());
  // Over a face, over an interior vertex (8 triangles), over an edge: k (reach − h) along +z.
  for (const Vec3& point : {Vec3(0.0071F, 0.0093F, 5e-4F), Vec3(0.008F, 0.008F, 5e-4F), Vec3(0.006F, 0.0031F, 5e-4F)}) {
    ASSERT_TRUE(scene.run({capsule(ToolSegment::jaw1, point, point)}).is_ok());
    ASSERT_EQ(scene.contact.contact_count(), 1U);
    const float expected = kStiffness * (kReach - 5e-4F);
    EXPECT_TRUE((scene.contact.contact(0).force_on_tool_n - Vec3(0.0F, 0.0F, expected)).norm() < 1e-4F * expected)
        << scene.contact.contact(0).force_on_tool_n.transpose();
    EXPECT_EQ(scene.contact.contact(0).along_m, 0.0F);
  }
  // Beside the plate's open edge x = 0: the force points from the edge to the centre.
  const Vec3 beside(-5e-4F, 0.0071F, 3e-4F);
  ASSERT_TRUE(scene.run({capsule(ToolSegment::jaw1, beside, beside)}).is_ok());
  ASSERT_EQ(scene.contact.contact_count(), 1U);
  const float distance = std::hypot(5e-4F, 3e-4F);
  const Vec3 expected_direction = Vec3(-5e-4F, 0.0F, 3e-4F) / distance;
  const Vec3 force = scene.contact.contact(0).force_on_tool_n;
  EXPECT_NEAR(force.norm(), kStiffness * (kReach - distance), 1e-4F * kStiffness * (kReach - distance));
  EXPECT_TRUE((force.normalized() - expected_direction).norm() < 1e-5F) << force.transpose();
  EXPECT_EQ(scene.contact.contact(0).feature, TriangleFeature::edge2);
}

// ---- 3. continuity across edges and vertices ----

struct SweepResult {
  float max_magnitude_change = 0.0F;  // relative, between consecutive steps
  float max_direction_change = 0.0F;  // |Δn| (rad for small angles)
  std::set<std::uint32_t> triangles;
  std::set<TriangleFeature> features;
  int steps_in_contact = 0;
};

template <class CapsuleAt>
SweepResult sweep(Scene& scene, int steps, CapsuleAt capsule_at) {
  SweepResult result;
  Vec3 previous = Vec3::Zero();
  EXPECT_TRUE(scene.grid.rebuild(scene.mesh.positions, scene.mesh.triangles).is_ok());
  for (int step = 0; step <= steps; ++step) {
    EXPECT_TRUE(scene.update({capsule_at(step)}).is_ok());
    if (scene.contact.contact_count() != 1) {
      ADD_FAILURE() << "no contact at step " << step;
      return result;
    }
    const SegmentContact& contact = scene.contact.contact(0);
    const Vec3 force = contact.force_on_tool_n;
    result.triangles.insert(contact.triangle);
    result.features.insert(contact.feature);
    ++result.steps_in_contact;
    if (step > 0) {
      result.max_magnitude_change =
          std::max(result.max_magnitude_change, std::abs(force.norm() - previous.norm()) / previous.norm());
      result.max_direction_change =
          std::max(result.max_direction_change, (force.normalized() - previous.normalized()).norm());
    }
    previous = force;
  }
  return result;
}

TEST(SegmentSurfaceContact, ForceIsContinuousWhenATiltedSegmentSlidesAcrossEdgesAndVertices) {
  Scene scene = make_scene(make_plate());
  const float height = 6e-4F;
  const Vec3 up = Vec3(0.5F, 0.2F, 0.8F).normalized() * 0.02F;  // the shaft rises away from its tip
  // Along the diagonal through the interior vertices (x = y), then along the edge line y = 4 kCell.
  const Vec3 start(0.0011F, 0.0011F, height);
  const Vec3 diagonal_end(0.0149F, 0.0149F, height);
  const int steps = 2000;
  const SweepResult diagonal = sweep(scene, steps, [&](int step) {
    const Vec3 tip = start + (diagonal_end - start) * (static_cast<float>(step) / static_cast<float>(steps));
    return capsule(ToolSegment::shaft, tip, tip + up);
  });
  EXPECT_EQ(diagonal.steps_in_contact, steps + 1);
  EXPECT_LT(diagonal.max_magnitude_change, 1e-3F);
  EXPECT_LT(diagonal.max_direction_change, 1e-3F);
  EXPECT_GE(diagonal.triangles.size(), 8U);  // one of each pair the diagonal edges separate
  // Across the plate in general position: edges of every direction.
  const Vec3 across_start(0.0011F, 0.0143F, height);
  const Vec3 across_end(0.0149F, 0.0021F, height);
  const SweepResult across = sweep(scene, steps, [&](int step) {
    const Vec3 tip = across_start + (across_end - across_start) * (static_cast<float>(step) / static_cast<float>(steps));
    return capsule(ToolSegment::shaft, tip, tip + up);
  });
  EXPECT_LT(across.max_magnitude_change, 1e-3F);
  EXPECT_LT(across.max_direction_change, 1e-3F);
  EXPECT_GE(across.triangles.size(), 14U);  // it really crossed many triangles
  const SweepResult edge_line = sweep(scene, steps, [&](int step) {
    const Vec3 tip(0.0011F + 0.0138F * static_cast<float>(step) / static_cast<float>(steps), 4.0F * kCell, height);
    return capsule(ToolSegment::shaft, tip, tip + up);
  });
  EXPECT_LT(edge_line.max_magnitude_change, 1e-3F);
  EXPECT_LT(edge_line.max_direction_change, 1e-3F);
  EXPECT_GE(edge_line.triangles.size(), 6U);
  // And the magnitude is the exact penalty everywhere on the sweep.
  ASSERT_TRUE(scene.run({capsule(ToolSegment::shaft, Vec3(0.008F, 0.008F, height), Vec3(0.008F, 0.008F, height) + up)})
                  .is_ok());
  ASSERT_EQ(scene.contact.contact_count(), 1U);
  EXPECT_NEAR(scene.contact.contact(0).force_on_tool_n.z(), kStiffness * (kReach - height), 1e-4F);
}

TEST(SegmentSurfaceContact, ForceIsContinuousWhenAParallelSegmentSlidesOverThePlate) {
  Scene scene = make_scene(make_plate());
  const float height = 2e-4F;
  const int steps = 1500;
  const SweepResult result = sweep(scene, steps, [&](int step) {
    const float shift = 0.008F * static_cast<float>(step) / static_cast<float>(steps);
    return capsule(ToolSegment::jaw0, Vec3(0.001F + shift, 0.0023F + 0.5F * shift, height),
                   Vec3(0.006F + shift, 0.004F + 0.5F * shift, height));
  });
  EXPECT_LT(result.max_magnitude_change, 1e-3F);
  EXPECT_LT(result.max_direction_change, 1e-3F);
  EXPECT_GE(result.triangles.size(), 4U);
}

TEST(SegmentSurfaceContact, ForceTurnsContinuouslyAroundTheConvexEdgesOfATube) {
  Scene scene = make_scene(make_tube());
  const float orbit = 0.0046F;  // from the axis: 0.6–0.68 mm from the wall, within reach
  const float first = std::numbers::pi_v<float> / kSegments;  // the middle of face column 0
  const float span = 2.0F * std::numbers::pi_v<float> / kSegments;  // to the middle of column 1
  // ~1e-4 rad per step: near an edge line the direction turns by about orbit / (orbit − R)
  // ≈ 8 times that, within the 1e-3 bound; a jump at the edge would be far larger.
  const int steps = 4000;
  const auto at = [&](float angle) {
    const Vec3 radial(std::cos(angle), std::sin(angle), 0.0F);
    // Ends between rings (a ring is every 2 mm), so the ends project inside faces.
    return capsule(ToolSegment::shaft, orbit * radial + Vec3(0.0F, 0.0F, 0.0123F),
                   orbit * radial + Vec3(0.0F, 0.0F, 0.0177F));
  };
  const SweepResult result = sweep(scene, steps, [&](int step) {
    return at(first + span * static_cast<float>(step) / static_cast<float>(steps));
  });
  EXPECT_EQ(result.steps_in_contact, steps + 1);
  EXPECT_LT(result.max_magnitude_change, 1e-3F);
  EXPECT_LT(result.max_direction_change, 1e-3F);
  EXPECT_TRUE(result.features.count(TriangleFeature::face) == 1);
  EXPECT_GE(result.features.size(), 2U);  // also the edges between the columns

  // At a face centre the force is radial with k (reach − (orbit − apothem)); over an edge line
  // radial with k (reach − (orbit − R)). Outward both times, remembered side outer.
  for (const auto& [angle, wall] : {std::pair{first, kApothem}, std::pair{2.0F * first, kTubeRadius}}) {
    ASSERT_TRUE(scene.run({at(angle)}).is_ok());
    ASSERT_EQ(scene.contact.contact_count(), 1U);
    const Vec3 radial(std::cos(angle), std::sin(angle), 0.0F);
    const float expected = kStiffness * (kReach - (orbit - wall));
    const Vec3 force = scene.contact.contact(0).force_on_tool_n;
    EXPECT_NEAR(force.norm(), expected, 1e-3F * expected);
    EXPECT_TRUE((force.normalized() - radial).norm() < 1e-3F) << force.transpose();
    EXPECT_EQ(scene.contact.side(ToolSegment::shaft), 1);
  }
}

TEST(SegmentSurfaceContact, JawInTheLumenIsPushedTowardsTheAxis) {
  Scene scene = make_scene(make_tube());
  const float angle = 5.0F * std::numbers::pi_v<float> / kSegments;  // middle of column 2
  const Vec3 radial(std::cos(angle), std::sin(angle), 0.0F);
  const float inside = kApothem - 7e-4F;
  ASSERT_TRUE(scene.run({capsule(ToolSegment::jaw0, inside * radial + Vec3(0.0F, 0.0F, 0.02F),
                                 inside * radial + Vec3(0.0F, 0.0F, 0.025F))})
                  .is_ok());
  ASSERT_EQ(scene.contact.contact_count(), 1U);
  const float expected = kStiffness * (kReach - 7e-4F);
  const Vec3 force = scene.contact.contact(0).force_on_tool_n;
  EXPECT_NEAR(force.norm(), expected, 1e-3F * expected);
  EXPECT_TRUE((force.normalized() + radial).norm() < 1e-4F) << force.transpose();
  EXPECT_EQ(scene.contact.side(ToolSegment::jaw0), -1);
}

// ---- 4. side memory ----

TEST(SegmentSurfaceContact, SegmentPushedThroughThePlateKeepsBeingPushedBackUntilItLeavesReach) {
  Scene scene = make_scene(make_plate());
  const Vec3 velocity(0.0F, 0.0F, -0.01F);
  const int steps = 300;
  bool crossed = false;
  for (int step = 0; step <= steps; ++step) {
    const float z = 1.1e-3F - 2.4e-3F * static_cast<float>(step) / static_cast<float>(steps);  // to −1.3 mm
    ASSERT_TRUE(scene.run({capsule(ToolSegment::shaft, Vec3(0.004F, 0.005F, z), Vec3(0.012F, 0.007F, z), kRadius,
                                   velocity)})
                    .is_ok());
    if (std::abs(z) < kReach - 1e-6F) {
      ASSERT_EQ(scene.contact.contact_count(), 1U) << z;
      const Vec3 force = scene.contact.contact(0).force_on_tool_n;
      const float expected = kStiffness * (kReach - std::abs(z));
      EXPECT_NEAR(force.z(), expected, 1e-3F * expected + 1e-6F) << z;  // +z: the side it came from
      EXPECT_NEAR(force.head<2>().norm(), 0.0F, 1e-6F) << z;
      EXPECT_EQ(scene.contact.side(ToolSegment::shaft), 1) << z;
      crossed = crossed || z < -1e-4F;
    } else if (z < -kReach - 1e-6F) {
      EXPECT_EQ(scene.contact.contact_count(), 0U) << z;  // pushed through: the contact ended
      EXPECT_EQ(scene.contact.side(ToolSegment::shaft), 0);
    }
  }
  EXPECT_TRUE(crossed);
  // Coming back up from below is a new contact from the inner side: pushed down.
  const float z = -9e-4F;
  ASSERT_TRUE(scene.run({capsule(ToolSegment::shaft, Vec3(0.004F, 0.005F, z), Vec3(0.012F, 0.007F, z), kRadius,
                                 -velocity)})
                  .is_ok());
  ASSERT_EQ(scene.contact.contact_count(), 1U);
  EXPECT_LT(scene.contact.contact(0).force_on_tool_n.z(), 0.0F);
  EXPECT_EQ(scene.contact.side(ToolSegment::shaft), -1);
}

TEST(SegmentSurfaceContact, TiltedSegmentCrossingThePlateIsPushedToTheSideItCameFrom) {
  Scene scene = make_scene(make_plate());
  // The jaw's tip approaches from above and goes 2 mm through; the jaw crosses the mid-surface
  // (distance 0) and must keep being pushed up with k·reach.
  const Vec3 along = Vec3(0.3F, 0.1F, 1.0F).normalized();
  for (int step = 0; step <= 200; ++step) {
    const Vec3 tip = Vec3(0.0071F, 0.0069F, 1.0e-3F - 3e-3F * static_cast<float>(step) / 200.0F);
    ASSERT_TRUE(scene.run({capsule(ToolSegment::jaw1, tip + 0.015F * along, tip)}).is_ok());
    ASSERT_EQ(scene.contact.contact_count(), 1U) << step;
    const Vec3 force = scene.contact.contact(0).force_on_tool_n;
    ASSERT_TRUE(finite(force));
    EXPECT_GT(force.z(), 0.0F) << step;
    if (tip.z() < -1e-5F) {
      EXPECT_EQ(scene.contact.contact(0).distance_m, 0.0F);
      EXPECT_NEAR(force.z(), kStiffness * kReach, 1e-4F) << step;
      EXPECT_NEAR(force.head<2>().norm(), 0.0F, 1e-6F);
    }
  }
}

TEST(SegmentSurfaceContact, ContactStartingOnTheMidSurfaceTakesTheSideTheSegmentCameFrom) {
  Scene scene = make_scene(make_plate());
  const Vec3 a(0.004F, 0.005F, 0.0F);
  const Vec3 b(0.012F, 0.007F, 0.0F);
  ASSERT_TRUE(scene.run({capsule(ToolSegment::jaw0, a, b, kRadius, Vec3(0.0F, 0.0F, -0.2F))}).is_ok());
  ASSERT_EQ(scene.contact.contact_count(), 1U);
  EXPECT_EQ(scene.contact.side(ToolSegment::jaw0), 1);  // moving down: came from above
  EXPECT_NEAR(scene.contact.contact(0).force_on_tool_n.z(), kStiffness * kReach, 1e-4F);
  scene.contact.reset();
  EXPECT_EQ(scene.contact.side(ToolSegment::jaw0), 0);
  EXPECT_EQ(scene.contact.contact_count(), 0U);
  ASSERT_TRUE(scene.run({capsule(ToolSegment::jaw0, a, b, kRadius, Vec3(0.0F, 0.0F, 0.2F))}).is_ok());
  EXPECT_EQ(scene.contact.side(ToolSegment::jaw0), -1);  // moving up: came from below
  EXPECT_NEAR(scene.contact.contact(0).force_on_tool_n.z(), -kStiffness * kReach, 1e-4F);
  // A segment left out of an update loses its memory.
  ASSERT_TRUE(scene.run({}).is_ok());
  EXPECT_EQ(scene.contact.side(ToolSegment::jaw0), 0);
}

// ---- 5. action = reaction ----

TEST(SegmentSurfaceContact, NodeForcesBalanceToolForcesAndFollowTheBarycentricWeights) {
  SegmentContactSettings settings = default_settings();
  settings.damping_n_s_per_m = 2.0F;
  Scene scene = make_scene(make_plate(), settings);
  std::vector<float> surface_velocities(scene.mesh.positions.size());
  for (std::size_t i = 0; i < surface_velocities.size(); ++i) {
    surface_velocities[i] = 0.01F * std::sin(static_cast<float>(i));
  }
  // Shaft lying over the plate, two jaws pointing at it from different angles; jaw 1 shares
  // the shaft's region so some nodes are loaded by two contacts.
  const std::vector<ToolCapsule> capsules = {
      capsule(ToolSegment::shaft, Vec3(0.002F, 0.013F, 9e-4F), Vec3(0.009F, 0.011F, 5e-4F), 0.0012F,
              Vec3(0.01F, -0.02F, -0.03F)),
      capsule(ToolSegment::jaw0, Vec3(0.01F, 0.0F, 0.01F), Vec3(0.0111F, 0.0047F, 3e-4F), kRadius,
              Vec3(0.0F, 0.0F, -0.05F)),
      capsule(ToolSegment::jaw1, Vec3(0.009F, 0.011F, 5e-4F), Vec3(0.0095F, 0.0105F, 1e-4F), 5e-4F,
              Vec3(0.02F, 0.0F, 0.0F))};
  ASSERT_TRUE(scene.run(capsules, surface_velocities).is_ok());
  ASSERT_EQ(scene.contact.contact_count(), 3U);
  const Vec3 tools = sum_tool_forces(scene.contact);
  const Vec3 nodes = sum_node_forces(scene.contact);
  EXPECT_GT(tools.norm(), 0.5F);
  EXPECT_LT((tools + nodes).norm(), 1e-5F * tools.norm()) << tools.transpose() << " / " << nodes.transpose();
  std::set<std::uint32_t> distinct;
  for (const NodeForce& force : scene.contact.node_forces()) EXPECT_TRUE(distinct.insert(force.node).second);

  // One contact: every vertex carries −w·F and the weights locate the mesh point.
  ASSERT_TRUE(scene.run({capsules[1]}).is_ok());
  ASSERT_EQ(scene.contact.contact_count(), 1U);
  const SegmentContact& contact = scene.contact.contact(0);
  Vec3 located = Vec3::Zero();
  for (int corner = 0; corner < 3; ++corner) {
    located += contact.barycentric[corner] * scene.node(contact.vertices[static_cast<std::size_t>(corner)]);
    const float weight = contact.barycentric[corner];
    const auto entry = std::find_if(scene.contact.node_forces().begin(), scene.contact.node_forces().end(),
                                    [&](const NodeForce& force) { return force.node == contact.vertices[static_cast<std::size_t>(corner)]; });
    if (weight == 0.0F) {
      EXPECT_EQ(entry, scene.contact.node_forces().end());
      continue;
    }
    ASSERT_NE(entry, scene.contact.node_forces().end());
    EXPECT_LT((entry->force_n + weight * contact.force_on_tool_n).norm(), 1e-6F * contact.force_on_tool_n.norm());
  }
  EXPECT_LT((located - contact.mesh_point_m).norm(), 1e-7F);
  EXPECT_LT((located - Vec3(0.0111F, 0.0047F, 0.0F)).norm(), 1e-7F);

  // The caller's span: copies what fits, counts the rest.
  ASSERT_TRUE(scene.run(capsules, surface_velocities).is_ok());
  const std::size_t total = scene.contact.node_forces().size();
  ASSERT_GE(total, 4U);
  std::array<NodeForce, 9> all{};
  EXPECT_EQ(scene.contact.write_node_forces(all), total);
  EXPECT_EQ(scene.contact.node_force_overflow_count(), 0U);
  for (std::size_t i = 0; i < total; ++i) EXPECT_EQ(all[i].node, scene.contact.node_forces()[i].node);
  std::array<NodeForce, 2> few{};
  EXPECT_EQ(scene.contact.write_node_forces(few), 2U);
  EXPECT_EQ(scene.contact.node_force_overflow_count(), total - 2);
}

// ---- 6. clamp, damping, refusals, deformation ----

TEST(SegmentSurfaceContact, ForceIsClampedToMaxForce) {
  SegmentContactSettings settings = default_settings();
  settings.max_force_n = 0.5F;
  Scene scene = make_scene(make_plate(), settings);
  ASSERT_TRUE(scene.run({capsule(ToolSegment::shaft, Vec3(0.005F, 0.005F, 1e-4F), Vec3(0.005F, 0.005F, 0.02F))}).is_ok());
  ASSERT_EQ(scene.contact.contact_count(), 1U);
  EXPECT_TRUE(scene.contact.contact(0).clamped);
  EXPECT_NEAR(scene.contact.contact(0).force_on_tool_n.norm(), 0.5F, 1e-6F);
  EXPECT_NEAR(scene.contact.contact(0).force_on_tool_n.z(), 0.5F, 1e-6F);
  EXPECT_LT((sum_node_forces(scene.contact) + sum_tool_forces(scene.contact)).norm(), 1e-6F);
  // Below the clamp: not clamped.
  ASSERT_TRUE(scene.run({capsule(ToolSegment::shaft, Vec3(0.005F, 0.005F, 9e-4F), Vec3(0.005F, 0.005F, 0.02F))}).is_ok());
  EXPECT_FALSE(scene.contact.contact(0).clamped);
  EXPECT_NEAR(scene.contact.contact(0).force_on_tool_n.z(), kStiffness * (kReach - 9e-4F), 1e-5F);
}

TEST(SegmentSurfaceContact, DamperResistsApproachAndNeverPulls) {
  SegmentContactSettings settings = default_settings();
  settings.damping_n_s_per_m = 5.0F;
  Scene scene = make_scene(make_plate(), settings);
  const float height = 6e-4F;
  const float spring = kStiffness * (kReach - height);
  const auto run_with = [&](const Vec3& velocity, const std::vector<float>& surface = {}) {
    EXPECT_TRUE(scene.run({capsule(ToolSegment::jaw0, Vec3(0.007F, 0.006F, height), Vec3(0.007F, 0.006F, 0.02F),
                                   kRadius, velocity)},
                          surface)
                    .is_ok());
    EXPECT_EQ(scene.contact.contact_count(), 1U);
    return scene.contact.contact_count() == 1 ? scene.contact.contact(0).force_on_tool_n : Vec3::Zero();
  };
  // Approaching at 0.1 m/s: + b v.
  EXPECT_NEAR(run_with(Vec3(0.0F, 0.0F, -0.1F)).z(), spring + 0.5F, 1e-5F);
  // Tangential motion: no normal damping.
  EXPECT_NEAR(run_with(Vec3(0.3F, 0.0F, 0.0F)).z(), spring, 1e-5F);
  // Separating slowly: less force, still pushing.
  EXPECT_NEAR(run_with(Vec3(0.0F, 0.0F, 0.05F)).z(), spring - 0.25F, 1e-5F);
  // Separating fast: the damper would pull; the force is zero, the contact still recorded.
  const Vec3 fast = run_with(Vec3(0.0F, 0.0F, 1.0F));
  EXPECT_EQ(fast.z(), 0.0F);
  EXPECT_TRUE(scene.contact.node_forces().empty());
  // The surface moving with the tool: no relative velocity, no damping.
  std::vector<float> surface(scene.mesh.positions.size(), 0.0F);
  for (std::size_t i = 2; i < surface.size(); i += 3) surface[i] = -0.1F;
  EXPECT_NEAR(run_with(Vec3(0.0F, 0.0F, -0.1F), surface).z(), spring, 1e-5F);
}

TEST(SegmentSurfaceContact, NonFiniteInputIsRefusedWithNoOutput) {
  Scene scene = make_scene(make_plate());
  const ToolCapsule good = capsule(ToolSegment::shaft, Vec3(0.005F, 0.005F, 5e-4F), Vec3(0.01F, 0.005F, 0.01F));
  ASSERT_TRUE(scene.run({good}).is_ok());
  ASSERT_EQ(scene.contact.contact_count(), 1U);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<ToolCapsule> bad_inputs;
  for (int which = 0; which < 4; ++which) {
    ToolCapsule bad = good;
    bad.segment = ToolSegment::jaw0;
    if (which == 0) bad.start_m.x() = nan;
    if (which == 1) bad.end_m.z() = inf;
    if (which == 2) bad.start_velocity_m_per_s.y() = nan;
    if (which == 3) bad.end_velocity_m_per_s.x() = -inf;
    bad_inputs.push_back(bad);
  }
  for (const ToolCapsule& bad : bad_inputs) {
    const core::Status status = scene.run({good, bad});
    EXPECT_EQ(status.code(), core::StatusCode::numeric_error);
    EXPECT_EQ(scene.contact.contact_count(), 0U);
    EXPECT_TRUE(scene.contact.tool_forces().empty());
    EXPECT_TRUE(scene.contact.node_forces().empty());
    EXPECT_EQ(scene.contact.side(ToolSegment::shaft), 1);  // a glitch does not drop the memory
  }
  ToolCapsule nan_radius = good;
  nan_radius.radius_m = nan;
  EXPECT_EQ(scene.run({nan_radius}).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(scene.contact.contact_count(), 0U);
  ToolCapsule negative_radius = good;
  negative_radius.radius_m = -1e-3F;
  EXPECT_EQ(scene.run({negative_radius}).code(), core::StatusCode::invalid_argument);
  // Repeated or unknown segment, too many capsules, wrong surface velocity size.
  EXPECT_EQ(scene.run({good, good}).code(), core::StatusCode::invalid_argument);
  ToolCapsule unknown = good;
  unknown.segment = static_cast<ToolSegment>(7);
  EXPECT_EQ(scene.run({unknown}).code(), core::StatusCode::invalid_argument);
  ToolCapsule jaw0 = good;
  jaw0.segment = ToolSegment::jaw0;
  ToolCapsule jaw1 = good;
  jaw1.segment = ToolSegment::jaw1;
  EXPECT_EQ(scene.run({good, jaw0, jaw1, good}).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(scene.run({good}, std::vector<float>(5, 0.0F)).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(scene.contact.contact_count(), 0U);
  // And the object recovers at once.
  ASSERT_TRUE(scene.run({good, jaw0, jaw1}).is_ok());
  EXPECT_EQ(scene.contact.contact_count(), 3U);
  for (const SegmentContact& contact : scene.contact.contacts()) EXPECT_TRUE(finite(contact.force_on_tool_n));
}

TEST(SegmentSurfaceContact, DeformedMeshMovesTheContact) {
  Scene scene = make_scene(make_plate());
  const ToolCapsule tool = capsule(ToolSegment::jaw1, Vec3(0.0081F, 0.0079F, 8e-4F), Vec3(0.0081F, 0.0079F, 0.02F));
  ASSERT_TRUE(scene.run({tool}).is_ok());
  ASSERT_EQ(scene.contact.contact_count(), 1U);
  const float before = scene.contact.contact(0).force_on_tool_n.z();
  // Lift the whole plate by 0.3 mm (rebuilt grid in run()): 0.3 N more, contact point lifted.
  for (std::size_t i = 2; i < scene.mesh.positions.size(); i += 3) scene.mesh.positions[i] += 3e-4F;
  ASSERT_TRUE(scene.run({tool}).is_ok());
  ASSERT_EQ(scene.contact.contact_count(), 1U);
  EXPECT_NEAR(scene.contact.contact(0).force_on_tool_n.z() - before, kStiffness * 3e-4F, 1e-5F);
  EXPECT_NEAR(scene.contact.contact(0).mesh_point_m.z(), 3e-4F, 1e-7F);
  // Raise the interior vertex (8 mm, 8 mm) into a 1.5 mm peak and hold the tool's tip 0.4 mm
  // above it, a little aside (in the Voronoi region of the apex of every incident triangle):
  // the closest point is that vertex and the force points from it to the tip.
  const std::uint32_t peak = 4 * 9 + 4;
  scene.mesh.positions[3 * peak + 2] = 1.5e-3F;
  const Vec3 tip(0.0081F, 0.0079F, 1.9e-3F);
  ASSERT_TRUE(scene.run({capsule(ToolSegment::jaw1, tip + Vec3(0.0F, 0.0F, 0.01F), tip)}).is_ok());
  ASSERT_EQ(scene.contact.contact_count(), 1U);
  const SegmentContact& contact = scene.contact.contact(0);
  EXPECT_LT((contact.mesh_point_m - scene.node(peak)).norm(), 1e-6F);
  EXPECT_GE(static_cast<int>(contact.feature), static_cast<int>(TriangleFeature::vertex0));
  const Vec3 offset = tip - scene.node(peak);
  EXPECT_LT((contact.normal - offset.normalized()).norm(), 1e-3F) << contact.normal.transpose();
  EXPECT_NEAR(contact.force_on_tool_n.norm(), kStiffness * (kReach - offset.norm()), 1e-4F);
}

TEST(SegmentSurfaceContact, CandidateOverflowUsesTheFirstCandidatesAndIsCounted) {
  SegmentContactSettings settings = default_settings();
  settings.max_candidates = 3;
  Scene scene = make_scene(make_plate(), settings);
  // A shaft lying over the whole plate: dozens of triangles in its box.
  const core::Status status =
      scene.run({capsule(ToolSegment::shaft, Vec3(0.001F, 0.001F, 5e-4F), Vec3(0.015F, 0.015F, 5e-4F))});
  EXPECT_EQ(status.code(), core::StatusCode::capacity_exceeded);
  EXPECT_EQ(scene.contact.candidate_overflow_count(), 1U);
  ASSERT_EQ(scene.contact.contact_count(), 1U);  // the plate is flat: any candidate is right
  EXPECT_NEAR(scene.contact.contact(0).force_on_tool_n.z(), kStiffness * (kReach - 5e-4F), 1e-4F);
  EXPECT_EQ(scene.run({capsule(ToolSegment::shaft, Vec3(0.001F, 0.015F, 5e-4F), Vec3(0.015F, 0.001F, 5e-4F))}).code(),
            core::StatusCode::capacity_exceeded);
  EXPECT_EQ(scene.contact.candidate_overflow_count(), 2U);
  // With room for every candidate the same query is fine and nothing is counted.
  Scene roomy = make_scene(make_plate());
  ASSERT_TRUE(roomy.run({capsule(ToolSegment::shaft, Vec3(0.001F, 0.001F, 5e-4F), Vec3(0.015F, 0.015F, 5e-4F))}).is_ok());
  EXPECT_EQ(roomy.contact.candidate_overflow_count(), 0U);
}

TEST(SegmentSurfaceContact, DegenerateTrianglesAreSkipped) {
  Mesh mesh;
  mesh.positions = {0.0F, 0.0F, 0.0F, 0.01F, 0.0F, 0.0F, 0.02F, 0.0F, 0.0F, 0.0F, 0.01F, 0.0F};
  mesh.triangles = {0, 1, 2};  // collinear: no plane
  Scene scene = make_scene(std::move(mesh));
  ASSERT_TRUE(scene.run({capsule(ToolSegment::shaft, Vec3(0.01F, 0.0F, 3e-4F), Vec3(0.01F, 0.0F, 0.01F))}).is_ok());
  EXPECT_EQ(scene.contact.contact_count(), 0U);
  scene.mesh.triangles = {0, 1, 2, 0, 1, 3};  // plus a real one sharing the edge
  ASSERT_TRUE(scene.run({capsule(ToolSegment::shaft, Vec3(0.005F, 0.002F, 3e-4F), Vec3(0.005F, 0.002F, 0.01F))}).is_ok());
  ASSERT_EQ(scene.contact.contact_count(), 1U);
  EXPECT_EQ(scene.contact.contact(0).triangle, 1U);
}

TEST(SegmentSurfaceContact, SettingsAreCheckedFieldByField) {
  auto arena = core::Arena::create(1U << 20);
  ASSERT_TRUE(arena.has_value());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  struct Case {
    const char* field;
    SegmentContactSettings settings;
  };
  std::vector<Case> cases;
  SegmentContactSettings s = default_settings();
  s.surface_half_thickness_m = -1e-4F;
  cases.push_back({"surface_half_thickness_m", s});
  s = default_settings();
  s.stiffness_n_per_m = 0.0F;
  cases.push_back({"stiffness_n_per_m", s});
  s = default_settings();
  s.stiffness_n_per_m = nan;
  cases.push_back({"stiffness_n_per_m", s});
  s = default_settings();
  s.damping_n_s_per_m = -1.0F;
  cases.push_back({"damping_n_s_per_m", s});
  s = default_settings();
  s.max_force_n = std::numeric_limits<float>::infinity();
  cases.push_back({"max_force_n", s});
  s = default_settings();
  s.max_candidates = 0;
  cases.push_back({"max_candidates", s});
  for (const Case& c : cases) {
    auto refused = SegmentSurfaceContact::create(c.settings, arena.value());
    ASSERT_FALSE(refused.has_value()) << c.field;
    EXPECT_NE(refused.error().message.find(c.field), std::string::npos) << refused.error().message;
    EXPECT_NE(refused.error().message.find("segment contact"), std::string::npos);
  }
  EXPECT_TRUE(SegmentSurfaceContact::create(default_settings(), arena.value()).has_value());
  auto tiny = core::Arena::create(64);
  ASSERT_TRUE(tiny.has_value());
  auto exhausted = SegmentSurfaceContact::create(default_settings(), tiny.value());
  ASSERT_FALSE(exhausted.has_value());
  EXPECT_NE(exhausted.error().message.find("arena"), std::string::npos);
}

// ---- 7. no heap ----

TEST(SegmentSurfaceContact, NoHeapInAThousandUpdates) {
  if (!core::alloc::hooks_installed()) GTEST_SKIP() << "allocation hooks not linked";
  Scene scene = make_scene(make_tube());
  const TriangleMeshView view{scene.mesh.positions, scene.mesh.triangles};
  std::vector<float> surface_velocities(scene.mesh.positions.size(), 0.001F);
  std::array<ToolCapsule, 3> capsules{};
  std::array<NodeForce, 9> node_forces{};
  std::uint64_t contacts = 0;
  ASSERT_TRUE(scene.grid.rebuild(scene.mesh.positions, scene.mesh.triangles).is_ok());
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (int cycle = 0; cycle < 1000; ++cycle) {
    const float angle = 1e-3F * static_cast<float>(cycle);
    const Vec3 radial(std::cos(angle), std::sin(angle), 0.0F);
    const Vec3 hinge = (kApothem + 5e-4F) * radial + Vec3(0.0F, 0.0F, 0.02F);
    capsules[0] = capsule(ToolSegment::shaft, hinge + Vec3(0.0F, 0.0F, -0.015F), hinge, 0.0025F, Vec3(0.01F, 0.0F, 0.0F));
    capsules[1] = capsule(ToolSegment::jaw0, hinge, hinge + 0.01F * radial.cross(Vec3::UnitZ()), kRadius);
    capsules[2] = capsule(ToolSegment::jaw1, hinge, hinge - 0.01F * radial.cross(Vec3::UnitZ()), kRadius);
    if (!scene.contact.update(capsules, view, surface_velocities, scene.grid).is_ok()) break;
    contacts += scene.contact.contact_count();
    static_cast<void>(scene.contact.write_node_forces(node_forces));
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
  EXPECT_EQ(contacts, 3000U);
}

}  // namespace
}  // namespace trainer::model
