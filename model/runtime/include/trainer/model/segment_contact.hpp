// Ray-based contact of an instrument's capsule segments (the forceps shaft and its two jaws,
// Basdogan's line-segment tool, METHODS.md §4) against a deforming thin triangle shell such as
// the modal cystic duct. Owns the per-cycle search, the penalty force on each segment, the
// memory of which side of the wall each segment is pushed to, and the equal and opposite
// forces on the mesh nodes. One instance per (instrument, surface).
//
// The mesh is the shell's mid-surface (outward normals); its walls lie surface_half_thickness_m
// either side of it. A capsule of radius r touches the wall when its axis segment comes closer
// than reach = r + half thickness to the mid-surface.
//
// Contact rule: ONE contact per segment, at the closest pair of points between the segment and
// the whole mesh (the minimum over the candidate triangles of closest_points_segment_triangle;
// among distances equal within float rounding a face-region point wins, then an edge-region
// one, then the pair most perpendicular to its triangle, then the lowest triangle id). That distance is continuous as the segment slides across edges and vertices, so the
// magnitude k·(reach − distance) is too, and so is the direction (q − p)/|q − p| from the mesh
// point p to the segment point q (it turns continuously about an edge or a vertex).
//
// Side memory (god-object-like, for a shell the tool can reach through): when a segment's
// contact begins, the side of the mid-surface it is on is remembered as ±1 relative to the
// outward angle-weighted pseudo-normal m at p (Bærentzen & Aanæs 2005; the face normal inside
// a face). A contact that begins with the segment already crossing the mid-surface (distance
// ~0: it moved more than reach in one cycle, or the first update) takes the side it came from,
// −sign(v·m) for the relative velocity v at q, and the outer side when v·m = 0. While the
// contact lasts the segment is pushed to the remembered side s:
//   q on side s, distance above rounding:  n = (q − p)/|q − p|
//   q crossing (distance ~0) or behind:    n = s·m
// Depth is reach − distance on either side, so a segment pushed through the mid-surface is
// still pushed back (never the other way), with a force that peaks at k·reach on the
// mid-surface and falls to zero at reach behind it, where the contact ends and the memory is
// dropped (the wall has been pushed through; no force jump). Contact, and the memory, end
// when no non-degenerate triangle is within reach (the broad phase's query_segment() with a
// margin of reach returns every triangle within reach as a candidate), when the segment is not
// passed to an update, or at reset().
//
// Force on the tool: f = k·depth − b·((v_q − v_p)·n), clipped at 0 (the damper never pulls)
// and at max_force_n, along n. v_q is interpolated between the capsule's end velocities
// (exact for a rigid segment); v_p is interpolated from the surface node velocities with the
// barycentric weights of p, or zero when the caller has none (an empty span). The reaction −f·n
// goes to the three vertices of p's triangle with p's barycentric weights (force conserved; the
// moment too while n ∥ q − p). Node forces are merged per node (≤ 9 entries).
//
// ToolForce::along_m follows ForcepsCatheterContact: the distance from the capsule's start to
// q, so a shaft capsule must start at the shaft start (handle end) and a jaw capsule at the
// hinge.
//
// Limits: a segment crossing the mid-surface (distance 0) gets k·reach however deep its tip
// goes; a segment parallel to the surface has many equally close points and q is one of them
// (an end or an edge crossing), so along_m can jump while the force does not; on an open
// boundary edge the direction switches from (q − p)/|q − p| to s·m when q goes behind the
// plane; one contact per segment, so a segment touching two separate folds of the mesh feels
// only the nearer one (and in a concave crease equidistant from both faces the direction
// switches between their normals). Float rounding: point pairs whose distances differ by less
// than 4 ulp of the coordinates (δ ≈ 1e-8 m at 2 cm from the origin) are a tie, and two tied
// pairs on different edges, neither perpendicular to its triangle, may be told apart wrongly:
// the direction can then tilt by up to √(2δ/distance), 4e-3 rad at a distance of 1 mm. Ties
// between a face or an edge and a neighbour's vertex or edge beside it, the common case on a
// flat or gently curved region, are resolved exactly (see better() in the source).
//
// Runtime code: float, noexcept, no heap after create(), scratch carved from a core::Arena.
// One thread owns the object. Units SI; every position in the mesh's (model) frame.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/core/status.hpp"
#include "trainer/model/bucket_grid.hpp"
#include "trainer/model/forceps_catheter.hpp"  // ToolSegment, ToolForce
#include "trainer/model/geometry.hpp"
#include "trainer/model/particle_contact.hpp"  // NodeForce
#include "trainer/model/proxy.hpp"             // TriangleMeshView
#include "trainer/model/triangle_bvh.hpp"      // QueryCache

