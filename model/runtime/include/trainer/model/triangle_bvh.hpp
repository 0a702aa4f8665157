// Broad phase for a deforming triangle mesh of fixed connectivity (the modal duct, a tensor
// model's surface): a bounding-volume hierarchy of axis-aligned boxes built once over the rest
// positions and refitted, never rebuilt, as the mesh deforms (issue 19; docs/collision.md).
//
// Build (setup path, create()): triangles are split recursively at the median of their
// centroids along the longest axis of the centroids' box, down to leaves of at most leaf_size
// triangles; nodes are stored in depth-first order (a node's left child follows it), so a
// refit is one backward pass over the nodes. The topology never changes afterwards: a mesh
// that deforms a lot gets looser boxes, never a wrong answer.
//
// Refit (RT path): every triangle's box is its AABB over the given positions grown by a slack
// s, and every node's box the union of its children's. refit() skips the work while every
// coordinate is within s of the positions of the last refit (a triangle's AABB then still lies
// inside its stored box), so the work per cycle is one pass over the vertices, plus one pass
// over triangles and nodes when something moved farther: bounded, O(n + m), never the
// hash's rebuild spike.
//
// Query (RT path): the triangles whose stored box overlaps the query box — an exact test per
// triangle, no false candidate of a hash or a cell overhang; the descent runs over a 4-wide copy
// of the tree, 4 boxes per SSE2 test (segment_box.hpp) — returned in increasing id order
// (collected in a bitset, emitted by word), so the narrow phases see them in the same order
// whatever the hierarchy or the refit history: the contacts found are bit-identical to a brute
// force over all triangles in id order (tests/model/runtime/triangle_bvh_test.cpp).
//
// Units: metres. One thread owns a hierarchy; every array is carved from a core::Arena.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/core/status.hpp"
#include "trainer/model/broad_phase.hpp"
#include "trainer/model/segment_box.hpp"

namespace trainer::model {

// Candidates of one repeated query (a tool capsule's segment or a catheter particle's sphere,
// cycle after cycle), kept by TriangleBvh::query_segment_cached_within /
// query_sphere_cached_within: the triangles whose stored box passed the query's own test with
// extra_margin_m more when they were collected, their boxes in packs of 4, and per triangle a
// lower bound of its reference triangle's distance from the query's segment (a sphere: its
// centre), computed when first needed. Valid while the hierarchy has not refitted and the query
// has moved less than the extra margin (docs/collision.md "Cached queries"). Storage from an
// arena at create(); the owner keeps one per repeated query; one thread.
struct QueryCache {
  static constexpr std::size_t kDefaultCapacity = 128;
  static constexpr float kDefaultExtraMarginM = 1e-3F;

  // Refuses a capacity of 0 or above 2^20, an extra margin not finite or ≤ 0, an arena too small.
  static core::Expected<QueryCache> create(core::Arena& arena, std::size_t capacity = kDefaultCapacity,
                                                  float extra_margin_m = kDefaultExtraMarginM);
  void invalidate() noexcept { valid = false; }

  std::span<std::uint32_t> ids;   // increasing
  std::span<AabbPack4> packs;     // ids' stored boxes, 4 per pack (unused lanes never pass)
  std::span<double> below_m;      // per id: lower bound of dist(cached segment, reference triangle); < 0 not yet
  std::size_t count = 0;
  float extra_margin_m = kDefaultExtraMarginM;
  // What the candidates were collected for.
  const void* hierarchy = nullptr;
  std::uint64_t refit = 0;
  float slack_m = 0.0F;
  float test_margin_m = 0.0F;  // segment: the slab test's margin they were collected with
  Aabb box;                    // sphere: the box they were collected with
  Vec3 p0 = Vec3::Zero();      // the segment (a sphere: p0 = p1 = its centre)
  Vec3 p1 = Vec3::Zero();
  float scale_m = 0.0F;        // the largest coordinate magnitude of the cached query and the root box
  bool sphere = false;
  bool valid = false;
  // Since create(): queries answered from the kept candidates, and collections.
  std::uint64_t reuses = 0;
  std::uint64_t collections = 0;
};

class TriangleBvh final : public TriangleBroadPhase {
 public:
  // Deepest hierarchy create() accepts (a median split of 2^32 triangles in leaves of 1 is 33
  // deep): the query's traversal stack is this long.
  static constexpr std::size_t kMaxDepth = 40;
  // Reference-triangle bounds a cached query computes per call at most (the others wait).
  static constexpr int kBoundsPerQuery = 3;

