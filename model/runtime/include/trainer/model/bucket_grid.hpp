// Broad phase for a deforming triangle mesh: Cotin's bucket detector (METHODS.md §4) as a
// uniform spatial hash rebuilt every cycle. Space is cut into cubic cells of edge
// cell_size_m; cell (i, j, k) maps to one of table_size buckets by a hash; every triangle is
// stored in the bucket of each cell its axis-aligned bounding box (AABB) covers. A query box
// returns every triangle stored in the buckets of the cells it covers, deduplicated: a
// superset of the triangles whose AABB overlaps the box (hash collisions only add
// candidates), so a narrow phase over the candidates finds exactly what a brute force over
// all triangles finds.
//
// Differences from Cotin's paper: he hashes nodes and then searches the nearest node's
// triangles; we hash triangles, so a contact inside a large triangle whose vertices are all
// far away is never missed and there is no nearest-node search.
//
// Storage is a compressed bucket table (counts → prefix sums → entries), rebuilt from
// scratch in O(m + table_size) with two passes over the triangles; every array is carved from
// a core::Arena at create(). Cell size: about the mean edge length of the mesh, or the tool
// radius if larger (docs/collision.md has the measurement): much smaller and a triangle
// occupies many cells (more entries, slower rebuild), much larger and queries return many
// triangles the narrow phase then rejects.
//
// A grid need not be rebuilt every time the mesh deforms: rebuilt over positions P with a
// slack s (every triangle stored in the cells of its AABB grown by s), it answers exactly as
// above for any later positions P' with every vertex within s of P — a triangle's AABB under
// P' lies inside its AABB under P grown by s. The trainer rebuilds only when some vertex has
// moved farther than s since the last rebuild (docs/collision.md measures the saving).
//
// Exact filter (issue 19): a hash bucket also holds triangles of other cells (hash collisions)
// and a triangle's cells reach beyond its box; on the duct ~70 % of what the buckets held did
// not overlap the query. Every triangle's stored box (its AABB at the rebuild grown by the
// slack) is kept beside the table, and query() returns only triangles whose stored box
// overlaps the query box, in the order the buckets gave them (so the narrow phases see the
// same triangles in the same order as before, less ones they were bound to reject). A query
// box outside the union of the stored boxes (bounds()) returns nothing without touching the
// table: a catheter particle far from the duct costs one box test.
//
// Units: metres. One thread owns a grid (the haptic thread); query() is not const because it
// stamps triangles to deduplicate without clearing a set.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/core/status.hpp"
#include "trainer/model/broad_phase.hpp"

namespace trainer::model {

struct BucketGridSettings {
  std::uint32_t max_triangles = 0;
  std::uint32_t max_vertices = 0;
  float cell_size_m = 0.0F;          // > 0
  std::uint32_t table_size = 0;      // buckets, a power of two
  std::uint32_t max_entries = 0;     // (triangle, cell) pairs over the whole mesh
};

class BucketGrid final : public TriangleBroadPhase {
 public:
  // Cell coordinates are clamped to ±kMaxCellIndex so a far-away (or huge) coordinate cannot
  // overflow; the clamp is applied to stored triangles and query boxes alike, so the result
  // stays a superset.
  static constexpr std::int32_t kMaxCellIndex = 1 << 20;

  // Setup path: checks the settings and carves the bucket table, the entries and the
  // deduplication stamps from `arena`.
  static core::Expected<BucketGrid> create(const BucketGridSettings& settings, core::Arena& arena);

  // ---- RT path: noexcept, no heap ----

  // Rebuilds the table from the current vertex positions (3n floats, x y z per vertex) and
  // triangles (3m vertex indices). Refuses, leaving the grid empty: more than max_vertices or
  // max_triangles (capacity_exceeded), a length not a multiple of 3 or an index ≥ n
  // (invalid_argument), a non-finite position (numeric_error), and more (triangle, cell)
  // pairs than max_entries (capacity_exceeded; required_entries() then says how many), a
  // negative or non-finite slack (invalid_argument). `slack_m` grows every triangle's AABB
  // (see the header comment).
  core::Status rebuild(std::span<const float> positions_m,
                       std::span<const std::uint32_t> triangles, float slack_m = 0.0F) noexcept;

  // Triangle ids whose stored box (AABB at the last rebuild grown by its slack) overlaps the
  // box, each once, into `out_ids`; `out_count` is how many were written. capacity_exceeded when `out_ids` was too short (the first
  // out_ids.size() found are written); invalid_argument for a non-finite or inverted box.
  // A box covering more cells than there are buckets scans every bucket instead.
  core::Status query(const Aabb& box, std::span<std::uint32_t> out_ids,
                     std::size_t& out_count) noexcept override;

  void clear() noexcept;

  std::size_t triangle_count() const noexcept { return triangle_count_; }
  std::size_t entry_count() const noexcept { return entry_count_; }
  // Pairs the last rebuild needed (also when it refused for lack of max_entries).
  std::size_t required_entries() const noexcept { return required_entries_; }
  float cell_size_m() const noexcept { return cell_size_m_; }
  // Union of the stored boxes of the last rebuild (empty-inverted when nothing is stored).
  const Aabb& bounds() const noexcept { return bounds_; }
  // Since create(): triangles the buckets held that the exact box test rejected, and those it
  // passed (a measure of the hash's false candidates; docs/collision.md).
  std::uint64_t rejected_count() const noexcept { return rejected_count_; }
  std::uint64_t passed_count() const noexcept { return passed_count_; }
  std::size_t table_size() const noexcept { return bucket_start_.size() - 1; }

 private:
  struct CellRange {
    std::int32_t min[3];
    std::int32_t max[3];
  };

  BucketGrid() = default;
  std::int32_t cell_index(float coordinate_m) const noexcept;
  CellRange cells_of(const Vec3& min_m, const Vec3& max_m) const noexcept;
  std::uint32_t bucket_of(std::int32_t i, std::int32_t j, std::int32_t k) const noexcept;
  // Appends the not-yet-stamped triangles of `bucket` whose stored box overlaps `box`; false
  // when out_ids is full.
  bool collect_bucket(std::uint32_t bucket, const Aabb& box, std::span<std::uint32_t> out_ids,
                      std::size_t& out_count) noexcept;

  float cell_size_m_ = 0.0F;
  float inverse_cell_size_ = 0.0F;
  std::uint32_t bucket_mask_ = 0;
  std::uint32_t max_vertices_ = 0;
  std::size_t triangle_count_ = 0;
  std::size_t entry_count_ = 0;
  std::size_t required_entries_ = 0;
  std::uint32_t stamp_ = 0;
  Aabb bounds_{Vec3::Constant(1.0F), Vec3::Constant(-1.0F)};
  std::uint64_t rejected_count_ = 0;
  std::uint64_t passed_count_ = 0;

  std::span<std::uint32_t> bucket_start_;  // table_size + 1 prefix sums into entries_
  std::span<std::uint32_t> entries_;       // triangle ids, grouped by bucket
  std::span<CellRange> triangle_cells_;    // per triangle: the cells its AABB covers
  std::span<Aabb> triangle_boxes_;         // per triangle: its AABB grown by the slack
  std::span<std::uint32_t> stamps_;        // per triangle: last query that returned it
};

}  // namespace trainer::model
