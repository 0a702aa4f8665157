// Bounding-volume hierarchy over a fixed triangle set, refitted; see triangle_bvh.hpp.
#include "trainer/model/triangle_bvh.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "arena_carve.hpp"
#include "triangle_bvh_internal.hpp"

#if defined(__SSE2__)
#include <xmmintrin.h>
#endif

namespace trainer::model {
using bvh_detail::bvh_vertex;
using bvh_detail::carve_bvh;

namespace {

const Aabb kEmptyBox{Vec3::Constant(1.0F), Vec3::Constant(-1.0F)};  // inverted: overlaps nothing

// Setup-path recursion state: the nodes are appended depth-first.
struct BvhBuilder {
  std::span<std::uint32_t> order;
  std::vector<Vec3> centroids;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> nodes;  // (first | right child, count)
  std::uint32_t leaf_size = 4;
  std::size_t depth = 0;

  void build(std::uint32_t first, std::uint32_t count, std::size_t level) {
    depth = std::max(depth, level + 1);
    const std::size_t index = nodes.size();
    nodes.emplace_back(first, count);
    if (count <= leaf_size) return;
    Vec3 low = Vec3::Constant(INFINITY);
    Vec3 high = Vec3::Constant(-INFINITY);
    for (std::uint32_t i = first; i < first + count; ++i) {
      low = low.cwiseMin(centroids[order[i]]);
      high = high.cwiseMax(centroids[order[i]]);
    }
    int axis = 0;
    (high - low).maxCoeff(&axis);
    const std::uint32_t half = count / 2;
    // Ties broken by id, so the hierarchy does not depend on the library's nth_element.
    std::nth_element(order.begin() + first, order.begin() + first + half, order.begin() + first + count,
                     [&](std::uint32_t x, std::uint32_t y) {
                       const float cx = centroids[x][axis];
                       const float cy = centroids[y][axis];
                       return cx < cy || (cx == cy && x < y);
                     });
    nodes[index].second = 0;
    build(first, half, level + 1);
    nodes[index].first = static_cast<std::uint32_t>(nodes.size());  // the right child
    build(first + half, count - half, level + 1);
  }
};

// The wide tree over the binary one (setup path): a wide node takes the binary node's children,
// each replaced by its own two children when it is internal; a leaf's triangles go into packs
// of 4 (lanes past its count unused).
template <class WideNode>
struct WideBuilder {
  const std::vector<std::pair<std::uint32_t, std::uint32_t>>& binary;
  std::span<const std::uint32_t> order;
  std::vector<WideNode> nodes;
  std::vector<std::uint32_t> pack_ids;  // kUnusedLane past a leaf's count
  std::size_t depth = 0;

  bool leaf(std::uint32_t n) const { return binary[n].second > 0; }

  std::uint32_t build(std::uint32_t n, std::size_t level) {
    depth = std::max(depth, level + 1);
    std::uint32_t lanes[4];
    std::uint32_t used = 0;
    if (leaf(n)) {
      lanes[used++] = n;
    } else {
      for (const std::uint32_t child : {n + 1, binary[n].first}) {
        if (leaf(child)) {
          lanes[used++] = child;
        } else {
          lanes[used++] = child + 1;
          lanes[used++] = binary[child].first;
        }
      }
    }
    const auto index = static_cast<std::uint32_t>(nodes.size());
    nodes.emplace_back();
    nodes[index].used = used;
    for (std::uint32_t k = 0; k < used; ++k) {
      const std::uint32_t lane = lanes[k];
      nodes[index].binary[k] = lane;
      if (leaf(lane)) {
        const std::uint32_t first = binary[lane].first;
        const std::uint32_t count = binary[lane].second;
        const std::uint32_t packs = (count + 3) / 4;
        nodes[index].child[k] = static_cast<std::uint32_t>(pack_ids.size() / 4);
        nodes[index].packs[k] = packs;
        for (std::uint32_t i = 0; i < 4 * packs; ++i) pack_ids.push_back(i < count ? order[first + i] : kUnusedLane);
      } else {
        const std::uint32_t child = build(lane, level + 1);
        nodes[index].child[k] = child;
        nodes[index].packs[k] = 0;
      }
    }
    return index;
  }

