// Particle sphere vs triangle shell penalty contact; see particle_contact.hpp.
#include "trainer/model/particle_contact.hpp"

#include "mesh_access.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace trainer::model {
namespace {

using detail::contains;
using detail::corner_angle;
using detail::face_normal;
using detail::triangle_vertices;
using detail::vertex_position;

constexpr std::uint32_t kNoSlot = std::numeric_limits<std::uint32_t>::max();
// A particle's kept candidates: its query box grown by 0.25 mm (a particle's box, some 5 mm
// across, holds tens of the duct's slack-grown boxes; 1 mm more on each side overflowed 64).
// A particle inside the duct's lumen while the duct is held deformed collects 120-180 (its
// box spans most of the lumen's circumference): at 128 that overflowed, and every such query
// traversed twice (the failed fill, then query_within); 256 holds it.
constexpr std::size_t kParticleCacheCapacity = 256;
constexpr float kParticleCacheMarginM = 2.5e-4F;
using detail::kMinDirectionDistanceM;

// How much farther than reach a triangle's box must be for the particle's exact test to be
// certain to reject it. The exact test compares the float distance |c − p| (p the closest point
// computed in float) with reach; p and the distance carry a rounding error of a few ulp of the
// coordinates (|c| + reach bounds them near a contact), and the box distance a few ulp of
// reach. 64 ulp of that magnitude plus 1 µm is far above both, and far below the millimetres
// by which most broad-phase candidates miss.
float particle_box_guard_m(const Vec3& centre_m, float reach_m) noexcept {
  return 1e-6F + 64.0F * std::numeric_limits<float>::epsilon() * (centre_m.cwiseAbs().maxCoeff() + reach_m);
}

bool share_vertex(const std::uint32_t (&first)[3], const std::uint32_t (&second)[3]) noexcept {
  return contains(second, first[0]) || contains(second, first[1]) || contains(second, first[2]);
}

// The two vertex ids of edge `feature` (edge i joins corner i and corner i + 1).
void edge_vertices(const std::uint32_t (&vertices)[3], TriangleFeature feature, std::uint32_t& first,
                   std::uint32_t& second) noexcept {
  const int edge = static_cast<int>(feature) - static_cast<int>(TriangleFeature::edge0);
  first = vertices[edge];
  second = vertices[(edge + 1) % 3];
}

}  // namespace

