// Geometric predicates (geometry.hpp) against independent double-precision references on
// random inputs, and hand cases on edges, vertices, parallel and degenerate input.
//
// References use different algorithms from the code under test: plane projection plus
// edge clamping for the closest point (not Ericson's regions), plane intersection with
// area barycentrics (not Möller–Trumbore), and golden-section search over the segment
// parameter of a convex distance function for the segment closest points.
// Tolerances: inputs are in [−1, 1] m, float ε = 1.2e-7; distances agree to 2e-5 m
// (a few hundred ε after the cancellations of a dot-product formulation).
#include "trainer/model/geometry.hpp"

#include <array>
#include <cmath>
#include <cstring>
#include <random>

#include <gtest/gtest.h>

namespace trainer::model {
namespace {

using Vec3d = Eigen::Vector3d;

Vec3d to_double(const Vec3& v) { return v.cast<double>(); }

// ---- double references ----

Vec3d closest_on_segment_reference(const Vec3d& p, const Vec3d& a, const Vec3d& b) {
  const Vec3d ab = b - a;
  const double length_squared = ab.squaredNorm();
  if (length_squared == 0.0) return a;
  const double t = std::clamp((p - a).dot(ab) / length_squared, 0.0, 1.0);
  return a + t * ab;
}

// Barycentric coordinates of the projection of p on the plane, by sub-triangle areas.
bool plane_barycentric(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c,
                       Vec3d& weights) {
  const Vec3d n = (b - a).cross(c - a);
  const double n2 = n.squaredNorm();
  if (n2 <= 1e-18 * (b - a).squaredNorm() * (c - a).squaredNorm() || n2 == 0.0) return false;
  weights = Vec3d((c - b).cross(p - b).dot(n) / n2, (a - c).cross(p - c).dot(n) / n2,
                  (b - a).cross(p - a).dot(n) / n2);
  return true;
}

Vec3d closest_on_triangle_reference(const Vec3d& p, const Vec3d& a, const Vec3d& b,
                                    const Vec3d& c) {
  Vec3d weights;
  if (plane_barycentric(p, a, b, c, weights) && weights.minCoeff() >= 0.0) {
    return weights[0] * a + weights[1] * b + weights[2] * c;
  }
  const std::array<Vec3d, 3> candidates{closest_on_segment_reference(p, a, b),
                                        closest_on_segment_reference(p, b, c),
                                        closest_on_segment_reference(p, c, a)};
  Vec3d best = candidates[0];
  for (const Vec3d& candidate : candidates) {
    if ((candidate - p).squaredNorm() < (best - p).squaredNorm()) best = candidate;
  }
  return best;
}

// Minimum over s in [0, 1] of a convex function, golden-section search.
template <class F>
double minimise_convex(F f, double& argmin) {
  double low = 0.0;
  double high = 1.0;
  const double ratio = (std::sqrt(5.0) - 1.0) / 2.0;
  for (int i = 0; i < 200; ++i) {
    const double m1 = high - ratio * (high - low);
    const double m2 = low + ratio * (high - low);
    if (f(m1) < f(m2)) {
      high = m2;
    } else {
      low = m1;
    }
  }
  argmin = 0.5 * (low + high);
  double best = f(argmin);
  for (const double end : {0.0, 1.0}) {
    if (f(end) < best) {
      best = f(end);
      argmin = end;
    }
  }
  return best;
}

std::mt19937 make_rng(unsigned seed) { return std::mt19937(seed); }
Vec3 random_point(std::mt19937& rng, float extent = 1.0F) {
  std::uniform_real_distribution<float> u(-extent, extent);
  return {u(rng), u(rng), u(rng)};
}

bool finite(const TrianglePoint& p) { return p.point.allFinite() && p.barycentric.allFinite(); }

void expect_consistent(const TrianglePoint& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  ASSERT_TRUE(finite(p));
  EXPECT_NEAR(p.barycentric.sum(), 1.0F, 1e-5F);
  EXPECT_GE(p.barycentric.minCoeff(), 0.0F);
  const Vec3 rebuilt = p.barycentric[0] * a + p.barycentric[1] * b + p.barycentric[2] * c;
  EXPECT_LT((rebuilt - p.point).norm(), 2e-5F);
  const int feature = static_cast<int>(p.feature);
  if (p.feature == TriangleFeature::face) {
    EXPECT_GT(p.barycentric.minCoeff(), 0.0F);
  } else if (feature < static_cast<int>(TriangleFeature::vertex0)) {
    const int edge = feature - static_cast<int>(TriangleFeature::edge0);
    EXPECT_EQ(p.barycentric[(edge + 2) % 3], 0.0F) << "edge " << edge;
  } else {
    EXPECT_EQ(p.barycentric[feature - static_cast<int>(TriangleFeature::vertex0)], 1.0F);
  }
}

// ---- closest point on a triangle ----

TEST(ClosestPointOnTriangle, MatchesDoubleReferenceOnRandomInput) {
  auto rng = make_rng(1);
  for (int trial = 0; trial < 20000; ++trial) {
    const Vec3 a = random_point(rng), b = random_point(rng), c = random_point(rng);
    const Vec3 p = random_point(rng, 2.0F);
    const TrianglePoint result = closest_point_on_triangle(p, a, b, c);
    const Vec3d reference =
        closest_on_triangle_reference(to_double(p), to_double(a), to_double(b), to_double(c));
    ASSERT_LT((to_double(result.point) - reference).norm(), 5e-5) << "trial " << trial;
    expect_consistent(result, a, b, c);
  }
}

TEST(ClosestPointOnTriangle, RegionsByHand) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  struct Case {
    Vec3 p;
    Vec3 expected;
    TriangleFeature feature;
  };
  const Case cases[] = {
      {{0.2F, 0.2F, 0.5F}, {0.2F, 0.2F, 0}, TriangleFeature::face},
      {{-1, -1, 0.3F}, a, TriangleFeature::vertex0},
      {{2, -0.5F, 0}, b, TriangleFeature::vertex1},
      {{-0.1F, 3, -1}, c, TriangleFeature::vertex2},
      {{0.5F, -1, 0.2F}, {0.5F, 0, 0}, TriangleFeature::edge0},
      {{1, 1, 0}, {0.5F, 0.5F, 0}, TriangleFeature::edge1},
      {{-2, 0.25F, 0}, {0, 0.25F, 0}, TriangleFeature::edge2},
  };
  for (const Case& test : cases) {
    const TrianglePoint result = closest_point_on_triangle(test.p, a, b, c);
    EXPECT_LT((result.point - test.expected).norm(), 1e-6F) << test.p.transpose();
    EXPECT_EQ(result.feature, test.feature) << test.p.transpose();
    expect_consistent(result, a, b, c);
  }
}

TEST(ClosestPointOnTriangle, DegenerateTrianglesAreTheirEdges) {
  auto rng = make_rng(2);
  for (int trial = 0; trial < 2000; ++trial) {
    const Vec3 a = random_point(rng);
    const Vec3 b = random_point(rng);
    const Vec3 p = random_point(rng, 2.0F);
    // Collinear (c between a and b), repeated vertex, and a single point.
    const Vec3 triangles[3][3] = {{a, b, 0.3F * a + 0.7F * b}, {a, a, b}, {a, a, a}};
    for (const auto& t : triangles) {
      EXPECT_TRUE(triangle_is_degenerate(t[0], t[1], t[2]));
      const TrianglePoint result = closest_point_on_triangle(p, t[0], t[1], t[2]);
      const Vec3d reference = closest_on_triangle_reference(to_double(p), to_double(t[0]),
                                                            to_double(t[1]), to_double(t[2]));
      ASSERT_LT((to_double(result.point) - reference).norm(), 5e-5);
      expect_consistent(result, t[0], t[1], t[2]);
      EXPECT_NE(result.feature, TriangleFeature::face);
    }
  }
}

// ---- sphere vs triangle ----

TEST(SphereTriangle, MatchesReferenceDistanceAndNormalRules) {
  auto rng = make_rng(3);
  std::uniform_real_distribution<float> radius_draw(0.0F, 1.0F);
  int contacts = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const Vec3 a = random_point(rng), b = random_point(rng), c = random_point(rng);
    const Vec3 centre = random_point(rng, 1.5F);
    const float radius_f = radius_draw(rng);
    const double radius = radius_f;
    const SphereTriangleContact contact = sphere_triangle_contact(centre, radius_f, a, b, c);
    const double distance =
        (closest_on_triangle_reference(to_double(centre), to_double(a), to_double(b), to_double(c)) -
         to_double(centre)).norm();
    ASSERT_NEAR(contact.distance_m, distance, 5e-5);
    if (std::abs(distance - radius) < 1e-4) continue;  // too close to call in float
    ASSERT_EQ(contact.in_contact, distance < radius) << "trial " << trial;
    if (!contact.in_contact) continue;
    ++contacts;
    EXPECT_NEAR(contact.depth_m, radius - distance, 5e-5);
    EXPECT_NEAR(contact.normal.norm(), 1.0F, 1e-5F);
    const Vec3 offset = centre - contact.closest.point;
    // The normal points from the triangle towards the centre.
    EXPECT_GE(contact.normal.dot(offset), -1e-6F);
    if (contact.closest.feature == TriangleFeature::face) {
      EXPECT_GT(std::abs(contact.normal.dot(triangle_normal(a, b, c))), 1.0F - 1e-5F);
    } else if (offset.norm() > 1e-4F) {
      EXPECT_LT((contact.normal - offset.normalized()).norm(), 1e-4F);
    }
  }
  EXPECT_GT(contacts, 1000);
}

