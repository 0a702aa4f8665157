// The box prefilter of ParticleSurfaceContact (particle_contact.cpp): a candidate triangle whose
// own box is farther than reach (plus a rounding guard) is dropped before its closest point is
// computed. It must never drop a triangle the exact test would keep: particles are placed at
// reach ± a few ulp from random triangles of a deformed tube, at random points of their faces,
// edges and vertices (a vertex region is where the box distance equals the true distance, the
// tightest case), and the contact found must be the brute-force answer over every triangle.
#include "trainer/model/particle_contact.hpp"

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "trainer/core/arena.hpp"
#include "trainer/model/geometry.hpp"
#include "trainer/model/triangle_bvh.hpp"

namespace trainer::model {
namespace {

struct PrefilterMesh {
  std::vector<float> positions;
  std::vector<std::uint32_t> triangles;
  Vec3 vertex(std::uint32_t i) const { return {positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]}; }
};

// A 16-sided tube along z (radius 4 mm, 40 mm, 21 rings) with a radial wave and a twist, away
// from the origin like the duct in its model frame.
PrefilterMesh make_prefilter_tube() {
  PrefilterMesh mesh;
  constexpr std::uint32_t kRingCount = 21;
  constexpr std::uint32_t kSegmentCount = 16;
  for (std::uint32_t r = 0; r < kRingCount; ++r) {
    const float z = 0.002F * static_cast<float>(r);
    const float radius = 0.004F + 4e-4F * std::sin(300.0F * z);
    for (std::uint32_t s = 0; s < kSegmentCount; ++s) {
      const float angle = 2.0F * std::numbers::pi_v<float> * static_cast<float>(s) / kSegmentCount + 5.0F * z;
      mesh.positions.insert(mesh.positions.end(),
                            {0.03F + radius * std::cos(angle), -0.01F + radius * std::sin(angle), z});
    }
  }
  for (std::uint32_t r = 0; r + 1 < kRingCount; ++r) {
    for (std::uint32_t s = 0; s < kSegmentCount; ++s) {
      const std::uint32_t i = r * kSegmentCount + s;
      const std::uint32_t j = r * kSegmentCount + (s + 1) % kSegmentCount;
      mesh.triangles.insert(mesh.triangles.end(), {i, j, i + kSegmentCount, j, j + kSegmentCount, i + kSegmentCount});
    }
  }
  return mesh;
}

// The exact test over every triangle, as particle_contacts() does it for its candidates.
bool brute_force_within_reach(const PrefilterMesh& mesh, const Vec3& centre, float reach) {
  for (std::size_t t = 0; t < mesh.triangles.size() / 3; ++t) {
    const Vec3 a = mesh.vertex(mesh.triangles[3 * t]);
    const Vec3 b = mesh.vertex(mesh.triangles[3 * t + 1]);
    const Vec3 c = mesh.vertex(mesh.triangles[3 * t + 2]);
    if (triangle_is_degenerate(a, b, c)) continue;
    const TrianglePoint closest = closest_point_on_nondegenerate_triangle(centre, a, b, c);
    if ((centre - closest.point).norm() < reach) return true;
  }
  return false;
}

TEST(ParticleContactPrefilter, NeverDropsATriangleTheExactTestKeeps) {
  const PrefilterMesh mesh = make_prefilter_tube();
  auto arena = core::Arena::create(8U << 20);
  ASSERT_TRUE(arena.has_value());
  auto grid = BucketGrid::create({4096, 4096, 0.002F, 4096, 1U << 16}, *arena);
  ASSERT_TRUE(grid.has_value());
  ParticleContactSettings settings;
  settings.max_particles = 1;
  settings.max_contacts = 64;
  settings.max_nodes = 4096;
  settings.max_candidates = 1024;
  settings.stiffness_n_per_m = 1000.0F;
  settings.surface_offset_m = 5e-4F;
  settings.max_force_n = 100.0F;
  settings.side = ContactSide::both;  // every patch within reach gives a record
  auto contact = ParticleSurfaceContact::create(settings, *arena);
  ASSERT_TRUE(contact.has_value());
  ASSERT_TRUE(grid->rebuild(mesh.positions, mesh.triangles).is_ok());
  const float radius = 0.00225F;  // the cbd catheter's 1.25 mm + 1 mm detection margin
  const float reach = radius + settings.surface_offset_m;

  std::mt19937 random(19);
  std::uniform_real_distribution<float> across(-0.006F, 0.006F);
  std::uniform_real_distribution<float> along(-0.002F, 0.042F);
  std::uniform_int_distribution<int> ulps(-6, 6);
  int touching = 0;
  int apart = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    // A random point in and around the tube and its closest point on the mesh (a face, edge or
    // vertex region, whichever it falls in; vertex regions are where the box distance equals
    // the true distance, the tightest case for the guard).
    const Vec3 start(0.03F + across(random), -0.01F + across(random), along(random));
    float nearest = std::numeric_limits<float>::max();
    Vec3 closest_point = Vec3::Zero();
    for (std::size_t t = 0; t < mesh.triangles.size() / 3; ++t) {
      const TrianglePoint closest = closest_point_on_nondegenerate_triangle(
          start, mesh.vertex(mesh.triangles[3 * t]), mesh.vertex(mesh.triangles[3 * t + 1]),
          mesh.vertex(mesh.triangles[3 * t + 2]));
      const float distance = (start - closest.point).norm();
      if (distance < nearest) {
        nearest = distance;
        closest_point = closest.point;
      }
    }
    if (!(nearest > 1e-4F)) continue;
    // Along the same ray to reach from that point, then a few ulp of reach closer or farther.
    float distance = reach;
    const int steps = ulps(random);
    for (int k = 0; k < std::abs(steps); ++k) distance = std::nextafter(distance, steps > 0 ? 1.0F : 0.0F);
    const Vec3 centre = closest_point + distance * (start - closest_point).normalized();
    const std::vector<Vec3> particles{centre};
    ParticleContactOutput out;
    ASSERT_TRUE(contact->compute(particles, {}, radius, {mesh.positions, mesh.triangles}, {}, *grid, out).is_ok());
    const bool expected = brute_force_within_reach(mesh, centre, reach);
    EXPECT_EQ(out.contact_count > 0, expected) << "trial " << trial << " steps " << steps;
    (expected ? touching : apart) += 1;
  }
  // Both sides of the boundary were exercised.
  EXPECT_GT(touching, 1000);
  EXPECT_GT(apart, 1000);
}

