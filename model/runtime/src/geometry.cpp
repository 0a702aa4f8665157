// Exact predicates on triangles and segments; see geometry.hpp for the conventions.
#include "trainer/model/geometry.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace trainer::model {
namespace {

constexpr float kParallelSine = 1e-6F;

float clamp01(float value) noexcept { return std::clamp(value, 0.0F, 1.0F); }

// numerator / denominator for a denominator known to be ≥ 0; 0 when it is not positive
// (rounding at a degenerate configuration), so no NaN can escape.
float safe_ratio(float numerator, float denominator) noexcept {
  return denominator > 0.0F ? numerator / denominator : 0.0F;
}

TriangleFeature edge_feature(int edge) noexcept {
  return static_cast<TriangleFeature>(static_cast<int>(TriangleFeature::edge0) + edge);
}
TriangleFeature vertex_feature(int vertex) noexcept {
  return static_cast<TriangleFeature>(static_cast<int>(TriangleFeature::vertex0) + vertex);
}

// Point at parameter `t` of edge `edge` (from vertex edge to vertex edge+1), as a
// TrianglePoint: the feature is the vertex at t = 0 or 1, else the edge.
TrianglePoint edge_point(int edge, float t, const Vec3& start, const Vec3& end) noexcept {
  TrianglePoint result;
  result.point = start + t * (end - start);
  result.barycentric = Vec3::Zero();
  const int next = (edge + 1) % 3;
  result.barycentric[edge] = 1.0F - t;
  result.barycentric[next] = t;
  if (t <= 0.0F) {
    result.feature = vertex_feature(edge);
  } else if (t >= 1.0F) {
    result.feature = vertex_feature(next);
  } else {
    result.feature = edge_feature(edge);
  }
  return result;
}

float closest_parameter_on_segment(const Vec3& p, const Vec3& start, const Vec3& end) noexcept {
  const Vec3 direction = end - start;
  return clamp01(safe_ratio((p - start).dot(direction), direction.squaredNorm()));
}

// A degenerate triangle is the union of its edges.
TrianglePoint closest_point_on_degenerate(const Vec3& p, const Vec3& a, const Vec3& b,
                                          const Vec3& c) noexcept {
  const Vec3* vertices[3] = {&a, &b, &c};
  TrianglePoint best;
  float best_distance_squared = INFINITY;
  for (int edge = 0; edge < 3; ++edge) {
    const Vec3& start = *vertices[edge];
    const Vec3& end = *vertices[(edge + 1) % 3];
    const TrianglePoint candidate =
        edge_point(edge, closest_parameter_on_segment(p, start, end), start, end);
    const float distance_squared = (candidate.point - p).squaredNorm();
    if (distance_squared < best_distance_squared) {
      best_distance_squared = distance_squared;
      best = candidate;
    }
  }
  return best;
}

}  // namespace

bool triangle_is_degenerate(const Vec3& a, const Vec3& b, const Vec3& c) noexcept {
  const Vec3 ab = b - a;
  const Vec3 ac = c - a;
  const float cross_squared = ab.cross(ac).squaredNorm();
  return cross_squared <= kDegenerateSine * kDegenerateSine * ab.squaredNorm() * ac.squaredNorm();
}

Vec3 triangle_normal(const Vec3& a, const Vec3& b, const Vec3& c) noexcept {
  if (triangle_is_degenerate(a, b, c)) return Vec3::Zero();
  return nondegenerate_triangle_normal(a, b, c);
}