  static constexpr std::uint32_t kUnusedLane = 0xFFFFFFFFU;
};

}  // namespace

core::Expected<TriangleBvh> TriangleBvh::create(std::span<const float> positions_m,
                                                std::span<const std::uint32_t> triangles,
                                                core::Arena& arena, std::uint32_t leaf_size) {
  if (positions_m.size() % 3 != 0 || triangles.size() % 3 != 0 || triangles.empty()) {
    return core::make_error("triangle bvh: " + std::to_string(positions_m.size()) + " coordinates and " +
                            std::to_string(triangles.size()) +
                            " triangle indices: expected 3 per vertex and 3 per triangle, at least one triangle");
  }
  if (leaf_size == 0 || leaf_size > 64) {
    return core::make_error("triangle bvh: leaf_size = " + std::to_string(leaf_size) + ": expected 1..64");
  }
  const std::size_t vertex_count = positions_m.size() / 3;
  const std::size_t triangle_count = triangles.size() / 3;
  if (triangle_count >= (std::size_t{1} << 31)) {
    return core::make_error("triangle bvh: " + std::to_string(triangle_count) + " triangles: expected < 2^31");
  }
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    if (triangles[i] >= vertex_count) {
      return core::make_error("triangle bvh: triangle " + std::to_string(i / 3) + " vertex index " +
                              std::to_string(triangles[i]) + ": expected < " + std::to_string(vertex_count));
    }
  }
  for (std::size_t i = 0; i < positions_m.size(); ++i) {
    if (!std::isfinite(positions_m[i])) {
      return core::make_error("triangle bvh: vertex " + std::to_string(i / 3) + " not finite");
    }
  }
  BvhBuilder builder;
  auto order = carve_bvh<std::uint32_t>(arena, triangle_count, "bvh triangle order");
  if (!order) return std::move(order).error();
  builder.order = order.value();
  builder.leaf_size = leaf_size;
  builder.centroids.resize(triangle_count);
  for (std::size_t t = 0; t < triangle_count; ++t) {
    builder.order[t] = static_cast<std::uint32_t>(t);
    builder.centroids[t] = (bvh_vertex(positions_m, triangles[3 * t]) + bvh_vertex(positions_m, triangles[3 * t + 1]) +
                            bvh_vertex(positions_m, triangles[3 * t + 2])) /
                           3.0F;
  }
  builder.nodes.reserve(2 * triangle_count);
  builder.build(0, static_cast<std::uint32_t>(triangle_count), 0);
  if (builder.depth > kMaxDepth) {
    return core::make_error("triangle bvh: depth " + std::to_string(builder.depth) + ": expected <= " +
                            std::to_string(kMaxDepth));
  }