TEST(SphereTriangle, HandCasesAndDegenerate) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  // Face, from below: the normal turns towards the centre.
  SphereTriangleContact below = sphere_triangle_contact({0.2F, 0.2F, -0.1F}, 0.25F, a, b, c);
  ASSERT_TRUE(below.in_contact);
  EXPECT_NEAR(below.depth_m, 0.15F, 1e-6F);
  EXPECT_LT((below.normal - Vec3(0, 0, -1)).norm(), 1e-6F);
  // Centre in the plane, inside: the stored orientation.
  SphereTriangleContact in_plane = sphere_triangle_contact({0.2F, 0.2F, 0}, 0.1F, a, b, c);
  ASSERT_TRUE(in_plane.in_contact);
  EXPECT_LT((in_plane.normal - Vec3(0, 0, 1)).norm(), 1e-6F);
  // Edge region: radial normal.
  SphereTriangleContact edge = sphere_triangle_contact({0.5F, -0.3F, 0.4F}, 0.6F, a, b, c);
  ASSERT_TRUE(edge.in_contact);
  EXPECT_EQ(edge.closest.feature, TriangleFeature::edge0);
  EXPECT_LT((edge.normal - Vec3(0, -0.6F, 0.8F)).norm(), 1e-5F);
  // Centre exactly on a vertex: face normal, full depth.
  SphereTriangleContact on_vertex = sphere_triangle_contact(b, 0.1F, a, b, c);
  ASSERT_TRUE(on_vertex.in_contact);
  EXPECT_NEAR(on_vertex.depth_m, 0.1F, 1e-7F);
  EXPECT_TRUE(on_vertex.normal.allFinite());
  EXPECT_NEAR(on_vertex.normal.norm(), 1.0F, 1e-6F);
  // Touching exactly (distance == radius) is not contact.
  EXPECT_FALSE(sphere_triangle_contact({0.2F, 0.2F, 0.5F}, 0.5F, a, b, c).in_contact);
  // Degenerate triangle: never contact, distance still exact.
  const SphereTriangleContact flat = sphere_triangle_contact({0.5F, 0.1F, 0}, 1.0F, a, b, b);
  EXPECT_FALSE(flat.in_contact);
  EXPECT_NEAR(flat.distance_m, 0.1F, 1e-6F);
  EXPECT_TRUE(flat.normal.allFinite());
}