bool segment_beyond_triangle_plane(const Vec3& p0, const Vec3& p1, const Vec3& a, const Vec3& b, const Vec3& c,
                                   float distance_m) noexcept {
  if (!(distance_m >= 0.0F)) return false;
  const Vec3 ab = b - a;
  const Vec3 ac = c - a;
  const Vec3 normal = ab.cross(ac);
  const Vec3 to0 = p0 - a;
  const Vec3 to1 = p1 - a;
  const float h0 = normal.dot(to0);
  const float h1 = normal.dot(to1);
  if (!(h0 * h1 > 0.0F)) return false;  // the segment meets the plane (or NaN, or underflow)
  const float nearer = std::min(std::abs(h0), std::abs(h1));
  // Rounding, bounded with L1 norms (≥ the Euclidean ones): the computed normal is off by at
  // most ~5 ε |ab|₁ |ac|₁ and each height by ~ε |to|₁ (5 |ab|₁ |ac|₁ + 5 |normal|₁); the
  // factor 64 ε leaves a wide margin. With them the exact heights share the computed sign and
  // |H| / |N| > distance_m for both ends, so every point of the segment is that far from the
  // plane.
  constexpr float kEps = std::numeric_limits<float>::epsilon();
  const float spread = ab.cwiseAbs().sum() * ac.cwiseAbs().sum();
  const float reach = std::max(to0.cwiseAbs().sum(), to1.cwiseAbs().sum());
  const float normal_error = 8.0F * kEps * spread;
  const float height_error = 64.0F * kEps * reach * (spread + normal.cwiseAbs().sum());
  return nearer > distance_m * (normal.norm() + normal_error) + height_error;
}

Vec3 nondegenerate_triangle_normal(const Vec3& a, const Vec3& b, const Vec3& c) noexcept {
  return (b - a).cross(c - a).normalized();
}

TrianglePoint closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b,
                                        const Vec3& c) noexcept {
  if (triangle_is_degenerate(a, b, c)) return closest_point_on_degenerate(p, a, b, c);
  return closest_point_on_nondegenerate_triangle(p, a, b, c);
}

TrianglePoint closest_point_on_nondegenerate_triangle(const Vec3& p, const Vec3& a, const Vec3& b,
                                                      const Vec3& c) noexcept {
  // Ericson §5.1.5: classify p into the Voronoi regions of the vertices, then the edges,
  // then the face, with dot products only.
  const Vec3 ab = b - a;
  const Vec3 ac = c - a;
  const Vec3 ap = p - a;
  const float d1 = ab.dot(ap);
  const float d2 = ac.dot(ap);
  TrianglePoint result;
  if (d1 <= 0.0F && d2 <= 0.0F) {
    result.point = a;
    result.barycentric = Vec3(1.0F, 0.0F, 0.0F);
    result.feature = TriangleFeature::vertex0;
    return result;
  }
  const Vec3 bp = p - b;
  const float d3 = ab.dot(bp);
  const float d4 = ac.dot(bp);
  if (d3 >= 0.0F && d4 <= d3) {
    result.point = b;
    result.barycentric = Vec3(0.0F, 1.0F, 0.0F);
    result.feature = TriangleFeature::vertex1;
    return result;
  }
  const float vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0F && d1 >= 0.0F && d3 <= 0.0F) {
    return edge_point(0, clamp01(safe_ratio(d1, d1 - d3)), a, b);
  }
  const Vec3 cp = p - c;
  const float d5 = ab.dot(cp);
  const float d6 = ac.dot(cp);
  if (d6 >= 0.0F && d5 <= d6) {
    result.point = c;
    result.barycentric = Vec3(0.0F, 0.0F, 1.0F);
    result.feature = TriangleFeature::vertex2;
    return result;
  }
  const float vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0F && d2 >= 0.0F && d6 <= 0.0F) {
    // Edge c–a, parameterised from c: point = c + s (a − c) with s = 1 − d2/(d2 − d6).
    return edge_point(2, 1.0F - clamp01(safe_ratio(d2, d2 - d6)), c, a);
  }
  const float va = d3 * d6 - d5 * d4;
  if (va <= 0.0F && (d4 - d3) >= 0.0F && (d5 - d6) >= 0.0F) {
    return edge_point(1, clamp01(safe_ratio(d4 - d3, (d4 - d3) + (d5 - d6))), b, c);
  }
  // Face: va + vb + vc = |ab × ac|² > 0 for a non-degenerate triangle.
  const float sum = va + vb + vc;
  const float v = clamp01(safe_ratio(vb, sum));
  const float w = clamp01(safe_ratio(vc, sum));
  const float u = std::max(0.0F, 1.0F - v - w);
  result.barycentric = Vec3(u, v, w);
  result.point = u * a + v * b + w * c;
  result.feature = TriangleFeature::face;
  return result;
}