  TriangleBvh bvh;
  auto nodes = carve_bvh<Node>(arena, builder.nodes.size(), "bvh nodes");
  if (!nodes) return std::move(nodes).error();
  auto copy = carve_bvh<std::uint32_t>(arena, triangles.size(), "bvh triangles");
  if (!copy) return std::move(copy).error();
  // One float more than 3n: refit_boxes loads each vertex as 4 floats.
  auto reference = carve_bvh<float>(arena, positions_m.size() + 1, "bvh reference positions");
  if (!reference) return std::move(reference).error();
  auto bits = carve_bvh<std::uint64_t>(arena, (triangle_count + 63) / 64, "bvh hit bits");
  if (!bits) return std::move(bits).error();
  WideBuilder<WideNode> wide{builder.nodes, builder.order, {}, {}, 0};
  wide.nodes.reserve(builder.nodes.size());
  (void)wide.build(0, 0);
  auto wide_nodes = carve_bvh<WideNode>(arena, wide.nodes.size(), "bvh wide nodes");
  if (!wide_nodes) return std::move(wide_nodes).error();
  auto packs = carve_bvh<AabbPack4>(arena, wide.pack_ids.size() / 4, "bvh leaf packs");
  if (!packs) return std::move(packs).error();
  auto pack_ids = carve_bvh<std::uint32_t>(arena, wide.pack_ids.size(), "bvh pack ids");
  if (!pack_ids) return std::move(pack_ids).error();
  auto triangle_lane = carve_bvh<std::uint32_t>(arena, triangle_count, "bvh triangle lanes");
  if (!triangle_lane) return std::move(triangle_lane).error();
  bvh.nodes_ = nodes.value();
  for (std::size_t n = 0; n < builder.nodes.size(); ++n) {
    bvh.nodes_[n] = Node{kEmptyBox, builder.nodes[n].first, builder.nodes[n].second};
  }
  bvh.order_ = builder.order;
  bvh.triangles_ = copy.value();
  std::copy(triangles.begin(), triangles.end(), bvh.triangles_.begin());
  bvh.reference_ = reference.value().first(positions_m.size());
  reference.value().back() = 0.0F;
  bvh.hit_bits_ = bits.value();
  bvh.wide_ = wide_nodes.value();
  std::copy(wide.nodes.begin(), wide.nodes.end(), bvh.wide_.begin());
  for (WideNode& node : bvh.wide_) {
    for (int lane = 0; lane < 4; ++lane) node.boxes.clear(lane);
  }
  bvh.leaf_packs_ = packs.value();
  for (AabbPack4& pack : bvh.leaf_packs_) {
    for (int lane = 0; lane < 4; ++lane) pack.clear(lane);
  }
  bvh.pack_ids_ = pack_ids.value();
  auto pack_box = carve_bvh<BoxQuads>(arena, bvh.leaf_packs_.size(), "bvh pack boxes");
  if (!pack_box) return std::move(pack_box).error();
  auto wide_box = carve_bvh<BoxQuads>(arena, bvh.wide_.size(), "bvh wide node boxes");
  if (!wide_box) return std::move(wide_box).error();
  bvh.pack_box_ = pack_box.value();
  bvh.wide_box_ = wide_box.value();
  std::copy(wide.pack_ids.begin(), wide.pack_ids.end(), bvh.pack_ids_.begin());
  bvh.triangle_lane_ = triangle_lane.value();
  for (std::size_t k = 0; k < wide.pack_ids.size(); ++k) {
    if (wide.pack_ids[k] < triangle_count) bvh.triangle_lane_[wide.pack_ids[k]] = static_cast<std::uint32_t>(k);
  }
  std::fill(bvh.hit_bits_.begin(), bvh.hit_bits_.end(), std::uint64_t{0});
  bvh.depth_ = builder.depth;
  if (const core::Status status = bvh.refit(positions_m, 0.0F); !status.is_ok()) {
    return core::make_error(std::string("triangle bvh: first refit: ") + status.detail());
  }
  return bvh;
}

namespace {

// Box arithmetic of refit_boxes, 4 floats at a time (SSE2) or lane by lane: x y z and a fourth
// lane that is never stored. min/max keep std::min/std::max's operand order (b < a ? b : a),
// so the boxes are the bits the per-triangle Eigen code stored.
#if defined(__SSE2__)
using Quad = __m128;
inline Quad quad_load(const float* p) noexcept { return _mm_loadu_ps(p); }
inline Quad quad_min(Quad a, Quad b) noexcept { return _mm_min_ps(b, a); }
inline Quad quad_max(Quad a, Quad b) noexcept { return _mm_max_ps(b, a); }
inline Quad quad_add(Quad a, float s) noexcept { return _mm_add_ps(a, _mm_set1_ps(s)); }
inline Quad quad_sub(Quad a, float s) noexcept { return _mm_sub_ps(a, _mm_set1_ps(s)); }
inline Quad quad_fill(float s) noexcept { return _mm_set1_ps(s); }
inline void quad_store(float* p, Quad a) noexcept { _mm_store_ps(p, a); }
inline void transpose_quads(Quad& a, Quad& b, Quad& c, Quad& d) noexcept { _MM_TRANSPOSE4_PS(a, b, c, d); }
#else
struct Quad {
  float v[4];
};
inline Quad quad_load(const float* p) noexcept { return {{p[0], p[1], p[2], p[3]}}; }
inline Quad quad_min(Quad a, Quad b) noexcept {
  for (int k = 0; k < 4; ++k) a.v[k] = std::min(a.v[k], b.v[k]);
  return a;
}
inline Quad quad_max(Quad a, Quad b) noexcept {
  for (int k = 0; k < 4; ++k) a.v[k] = std::max(a.v[k], b.v[k]);
  return a;
}
inline Quad quad_add(Quad a, float s) noexcept {
  for (float& x : a.v) x = x + s;
  return a;
}
inline Quad quad_sub(Quad a, float s) noexcept {
  for (float& x : a.v) x = x - s;
  return a;
}
inline Quad quad_fill(float s) noexcept { return {{s, s, s, s}}; }
inline void quad_store(float* p, Quad a) noexcept {
  for (int k = 0; k < 4; ++k) p[k] = a.v[k];
}
inline void transpose_quads(Quad& a, Quad& b, Quad& c, Quad& d) noexcept {
  Quad* rows[4] = {&a, &b, &c, &d};
  for (int i = 0; i < 4; ++i) {
    for (int j = i + 1; j < 4; ++j) std::swap(rows[i]->v[j], rows[j]->v[i]);
  }
}
#endif

}  // namespace