// ---- segment vs triangle ----

TEST(SegmentTriangle, MatchesPlaneIntersectionReference) {
  auto rng = make_rng(4);
  int hits = 0;
  int compared = 0;
  for (int trial = 0; trial < 50000; ++trial) {
    const Vec3 a = random_point(rng), b = random_point(rng), c = random_point(rng);
    const Vec3 p0 = random_point(rng, 1.5F), p1 = random_point(rng, 1.5F);
    const SegmentTriangleHit result = intersect_segment_triangle(p0, p1, a, b, c);
    ASSERT_TRUE(std::isfinite(result.t) && result.point.allFinite() &&
                result.on_triangle.barycentric.allFinite());
    const Vec3d A = to_double(a), B = to_double(b), C = to_double(c);
    const Vec3d P0 = to_double(p0), P1 = to_double(p1);
    const Vec3d n = (B - A).cross(C - A);
    const Vec3d d = P1 - P0;
    const double sine = n.dot(d) / (n.norm() * d.norm());
    if (std::abs(sine) < 1e-3) continue;  // nearly parallel: ambiguous in float
    const double t = n.dot(A - P0) / n.dot(d);
    Vec3d weights;
    ASSERT_TRUE(plane_barycentric(P0 + t * d, A, B, C, weights));
    const double margin = std::min({std::abs(t), std::abs(1.0 - t), std::abs(weights[0]),
                                    std::abs(weights[1]), std::abs(weights[2])});
    if (margin < 1e-4) continue;  // on a boundary: the closed/open choice is tested by hand
    ++compared;
    const bool expected = t > 0.0 && t < 1.0 && weights.minCoeff() > 0.0;
    ASSERT_EQ(result.hit, expected) << "trial " << trial;
    if (!expected) continue;
    ++hits;
    EXPECT_NEAR(result.t, t, 1e-4);
    EXPECT_LT((result.on_triangle.barycentric.cast<double>() - weights).norm(), 1e-4);
    EXPECT_EQ(result.front_facing, n.dot(d) < 0.0);
    EXPECT_EQ(result.on_triangle.feature, TriangleFeature::face);
  }
  EXPECT_GT(compared, 40000);
  EXPECT_GT(hits, 2000);
}

