// Spatial hash over a deforming triangle mesh; see bucket_grid.hpp.
#include "trainer/model/bucket_grid.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "arena_carve.hpp"

namespace trainer::model {
namespace {

template <class T>
core::Expected<std::span<T>> carve(core::Arena& arena, std::size_t count, std::string_view what) {
  return detail::carve_array<T>(arena, count, what, "bucket grid");
}

bool is_power_of_two(std::uint32_t value) { return value != 0 && (value & (value - 1)) == 0; }

}  // namespace

core::Expected<BucketGrid> BucketGrid::create(const BucketGridSettings& settings,
                                              core::Arena& arena) {
  if (settings.max_triangles == 0 || settings.max_vertices == 0 || settings.max_entries == 0) {
    return core::make_error("bucket grid: max_triangles = " +
                            std::to_string(settings.max_triangles) + ", max_vertices = " +
                            std::to_string(settings.max_vertices) + ", max_entries = " +
                            std::to_string(settings.max_entries) + ": expected all ≥ 1");
  }
  if (!(settings.cell_size_m > 0.0F) || !std::isfinite(settings.cell_size_m)) {
    return core::make_error("bucket grid: cell_size_m = " + std::to_string(settings.cell_size_m) +
                            ": expected a finite length > 0 (about the mean edge length)");
  }
  if (!is_power_of_two(settings.table_size) || settings.table_size > (1U << 30)) {
    return core::make_error("bucket grid: table_size = " + std::to_string(settings.table_size) +
                            ": expected a power of two, 1..2^30");
  }
  BucketGrid grid;
  grid.cell_size_m_ = settings.cell_size_m;
  grid.inverse_cell_size_ = 1.0F / settings.cell_size_m;
  grid.bucket_mask_ = settings.table_size - 1;
  grid.max_vertices_ = settings.max_vertices;
  auto starts = carve<std::uint32_t>(arena, std::size_t{settings.table_size} + 1, "bucket starts");
  if (!starts) return std::move(starts).error();
  auto entries = carve<std::uint32_t>(arena, settings.max_entries, "bucket entries");
  if (!entries) return std::move(entries).error();
  auto cells = carve<CellRange>(arena, settings.max_triangles, "triangle cell ranges");
  if (!cells) return std::move(cells).error();
  auto stamps = carve<std::uint32_t>(arena, settings.max_triangles, "query stamps");
  if (!stamps) return std::move(stamps).error();
  auto boxes = carve<Aabb>(arena, settings.max_triangles, "triangle boxes");
  if (!boxes) return std::move(boxes).error();
  grid.bucket_start_ = starts.value();
  grid.entries_ = entries.value();
  grid.triangle_cells_ = cells.value();
  grid.stamps_ = stamps.value();
  grid.triangle_boxes_ = boxes.value();
  return grid;
}

std::int32_t BucketGrid::cell_index(float coordinate_m) const noexcept {
  // Clamp first (so the conversion is defined), then floor by truncation and a correction for
  // negative fractions: std::floor is a libm call on the x86-64 baseline (no SSE4.1 round),
  // and this runs 6 times per triangle per rebuild.
  constexpr auto kLimit = static_cast<float>(kMaxCellIndex);
  const float cell = std::clamp(coordinate_m * inverse_cell_size_, -kLimit, kLimit);
  const auto truncated = static_cast<std::int32_t>(cell);
  return static_cast<float>(truncated) > cell ? truncated - 1 : truncated;
}

BucketGrid::CellRange BucketGrid::cells_of(const Vec3& min_m, const Vec3& max_m) const noexcept {
  CellRange range{};
  for (int axis = 0; axis < 3; ++axis) {
    range.min[axis] = cell_index(min_m[axis]);
    range.max[axis] = cell_index(max_m[axis]);
  }
  return range;
}

std::uint32_t BucketGrid::bucket_of(std::int32_t i, std::int32_t j, std::int32_t k) const noexcept {
  // Teschner et al. 2003 primes; unsigned arithmetic wraps by definition.
  const std::uint32_t hash = (static_cast<std::uint32_t>(i) * 73856093U) ^
                             (static_cast<std::uint32_t>(j) * 19349663U) ^
                             (static_cast<std::uint32_t>(k) * 83492791U);
  return hash & bucket_mask_;
}

namespace {
std::uint64_t cell_count(const std::int32_t* min, const std::int32_t* max) noexcept {
  std::uint64_t count = 1;
  for (int axis = 0; axis < 3; ++axis) {
    count *= static_cast<std::uint64_t>(static_cast<std::int64_t>(max[axis]) - min[axis] + 1);
  }
  return count;
}
}  // namespace

void BucketGrid::clear() noexcept {
  triangle_count_ = 0;
  entry_count_ = 0;
  bounds_ = Aabb{Vec3::Constant(1.0F), Vec3::Constant(-1.0F)};
  std::fill(bucket_start_.begin(), bucket_start_.end(), 0U);
}

core::Status BucketGrid::rebuild(std::span<const float> positions_m,
                                 std::span<const std::uint32_t> triangles, float slack_m) noexcept {
  clear();
  required_entries_ = 0;
  if (positions_m.size() % 3 != 0 || triangles.size() % 3 != 0) {
    return {core::StatusCode::invalid_argument, "bucket grid: positions or triangles not 3 per item"};
  }
  const std::size_t vertex_count = positions_m.size() / 3;
  const std::size_t triangle_count = triangles.size() / 3;
  if (vertex_count > max_vertices_ || triangle_count > triangle_cells_.size()) {
    return {core::StatusCode::capacity_exceeded, "bucket grid: more vertices or triangles than sized"};
  }
  if (!(slack_m >= 0.0F) || !std::isfinite(slack_m)) {
    return {core::StatusCode::invalid_argument, "bucket grid: slack negative or non-finite"};
  }
  for (const float value : positions_m) {
    if (!std::isfinite(value)) return {core::StatusCode::numeric_error, "bucket grid: non-finite vertex"};
  }
  // Pass 1: each triangle's cell range and the total number of (triangle, cell) pairs.
  std::uint64_t required = 0;
  for (std::size_t t = 0; t < triangle_count; ++t) {
    Vec3 low = Vec3::Constant(INFINITY);
    Vec3 high = Vec3::Constant(-INFINITY);
    for (std::size_t corner = 0; corner < 3; ++corner) {
      const std::uint32_t vertex = triangles[3 * t + corner];
      if (vertex >= vertex_count) {
        return {core::StatusCode::invalid_argument, "bucket grid: triangle vertex index out of range"};
      }
      const Vec3 p(positions_m[3 * vertex], positions_m[3 * vertex + 1], positions_m[3 * vertex + 2]);
      low = low.cwiseMin(p);
      high = high.cwiseMax(p);
    }
    const Aabb stored{(low.array() - slack_m).matrix(), (high.array() + slack_m).matrix()};
    triangle_boxes_[t] = stored;
    triangle_cells_[t] = cells_of(stored.min_m, stored.max_m);
    if (t == 0) {
      bounds_ = stored;
    } else {
      bounds_.min_m = bounds_.min_m.cwiseMin(stored.min_m);
      bounds_.max_m = bounds_.max_m.cwiseMax(stored.max_m);
    }
    required += cell_count(triangle_cells_[t].min, triangle_cells_[t].max);
  }
  required_entries_ = static_cast<std::size_t>(std::min<std::uint64_t>(required, SIZE_MAX));
  if (required > entries_.size()) {
    bounds_ = Aabb{Vec3::Constant(1.0F), Vec3::Constant(-1.0F)};
    return {core::StatusCode::capacity_exceeded, "bucket grid: more (triangle, cell) pairs than max_entries"};
  }
  // Pass 2: count per bucket (shifted by one), prefix sums → bucket_start_[b] = first entry.
  const auto for_each_cell = [this](const CellRange& range, auto&& visit) {
    for (std::int32_t i = range.min[0]; i <= range.max[0]; ++i) {
      for (std::int32_t j = range.min[1]; j <= range.max[1]; ++j) {
        for (std::int32_t k = range.min[2]; k <= range.max[2]; ++k) visit(bucket_of(i, j, k));
      }
    }
  };
  for (std::size_t t = 0; t < triangle_count; ++t) {
    for_each_cell(triangle_cells_[t], [this](std::uint32_t bucket) { ++bucket_start_[bucket + 1]; });
  }
  for (std::size_t b = 1; b < bucket_start_.size(); ++b) bucket_start_[b] += bucket_start_[b - 1];
  // Pass 3: fill, using bucket_start_[b] as the cursor of bucket b; afterwards it holds the
  // end of b, so shifting right by one restores the starts.
  for (std::size_t t = 0; t < triangle_count; ++t) {
    const auto id = static_cast<std::uint32_t>(t);
    for_each_cell(triangle_cells_[t], [this, id](std::uint32_t bucket) {
      entries_[bucket_start_[bucket]++] = id;
    });
  }
  for (std::size_t b = bucket_start_.size() - 1; b > 0; --b) bucket_start_[b] = bucket_start_[b - 1];
  bucket_start_[0] = 0;
  triangle_count_ = triangle_count;
  entry_count_ = static_cast<std::size_t>(required);
  return core::Status::ok();
}

bool BucketGrid::collect_bucket(std::uint32_t bucket, const Aabb& box, std::span<std::uint32_t> out_ids,
                                std::size_t& out_count) noexcept {
  for (std::uint32_t e = bucket_start_[bucket]; e < bucket_start_[bucket + 1]; ++e) {
    const std::uint32_t id = entries_[e];
    if (stamps_[id] == stamp_) continue;
    stamps_[id] = stamp_;  // tested once per query, whatever the answer
    if (!triangle_boxes_[id].overlaps(box)) {
      ++rejected_count_;
      continue;
    }
    if (out_count == out_ids.size()) return false;
    ++passed_count_;
    out_ids[out_count++] = id;
  }
  return true;
}

core::Status BucketGrid::query(const Aabb& box, std::span<std::uint32_t> out_ids,
                               std::size_t& out_count) noexcept {
  out_count = 0;
  if (!box.min_m.allFinite() || !box.max_m.allFinite() ||
      (box.min_m.array() > box.max_m.array()).any()) {
    return {core::StatusCode::invalid_argument, "bucket grid: query box non-finite or inverted"};
  }
  if (triangle_count_ == 0 || !bounds_.overlaps(box)) return core::Status::ok();
  if (++stamp_ == 0) {  // wrapped: forget every stamp
    std::fill(stamps_.begin(), stamps_.end(), 0U);
    stamp_ = 1;
  }
  const CellRange range = cells_of(box.min_m, box.max_m);
  const core::Status truncated{core::StatusCode::capacity_exceeded, "bucket grid: query output full"};
  if (cell_count(range.min, range.max) > table_size()) {
    for (std::uint32_t bucket = 0; bucket <= bucket_mask_; ++bucket) {
      if (!collect_bucket(bucket, box, out_ids, out_count)) return truncated;
    }
    return core::Status::ok();
  }
  for (std::int32_t i = range.min[0]; i <= range.max[0]; ++i) {
    for (std::int32_t j = range.min[1]; j <= range.max[1]; ++j) {
      for (std::int32_t k = range.min[2]; k <= range.max[2]; ++k) {
        if (!collect_bucket(bucket_of(i, j, k), box, out_ids, out_count)) return truncated;
      }
    }
  }
  return core::Status::ok();
}

}  // namespace trainer::model
