// Does a segment pass through an axis-aligned box grown by a margin? The test TriangleBvh's
// query_segment() applies to its node and triangle boxes (issue 19; docs/collision.md "Segment
// queries"), set up once per segment so that each box costs no division: the overlap of the segment's own grown box, then
// slab clipping of t in [0, 1], an interval that misses by less than kSlabTolerance counting as
// a hit (rounding). Every point of the segment within `margin` of a point inside the box lies in
// the grown box, so a box that fails holds nothing within `margin` of the segment.
//
// Bit for bit the predicate TriangleBvh used before this header (per box: the inverse 1/d of
// each axis, t = (box bound ∓ margin − p0)·inverse, a zero axis tested as p0 within the grown
// slab): the inverse is the same division made once, and a zero axis takes an infinite inverse
// whose 0·∞ = NaN cases are ignored exactly as the per-axis branch ignored that axis
// (segment_box_test.cpp compares the two on random and edge-case boxes). Monotone in the box:
// a box inside another (as a triangle's inside its leaf's) never passes where the outer fails.
//
// RT path: inline, noexcept, no heap; SSE2 for four boxes at once (struct-of-arrays) where the
// compiler targets it, the same arithmetic lane by lane otherwise.
#pragma once

#include <cstdint>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "trainer/model/broad_phase.hpp"

namespace trainer::model {

// Four boxes, struct-of-arrays (lane k = box k); an unused lane holds an inverted box
// (min +∞, max −∞) that never passes.
struct alignas(16) AabbPack4 {
  float min_x[4];
  float min_y[4];
  float min_z[4];
  float max_x[4];
  float max_y[4];
  float max_z[4];

  void set(int lane, const Aabb& box) noexcept {
    min_x[lane] = box.min_m.x();
    min_y[lane] = box.min_m.y();
    min_z[lane] = box.min_m.z();
    max_x[lane] = box.max_m.x();
    max_y[lane] = box.max_m.y();
    max_z[lane] = box.max_m.z();
  }
  void clear(int lane) noexcept {
    constexpr float kInfinity = std::numeric_limits<float>::infinity();
    min_x[lane] = min_y[lane] = min_z[lane] = kInfinity;
    max_x[lane] = max_y[lane] = max_z[lane] = -kInfinity;
  }
};

class SegmentBoxTest {
 public:
  static constexpr float kSlabTolerance = 1e-6F;

  // p0, p1 finite, margin ≥ 0 finite (the caller checks).
  SegmentBoxTest(const Vec3& p0, const Vec3& p1, float margin) noexcept : margin_(margin) {
    const Vec3 d = p1 - p0;
    for (int axis = 0; axis < 3; ++axis) {
      origin_[axis] = p0[axis];
      // A zero axis (either sign) takes +∞: see the header comment.
      inverse_[axis] = d[axis] == 0.0F ? std::numeric_limits<float>::infinity() : 1.0F / d[axis];
      around_min_[axis] = std::min(p0[axis], p1[axis]) - margin;
      around_max_[axis] = std::max(p0[axis], p1[axis]) + margin;
    }
  }

  // One box.
  bool meets(const Aabb& box) const noexcept {
    float near = 0.0F;
    float far = 1.0F;
    for (int axis = 0; axis < 3; ++axis) {
      if (!(box.min_m[axis] <= around_max_[axis] && around_min_[axis] <= box.max_m[axis])) return false;
      const float t1 = (box.min_m[axis] - margin_ - origin_[axis]) * inverse_[axis];
      const float t2 = (box.max_m[axis] + margin_ - origin_[axis]) * inverse_[axis];
      near = max_keep(lane_min(t2, t1), near);
      far = min_keep(lane_max(t1, t2), far);
    }
    return !(near > far + kSlabTolerance);
  }

