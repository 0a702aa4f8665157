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

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <Eigen/Geometry>

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
  void copy_lane(int lane, const AabbPack4& from, int from_lane) noexcept {
    min_x[lane] = from.min_x[from_lane];
    min_y[lane] = from.min_y[from_lane];
    min_z[lane] = from.min_z[from_lane];
    max_x[lane] = from.max_x[from_lane];
    max_y[lane] = from.max_y[from_lane];
    max_z[lane] = from.max_z[from_lane];
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

// A lower bound of the Euclidean distance between the segment p0–p1 and the triangle abc
// (float inputs, converted exactly), computed in double: the distance between two convex sets
// is reached at an end of the segment, on an edge of the triangle, or is 0 where the segment
// crosses it, so it is the least of the three segment–edge distances, each end's distance to
// the triangle's plane when its foot lies inside (barycentric weights ≥ −1e-9: a foot a
// hair outside still gives a plane distance, which never exceeds the true one), and 0 for a
// crossing (idem); a triangle whose normal is 0 in double is its edges. Less 1e-7 m, far more
// than double rounding on metre-scale input. TriangleBvh's cached segment queries
// (docs/collision.md "Cached queries") keep a triangle while this bound, taken once
// per cache against the hierarchy's reference positions, allows it within reach.
namespace segment_bound_detail {
using Vec3d = Eigen::Vector3d;
inline double segment_segment_distance(const Vec3d& p1, const Vec3d& q1, const Vec3d& p2, const Vec3d& q2) noexcept {
  // Ericson, Real-Time Collision Detection 5.1.9: each parameter optimal given the other.
  const Vec3d d1 = q1 - p1;
  const Vec3d d2 = q2 - p2;
  const Vec3d r = p1 - p2;
  const double a = d1.squaredNorm();
  const double e = d2.squaredNorm();
  const double f = d2.dot(r);
  double s = 0.0;
  double t = 0.0;
  if (a <= 0.0 && e <= 0.0) return r.norm();
  if (a <= 0.0) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= 0.0) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2);
      const double denom = a * e - b * b;
      s = denom > 0.0 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0.0) {
        t = 0.0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1.0) {
        t = 1.0;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  return (p1 + s * d1 - (p2 + t * d2)).norm();
}
// x's barycentric weights in the triangle (normal n, n·n = n2 > 0) all ≥ −1e-9.
inline bool inside_triangle(const Vec3d& x, const Vec3d (&v)[3], const Vec3d& n, double n2) noexcept {
  for (int k = 0; k < 3; ++k) {
    const Vec3d& from = v[k];
    const Vec3d& to = v[(k + 1) % 3];
    if (n.dot((to - from).cross(x - from)) < -1e-9 * n2) return false;
  }
  return true;
}
}  // namespace segment_bound_detail

inline double segment_triangle_distance_below(const Vec3& p0f, const Vec3& p1f, const Vec3& af, const Vec3& bf,
                                              const Vec3& cf) noexcept {
  using segment_bound_detail::Vec3d;
  const Vec3d p0 = p0f.cast<double>();
  const Vec3d p1 = p1f.cast<double>();
  const Vec3d v[3] = {af.cast<double>(), bf.cast<double>(), cf.cast<double>()};
  double distance = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    distance = std::min(distance, segment_bound_detail::segment_segment_distance(p0, p1, v[k], v[(k + 1) % 3]));
  }
  const Vec3d n = (v[1] - v[0]).cross(v[2] - v[0]);
  const double n2 = n.squaredNorm();
  if (n2 > 0.0) {
    const double s0 = n.dot(p0 - v[0]);
    const double s1 = n.dot(p1 - v[0]);
    const double length = std::sqrt(n2);
    if (segment_bound_detail::inside_triangle(p0 - (s0 / n2) * n, v, n, n2)) distance = std::min(distance, std::abs(s0) / length);
    if (segment_bound_detail::inside_triangle(p1 - (s1 / n2) * n, v, n, n2)) distance = std::min(distance, std::abs(s1) / length);
    if ((s0 <= 0.0 && s1 >= 0.0) || (s0 >= 0.0 && s1 <= 0.0)) {
      const double t = s0 != s1 ? s0 / (s0 - s1) : 0.0;
      if (segment_bound_detail::inside_triangle(p0 + t * (p1 - p0), v, n, n2)) distance = 0.0;
    }
  }
  return std::max(0.0, distance - 1e-7);
}

}  // namespace trainer::model