core::Expected<ParticleSurfaceContact> ParticleSurfaceContact::create(
    const ParticleContactSettings& settings, core::Arena& arena) {
  const auto finite_at_least = [](float value, float minimum, bool strict) {
    return std::isfinite(value) && (strict ? value > minimum : value >= minimum);
  };
  const bool side_known = settings.side == ContactSide::outer ||
                          settings.side == ContactSide::inner || settings.side == ContactSide::both;
  if (settings.max_particles == 0 || settings.max_contacts == 0 || settings.max_nodes == 0 ||
      settings.max_candidates == 0 || !finite_at_least(settings.stiffness_n_per_m, 0.0F, true) ||
      !finite_at_least(settings.damping_n_s_per_m, 0.0F, false) ||
      !finite_at_least(settings.surface_offset_m, 0.0F, false) ||
      !finite_at_least(settings.max_force_n, 0.0F, true) || !side_known) {
    return core::make_error(
        "particle contact: settings max_particles = " + std::to_string(settings.max_particles) +
        ", max_contacts = " + std::to_string(settings.max_contacts) +
        ", max_nodes = " + std::to_string(settings.max_nodes) +
        ", max_candidates = " + std::to_string(settings.max_candidates) +
        ", stiffness_n_per_m = " + std::to_string(settings.stiffness_n_per_m) +
        ", damping_n_s_per_m = " + std::to_string(settings.damping_n_s_per_m) +
        ", surface_offset_m = " + std::to_string(settings.surface_offset_m) +
        ", max_force_n = " + std::to_string(settings.max_force_n) +
        ", side = " + std::to_string(static_cast<int>(settings.side)) +
        ": expected every count ≥ 1, stiffness > 0, damping ≥ 0, offset ≥ 0, max force > 0 "
        "(all finite), side outer/inner/both");
  }
  const auto fail = [](const core::Error& error) {
    return core::make_error("particle contact: arena exhausted: " + error.message);
  };
  auto particle_forces = arena.allocate_array<Vec3>(settings.max_particles, "particle contact forces");
  if (!particle_forces) return fail(particle_forces.error());
  const std::size_t node_force_capacity =
      std::min<std::size_t>(3 * static_cast<std::size_t>(settings.max_contacts), settings.max_nodes);
  auto node_forces = arena.allocate_array<NodeForce>(node_force_capacity, "particle contact node forces");
  if (!node_forces) return fail(node_forces.error());
  auto records = arena.allocate_array<ParticleContactRecord>(settings.max_contacts, "particle contact records");
  if (!records) return fail(records.error());
  auto node_slot = arena.allocate_array<std::uint32_t>(settings.max_nodes, "particle contact node slots");
  if (!node_slot) return fail(node_slot.error());
  auto candidate_ids = arena.allocate_array<std::uint32_t>(settings.max_candidates, "particle contact candidates");
  if (!candidate_ids) return fail(candidate_ids.error());
  auto candidates = arena.allocate_array<Candidate>(settings.max_candidates, "particle contact patches");
  if (!candidates) return fail(candidates.error());

  std::span<QueryCache> caches;
  if (settings.cached_particles > 0) {
    auto carved = arena.allocate_array<QueryCache>(settings.cached_particles, "particle contact query caches");
    if (!carved) return fail(carved.error());
    caches = carved.value();
    for (QueryCache& cache : caches) {
      auto made = QueryCache::create(arena, kParticleCacheCapacity, kParticleCacheMarginM);
      if (!made) return fail(made.error());
      cache = std::move(made).value();
    }
  }

  ParticleSurfaceContact contact;
  contact.caches_ = caches;
  contact.settings_ = settings;
  contact.particle_forces_n_ = particle_forces.value();
  contact.records_ = records.value();
  contact.node_forces_ = node_forces.value();
  contact.node_slot_ = node_slot.value();
  std::fill(contact.node_slot_.begin(), contact.node_slot_.end(), kNoSlot);
  contact.candidate_ids_ = candidate_ids.value();
  contact.candidates_ = candidates.value();
  return contact;
}

void ParticleSurfaceContact::clear_outputs() noexcept {
  for (std::size_t i = 0; i < node_force_count_; ++i) node_slot_[node_forces_[i].node] = kNoSlot;
  node_force_count_ = 0;
  for (std::size_t i = 0; i < particle_count_; ++i) particle_forces_n_[i].setZero();
  particle_count_ = 0;
  contact_count_ = 0;
  clamped_count_ = 0;
  dropped_count_ = 0;
}

std::uint32_t ParticleSurfaceContact::find_patch(std::uint32_t index) noexcept {
  while (candidates_[index].patch != index) {
    candidates_[index].patch = candidates_[candidates_[index].patch].patch;  // path halving
    index = candidates_[index].patch;
  }
  return index;
}

void ParticleSurfaceContact::add_node_force(std::uint32_t node, const Vec3& force_n) noexcept {
  std::uint32_t& slot = node_slot_[node];
  if (slot == kNoSlot) {
    // Cannot overflow: each contact adds at most 3 new nodes and contacts ≤ max_contacts, and
    // there are at most max_nodes distinct nodes; the check keeps that a local guarantee.
    if (node_force_count_ >= node_forces_.size()) return;
    slot = static_cast<std::uint32_t>(node_force_count_++);
    node_forces_[slot] = NodeForce{node, Vec3::Zero()};
  }
  node_forces_[slot].force_n += force_n;
}

