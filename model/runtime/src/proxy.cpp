// God-object proxy by surface walking; see proxy.hpp.
#include "trainer/model/proxy.hpp"

#include "mesh_access.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace trainer::model {
namespace {

struct TriangleCorners {
  Vec3 a;
  Vec3 b;
  Vec3 c;
};

using detail::vertex_position;

// False when the triangle id or one of its vertices is outside the mesh (a grid built from
// other arrays); the triangle is then skipped.
bool corners_of(const TriangleMeshView& mesh, std::uint32_t triangle, TriangleCorners& corners) noexcept {
  const std::size_t base = 3 * static_cast<std::size_t>(triangle);
  if (base + 2 >= mesh.triangles.size()) return false;
  const std::size_t vertex_count = mesh.positions_m.size() / 3;
  const std::uint32_t i = mesh.triangles[base];
  const std::uint32_t j = mesh.triangles[base + 1];
  const std::uint32_t k = mesh.triangles[base + 2];
  if (i >= vertex_count || j >= vertex_count || k >= vertex_count) return false;
  corners = {vertex_position(mesh, i), vertex_position(mesh, j), vertex_position(mesh, k)};
  return true;
}

// Interior angle of the triangle at `vertex` (0, 1, 2), radians.
float corner_angle(const TriangleCorners& corners, int vertex) noexcept {
  const Vec3* points[3] = {&corners.a, &corners.b, &corners.c};
  const Vec3& apex = *points[vertex];
  const Vec3 first = *points[(vertex + 1) % 3] - apex;
  const Vec3 second = *points[(vertex + 2) % 3] - apex;
  return std::atan2(first.cross(second).norm(), first.dot(second));
}

constexpr float kPi = 3.14159265358979F;

}  // namespace

core::Expected<GodObjectProxy> GodObjectProxy::create(const ProxySettings& settings,
                                                      core::Arena& arena) {
  const auto finite_at_least = [](float value, float minimum, bool strict) {
    return std::isfinite(value) && (strict ? value > minimum : value >= minimum);
  };
  if (!finite_at_least(settings.tool_radius_m, 0.0F, false) ||
      !finite_at_least(settings.stiffness_n_per_m, 0.0F, true) ||
      !finite_at_least(settings.damping_n_s_per_m, 0.0F, false) ||
      !finite_at_least(settings.max_travel_per_update_m, 0.0F, true) ||
      !finite_at_least(settings.contact_tolerance_m, 0.0F, true) || settings.max_candidates == 0) {
    return core::make_error(
        "god-object proxy: settings tool_radius_m = " + std::to_string(settings.tool_radius_m) +
        ", stiffness_n_per_m = " + std::to_string(settings.stiffness_n_per_m) +
        ", damping_n_s_per_m = " + std::to_string(settings.damping_n_s_per_m) +
        ", max_travel_per_update_m = " + std::to_string(settings.max_travel_per_update_m) +
        ", contact_tolerance_m = " + std::to_string(settings.contact_tolerance_m) +
        ", max_candidates = " + std::to_string(settings.max_candidates) +
        ": expected radius ≥ 0, stiffness > 0, damping ≥ 0, travel > 0, tolerance > 0, "
        "candidates ≥ 1, all finite");
  }
  auto candidates = arena.allocate_array<std::uint32_t>(settings.max_candidates, "proxy candidates");
  if (!candidates) {
    return core::make_error("god-object proxy: arena exhausted: " + candidates.error().message);
  }
  GodObjectProxy proxy;
  proxy.settings_ = settings;
  proxy.candidates_ = candidates.value();
  return proxy;
}

void GodObjectProxy::set_free(const Vec3& tool_m) noexcept {
  contact_ = ProxyContact{};
  contact_.proxy_m = tool_m;
  contact_.surface_point_m = tool_m;
}

void GodObjectProxy::reset(const Vec3& tool_m) noexcept {
  set_free(tool_m);
  previous_tool_m_ = tool_m;
  has_previous_ = true;
}

core::Status GodObjectProxy::first_crossing(const Vec3& p0, const Vec3& p1,
                                            const TriangleMeshView& mesh, TriangleBroadPhase& grid,
                                            bool& found, SurfacePoint& hit) noexcept {
  found = false;
  std::size_t count = 0;
  const core::Status status = grid.query(
      Aabb::around_segment(p0, p1, settings_.contact_tolerance_m), candidates_, count);
  if (!status.is_ok()) return status;
  float best_t = INFINITY;
  for (std::size_t index = 0; index < count; ++index) {
    TriangleCorners corners{};
    if (!corners_of(mesh, candidates_[index], corners)) continue;
    const SegmentTriangleHit crossing =
        intersect_segment_triangle(p0, p1, corners.a, corners.b, corners.c);
    if (!crossing.hit || !crossing.front_facing || !(crossing.t < best_t)) continue;
    best_t = crossing.t;
    found = true;
    hit = {crossing.point, crossing.on_triangle.barycentric, candidates_[index],
           crossing.on_triangle.feature};
  }
  return core::Status::ok();
}