  // Bit k set when box k of `pack` passes.
  unsigned meets4(const AabbPack4& pack) const noexcept {
#if defined(__SSE2__)
    __m128 near = _mm_setzero_ps();
    __m128 far = _mm_set1_ps(1.0F);
    __m128 inside = _mm_castsi128_ps(_mm_set1_epi32(-1));
    const float* mins[3] = {pack.min_x, pack.min_y, pack.min_z};
    const float* maxs[3] = {pack.max_x, pack.max_y, pack.max_z};
    const __m128 margin = _mm_set1_ps(margin_);
    for (int axis = 0; axis < 3; ++axis) {
      const __m128 low = _mm_load_ps(mins[axis]);
      const __m128 high = _mm_load_ps(maxs[axis]);
      inside = _mm_and_ps(inside, _mm_and_ps(_mm_cmple_ps(low, _mm_set1_ps(around_max_[axis])),
                                             _mm_cmple_ps(_mm_set1_ps(around_min_[axis]), high)));
      const __m128 origin = _mm_set1_ps(origin_[axis]);
      const __m128 inverse = _mm_set1_ps(inverse_[axis]);
      const __m128 t1 = _mm_mul_ps(_mm_sub_ps(_mm_sub_ps(low, margin), origin), inverse);
      const __m128 t2 = _mm_mul_ps(_mm_sub_ps(_mm_add_ps(high, margin), origin), inverse);
      // _mm_min_ps/_mm_max_ps return the second operand when either is NaN: lane_min/lane_max
      // and max_keep/min_keep below are the same operations.
      near = _mm_max_ps(_mm_min_ps(t2, t1), near);
      far = _mm_min_ps(_mm_max_ps(t1, t2), far);
    }
    const __m128 miss = _mm_cmpgt_ps(near, _mm_add_ps(far, _mm_set1_ps(kSlabTolerance)));
    return static_cast<unsigned>(_mm_movemask_ps(_mm_andnot_ps(miss, inside)));
#else
    unsigned mask = 0;
    for (int lane = 0; lane < 4; ++lane) {
      const Aabb box{Vec3(pack.min_x[lane], pack.min_y[lane], pack.min_z[lane]),
                     Vec3(pack.max_x[lane], pack.max_y[lane], pack.max_z[lane])};
      if (meets(box)) mask |= 1U << lane;
    }
    return mask;
#endif
  }

  // Bit k set when box k of `pack` overlaps `box` (closed boxes, Aabb::overlaps).
  static unsigned overlaps4(const AabbPack4& pack, const Aabb& box) noexcept {
#if defined(__SSE2__)
    __m128 inside = _mm_and_ps(_mm_cmple_ps(_mm_load_ps(pack.min_x), _mm_set1_ps(box.max_m.x())),
                               _mm_cmple_ps(_mm_set1_ps(box.min_m.x()), _mm_load_ps(pack.max_x)));
    inside = _mm_and_ps(inside, _mm_and_ps(_mm_cmple_ps(_mm_load_ps(pack.min_y), _mm_set1_ps(box.max_m.y())),
                                           _mm_cmple_ps(_mm_set1_ps(box.min_m.y()), _mm_load_ps(pack.max_y))));
    inside = _mm_and_ps(inside, _mm_and_ps(_mm_cmple_ps(_mm_load_ps(pack.min_z), _mm_set1_ps(box.max_m.z())),
                                           _mm_cmple_ps(_mm_set1_ps(box.min_m.z()), _mm_load_ps(pack.max_z))));
    return static_cast<unsigned>(_mm_movemask_ps(inside));
#else
    unsigned mask = 0;
    for (int lane = 0; lane < 4; ++lane) {
      const Aabb stored{Vec3(pack.min_x[lane], pack.min_y[lane], pack.min_z[lane]),
                        Vec3(pack.max_x[lane], pack.max_y[lane], pack.max_z[lane])};
      if (stored.overlaps(box)) mask |= 1U << lane;
    }
    return mask;
#endif
  }

 private:
  // SSE's minps/maxps: the second operand when either is NaN (or both equal).
  static float lane_min(float a, float b) noexcept { return a < b ? a : b; }
  static float lane_max(float a, float b) noexcept { return a > b ? a : b; }
  static float max_keep(float value, float kept) noexcept { return value > kept ? value : kept; }
  static float min_keep(float value, float kept) noexcept { return value < kept ? value : kept; }

  float origin_[3];
  float inverse_[3];
  float around_min_[3];
  float around_max_[3];
  float margin_;
};

}  // namespace trainer::model