core::Status ParticleSurfaceContact::compute(std::span<const Vec3> particles_m,
                                             std::span<const Vec3> particle_velocities_m_per_s,
                                             float radius_m, const TriangleMeshView& mesh,
                                             std::span<const float> surface_velocities_m_per_s,
                                             TriangleBroadPhase& grid, ParticleContactOutput& out,
                                             const Aabb* grid_bounds) noexcept {
  clear_outputs();
  core::Status status = core::Status::ok();
  if (particles_m.size() > settings_.max_particles) {
    status = {core::StatusCode::capacity_exceeded, "particle contact: more particles than max_particles"};
  } else if (mesh.positions_m.size() / 3 > settings_.max_nodes) {
    status = {core::StatusCode::capacity_exceeded, "particle contact: more mesh vertices than max_nodes"};
  } else if (!(std::isfinite(radius_m) && radius_m >= 0.0F)) {
    status = {core::StatusCode::invalid_argument, "particle contact: radius must be finite and >= 0"};
  } else if (!particle_velocities_m_per_s.empty() &&
             particle_velocities_m_per_s.size() != particles_m.size()) {
    status = {core::StatusCode::invalid_argument,
              "particle contact: particle velocities must be empty or one per particle"};
  } else if (!surface_velocities_m_per_s.empty() &&
             surface_velocities_m_per_s.size() != mesh.positions_m.size()) {
    status = {core::StatusCode::invalid_argument,
              "particle contact: surface velocities must be empty or 3 per vertex"};
  }
  if (status.is_ok()) {
    particle_count_ = particles_m.size();
    const float reach_m = radius_m + settings_.surface_offset_m;
    for (std::size_t particle = 0; particle < particle_count_; ++particle) {
      const Vec3& centre = particles_m[particle];
      const Vec3 velocity =
          particle_velocities_m_per_s.empty() ? Vec3::Zero() : particle_velocities_m_per_s[particle];
      core::Status particle_status = core::Status::ok();
      if (!centre.allFinite() || !velocity.allFinite()) {
        particle_status = {core::StatusCode::numeric_error,
                           "particle contact: non-finite particle position or velocity"};
      } else if (grid_bounds != nullptr && !grid_bounds->overlaps(Aabb::around_point(centre, reach_m))) {
        // Outside every box the broad phase holds: it would return no candidate.
      } else if (reach_m > 0.0F) {  // a zero reach touches nothing (contact needs distance < reach)
        particle_status =
            particle_contacts(particle, centre, velocity, reach_m, mesh, surface_velocities_m_per_s, grid);
      }
      if (status.is_ok() && !particle_status.is_ok()) status = particle_status;
    }
  }
  out.contacts = {records_.data(), contact_count_};
  out.particle_forces_n = {particle_forces_n_.data(), particle_count_};
  out.node_forces = {node_forces_.data(), node_force_count_};
  out.contact_count = contact_count_;
  out.clamped_count = clamped_count_;
  out.dropped_count = dropped_count_;
  return status;
}

