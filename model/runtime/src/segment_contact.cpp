// Capsule segments vs thin triangle shell penalty contact; see segment_contact.hpp.
#include "trainer/model/segment_contact.hpp"

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

using detail::kMinDirectionDistanceM;
constexpr float kDirectionUlps = 16.0F;
// Distances within this many ulp of the coordinates are equal when choosing the closest triangle.
constexpr float kTieUlps = 4.0F;

// Obliquities (sines) closer than this are equal when breaking a distance tie.
constexpr float kObliquityTie = 1e-5F;

int feature_rank(TriangleFeature feature) noexcept {
  if (feature == TriangleFeature::face) return 0;
  return feature <= TriangleFeature::edge2 ? 1 : 2;
}

// Sine of the angle between q − p and the triangle's normal; 0 when the segment touches the
// mid-surface (distance 0: there is no direction to judge).
float obliquity(const SegmentTriangleClosest& closest, const Vec3& normal) noexcept {
  if (!(closest.distance_m > 0.0F)) return 0.0F;
  const Vec3 offset = closest.on_segment - closest.on_triangle.point;
  return (offset - offset.dot(normal) * normal).norm() / closest.distance_m;
}

// Marks a candidate whose obliquity (≥ 0 when known) has not been needed yet.
constexpr float kObliquityUnknown = -1.0F;

bool finite_at_least(float value, float minimum, bool strict) noexcept {
  return std::isfinite(value) && (strict ? value > minimum : value >= minimum);
}

core::Error setting_error(const char* field, float value, const char* expected) {
  return core::make_error(std::string("segment contact: ") + field + " = " + std::to_string(value) +
                          ": expected " + expected);
}

}  // namespace

core::Expected<SegmentSurfaceContact> SegmentSurfaceContact::create(const SegmentContactSettings& settings,
                                                                    core::Arena& arena) {
  if (!finite_at_least(settings.surface_half_thickness_m, 0.0F, false)) {
    return setting_error("surface_half_thickness_m", settings.surface_half_thickness_m, "finite and >= 0 (m)");
  }
  if (!finite_at_least(settings.stiffness_n_per_m, 0.0F, true)) {
    return setting_error("stiffness_n_per_m", settings.stiffness_n_per_m, "finite and > 0 (N/m)");
  }
  if (!finite_at_least(settings.damping_n_s_per_m, 0.0F, false)) {
    return setting_error("damping_n_s_per_m", settings.damping_n_s_per_m, "finite and >= 0 (N s/m)");
  }
  if (!finite_at_least(settings.max_force_n, 0.0F, true)) {
    return setting_error("max_force_n", settings.max_force_n, "finite and > 0 (N)");
  }
  if (settings.max_candidates == 0) {
    return core::make_error("segment contact: max_candidates = 0: expected >= 1 (triangles per grid query)");
  }
  const auto fail = [](const core::Error& error) {
    return core::make_error("segment contact: arena exhausted: " + error.message);
  };
  auto candidate_ids = arena.allocate_array<std::uint32_t>(settings.max_candidates, "segment contact candidate ids");
  if (!candidate_ids) return fail(candidate_ids.error());
  auto candidates = arena.allocate_array<Candidate>(settings.max_candidates, "segment contact candidates");
  if (!candidates) return fail(candidates.error());
  auto spheres = arena.allocate_array<TriangleSphere>(2 * static_cast<std::size_t>(settings.max_candidates),
                                                      "segment contact triangle spheres");
  if (!spheres) return fail(spheres.error());

  SegmentSurfaceContact contact;
  contact.spheres_[0] = spheres->first(settings.max_candidates);
  contact.spheres_[1] = spheres->subspan(settings.max_candidates);
  contact.settings_ = settings;
  contact.candidate_ids_ = candidate_ids.value();
  for (QueryCache& cache : contact.caches_) {
    auto made = QueryCache::create(arena);
    if (!made) return fail(made.error());
    cache = std::move(made).value();
  }
  contact.candidates_ = candidates.value();
  return contact;
}

