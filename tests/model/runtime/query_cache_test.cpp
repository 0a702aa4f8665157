// Cached queries of TriangleBvh (issue 19; docs/collision.md "Cached queries"): a tool
// capsule's segment query and a catheter particle's sphere query answered from the candidates
// kept in a QueryCache while the hierarchy has not refitted and the query moved less than the
// cache's extra margin, filtered by the query's own box test and by a lower bound on the
// reference triangle's distance. Checked against brute force on deforming tubes with random
// walks whose steps straddle the extra margin: every triangle within reach is returned, in
// increasing id order; every triangle the plain stated-deviation query returns whose reference
// triangle lies within reach + √3 D is returned too (this fails when the reuse test is cut
// 20 µm too tight: checked); the answer is a subset of the plain query's. The contacts that
// SegmentSurfaceContact and ParticleSurfaceContact find through the caches over slowly moving
// sequences are bit-identical to feeding them every triangle; no heap.
#include "trainer/model/triangle_bvh.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "all_triangles_broad_phase.hpp"

#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/model/geometry.hpp"
#include "trainer/model/particle_contact.hpp"
#include "trainer/model/segment_box.hpp"
#include "trainer/model/segment_contact.hpp"

namespace trainer::model {
namespace query_cache_test {
namespace {

struct TubeMesh {
  std::vector<float> rest;
  std::vector<float> positions;
  std::vector<std::uint32_t> triangles;
  std::size_t triangle_count() const { return triangles.size() / 3; }
  Vec3 vertex(const std::vector<float>& p, std::uint32_t v) const { return {p[3 * v], p[3 * v + 1], p[3 * v + 2]}; }
  Vec3 corner(const std::vector<float>& p, std::uint32_t t, int k) const {
    return vertex(p, triangles[3 * static_cast<std::size_t>(t) + static_cast<std::size_t>(k)]);
  }
};

// Radius 4 mm, 2 mm between rings (the duct's scale), placed 5 cm off the origin so that the
// coordinates' rounding is the duct's, not a toy's.
TubeMesh tube(std::uint32_t rings, std::uint32_t segments) {
  TubeMesh mesh;
  for (std::uint32_t r = 0; r < rings; ++r) {
    for (std::uint32_t s = 0; s < segments; ++s) {
      const float angle = 2.0F * std::numbers::pi_v<float> * static_cast<float>(s) / static_cast<float>(segments);
      mesh.rest.insert(mesh.rest.end(),
                       {0.05F + 0.004F * std::cos(angle), 0.004F * std::sin(angle), 0.002F * static_cast<float>(r)});
    }
  }
  for (std::uint32_t r = 0; r + 1 < rings; ++r) {
    for (std::uint32_t s = 0; s < segments; ++s) {
      const std::uint32_t i = r * segments + s;
      const std::uint32_t j = r * segments + (s + 1) % segments;
      mesh.triangles.insert(mesh.triangles.end(), {i, j, i + segments, j, j + segments, i + segments});
    }
  }
  mesh.positions = mesh.rest;
  return mesh;
}

#if defined(TRAINER_SANITIZER_BUILD)
constexpr int kCacheCycles = 40;
#else
constexpr int kCacheCycles = 400;
#endif

core::Arena cache_arena() {
  auto arena = core::Arena::create(16U << 20);
  EXPECT_TRUE(arena.has_value());
  return std::move(arena).value();
}

bool same_bits(const Vec3& x, const Vec3& y) { return std::memcmp(x.data(), y.data(), sizeof(float) * 3) == 0; }

// A point that moves by `step` (± 3 %) along one random axis and by less than a fifth of it
// along the others, so that the largest coordinate change straddles `step`; now and then a jump.
Vec3 walk(const Vec3& from, float step, std::mt19937& rng, const Vec3& low, const Vec3& high) {
  std::uniform_real_distribution<float> u(-1.0F, 1.0F);
  Vec3 to = from;
  const int main_axis = static_cast<int>(3.0F * (0.5F + 0.5F * u(rng))) % 3;
  for (int axis = 0; axis < 3; ++axis) {
    to[axis] += axis == main_axis ? step * (1.0F + 0.03F * u(rng)) * (u(rng) < 0.0F ? -1.0F : 1.0F) : 0.2F * step * u(rng);
  }
  if (u(rng) > 0.97F) to = from + Vec3(0.004F * u(rng), 0.004F * u(rng), 0.004F * u(rng));
  return to.cwiseMax(low).cwiseMin(high);
}

TEST(SegmentTriangleDistanceBelow, NeverAboveTheNarrowPhasesFloatDistanceAndClose) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0F, 1.0F);
  std::size_t checked = 0;
  for (int trial = 0; trial < 40000; ++trial) {
    const Vec3 offset(0.05F, -0.02F, 0.03F);
    const float size = trial % 3 == 0 ? 0.01F : 0.003F;
    const auto point = [&] { return Vec3(offset + size * Vec3(u(rng), u(rng), u(rng))); };
    Vec3 a = point();
    Vec3 b = point();
    Vec3 c = point();
    Vec3 p0 = point();
    Vec3 p1 = point();
    switch (trial % 10) {
      case 0: c = a + 0.5F * (b - a); break;          // collinear
      case 1: b = a; break;                            // repeated vertex
      case 2: p1 = p0; break;                          // a point
      case 3: p0 = (a + b + c) / 3.0F + 1e-4F * (p1 - p0); break;  // crossing near the centroid
      case 4: p1 = p0 + 1e-3F * (b - a); break;        // short, parallel to an edge
      default: break;
    }
    const double below = segment_triangle_distance_below(p0, p1, a, b, c);
    const float exact = closest_points_segment_triangle(p0, p1, a, b, c).distance_m;
    // What the cached queries rely on: the bound never exceeds the narrow phase's float distance
    // by more than the rounding they allow (1 µm + 1e-4 of the coordinates' scale).
    ASSERT_LE(below, static_cast<double>(exact) + 1e-6 + 1e-4 * 0.06) << trial;
    // And it is a useful bound, not 0.
    ASSERT_GE(below, static_cast<double>(exact) - 2e-6) << trial;
    ++checked;
  }
  EXPECT_EQ(checked, 40000U);
}

TriangleBvh make_bvh(const TubeMesh& mesh, core::Arena& arena) {
  auto created = TriangleBvh::create(mesh.rest, mesh.triangles, arena);
  EXPECT_TRUE(created.has_value());
  return std::move(created).value();
}

struct CacheFixture {
  core::Arena arena = cache_arena();
  TubeMesh mesh = tube(21, 16);
  TriangleBvh bvh = make_bvh(mesh, arena);
  std::vector<float> reference;
  float slack = 0.0015F;

