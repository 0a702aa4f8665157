// Point-based contact of particle spheres (the catheter's particles) against a triangle shell
// such as the duct (METHODS.md §4: "each particle sphere against the duct's inner surface,
// force from penetration depth"). Owns the per-cycle contact search, the penalty force on
// every particle and the equal and opposite forces on the mesh nodes.
//
// The mesh is the shell's mid-surface with outward normals; the wall surface lies
// surface_offset_m (half the shell thickness) from it on the side the particle is on. A
// particle of radius r touches the wall when its centre is closer than reach = r + offset to
// the mid-surface, on the allowed side (`side`: inner = against the outward normals, the
// lumen of a duct; outer; both).
//
// Contact rule (one force per touched region, never one per triangle): for each particle the
// triangles within reach are grouped into patches connected through shared vertices, and each
// patch contributes only its deepest contact (smallest distance to the mid-surface; distances
// equal within float rounding prefer a face-region contact, then the lowest triangle id). A particle on a shared edge or vertex therefore gets one force, not
// one per incident triangle, and the force magnitude k·(reach − distance to the mesh) is
// continuous as the particle slides across edges. Two separate patches (a particle squeezed
// between opposite walls) both push. Which side the particle is on is decided at that closest
// point against the angle-weighted pseudo-normal (Bærentzen & Aanæs 2005) of the feature it
// lies on (face, edge or vertex), so a particle outside a convex edge is never mistaken for one
// inside. Limits of the rule: in a concave crease (the inside of a polygonal tube seen from the
// lumen) the direction is the nearer face's normal and flips to the other face's normal on the
// bisector (the magnitude stays continuous, the direction jumps by the dihedral angle, and a
// particle pushed into the crease chatters about the bisector); a particle whose centre crosses
// the mid-surface is on the other side and loses the contact, so the caller keeps a particle's
// travel per cycle and its penetration below reach (the clamp max_force_n / stiffness should
// be below reach for that reason).
//
// Force on the particle, along the contact normal n (unit, from the mid-surface point p
// towards the centre c; the pseudo-normal turned to the particle's side when c lies on the
// mesh): f = k·(reach − |c − p|) − b·((v_particle − v_surface(p))·n), clipped at 0 (the
// damper never pulls) and at max_force_n. The reaction −f·n goes to the three vertices of the
// contact triangle with the barycentric weights of p, so the total force and (because the
// force line passes through p and c) the moment about any point are conserved to rounding.
// Node forces are merged per node into a compact list.
//
// Runtime code: float, noexcept, no heap after create(), storage carved from a core::Arena,
// fixed capacities checked at create() and at every call. One thread owns the object. Units
// SI; every position in the mesh's (model) frame.
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
#include "trainer/model/geometry.hpp"
#include "trainer/model/modal_model.hpp"
#include "trainer/model/proxy.hpp"  // TriangleMeshView
#include "trainer/model/triangle_bvh.hpp"  // QueryCache

namespace trainer::model {

// Which side of the mid-surface mesh the particles live on.
enum class ContactSide : std::uint8_t {
  outer = 0,  // along the outward normals
  inner = 1,  // against them: inside a duct's lumen
  both = 2,   // whichever side the centre is on (no memory: a centre crossing the mesh flips)
};

struct ParticleContactSettings {
  std::uint32_t max_particles = 0;     // ≥ 1: particles one compute() may take
  std::uint32_t max_contacts = 0;      // ≥ 1: kept particle–patch contacts per compute()
  std::uint32_t max_nodes = 0;         // ≥ 1: mesh vertices (node ids are below this)
  std::uint32_t max_candidates = 256;  // ≥ 1: triangles one grid query may return per particle
  float stiffness_n_per_m = 0.0F;      // > 0
  float damping_n_s_per_m = 0.0F;      // ≥ 0, along the contact normal only
  float surface_offset_m = 0.0F;       // ≥ 0: half the shell thickness
  float max_force_n = 0.0F;            // > 0: clamp per contact
  ContactSide side = ContactSide::inner;
  // Particles 0 .. cached_particles − 1 keep their broad-phase candidates from compute to
  // compute (TriangleBroadPhase::query_sphere_cached: a particle moves little per cycle); one
  // QueryCache each from the arena. 0: every query from scratch.
  std::uint32_t cached_particles = 0;
};

// Force on one mesh node (N, model frame); each node appears once per compute().
struct NodeForce {
  std::uint32_t node = 0;
  Vec3 force_n = Vec3::Zero();
};

// One kept particle–patch contact, as found (whatever force it gave): enough for a caller
// that evaluates the contact itself at a finer step (the catheter's substeps, through
// model::ContactPlane) and returns the reaction to the three vertices.
struct ParticleContactRecord {
  std::uint32_t particle = 0;
  std::array<std::uint32_t, 3> vertices{};
  Vec3 barycentric = Vec3::Zero();  // of point_m in the triangle
  Vec3 point_m = Vec3::Zero();      // closest point on the mid-surface
  Vec3 normal = Vec3::UnitZ();      // unit, from point_m towards the particle's side
  float distance_m = 0.0F;          // |centre − point_m|
  Vec3 surface_velocity_m_per_s = Vec3::Zero();  // of point_m (zero without surface velocities)
};

// Results of the last compute(): views into the object's storage, valid until the next call.
struct ParticleContactOutput {
  std::span<const ParticleContactRecord> contacts;  // one per kept contact, contact_count of them
  std::span<const Vec3> particle_forces_n;  // one per particle, in input order
  std::span<const NodeForce> node_forces;   // merged reactions, Σ = −Σ particle forces
  std::uint32_t contact_count = 0;          // kept contacts (≤ max_contacts)
  std::uint32_t clamped_count = 0;          // of those, limited by max_force_n
  std::uint32_t dropped_count = 0;          // found beyond max_contacts (not applied)
};

class ParticleSurfaceContact {
 public:
  // Setup path: checks the settings (the message names each value and the expected range)
  // and carves every array from `arena`.
  static core::Expected<ParticleSurfaceContact> create(const ParticleContactSettings& settings,
                                                       core::Arena& arena);