TEST(SegmentTriangle, EdgesAndVerticesCountForTheClosedTriangle) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  const auto through = [&](const Vec3& target) {
    return intersect_segment_triangle(target + Vec3(0, 0, 1), target - Vec3(0, 0, 1), a, b, c);
  };
  const struct {
    Vec3 point;
    TriangleFeature feature;
  } cases[] = {{{0.5F, 0, 0}, TriangleFeature::edge0},   {{0.5F, 0.5F, 0}, TriangleFeature::edge1},
               {{0, 0.5F, 0}, TriangleFeature::edge2},   {a, TriangleFeature::vertex0},
               {b, TriangleFeature::vertex1},            {c, TriangleFeature::vertex2},
               {{0.25F, 0.25F, 0}, TriangleFeature::face}};
  for (const auto& test : cases) {
    const SegmentTriangleHit hit = through(test.point);
    ASSERT_TRUE(hit.hit) << test.point.transpose();
    EXPECT_EQ(hit.on_triangle.feature, test.feature) << test.point.transpose();
    EXPECT_FLOAT_EQ(hit.t, 0.5F);
    EXPECT_TRUE(hit.front_facing);  // moving along −z against the +z normal
    expect_consistent(hit.on_triangle, a, b, c);
  }
  EXPECT_FALSE(through({0.6F, 0.6F, 0}).hit);
  EXPECT_FALSE(through({-0.01F, 0.5F, 0}).hit);
  // The segment's own endpoints are closed too; upward crossings are back-facing.
  const SegmentTriangleHit at_end = intersect_segment_triangle({0.2F, 0.2F, -1}, {0.2F, 0.2F, 0}, a, b, c);
  ASSERT_TRUE(at_end.hit);
  EXPECT_FLOAT_EQ(at_end.t, 1.0F);
  EXPECT_FALSE(at_end.front_facing);
  EXPECT_FALSE(intersect_segment_triangle({0.2F, 0.2F, 0.5F}, {0.2F, 0.2F, 0.01F}, a, b, c).hit);
}