core::Status ParticleSurfaceContact::particle_contacts(std::size_t particle, const Vec3& centre_m,
                                                       const Vec3& velocity, float reach_m,
                                                       const TriangleMeshView& mesh,
                                                       std::span<const float> surface_velocities,
                                                       TriangleBroadPhase& grid) noexcept {
  std::size_t id_count = 0;
  core::Status status =
      particle < caches_.size()
          ? grid.query_sphere_cached(centre_m, reach_m, caches_[particle], candidate_ids_, id_count)
          : grid.query(Aabb::around_point(centre_m, reach_m), candidate_ids_, id_count);
  // capacity_exceeded: the ids returned are still used (a crowded region keeps its contacts).
  if (!status.is_ok() && status.code() != core::StatusCode::capacity_exceeded) return status;
  if (id_count == 0) return status;  // nothing near (most particles): no patch, no contact

  // Triangles within reach (degenerate ones have no plane: their neighbours carry the contact).
  // Most candidates of the broad phase (boxes grown by its slack) are beyond reach: a
  // triangle whose own box is farther than reach plus a rounding guard (particle_box_guard_m)
  // cannot pass the exact test below, so it is dropped before the closest point is computed.
  // The candidates kept, their order and every value computed for them are those of the exact
  // test alone (docs/collision.md, "Particle ↔ surface contact").
  const float guarded_reach = reach_m + particle_box_guard_m(centre_m, reach_m);
  const float guarded_squared = guarded_reach * guarded_reach;
  std::uint32_t count = 0;
  for (std::size_t k = 0; k < id_count; ++k) {
    Candidate& candidate = candidates_[count];
    if (!triangle_vertices(mesh, candidate_ids_[k], candidate.vertices)) continue;
    const Vec3 a = vertex_position(mesh, candidate.vertices[0]);
    const Vec3 b = vertex_position(mesh, candidate.vertices[1]);
    const Vec3 c = vertex_position(mesh, candidate.vertices[2]);
    const Vec3 below = a.cwiseMin(b).cwiseMin(c) - centre_m;  // > 0 where the box is above
    const Vec3 above = centre_m - a.cwiseMax(b).cwiseMax(c);  // > 0 where the box is below
    if (below.cwiseMax(above).cwiseMax(0.0F).squaredNorm() > guarded_squared) continue;
    if (triangle_is_degenerate(a, b, c)) continue;
    const TrianglePoint closest = closest_point_on_nondegenerate_triangle(centre_m, a, b, c);
    const float distance = (centre_m - closest.point).norm();
    if (!(distance < reach_m)) continue;
    candidate.triangle = candidate_ids_[k];
    candidate.patch = count;
    candidate.distance_m = distance;
    candidate.point_m = closest.point;
    candidate.barycentric = closest.barycentric;
    candidate.feature = closest.feature;
    ++count;
  }
  // Patches: connected through shared vertices (the few triangles near one particle).
  for (std::uint32_t i = 0; i < count; ++i) {
    for (std::uint32_t j = i + 1; j < count; ++j) {
      if (!share_vertex(candidates_[i].vertices, candidates_[j].vertices)) continue;
      const std::uint32_t root_i = find_patch(i);
      const std::uint32_t root_j = find_patch(j);
      if (root_i != root_j) candidates_[std::max(root_i, root_j)].patch = std::min(root_i, root_j);
    }
  }
  // Float rounding of |c − p| for coordinates of magnitude |c| (a few ulp).
  const float tie_m = 4.0F * std::numeric_limits<float>::epsilon() * (centre_m.norm() + reach_m);
  for (std::uint32_t root = 0; root < count; ++root) {
    if (find_patch(root) != root) continue;
    std::uint32_t deepest = root;
    for (std::uint32_t j = root + 1; j < count; ++j) {
      if (find_patch(j) != root) continue;
      const Candidate& best = candidates_[deepest];
      const Candidate& other = candidates_[j];
      // Distances within rounding (tie_m) are equal: a face contact then wins over an edge
      // or vertex one (a centre a hair off a shared edge is the face's, whose normal is
      // exact), then the lower triangle id.
      const bool tie = std::abs(other.distance_m - best.distance_m) <= tie_m;
      const bool other_face = other.feature == TriangleFeature::face;
      const bool best_face = best.feature == TriangleFeature::face;
      if ((!tie && other.distance_m < best.distance_m) ||
          (tie && other_face && !best_face) ||
          (tie && other_face == best_face && other.triangle < best.triangle)) {
        deepest = j;
      }
    }
    const core::Status applied =
        apply_contact(particle, deepest, count, centre_m, velocity, reach_m, mesh, surface_velocities);
    if (status.is_ok() && !applied.is_ok()) status = applied;
  }
  return status;
}

