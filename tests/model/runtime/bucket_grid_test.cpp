// Bucket grid (bucket_grid.hpp) against a brute force over all triangles: on random deformed
// tube meshes, thousands of random boxes return every triangle whose AABB overlaps the box,
// each once, and the sphere contacts found through the grid are exactly those of the brute
// force. Also: capacity and argument refusals, truncated queries, and no heap in the RT calls.
#include "trainer/model/bucket_grid.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/model/geometry.hpp"

namespace trainer::model {
namespace {

struct Mesh {
  std::vector<float> rest;
  std::vector<float> positions;
  std::vector<std::uint32_t> triangles;
  std::size_t triangle_count() const { return triangles.size() / 3; }
  Vec3 vertex(std::uint32_t v) const {
    return {positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]};
  }
};

// Open tube along z: `rings` rings of `segments` vertices, radius 4 mm, 2 mm between rings
// (the duct's scale); 2 (rings − 1) segments triangles.
Mesh make_tube(std::uint32_t rings, std::uint32_t segments) {
  Mesh mesh;
  const float radius = 0.004F;
  for (std::uint32_t r = 0; r < rings; ++r) {
    for (std::uint32_t s = 0; s < segments; ++s) {
      const float angle = 2.0F * std::numbers::pi_v<float> * static_cast<float>(s) /
                          static_cast<float>(segments);
      mesh.rest.insert(mesh.rest.end(), {radius * std::cos(angle), radius * std::sin(angle),
                                         0.002F * static_cast<float>(r)});
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

// A smooth random deformation (a few sine waves) plus per-vertex jitter, amplitude ~1 mm.
void deform(Mesh& mesh, std::mt19937& rng) {
  std::uniform_real_distribution<float> u(-1.0F, 1.0F);
  const float phase = u(rng) * 3.0F;
  const float amplitude = 0.001F * u(rng);
  for (std::size_t v = 0; v < mesh.rest.size() / 3; ++v) {
    const float z = mesh.rest[3 * v + 2];
    mesh.positions[3 * v] = mesh.rest[3 * v] + amplitude * std::sin(300.0F * z + phase) + 2e-4F * u(rng);
    mesh.positions[3 * v + 1] = mesh.rest[3 * v + 1] + amplitude * std::cos(200.0F * z) + 2e-4F * u(rng);
    mesh.positions[3 * v + 2] = mesh.rest[3 * v + 2] + 2e-4F * u(rng);
  }
}

Aabb triangle_box(const Mesh& mesh, std::size_t t) {
  const Vec3 a = mesh.vertex(mesh.triangles[3 * t]);
  const Vec3 b = mesh.vertex(mesh.triangles[3 * t + 1]);
  const Vec3 c = mesh.vertex(mesh.triangles[3 * t + 2]);
  return {a.cwiseMin(b).cwiseMin(c), a.cwiseMax(b).cwiseMax(c)};
}

bool overlaps(const Aabb& x, const Aabb& y) {
  return (x.min_m.array() <= y.max_m.array()).all() && (y.min_m.array() <= x.max_m.array()).all();
}

core::Arena make_arena() {
  auto arena = core::Arena::create(64U << 20);
  EXPECT_TRUE(arena.has_value());
  return std::move(arena).value();
}

BucketGrid make_grid(core::Arena& arena, std::uint32_t triangles, std::uint32_t vertices,
                     float cell_size_m, std::uint32_t max_entries = 1U << 20) {
  auto grid = BucketGrid::create({triangles, vertices, cell_size_m, 4096, max_entries}, arena);
  EXPECT_TRUE(grid.has_value()) << (grid ? "" : grid.error().message);
  return std::move(grid).value();
}

// Queries per deformed mesh: 100 in sanitizer builds (memory errors, not statistics).
#if defined(TRAINER_SANITIZER_BUILD)
constexpr int kQueriesPerMesh = 100;
#else
constexpr int kQueriesPerMesh = 500;
#endif

TEST(BucketGrid, QueriesEqualBruteForceOnRandomDeformedMeshes) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.0F, 1.0F);
  core::Arena arena = make_arena();
  std::size_t total_contacts = 0;
  for (const float cell_size : {0.0008F, 0.002F, 0.006F}) {
    Mesh mesh = make_tube(21, 16);  // the duct's 640 triangles
    BucketGrid grid = make_grid(arena, 640, 336, cell_size);
    std::vector<std::uint32_t> out(640);
    for (int cycle = 0; cycle < 10; ++cycle) {
      deform(mesh, rng);
      ASSERT_TRUE(grid.rebuild(mesh.positions, mesh.triangles).is_ok());
      ASSERT_EQ(grid.triangle_count(), 640U);
      for (int query = 0; query < kQueriesPerMesh; ++query) {
        const Vec3 centre(0.012F * (u(rng) - 0.5F), 0.012F * (u(rng) - 0.5F), 0.044F * u(rng) - 0.002F);
        const float radius = 0.003F * u(rng);
        const Aabb box = Aabb::around_point(centre, radius);
        std::size_t count = 0;
        ASSERT_TRUE(grid.query(box, out, count).is_ok());
        const std::set<std::uint32_t> found(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(count));
        ASSERT_EQ(found.size(), count) << "duplicates in the answer";
        std::set<std::uint32_t> contacts_grid;
        std::set<std::uint32_t> contacts_brute;
        for (std::uint32_t t = 0; t < mesh.triangle_count(); ++t) {
          // Exactly the triangles whose box overlaps (no slack: the stored box is the AABB):
          // none missed, and no hash collision or cell overhang passed on (issue 19).
          ASSERT_EQ(found.count(t) != 0, overlaps(triangle_box(mesh, t), box))
              << "triangle " << t << " cell " << cell_size;
          const Vec3 a = mesh.vertex(mesh.triangles[3 * t]);
          const Vec3 b = mesh.vertex(mesh.triangles[3 * t + 1]);
          const Vec3 c = mesh.vertex(mesh.triangles[3 * t + 2]);
          if (sphere_triangle_contact(centre, radius, a, b, c).in_contact) contacts_brute.insert(t);
        }
        for (const std::uint32_t t : found) {
          ASSERT_LT(t, mesh.triangle_count());
          const Vec3 a = mesh.vertex(mesh.triangles[3 * t]);
          const Vec3 b = mesh.vertex(mesh.triangles[3 * t + 1]);
          const Vec3 c = mesh.vertex(mesh.triangles[3 * t + 2]);
          if (sphere_triangle_contact(centre, radius, a, b, c).in_contact) contacts_grid.insert(t);
        }
        ASSERT_EQ(contacts_grid, contacts_brute);
        total_contacts += contacts_brute.size();
      }
    }
  }
  EXPECT_GT(total_contacts, 2U * kQueriesPerMesh);  // the queries did reach the surface
}

// Rebuilt with a slack s over some positions, the grid still returns every triangle whose
// AABB overlaps the box after the vertices move up to s (what the trainer relies on to
// rebuild only when a vertex has moved farther); without the slack it misses some, so the
// slack is what makes it right.
TEST(BucketGrid, SlackKeepsTheGridRightWhileVerticesMoveLessThanIt) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<float> u(0.0F, 1.0F);
  core::Arena arena = make_arena();
  Mesh mesh = make_tube(21, 16);
  BucketGrid grid = make_grid(arena, 640, 336, 0.003F);
  std::vector<std::uint32_t> out(640);
  std::size_t missed_without_slack = 0;
  std::size_t checked = 0;
  for (int cycle = 0; cycle < 10; ++cycle) {
    deform(mesh, rng);
    float largest = 0.0F;
    for (std::size_t v = 0; v < mesh.rest.size() / 3; ++v) {
      const Vec3 displacement(mesh.positions[3 * v] - mesh.rest[3 * v],
                              mesh.positions[3 * v + 1] - mesh.rest[3 * v + 1],
                              mesh.positions[3 * v + 2] - mesh.rest[3 * v + 2]);
      largest = std::max(largest, displacement.norm());
    }
    for (const float slack : {0.0F, largest}) {
      ASSERT_TRUE(grid.rebuild(mesh.rest, mesh.triangles, slack).is_ok());  // built at rest
      for (int query = 0; query < 300; ++query) {
        const Vec3 centre(0.012F * (u(rng) - 0.5F), 0.012F * (u(rng) - 0.5F), 0.044F * u(rng) - 0.002F);
        const Aabb box = Aabb::around_point(centre, 0.0015F * u(rng));
        std::size_t count = 0;
        ASSERT_TRUE(grid.query(box, out, count).is_ok());
        const std::set<std::uint32_t> found(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(count));
        for (std::uint32_t t = 0; t < mesh.triangle_count(); ++t) {
          if (!overlaps(triangle_box(mesh, t), box)) continue;  // the deformed triangle
          if (slack > 0.0F) {
            ++checked;
            ASSERT_TRUE(found.count(t)) << "missed triangle " << t << " with slack " << slack;
          } else if (found.count(t) == 0) {
            ++missed_without_slack;
          }
        }
      }
    }
  }
  EXPECT_GT(checked, 1000U);
  EXPECT_GT(missed_without_slack, 0U) << "the deformation should move triangles out of their rest cells";
  EXPECT_EQ(grid.rebuild(mesh.rest, mesh.triangles, -1e-3F).code(), core::StatusCode::invalid_argument);
  EXPECT_EQ(grid.rebuild(mesh.rest, mesh.triangles, NAN).code(), core::StatusCode::invalid_argument);
}

// A box outside the union of the stored boxes returns nothing and touches no bucket (the
// catheter particles far from the duct); bounds() is that union, grown by the slack.
TEST(BucketGrid, BoxOutsideTheBoundsReturnsNothing) {
  core::Arena arena = make_arena();
  Mesh mesh = make_tube(21, 16);
  BucketGrid grid = make_grid(arena, 640, 336, 0.002F);
  ASSERT_TRUE(grid.rebuild(mesh.positions, mesh.triangles, 0.0005F).is_ok());
  EXPECT_NEAR(grid.bounds().min_m.z(), -0.0005F, 1e-7F);
  EXPECT_NEAR(grid.bounds().max_m.z(), 0.0405F, 1e-7F);
  EXPECT_NEAR(grid.bounds().max_m.x(), 0.0045F, 1e-7F);
  std::vector<std::uint32_t> out(640);
  std::size_t count = 7;
  const std::uint64_t rejected = grid.rejected_count();
  const std::uint64_t passed = grid.passed_count();
  ASSERT_TRUE(grid.query(Aabb::around_point({0.0F, 0.0F, 0.0420F}, 0.001F), out, count).is_ok());
  EXPECT_EQ(count, 0U);
  EXPECT_EQ(grid.rejected_count(), rejected);  // not one bucket entry looked at
  EXPECT_EQ(grid.passed_count(), passed);
  // Touching the bounds' face (closed boxes) reaches the end ring's triangles.
  ASSERT_TRUE(grid.query(Aabb::around_point({0.004F, 0.0F, 0.0415F}, 0.001F), out, count).is_ok());
  EXPECT_GT(count, 0U);
  grid.clear();
  ASSERT_TRUE(grid.query(Aabb::around_point({0.004F, 0.0F, 0.02F}, 0.001F), out, count).is_ok());
  EXPECT_EQ(count, 0U);
}

TEST(BucketGrid, CandidatesStayFewWithAGoodCellSize) {
  // Not a timing claim: with the cell ≈ the edge length a small box sees a handful of
  // triangles, not the mesh (the point of a broad phase).
  core::Arena arena = make_arena();
  Mesh mesh = make_tube(101, 32);
  BucketGrid grid = make_grid(arena, 6400, 3232, 0.002F);
  ASSERT_TRUE(grid.rebuild(mesh.positions, mesh.triangles).is_ok());
  std::vector<std::uint32_t> out(6400);
  std::size_t count = 0;
  ASSERT_TRUE(grid.query(Aabb::around_point({0.004F, 0, 0.1F}, 0.0005F), out, count).is_ok());
  EXPECT_GE(count, 2U);
  EXPECT_LT(count, 64U);
}

TEST(BucketGrid, RefusesWhatDoesNotFitAndSaysHowMuchWasNeeded) {
  core::Arena arena = make_arena();
  Mesh mesh = make_tube(21, 16);
  BucketGrid roomy = make_grid(arena, 640, 336, 0.001F);
  ASSERT_TRUE(roomy.rebuild(mesh.positions, mesh.triangles).is_ok());
  const std::size_t needed = roomy.entry_count();
  ASSERT_GT(needed, 640U);
  EXPECT_EQ(roomy.required_entries(), needed);

  BucketGrid tight = make_grid(arena, 640, 336, 0.001F, static_cast<std::uint32_t>(needed - 1));
  const core::Status status = tight.rebuild(mesh.positions, mesh.triangles);
  EXPECT_EQ(status.code(), core::StatusCode::capacity_exceeded);
  EXPECT_EQ(tight.required_entries(), needed);
  EXPECT_EQ(tight.triangle_count(), 0U);
  std::vector<std::uint32_t> out(16);
  std::size_t count = 5;
  EXPECT_TRUE(tight.query(Aabb::around_point({0.004F, 0, 0.01F}, 0.01F), out, count).is_ok());
  EXPECT_EQ(count, 0U);  // empty after a refused rebuild, never half-built

  BucketGrid exact = make_grid(arena, 640, 336, 0.001F, static_cast<std::uint32_t>(needed));
  EXPECT_TRUE(exact.rebuild(mesh.positions, mesh.triangles).is_ok());

  BucketGrid small = make_grid(arena, 100, 336, 0.001F);
  EXPECT_EQ(small.rebuild(mesh.positions, mesh.triangles).code(), core::StatusCode::capacity_exceeded);
  BucketGrid few_vertices = make_grid(arena, 640, 100, 0.001F);
  EXPECT_EQ(few_vertices.rebuild(mesh.positions, mesh.triangles).code(),
            core::StatusCode::capacity_exceeded);
}

TEST(BucketGrid, RefusesBadArguments) {
  core::Arena arena = make_arena();
  Mesh mesh = make_tube(3, 4);
  BucketGrid grid = make_grid(arena, 64, 64, 0.001F);
  std::vector<std::uint32_t> bad_index = mesh.triangles;
  bad_index[5] = 12;  // 12 vertices: 0..11
  EXPECT_EQ(grid.rebuild(mesh.positions, bad_index).code(), core::StatusCode::invalid_argument);
  std::vector<std::uint32_t> ragged(mesh.triangles.begin(), mesh.triangles.end() - 1);
  EXPECT_EQ(grid.rebuild(mesh.positions, ragged).code(), core::StatusCode::invalid_argument);
  std::vector<float> nan_positions = mesh.positions;
  nan_positions[7] = NAN;
  EXPECT_EQ(grid.rebuild(nan_positions, mesh.triangles).code(), core::StatusCode::numeric_error);
  ASSERT_TRUE(grid.rebuild(mesh.positions, mesh.triangles).is_ok());
  std::vector<std::uint32_t> out(64);
  std::size_t count = 0;
  EXPECT_EQ(grid.query({Vec3(1, 0, 0), Vec3(0, 1, 1)}, out, count).code(),
            core::StatusCode::invalid_argument);
  EXPECT_EQ(grid.query({Vec3(0, 0, 0), Vec3(INFINITY, 1, 1)}, out, count).code(),
            core::StatusCode::invalid_argument);

  const auto error_of = [&](BucketGridSettings settings) {
    auto created = BucketGrid::create(settings, arena);
    return created ? std::string() : created.error().message;
  };
  EXPECT_NE(error_of({64, 64, 0.001F, 1000, 100}).find("power of two"), std::string::npos);
  EXPECT_NE(error_of({64, 64, 0.0F, 1024, 100}).find("cell_size_m"), std::string::npos);
  EXPECT_NE(error_of({0, 64, 0.001F, 1024, 100}).find("max_triangles"), std::string::npos);
}

TEST(BucketGrid, TruncatedQueryAndWholeSpaceQuery) {
  core::Arena arena = make_arena();
  Mesh mesh = make_tube(21, 16);
  BucketGrid grid = make_grid(arena, 640, 336, 0.002F);
  ASSERT_TRUE(grid.rebuild(mesh.positions, mesh.triangles).is_ok());
  // A box around everything covers more cells than buckets... or not; either way all 640.
  std::vector<std::uint32_t> out(640);
  std::size_t count = 0;
  ASSERT_TRUE(grid.query({Vec3::Constant(-1.0F), Vec3::Constant(1.0F)}, out, count).is_ok());
  EXPECT_EQ(count, 640U);
  EXPECT_EQ(std::set<std::uint32_t>(out.begin(), out.end()).size(), 640U);
  // Too short an output: the first ones, distinct, and a status.
  std::vector<std::uint32_t> short_out(10);
  EXPECT_EQ(grid.query({Vec3::Constant(-1.0F), Vec3::Constant(1.0F)}, short_out, count).code(),
            core::StatusCode::capacity_exceeded);
  EXPECT_EQ(count, 10U);
  EXPECT_EQ(std::set<std::uint32_t>(short_out.begin(), short_out.end()).size(), 10U);
  // Far away coordinates clamp instead of overflowing, and find nothing there.
  ASSERT_TRUE(grid.query(Aabb::around_point(Vec3::Constant(1e12F), 1.0F), out, count).is_ok());
  EXPECT_EQ(count, 0U);
}

TEST(BucketGrid, NoHeapInRebuildAndQuery) {
  ASSERT_TRUE(core::alloc::hooks_installed());
  core::Arena arena = make_arena();
  Mesh mesh = make_tube(21, 16);
  BucketGrid grid = make_grid(arena, 640, 336, 0.002F);
  arena.seal();
  std::mt19937 rng(3);
  std::vector<std::vector<float>> shapes;
  for (int i = 0; i < 4; ++i) {
    deform(mesh, rng);
    shapes.push_back(mesh.positions);
  }
  std::vector<std::uint32_t> out(640);
  std::size_t found = 0;
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (int cycle = 0; cycle < 2000; ++cycle) {
    if (!grid.rebuild(shapes[static_cast<std::size_t>(cycle) % 4], mesh.triangles).is_ok()) break;
    std::size_t count = 0;
    const Vec3 centre(0.004F, 0.0F, 0.00002F * static_cast<float>(cycle));
    if (!grid.query(Aabb::around_point(centre, 0.001F), out, count).is_ok()) break;
    found += count;
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
  EXPECT_GT(found, 2000U);
}

}  // namespace
}  // namespace trainer::model