void TriangleBvh::refit_boxes() noexcept {
  // Straight into the traversal's arrays (issue 19: the per-triangle Aabb array, the binary
  // nodes' boxes and their lane-by-lane copies into the 4-wide tree took 4.8 µs for the duct's
  // 640 triangles, scalar stores read back at once). Boxes are kept as two quads (x y z, and a
  // fourth lane never used) and transposed into the packs' lanes. Every box is a min/max of the
  // same values as before (exact: any order gives the same bits), each triangle's grown by the
  // slack with the same subtraction and addition.
  const float* positions = reference_.data();  // 3n + 1 floats: a vertex loads as 4
  const float slack = slack_m_;
  const float kInfinity = std::numeric_limits<float>::infinity();
  const Quad empty_low = quad_fill(kInfinity);
  const Quad empty_high = quad_fill(-kInfinity);
  const std::size_t triangle_count = triangles_.size() / 3;
  for (std::size_t pack = 0; pack < leaf_packs_.size(); ++pack) {
    Quad low[4];
    Quad high[4];
    for (std::size_t lane = 0; lane < 4; ++lane) {
      const std::uint32_t id = pack_ids_[4 * pack + lane];
      if (id >= triangle_count) {  // unused lane: inverted
        low[lane] = empty_low;
        high[lane] = empty_high;
        continue;
      }
      const std::uint32_t* corner = triangles_.data() + 3 * static_cast<std::size_t>(id);
      const Quad a = quad_load(positions + 3 * static_cast<std::size_t>(corner[0]));
      const Quad b = quad_load(positions + 3 * static_cast<std::size_t>(corner[1]));
      const Quad c = quad_load(positions + 3 * static_cast<std::size_t>(corner[2]));
      low[lane] = quad_sub(quad_min(quad_min(a, b), c), slack);
      high[lane] = quad_add(quad_max(quad_max(a, b), c), slack);
    }
    BoxQuads& box = pack_box_[pack];
    quad_store(box.low, quad_min(quad_min(low[0], low[1]), quad_min(low[2], low[3])));
    quad_store(box.high, quad_max(quad_max(high[0], high[1]), quad_max(high[2], high[3])));
    transpose_quads(low[0], low[1], low[2], low[3]);
    transpose_quads(high[0], high[1], high[2], high[3]);
    AabbPack4& out = leaf_packs_[pack];
    quad_store(out.min_x, low[0]);
    quad_store(out.min_y, low[1]);
    quad_store(out.min_z, low[2]);
    quad_store(out.max_x, high[0]);
    quad_store(out.max_y, high[1]);
    quad_store(out.max_z, high[2]);
  }
  // The wide nodes bottom-up (a node's children follow it): a lane's box is the union of its
  // leaf's packs or of its child node's lanes; unused lanes stay inverted.
  for (std::size_t n = wide_.size(); n-- > 0;) {
    WideNode& wide = wide_[n];
    Quad low[4] = {empty_low, empty_low, empty_low, empty_low};
    Quad high[4] = {empty_high, empty_high, empty_high, empty_high};
    for (std::uint32_t lane = 0; lane < wide.used; ++lane) {
      const std::uint32_t child = wide.child[lane];
      if (wide.packs[lane] == 0) {
        const BoxQuads& node = wide_box_[child];
        low[lane] = quad_load(node.low);
        high[lane] = quad_load(node.high);
      } else {
        low[lane] = quad_load(pack_box_[child].low);
        high[lane] = quad_load(pack_box_[child].high);
        for (std::uint32_t pack = child + 1; pack < child + wide.packs[lane]; ++pack) {
          low[lane] = quad_min(low[lane], quad_load(pack_box_[pack].low));
          high[lane] = quad_max(high[lane], quad_load(pack_box_[pack].high));
        }
      }
    }
    BoxQuads& box = wide_box_[n];
    quad_store(box.low, quad_min(quad_min(low[0], low[1]), quad_min(low[2], low[3])));
    quad_store(box.high, quad_max(quad_max(high[0], high[1]), quad_max(high[2], high[3])));
    transpose_quads(low[0], low[1], low[2], low[3]);
    transpose_quads(high[0], high[1], high[2], high[3]);
    quad_store(wide.boxes.min_x, low[0]);
    quad_store(wide.boxes.min_y, low[1]);
    quad_store(wide.boxes.min_z, low[2]);
    quad_store(wide.boxes.max_x, high[0]);
    quad_store(wide.boxes.max_y, high[1]);
    quad_store(wide.boxes.max_z, high[2]);
  }
  // The root's box (bounds()): the union of the top node's lanes.
  const BoxQuads& top = wide_box_[0];
  nodes_[0].box = Aabb{Vec3(top.low[0], top.low[1], top.low[2]), Vec3(top.high[0], top.high[1], top.high[2])};
  // A stored bound is fl(reference ∓ slack), a test's fl(bound ∓ margin − p0) or fl(query ±
  // unused slack): a few ulp of the coordinates each; the guard of the stated-deviation queries
  // is 16 of them, with the coordinates' scale from the root box.
  const Aabb& root = nodes_[0].box;
  rounding_guard_m_ = 16.0F * std::numeric_limits<float>::epsilon() *
                      (std::max(root.min_m.cwiseAbs().maxCoeff(), root.max_m.cwiseAbs().maxCoeff()) + slack);
}

