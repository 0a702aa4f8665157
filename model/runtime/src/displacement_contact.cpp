// Displacement-driven tip contact on a deformable surface (displacement_contact.hpp).
#include "trainer/model/displacement_contact.hpp"

#include <algorithm>
#include <limits>
#include <string>

#include "trainer/model/geometry.hpp"

namespace trainer::model {

namespace {

Vec3 vertex(std::span<const float> positions, std::uint32_t node) noexcept {
  const std::size_t base = 3 * static_cast<std::size_t>(node);
  return {positions[base], positions[base + 1], positions[base + 2]};
}

struct Corners {
  std::uint32_t node[3];
  Vec3 a, b, c;
};

Corners corners(const TriangleMeshView& mesh, std::uint32_t triangle) noexcept {
  Corners result{};
  for (std::size_t i = 0; i < 3; ++i) {
    result.node[i] = mesh.triangles[3 * static_cast<std::size_t>(triangle) + i];
  }
  result.a = vertex(mesh.positions_m, result.node[0]);
  result.b = vertex(mesh.positions_m, result.node[1]);
  result.c = vertex(mesh.positions_m, result.node[2]);
  return result;
}

}  // namespace

core::Expected<DisplacementContact> DisplacementContact::create(
    const DisplacementContactSettings& settings, std::span<const std::uint32_t> fixed_nodes,
    core::Arena& arena) {
  if (!(settings.tip_radius_m >= 0.0F) || !(settings.tip_radius_m < 1.0F)) {
    return core::make_error("displacement contact: tip_radius_m " +
                            std::to_string(settings.tip_radius_m) + ", expected [0, 1) m");
  }
  if (settings.max_candidates == 0) {
    return core::make_error("displacement contact: max_candidates must be > 0");
  }
  for (std::size_t i = 1; i < fixed_nodes.size(); ++i) {
    if (fixed_nodes[i] <= fixed_nodes[i - 1]) {
      return core::make_error("displacement contact: fixed nodes must be strictly increasing");
    }
  }
  auto candidates = arena.allocate_array<std::uint32_t>(settings.max_candidates,
                                                        "displacement contact candidates");
  if (!candidates) return std::move(candidates).error();
  DisplacementContact contact;
  contact.settings_ = settings;
  contact.fixed_nodes_ = fixed_nodes;
  contact.candidates_ = candidates.value();
  return contact;
}

bool DisplacementContact::is_fixed(std::uint32_t node) const noexcept {
  return std::binary_search(fixed_nodes_.begin(), fixed_nodes_.end(), node);
}

core::Status DisplacementContact::update(const TriangleMeshView& deformed, TriangleBroadPhase& grid,
                                         const Vec3& previous_tip_m, const Vec3& tip_m) noexcept {
  if (!tip_m.allFinite() || !previous_tip_m.allFinite()) {
    in_contact_ = false;
    return core::Status{core::StatusCode::numeric_error, "non-finite tool tip"};
  }
  if (in_contact_) return core::Status{};
  const float radius = settings_.tip_radius_m;
  std::size_t count = 0;
  // A truncated candidate list still holds real candidates: use them, report the overflow.
  const core::Status queried =
      grid.query(Aabb::around_segment(previous_tip_m, tip_m, radius), candidates_, count);
  if (!queried.is_ok() && queried.code() != core::StatusCode::capacity_exceeded) return queried;
  const std::size_t triangle_count = deformed.triangles.size() / 3;
  // The path crossing the surface from outside: the earliest crossing wins; equal ones (through
  // a shared edge or vertex) go to the lowest triangle id, so the answer does not depend on
  // the order the grid returns candidates in.
  float best_t = std::numeric_limits<float>::infinity();
  float best_depth = 0.0F;
  bool found = false;
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint32_t id = candidates_[i];
    if (id >= triangle_count) continue;
    const Corners tri = corners(deformed, id);
    const SegmentTriangleHit hit =
        intersect_segment_triangle(previous_tip_m, tip_m, tri.a, tri.b, tri.c);
    if (hit.hit && hit.front_facing && (hit.t < best_t || (found && hit.t == best_t && id < triangle_))) {
      best_t = hit.t;
      triangle_ = id;
      barycentric_ = hit.on_triangle.barycentric;
      found = true;
    }
  }
  // Else the tip sphere touching a triangle from its outward side: the deepest wins (ties as
  // above).
  if (!found && radius > 0.0F) {
    for (std::size_t i = 0; i < count; ++i) {
      const std::uint32_t id = candidates_[i];
      if (id >= triangle_count) continue;
      const Corners tri = corners(deformed, id);
      const SphereTriangleContact touch = sphere_triangle_contact(tip_m, radius, tri.a, tri.b, tri.c);
      if (!touch.in_contact) continue;
      if (triangle_normal(tri.a, tri.b, tri.c).dot(tip_m - touch.closest.point) <= 0.0F) continue;
      if (touch.depth_m > best_depth || (found && touch.depth_m == best_depth && id < triangle_)) {
        best_depth = touch.depth_m;
        triangle_ = id;
        barycentric_ = touch.closest.barycentric;
        found = true;
      }
    }
  }
  if (found) {
    // A contact on a triangle with no free node cannot be imposed: it is the clamp, ignore it.
    const Corners tri = corners(deformed, triangle_);
    if (is_fixed(tri.node[0]) && is_fixed(tri.node[1]) && is_fixed(tri.node[2])) found = false;
  }
  if (found) {
    in_contact_ = true;
    ++onsets_;
  }
  return queried.is_ok() ? core::Status{} : queried;
}

std::size_t DisplacementContact::targets(const TriangleMeshView& deformed,
                                         std::span<const float> rest_positions_m,
                                         const Vec3& tip_m,
                                         std::span<ImposedDisplacement> out) const noexcept {
  if (!in_contact_ || out.size() < kMaxTargets) return 0;
  const Corners now = corners(deformed, triangle_);
  const Vec3 rest = barycentric_[0] * vertex(rest_positions_m, now.node[0]) +
                    barycentric_[1] * vertex(rest_positions_m, now.node[1]) +
                    barycentric_[2] * vertex(rest_positions_m, now.node[2]);
  const Vec3 normal = triangle_normal(now.a, now.b, now.c);
  const Vec3 imposed = tip_m - settings_.tip_radius_m * normal - rest;
  if (!imposed.allFinite()) return 0;
  std::size_t count = 0;
  for (const std::uint32_t node : now.node) {
    if (is_fixed(node)) continue;
    out[count++] = ImposedDisplacement{node, imposed};
  }
  return count;
}

void DisplacementContact::observe_force(const TriangleMeshView& deformed,
                                        const Vec3& force_on_tissue_n) noexcept {
  if (!in_contact_) return;
  const Corners now = corners(deformed, triangle_);
  if (triangle_normal(now.a, now.b, now.c).dot(force_on_tissue_n) > 0.0F) in_contact_ = false;
}

}  // namespace trainer::model
