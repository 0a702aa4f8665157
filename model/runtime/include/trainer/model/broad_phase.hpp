// What the contact narrow phases (SegmentSurfaceContact, ParticleSurfaceContact,
// DisplacementContact, GodObjectProxy) need from a broad phase over a triangle mesh: the ids of
// the triangles that may lie within a box. Two implementations: BucketGrid (a spatial hash
// rebuilt over the positions) and TriangleBvh (a bounding-volume hierarchy over a fixed triangle
// set, refitted); docs/collision.md compares them.
//
// Contract of query(): every triangle whose current AABB overlaps the box is returned (a
// superset is allowed: the narrow phase rejects what is out of reach), each id once;
// capacity_exceeded when `out_ids` is too short (the ids written are real candidates);
// invalid_argument for a non-finite or inverted box. RT path: noexcept, no heap. One thread
// owns a broad phase (query() may stamp scratch state).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "trainer/core/status.hpp"

namespace trainer::model {

using Vec3 = Eigen::Vector3f;
struct QueryCache;  // triangle_bvh.hpp

struct Aabb {
  Vec3 min_m = Vec3::Zero();
  Vec3 max_m = Vec3::Zero();

  static Aabb around_point(const Vec3& centre, float half_size_m) noexcept {
    return {(centre.array() - half_size_m).matrix(), (centre.array() + half_size_m).matrix()};
  }
  static Aabb around_segment(const Vec3& p0, const Vec3& p1, float margin_m) noexcept {
    return {(p0.cwiseMin(p1).array() - margin_m).matrix(),
            (p0.cwiseMax(p1).array() + margin_m).matrix()};
  }
  // Closed boxes: touching counts (a triangle on the query box's face is within reach exactly).
  bool overlaps(const Aabb& other) const noexcept {
    return min_m.x() <= other.max_m.x() && other.min_m.x() <= max_m.x() &&
           min_m.y() <= other.max_m.y() && other.min_m.y() <= max_m.y() &&
           min_m.z() <= other.max_m.z() && other.min_m.z() <= max_m.z();
  }
};

class TriangleBroadPhase {
 public:
  virtual core::Status query(const Aabb& box, std::span<std::uint32_t> out_ids,
                             std::size_t& out_count) noexcept = 0;

  // The triangles that may lie within margin_m of the segment p0–p1: the same contract as
  // query() for every triangle closer than margin_m to the segment (each returned once; a
  // superset allowed). This default asks query() for the segment's box grown by margin_m; a
  // broad phase may test its boxes against the segment itself (TriangleBvh: a long diagonal
  // shaft's box holds far more triangles than the thin cylinder around it).
  // invalid_argument: a non-finite point or a negative or non-finite margin.
  virtual core::Status query_segment(const Vec3& p0, const Vec3& p1, float margin_m,
                                     std::span<std::uint32_t> out_ids, std::size_t& out_count) noexcept {
    if (!(margin_m >= 0.0F) || !std::isfinite(margin_m)) {
      out_count = 0;
      return {core::StatusCode::invalid_argument, "broad phase: segment margin negative or non-finite"};
    }
    return query(Aabb::around_segment(p0, p1, margin_m), out_ids, out_count);
  }

  // query_segment() for a query repeated cycle after cycle by a segment that moves a little
  // (a tool's capsule): the broad phase may keep candidates in `cache` (one per repeated
  // query, owned by the caller) and answer from them while they are still a superset
  // (TriangleBvh: docs/collision.md "Cached queries"). The contract is query_segment()'s
  // for every triangle within margin_m: each such triangle returned, in increasing id order
  // where the broad phase orders them, and possibly fewer others. This default ignores the cache.
  virtual core::Status query_segment_cached(const Vec3& p0, const Vec3& p1, float margin_m, QueryCache& cache,
                                            std::span<std::uint32_t> out_ids, std::size_t& out_count) noexcept {
    (void)cache;
    return query_segment(p0, p1, margin_m, out_ids, out_count);
  }

  // query(Aabb::around_point(centre, radius_m)) for a repeated query (a catheter particle's),
  // the same contract for every triangle within radius_m of the centre; the default ignores
  // the cache.
  virtual core::Status query_sphere_cached(const Vec3& centre, float radius_m, QueryCache& cache,
                                           std::span<std::uint32_t> out_ids, std::size_t& out_count) noexcept {
    (void)cache;
    return query(Aabb::around_point(centre, radius_m), out_ids, out_count);
  }

 protected:
  TriangleBroadPhase() = default;
  TriangleBroadPhase(const TriangleBroadPhase&) = default;
  TriangleBroadPhase(TriangleBroadPhase&&) = default;
  TriangleBroadPhase& operator=(const TriangleBroadPhase&) = default;
  TriangleBroadPhase& operator=(TriangleBroadPhase&&) = default;
  ~TriangleBroadPhase() = default;
};

}  // namespace trainer::model