void TriangleBvh::keep_warm(std::size_t lines) noexcept {
  const std::span<const std::byte> regions[] = {
      std::as_bytes(reference_), std::as_bytes(triangles_), std::as_bytes(pack_ids_),
      std::as_bytes(leaf_packs_), std::as_bytes(pack_box_),  std::as_bytes(wide_),
      std::as_bytes(wide_box_)};
  constexpr std::size_t kRegions = std::size(regions);
  for (std::size_t k = 0; k < lines; ++k) {
    if (warm_region_ >= kRegions) warm_region_ = 0;
    const std::span<const std::byte> region = regions[warm_region_];
    if (64 * warm_line_ < region.size()) __builtin_prefetch(region.data() + 64 * warm_line_, 0, 2);
    if (64 * ++warm_line_ >= region.size()) {
      warm_line_ = 0;
      ++warm_region_;
    }
  }
}

core::Status TriangleBvh::refit(std::span<const float> positions_m, float slack_m) noexcept {
  ++refit_calls_;
  if (positions_m.size() != reference_.size()) {
    ready_ = false;
    return {core::StatusCode::invalid_argument, "triangle bvh: positions not 3 per vertex of the mesh"};
  }
  if (!(slack_m >= 0.0F) || !std::isfinite(slack_m)) {
    ready_ = false;
    return {core::StatusCode::invalid_argument, "triangle bvh: slack negative or non-finite"};
  }
  // Largest coordinate change since the last refit (Eigen's packet reductions: the pass is
  // vectorized, ~4 coordinates per instruction on SSE2).
  const Eigen::Map<const Eigen::ArrayXf> now(positions_m.data(), static_cast<Eigen::Index>(positions_m.size()));
  const Eigen::Map<const Eigen::ArrayXf> before(reference_.data(), static_cast<Eigen::Index>(reference_.size()));
  // x − x is 0 for a finite x and NaN otherwise: the sum is 0 exactly when every coordinate is
  // finite (vectorized; allFinite() is a scalar loop, 1,008 compares on the duct).
  if (!((now - now).sum() == 0.0F)) {
    ready_ = false;
    return {core::StatusCode::numeric_error, "triangle bvh: non-finite vertex"};
  }
  if (ready_ && slack_m == slack_m_) {
    const float deviation = (now - before).abs().maxCoeff();
    if (deviation <= slack_m) {
      last_deviation_m_ = deviation;
      return core::Status::ok();
    }
  }
  last_deviation_m_ = 0.0F;
  std::copy(positions_m.begin(), positions_m.end(), reference_.begin());
  slack_m_ = slack_m;
  refit_boxes();
  ready_ = true;
  ++refit_count_;
  return core::Status::ok();
}