core::Status ParticleSurfaceContact::apply_contact(std::size_t particle, std::uint32_t deepest,
                                                   std::size_t candidate_count, const Vec3& centre_m,
                                                   const Vec3& velocity, float reach_m,
                                                   const TriangleMeshView& mesh,
                                                   std::span<const float> surface_velocities) noexcept {
  const Candidate& contact = candidates_[deepest];
  // Pseudo-normal of the closest feature: the face normal; on an edge the sum of the normals
  // of the triangles sharing it (equal angle weights π); on a vertex the angle-weighted sum.
  // Every triangle incident to the closest point is at most as far, so it is in the list.
  Vec3 pseudo_normal = Vec3::Zero();
  if (contact.feature == TriangleFeature::face) {
    pseudo_normal = face_normal(mesh, contact.vertices);
  } else if (contact.feature <= TriangleFeature::edge2) {
    std::uint32_t first = 0;
    std::uint32_t second = 0;
    edge_vertices(contact.vertices, contact.feature, first, second);
    for (std::size_t j = 0; j < candidate_count; ++j) {
      const Candidate& other = candidates_[j];
      if (contains(other.vertices, first) && contains(other.vertices, second)) {
        pseudo_normal += face_normal(mesh, other.vertices);
      }
    }
  } else {
    const int corner = static_cast<int>(contact.feature) - static_cast<int>(TriangleFeature::vertex0);
    const std::uint32_t vertex = contact.vertices[corner];
    for (std::size_t j = 0; j < candidate_count; ++j) {
      const Candidate& other = candidates_[j];
      if (contains(other.vertices, vertex)) {
        pseudo_normal += corner_angle(mesh, other.vertices, vertex) * face_normal(mesh, other.vertices);
      }
    }
  }
  const float pseudo_length = pseudo_normal.norm();
  // Folded mesh (incident normals cancel): fall back to the contact triangle's own normal.
  pseudo_normal = pseudo_length > 0.0F ? Vec3(pseudo_normal / pseudo_length) : face_normal(mesh, contact.vertices);

  const Vec3 offset = centre_m - contact.point_m;
  const float height = offset.dot(pseudo_normal);
  float side_sign = 1.0F;
  switch (settings_.side) {
    case ContactSide::outer:
      if (height < 0.0F) return core::Status::ok();
      break;
    case ContactSide::inner:
      if (height > 0.0F) return core::Status::ok();
      side_sign = -1.0F;
      break;
    case ContactSide::both:
      side_sign = height < 0.0F ? -1.0F : 1.0F;
      break;
  }
  if (contact_count_ >= settings_.max_contacts) {
    ++dropped_count_;
    return {core::StatusCode::capacity_exceeded, "particle contact: more contacts than max_contacts"};
  }
  const Vec3 normal = contact.distance_m > kMinDirectionDistanceM ? Vec3(offset / contact.distance_m)
                                                                  : Vec3(side_sign * pseudo_normal);
  const float depth = reach_m - contact.distance_m;

  Vec3 relative_velocity = velocity;
  if (!surface_velocities.empty()) {
    for (int corner = 0; corner < 3; ++corner) {
      const std::size_t base = 3 * static_cast<std::size_t>(contact.vertices[corner]);
      relative_velocity -= contact.barycentric[corner] *
                           Vec3(surface_velocities[base], surface_velocities[base + 1], surface_velocities[base + 2]);
    }
  }
  float magnitude = settings_.stiffness_n_per_m * depth -
                    settings_.damping_n_s_per_m * relative_velocity.dot(normal);
  if (!std::isfinite(magnitude) || !normal.allFinite()) {
    return {core::StatusCode::numeric_error, "particle contact: non-finite contact force"};
  }
  ParticleContactRecord& record = records_[contact_count_++];
  record.particle = static_cast<std::uint32_t>(particle);
  record.vertices = {contact.vertices[0], contact.vertices[1], contact.vertices[2]};
  record.barycentric = contact.barycentric;
  record.point_m = contact.point_m;
  record.normal = normal;
  record.distance_m = contact.distance_m;
  record.surface_velocity_m_per_s = velocity - relative_velocity;
  if (!(magnitude > 0.0F)) return core::Status::ok();  // separating fast: the damper never pulls
  if (magnitude > settings_.max_force_n) {
    magnitude = settings_.max_force_n;
    ++clamped_count_;
  }
  const Vec3 force = magnitude * normal;
  particle_forces_n_[particle] += force;
  for (int corner = 0; corner < 3; ++corner) {
    const float weight = contact.barycentric[corner];
    if (weight != 0.0F) add_node_force(contact.vertices[corner], -weight * force);
  }
  return core::Status::ok();
}

core::Status apply_node_forces(std::span<const NodeForce> node_forces, ModalModel& model,
                               std::size_t& applied_count) noexcept {
  applied_count = 0;
  core::Status first_refusal = core::Status::ok();
  for (const NodeForce& entry : node_forces) {
    const core::Status status = model.add_node_force(entry.node, entry.force_n);
    if (status.is_ok()) {
      ++applied_count;
    } else if (first_refusal.is_ok()) {
      first_refusal = status;
    }
  }
  return first_refusal;
}

}  // namespace trainer::model