TEST(SegmentTriangle, SharedEdgeHasNoCrack) {
  // Unit square from two triangles sharing the diagonal b–d: every segment through the
  // square (interior, diagonal, or any edge) hits at least one, at the same t.
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(1, 1, 0), d(0, 1, 0);
  auto rng = make_rng(5);
  std::uniform_real_distribution<float> u(0.0F, 1.0F);
  for (int trial = 0; trial < 20000; ++trial) {
    const float x = u(rng);
    const float y = trial % 4 == 0 ? 1.0F - x : u(rng);  // a quarter exactly on the diagonal
    const Vec3 target(x, y, 0);
    const Vec3 tilt = random_point(rng, 0.5F);
    const Vec3 p0 = target + Vec3(tilt.x(), tilt.y(), 1.0F);
    const Vec3 p1 = target - Vec3(tilt.x(), tilt.y(), 1.0F);
    const SegmentTriangleHit first = intersect_segment_triangle(p0, p1, a, b, d);
    const SegmentTriangleHit second = intersect_segment_triangle(p0, p1, b, c, d);
    ASSERT_TRUE(first.hit || second.hit) << target.transpose();
    if (first.hit && second.hit) {
      EXPECT_NEAR(first.t, second.t, 1e-6F);
    }
  }
}

TEST(SegmentTriangle, ParallelAndDegenerateNeverHitNorProduceNaN) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  // In the plane, across the triangle.
  EXPECT_FALSE(intersect_segment_triangle({-1, 0.2F, 0}, {2, 0.2F, 0}, a, b, c).hit);
  // Parallel above.
  EXPECT_FALSE(intersect_segment_triangle({-1, 0.2F, 0.1F}, {2, 0.2F, 0.1F}, a, b, c).hit);
  // Zero-length segment on the triangle.
  const SegmentTriangleHit point = intersect_segment_triangle({0.2F, 0.2F, 0}, {0.2F, 0.2F, 0}, a, b, c);
  EXPECT_FALSE(point.hit);
  EXPECT_TRUE(std::isfinite(point.t));
  // Zero-area triangles.
  EXPECT_FALSE(intersect_segment_triangle({0.5F, 0, 1}, {0.5F, 0, -1}, a, b, Vec3(2, 0, 0)).hit);
  EXPECT_FALSE(intersect_segment_triangle({0, 0, 1}, {0, 0, -1}, a, a, a).hit);
  // Random junk including degenerate shapes: everything finite.
  auto rng = make_rng(6);
  for (int trial = 0; trial < 10000; ++trial) {
    const Vec3 p = random_point(rng), q = random_point(rng);
    const Vec3 v0 = random_point(rng);
    const Vec3 v1 = trial % 3 == 0 ? v0 : random_point(rng);
    const Vec3 v2 = trial % 5 == 0 ? 0.5F * (v0 + v1) : random_point(rng);
    const Vec3 end = trial % 7 == 0 ? p : q;
    const SegmentTriangleHit hit = intersect_segment_triangle(p, end, v0, v1, v2);
    ASSERT_TRUE(std::isfinite(hit.t) && hit.point.allFinite() &&
                hit.on_triangle.barycentric.allFinite());
    const SegmentTriangleClosest closest = closest_points_segment_triangle(p, end, v0, v1, v2);
    ASSERT_TRUE(std::isfinite(closest.distance_m) && closest.on_segment.allFinite() &&
                closest.on_triangle.point.allFinite() && std::isfinite(closest.segment_t));
    const SegmentSegmentClosest pair = closest_points_segments(p, end, v0, v1);
    ASSERT_TRUE(std::isfinite(pair.distance_m) && pair.on_first.allFinite() &&
                pair.on_second.allFinite());
    const SphereTriangleContact sphere = sphere_triangle_contact(p, 0.5F, v0, v1, v2);
    ASSERT_TRUE(sphere.normal.allFinite() && std::isfinite(sphere.depth_m));
  }
}

// ---- segment vs segment ----