// The closest pair: the smaller distance, unless the two are equal within rounding (tie_m,
// a few ulp of the coordinates). Two different pairs whose distances differ by δ can lie
// √(2 d δ) apart sideways, so for a distance d of a millimetre a tie of 1e-8 m hides a
// sideways offset of several micrometres: a neighbour's pair ending on the edge or vertex next
// to the true projection would tilt the direction by several milliradians and make it jump as
// the segment slides. Ties therefore go to the higher-dimensional feature (face, edge,
// vertex: a vertex pair that ties with an edge or face pair is the clamped end of a
// neighbour, and where the vertex itself is closest its incident edges report it too), then
// to the pair most perpendicular to its triangle (the true projection onto a face or onto the
// shared edge of a flat region is perpendicular, a neighbour's edge point beside it is not),
// then to the lower triangle id so the choice is reproducible.
bool SegmentSurfaceContact::better(const Candidate& candidate, const Candidate& current, float tie_m) noexcept {
  const float difference = candidate.closest.distance_m - current.closest.distance_m;
  if (std::abs(difference) > tie_m) return difference < 0.0F;
  const int candidate_rank = feature_rank(candidate.closest.on_triangle.feature);
  const int current_rank = feature_rank(current.closest.on_triangle.feature);
  if (candidate_rank != current_rank) return candidate_rank < current_rank;
  if (std::abs(candidate.obliquity - current.obliquity) > kObliquityTie) {
    return candidate.obliquity < current.obliquity;
  }
  return candidate.triangle < current.triangle;
}

// better() reads the obliquities only past the distance and the feature rank.
bool SegmentSurfaceContact::needs_obliquity(const Candidate& candidate, const Candidate& current,
                                            float tie_m) noexcept {
  return std::abs(candidate.closest.distance_m - current.closest.distance_m) <= tie_m &&
         feature_rank(candidate.closest.on_triangle.feature) == feature_rank(current.closest.on_triangle.feature);
}

void SegmentSurfaceContact::set_obliquity(Candidate& candidate, const TriangleMeshView& mesh) noexcept {
  if (candidate.obliquity != kObliquityUnknown) return;
  candidate.obliquity = obliquity(candidate.closest, nondegenerate_triangle_normal(vertex_position(mesh, candidate.vertices[0]),
                                                                                  vertex_position(mesh, candidate.vertices[1]),
                                                                                  vertex_position(mesh, candidate.vertices[2])));
}

void SegmentSurfaceContact::clear_outputs() noexcept {
  contact_count_ = 0;
  node_force_count_ = 0;
}

void SegmentSurfaceContact::reset() noexcept {
  clear_outputs();
  sides_.fill(0);
  for (QueryCache& cache : caches_) cache.invalidate();
}

std::size_t SegmentSurfaceContact::write_node_forces(std::span<NodeForce> out) noexcept {
  const std::size_t written = std::min(out.size(), node_force_count_);
  std::copy_n(node_forces_.begin(), written, out.begin());
  node_force_overflow_count_ += node_force_count_ - written;
  return written;
}

void SegmentSurfaceContact::add_node_force(std::uint32_t node, const Vec3& force_n) noexcept {
  for (std::size_t i = 0; i < node_force_count_; ++i) {
    if (node_forces_[i].node == node) {
      node_forces_[i].force_n += force_n;
      return;
    }
  }
  // Cannot overflow: at most 3 contacts of 3 vertices each.
  if (node_force_count_ >= node_forces_.size()) return;
  node_forces_[node_force_count_++] = NodeForce{node, force_n};
}

