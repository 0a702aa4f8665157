// Exact geometric predicates for contact on triangle meshes (METHODS.md §4): closest point on
// a triangle (Ericson, Real-Time Collision Detection §5.1.5, region method), sphere vs
// triangle, segment vs triangle intersection (Möller–Trumbore), closest points between a
// segment and a triangle (capsule contact: instrument shaft or jaw of radius r against the
// duct) and between two segments (Ericson §5.1.9).
//
// Runtime code: float, noexcept, no heap, free functions. Units: metres, any frame (all
// arguments in the same frame). Triangles are (a, b, c) = vertices 0, 1, 2; the face normal
// is (b − a) × (c − a) normalised (counter-clockwise seen from the outside for an outward
// mesh). Edge i joins vertex i and vertex (i + 1) mod 3: edge 0 = ab, edge 1 = bc, edge 2 = ca.
//
// Corner cases (every function): no NaN or infinity is ever returned for finite input. A
// zero-length segment and a zero-area triangle are handled explicitly (see each function).
// A triangle is degenerate when |ab × ac|² ≤ kDegenerateSine² |ab|² |ac|² (the smaller angle
// at a is under ~1e-5 rad, or an edge has zero length): it has no usable plane.
#pragma once

#include <cstdint>

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross products

namespace trainer::model {

using Vec3 = Eigen::Vector3f;

// Which closed feature of a triangle a point lies on (the Voronoi region of the query).
enum class TriangleFeature : std::uint8_t {
  face = 0,     // strictly inside
  edge0 = 1,    // a–b
  edge1 = 2,    // b–c
  edge2 = 3,    // c–a
  vertex0 = 4,  // a
  vertex1 = 5,  // b
  vertex2 = 6,  // c
};

inline constexpr float kDegenerateSine = 1e-5F;
// Barycentric slack of the closed-triangle intersection test (see intersect_segment_triangle).
inline constexpr float kBarycentricTolerance = 1e-6F;

// Unit face normal, or zero for a degenerate triangle.
Vec3 triangle_normal(const Vec3& a, const Vec3& b, const Vec3& c) noexcept;
bool triangle_is_degenerate(const Vec3& a, const Vec3& b, const Vec3& c) noexcept;

// Conservative pre-test of a contact loop (cheaper than the closest points): true only when
// the whole closed segment p0–p1 is certainly farther than distance_m from the triangle's
// plane, hence from the triangle, float rounding of the test included (a margin of a few
// dozen ε relative to the triangle's and the segment's extents). False whenever the segment
// meets or nearly meets the plane, for a degenerate triangle (no plane: the normal's rounding
// swamps it), a NaN, or distance_m < 0. Never true for a distance_m at or above the distance
// closest_points_segment_triangle computes (tested on random and degenerate input).
bool segment_beyond_triangle_plane(const Vec3& p0, const Vec3& p1, const Vec3& a, const Vec3& b, const Vec3& c,
                                   float distance_m) noexcept;

// The `_nondegenerate_` variants below are the functions of the same name without their
// triangle_is_degenerate test, bit for bit, for a caller that has already made it (a contact
// loop testing the same triangle several times): precondition !triangle_is_degenerate(a, b, c).
Vec3 nondegenerate_triangle_normal(const Vec3& a, const Vec3& b, const Vec3& c) noexcept;

struct TrianglePoint {
  Vec3 point = Vec3::Zero();
  Vec3 barycentric = Vec3(1.0F, 0.0F, 0.0F);  // weights of a, b, c; sum 1, each in [0, 1]
  TriangleFeature feature = TriangleFeature::vertex0;
};

// Closest point of the closed triangle to `p`. A degenerate triangle is treated as the union
// of its three edges (a point or a segment), so the answer is still exact.
TrianglePoint closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b,
                                        const Vec3& c) noexcept;
TrianglePoint closest_point_on_nondegenerate_triangle(const Vec3& p, const Vec3& a, const Vec3& b,
                                                      const Vec3& c) noexcept;