  // ---- RT path: noexcept, no heap ----

  // One cycle. `particle_velocities_m_per_s`: one per particle, or empty (at rest).
  // `surface_velocities_m_per_s`: 3n like mesh.positions_m, or empty (rigid, at rest). The
  // caller rebuilt `grid` over mesh.positions_m. `out` is always valid afterwards.
  // Status (the first problem found; the rest of the work is still done, so the output stays
  // consistent — every applied particle force has its node reactions):
  //   invalid_argument  velocity spans of the wrong size, radius negative or non-finite
  //                     (nothing computed, all forces zero);
  //   capacity_exceeded more particles than max_particles or vertices than max_nodes
  //                     (nothing computed); a grid query beyond max_candidates (that particle
  //                     uses the candidates returned); more contacts than max_contacts (the
  //                     extra ones are dropped and counted);
  //   numeric_error     a non-finite particle position/velocity or contact force (that
  //                     particle or contact gets no force).
  // `grid_bounds` (optional): a box that holds the box of every triangle `grid` can return
  // (TriangleBvh::bounds() while it is ready). A particle whose reach box misses it is not
  // queried: the broad phase would return nothing for it (most of a catheter lies outside the
  // duct's box), so the output is the same with or without it.
  core::Status compute(std::span<const Vec3> particles_m,
                       std::span<const Vec3> particle_velocities_m_per_s, float radius_m,
                       const TriangleMeshView& mesh, std::span<const float> surface_velocities_m_per_s,
                       TriangleBroadPhase& grid, ParticleContactOutput& out,
                       const Aabb* grid_bounds = nullptr) noexcept;

  const ParticleContactSettings& settings() const noexcept { return settings_; }

 private:
  // A triangle within reach of the current particle (scratch, one particle at a time).
  struct Candidate {
    std::uint32_t triangle;
    std::uint32_t patch;  // union-find parent (index into the candidate scratch)
    std::uint32_t vertices[3];
    float distance_m;
    Vec3 point_m;      // closest point on the triangle (mid-surface)
    Vec3 barycentric;  // of point_m in the triangle
    TriangleFeature feature;
  };

  ParticleSurfaceContact() = default;
  void clear_outputs() noexcept;
  std::uint32_t find_patch(std::uint32_t index) noexcept;
  // Handles one particle; returns the first problem (contacts beyond capacity are counted).
  core::Status particle_contacts(std::size_t particle, const Vec3& centre_m, const Vec3& velocity,
                                 float reach_m, const TriangleMeshView& mesh,
                                 std::span<const float> surface_velocities, TriangleBroadPhase& grid) noexcept;
  // Applies the deepest contact of one patch (index into the candidate scratch).
  core::Status apply_contact(std::size_t particle, std::uint32_t deepest, std::size_t candidate_count,
                             const Vec3& centre_m, const Vec3& velocity, float reach_m,
                             const TriangleMeshView& mesh,
                             std::span<const float> surface_velocities) noexcept;
  void add_node_force(std::uint32_t node, const Vec3& force_n) noexcept;

  ParticleContactSettings settings_{};
  std::span<Vec3> particle_forces_n_;
  std::span<ParticleContactRecord> records_;  // max_contacts
  std::span<NodeForce> node_forces_;        // 3 · max_contacts entries at most
  std::span<std::uint32_t> node_slot_;      // per node: index in node_forces_, or kNoSlot
  std::span<std::uint32_t> candidate_ids_;  // grid query output
  std::span<QueryCache> caches_;            // settings.cached_particles
  std::span<Candidate> candidates_;         // within reach, for the current particle
  std::size_t particle_count_ = 0;
  std::size_t node_force_count_ = 0;
  std::uint32_t contact_count_ = 0;
  std::uint32_t clamped_count_ = 0;
  std::uint32_t dropped_count_ = 0;
};

// Adds every entry to `model` (ModalModel::add_node_force each). Applies all it can and
// returns the first refusal (unknown node, more loaded nodes than the model takes, a
// non-surface node with static correction); `applied_count` says how many were accepted.
core::Status apply_node_forces(std::span<const NodeForce> node_forces, ModalModel& model,
                               std::size_t& applied_count) noexcept;

}  // namespace trainer::model