  // Setup path. `positions_m`: 3n floats (x y z per vertex), `triangles`: 3m vertex indices.
  // Refuses (naming what and the value): no triangle, a length not a multiple of 3, an index
  // ≥ n, a non-finite position, leaf_size outside 1..64, an arena too small. The hierarchy
  // is refitted to `positions_m` with no slack (ready to query).
  static core::Expected<TriangleBvh> create(std::span<const float> positions_m,
                                            std::span<const std::uint32_t> triangles,
                                            core::Arena& arena, std::uint32_t leaf_size = 4);

  // ---- RT path: noexcept, no heap ----

  // Makes the hierarchy answer for `positions_m` (3n, the n of create()): boxes grown by
  // `slack_m`, refitted only when some coordinate moved farther than slack_m since the last
  // refit (or the slack changed, or the last refit failed). invalid_argument: wrong length,
  // negative or non-finite slack; numeric_error: a non-finite position. On a refusal the
  // hierarchy is empty (queries return nothing) until a good refit.
  core::Status refit(std::span<const float> positions_m, float slack_m = 0.0F) noexcept;
  // Asks for the next `lines` cache lines of the arrays a refit that does the work reads and
  // writes (reference positions, triangles, pack ids, leaf packs, pack and node boxes, wide
  // nodes), round robin: prefetches into L2, nothing changes (LazyModalSurface::keep_warm).
  void keep_warm(std::size_t lines) noexcept;

  // Triangle ids whose stored box overlaps `box`, increasing, each once. capacity_exceeded
  // when out_ids is too short (the lowest out_ids.size() ids are written); invalid_argument
  // for a non-finite or inverted box.
  core::Status query(const Aabb& box, std::span<std::uint32_t> out_ids,
                     std::size_t& out_count) noexcept override;

  // Triangles whose stored box, grown by margin_m (and a relative 1e-5 for rounding), the
  // segment p0–p1 passes through (slab test per node and per triangle), increasing, each once:
  // every triangle closer than margin_m to the segment is among them (a point of the segment
  // within margin_m of a point of the triangle lies in the grown box). Same statuses as query().
  core::Status query_segment(const Vec3& p0, const Vec3& p1, float margin_m, std::span<std::uint32_t> out_ids,
                             std::size_t& out_count) noexcept override;