core::Status GodObjectProxy::nearest_within_radius(const Vec3& tool_m, const TriangleMeshView& mesh,
                                                   TriangleBroadPhase& grid, bool& found,
                                                   SurfacePoint& nearest) noexcept {
  found = false;
  std::size_t count = 0;
  const float reach = settings_.tool_radius_m + settings_.contact_tolerance_m;
  const core::Status status = grid.query(Aabb::around_point(tool_m, reach), candidates_, count);
  if (!status.is_ok()) return status;
  float best_distance = settings_.tool_radius_m;
  for (std::size_t index = 0; index < count; ++index) {
    TriangleCorners corners{};
    if (!corners_of(mesh, candidates_[index], corners)) continue;
    const TrianglePoint closest = closest_point_on_triangle(tool_m, corners.a, corners.b, corners.c);
    const Vec3 offset = tool_m - closest.point;
    const float distance = offset.norm();
    if (!(distance < best_distance)) continue;
    if (offset.dot(triangle_normal(corners.a, corners.b, corners.c)) < 0.0F) continue;  // behind
    best_distance = distance;
    found = true;
    nearest = {closest.point, closest.barycentric, candidates_[index], closest.feature};
  }
  return core::Status::ok();
}

core::Status GodObjectProxy::walk(const Vec3& tool_m, const TriangleMeshView& mesh,
                                  TriangleBroadPhase& grid, SurfacePoint& point) noexcept {
  const float tolerance = settings_.contact_tolerance_m;
  // A move must shorten the distance by this much: two triangles sharing the minimum (an
  // edge) must not hand the point back and forth.
  const float improvement = 0.01F * tolerance;
  float budget = settings_.max_travel_per_update_m;
  for (int step = 0; step < kMaxWalkSteps; ++step) {
    std::size_t count = 0;
    const core::Status status =
        grid.query(Aabb::around_point(point.point_m, tolerance), candidates_, count);
    if (!status.is_ok()) return status;
    SurfacePoint best = point;
    float best_distance = (tool_m - point.point_m).norm();
    for (std::size_t index = 0; index < count; ++index) {
      TriangleCorners corners{};
      if (!corners_of(mesh, candidates_[index], corners)) continue;
      const TrianglePoint here =
          closest_point_on_triangle(point.point_m, corners.a, corners.b, corners.c);
      if ((here.point - point.point_m).squaredNorm() > tolerance * tolerance) continue;
      const TrianglePoint target = closest_point_on_triangle(tool_m, corners.a, corners.b, corners.c);
      const float distance = (tool_m - target.point).norm();
      if (distance < best_distance - improvement) {
        best_distance = distance;
        best = {target.point, target.barycentric, candidates_[index], target.feature};
      }
    }
    const Vec3 move = best.point_m - point.point_m;
    const float length = move.norm();
    if (best.triangle == point.triangle && length <= improvement) {
      point.feature = best.feature;
      point.barycentric = best.barycentric;
      break;
    }
    if (length > budget) {
      // Part of the way: the segment lies in best's triangle (it holds both ends).
      point.point_m += move * (budget / length);
      point.triangle = best.triangle;
      TriangleCorners corners{};
      if (corners_of(mesh, best.triangle, corners)) {
        const TrianglePoint here =
            closest_point_on_triangle(point.point_m, corners.a, corners.b, corners.c);
        point.feature = here.feature;
        point.barycentric = here.barycentric;
      }
      break;
    }
    budget -= length;
    const bool moved = length > improvement || best.triangle != point.triangle;
    point = best;
    if (!moved) break;
  }
  return core::Status::ok();
}

core::Status GodObjectProxy::pseudo_normal(const SurfacePoint& point, const TriangleMeshView& mesh,
                                           TriangleBroadPhase& grid, Vec3& normal) noexcept {
  normal = Vec3::Zero();
  const float tolerance = settings_.contact_tolerance_m;
  std::size_t count = 0;
  const core::Status status =
      grid.query(Aabb::around_point(point.point_m, tolerance), candidates_, count);
  if (!status.is_ok()) return status;
  for (std::size_t index = 0; index < count; ++index) {
    TriangleCorners corners{};
    if (!corners_of(mesh, candidates_[index], corners)) continue;
    const TrianglePoint here =
        closest_point_on_triangle(point.point_m, corners.a, corners.b, corners.c);
    if ((here.point - point.point_m).squaredNorm() > tolerance * tolerance) continue;
    // Angle-weighted pseudo-normal: the share of the full angle around the point that this
    // triangle covers (2π inside a face, π on an edge, the corner angle at a vertex).
    float weight = 2.0F * kPi;
    if (here.feature >= TriangleFeature::vertex0) {
      weight = corner_angle(corners, static_cast<int>(here.feature) -
                                         static_cast<int>(TriangleFeature::vertex0));
    } else if (here.feature != TriangleFeature::face) {
      weight = kPi;
    }
    normal += weight * triangle_normal(corners.a, corners.b, corners.c);
  }
  return core::Status::ok();
}