core::Status TriangleBvh::query(const Aabb& box, std::span<std::uint32_t> out_ids,
                                std::size_t& out_count) noexcept {
  out_count = 0;
  if (!box.min_m.allFinite() || !box.max_m.allFinite() || (box.min_m.array() > box.max_m.array()).any()) {
    return {core::StatusCode::invalid_argument, "triangle bvh: query box non-finite or inverted"};
  }
  return collect([&box](const AabbPack4& pack) { return SegmentBoxTest::overlaps4(pack, box); }, out_ids,
                 out_count);
}

core::Status TriangleBvh::query_segment(const Vec3& p0, const Vec3& p1, float margin_m,
                                        std::span<std::uint32_t> out_ids, std::size_t& out_count) noexcept {
  out_count = 0;
  if (!p0.allFinite() || !p1.allFinite() || !(margin_m >= 0.0F) || !std::isfinite(margin_m)) {
    return {core::StatusCode::invalid_argument, "triangle bvh: segment non-finite or margin negative"};
  }
  // The margin grown a little so that rounding in the clipping never drops a triangle at
  // exactly margin_m; the segment's own box first (cheap, and exact for a degenerate segment).
  const float margin = margin_m * (1.0F + 1e-5F) + 1e-9F;
  const SegmentBoxTest test(p0, p1, margin);
  return collect([&test](const AabbPack4& pack) { return test.meets4(pack); }, out_ids, out_count);
}

core::Status TriangleBvh::query_segment_within(const Vec3& p0, const Vec3& p1, float margin_m, float deviation_m,
                                               std::span<std::uint32_t> out_ids, std::size_t& out_count) noexcept {
  out_count = 0;
  if (!p0.allFinite() || !p1.allFinite() || !(margin_m >= 0.0F) || !std::isfinite(margin_m)) {
    return {core::StatusCode::invalid_argument, "triangle bvh: segment non-finite or margin negative"};
  }
  if (!ready_) return core::Status::ok();
  const float margin = margin_m * (1.0F + 1e-5F) + 1e-9F - unused_slack(deviation_m);
  const SegmentBoxTest test(p0, p1, margin);
  return collect([&test](const AabbPack4& pack) { return test.meets4(pack); }, out_ids, out_count);
}

float TriangleBvh::unused_slack(float deviation_m) const noexcept {
  if (!(deviation_m >= 0.0F && deviation_m < slack_m_)) return 0.0F;
  return std::max(0.0F, (slack_m_ - deviation_m) - rounding_guard_m_);
}

core::Status TriangleBvh::query_within(const Aabb& box, float deviation_m, std::span<std::uint32_t> out_ids,
                                       std::size_t& out_count) noexcept {
  out_count = 0;
  if (!box.min_m.allFinite() || !box.max_m.allFinite() || (box.min_m.array() > box.max_m.array()).any()) {
    return {core::StatusCode::invalid_argument, "triangle bvh: query box non-finite or inverted"};
  }
  if (!ready_) return core::Status::ok();
  // A stored box shrunk by u overlaps `box` exactly when the stored box overlaps `box` shrunk
  // by u, even where that inverts it (each axis: min + u ≤ q_max ⇔ min ≤ q_max − u).
  const float unused = unused_slack(deviation_m);
  const Aabb shrunk{(box.min_m.array() + unused).matrix(), (box.max_m.array() - unused).matrix()};
  return collect([&shrunk](const AabbPack4& pack) { return SegmentBoxTest::overlaps4(pack, shrunk); }, out_ids,
                 out_count);
}

}  // namespace trainer::model