namespace trainer::model {

struct SegmentContactSettings {
  float surface_half_thickness_m = 0.0F;  // ≥ 0: the walls lie this far either side of the mesh
  float stiffness_n_per_m = 0.0F;         // > 0
  float damping_n_s_per_m = 0.0F;         // ≥ 0, along the contact normal only
  float max_force_n = 0.0F;               // > 0: clamp per segment
  std::uint32_t max_candidates = 256;     // ≥ 1: triangles one grid query may return
};

// One of the instrument's capsules this cycle. `start_m` is where along_m is measured from:
// the shaft start for the shaft, the hinge for a jaw.
struct ToolCapsule {
  ToolSegment segment = ToolSegment::shaft;
  Vec3 start_m = Vec3::Zero();
  Vec3 end_m = Vec3::Zero();
  float radius_m = 0.0F;                        // ≥ 0
  Vec3 start_velocity_m_per_s = Vec3::Zero();
  Vec3 end_velocity_m_per_s = Vec3::Zero();
};

// One segment's contact of the last update (kept whatever force it gave, 0 when the damper
// cancelled it).
struct SegmentContact {
  ToolSegment segment = ToolSegment::shaft;
  float along_m = 0.0F;                     // from the capsule's start to segment_point_m
  Vec3 segment_point_m = Vec3::Zero();      // q, on the capsule's axis
  Vec3 mesh_point_m = Vec3::Zero();         // p, on the mid-surface
  std::uint32_t triangle = 0;
  std::array<std::uint32_t, 3> vertices{};
  Vec3 barycentric = Vec3::Zero();          // of p in `triangle`
  TriangleFeature feature = TriangleFeature::face;
  Vec3 normal = Vec3::UnitZ();              // unit, the direction the tool is pushed
  float distance_m = 0.0F;                  // |q − p|
  float depth_m = 0.0F;                     // reach − distance, > 0
  std::int8_t side = 1;                     // remembered side: +1 outer, −1 inner
  bool clamped = false;                     // limited by max_force_n
  Vec3 force_on_tool_n = Vec3::Zero();
};

class SegmentSurfaceContact {
 public:
  static constexpr std::size_t kMaxSegments = 3;  // shaft, jaw 0, jaw 1
  static constexpr std::size_t kMaxNodeForces = 3 * kMaxSegments;

  // Setup path: checks every setting (the message names the field, its value and the expected
  // range) and carves the candidate buffers from `arena`.
  static core::Expected<SegmentSurfaceContact> create(const SegmentContactSettings& settings,
                                                      core::Arena& arena);

  // ---- RT path: noexcept, no heap ----

  // One cycle. `capsules`: up to 3, each ToolSegment at most once (a segment left out loses
  // its side memory). `surface_velocities_m_per_s`: 3n like mesh.positions_m, or empty (the
  // surface is taken at rest). The caller rebuilt `grid` over mesh.positions_m. The results
  // below are valid after every call, whatever the status (the first problem found):
  //   invalid_argument  more than 3 capsules, a repeated or unknown segment, a negative or
  //                     non-finite radius, surface velocities of the wrong size (nothing
  //                     computed, no contact, side memory kept); a grid refusal (that segment
  //                     gets no contact this cycle, its memory is kept);
  //   numeric_error     a non-finite capsule position or velocity (nothing computed, no
  //                     contact, memory kept) or a non-finite contact force (that contact is
  //                     dropped: never a NaN out);
  //   capacity_exceeded a grid query returned more than max_candidates triangles: that segment
  //                     uses the first max_candidates (candidate_overflow_count() counts it).
  core::Status update(std::span<const ToolCapsule> capsules, const TriangleMeshView& mesh,
                      std::span<const float> surface_velocities_m_per_s, TriangleBroadPhase& grid) noexcept;