void GodObjectProxy::set_contact(const SurfacePoint& point, const Vec3& direction,
                                 const Vec3& tool_m, const Vec3& tool_velocity_m_per_s) noexcept {
  ProxyContact next;
  next.in_contact = true;
  next.surface_point_m = point.point_m;
  next.barycentric = point.barycentric;
  next.proxy_m = point.point_m + settings_.tool_radius_m * direction;
  next.normal = direction;
  next.triangle = point.triangle;
  next.feature = point.feature;
  const Vec3 spring = settings_.stiffness_n_per_m * (next.proxy_m - tool_m);
  const float spring_normal = spring.dot(direction);
  // The damper acts along the normal and may only push (a pulling damper makes the surface
  // sticky when the tool withdraws fast).
  const float damped_normal = std::max(
      0.0F, spring_normal - settings_.damping_n_s_per_m * tool_velocity_m_per_s.dot(direction));
  next.force_n = spring + (damped_normal - spring_normal) * direction;
  next.depth_m = (next.proxy_m - tool_m).norm();
  contact_ = next;
}

core::Status GodObjectProxy::update(const Vec3& tool_m, const Vec3& tool_velocity_m_per_s,
                                    const TriangleMeshView& mesh, TriangleBroadPhase& grid) noexcept {
  if (!tool_m.allFinite() || !tool_velocity_m_per_s.allFinite()) {
    return {core::StatusCode::numeric_error, "proxy: non-finite tool position or velocity"};
  }
  if (!has_previous_) reset(tool_m);
  const core::Status status = advance(tool_m, tool_velocity_m_per_s, mesh, grid, true);
  if (status.is_ok()) previous_tool_m_ = tool_m;
  return status;
}

core::Status GodObjectProxy::advance(const Vec3& tool_m, const Vec3& tool_velocity_m_per_s,
                                     const TriangleMeshView& mesh, TriangleBroadPhase& grid,
                                     bool may_restart) noexcept {
  const float radius = settings_.tool_radius_m;
  Vec3 free_from = previous_tool_m_;

  if (contact_.in_contact) {
    SurfacePoint point{contact_.surface_point_m, contact_.barycentric, contact_.triangle,
                       contact_.feature};
    TriangleCorners current{};
    if (corners_of(mesh, point.triangle, current)) {  // follow the deformed triangle
      point.point_m = point.barycentric[0] * current.a + point.barycentric[1] * current.b +
                      point.barycentric[2] * current.c;
    }
    core::Status status = walk(tool_m, mesh, grid, point);
    Vec3 normal = Vec3::Zero();
    if (status.is_ok()) status = pseudo_normal(point, mesh, grid, normal);
    if (!status.is_ok()) return status;  // keep the last contact: never escape on overflow
    if (normal.squaredNorm() > 0.0F) {
      normal.normalize();
    } else {
      normal = contact_.normal;  // a degenerate patch: keep the last direction
    }
    const Vec3 offset = tool_m - point.point_m;
    const float distance = offset.norm();
    const bool inside = offset.dot(normal) < 0.0F;
    if (inside || distance < radius) {
      // Direction of the proxy centre from the surface point, continuous across features.
      // On a face that is exactly the face normal (not the rounded offset direction); on an
      // edge or vertex it lies in the normal cone.
      Vec3 direction = normal;
      TriangleCorners walked{};
      if (point.feature == TriangleFeature::face && corners_of(mesh, point.triangle, walked) &&
          !triangle_is_degenerate(walked.a, walked.b, walked.c)) {
        direction = triangle_normal(walked.a, walked.b, walked.c);
      } else if (distance > settings_.contact_tolerance_m) {
        direction = (inside ? -offset : offset) / distance;
      }
      set_contact(point, direction, tool_m, tool_velocity_m_per_s);
      return core::Status::ok();
    }
    // Left the surface: continue as a free tool from just in front of it, so a tool that
    // leaves one wall and crosses another in the same cycle is still caught.
    if (!may_restart) {
      set_free(tool_m);
      return core::Status::ok();
    }
    free_from = point.point_m + settings_.contact_tolerance_m * normal;
  }

  bool found = false;
  SurfacePoint start{};
  core::Status status = first_crossing(free_from, tool_m, mesh, grid, found, start);
  if (status.is_ok() && !found && radius > 0.0F) {
    status = nearest_within_radius(tool_m, mesh, grid, found, start);
  }
  if (!status.is_ok()) return status;
  if (!found) {
    set_free(tool_m);
    return core::Status::ok();
  }
  TriangleCorners corners{};
  Vec3 face_normal = corners_of(mesh, start.triangle, corners)
                         ? triangle_normal(corners.a, corners.b, corners.c)
                         : Vec3::Zero();
  if (face_normal.isZero()) face_normal = Vec3::UnitZ();  // unreachable: a hit needs a plane
  // Contact starts at `start` (reachable only with may_restart: the nested call below enters
  // the contact branch); the contact branch walks from there in this same cycle.
  set_contact(start, face_normal, tool_m, tool_velocity_m_per_s);
  const core::Status walked = advance(tool_m, tool_velocity_m_per_s, mesh, grid, false);
  if (!walked.is_ok()) set_contact(start, face_normal, tool_m, tool_velocity_m_per_s);
  return walked;
}

}  // namespace trainer::model