core::Status SegmentSurfaceContact::update(std::span<const ToolCapsule> capsules, const TriangleMeshView& mesh,
                                           std::span<const float> surface_velocities_m_per_s,
                                           TriangleBroadPhase& grid) noexcept {
  clear_outputs();
  previous_sphere_count_ = 0;  // the mesh may have moved since the last update
  if (capsules.size() > kMaxSegments) {
    return {core::StatusCode::invalid_argument, "segment contact: more than 3 capsules"};
  }
  if (!surface_velocities_m_per_s.empty() && surface_velocities_m_per_s.size() != mesh.positions_m.size()) {
    return {core::StatusCode::invalid_argument, "segment contact: surface velocities must be empty or 3 per vertex"};
  }
  std::array<bool, kMaxSegments> present{};
  for (const ToolCapsule& capsule : capsules) {
    const auto index = static_cast<std::size_t>(capsule.segment);
    if (index >= kMaxSegments || present[index]) {
      return {core::StatusCode::invalid_argument, "segment contact: unknown or repeated tool segment"};
    }
    present[index] = true;
    if (!capsule.start_m.allFinite() || !capsule.end_m.allFinite() || !capsule.start_velocity_m_per_s.allFinite() ||
        !capsule.end_velocity_m_per_s.allFinite()) {
      return {core::StatusCode::numeric_error, "segment contact: non-finite capsule position or velocity"};
    }
    if (!finite_at_least(capsule.radius_m, 0.0F, false)) {
      return {core::StatusCode::invalid_argument, "segment contact: capsule radius must be finite and >= 0"};
    }
  }
  for (std::size_t index = 0; index < kMaxSegments; ++index) {
    if (!present[index]) sides_[index] = 0;  // withdrawn: its contact has ended
  }
  core::Status status = core::Status::ok();
  for (const ToolCapsule& capsule : capsules) {
    const core::Status segment_status = segment_contact(capsule, mesh, surface_velocities_m_per_s, grid);
    if (status.is_ok() && !segment_status.is_ok()) status = segment_status;
  }
  return status;
}

Vec3 SegmentSurfaceContact::pseudo_normal(std::size_t best, std::size_t candidate_count,
                                          const TriangleMeshView& mesh) const noexcept {
  const Candidate& contact = candidates_[best];
  const TriangleFeature feature = contact.closest.on_triangle.feature;
  // Every triangle incident to the closest point is at most as far from the segment, so it
  // is among the candidates (unless the query was truncated: then the sum is partial).
  Vec3 normal = Vec3::Zero();
  if (feature == TriangleFeature::face) {
    normal = face_normal(mesh, contact.vertices);
  } else if (feature <= TriangleFeature::edge2) {
    const int edge = static_cast<int>(feature) - static_cast<int>(TriangleFeature::edge0);
    const std::uint32_t first = contact.vertices[edge];
    const std::uint32_t second = contact.vertices[(edge + 1) % 3];
    for (std::size_t j = 0; j < candidate_count; ++j) {
      const Candidate& other = candidates_[j];
      if (contains(other.vertices, first) && contains(other.vertices, second)) {
        normal += face_normal(mesh, other.vertices);  // equal angle weights π on an edge
      }
    }
  } else {
    const int corner = static_cast<int>(feature) - static_cast<int>(TriangleFeature::vertex0);
    const std::uint32_t vertex = contact.vertices[corner];
    for (std::size_t j = 0; j < candidate_count; ++j) {
      const Candidate& other = candidates_[j];
      if (contains(other.vertices, vertex)) {
        normal += corner_angle(mesh, other.vertices, vertex) * face_normal(mesh, other.vertices);
      }
    }
  }
  const float length = normal.norm();
  // Folded mesh (incident normals cancel): the contact triangle's own normal.
  return length > 0.0F ? Vec3(normal / length) : face_normal(mesh, contact.vertices);
}