struct SphereTriangleContact {
  bool in_contact = false;
  float depth_m = 0.0F;         // radius − distance, > 0 when in contact
  float distance_m = 0.0F;      // centre to the closest point (set even without contact)
  Vec3 normal = Vec3::Zero();   // unit, from the triangle towards the centre
  TrianglePoint closest;        // on the triangle
};

// Contact when distance(centre, triangle) < radius. The triangle is two-sided: on the face
// region the normal is the face normal turned towards the centre (the stored orientation if
// the centre lies in the plane); on an edge or vertex region it is (centre − closest)/distance,
// or the face normal when the centre lies exactly on that edge or vertex. A degenerate
// triangle never reports contact (it has no normal; its neighbours carry the contact), but
// distance_m and closest are still filled.
SphereTriangleContact sphere_triangle_contact(const Vec3& centre, float radius_m, const Vec3& a,
                                              const Vec3& b, const Vec3& c) noexcept;

struct SegmentTriangleHit {
  bool hit = false;
  float t = 0.0F;               // along the segment: point = p0 + t (p1 − p0), t in [0, 1]
  Vec3 point = Vec3::Zero();
  TrianglePoint on_triangle;    // barycentrics and feature of the hit
  bool front_facing = false;    // the segment crosses from the normal side to the back side
};

// Möller–Trumbore on the CLOSED triangle and the closed segment: a hit on an edge or a vertex
// (barycentric weight ≥ −kBarycentricTolerance) is accepted and reported once by this triangle
// with feature = that edge or vertex, its barycentrics clamped to [0, 1]. A segment through an
// edge shared by two triangles is therefore reported by both; a caller looking for the first
// hit on a mesh keeps the smallest t (the two agree), a caller counting crossings merges hits
// whose feature is a shared edge or vertex. No hit: a zero-length segment, a degenerate
// triangle, a segment parallel to the plane (|sin angle| ≤ 1e-6, including a segment lying in
// the plane: use closest_points_segment_triangle for that), t outside [0, 1].
SegmentTriangleHit intersect_segment_triangle(const Vec3& p0, const Vec3& p1, const Vec3& a,
                                              const Vec3& b, const Vec3& c) noexcept;
SegmentTriangleHit intersect_segment_nondegenerate_triangle(const Vec3& p0, const Vec3& p1, const Vec3& a,
                                                            const Vec3& b, const Vec3& c) noexcept;

struct SegmentSegmentClosest {
  float distance_m = 0.0F;
  float s = 0.0F;               // on the first segment: p0 + s (p1 − p0)
  float t = 0.0F;               // on the second segment: q0 + t (q1 − q0)
  Vec3 on_first = Vec3::Zero();
  Vec3 on_second = Vec3::Zero();
};

// Closest points of two closed segments (Ericson §5.1.9). A zero-length segment is a point;
// (nearly) parallel segments, |sin angle| ≤ 1e-6, return one of the equally close pairs.
SegmentSegmentClosest closest_points_segments(const Vec3& p0, const Vec3& p1, const Vec3& q0,
                                              const Vec3& q1) noexcept;

struct SegmentTriangleClosest {
  float distance_m = 0.0F;
  float segment_t = 0.0F;       // on the segment: p0 + t (p1 − p0)
  Vec3 on_segment = Vec3::Zero();
  TrianglePoint on_triangle;
};

// Closest points between a closed segment and a closed triangle: 0 when they intersect
// (the Möller–Trumbore hit), otherwise the best of: each endpoint against the triangle and
// the segment against each edge. A segment in the plane of the triangle is covered by the
// endpoint and edge terms (distance 0 when it overlaps). Capsule (radius r) vs triangle is
// contact when distance_m < r.
SegmentTriangleClosest closest_points_segment_triangle(const Vec3& p0, const Vec3& p1,
                                                       const Vec3& a, const Vec3& b,
                                                       const Vec3& c) noexcept;
SegmentTriangleClosest closest_points_segment_nondegenerate_triangle(const Vec3& p0, const Vec3& p1,
                                                                     const Vec3& a, const Vec3& b,
                                                                     const Vec3& c) noexcept;

}  // namespace trainer::model