  CacheFixture() {
    EXPECT_TRUE(bvh.refit(mesh.rest, slack).is_ok());
    reference = mesh.rest;
  }
  // Every vertex within `amount` (per coordinate) of the reference, mostly; now and then beyond
  // the slack (a refit). Returns the true deviation.
  float deform(std::mt19937& rng, int cycle) {
    std::uniform_real_distribution<float> u(-1.0F, 1.0F);
    std::mt19937 block(static_cast<unsigned>(1000 + cycle / 40));  // the same amount for 40 cycles
    const float amount = cycle % 50 == 49 ? 1.3F * slack : 0.8F * slack * (0.5F + 0.5F * u(block));
    for (std::size_t i = 0; i < mesh.rest.size(); ++i) mesh.positions[i] = reference[i] + amount * u(rng);
    const std::uint64_t refits = bvh.refit_count();
    EXPECT_TRUE(bvh.refit(mesh.positions, slack).is_ok());
    if (bvh.refit_count() != refits) reference = mesh.positions;
    float deviation = 0.0F;
    for (std::size_t i = 0; i < mesh.rest.size(); ++i) {
      deviation = std::max(deviation, std::abs(mesh.positions[i] - reference[i]));
    }
    return deviation;
  }
  double reference_distance(const Vec3& p0, const Vec3& p1, std::uint32_t t) const {
    return segment_triangle_distance_below(p0, p1, mesh.corner(reference, t, 0), mesh.corner(reference, t, 1),
                                           mesh.corner(reference, t, 2));
  }
};

TEST(CachedQueries, EveryTriangleWithinReachAndEveryReferenceNearOneOfTheStatedQuery) {
  CacheFixture f;
  std::mt19937 rng(71);
  std::uniform_real_distribution<float> u(0.0F, 1.0F);
  auto segment_cache = QueryCache::create(f.arena);
  auto sphere_cache = QueryCache::create(f.arena, 128, 2.5e-4F);
  ASSERT_TRUE(segment_cache.has_value() && sphere_cache.has_value());
  QueryCache& segment = *segment_cache;
  QueryCache& sphere = *sphere_cache;
  // Within 5.5 mm of the tube's axis (the wall at 4 mm): mostly near the wall.
  const Vec3 low(0.0445F, -0.0055F, 0.0F);
  const Vec3 high(0.0555F, 0.0055F, 0.04F);
  Vec3 p0(0.052F, 0.0F, 0.01F);
  Vec3 p1(0.0535F, 0.002F, 0.016F);
  Vec3 centre(0.0535F, 0.0F, 0.02F);
  std::vector<std::uint32_t> cached(640);
  std::vector<std::uint32_t> plain(640);
  std::size_t within = 0;
  std::size_t near_reference = 0;
  std::size_t cached_total = 0;
  std::size_t plain_total = 0;
  for (int cycle = 0; cycle < kCacheCycles; ++cycle) {
    const float deviation = f.deform(rng, cycle);
    // The statement: the true deviation, overstated, or none (the slack), the same kind for 40
    // cycles (and the deviation about the same: the reuse test then sees the motion alone).
    const int kind_of_statement = (cycle / 40) % 5;
    const float stated = kind_of_statement == 3
                             ? -1.0F
                             : (kind_of_statement == 1 ? std::min(deviation + 1e-4F, f.slack) : deviation);
    const double bound = stated >= 0.0F && stated < f.slack ? stated : f.slack;
    for (int step = 0; step < 4; ++step) {
      // Steps straddling the segment cache's extra margin (1 mm) and, for the sphere, its 0.25 mm.
      const float segment_step = step % 2 == 0 ? segment.extra_margin_m : 0.05F * segment.extra_margin_m;
      p0 = walk(p0, segment_step, rng, low, high);
      p1 = step == 3 && cycle % 9 == 0 ? p0 : walk(p1, segment_step, rng, low, high);
      if ((p1 - p0).norm() > 0.008F) p1 = p0 + 0.008F * (p1 - p0).normalized();  // a jaw, not a shaft
      centre = walk(centre, step % 2 == 0 ? sphere.extra_margin_m : 2e-5F, rng, low, high);
      // Reach and radius change every 40 cycles only: the reuse test then sees the motion alone.
      std::mt19937 sizes(static_cast<unsigned>(cycle / 40));
      const float reach = 0.001F + 0.0025F * u(sizes);
      const float radius = 0.0005F + 0.002F * u(sizes);
      for (int kind = 0; kind < 2; ++kind) {
        std::size_t count = 0;
        std::size_t plain_count = 0;
        const Vec3 q0 = kind == 0 ? p0 : centre;
        const Vec3 q1 = kind == 0 ? p1 : centre;
        const float margin = kind == 0 ? reach : radius;
        if (kind == 0) {
          ASSERT_TRUE(f.bvh.query_segment_cached_within(p0, p1, reach, stated, segment, cached, count).is_ok());
          ASSERT_TRUE(f.bvh.query_segment_within(p0, p1, reach, stated, plain, plain_count).is_ok());
        } else {
          ASSERT_TRUE(f.bvh.query_sphere_cached_within(centre, radius, stated, sphere, cached, count).is_ok());
          ASSERT_TRUE(f.bvh.query_within(Aabb::around_point(centre, radius), stated, plain, plain_count).is_ok());
        }
        const auto begin = cached.begin();
        const auto end = cached.begin() + static_cast<std::ptrdiff_t>(count);
        ASSERT_TRUE(std::adjacent_find(begin, end, std::greater_equal<>()) == end) << "not increasing";
        ASSERT_TRUE(std::includes(plain.begin(), plain.begin() + static_cast<std::ptrdiff_t>(plain_count), begin, end));
        // Every triangle the narrow phase would take (float distance below reach).
        for (std::uint32_t t = 0; t < f.mesh.triangle_count(); ++t) {
          const Vec3 a = f.mesh.corner(f.mesh.positions, t, 0);
          const Vec3 b = f.mesh.corner(f.mesh.positions, t, 1);
          const Vec3 c = f.mesh.corner(f.mesh.positions, t, 2);
          const float distance = kind == 0 ? closest_points_segment_triangle(q0, q1, a, b, c).distance_m
                                           : (q0 - closest_point_on_triangle(q0, a, b, c).point).norm();
          if (!(distance < margin)) continue;
          ++within;
          ASSERT_TRUE(std::binary_search(begin, end, t)) << "missed " << t << " cycle " << cycle << " kind " << kind;
        }
        // Every triangle of the stated query whose reference triangle is within margin + √3 D:
        // the cached box stage lost nothing.
        for (std::size_t k = 0; k < plain_count; ++k) {
          if (f.reference_distance(q0, q1, plain[k]) > static_cast<double>(margin) + std::sqrt(3.0) * bound) continue;
          ++near_reference;
          ASSERT_TRUE(std::binary_search(begin, end, plain[k]))
              << "lost " << plain[k] << " cycle " << cycle << " step " << step << " kind " << kind;
        }
        cached_total += count;
        plain_total += plain_count;
      }
    }
  }
  EXPECT_GT(within, static_cast<std::size_t>(4 * kCacheCycles));
  EXPECT_GT(near_reference, within);
  EXPECT_LT(cached_total, plain_total) << "the reference-triangle bound should drop some";
  // Both caches were reused, and filled again when the query moved or the hierarchy refitted.
  EXPECT_GT(segment.reuses, static_cast<std::uint64_t>(kCacheCycles));
  EXPECT_GT(segment.collections, static_cast<std::uint64_t>(kCacheCycles / 2));
  EXPECT_GT(sphere.reuses, static_cast<std::uint64_t>(kCacheCycles));
  EXPECT_GT(sphere.collections, static_cast<std::uint64_t>(kCacheCycles / 2));
}

TEST(CachedQueries, OverflowAnswersThePlainWayAndRefusalsNameTheValue) {
  CacheFixture f;
  auto tiny = QueryCache::create(f.arena, 2);
  ASSERT_TRUE(tiny.has_value());
  std::vector<std::uint32_t> cached(640);
  std::vector<std::uint32_t> plain(640);
  std::size_t count = 0;
  std::size_t plain_count = 0;
  const Vec3 p0(0.046F, 0.0F, 0.0F);
  const Vec3 p1(0.054F, 0.0F, 0.04F);
  ASSERT_TRUE(f.bvh.query_segment_cached_within(p0, p1, 0.002F, 0.0F, *tiny, cached, count).is_ok());
  ASSERT_TRUE(f.bvh.query_segment_within(p0, p1, 0.002F, 0.0F, plain, plain_count).is_ok());
  ASSERT_GT(plain_count, 2U);
  ASSERT_EQ(count, plain_count);
  EXPECT_TRUE(std::equal(plain.begin(), plain.begin() + static_cast<std::ptrdiff_t>(count), cached.begin()));
  EXPECT_FALSE(tiny->valid);
  // Output shorter than the answer: the lowest ids, capacity_exceeded.
  auto cache = QueryCache::create(f.arena);
  ASSERT_TRUE(cache.has_value());
  EXPECT_EQ(f.bvh.query_segment_cached_within(p0, p1, 0.002F, 0.0F, *cache, std::span(cached).first(3), count).code(),
            core::StatusCode::capacity_exceeded);
  EXPECT_EQ(count, 3U);
  EXPECT_EQ(f.bvh.query_segment_cached_within(p0, Vec3(NAN, 0, 0), 0.002F, 0.0F, *cache, cached, count).code(),
            core::StatusCode::invalid_argument);
  EXPECT_EQ(f.bvh.query_sphere_cached_within(p0, -1.0F, 0.0F, *cache, cached, count).code(),
            core::StatusCode::invalid_argument);
  const auto refused = QueryCache::create(f.arena, 0);
  ASSERT_FALSE(refused.has_value());
  EXPECT_NE(refused.error().message.find("capacity 0"), std::string::npos) << refused.error().message;
  EXPECT_FALSE(QueryCache::create(f.arena, 8, 0.0F).has_value());
}

// SegmentSurfaceContact and ParticleSurfaceContact (with cached_particles) through the
// hierarchy's cached queries, over sequences where tools and particles move a little per cycle
// (the caches are reused) and the wall deforms within the slack (sometimes beyond: a refit),
// against the same narrow phases fed every triangle: bit-identical.
using EveryTriangle = test_support::AllTriangles;

TEST(CachedQueries, ContactsAreBitIdenticalToAllTrianglesOverMovingSequences) {
  CacheFixture f;
  std::mt19937 rng(23);
  std::uniform_real_distribution<float> u(-1.0F, 1.0F);
  EveryTriangle all(f.mesh.triangle_count());
  SegmentContactSettings segment_settings;
  segment_settings.surface_half_thickness_m = 0.0005F;
  segment_settings.stiffness_n_per_m = 500.0F;
  segment_settings.damping_n_s_per_m = 0.5F;
  segment_settings.max_force_n = 5.0F;
  segment_settings.max_candidates = 640;
  auto through_bvh = SegmentSurfaceContact::create(segment_settings, f.arena);
  auto through_all = SegmentSurfaceContact::create(segment_settings, f.arena);
  ASSERT_TRUE(through_bvh.has_value() && through_all.has_value());
  ParticleContactSettings particle_settings;
  particle_settings.max_particles = 12;
  particle_settings.max_contacts = 64;
  particle_settings.max_nodes = 336;
  particle_settings.max_candidates = 640;
  particle_settings.stiffness_n_per_m = 300.0F;
  particle_settings.damping_n_s_per_m = 0.1F;
  particle_settings.surface_offset_m = 0.0002F;
  particle_settings.max_force_n = 2.0F;
  particle_settings.side = ContactSide::both;
  particle_settings.cached_particles = 12;
  auto particles_bvh = ParticleSurfaceContact::create(particle_settings, f.arena);
  particle_settings.cached_particles = 0;
  auto particles_all = ParticleSurfaceContact::create(particle_settings, f.arena);
  ASSERT_TRUE(particles_bvh.has_value() && particles_all.has_value());

  const Vec3 low(0.04F, -0.01F, -0.002F);
  const Vec3 high(0.06F, 0.01F, 0.042F);
  std::vector<ToolCapsule> capsules(3);
  const ToolSegment segments[3] = {ToolSegment::shaft, ToolSegment::jaw0, ToolSegment::jaw1};
  for (int s = 0; s < 3; ++s) {
    capsules[static_cast<std::size_t>(s)].segment = segments[s];
    capsules[static_cast<std::size_t>(s)].start_m = Vec3(0.05F + 0.003F * u(rng), 0.003F * u(rng), 0.02F);
    capsules[static_cast<std::size_t>(s)].end_m = capsules[static_cast<std::size_t>(s)].start_m + Vec3(0.0F, 0.002F, 0.005F);
    capsules[static_cast<std::size_t>(s)].radius_m = s == 0 ? 0.0025F : 0.001F;
  }
  std::vector<Vec3> particles(12);
  for (std::size_t p = 0; p < particles.size(); ++p) {
    const float angle = 0.5F * static_cast<float>(p);
    particles[p] = Vec3(0.05F + 0.0035F * std::cos(angle), 0.0035F * std::sin(angle), 0.003F * static_cast<float>(p));
  }
  std::size_t segment_contacts = 0;
  std::size_t particle_contacts = 0;
  for (int cycle = 0; cycle < kCacheCycles; ++cycle) {
    (void)f.deform(rng, cycle);
    const TriangleMeshView view{f.mesh.positions, f.mesh.triangles};
    for (ToolCapsule& capsule : capsules) {
      const float step = cycle % 10 == 0 ? 0.0012F : 0.00005F;
      capsule.start_m = walk(capsule.start_m, step, rng, low, high);
      capsule.end_m = walk(capsule.end_m, step, rng, low, high);
      capsule.start_velocity_m_per_s = Vec3(0.05F * u(rng), 0.0F, 0.01F);
      capsule.end_velocity_m_per_s = capsule.start_velocity_m_per_s;
    }
    for (Vec3& particle : particles) particle = walk(particle, cycle % 10 == 5 ? 0.0003F : 0.00002F, rng, low, high);
    const core::Status a = through_bvh->update(capsules, view, {}, f.bvh);
    const core::Status b = through_all->update(capsules, view, {}, all);
    ASSERT_EQ(a.code(), b.code());
    ASSERT_EQ(through_bvh->contact_count(), through_all->contact_count()) << cycle;
    for (std::size_t k = 0; k < through_all->contact_count(); ++k) {
      const SegmentContact& x = through_bvh->contact(k);
      const SegmentContact& y = through_all->contact(k);
      ASSERT_EQ(x.triangle, y.triangle);
      ASSERT_EQ(x.feature, y.feature);
      ASSERT_EQ(x.side, y.side);
      ASSERT_TRUE(same_bits(x.force_on_tool_n, y.force_on_tool_n)) << cycle;
      ASSERT_TRUE(same_bits(x.normal, y.normal));
      ASSERT_TRUE(same_bits(x.mesh_point_m, y.mesh_point_m));
    }
    segment_contacts += through_all->contact_count();
    ParticleContactOutput out_bvh;
    ParticleContactOutput out_all;
    const core::Status pa = particles_bvh->compute(particles, {}, 0.0008F, view, {}, f.bvh, out_bvh);
    const core::Status pb = particles_all->compute(particles, {}, 0.0008F, view, {}, all, out_all);
    ASSERT_EQ(pa.code(), pb.code());
    ASSERT_EQ(out_bvh.contact_count, out_all.contact_count) << cycle;
    for (std::size_t k = 0; k < out_all.contact_count; ++k) {
      ASSERT_EQ(out_bvh.contacts[k].particle, out_all.contacts[k].particle);
      ASSERT_EQ(out_bvh.contacts[k].vertices, out_all.contacts[k].vertices);
      ASSERT_TRUE(same_bits(out_bvh.contacts[k].normal, out_all.contacts[k].normal));
    }
    for (std::size_t p = 0; p < particles.size(); ++p) {
      ASSERT_TRUE(same_bits(out_bvh.particle_forces_n[p], out_all.particle_forces_n[p]));
    }
    particle_contacts += out_all.contact_count;
  }
  EXPECT_GT(segment_contacts, static_cast<std::size_t>(kCacheCycles / 2));
  EXPECT_GT(particle_contacts, static_cast<std::size_t>(kCacheCycles / 2));
}

TEST(CachedQueries, NoHeap) {
  ASSERT_TRUE(core::alloc::hooks_installed());
  CacheFixture f;
  auto segment = QueryCache::create(f.arena);
  auto sphere = QueryCache::create(f.arena, 128, 2.5e-4F);
  ASSERT_TRUE(segment.has_value() && sphere.has_value());
  f.arena.seal();
  std::vector<std::uint32_t> out(640);
  std::size_t found = 0;
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (int cycle = 0; cycle < 2000; ++cycle) {
    std::size_t count = 0;
    const Vec3 centre(0.054F, 0.0F, 0.00002F * static_cast<float>(cycle));
    if (!f.bvh.query_segment_cached_within(centre, centre + Vec3(0.0F, 0.003F, 0.001F), 0.001F, 0.0001F, *segment, out,
                                           count)
             .is_ok()) {
      break;
    }
    found += count;
    if (!f.bvh.query_sphere_cached_within(centre, 0.001F, 0.0001F, *sphere, out, count).is_ok()) break;
    found += count;
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
  EXPECT_GT(found, 4000U);
  EXPECT_GT(segment->reuses, 1000U);
}

}  // namespace
}  // namespace query_cache_test
}  // namespace trainer::model