TEST(SegmentSegment, MatchesConvexSearchReference) {
  auto rng = make_rng(7);
  for (int trial = 0; trial < 20000; ++trial) {
    const Vec3 p0 = random_point(rng), q0 = random_point(rng);
    Vec3 p1 = random_point(rng), q1 = random_point(rng);
    if (trial % 10 == 0) q1 = q0 + 0.7F * (p1 - p0);  // parallel
    if (trial % 13 == 0) p1 = p0;                     // a point
    const SegmentSegmentClosest result = closest_points_segments(p0, p1, q0, q1);
    const Vec3d P0 = to_double(p0), P1 = to_double(p1), Q0 = to_double(q0), Q1 = to_double(q1);
    double s_best = 0.0;
    const double reference = minimise_convex(
        [&](double s) {
          const Vec3d point = P0 + s * (P1 - P0);
          return (closest_on_segment_reference(point, Q0, Q1) - point).norm();
        },
        s_best);
    ASSERT_NEAR(result.distance_m, reference, 2e-5) << "trial " << trial;
    EXPECT_LT((result.on_first - (p0 + result.s * (p1 - p0))).norm(), 1e-5F);
    EXPECT_LT((result.on_second - (q0 + result.t * (q1 - q0))).norm(), 1e-5F);
    EXPECT_NEAR((result.on_first - result.on_second).norm(), result.distance_m, 1e-6F);
    EXPECT_TRUE(result.s >= 0.0F && result.s <= 1.0F && result.t >= 0.0F && result.t <= 1.0F);
  }
}

TEST(SegmentSegment, HandCases) {
  // Crossing at right angles, 1 apart.
  SegmentSegmentClosest crossing = closest_points_segments({-1, 0, 0}, {1, 0, 0}, {0, -1, 1}, {0, 1, 1});
  EXPECT_NEAR(crossing.distance_m, 1.0F, 1e-6F);
  EXPECT_NEAR(crossing.s, 0.5F, 1e-6F);
  EXPECT_NEAR(crossing.t, 0.5F, 1e-6F);
  // Collinear, disjoint: the facing endpoints.
  SegmentSegmentClosest collinear = closest_points_segments({0, 0, 0}, {1, 0, 0}, {3, 0, 0}, {2, 0, 0});
  EXPECT_NEAR(collinear.distance_m, 1.0F, 1e-6F);
  // Parallel, overlapping: distance is the gap.
  EXPECT_NEAR(closest_points_segments({0, 0, 0}, {2, 0, 0}, {1, 0.5F, 0}, {3, 0.5F, 0}).distance_m,
              0.5F, 1e-6F);
  // Two points.
  SegmentSegmentClosest points = closest_points_segments({0, 0, 0}, {0, 0, 0}, {0, 3, 4}, {0, 3, 4});
  EXPECT_FLOAT_EQ(points.distance_m, 5.0F);
}

// ---- segment vs triangle closest points (capsule) ----

TEST(SegmentTriangleClosest, MatchesConvexSearchReference) {
  auto rng = make_rng(8);
  for (int trial = 0; trial < 20000; ++trial) {
    const Vec3 a = random_point(rng), b = random_point(rng), c = random_point(rng);
    const Vec3 p0 = random_point(rng, 1.5F);
    Vec3 p1 = random_point(rng, 1.5F);
    if (trial % 11 == 0) {  // in the plane of the triangle
      const Vec3 n = triangle_normal(a, b, c);
      p1 = p1 - n * n.dot(p1 - a);
      p1 = p1 - n * n.dot(p1 - a);
    }
    const SegmentTriangleClosest result = closest_points_segment_triangle(p0, p1, a, b, c);
    const Vec3d A = to_double(a), B = to_double(b), C = to_double(c);
    const Vec3d P0 = to_double(p0), P1 = to_double(p1);
    double t_best = 0.0;
    const double reference = minimise_convex(
        [&](double t) {
          const Vec3d point = P0 + t * (P1 - P0);
          return (closest_on_triangle_reference(point, A, B, C) - point).norm();
        },
        t_best);
    ASSERT_NEAR(result.distance_m, reference, 3e-5) << "trial " << trial;
    EXPECT_NEAR((result.on_segment - result.on_triangle.point).norm(), result.distance_m, 1e-5F);
    EXPECT_LT((result.on_segment - (p0 + result.segment_t * (p1 - p0))).norm(), 2e-5F);
    expect_consistent(result.on_triangle, a, b, c);
  }
}