SphereTriangleContact sphere_triangle_contact(const Vec3& centre, float radius_m, const Vec3& a,
                                              const Vec3& b, const Vec3& c) noexcept {
  SphereTriangleContact contact;
  contact.closest = closest_point_on_triangle(centre, a, b, c);
  const Vec3 offset = centre - contact.closest.point;
  contact.distance_m = offset.norm();
  const Vec3 face_normal = triangle_normal(a, b, c);
  if (face_normal.isZero() || !(contact.distance_m < radius_m)) return contact;
  contact.in_contact = true;
  contact.depth_m = radius_m - contact.distance_m;
  if (contact.closest.feature == TriangleFeature::face || contact.distance_m <= 0.0F) {
    contact.normal = offset.dot(face_normal) < 0.0F ? Vec3(-face_normal) : face_normal;
  } else {
    contact.normal = offset / contact.distance_m;
  }
  return contact;
}

SegmentTriangleHit intersect_segment_triangle(const Vec3& p0, const Vec3& p1, const Vec3& a,
                                              const Vec3& b, const Vec3& c) noexcept {
  if (triangle_is_degenerate(a, b, c)) return SegmentTriangleHit{};
  return intersect_segment_nondegenerate_triangle(p0, p1, a, b, c);
}

SegmentTriangleHit intersect_segment_nondegenerate_triangle(const Vec3& p0, const Vec3& p1, const Vec3& a,
                                                            const Vec3& b, const Vec3& c) noexcept {
  SegmentTriangleHit result;
  const Vec3 direction = p1 - p0;
  const float length_squared = direction.squaredNorm();
  if (!(length_squared > 0.0F)) return result;
  const Vec3 e1 = b - a;
  const Vec3 e2 = c - a;
  const Vec3 h = direction.cross(e2);
  // det = e1 · (d × e2) = −d · (e1 × e2): |det| = |d| |e1 × e2| |sin(angle to the plane)|.
  const float det = e1.dot(h);
  const float scale_squared = length_squared * e1.cross(e2).squaredNorm();
  if (det * det <= kParallelSine * kParallelSine * scale_squared) return result;
  const float inverse_det = 1.0F / det;
  const Vec3 s = p0 - a;
  const float u = inverse_det * s.dot(h);
  if (u < -kBarycentricTolerance || u > 1.0F + kBarycentricTolerance) return result;
  const Vec3 q = s.cross(e1);
  const float v = inverse_det * direction.dot(q);
  if (v < -kBarycentricTolerance || u + v > 1.0F + kBarycentricTolerance) return result;
  const float t = inverse_det * e2.dot(q);
  if (!(t >= 0.0F && t <= 1.0F)) return result;

  Vec3 weights(std::max(0.0F, 1.0F - u - v), clamp01(u), clamp01(v));
  weights /= weights.sum();  // ≥ 1 − 3 tolerance, never zero
  int zero_count = 0;
  int last_zero = 0;
  int last_nonzero = 0;
  for (int i = 0; i < 3; ++i) {
    if (weights[i] <= kBarycentricTolerance) {
      weights[i] = 0.0F;
      ++zero_count;
      last_zero = i;
    } else {
      last_nonzero = i;
    }
  }
  weights /= weights.sum();
  result.hit = true;
  result.t = t;
  result.point = p0 + t * direction;
  result.front_facing = det > 0.0F;
  result.on_triangle.barycentric = weights;
  result.on_triangle.point = result.point;
  if (zero_count == 0) {
    result.on_triangle.feature = TriangleFeature::face;
  } else if (zero_count == 1) {
    // The weight of vertex i is zero on the edge opposite i, which is edge (i + 1) mod 3.
    result.on_triangle.feature = edge_feature((last_zero + 1) % 3);
  } else {
    result.on_triangle.feature = vertex_feature(last_nonzero);
  }
  return result;
}