  // Forgets every contact and side memory (a tool withdrawn, a scene reset).
  void reset() noexcept;

  // Copies the merged node forces (Σ = −Σ tool forces) to `out`; returns how many were written.
  // Entries that do not fit are dropped and counted in node_force_overflow_count().
  std::size_t write_node_forces(std::span<NodeForce> out) noexcept;

  std::size_t contact_count() const noexcept { return contact_count_; }
  // index < contact_count().
  const SegmentContact& contact(std::size_t index) const noexcept { return contacts_[index]; }
  std::span<const SegmentContact> contacts() const noexcept { return {contacts_.data(), contact_count_}; }
  // One per contact, in the same order: what the instrument's Jacobian maps to joint efforts.
  std::span<const ToolForce> tool_forces() const noexcept { return {tool_forces_.data(), contact_count_}; }
  std::span<const NodeForce> node_forces() const noexcept { return {node_forces_.data(), node_force_count_}; }
  // Remembered side of a segment's ongoing contact: +1 outer, −1 inner, 0 none.
  int side(ToolSegment segment) const noexcept { return sides_[static_cast<std::size_t>(segment)]; }
  // Since create(): grid queries truncated to max_candidates; node forces that did not fit.
  std::uint64_t candidate_overflow_count() const noexcept { return candidate_overflow_count_; }
  std::uint64_t node_force_overflow_count() const noexcept { return node_force_overflow_count_; }
  const SegmentContactSettings& settings() const noexcept { return settings_; }

 private:
  // A non-degenerate triangle within reach of the current segment (scratch).
  struct Candidate {
    std::uint32_t triangle;
    std::uint32_t vertices[3];
    SegmentTriangleClosest closest;
    float obliquity;  // sine of the angle between q − p and the triangle's normal; < 0 not yet computed
  };

  // A candidate's bounding sphere (centroid, radius about it) of this update.
  struct TriangleSphere {
    std::uint32_t triangle;
    Vec3 centroid;
    float radius;
  };

  SegmentSurfaceContact() = default;
  static bool better(const Candidate& candidate, const Candidate& current, float tie_m) noexcept;
  static bool needs_obliquity(const Candidate& candidate, const Candidate& current, float tie_m) noexcept;
  static void set_obliquity(Candidate& candidate, const TriangleMeshView& mesh) noexcept;
  void clear_outputs() noexcept;
  core::Status segment_contact(const ToolCapsule& capsule, const TriangleMeshView& mesh,
                               std::span<const float> surface_velocities, TriangleBroadPhase& grid) noexcept;
  // Outward angle-weighted pseudo-normal at the closest feature of candidates_[best] (unit).
  Vec3 pseudo_normal(std::size_t best, std::size_t candidate_count, const TriangleMeshView& mesh) const noexcept;
  void add_node_force(std::uint32_t node, const Vec3& force_n) noexcept;

  SegmentContactSettings settings_{};
  std::span<std::uint32_t> candidate_ids_;  // grid query output
  std::array<QueryCache, kMaxSegments> caches_{};  // per segment: its repeated query's candidates
  std::span<Candidate> candidates_;         // within reach, for the current segment
  std::array<std::span<TriangleSphere>, 2> spheres_{};  // the previous segment's, this one's
  unsigned sphere_buffer_ = 0;               // spheres_[sphere_buffer_]: the previous segment's
  std::size_t previous_sphere_count_ = 0;
  std::array<SegmentContact, kMaxSegments> contacts_{};
  std::array<ToolForce, kMaxSegments> tool_forces_{};
  std::array<NodeForce, kMaxNodeForces> node_forces_{};
  std::array<std::int8_t, kMaxSegments> sides_{};
  std::size_t contact_count_ = 0;
  std::size_t node_force_count_ = 0;
  std::uint64_t candidate_overflow_count_ = 0;
  std::uint64_t node_force_overflow_count_ = 0;
};

}  // namespace trainer::model