TEST(SegmentTriangleClosest, HandCases) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  // Piercing: zero, at the hit.
  const SegmentTriangleClosest pierce = closest_points_segment_triangle({0.2F, 0.2F, 1}, {0.2F, 0.2F, -1}, a, b, c);
  EXPECT_EQ(pierce.distance_m, 0.0F);
  EXPECT_NEAR(pierce.segment_t, 0.5F, 1e-6F);
  // Shaft above and parallel to the face: endpoint term, face feature.
  const SegmentTriangleClosest above = closest_points_segment_triangle({0.1F, 0.1F, 0.3F}, {0.3F, 0.3F, 0.3F}, a, b, c);
  EXPECT_NEAR(above.distance_m, 0.3F, 1e-6F);
  EXPECT_EQ(above.on_triangle.feature, TriangleFeature::face);
  // Shaft crossing over edge b–c outside the triangle: edge term.
  const SegmentTriangleClosest over_edge =
      closest_points_segment_triangle({1, 1, -1}, {1, 1, 1}, a, b, c);
  EXPECT_NEAR(over_edge.distance_m, std::sqrt(0.5F), 1e-6F);
  EXPECT_EQ(over_edge.on_triangle.feature, TriangleFeature::edge1);
  // In the plane, through the triangle: zero (the Möller–Trumbore test refuses it).
  const SegmentTriangleClosest coplanar = closest_points_segment_triangle({-1, 0.2F, 0}, {2, 0.2F, 0}, a, b, c);
  EXPECT_NEAR(coplanar.distance_m, 0.0F, 1e-7F);
}

// ---- the contact loops' pre-test and the _nondegenerate_ variants ----

// segment_beyond_triangle_plane must never reject a triangle at a distance the exact test
// computes: for every case it is false at that distance (so, being monotone in the distance,
// at any threshold the exact test would accept). Regular, sliver (just above the degenerate
// threshold) and degenerate triangles (collinear, repeated or coincident vertices); random,
// zero-length, in-plane, parallel-above-the-plane and long segments; metre and millimetre
// scales with an offset of 0.3 m (the duct's coordinates). When it rejects at half the
// distance, the double reference agrees that the segment is that far.
// Fewer cases in sanitizer builds (memory errors, not statistics: 2.9 s under ASan in full).
#if defined(TRAINER_SANITIZER_BUILD)
constexpr int kPlanePreTestCases = 8000;
#else
constexpr int kPlanePreTestCases = 40000;
#endif