SegmentSegmentClosest closest_points_segments(const Vec3& p0, const Vec3& p1, const Vec3& q0,
                                              const Vec3& q1) noexcept {
  const Vec3 d1 = p1 - p0;
  const Vec3 d2 = q1 - q0;
  const Vec3 r = p0 - q0;
  const float a = d1.squaredNorm();
  const float e = d2.squaredNorm();
  const float f = d2.dot(r);
  float s = 0.0F;
  float t = 0.0F;
  if (!(a > 0.0F) && !(e > 0.0F)) {
    // Two points.
  } else if (!(a > 0.0F)) {
    t = clamp01(f / e);
  } else {
    const float c = d1.dot(r);
    if (!(e > 0.0F)) {
      s = clamp01(-c / a);
    } else {
      const float b = d1.dot(d2);
      const float denominator = a * e - b * b;  // |d1 × d2|² ≥ 0
      if (denominator > kParallelSine * kParallelSine * a * e) {
        s = clamp01((b * f - c * e) / denominator);
      }
      // t for the chosen s, then re-clamp t and recompute s (Ericson §5.1.9).
      const float t_numerator = b * s + f;
      if (t_numerator < 0.0F) {
        t = 0.0F;
        s = clamp01(-c / a);
      } else if (t_numerator > e) {
        t = 1.0F;
        s = clamp01((b - c) / a);
      } else {
        t = t_numerator / e;
      }
    }
  }
  SegmentSegmentClosest result;
  result.s = s;
  result.t = t;
  result.on_first = p0 + s * d1;
  result.on_second = q0 + t * d2;
  result.distance_m = (result.on_first - result.on_second).norm();
  return result;
}

namespace {

// The closest pair, the triangle's degeneracy decided once by the caller (the three calls on
// the triangle then take the same branches as they would have deciding it themselves).
SegmentTriangleClosest segment_triangle_closest(const Vec3& p0, const Vec3& p1, const Vec3& a, const Vec3& b,
                                                const Vec3& c, bool degenerate) noexcept {
  SegmentTriangleClosest best;
  const SegmentTriangleHit hit =
      degenerate ? SegmentTriangleHit{} : intersect_segment_nondegenerate_triangle(p0, p1, a, b, c);
  if (hit.hit) {
    best.distance_m = 0.0F;
    best.segment_t = hit.t;
    best.on_segment = hit.point;
    best.on_triangle = hit.on_triangle;
    return best;
  }
  float best_distance_squared = INFINITY;
  const auto consider_endpoint = [&](const Vec3& endpoint, float t) {
    const TrianglePoint on_triangle = degenerate ? closest_point_on_degenerate(endpoint, a, b, c)
                                                 : closest_point_on_nondegenerate_triangle(endpoint, a, b, c);
    const float distance_squared = (on_triangle.point - endpoint).squaredNorm();
    if (distance_squared < best_distance_squared) {
      best_distance_squared = distance_squared;
      best.segment_t = t;
      best.on_segment = endpoint;
      best.on_triangle = on_triangle;
    }
  };
  consider_endpoint(p0, 0.0F);
  consider_endpoint(p1, 1.0F);
  const Vec3* vertices[3] = {&a, &b, &c};
  for (int edge = 0; edge < 3; ++edge) {
    const Vec3& start = *vertices[edge];
    const Vec3& end = *vertices[(edge + 1) % 3];
    const SegmentSegmentClosest pair = closest_points_segments(p0, p1, start, end);
    const float distance_squared = pair.distance_m * pair.distance_m;
    if (distance_squared < best_distance_squared) {
      best_distance_squared = distance_squared;
      best.segment_t = pair.s;
      best.on_segment = pair.on_first;
      best.on_triangle = edge_point(edge, pair.t, start, end);
      best.on_triangle.point = pair.on_second;
    }
  }
  best.distance_m = std::sqrt(best_distance_squared);
  return best;
}

}  // namespace

SegmentTriangleClosest closest_points_segment_triangle(const Vec3& p0, const Vec3& p1,
                                                       const Vec3& a, const Vec3& b,
                                                       const Vec3& c) noexcept {
  return segment_triangle_closest(p0, p1, a, b, c, triangle_is_degenerate(a, b, c));
}

SegmentTriangleClosest closest_points_segment_nondegenerate_triangle(const Vec3& p0, const Vec3& p1,
                                                                     const Vec3& a, const Vec3& b,
                                                                     const Vec3& c) noexcept {
  return segment_triangle_closest(p0, p1, a, b, c, false);
}

}  // namespace trainer::model
