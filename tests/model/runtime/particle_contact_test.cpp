// Particle sphere vs triangle shell contact (particle_contact.hpp) on hand-built meshes with
// known answers: a 16-sided tube like the duct (pressing on the inner wall, the outside,
// sliding across shared edges and creases), a flat plate (one force on an edge or a vertex,
// coincident particles), degenerate triangles, action = reaction (force and moment) with
// damping on a deformed tube, capacities and refusals, no heap in the RT call, the particle
// catheter settling against a rigid tube under a sideways push, and the hand-over of the node
// forces to a ModalModel.
#include "trainer/model/particle_contact.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/model/catheter.hpp"
#include "trainer/model/modal_model.hpp"

namespace trainer::model {
namespace {

constexpr float kStiffness = 1000.0F;  // N/m: 1 mm of penetration = 1 N
constexpr float kRadius = 5e-4F;       // particle radius (m)
constexpr float kOffset = 1e-4F;       // half the wall thickness (m)
constexpr float kReach = kRadius + kOffset;

constexpr float kTubeRadius = 0.004F;
constexpr float kTubeLength = 0.04F;
constexpr std::uint32_t kSegments = 16;
constexpr std::uint32_t kRings = 21;  // 2 (21 − 1) 16 = 640 triangles, like the duct
const float kApothem = kTubeRadius * std::cos(std::numbers::pi_v<float> / kSegments);

struct Mesh {
  std::vector<float> positions;
  std::vector<std::uint32_t> triangles;
};

// Tube along z with outward normals; `radial_wave_m` adds a peristaltic-like deformation.
Mesh make_tube(float radial_wave_m = 0.0F) {
  Mesh mesh;
  for (std::uint32_t r = 0; r < kRings; ++r) {
    const float z = kTubeLength * static_cast<float>(r) / static_cast<float>(kRings - 1);
    const float radius = kTubeRadius + radial_wave_m * std::sin(400.0F * z);
    for (std::uint32_t s = 0; s < kSegments; ++s) {
      const float angle = 2.0F * std::numbers::pi_v<float> * static_cast<float>(s) / kSegments;
      mesh.positions.insert(mesh.positions.end(), {radius * std::cos(angle), radius * std::sin(angle), z});
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

// Unit radial direction through the middle of the tube's face column `segment`.
Vec3 face_direction(float segment) {
  const float angle = 2.0F * std::numbers::pi_v<float> * (segment + 0.5F) / kSegments;
  return {std::cos(angle), std::sin(angle), 0.0F};
}

// Plate [0, 4h]² at z = 0, normal +z, 4 × 4 quads split along alternating diagonals so
// interior vertices have 4, 6 or 8 triangles.
Mesh make_plate(float h = 0.002F) {
  Mesh mesh;
  for (std::uint32_t y = 0; y <= 4; ++y) {
    for (std::uint32_t x = 0; x <= 4; ++x) {
      mesh.positions.insert(mesh.positions.end(), {h * static_cast<float>(x), h * static_cast<float>(y), 0.0F});
    }
  }
  for (std::uint32_t y = 0; y < 4; ++y) {
    for (std::uint32_t x = 0; x < 4; ++x) {
      const std::uint32_t a = y * 5 + x;
      const std::uint32_t b = a + 1;
      const std::uint32_t c = a + 6;
      const std::uint32_t d = a + 5;
      if ((x + y) % 2 == 0) {
        mesh.triangles.insert(mesh.triangles.end(), {a, b, c, a, c, d});
      } else {
        mesh.triangles.insert(mesh.triangles.end(), {a, b, d, b, c, d});
      }
    }
  }
  return mesh;
}

ParticleContactSettings default_settings(ContactSide side) {
  ParticleContactSettings settings;
  settings.max_particles = 64;
  settings.max_contacts = 256;
  settings.max_nodes = 4096;
  settings.stiffness_n_per_m = kStiffness;
  settings.surface_offset_m = kOffset;
  settings.max_force_n = 100.0F;
  settings.side = side;
  return settings;
}

struct Scene {
  Mesh mesh;
  core::Arena arena;
  BucketGrid grid;
  ParticleSurfaceContact contact;
  ParticleContactOutput out;

  core::Status run(const std::vector<Vec3>& particles, const std::vector<Vec3>& velocities = {},
                   float radius_m = kRadius, const std::vector<float>& surface_velocities = {}) {
    EXPECT_TRUE(grid.rebuild(mesh.positions, mesh.triangles).is_ok());
    return contact.compute(particles, velocities, radius_m, {mesh.positions, mesh.triangles},
                           surface_velocities, grid, out);
  }
  Vec3 node(std::uint32_t index) const {
    return {mesh.positions[3 * index], mesh.positions[3 * index + 1], mesh.positions[3 * index + 2]};
  }
};

Scene make_scene(Mesh mesh, const ParticleContactSettings& settings) {
  auto arena = core::Arena::create(8U << 20);
  EXPECT_TRUE(arena.has_value());
  core::Arena owned = std::move(arena).value();
  auto grid = BucketGrid::create({4096, 4096, 0.002F, 4096, 1U << 16}, owned);
  EXPECT_TRUE(grid.has_value());
  auto contact = ParticleSurfaceContact::create(settings, owned);
  EXPECT_TRUE(contact.has_value()) << (contact ? "" : contact.error().message);
  return Scene{std::move(mesh), std::move(owned), std::move(grid).value(), std::move(contact).value(), {}};
}

bool finite(const Vec3& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); }

// Σ particle forces + Σ node forces and the same for the moments about the origin (forces at
// the particle centres and at the nodes); both must vanish to float rounding of the scale.
void expect_action_equals_reaction(const Scene& scene, const std::vector<Vec3>& particles) {
  Vec3 force_sum = Vec3::Zero();
  Vec3 moment_sum = Vec3::Zero();
  float force_scale = 0.0F;
  float moment_scale = 0.0F;
  for (std::size_t i = 0; i < scene.out.particle_forces_n.size(); ++i) {
    const Vec3& force = scene.out.particle_forces_n[i];
    ASSERT_TRUE(finite(force));
    force_sum += force;
    moment_sum += particles[i].cross(force);
    force_scale += force.norm();
    moment_scale += particles[i].norm() * force.norm();
  }
  std::set<std::uint32_t> nodes;
  for (const NodeForce& entry : scene.out.node_forces) {
    ASSERT_TRUE(finite(entry.force_n));
    EXPECT_TRUE(nodes.insert(entry.node).second) << "node " << entry.node << " listed twice";
    force_sum += entry.force_n;
    moment_sum += scene.node(entry.node).cross(entry.force_n);
    force_scale += entry.force_n.norm();
    moment_scale += scene.node(entry.node).norm() * entry.force_n.norm();
  }
  // float sums of O(100) terms: a few 1e-7 relative.
  EXPECT_LE(force_sum.norm(), 2e-6F * force_scale + 1e-9F);
  EXPECT_LE(moment_sum.norm(), 2e-6F * moment_scale + 1e-12F);
}

TEST(ParticleSurfaceContact, InsideParticlePressesTheInnerWallTowardsTheAxis) {
  Scene scene = make_scene(make_tube(), default_settings(ContactSide::inner));
  const Vec3 outward = face_direction(2.0F);
  for (float depth : {1e-6F, 1e-5F, 1e-4F, 3e-4F, 5.9e-4F}) {
    for (float z : {0.0105F, 0.0113F, 0.0291F}) {
      const Vec3 centre = (kApothem - kReach + depth) * outward + Vec3(0, 0, z);
      ASSERT_TRUE(scene.run({centre}).is_ok());
      ASSERT_EQ(scene.out.contact_count, 1U) << depth << " " << z;
      const Vec3 expected = -kStiffness * depth * outward;  // towards the axis
      EXPECT_LT((scene.out.particle_forces_n[0] - expected).norm(), 2e-3F * kStiffness * depth + 2e-5F)
          << "depth " << depth << " z " << z;
      EXPECT_LE(scene.out.node_forces.size(), 3U);
      expect_action_equals_reaction(scene, {centre});
      // The record describes the same contact: the particle, its distance to the mid-surface
      // (reach − depth), the normal towards the axis and a closest point that is the
      // barycentric mix of the recorded vertices.
      ASSERT_EQ(scene.out.contacts.size(), 1U);
      const ParticleContactRecord& record = scene.out.contacts[0];
      EXPECT_EQ(record.particle, 0U);
      EXPECT_NEAR(record.distance_m, kReach - depth, 2e-6F);
      EXPECT_LT((record.normal + outward).norm(), 1e-3F);
      Vec3 mixed = Vec3::Zero();
      for (std::size_t corner = 0; corner < 3; ++corner) {
        mixed += record.barycentric[static_cast<Eigen::Index>(corner)] * scene.node(record.vertices[corner]);
      }
      EXPECT_LT((mixed - record.point_m).norm(), 1e-6F);
      EXPECT_LT((record.point_m + record.distance_m * record.normal - centre).norm(), 2e-6F);
    }
  }
  // On the axis and just short of touching: nothing.
  for (const Vec3& centre : {Vec3(0, 0, 0.02F), Vec3((kApothem - kReach - 1e-5F) * outward + Vec3(0, 0, 0.02F))}) {
    ASSERT_TRUE(scene.run({centre}).is_ok());
    EXPECT_EQ(scene.out.contact_count, 0U);
    EXPECT_EQ(scene.out.particle_forces_n[0], Vec3::Zero());
    EXPECT_TRUE(scene.out.node_forces.empty());
  }
}

TEST(ParticleSurfaceContact, SideSelectsWhichParticlesTouch) {
  const Vec3 outward = face_direction(5.0F);
  const float depth = 2e-4F;
  const Vec3 inside = (kApothem - kReach + depth) * outward + Vec3(0, 0, 0.02F);
  const Vec3 outside = (kApothem + kReach - depth) * outward + Vec3(0, 0, 0.02F);
  // Just outside a vertex of the polygon (a convex edge seen from outside): the closest point
  // is on the edge line, where only the pseudo-normal tells the side reliably.
  const Vec3 outside_edge = Vec3(kTubeRadius + 3e-4F, 0.0F, 0.021F);
  {
    Scene scene = make_scene(make_tube(), default_settings(ContactSide::inner));
    ASSERT_TRUE(scene.run({outside, outside_edge}).is_ok());
    EXPECT_EQ(scene.out.contact_count, 0U);
    EXPECT_EQ(scene.out.particle_forces_n[0], Vec3::Zero());
    EXPECT_EQ(scene.out.particle_forces_n[1], Vec3::Zero());
    EXPECT_TRUE(scene.out.node_forces.empty());
  }
  {
    Scene scene = make_scene(make_tube(), default_settings(ContactSide::outer));
    ASSERT_TRUE(scene.run({outside, inside, outside_edge}).is_ok());
    EXPECT_EQ(scene.out.contact_count, 2U);
    EXPECT_LT((scene.out.particle_forces_n[0] - kStiffness * depth * outward).norm(), 1e-3F);
    EXPECT_EQ(scene.out.particle_forces_n[1], Vec3::Zero());
    // Outside the vertex column: pushed away from the edge, radially.
    const Vec3 edge_force = scene.out.particle_forces_n[2];
    EXPECT_NEAR(edge_force.norm(), kStiffness * (kReach - 3e-4F), 1e-3F);
    EXPECT_GT(edge_force.normalized().x(), 0.9999F);
  }
  {
    Scene scene = make_scene(make_tube(), default_settings(ContactSide::both));
    ASSERT_TRUE(scene.run({outside, inside}).is_ok());
    EXPECT_EQ(scene.out.contact_count, 2U);
    EXPECT_LT((scene.out.particle_forces_n[0] - kStiffness * depth * outward).norm(), 1e-3F);
    EXPECT_LT((scene.out.particle_forces_n[1] + kStiffness * depth * outward).norm(), 1e-3F);
  }
}

TEST(ParticleSurfaceContact, ActionEqualsReactionWithDampingOnADeformedTube) {
  ParticleContactSettings settings = default_settings(ContactSide::inner);
  settings.damping_n_s_per_m = 0.5F;
  Scene scene = make_scene(make_tube(3e-4F), settings);
  std::mt19937 random(11);
  std::uniform_real_distribution<float> unit(0.0F, 1.0F);
  std::uniform_real_distribution<float> speed(-0.05F, 0.05F);
  std::uint32_t contacts = 0;
  for (int trial = 0; trial < 50; ++trial) {
    std::vector<Vec3> particles;
    std::vector<Vec3> velocities;
    for (int i = 0; i < 41; ++i) {
      const float angle = 2.0F * std::numbers::pi_v<float> * unit(random);
      const float radius = kTubeRadius - 1.2e-3F + 1.4e-3F * unit(random);
      particles.emplace_back(radius * std::cos(angle), radius * std::sin(angle), 0.002F + 0.036F * unit(random));
      velocities.emplace_back(speed(random), speed(random), speed(random));
    }
    std::vector<float> surface_velocities(scene.mesh.positions.size());
    for (float& value : surface_velocities) value = 0.4F * speed(random);
    ASSERT_TRUE(scene.run(particles, velocities, kRadius, surface_velocities).is_ok());
    contacts += scene.out.contact_count;
    expect_action_equals_reaction(scene, particles);
  }
  EXPECT_GT(contacts, 500U);  // most particles were near the wall
}

TEST(ParticleSurfaceContact, SlidingAcrossSharedEdgesKeepsTheMagnitudeContinuous) {
  Scene scene = make_scene(make_tube(), default_settings(ContactSide::inner));
  // Along z over a face column: crosses 10 ring edges and 10 diagonals; force constant.
  const Vec3 outward = face_direction(7.0F);
  const float depth = 2e-4F;
  for (int step = 0; step <= 2000; ++step) {
    const Vec3 centre = (kApothem - kReach + depth) * outward + Vec3(0, 0, 0.01F + 1e-5F * static_cast<float>(step));
    ASSERT_TRUE(scene.run({centre}).is_ok());
    ASSERT_EQ(scene.out.contact_count, 1U) << step;
    ASSERT_LT((scene.out.particle_forces_n[0] + kStiffness * depth * outward).norm(), 1e-3F) << step;
  }
  // Around the circumference at a constant radius: 16 concave creases. The distance to the
  // mesh is 1-Lipschitz, so |Δ|F|| ≤ k |Δcentre| per step; the direction turns at a crease.
  const float orbit = kApothem - kReach + depth;
  float previous = -1.0F;
  float smallest = std::numeric_limits<float>::max();
  float largest = 0.0F;
  for (int step = 0; step <= 6400; ++step) {
    const float angle = 1e-3F * static_cast<float>(step);
    const Vec3 centre(orbit * std::cos(angle), orbit * std::sin(angle), 0.0203F);
    ASSERT_TRUE(scene.run({centre}).is_ok());
    ASSERT_EQ(scene.out.contact_count, 1U) << step;
    const Vec3 force = scene.out.particle_forces_n[0];
    // The walls are vertical, so the force is horizontal up to float rounding of the contact
    // direction (a 0.4 mm lever between float closest points 4 mm from the axis): 1e-3 of |F|.
    ASSERT_LT(std::abs(force.z()), 1e-3F * force.norm()) << step << " " << force.transpose();
    ASSERT_LT(force.dot(centre), 0.0F);  // towards the axis
    const float magnitude = force.norm();
    if (previous >= 0.0F) {
      ASSERT_LE(std::abs(magnitude - previous), kStiffness * orbit * 1e-3F * 1.01F + 1e-5F) << step;
    }
    previous = magnitude;
    smallest = std::min(smallest, magnitude);
    largest = std::max(largest, magnitude);
  }
  EXPECT_NEAR(largest, kStiffness * depth, 1e-4F);  // at the face centres
  EXPECT_LT(smallest, 0.8F * largest);              // the creases are farther away
}

TEST(ParticleSurfaceContact, EdgeOrVertexOfAFlatPlateGivesOneForce) {
  Scene scene = make_scene(make_plate(), default_settings(ContactSide::outer));
  const float h = 0.002F;
  const float depth = 1.5e-4F;
  const float height = kReach - depth;
  // Vertex (2, 2) has 4 triangles, (1, 2) 8 triangles... every interior vertex and the middle
  // of an edge (diagonal and axis-aligned), and a face point for comparison.
  const std::vector<Vec3> points = {{2 * h, 2 * h, 0},   {1 * h, 2 * h, 0},     {1 * h, 1 * h, 0},
                                    {1.5F * h, 2 * h, 0}, {1.5F * h, 1.5F * h, 0}, {2.5F * h, 2.5F * h, 0},
                                    {1.3F * h, 1.6F * h, 0}};
  for (const Vec3& point : points) {
    const Vec3 centre = point + Vec3(0, 0, height);
    ASSERT_TRUE(scene.run({centre}).is_ok());
    EXPECT_EQ(scene.out.contact_count, 1U);
    EXPECT_LT((scene.out.particle_forces_n[0] - Vec3(0, 0, kStiffness * depth)).norm(), 1e-4F)
        << point.transpose();
    expect_action_equals_reaction(scene, {centre});
  }
  // Exactly above a vertex: the whole reaction on that node.
  ASSERT_TRUE(scene.run({points[0] + Vec3(0, 0, height)}).is_ok());
  ASSERT_EQ(scene.out.node_forces.size(), 1U);
  EXPECT_EQ(scene.out.node_forces[0].node, 12U);
  // Coincident with the surface at a vertex and on an edge: depth = reach, the stored normal
  // side for outer/both, the opposite for inner.
  for (ContactSide side : {ContactSide::outer, ContactSide::inner, ContactSide::both}) {
    Scene sided = make_scene(make_plate(), default_settings(side));
    for (const Vec3& point : {points[1], points[3], points[6]}) {
      ASSERT_TRUE(sided.run({point}).is_ok());
      ASSERT_EQ(sided.out.contact_count, 1U);
      const float sign = side == ContactSide::inner ? -1.0F : 1.0F;
      EXPECT_LT((sided.out.particle_forces_n[0] - Vec3(0, 0, sign * kStiffness * kReach)).norm(), 1e-4F);
      expect_action_equals_reaction(sided, {point});
    }
  }
}

TEST(ParticleSurfaceContact, TwoSeparatePatchesBothPush) {
  // Two plates 1 mm apart facing each other (a collapsed duct): a particle between them,
  // 0.45 and 0.55 mm from them, touches two unconnected patches and gets both forces.
  Mesh mesh = make_plate();
  const Mesh upper = make_plate();
  const auto base = static_cast<std::uint32_t>(mesh.positions.size() / 3);
  for (std::size_t v = 0; v < upper.positions.size(); v += 3) {
    mesh.positions.insert(mesh.positions.end(), {upper.positions[v], upper.positions[v + 1], 0.001F});
  }
  for (std::size_t t = 0; t < upper.triangles.size(); t += 3) {  // reversed: normal −z
    mesh.triangles.insert(mesh.triangles.end(),
                          {base + upper.triangles[t], base + upper.triangles[t + 2], base + upper.triangles[t + 1]});
  }
  Scene scene = make_scene(std::move(mesh), default_settings(ContactSide::outer));
  const Vec3 centre(0.0033F, 0.0041F, 0.00045F);
  ASSERT_TRUE(scene.run({centre}).is_ok());
  EXPECT_EQ(scene.out.contact_count, 2U);
  const float expected_z = kStiffness * ((kReach - 0.00045F) - (kReach - 0.00055F));
  EXPECT_LT((scene.out.particle_forces_n[0] - Vec3(0, 0, expected_z)).norm(), 1e-4F);
  expect_action_equals_reaction(scene, {centre});
}

TEST(ParticleSurfaceContact, DegenerateTrianglesZeroRadiusAndCoincidentParticlesStayFinite) {
  Mesh mesh = make_plate();
  // A zero-area sliver (repeated vertex) and a collinear triangle lying on the plate's edges.
  mesh.positions.insert(mesh.positions.end(), {0.003F, 0.004F, 0.0F});  // vertex 25: middle of 11–12
  mesh.triangles.insert(mesh.triangles.end(), {12, 12, 13, 11, 25, 12});
  Scene scene = make_scene(std::move(mesh), default_settings(ContactSide::both));
  std::mt19937 random(5);
  std::uniform_real_distribution<float> along(0.0F, 0.008F);
  std::uniform_real_distribution<float> above(-8e-4F, 8e-4F);
  std::vector<Vec3> particles;
  for (int i = 0; i < 30; ++i) particles.emplace_back(along(random), along(random), above(random));
  for (std::uint32_t v = 0; v < 26; ++v) particles.push_back(scene.node(v));  // coincident with vertices
  particles.resize(64, Vec3(0.003F, 0.004F, 0.0F));
  for (float radius : {kRadius, 0.0F}) {
    ASSERT_TRUE(scene.run(particles, {}, radius).is_ok());
    EXPECT_GT(scene.out.contact_count, 30U);
    expect_action_equals_reaction(scene, particles);
    for (const Vec3& force : scene.out.particle_forces_n) EXPECT_LE(force.norm(), kStiffness * kReach * 1.0001F);
  }
  // Zero radius on a zero-thickness shell reaches nothing.
  ParticleContactSettings thin = default_settings(ContactSide::both);
  thin.surface_offset_m = 0.0F;
  Scene bare = make_scene(make_plate(), thin);
  ASSERT_TRUE(bare.run(particles, {}, 0.0F).is_ok());
  EXPECT_EQ(bare.out.contact_count, 0U);
  for (const Vec3& force : bare.out.particle_forces_n) EXPECT_EQ(force, Vec3::Zero());
}

TEST(ParticleSurfaceContact, DampingNeverPullsAndTheClampCounts) {
  ParticleContactSettings settings = default_settings(ContactSide::outer);
  settings.damping_n_s_per_m = 2.0F;
  Scene scene = make_scene(make_plate(), settings);
  const float depth = 1e-4F;
  const Vec3 centre(0.0031F, 0.0047F, kReach - depth);
  ASSERT_TRUE(scene.run({centre}, {Vec3(0, 0, -0.1F)}).is_ok());  // approaching: k d + b v
  EXPECT_NEAR(scene.out.particle_forces_n[0].z(), kStiffness * depth + 0.2F, 1e-4F);
  ASSERT_TRUE(scene.run({centre}, {Vec3(0, 0, 1.0F)}).is_ok());  // leaving fast: no pull
  EXPECT_EQ(scene.out.contact_count, 1U);
  EXPECT_EQ(scene.out.particle_forces_n[0], Vec3::Zero());
  EXPECT_TRUE(scene.out.node_forces.empty());
  // The surface moving with the particle: no relative velocity, spring only.
  std::vector<float> surface(scene.mesh.positions.size(), 0.0F);
  for (std::size_t v = 0; v < surface.size(); v += 3) surface[v + 2] = -0.1F;
  ASSERT_TRUE(scene.run({centre}, {Vec3(0, 0, -0.1F)}, kRadius, surface).is_ok());
  EXPECT_NEAR(scene.out.particle_forces_n[0].z(), kStiffness * depth, 1e-5F);

  settings.max_force_n = 0.05F;
  Scene clamped = make_scene(make_plate(), settings);
  ASSERT_TRUE(clamped.run({centre, centre + Vec3(0.002F, 0, 7e-5F), centre + Vec3(0, 0, 1e-3F)}).is_ok());
  EXPECT_EQ(clamped.out.contact_count, 2U);
  EXPECT_EQ(clamped.out.clamped_count, 1U);
  EXPECT_NEAR(clamped.out.particle_forces_n[0].z(), 0.05F, 1e-6F);
  EXPECT_NEAR(clamped.out.particle_forces_n[1].z(), kStiffness * (depth - 7e-5F), 1e-5F);
}

TEST(ParticleSurfaceContact, CapacitiesAndRefusals) {
  const Vec3 outward = face_direction(3.0F);
  std::vector<Vec3> pressed;
  for (int i = 0; i < 5; ++i) {
    pressed.push_back((kApothem - kReach + 1e-4F) * outward + Vec3(0, 0, 0.005F + 0.006F * static_cast<float>(i)));
  }
  ParticleContactSettings settings = default_settings(ContactSide::inner);
  settings.max_contacts = 2;
  settings.max_particles = 5;
  Scene scene = make_scene(make_tube(), settings);
  core::Status status = scene.run(pressed);
  EXPECT_EQ(status.code(), core::StatusCode::capacity_exceeded);
  EXPECT_EQ(scene.out.contact_count, 2U);
  EXPECT_EQ(scene.out.dropped_count, 3U);
  EXPECT_LE(scene.out.node_forces.size(), 6U);
  expect_action_equals_reaction(scene, pressed);
  // More particles than max_particles: nothing computed.
  pressed.push_back(pressed.front());
  EXPECT_EQ(scene.run(pressed).code(), core::StatusCode::capacity_exceeded);
  EXPECT_TRUE(scene.out.particle_forces_n.empty());
  EXPECT_TRUE(scene.out.node_forces.empty());
  pressed.pop_back();
  // Wrong-size velocity spans, a negative or NaN radius.
  EXPECT_EQ(scene.run(pressed, {Vec3::Zero()}).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(scene.run(pressed, {}, kRadius, {1.0F, 2.0F}).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(scene.run(pressed, {}, -1e-3F).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(scene.run(pressed, {}, std::numeric_limits<float>::quiet_NaN()).code(),
            core::StatusCode::invalid_argument);
  EXPECT_EQ(scene.out.contact_count, 0U);
  // A NaN particle: numeric_error, the others still computed.
  settings.max_contacts = 16;
  Scene roomy = make_scene(make_tube(), settings);
  pressed[2] = Vec3(std::numeric_limits<float>::quiet_NaN(), 0, 0);
  EXPECT_EQ(roomy.run(pressed).code(), core::StatusCode::numeric_error);
  EXPECT_EQ(roomy.out.contact_count, 4U);
  EXPECT_EQ(roomy.out.particle_forces_n[2], Vec3::Zero());
  // A grid query beyond max_candidates: the candidates returned are still used.
  settings.max_candidates = 1;  // the grid returns only box-overlapping triangles: ≥ 2 here
  Scene crowded = make_scene(make_tube(), settings);
  pressed[2] = pressed[1];
  EXPECT_EQ(crowded.run(pressed).code(), core::StatusCode::capacity_exceeded);
  for (const Vec3& force : crowded.out.particle_forces_n) EXPECT_TRUE(finite(force));
  expect_action_equals_reaction(crowded, pressed);
  // More mesh vertices than max_nodes.
  settings = default_settings(ContactSide::inner);
  settings.max_nodes = 100;
  Scene small = make_scene(make_tube(), settings);
  EXPECT_EQ(small.run(pressed).code(), core::StatusCode::capacity_exceeded);
  // Settings refused at create, with a message.
  auto arena = core::Arena::create(1 << 20);
  ASSERT_TRUE(arena.has_value());
  for (int field = 0; field < 6; ++field) {
    ParticleContactSettings bad = default_settings(ContactSide::inner);
    if (field == 0) bad.max_particles = 0;
    if (field == 1) bad.max_contacts = 0;
    if (field == 2) bad.stiffness_n_per_m = 0.0F;
    if (field == 3) bad.surface_offset_m = -1e-4F;
    if (field == 4) bad.max_force_n = std::numeric_limits<float>::infinity();
    if (field == 5) bad.damping_n_s_per_m = -1.0F;
    auto refused = ParticleSurfaceContact::create(bad, arena.value());
    ASSERT_FALSE(refused.has_value()) << field;
    EXPECT_NE(refused.error().message.find("particle contact"), std::string::npos);
  }
}

TEST(ParticleSurfaceContact, NoHeapInTenThousandComputeCalls) {
  if (!core::alloc::hooks_installed()) GTEST_SKIP() << "allocation hooks not linked";
  Scene scene = make_scene(make_tube(2e-4F), default_settings(ContactSide::inner));
  ASSERT_TRUE(scene.grid.rebuild(scene.mesh.positions, scene.mesh.triangles).is_ok());
  std::vector<Vec3> particles(21);
  const std::vector<Vec3> velocities(21, Vec3(0.01F, 0.0F, 0.0F));
  const TriangleMeshView view{scene.mesh.positions, scene.mesh.triangles};
  std::uint64_t contacts = 0;
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (int cycle = 0; cycle < 10000; ++cycle) {
    for (std::size_t i = 0; i < particles.size(); ++i) {
      const float angle = 0.3F * static_cast<float>(i) + 1e-3F * static_cast<float>(cycle);
      const float radius = kTubeRadius - 5e-4F;
      particles[i] = Vec3(radius * std::cos(angle), radius * std::sin(angle), 0.002F + 0.0017F * static_cast<float>(i));
    }
    if (!scene.contact.compute(particles, velocities, kRadius, view, {}, scene.grid, scene.out).is_ok()) break;
    contacts += scene.out.contact_count;
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
  EXPECT_GT(contacts, 10000U * 10U);
}

// A free 36 mm catheter of 21 particles on the axis of a rigid tube, every particle pushed
// sideways towards a face column: it moves to the wall and settles there with the wall force
// on every particle equal and opposite to the push (static balance of eq. 27 with contact).
TEST(ParticleSurfaceContact, CatheterPushedSidewaysSettlesAgainstTheWall) {
  auto arena_created = core::Arena::create(8U << 20);
  ASSERT_TRUE(arena_created.has_value());
  core::Arena arena = std::move(arena_created).value();
  CatheterParams params;
  params.length_m = 0.036F;
  params.outer_radius_m = 1e-3F;
  params.bending_stiffness_n_m2 = 3.9e-5F;
  params.axial_stiffness_n = 157.0F;
  params.linear_density_kg_per_m = 3.5e-3F;
  params.damping_n_s_per_m = 0.01F;
  params.particle_count = 21;
  CatheterSetup setup;
  setup.start_position_m = Vec3(0, 0, 0.002F);
  setup.direction = Vec3::UnitZ();
  // The contact force is computed once per period and held over the catheter's substeps: an
  // explicit coupling, stable for ω_contact · period = √(k/m) · period ≈ 0.29 and
  // b · period / m ≈ 0.17 here (with period 2e-4 s and b = 0.02 it already oscillates).
  constexpr float kPeriod = 1e-4F;
  setup.haptic_period_s = kPeriod;
  setup.max_substeps = 256;
  auto catheter = Catheter::create(params, setup, arena);
  ASSERT_TRUE(catheter.has_value()) << (catheter ? "" : catheter.error().message);

  ParticleContactSettings settings = default_settings(ContactSide::inner);
  settings.stiffness_n_per_m = 50.0F;
  settings.damping_n_s_per_m = 0.01F;
  Scene scene = make_scene(make_tube(), settings);
  ASSERT_TRUE(scene.grid.rebuild(scene.mesh.positions, scene.mesh.triangles).is_ok());
  const TriangleMeshView view{scene.mesh.positions, scene.mesh.triangles};
  const Vec3 outward = face_direction(4.0F);
  const Vec3 push = 1e-3F * outward;  // N per particle

  for (int cycle = 0; cycle < 6000; ++cycle) {
    ASSERT_TRUE(scene.contact
                    .compute(catheter->positions_m(), catheter->velocities_m_per_s(), catheter->radius_m(),
                             view, {}, scene.grid, scene.out)
                    .is_ok());
    catheter->clear_forces();
    for (std::uint32_t i = 0; i < 21; ++i) {
      ASSERT_TRUE(catheter->add_force(i, push + scene.out.particle_forces_n[i]).is_ok());
    }
    ASSERT_TRUE(catheter->step(kPeriod).is_ok());
  }
  ASSERT_TRUE(scene.contact
                  .compute(catheter->positions_m(), catheter->velocities_m_per_s(), catheter->radius_m(), view,
                           {}, scene.grid, scene.out)
                  .is_ok());
  EXPECT_EQ(scene.out.contact_count, 21U);
  Vec3 wall_total = Vec3::Zero();
  for (std::uint32_t i = 0; i < 21; ++i) {
    const Vec3 wall = scene.out.particle_forces_n[i];
    EXPECT_LT((wall + push).norm(), 1e-2F * push.norm()) << "particle " << i;
    wall_total += wall;
    // At the wall: the centre one reach minus the static depth push/k inside the face plane.
    const float radial = catheter->positions_m()[i].dot(outward);
    EXPECT_NEAR(radial, kApothem - (catheter->radius_m() + kOffset) + push.norm() / 50.0F, 1e-6F);
  }
  EXPECT_LT((wall_total + 21.0F * push).norm(), 1e-3F * 21.0F * push.norm());
  // Settled: under 1e-6 of the push's work over the 2.8 mm travel (5.9e-5 J).
  EXPECT_LT(catheter->kinetic_energy_j(), 6e-11);
}

TEST(ParticleSurfaceContact, NodeForcesGoIntoAModalModel) {
  // One triangle (3 nodes) pressed by a particle; a modal model of the 3 nodes with 9 unit
  // modes (identity shapes, ω² = 1e4): each node force moves only its own node.
  Mesh triangle{{0, 0, 0, 0.004F, 0, 0, 0, 0.004F, 0}, {0, 1, 2}};
  Scene scene = make_scene(triangle, default_settings(ContactSide::outer));
  ASSERT_TRUE(scene.run({Vec3(0.001F, 0.001F, kReach - 2e-4F)}).is_ok());
  ASSERT_EQ(scene.out.node_forces.size(), 3U);

  std::vector<float> shapes(81, 0.0F);
  for (std::size_t i = 0; i < 9; ++i) shapes[i * 9 + i] = 1.0F;
  const std::vector<float> omega_squared(9, 1e4F);
  const std::vector<float> damping(9, 0.0F);
  const std::vector<std::uint32_t> surface = {0, 1, 2};
  ModalModelData data;
  data.node_count = 3;
  data.mode_count = 9;
  data.rest_positions = triangle.positions;
  data.mode_shapes = shapes;
  data.omega_squared = omega_squared;
  data.modal_damping = damping;
  data.surface_nodes = surface;
  auto arena = core::Arena::create(1 << 20);
  ASSERT_TRUE(arena.has_value());
  auto modal = ModalModel::create(data, arena.value(), {1e-3F, 0, false});
  ASSERT_TRUE(modal.has_value()) << (modal ? "" : modal.error().message);
  std::size_t applied = 0;
  ASSERT_TRUE(apply_node_forces(scene.out.node_forces, modal.value(), applied).is_ok());
  EXPECT_EQ(applied, 3U);
  EXPECT_EQ(modal->applied_load_count(), 3U);
  ASSERT_TRUE(modal->step().is_ok());
  for (const NodeForce& entry : scene.out.node_forces) {
    EXPECT_LT(entry.force_n.z(), 0.0F);  // the plate is pushed down
    EXPECT_LT(modal->displacement(entry.node).z(), 0.0F);
    EXPECT_NEAR(modal->displacement(entry.node).x(), 0.0F, 1e-12F);
  }
  // An unknown node is refused; the others still go in.
  const NodeForce mixed[] = {{1, Vec3(0, 0, -1e-3F)}, {7, Vec3(0, 0, -1e-3F)}};
  modal->clear_forces();
  EXPECT_EQ(apply_node_forces(mixed, modal.value(), applied).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(applied, 1U);
}

}  // namespace
}  // namespace trainer::model
