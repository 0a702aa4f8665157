// SegmentBoxTest (segment_box.hpp): bit for bit the per-box slab test TriangleBvh made before it
// (kept below as the reference, division per axis and the zero-axis branch included), for one
// box and for four at once, on random boxes and on the edge cases: axis-parallel and point
// segments (±0 direction components), a segment starting exactly on a grown face, tiny and
// denormal directions, degenerate and inverted boxes; and the 4-wide box overlap.
#include "trainer/model/segment_box.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <utility>

#include <gtest/gtest.h>

namespace trainer::model {
namespace {

// TriangleBvh's test before segment_box.hpp (query_segment: the segment's grown box, then this).
bool reference_meets(const Vec3& p0, const Vec3& p1, const Aabb& box, float margin) {
  const Aabb around = Aabb::around_segment(p0, p1, margin);
  if (!box.overlaps(around)) return false;
  const Vec3 d = p1 - p0;
  float t_low = 0.0F;
  float t_high = 1.0F;
  for (int axis = 0; axis < 3; ++axis) {
    const float low = box.min_m[axis] - margin;
    const float high = box.max_m[axis] + margin;
    if (d[axis] == 0.0F) {
      if (p0[axis] < low || p0[axis] > high) return false;
      continue;
    }
    const float inverse = 1.0F / d[axis];
    float t1 = (low - p0[axis]) * inverse;
    float t2 = (high - p0[axis]) * inverse;
    if (t1 > t2) std::swap(t1, t2);
    t_low = std::max(t_low, t1);
    t_high = std::min(t_high, t2);
    if (t_low > t_high + SegmentBoxTest::kSlabTolerance) return false;
  }
  return true;
}

void expect_same(const Vec3& p0, const Vec3& p1, float margin, const Aabb (&boxes)[4], int& passes) {
  const SegmentBoxTest test(p0, p1, margin);
  AabbPack4 pack{};
  for (int lane = 0; lane < 4; ++lane) pack.set(lane, boxes[lane]);
  const unsigned mask = test.meets4(pack);
  for (int lane = 0; lane < 4; ++lane) {
    const bool expected = reference_meets(p0, p1, boxes[lane], margin);
    ASSERT_EQ(test.meets(boxes[lane]), expected) << "lane " << lane << " p0 " << p0.transpose() << " p1 "
                                                 << p1.transpose() << " margin " << margin;
    ASSERT_EQ(((mask >> lane) & 1U) != 0, expected) << "4-wide, lane " << lane;
    passes += expected ? 1 : 0;
  }
}

TEST(SegmentBoxTest, IsBitForBitThePerBoxSlabTest) {
  std::mt19937 rng(1919);
  std::uniform_real_distribution<float> u(-0.02F, 0.02F);
  std::uniform_real_distribution<float> size(0.0F, 0.004F);
  std::uniform_int_distribution<int> kind(0, 9);
  int passes = 0;
  int cases = 0;
  for (int trial = 0; trial < 40000; ++trial) {
    Vec3 p0(u(rng), u(rng), u(rng));
    Vec3 p1(u(rng), u(rng), u(rng));
    const int k = kind(rng);
    if (k == 1) p1 = p0;                                              // a point
    if (k == 2) p1[trial % 3] = p0[trial % 3];                        // a zero axis
    if (k == 3) { p1.x() = p0.x(); p1.y() = p0.y(); }                 // parallel to z
    if (k == 4) p1[trial % 3] = std::nextafter(p0[trial % 3], 1.0F);  // a tiny axis
    if (k == 5) p1 = -p0 * 0.0F + p0;                                 // ±0 components
    const float margin = (k == 6) ? 0.0F : size(rng);
    Aabb boxes[4];
    for (Aabb& box : boxes) {
      const Vec3 centre(u(rng), u(rng), u(rng));
      const Vec3 half(size(rng), size(rng), size(rng));
      box = Aabb{centre - half, centre + half};
      const int edge = kind(rng);
      if (edge == 0) box.min_m = box.max_m = centre;  // a point box
      if (edge == 1) {                                // p0 exactly on a grown face, both sides
        const int axis = trial % 3;
        box.min_m[axis] = p0[axis] + margin;
        box.max_m[axis] = box.min_m[axis] + half[axis];
      }
      if (edge == 2) {
        const int axis = (trial + 1) % 3;
        box.max_m[axis] = p0[axis] - margin;
        box.min_m[axis] = box.max_m[axis] - half[axis];
      }
      if (edge == 3) std::swap(box.min_m, box.max_m);  // inverted: never passes
      if (edge == 4) box = Aabb{p0.cwiseMin(p1), p0.cwiseMax(p1)};
    }
    expect_same(p0, p1, margin, boxes, passes);
    ++cases;
  }
  // Zero directions of either sign with p0 on a grown face: 1/−0 would be −∞ (kept +∞ here).
  for (const float zero : {0.0F, -0.0F}) {
    const Vec3 p0(0.001F, 0.002F, 0.003F);
    const Vec3 p1(0.001F + zero, 0.005F, 0.003F + zero);
    const float margin = 0.0005F;
    Aabb boxes[4];
    boxes[0] = Aabb{Vec3(p0.x() + margin, 0.0F, 0.0F), Vec3(0.01F, 0.01F, 0.01F)};
    boxes[1] = Aabb{Vec3(-0.01F, 0.0F, -0.01F), Vec3(p0.x() - margin, 0.01F, p0.z() - margin)};
    boxes[2] = Aabb{Vec3(p0.x() + margin, 0.0F, p0.z() + margin), Vec3(p0.x() + margin, 0.01F, p0.z() + margin)};
    boxes[3] = Aabb{Vec3(0.0011F, 0.0F, 0.0F), Vec3(0.01F, 0.01F, 0.01F)};
    expect_same(p0, p1, margin, boxes, passes);
  }
  // Denormal direction components: an infinite inverse from a non-zero axis.
  {
    const Vec3 p0(0.001F, 0.002F, 0.003F);
    const Vec3 p1(0.001F + std::numeric_limits<float>::denorm_min(), 0.004F,
                  0.003F - std::numeric_limits<float>::denorm_min());
    const float margin = 0.0F;
    Aabb boxes[4];
    boxes[0] = Aabb{Vec3(0.001F, 0.0F, 0.0F), Vec3(0.002F, 0.01F, 0.01F)};
    boxes[1] = Aabb{Vec3(0.0F, 0.0F, 0.003F), Vec3(0.01F, 0.01F, 0.004F)};
    boxes[2] = Aabb{Vec3(0.0F, 0.0F, 0.0F), Vec3(0.001F, 0.01F, 0.003F)};
    boxes[3] = Aabb{Vec3(0.0F, 0.0F, 0.0F), Vec3(0.0009F, 0.01F, 0.01F)};
    expect_same(p0, p1, margin, boxes, passes);
  }
  // Both outcomes are well represented (the test can fail either way).
  EXPECT_GT(passes, cases / 10);
  EXPECT_LT(passes, 4 * cases - cases / 10);
}

TEST(SegmentBoxTest, FourWideOverlapIsAabbOverlaps) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0F, 1.0F);
  std::uniform_real_distribution<float> size(0.0F, 0.5F);
  int overlapping = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const Vec3 centre(u(rng), u(rng), u(rng));
    const Aabb query{centre.array() - size(rng), centre.array() + size(rng)};
    AabbPack4 pack{};
    Aabb boxes[4];
    for (int lane = 0; lane < 4; ++lane) {
      const Vec3 c(u(rng), u(rng), u(rng));
      const Vec3 half(size(rng), size(rng), size(rng));
      boxes[lane] = Aabb{c - half, c + half};
      if (lane == 3 && trial % 2 == 0) boxes[lane] = Aabb{Vec3(query.max_m.x(), c.y(), c.z()), Vec3(1.0F, 1.0F, 1.0F)};
      pack.set(lane, boxes[lane]);
    }
    if (trial % 5 == 0) pack.clear(2);
    const unsigned mask = SegmentBoxTest::overlaps4(pack, query);
    for (int lane = 0; lane < 4; ++lane) {
      const bool expected = (trial % 5 == 0 && lane == 2) ? false : boxes[lane].overlaps(query);
      ASSERT_EQ(((mask >> lane) & 1U) != 0, expected) << "trial " << trial << " lane " << lane;
      overlapping += expected ? 1 : 0;
    }
  }
  EXPECT_GT(overlapping, 1000);
}

}  // namespace
}  // namespace trainer::model