  // query_segment() for a caller that knows how far the mesh is from the positions of the last
  // refit: every vertex within deviation_m of them, per coordinate (0 ≤ deviation_m ≤ the
  // slack; LazyModalSurface's motion bound, or last_deviation_m() right after a refit). The
  // stored boxes are then taken as grown by deviation_m instead of the slack (the query's
  // margin reduced by the difference, plus a rounding guard), so fewer triangles come back and
  // still every one within margin_m. A deviation_m outside [0, slack] is ignored (the slack).
  core::Status query_segment_within(const Vec3& p0, const Vec3& p1, float margin_m, float deviation_m,
                                    std::span<std::uint32_t> out_ids, std::size_t& out_count) noexcept;
  // query_segment_within() answered from `cache` while it holds a superset (the hierarchy not
  // refitted since it was filled, the segment within its extra margin of the segment it was
  // filled for, per coordinate, less a rounding guard); otherwise the cache is filled again
  // first (a traversal with the extra margin). The kept candidates are tested with the
  // query's own box test (so every triangle query_segment_within returns passes it) and then
  // against a bound on the triangle itself: each vertex is within D (the stated deviation, or
  // the slack) of the reference positions per coordinate, so a triangle whose reference
  // triangle is farther than margin_m + √3 D (+ how far the segment moved since the fill, + the
  // narrow phase's float rounding: 1 µm + 1e-4 of the coordinates) from the segment cannot be
  // within margin_m (at most kBoundsPerQuery bounds computed per call, none in a filling call;
  // a triangle without one is kept). Returns, in increasing id order, every triangle within margin_m
  // of the segment and a subset of query_segment_within's list. A cache overflow (more than
  // its capacity) answers by query_segment_within and leaves the cache empty.
  core::Status query_segment_cached_within(const Vec3& p0, const Vec3& p1, float margin_m, float deviation_m,
                                           QueryCache& cache, std::span<std::uint32_t> out_ids,
                                           std::size_t& out_count) noexcept;
  // The same with the slack as the deviation (no statement).
  core::Status query_segment_cached(const Vec3& p0, const Vec3& p1, float margin_m, QueryCache& cache,
                                    std::span<std::uint32_t> out_ids, std::size_t& out_count) noexcept override {
    return query_segment_cached_within(p0, p1, margin_m, -1.0F, cache, out_ids, out_count);
  }

  // query_within(Aabb::around_point(centre, radius_m), deviation_m) answered from `cache` in
  // the same way (reused while the query's box, shrunk as query_within shrinks it, lies inside
  // the box the cache was filled with; the triangle bound is the point's distance): in
  // increasing id order, every triangle within radius_m of the centre and a subset of
  // query_within's list. A catheter particle's repeated wall query.
  core::Status query_sphere_cached_within(const Vec3& centre, float radius_m, float deviation_m, QueryCache& cache,
                                          std::span<std::uint32_t> out_ids, std::size_t& out_count) noexcept;
  core::Status query_sphere_cached(const Vec3& centre, float radius_m, QueryCache& cache,
                                   std::span<std::uint32_t> out_ids, std::size_t& out_count) noexcept override {
    return query_sphere_cached_within(centre, radius_m, -1.0F, cache, out_ids, out_count);
  }

  // query() with the same statement: every triangle whose current AABB overlaps `box` is
  // returned (a subset of query()'s list).
  core::Status query_within(const Aabb& box, float deviation_m, std::span<std::uint32_t> out_ids,
                            std::size_t& out_count) noexcept;

  std::size_t triangle_count() const noexcept { return triangles_.size() / 3; }
  std::size_t vertex_count() const noexcept { return reference_.size() / 3; }
  std::size_t node_count() const noexcept { return nodes_.size(); }
  std::size_t depth() const noexcept { return depth_; }
  bool ready() const noexcept { return ready_; }
  // Root box (the union of the stored triangle boxes); meaningful while ready().
  const Aabb& bounds() const noexcept { return nodes_[0].box; }
  // Since create(): refits that did the work (a coordinate beyond the slack), and calls.
  std::uint64_t refit_count() const noexcept { return refit_count_; }
  std::uint64_t refit_calls() const noexcept { return refit_calls_; }
  // After a successful refit(): the largest coordinate change between the positions it was
  // given and the hierarchy's reference (0 when it refitted). LazyModalSurface bounds the
  // motion from there on and keeps slack − this for it.
  float last_deviation_m() const noexcept { return last_deviation_m_; }
  // The positions of the last refit that did the work (what refit() compares against).
  // LazyModalSurface checks a part of the mesh against them (its per-cluster bound).
  std::span<const float> reference_positions() const noexcept { return reference_; }

