// TriangleBvh's cached queries (issue 19, round 4; docs/collision.md "Cached queries"): a
// query's candidates kept between cycles while the hierarchy has not refitted and the query
// moved less than the cache's extra margin; see triangle_bvh.hpp.
#include <algorithm>
#include <bit>
#include <cmath>
#include <string>

#include "trainer/model/triangle_bvh.hpp"
#include "triangle_bvh_internal.hpp"

namespace trainer::model {
using bvh_detail::bvh_vertex;
using bvh_detail::carve_bvh;

core::Expected<QueryCache> QueryCache::create(core::Arena& arena, std::size_t capacity,
                                                            float extra_margin_m) {
  if (capacity == 0 || capacity > (std::size_t{1} << 20) || !std::isfinite(extra_margin_m) ||
      !(extra_margin_m > 0.0F)) {
    return core::make_error("segment query cache: capacity " + std::to_string(capacity) + ", extra margin " +
                            std::to_string(extra_margin_m) + " m: expected 1..2^20 and a finite margin > 0");
  }
  QueryCache cache;
  auto ids = carve_bvh<std::uint32_t>(arena, capacity, "segment cache ids");
  if (!ids) return std::move(ids).error();
  auto packs = carve_bvh<AabbPack4>(arena, (capacity + 3) / 4, "segment cache packs");
  if (!packs) return std::move(packs).error();
  auto below = carve_bvh<double>(arena, capacity, "segment cache bounds");
  if (!below) return std::move(below).error();
  cache.ids = ids.value();
  cache.packs = packs.value();
  cache.below_m = below.value();
  cache.extra_margin_m = extra_margin_m;
  return cache;
}

core::Status TriangleBvh::query_segment_cached_within(const Vec3& p0, const Vec3& p1, float margin_m,
                                                      float deviation_m, QueryCache& cache,
                                                      std::span<std::uint32_t> out_ids,
                                                      std::size_t& out_count) noexcept {
  out_count = 0;
  if (!p0.allFinite() || !p1.allFinite() || !(margin_m >= 0.0F) || !std::isfinite(margin_m)) {
    return {core::StatusCode::invalid_argument, "triangle bvh: segment non-finite or margin negative"};
  }
  if (!ready_) {
    cache.valid = false;
    return core::Status::ok();
  }
  // The slab test's margin: query_segment_within's, the same expression.
  const float margin = margin_m * (1.0F + 1e-5F) + 1e-9F - unused_slack(deviation_m);
  bool reuse = cache_current(cache, false);
  if (reuse) {
    // A box the float slab test passes at (p0, p1, margin) holds a point of the real segment
    // within margin + 1e-6 of the segment's extent (the t tolerance) + a few ulp of the
    // coordinates; the point of the cached segment beside it is within `moved` (per
    // coordinate) more, and the cache's test passed every box within its margin less the same
    // rounding. Twice that, with factors to spare.
    const auto extent = static_cast<double>((p1 - p0).cwiseAbs().sum() + (cache.p1 - cache.p0).cwiseAbs().sum());
    const double guard = 4e-6 * extent + 128.0 * static_cast<double>(std::numeric_limits<float>::epsilon()) *
                                             (query_scale(p0, p1, cache) + static_cast<double>(cache.test_margin_m)) +
                         1e-9;
    reuse = static_cast<double>(margin) + moved_inf(p0, p1, cache) + guard <= static_cast<double>(cache.test_margin_m);
  }
  if (!reuse) {
    // Fill: the traversal with the extra margin (query_segment_within's test, wider).
    const float wide_margin = margin + cache.extra_margin_m;
    const SegmentBoxTest wide(p0, p1, wide_margin);
    if (!fill_cache(cache, [&wide](const AabbPack4& pack) { return wide.meets4(pack); }, p0, p1)) {
      // More candidates than the cache holds: this query the plain way, the cache left empty.
      return query_segment_within(p0, p1, margin_m, deviation_m, out_ids, out_count);
    }
    cache.test_margin_m = wide_margin;
  }
  const SegmentBoxTest test(p0, p1, margin);
  return answer_from_cache(cache, [&test](const AabbPack4& pack) { return test.meets4(pack); }, p0, p1, margin_m,
                           deviation_m, reuse ? kBoundsPerQuery : 0, out_ids, out_count);
}

core::Status TriangleBvh::query_sphere_cached_within(const Vec3& centre, float radius_m, float deviation_m,
                                                     QueryCache& cache, std::span<std::uint32_t> out_ids,
                                                     std::size_t& out_count) noexcept {
  out_count = 0;
  const Aabb box = Aabb::around_point(centre, radius_m);
  if (!centre.allFinite() || !(radius_m >= 0.0F) || !std::isfinite(radius_m)) {
    return {core::StatusCode::invalid_argument, "triangle bvh: query box non-finite or inverted"};
  }
  if (!ready_) {
    cache.valid = false;
    return core::Status::ok();
  }
  // query_within's box, shrunk by the unused slack (the same floats).
  const float unused = unused_slack(deviation_m);
  const Aabb shrunk{(box.min_m.array() + unused).matrix(), (box.max_m.array() - unused).matrix()};
  // Every box overlapping `shrunk` overlaps the cache's box when that contains it (exact
  // comparisons).
  const bool reuse = cache_current(cache, true) && (cache.box.min_m.array() <= shrunk.min_m.array()).all() &&
                     (shrunk.max_m.array() <= cache.box.max_m.array()).all();
  if (!reuse) {
    const Aabb wide{(shrunk.min_m.array() - cache.extra_margin_m).matrix(),
                    (shrunk.max_m.array() + cache.extra_margin_m).matrix()};
    if (!fill_cache(cache, [&wide](const AabbPack4& pack) { return SegmentBoxTest::overlaps4(pack, wide); }, centre,
                    centre)) {
      return query_within(box, deviation_m, out_ids, out_count);
    }
    cache.box = wide;
  }
  return answer_from_cache(cache, [&shrunk](const AabbPack4& pack) { return SegmentBoxTest::overlaps4(pack, shrunk); },
                           centre, centre, radius_m, deviation_m, reuse ? kBoundsPerQuery : 0, out_ids, out_count);
}

bool TriangleBvh::cache_current(QueryCache& cache, bool sphere) const noexcept {
  const bool current = cache.valid && cache.hierarchy == this && cache.refit == refit_count_ &&
                       cache.slack_m == slack_m_ && cache.sphere == sphere;
  if (current) {
    ++cache.reuses;
  } else {
    cache.valid = false;
    cache.sphere = sphere;
  }
  return current;
}

double TriangleBvh::query_scale(const Vec3& p0, const Vec3& p1, const QueryCache& cache) noexcept {
  // The largest coordinate magnitude of the query, the cached query and the root box (the
  // last two kept by the fill).
  return static_cast<double>(std::max({p0.cwiseAbs().maxCoeff(), p1.cwiseAbs().maxCoeff(), cache.scale_m}));
}

double TriangleBvh::moved_inf(const Vec3& p0, const Vec3& p1, const QueryCache& cache) noexcept {
  const Eigen::Vector3d d0 = p0.cast<double>() - cache.p0.cast<double>();
  const Eigen::Vector3d d1 = p1.cast<double>() - cache.p1.cast<double>();
  return std::max(d0.cwiseAbs().maxCoeff(), d1.cwiseAbs().maxCoeff());
}

template <class Accept4>
bool TriangleBvh::fill_cache(QueryCache& cache, Accept4&& accept4, const Vec3& p0, const Vec3& p1) noexcept {
  cache.valid = false;
  cache.count = 0;
  std::size_t count = 0;
  if (!collect(accept4, cache.ids, count).is_ok()) return false;
  for (std::size_t pack = 0; pack < (count + 3) / 4; ++pack) {
    for (int lane = 0; lane < 4; ++lane) {
      const std::size_t k = 4 * pack + static_cast<std::size_t>(lane);
      if (k < count) {
        const std::uint32_t slot = triangle_lane_[cache.ids[k]];
        cache.packs[pack].copy_lane(lane, leaf_packs_[slot / 4], static_cast<int>(slot % 4));
      } else {
        cache.packs[pack].clear(lane);
      }
    }
  }
  std::fill(cache.below_m.begin(), cache.below_m.begin() + static_cast<std::ptrdiff_t>(count), -1.0);
  cache.count = count;
  cache.hierarchy = this;
  cache.refit = refit_count_;
  cache.slack_m = slack_m_;
  cache.p0 = p0;
  cache.p1 = p1;
  cache.scale_m = std::max({p0.cwiseAbs().maxCoeff(), p1.cwiseAbs().maxCoeff(), bounds().min_m.cwiseAbs().maxCoeff(),
                            bounds().max_m.cwiseAbs().maxCoeff()});
  cache.valid = true;
  ++cache.collections;
  return true;
}

template <class Accept4>
core::Status TriangleBvh::answer_from_cache(QueryCache& cache, Accept4&& accept4, const Vec3& p0, const Vec3& p1,
                                            float reach_m, float deviation_m, int budget,
                                            std::span<std::uint32_t> out_ids, std::size_t& out_count) noexcept {
  // How far the query moved since the cache was filled (Euclidean: corresponding points of
  // the two segments are no farther apart than their ends).
  const double moved = std::max((p0.cast<double>() - cache.p0.cast<double>()).norm(),
                                (p1.cast<double>() - cache.p1.cast<double>()).norm());
  // Every vertex within `deviation` of the reference positions per coordinate (the statement,
  // or the slack, plus the statement's rounding guard), so every point of a triangle within
  // √3 deviation of its reference triangle's. A triangle the narrow phase takes within reach
  // has a float distance below reach_m; that float is within a few ulp of the coordinates of
  // the true distance (1e-4 of them and 1 µm: far more).
  const double deviation = (deviation_m >= 0.0F && deviation_m < slack_m_ ? static_cast<double>(deviation_m)
                                                                          : static_cast<double>(slack_m_)) +
                           static_cast<double>(rounding_guard_m_);
  const double rounding = 1e-6 + 1e-4 * query_scale(p0, p1, cache);
  const double limit = static_cast<double>(reach_m) + std::sqrt(3.0) * deviation + moved + rounding;
  bool truncated = false;
  for (std::size_t pack = 0; pack < (cache.count + 3) / 4 && !truncated; ++pack) {
    unsigned lanes = accept4(cache.packs[pack]);
    while (lanes != 0) {
      const auto lane = static_cast<std::size_t>(std::countr_zero(lanes));
      lanes &= lanes - 1;
      const std::size_t k = 4 * pack + lane;
      const std::uint32_t id = cache.ids[k];
      if (cache.below_m[k] < 0.0 && budget > 0) {
        // Each triangle's bound once per fill, at most `budget` per call (none in the call
        // that fills: every cache fills in the cycle after a refit, already a slow one, and
        // would compute ~10 each). A triangle without its bound yet is kept.
        --budget;
        const std::uint32_t* vertex = triangles_.data() + 3 * static_cast<std::size_t>(id);
        cache.below_m[k] = segment_triangle_distance_below(cache.p0, cache.p1, bvh_vertex(reference_, vertex[0]),
                                                           bvh_vertex(reference_, vertex[1]),
                                                           bvh_vertex(reference_, vertex[2]));
      }
      if (cache.below_m[k] > limit) continue;
      if (out_count == out_ids.size()) {
        truncated = true;
        break;
      }
      out_ids[out_count++] = id;
    }
  }
  if (truncated) return {core::StatusCode::capacity_exceeded, "triangle bvh: query output full"};
  return core::Status::ok();
}

}  // namespace trainer::model
