// Triangle BVH (triangle_bvh.hpp) against brute force over all triangles (issue 19): on random
// deformed tube meshes the query returns exactly the triangles whose box overlaps, in id
// order; the contacts that SegmentSurfaceContact and ParticleSurfaceContact find through it —
// random capsules and particles, with degenerate triangles, huge boxes and deep penetrations
// through the wall — are bit-identical to the same narrow phases fed every triangle in id
// order. Also: the slack skips refits and stays right, refusals, truncation, no heap.
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
#include "trainer/model/segment_contact.hpp"

namespace trainer::model {
namespace {

struct BvhMesh {
  std::vector<float> rest;
  std::vector<float> positions;
  std::vector<std::uint32_t> triangles;
  std::size_t triangle_count() const { return triangles.size() / 3; }
  Vec3 vertex(std::uint32_t v) const { return {positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]}; }
  Aabb box(std::size_t t) const {
    const Vec3 a = vertex(triangles[3 * t]);
    const Vec3 b = vertex(triangles[3 * t + 1]);
    const Vec3 c = vertex(triangles[3 * t + 2]);
    return {a.cwiseMin(b).cwiseMin(c), a.cwiseMax(b).cwiseMax(c)};
  }
};

// The duct's scale: radius 4 mm, 2 mm between rings, 2 (rings − 1) segments triangles.
BvhMesh bvh_tube(std::uint32_t rings, std::uint32_t segments) {
  BvhMesh mesh;
  for (std::uint32_t r = 0; r < rings; ++r) {
    for (std::uint32_t s = 0; s < segments; ++s) {
      const float angle = 2.0F * std::numbers::pi_v<float> * static_cast<float>(s) / static_cast<float>(segments);
      mesh.rest.insert(mesh.rest.end(), {0.004F * std::cos(angle), 0.004F * std::sin(angle), 0.002F * static_cast<float>(r)});
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

// Smooth waves plus jitter (~1 mm); every 37th vertex collapsed onto its ring neighbour, which
// makes the triangles around it degenerate (zero area) — the narrow phases must skip them alike.
void bvh_deform(BvhMesh& mesh, std::mt19937& rng, bool collapse) {
  std::uniform_real_distribution<float> u(-1.0F, 1.0F);
  const float phase = 3.0F * u(rng);
  const float amplitude = 0.001F * u(rng);
  const std::size_t n = mesh.rest.size() / 3;
  for (std::size_t v = 0; v < n; ++v) {
    const float z = mesh.rest[3 * v + 2];
    mesh.positions[3 * v] = mesh.rest[3 * v] + amplitude * std::sin(300.0F * z + phase) + 2e-4F * u(rng);
    mesh.positions[3 * v + 1] = mesh.rest[3 * v + 1] + amplitude * std::cos(200.0F * z) + 2e-4F * u(rng);
    mesh.positions[3 * v + 2] = mesh.rest[3 * v + 2] + 2e-4F * u(rng);
  }
  if (!collapse) return;
  for (std::size_t v = 1; v < n; v += 37) {
    for (std::size_t axis = 0; axis < 3; ++axis) mesh.positions[3 * v + axis] = mesh.positions[3 * (v - 1) + axis];
  }
}

// The reference: every triangle, in id order.
using AllTriangles = test_support::AllTriangles;

// Random rounds of the brute-force comparisons: fewer in sanitizer builds (memory errors, not
// statistics; the full counts take ~20 s under ASan).
#if defined(TRAINER_SANITIZER_BUILD)
constexpr int kBvhContactCycles = 8;
constexpr int kBvhSegmentQueries = 40;
#else
constexpr int kBvhContactCycles = 60;
constexpr int kBvhSegmentQueries = 300;
#endif

core::Arena bvh_arena() {
  auto arena = core::Arena::create(16U << 20);
  EXPECT_TRUE(arena.has_value());
  return std::move(arena).value();
}

bool same_bits(const Vec3& x, const Vec3& y) { return std::memcmp(x.data(), y.data(), sizeof(float) * 3) == 0; }

TEST(TriangleBvh, QueriesEqualBruteForceInIdOrder) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0F, 1.0F);
  core::Arena arena = bvh_arena();
  for (const std::uint32_t leaf : {1U, 4U, 16U}) {
    BvhMesh mesh = bvh_tube(21, 16);  // the duct's 640 triangles
    auto created = TriangleBvh::create(mesh.rest, mesh.triangles, arena, leaf);
    ASSERT_TRUE(created.has_value()) << created.error().message;
    TriangleBvh bvh = std::move(created).value();
    EXPECT_LE(bvh.depth(), 12U);
    std::vector<std::uint32_t> out(640);
    for (int cycle = 0; cycle < 10; ++cycle) {
      bvh_deform(mesh, rng, cycle % 2 == 1);
      ASSERT_TRUE(bvh.refit(mesh.positions).is_ok());
      for (int query = 0; query < 300; ++query) {
        const Vec3 centre(0.012F * (u(rng) - 0.5F), 0.012F * (u(rng) - 0.5F), 0.044F * u(rng) - 0.002F);
        const float half = query % 50 == 0 ? 0.05F : 0.003F * u(rng);  // now and then: everything
        const Aabb box = Aabb::around_point(centre, half);
        std::size_t count = 0;
        ASSERT_TRUE(bvh.query(box, out, count).is_ok());
        std::vector<std::uint32_t> expected;
        for (std::uint32_t t = 0; t < mesh.triangle_count(); ++t) {
          if (mesh.box(t).overlaps(box)) expected.push_back(t);
        }
        ASSERT_EQ(std::vector<std::uint32_t>(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(count)), expected)
            << "leaf " << leaf << " cycle " << cycle << " query " << query;
      }
    }
  }
}

// query_segment: every triangle closer than the margin to the segment is returned (brute force
// with the exact segment–triangle distance), and nothing outside query()'s box answer; long
// diagonal segments (a shaft across the tube) get far fewer candidates than their box holds.
TEST(TriangleBvh, SegmentQueryKeepsEveryTriangleWithinTheMargin) {
  std::mt19937 rng(29);
  std::uniform_real_distribution<float> u(0.0F, 1.0F);
  core::Arena arena = bvh_arena();
  BvhMesh mesh = bvh_tube(21, 16);
  auto created = TriangleBvh::create(mesh.rest, mesh.triangles, arena);
  ASSERT_TRUE(created.has_value());
  TriangleBvh bvh = std::move(created).value();
  std::vector<std::uint32_t> out(640);
  std::vector<std::uint32_t> boxed(640);
  std::size_t within = 0;
  std::size_t segment_total = 0;
  std::size_t box_total = 0;
  for (int cycle = 0; cycle < 10; ++cycle) {
    bvh_deform(mesh, rng, cycle % 2 == 1);
    ASSERT_TRUE(bvh.refit(mesh.positions, cycle % 3 == 0 ? 0.0F : 0.0004F).is_ok());
    for (int query = 0; query < kBvhSegmentQueries; ++query) {
      const Vec3 p0(0.02F * (u(rng) - 0.5F), 0.02F * (u(rng) - 0.5F), 0.05F * u(rng) - 0.005F);
      Vec3 p1(0.02F * (u(rng) - 0.5F), 0.02F * (u(rng) - 0.5F), 0.05F * u(rng) - 0.005F);
      if (query % 10 == 0) p1 = p0;                                  // a point
      if (query % 10 == 1) p1 = Vec3(p0.x(), p0.y(), p0.z() + 0.01F);  // axis-parallel
      const float margin = 0.003F * u(rng);
      std::size_t count = 0;
      std::size_t box_count = 0;
      ASSERT_TRUE(bvh.query_segment(p0, p1, margin, out, count).is_ok());
      ASSERT_TRUE(bvh.query(Aabb::around_segment(p0, p1, margin * (1.0F + 1e-5F) + 1e-9F), boxed, box_count).is_ok());
      const auto begin = out.begin();
      const auto end = out.begin() + static_cast<std::ptrdiff_t>(count);
      ASSERT_TRUE(std::is_sorted(begin, end));
      ASSERT_TRUE(std::includes(boxed.begin(), boxed.begin() + static_cast<std::ptrdiff_t>(box_count), begin, end));
      for (std::uint32_t t = 0; t < mesh.triangle_count(); ++t) {
        const Vec3 a = mesh.vertex(mesh.triangles[3 * t]);
        const Vec3 b = mesh.vertex(mesh.triangles[3 * t + 1]);
        const Vec3 c = mesh.vertex(mesh.triangles[3 * t + 2]);
        if (!(closest_points_segment_triangle(p0, p1, a, b, c).distance_m < margin)) continue;
        ++within;
        ASSERT_TRUE(std::binary_search(begin, end, t)) << "missed triangle " << t << " query " << query;
      }
      segment_total += count;
      box_total += box_count;
    }
  }
  EXPECT_GT(within, static_cast<std::size_t>(3 * kBvhSegmentQueries));
  EXPECT_LT(2 * segment_total, box_total) << "the slab test should cut the box's candidates at least in half";
  std::size_t count = 0;
  EXPECT_EQ(bvh.query_segment(Vec3::Zero(), Vec3(NAN, 0, 0), 0.001F, out, count).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(bvh.query_segment(Vec3::Zero(), Vec3::Zero(), -1.0F, out, count).code(), core::StatusCode::invalid_argument);
}

// query_segment_within: the mesh moved since the last refit (less than the slack: no refit; a
// collapsed vertex moves farther: a refit, then deviation 0), the caller states by how much (the true largest coordinate change, or more); every triangle
// within the margin is still returned, the list is a subset of query_segment()'s and clearly
// shorter; a deviation outside [0, slack] is the plain query. The same for query_within (boxes).
TEST(TriangleBvh, SegmentQueryWithinAStatedDeviationKeepsEveryTriangleWithinTheMargin) {
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> u(0.0F, 1.0F);
  core::Arena arena = bvh_arena();
  BvhMesh mesh = bvh_tube(21, 16);
  auto created = TriangleBvh::create(mesh.rest, mesh.triangles, arena);
  ASSERT_TRUE(created.has_value());
  TriangleBvh bvh = std::move(created).value();
  const float slack = 0.0015F;
  ASSERT_TRUE(bvh.refit(mesh.rest, slack).is_ok());
  std::vector<float> reference = mesh.rest;  // the positions of the last refit
  std::vector<std::uint32_t> plain(640);
  std::vector<std::uint32_t> tight(640);
  std::size_t within = 0;
  std::size_t plain_total = 0;
  std::size_t tight_total = 0;
  std::size_t box_within = 0;
  std::size_t box_plain_total = 0;
  std::size_t box_tight_total = 0;
  for (int cycle = 0; cycle < 10; ++cycle) {
    bvh_deform(mesh, rng, cycle % 2 == 1);  // ≤ 1.2 mm per coordinate, more where collapsed
    if (cycle % 3 == 2) mesh.positions = mesh.rest;
    const std::uint64_t refits = bvh.refit_count();
    ASSERT_TRUE(bvh.refit(mesh.positions, slack).is_ok());
    if (bvh.refit_count() != refits) reference = mesh.positions;  // moved beyond the slack
    float deviation = 0.0F;
    for (std::size_t i = 0; i < mesh.rest.size(); ++i) {
      deviation = std::max(deviation, std::abs(mesh.positions[i] - reference[i]));
    }
    ASSERT_EQ(bvh.last_deviation_m(), deviation);
    const float stated = cycle % 4 == 1 ? deviation + 1e-4F : deviation;
    for (int query = 0; query < kBvhSegmentQueries; ++query) {
      const Vec3 p0(0.02F * (u(rng) - 0.5F), 0.02F * (u(rng) - 0.5F), 0.05F * u(rng) - 0.005F);
      Vec3 p1(0.02F * (u(rng) - 0.5F), 0.02F * (u(rng) - 0.5F), 0.05F * u(rng) - 0.005F);
      if (query % 10 == 0) p1 = p0;
      if (query % 10 == 1) p1 = Vec3(p0.x(), p0.y(), p0.z() + 0.01F);
      const float margin = query % 7 == 0 ? 0.0F : 0.003F * u(rng);
      std::size_t plain_count = 0;
      std::size_t count = 0;
      ASSERT_TRUE(bvh.query_segment(p0, p1, margin, plain, plain_count).is_ok());
      ASSERT_TRUE(bvh.query_segment_within(p0, p1, margin, stated, tight, count).is_ok());
      const auto begin = tight.begin();
      const auto end = tight.begin() + static_cast<std::ptrdiff_t>(count);
      ASSERT_TRUE(std::is_sorted(begin, end));
      ASSERT_TRUE(std::includes(plain.begin(), plain.begin() + static_cast<std::ptrdiff_t>(plain_count), begin, end));
      for (std::uint32_t t = 0; t < mesh.triangle_count(); ++t) {
        const Vec3 a = mesh.vertex(mesh.triangles[3 * t]);
        const Vec3 b = mesh.vertex(mesh.triangles[3 * t + 1]);
        const Vec3 c = mesh.vertex(mesh.triangles[3 * t + 2]);
        const float distance = closest_points_segment_triangle(p0, p1, a, b, c).distance_m;
        if (!(distance < margin) && !(margin == 0.0F && distance == 0.0F)) continue;
        ++within;
        ASSERT_TRUE(std::binary_search(begin, end, t)) << "missed triangle " << t << " query " << query;
      }
      plain_total += plain_count;
      tight_total += count;
      // The box query with the same statement: every triangle whose current box overlaps.
      const Aabb box = Aabb::around_point(p0, query % 5 == 0 ? 0.0F : 0.0015F * u(rng));
      std::size_t box_plain = 0;
      std::size_t box_tight = 0;
      ASSERT_TRUE(bvh.query(box, plain, box_plain).is_ok());
      ASSERT_TRUE(bvh.query_within(box, stated, tight, box_tight).is_ok());
      ASSERT_TRUE(std::includes(plain.begin(), plain.begin() + static_cast<std::ptrdiff_t>(box_plain), tight.begin(),
                                tight.begin() + static_cast<std::ptrdiff_t>(box_tight)));
      for (std::uint32_t t = 0; t < mesh.triangle_count(); ++t) {
        if (!mesh.box(t).overlaps(box)) continue;
        ++box_within;
        ASSERT_TRUE(std::binary_search(tight.begin(), tight.begin() + static_cast<std::ptrdiff_t>(box_tight), t)) << t;
      }
      box_plain_total += box_plain;
      box_tight_total += box_tight;
      ASSERT_TRUE(bvh.query_segment(p0, p1, margin, plain, plain_count).is_ok());
      // Outside [0, slack]: the plain answer.
      std::size_t ignored = 0;
      ASSERT_TRUE(bvh.query_segment_within(p0, p1, margin, query % 2 == 0 ? -1.0F : slack, tight, ignored).is_ok());
      ASSERT_EQ(ignored, plain_count);
      ASSERT_TRUE(std::equal(tight.begin(), tight.begin() + static_cast<std::ptrdiff_t>(ignored), plain.begin()));
    }
  }
  EXPECT_GT(within, static_cast<std::size_t>(3 * kBvhSegmentQueries));
  EXPECT_LT(tight_total, plain_total - plain_total / 5) << "a stated deviation should cut candidates";
  EXPECT_GT(box_within, static_cast<std::size_t>(2 * kBvhSegmentQueries));
  EXPECT_LT(box_tight_total, box_plain_total - box_plain_total / 5);
  std::size_t count = 0;
  EXPECT_EQ(bvh.query_segment_within(Vec3::Zero(), Vec3(NAN, 0, 0), 0.001F, 0.0F, tight, count).code(),
            core::StatusCode::invalid_argument);
}

// Built and refitted with a slack at rest, the hierarchy still returns every triangle whose
// box overlaps after the vertices move less than the slack, without refitting; one coordinate
// beyond it refits.
TEST(TriangleBvh, SlackSkipsRefitsAndStaysRight) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(0.0F, 1.0F);
  core::Arena arena = bvh_arena();
  BvhMesh mesh = bvh_tube(21, 16);
  auto created = TriangleBvh::create(mesh.rest, mesh.triangles, arena);
  ASSERT_TRUE(created.has_value());
  TriangleBvh bvh = std::move(created).value();
  const float slack = 0.0015F;
  ASSERT_TRUE(bvh.refit(mesh.rest, slack).is_ok());
  const std::uint64_t refits = bvh.refit_count();
  std::vector<std::uint32_t> out(640);
  std::size_t checked = 0;
  for (int cycle = 0; cycle < 10; ++cycle) {
    bvh_deform(mesh, rng, false);  // ≤ 1.2 mm per coordinate
    ASSERT_TRUE(bvh.refit(mesh.positions, slack).is_ok());
    ASSERT_EQ(bvh.refit_count(), refits) << "moved less than the slack: no refit";
    for (int query = 0; query < 300; ++query) {
      const Vec3 centre(0.012F * (u(rng) - 0.5F), 0.012F * (u(rng) - 0.5F), 0.044F * u(rng) - 0.002F);
      const Aabb box = Aabb::around_point(centre, 0.0015F * u(rng));
      std::size_t count = 0;
      ASSERT_TRUE(bvh.query(box, out, count).is_ok());
      ASSERT_TRUE(std::is_sorted(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(count)));
      for (std::uint32_t t = 0; t < mesh.triangle_count(); ++t) {
        if (!mesh.box(t).overlaps(box)) continue;
        ++checked;
        ASSERT_TRUE(std::binary_search(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(count), t)) << t;
      }
    }
  }
  EXPECT_GT(checked, 1000U);
  mesh.positions[7] += 0.002F;  // one coordinate 2 mm away
  ASSERT_TRUE(bvh.refit(mesh.positions, slack).is_ok());
  EXPECT_EQ(bvh.refit_count(), refits + 1);
}

// The narrow phases through the hierarchy find bit for bit what they find when fed every
// triangle in id order: random capsules (shaft-like, jaw-like, some reaching right through the
// tube: deep penetrations and huge query boxes) and random particles, on deformed tubes with
// degenerate triangles.
TEST(TriangleBvh, ContactsAreBitIdenticalToAllTrianglesOnRandomQueries) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> u(0.0F, 1.0F);
  core::Arena arena = bvh_arena();
  BvhMesh mesh = bvh_tube(21, 16);
  auto created = TriangleBvh::create(mesh.rest, mesh.triangles, arena);
  ASSERT_TRUE(created.has_value());
  TriangleBvh bvh = std::move(created).value();
  AllTriangles all(mesh.triangle_count());
  SegmentContactSettings segment_settings;
  segment_settings.surface_half_thickness_m = 0.0005F;
  segment_settings.stiffness_n_per_m = 500.0F;
  segment_settings.damping_n_s_per_m = 0.5F;
  segment_settings.max_force_n = 5.0F;
  segment_settings.max_candidates = 640;
  auto through_bvh = SegmentSurfaceContact::create(segment_settings, arena);
  auto through_all = SegmentSurfaceContact::create(segment_settings, arena);
  ASSERT_TRUE(through_bvh.has_value() && through_all.has_value());
  ParticleContactSettings particle_settings;
  particle_settings.max_particles = 16;
  particle_settings.max_contacts = 64;
  particle_settings.max_nodes = 336;
  particle_settings.max_candidates = 640;
  particle_settings.stiffness_n_per_m = 300.0F;
  particle_settings.damping_n_s_per_m = 0.1F;
  particle_settings.surface_offset_m = 0.0002F;
  particle_settings.max_force_n = 2.0F;
  particle_settings.side = ContactSide::both;
  auto particles_bvh = ParticleSurfaceContact::create(particle_settings, arena);
  auto particles_all = ParticleSurfaceContact::create(particle_settings, arena);
  ASSERT_TRUE(particles_bvh.has_value() && particles_all.has_value());

  const auto random_point = [&](float spread) {
    return Vec3(spread * (u(rng) - 0.5F), spread * (u(rng) - 0.5F), 0.046F * u(rng) - 0.003F);
  };
  std::size_t segment_contacts = 0;
  std::size_t particle_contacts = 0;
  for (int cycle = 0; cycle < kBvhContactCycles; ++cycle) {
    bvh_deform(mesh, rng, cycle % 3 != 0);
    ASSERT_TRUE(bvh.refit(mesh.positions, 0.0003F).is_ok());
    const TriangleMeshView view{mesh.positions, mesh.triangles};
    std::vector<float> velocities(mesh.positions.size());
    for (float& v : velocities) v = 0.01F * (u(rng) - 0.5F);
    for (int trial = 0; trial < 20; ++trial) {
      std::vector<ToolCapsule> capsules;
      const ToolSegment segments[3] = {ToolSegment::shaft, ToolSegment::jaw0, ToolSegment::jaw1};
      for (int s = 0; s < 3; ++s) {
        ToolCapsule capsule;
        capsule.segment = segments[s];
        capsule.start_m = random_point(0.012F);
        // Mostly short segments near the wall; now and then one across the whole tube.
        capsule.end_m = trial % 7 == 0 ? random_point(0.03F) : Vec3(capsule.start_m + 0.004F * (random_point(2.0F) - Vec3(0, 0, 0.02F)));
        capsule.radius_m = s == 0 ? 0.0025F : 0.001F * u(rng);
        capsule.start_velocity_m_per_s = Vec3(0.05F * (u(rng) - 0.5F), 0.0F, 0.01F);
        capsule.end_velocity_m_per_s = capsule.start_velocity_m_per_s;
        capsules.push_back(capsule);
      }
      const core::Status a = through_bvh->update(capsules, view, velocities, bvh);
      const core::Status b = through_all->update(capsules, view, velocities, all);
      ASSERT_EQ(a.code(), b.code());
      ASSERT_EQ(through_bvh->contact_count(), through_all->contact_count());
      for (std::size_t k = 0; k < through_all->contact_count(); ++k) {
        const SegmentContact& x = through_bvh->contact(k);
        const SegmentContact& y = through_all->contact(k);
        ASSERT_EQ(x.triangle, y.triangle);
        ASSERT_EQ(x.feature, y.feature);
        ASSERT_EQ(x.side, y.side);
        ASSERT_TRUE(same_bits(x.force_on_tool_n, y.force_on_tool_n)) << cycle << " " << trial;
        ASSERT_TRUE(same_bits(x.normal, y.normal));
        ASSERT_TRUE(same_bits(x.mesh_point_m, y.mesh_point_m));
      }
      segment_contacts += through_all->contact_count();

      std::vector<Vec3> particles;
      for (int p = 0; p < 16; ++p) {
        // Near the wall (inside and out, some right on it) or far away.
        const float angle = 2.0F * std::numbers::pi_v<float> * u(rng);
        const float radius = p % 4 == 0 ? 0.03F * u(rng) : 0.004F + 0.0015F * (u(rng) - 0.5F);
        particles.emplace_back(radius * std::cos(angle), radius * std::sin(angle), 0.046F * u(rng) - 0.003F);
      }
      ParticleContactOutput out_bvh;
      ParticleContactOutput out_all;
      const core::Status pa = particles_bvh->compute(particles, {}, 0.0005F, view, velocities, bvh, out_bvh);
      const core::Status pb = particles_all->compute(particles, {}, 0.0005F, view, velocities, all, out_all);
      ASSERT_EQ(pa.code(), pb.code());
      ASSERT_EQ(out_bvh.contact_count, out_all.contact_count);
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
  }
  // The capsules and particles did reach the wall (at least 8 contacts of each kind a cycle).
  EXPECT_GT(segment_contacts, static_cast<std::size_t>(8 * kBvhContactCycles));
  EXPECT_GT(particle_contacts, static_cast<std::size_t>(8 * kBvhContactCycles));
}

TEST(TriangleBvh, RefusalsTruncationAndEmptyAfterABadRefit) {
  core::Arena arena = bvh_arena();
  BvhMesh mesh = bvh_tube(21, 16);
  EXPECT_FALSE(TriangleBvh::create(mesh.rest, {}, arena).has_value());
  EXPECT_FALSE(TriangleBvh::create(mesh.rest, mesh.triangles, arena, 0).has_value());
  std::vector<std::uint32_t> bad = mesh.triangles;
  bad[5] = 336;
  auto refused = TriangleBvh::create(mesh.rest, bad, arena);
  ASSERT_FALSE(refused.has_value());
  EXPECT_NE(refused.error().message.find("vertex index 336"), std::string::npos) << refused.error().message;
  auto created = TriangleBvh::create(mesh.rest, mesh.triangles, arena);
  ASSERT_TRUE(created.has_value());
  TriangleBvh bvh = std::move(created).value();
  std::vector<std::uint32_t> out(640);
  std::size_t count = 0;
  // Truncated: the lowest ids, capacity_exceeded.
  std::vector<std::uint32_t> short_out(5);
  EXPECT_EQ(bvh.query(Aabb::around_point(Vec3::Zero(), 1.0F), short_out, count).code(),
            core::StatusCode::capacity_exceeded);
  EXPECT_EQ(count, 5U);
  EXPECT_EQ(short_out, (std::vector<std::uint32_t>{0, 1, 2, 3, 4}));
  ASSERT_TRUE(bvh.query(Aabb::around_point(Vec3::Zero(), 1.0F), out, count).is_ok());
  EXPECT_EQ(count, 640U);  // the truncated query left no stale hit behind
  EXPECT_EQ(bvh.query(Aabb{Vec3::Constant(1.0F), Vec3::Zero()}, out, count).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(bvh.query(Aabb::around_point(Vec3(NAN, 0, 0), 1.0F), out, count).code(), core::StatusCode::invalid_argument);
  // Far from the mesh: nothing.
  ASSERT_TRUE(bvh.query(Aabb::around_point(Vec3(0, 0, 0.1F), 0.001F), out, count).is_ok());
  EXPECT_EQ(count, 0U);
  // Bad refits: refused, and the hierarchy answers nothing until a good one.
  std::vector<float> broken = mesh.rest;
  broken[10] = NAN;
  EXPECT_EQ(bvh.refit(broken).code(), core::StatusCode::numeric_error);
  EXPECT_FALSE(bvh.ready());
  ASSERT_TRUE(bvh.query(Aabb::around_point(Vec3::Zero(), 1.0F), out, count).is_ok());
  EXPECT_EQ(count, 0U);
  EXPECT_EQ(bvh.refit(std::span(mesh.rest).first(9)).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(bvh.refit(mesh.rest, -1.0F).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(bvh.refit(mesh.rest, NAN).code(), core::StatusCode::invalid_argument);
  ASSERT_TRUE(bvh.refit(mesh.rest).is_ok());
  ASSERT_TRUE(bvh.query(Aabb::around_point(Vec3::Zero(), 1.0F), out, count).is_ok());
  EXPECT_EQ(count, 640U);
}

TEST(TriangleBvh, NoHeapInRefitAndQuery) {
  ASSERT_TRUE(core::alloc::hooks_installed());
  core::Arena arena = bvh_arena();
  BvhMesh mesh = bvh_tube(21, 16);
  auto created = TriangleBvh::create(mesh.rest, mesh.triangles, arena);
  ASSERT_TRUE(created.has_value());
  TriangleBvh bvh = std::move(created).value();
  arena.seal();
  std::mt19937 rng(3);
  std::vector<std::vector<float>> shapes;
  for (int i = 0; i < 4; ++i) {
    bvh_deform(mesh, rng, false);
    shapes.push_back(mesh.positions);
  }
  std::vector<std::uint32_t> out(640);
  std::size_t found = 0;
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (int cycle = 0; cycle < 2000; ++cycle) {
    if (!bvh.refit(shapes[static_cast<std::size_t>(cycle) % 4], 0.0002F).is_ok()) break;
    std::size_t count = 0;
    const Vec3 centre(0.004F, 0.0F, 0.00002F * static_cast<float>(cycle));
    if (!bvh.query(Aabb::around_point(centre, 0.001F), out, count).is_ok()) break;
    found += count;
    if (!bvh.query_within(Aabb::around_point(centre, 0.001F), 0.0001F, out, count).is_ok()) break;
    found += count;
    if (!bvh.query_segment(centre, centre + Vec3(0.0F, 0.003F, 0.001F), 0.001F, out, count).is_ok()) break;
    found += count;
    if (!bvh.query_segment_within(centre, centre + Vec3(0.0F, 0.003F, 0.001F), 0.001F, 0.0001F, out, count).is_ok()) {
      break;
    }
    found += count;
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
  EXPECT_GT(found, 8000U);
}

}  // namespace
}  // namespace trainer::model