core::Status SegmentSurfaceContact::segment_contact(const ToolCapsule& capsule, const TriangleMeshView& mesh,
                                                    std::span<const float> surface_velocities,
                                                    TriangleBroadPhase& grid) noexcept {
  const auto segment_index = static_cast<std::size_t>(capsule.segment);
  std::int8_t& side = sides_[segment_index];
  const float reach_m = capsule.radius_m + settings_.surface_half_thickness_m;
  if (!(reach_m > 0.0F)) {  // contact needs distance < reach: a zero reach touches nothing
    side = 0;
    return core::Status::ok();
  }
  std::size_t id_count = 0;
  core::Status status =
      grid.query_segment_cached(capsule.start_m, capsule.end_m, reach_m, caches_[segment_index], candidate_ids_, id_count);
  if (status.code() == core::StatusCode::capacity_exceeded) {
    ++candidate_overflow_count_;  // the ids returned are still used: a crowded region keeps its contact
  } else if (!status.is_ok()) {
    return status;  // the side memory is kept: the next good cycle continues the contact
  }

  // Non-degenerate triangles within reach (a degenerate one has no plane: its neighbours
  // carry the contact); the closest one by better().
  const float scale_m = std::max(capsule.start_m.norm(), capsule.end_m.norm()) + reach_m;
  const float tie_m = kTieUlps * std::numeric_limits<float>::epsilon() * scale_m;
  const Vec3 axis = capsule.end_m - capsule.start_m;
  const float axis_squared = axis.squaredNorm();
  std::size_t count = 0;
  std::size_t best = 0;
  // Each candidate's bounding sphere, kept for the next capsule of this update (the two jaws
  // share most of their candidates): both lists are in increasing id order, so one pass
  // finds the ones the previous capsule computed, the same floats.
  const std::span<TriangleSphere> previous = spheres_[sphere_buffer_];
  const std::span<TriangleSphere> spheres = spheres_[sphere_buffer_ ^ 1U];
  std::size_t previous_index = 0;
  std::size_t sphere_count = 0;
  for (std::size_t k = 0; k < id_count; ++k) {
    Candidate& candidate = candidates_[count];
    if (!triangle_vertices(mesh, candidate_ids_[k], candidate.vertices)) continue;
    const Vec3 a = vertex_position(mesh, candidate.vertices[0]);
    const Vec3 b = vertex_position(mesh, candidate.vertices[1]);
    const Vec3 c = vertex_position(mesh, candidate.vertices[2]);
    // Cheap rejection before the exact test: the distance from the segment to the centroid
    // minus the triangle's radius about it is a lower bound of the segment–triangle distance.
    // Beyond reach, or beyond the best so far (a triangle containing the final closest point
    // is never beyond it, so the pseudo-normal still sees every incident triangle), skip.
    // tie_m covers the rounding of the bound.
    while (previous_index < previous_sphere_count_ && previous[previous_index].triangle < candidate_ids_[k]) {
      ++previous_index;
    }
    TriangleSphere& sphere = spheres[sphere_count++];
    if (previous_index < previous_sphere_count_ && previous[previous_index].triangle == candidate_ids_[k]) {
      sphere = previous[previous_index];
    } else {
      sphere.triangle = candidate_ids_[k];
      sphere.centroid = (a + b + c) / 3.0F;
      sphere.radius = std::sqrt(std::max({(a - sphere.centroid).squaredNorm(), (b - sphere.centroid).squaredNorm(),
                                          (c - sphere.centroid).squaredNorm()}));
    }
    const Vec3& centroid = sphere.centroid;
    const float bounding_radius = sphere.radius;
    const float along =
        axis_squared > 0.0F ? std::clamp((centroid - capsule.start_m).dot(axis) / axis_squared, 0.0F, 1.0F) : 0.0F;
    const float lower_bound = (capsule.start_m + along * axis - centroid).norm() - bounding_radius;
    const float limit = count > 0 ? std::min(reach_m, candidates_[best].closest.distance_m) : reach_m;
    if (lower_bound > limit + tie_m) continue;
    if (triangle_is_degenerate(a, b, c)) continue;
    // Second bound: the segment's distance to the triangle's plane (when it lies on one side),
    // against the reach only: what it skips the exact test would reject (it is never true at
    // the distance that test computes), so the candidate list is the same as without it. With
    // the best-so-far limit it skipped more (3 % faster in the cbd run) but could then drop a
    // triangle within reach, which only the tie analysis above keeps harmless.
    if (segment_beyond_triangle_plane(capsule.start_m, capsule.end_m, a, b, c, reach_m + tie_m)) continue;
    candidate.closest = closest_points_segment_nondegenerate_triangle(capsule.start_m, capsule.end_m, a, b, c);
    if (!(candidate.closest.distance_m < reach_m)) continue;
    candidate.triangle = candidate_ids_[k];
    // The obliquity only breaks a distance and feature tie (better()): computed then, for
    // both sides, from the same vertices (bit for bit what computing it here gave).
    candidate.obliquity = kObliquityUnknown;
    if (count > 0) {
      Candidate& current = candidates_[best];
      if (needs_obliquity(candidate, current, tie_m)) {
        set_obliquity(candidate, mesh);
        set_obliquity(current, mesh);
      }
      if (better(candidate, current, tie_m)) best = count;
    }
    ++count;
  }
  sphere_buffer_ ^= 1U;
  previous_sphere_count_ = sphere_count;
  if (count == 0) {
    side = 0;  // nothing within reach: the contact (and the memory of its side) has ended
    return status;
  }

  const Candidate& chosen = candidates_[best];
  const SegmentTriangleClosest& closest = chosen.closest;
  const Vec3 outward = pseudo_normal(best, count, mesh);
  const Vec3 offset = closest.on_segment - closest.on_triangle.point;
  const float distance = closest.distance_m;
  const float height = offset.dot(outward);

  const float t = closest.segment_t;
  Vec3 relative_velocity = (1.0F - t) * capsule.start_velocity_m_per_s + t * capsule.end_velocity_m_per_s;
  if (!surface_velocities.empty()) {
    for (int corner = 0; corner < 3; ++corner) {
      const std::size_t base = 3 * static_cast<std::size_t>(chosen.vertices[corner]);
      relative_velocity -= closest.on_triangle.barycentric[corner] *
                           Vec3(surface_velocities[base], surface_velocities[base + 1], surface_velocities[base + 2]);
    }
  }

  const float direction_threshold_m =
      std::max(kMinDirectionDistanceM, kDirectionUlps * std::numeric_limits<float>::epsilon() * scale_m);
  const bool direction_trusted = distance > direction_threshold_m;
  if (side == 0) {
    // The contact begins: the side the segment is on, or, when it is already crossing the
    // mid-surface (or level with it beside an open edge), the side it came from.
    if (direction_trusted && std::abs(height) > direction_threshold_m) {
      side = height > 0.0F ? std::int8_t{1} : std::int8_t{-1};
    } else {
      side = relative_velocity.dot(outward) > 0.0F ? std::int8_t{-1} : std::int8_t{1};
    }
  }
  const float side_sign = side > 0 ? 1.0F : -1.0F;
  const bool behind = side_sign * height < -direction_threshold_m;
  const Vec3 normal = direction_trusted && !behind ? Vec3(offset / distance) : Vec3(side_sign * outward);
  const float depth = reach_m - distance;

  float magnitude = settings_.stiffness_n_per_m * depth - settings_.damping_n_s_per_m * relative_velocity.dot(normal);
  if (!std::isfinite(magnitude) || !normal.allFinite() || !closest.on_triangle.point.allFinite()) {
    return {core::StatusCode::numeric_error, "segment contact: non-finite contact force"};
  }
  magnitude = std::max(magnitude, 0.0F);  // separating fast: the damper never pulls
  const bool clamped = magnitude > settings_.max_force_n;
  if (clamped) magnitude = settings_.max_force_n;
  const Vec3 force = magnitude * normal;

  SegmentContact& record = contacts_[contact_count_];
  record.segment = capsule.segment;
  record.along_m = t * (capsule.end_m - capsule.start_m).norm();
  record.segment_point_m = closest.on_segment;
  record.mesh_point_m = closest.on_triangle.point;
  record.triangle = chosen.triangle;
  record.vertices = {chosen.vertices[0], chosen.vertices[1], chosen.vertices[2]};
  record.barycentric = closest.on_triangle.barycentric;
  record.feature = closest.on_triangle.feature;
  record.normal = normal;
  record.distance_m = distance;
  record.depth_m = depth;
  record.side = side;
  record.clamped = clamped;
  record.force_on_tool_n = force;
  tool_forces_[contact_count_] = ToolForce{capsule.segment, record.along_m, force};
  ++contact_count_;
  for (int corner = 0; corner < 3; ++corner) {
    const float weight = closest.on_triangle.barycentric[corner];
    if (weight != 0.0F && magnitude > 0.0F) add_node_force(chosen.vertices[corner], -weight * force);
  }
  return status;
}

}  // namespace trainer::model