 private:
  struct Node {
    Aabb box;
    std::uint32_t first = 0;  // leaf: first slot in order_; internal: index of the right child
    std::uint32_t count = 0;  // leaf: triangles (≥ 1); internal: 0 (the left child is index + 1)
  };
  // The traversal's tree: the binary tree with every other level folded in, so a node has up
  // to 4 children (the binary node's grandchildren, or a child leaf itself), their boxes side
  // by side for one 4-wide test (segment_box.hpp). Boxes copied from nodes_ at each refit.
  struct WideNode {
    AabbPack4 boxes;                  // unused lanes inverted (never pass)
    std::uint32_t child[4] = {};      // internal: wide node index; leaf: its first pack
    std::uint32_t packs[4] = {};      // leaf: its pack count (≥ 1); internal or unused: 0
    std::uint32_t binary[4] = {};     // the binary node of each used lane
    std::uint32_t used = 0;           // lanes 0..used-1
  };

  TriangleBvh() = default;
  void refit_boxes() noexcept;
  // How much of the slack a stated deviation leaves unused, less the rounding guard (≥ 0; 0
  // for a deviation outside [0, slack)).
  float unused_slack(float deviation_m) const noexcept;
  // The traversal of query() and query_segment(): `accept4(pack)` gives the lanes of a pack of
  // 4 node or triangle boxes that may hold an answer.
  template <class Accept4>
  core::Status collect(Accept4&& accept4, std::span<std::uint32_t> out_ids, std::size_t& out_count) noexcept;
  // The cached queries' parts: whether `cache` was filled by this hierarchy in its current
  // state for this kind of query (counts a reuse; else marks it invalid), the coordinates'
  // scale, how far the segment's ends moved per coordinate, the fill, the answer.
  bool cache_current(QueryCache& cache, bool sphere) const noexcept;
  static double query_scale(const Vec3& p0, const Vec3& p1, const QueryCache& cache) noexcept;
  static double moved_inf(const Vec3& p0, const Vec3& p1, const QueryCache& cache) noexcept;
  template <class Accept4>
  bool fill_cache(QueryCache& cache, Accept4&& accept4, const Vec3& p0, const Vec3& p1) noexcept;
  template <class Accept4>
  core::Status answer_from_cache(QueryCache& cache, Accept4&& accept4, const Vec3& p0, const Vec3& p1, float reach_m,
                                 float deviation_m, int budget, std::span<std::uint32_t> out_ids,
                                 std::size_t& out_count) noexcept;

  std::span<std::uint32_t> triangles_;  // 3m, a copy of create()'s
  std::span<Node> nodes_;  // the binary tree (create); refit keeps only the root's box (bounds())
  std::span<std::uint32_t> order_;     // triangle ids, leaf by leaf
  std::span<float> reference_;         // 3n: the positions of the last refit
  std::span<std::uint64_t> hit_bits_;  // per triangle, one query's hits (all zero between queries)
  std::span<WideNode> wide_;           // root first
  std::span<AabbPack4> leaf_packs_;    // each leaf's triangle boxes, 4 per pack (stored boxes)
  std::span<std::uint32_t> pack_ids_;  // 4 per pack: the triangle in each lane
  std::span<std::uint32_t> triangle_lane_;  // per triangle: 4 × its pack + its lane (the cached queries' boxes)
  // A box as two quads (x y z and an unused lane): refit_boxes' unions per pack and per wide node.
  struct alignas(16) BoxQuads {
    float low[4];
    float high[4];
  };
  std::span<BoxQuads> pack_box_;  // per pack: the union of its lanes
  std::span<BoxQuads> wide_box_;  // per wide node: the union of its lanes
  std::size_t depth_ = 0;
  float slack_m_ = 0.0F;
  float rounding_guard_m_ = 0.0F;  // of query_segment_within / query_within, set by refit_boxes
  bool ready_ = false;
  std::uint64_t refit_count_ = 0;
  std::uint64_t refit_calls_ = 0;
  std::size_t warm_region_ = 0;  // keep_warm's next line: region, line in it
  std::size_t warm_line_ = 0;
  float last_deviation_m_ = 0.0F;
};

}  // namespace trainer::model