TEST(SegmentBeyondTrianglePlane, NeverRejectsWhatTheExactTestKeeps) {
  auto rng = make_rng(21);
  std::uniform_real_distribution<float> unit(0.0F, 1.0F);
  int rejected_at_half = 0;
  int cases = 0;
  for (int trial = 0; trial < kPlanePreTestCases; ++trial) {
    const float scale = trial % 2 == 0 ? 1.0F : 2e-3F;
    const Vec3 offset = trial % 4 < 2 ? Vec3::Zero() : Vec3(0.3F, -0.2F, 0.25F);
    Vec3 a = offset + scale * random_point(rng), b = offset + scale * random_point(rng),
         c = offset + scale * random_point(rng);
    switch (trial % 10) {
      case 1: c = a + unit(rng) * (b - a); break;                  // collinear
      case 2: b = a; break;                                         // repeated vertex
      case 3: b = a; c = a; break;                                  // a point
      case 4: c = a + 0.5F * (b - a) + 2e-5F * (b - a).norm() * random_point(rng); break;  // sliver
      default: break;
    }
    Vec3 p0 = offset + scale * random_point(rng, 1.5F);
    Vec3 p1 = offset + scale * random_point(rng, 1.5F);
    const Vec3 n = (b - a).cross(c - a).normalized();
    switch (trial % 7) {
      case 1: p1 = p0; break;  // zero-length
      case 2:                  // in the plane
        if (n.allFinite()) {
          p0 -= n * n.dot(p0 - a);
          p1 -= n * n.dot(p1 - a);
        }
        break;
      case 3:  // parallel to the plane, just above it
        if (n.allFinite()) {
          const float height = scale * 1e-3F * unit(rng);
          p0 += n * (height - n.dot(p0 - a));
          p1 += n * (height - n.dot(p1 - a));
        }
        break;
      case 4: p1 = p0 + 100.0F * (p1 - p0); break;  // long
      default: break;
    }
    const float distance = closest_points_segment_triangle(p0, p1, a, b, c).distance_m;
    ++cases;
    ASSERT_FALSE(segment_beyond_triangle_plane(p0, p1, a, b, c, distance))
        << "trial " << trial << " distance " << distance;
    ASSERT_FALSE(segment_beyond_triangle_plane(p0, p1, a, b, c, std::nextafter(distance, INFINITY)));
    if (segment_beyond_triangle_plane(p0, p1, a, b, c, 0.5F * distance)) {
      ++rejected_at_half;
      const Vec3d A = to_double(a), B = to_double(b), C = to_double(c);
      const Vec3d P0 = to_double(p0), P1 = to_double(p1);
      double t_best = 0.0;
      const double reference = minimise_convex(
          [&](double t) {
            const Vec3d point = P0 + t * (P1 - P0);
            return (closest_on_triangle_reference(point, A, B, C) - point).norm();
          },
          t_best);
      ASSERT_GT(reference, 0.5 * static_cast<double>(distance)) << "trial " << trial;
    }
  }
  EXPECT_FALSE(segment_beyond_triangle_plane({0, 0, 1}, {0, 0, 2}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, NAN));
  EXPECT_FALSE(segment_beyond_triangle_plane({0, 0, 1}, {0, 0, 2}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, -1.0F));
  EXPECT_TRUE(segment_beyond_triangle_plane({0, 0, 1}, {5, 5, 2}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 0.99F));
  EXPECT_FALSE(segment_beyond_triangle_plane({0, 0, 1}, {5, 5, -2}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 0.0F));
  // The test must be able to fail: it rejects a good share of the random cases at half the distance.
  EXPECT_GT(rejected_at_half, cases / 10);
}

// The _nondegenerate_ variants are the checked functions without the degeneracy test: bit
// for bit the same on non-degenerate triangles.
TEST(NondegenerateVariants, AreBitIdenticalOnNonDegenerateTriangles) {
  auto rng = make_rng(22);
  int compared = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const Vec3 a = random_point(rng), b = random_point(rng), c = random_point(rng);
    if (triangle_is_degenerate(a, b, c)) continue;
    const Vec3 p0 = random_point(rng, 1.5F);
    const Vec3 p1 = trial % 5 == 0 ? p0 : random_point(rng, 1.5F);
    const SegmentTriangleClosest checked = closest_points_segment_triangle(p0, p1, a, b, c);
    const SegmentTriangleClosest bare = closest_points_segment_nondegenerate_triangle(p0, p1, a, b, c);
    ASSERT_EQ(std::memcmp(&checked.distance_m, &bare.distance_m, sizeof(float)), 0);
    ASSERT_EQ(checked.segment_t, bare.segment_t);
    ASSERT_EQ(checked.on_triangle.feature, bare.on_triangle.feature);
    ASSERT_TRUE((checked.on_triangle.point.array() == bare.on_triangle.point.array()).all());
    ASSERT_TRUE((checked.on_triangle.barycentric.array() == bare.on_triangle.barycentric.array()).all());
    const TrianglePoint on = closest_point_on_triangle(p0, a, b, c);
    const TrianglePoint on_bare = closest_point_on_nondegenerate_triangle(p0, a, b, c);
    ASSERT_TRUE((on.point.array() == on_bare.point.array()).all() && on.feature == on_bare.feature);
    ASSERT_TRUE((triangle_normal(a, b, c).array() == nondegenerate_triangle_normal(a, b, c).array()).all());
    const SegmentTriangleHit hit = intersect_segment_triangle(p0, p1, a, b, c);
    const SegmentTriangleHit hit_bare = intersect_segment_nondegenerate_triangle(p0, p1, a, b, c);
    ASSERT_EQ(hit.hit, hit_bare.hit);
    ASSERT_EQ(hit.t, hit_bare.t);
    ++compared;
  }
  EXPECT_GT(compared, 19000);
}

}  // namespace
}  // namespace trainer::model