// With the hierarchy's root box as grid_bounds, particles outside it are not queried; the
// output (records, particle forces, node forces) is the same as without, for particles in,
// near and far from the tube, and counted queries show the skip happened.
TEST(ParticleContactPrefilter, GridBoundsSkipOnlyParticlesTheBroadPhaseCannotReach) {
  const PrefilterMesh mesh = make_prefilter_tube();
  auto arena = core::Arena::create(8U << 20);
  ASSERT_TRUE(arena.has_value());
  auto bvh = TriangleBvh::create(mesh.positions, mesh.triangles, *arena);
  ASSERT_TRUE(bvh.has_value());
  ASSERT_TRUE(bvh->refit(mesh.positions, 7.5e-4F).is_ok());
  struct CountingBroadPhase final : TriangleBroadPhase {
    TriangleBvh* inner = nullptr;
    int queries = 0;
    core::Status query(const Aabb& box, std::span<std::uint32_t> out_ids, std::size_t& out_count) noexcept override {
      ++queries;
      return inner->query(box, out_ids, out_count);
    }
  };
  CountingBroadPhase counting;
  counting.inner = &*bvh;
  ParticleContactSettings settings;
  settings.max_particles = 64;
  settings.max_contacts = 256;
  settings.max_nodes = 4096;
  settings.stiffness_n_per_m = 1000.0F;
  settings.surface_offset_m = 5e-4F;
  settings.max_force_n = 100.0F;
  settings.side = ContactSide::inner;
  auto with = ParticleSurfaceContact::create(settings, *arena);
  auto without = ParticleSurfaceContact::create(settings, *arena);
  ASSERT_TRUE(with.has_value() && without.has_value());
  std::mt19937 random(7);
  std::uniform_real_distribution<float> across(-0.012F, 0.012F);
  std::uniform_real_distribution<float> along(-0.02F, 0.06F);
  std::vector<Vec3> particles;
  for (int i = 0; i < 64; ++i) particles.emplace_back(0.03F + across(random), -0.01F + across(random), along(random));
  std::uint32_t contacts = 0;
  for (int round = 0; round < 20; ++round) {
    for (Vec3& p : particles) p.z() += 0.001F * static_cast<float>(round % 3) - 0.001F;
    ParticleContactOutput out_with;
    ParticleContactOutput out_without;
    counting.queries = 0;
    ASSERT_TRUE(with->compute(particles, {}, 0.00225F, {mesh.positions, mesh.triangles}, {}, counting, out_with,
                              &bvh->bounds()).is_ok());
    const int skipped_queries = counting.queries;
    counting.queries = 0;
    ASSERT_TRUE(without->compute(particles, {}, 0.00225F, {mesh.positions, mesh.triangles}, {}, counting,
                                 out_without).is_ok());
    EXPECT_EQ(counting.queries, 64);
    EXPECT_LT(skipped_queries, 64);
    ASSERT_EQ(out_with.contact_count, out_without.contact_count);
    contacts += out_with.contact_count;
    for (std::size_t k = 0; k < out_with.contacts.size(); ++k) {
      EXPECT_EQ(out_with.contacts[k].particle, out_without.contacts[k].particle);
      EXPECT_EQ(out_with.contacts[k].vertices, out_without.contacts[k].vertices);
      EXPECT_EQ(out_with.contacts[k].point_m, out_without.contacts[k].point_m);
      EXPECT_EQ(out_with.contacts[k].normal, out_without.contacts[k].normal);
    }
    for (std::size_t i = 0; i < particles.size(); ++i) {
      EXPECT_EQ(out_with.particle_forces_n[i], out_without.particle_forces_n[i]);
    }
    ASSERT_EQ(out_with.node_forces.size(), out_without.node_forces.size());
    for (std::size_t k = 0; k < out_with.node_forces.size(); ++k) {
      EXPECT_EQ(out_with.node_forces[k].node, out_without.node_forces[k].node);
      EXPECT_EQ(out_with.node_forces[k].force_n, out_without.node_forces[k].force_n);
    }
  }
  EXPECT_GT(contacts, 20U);  // the comparison covered particles touching the wall
}

}  // namespace
}  // namespace trainer::model
