// God-object proxy of a point (or ball) tool on a triangle mesh with outward normals
// (Zilles & Salisbury 1995, Ruspini et al. 1997; Basdogan Fig. 10; METHODS.md §4). The
// proxy is where the tool would be if the surface could not be penetrated; the force on the
// tool is F = k (proxy − tool) − b (v · n) n, the damping clipped so it never pulls.
//
// The god-object is the point of the surface locally closest to the tool, reached from where
// the tool entered: Zilles & Salisbury find it by moving towards the tool and projecting on
// the planes of up to three constraining triangles. We compute the same constrained local
// minimum by walking the surface: from the proxy's current point, move to the closest point
// (to the tool) on any triangle touching that point, while the distance decreases. On a face
// the walk stops at the projection (one plane), on an edge between two triangles (two planes),
// on a vertex (three or more planes, also a concave corner). The walk never leaves the
// surface, so a deep tool never snaps to the far side of a thin object, and over shared
// edges, flat regions and concave creases the proxy moves continuously (it is a projection:
// it moves at most as far as the tool).
//
// Convex creases: with the tool below the surface, the local minimum on one side of a ridge
// ceases to exist when its foot reaches the ridge, and the god-object must move to the other
// side (Zilles & Salisbury's proxy does the same through the plane extension). That move is
// rate-limited by max_travel_per_update_m, so the force changes per update by at most
// k (|Δtool| + max_travel_per_update_m) and its direction turns over several updates
// instead of jumping. Choose the cap at about twice the tool's largest travel per cycle
// (the default 0.5 mm suits a tool up to 0.25 m/s at 1 kHz); kMaxWalkSteps bounds the work.
//
//   free:     the proxy is the tool. Contact starts when the segment from the previous tool
//             position to the new one crosses a triangle from its outward side (so a tool
//             moving fast through a thin wall is still caught), or — for a radius > 0 — when
//             the tool centre comes within the radius of a triangle on its outward side.
//   contact:  walk; the tool is inside when it lies behind the surface at the walked point
//             (sign against the angle-weighted pseudo-normal there, Bærentzen & Aanæs 2005)
//             or closer than the radius. The proxy centre is the surface point + radius ·
//             normal. Contact ends (proxy = tool, zero force) when the tool is in front of
//             the surface and at least the radius away.
//
// Between updates the surface point is kept as barycentric coordinates in its triangle, so
// it moves with the deforming mesh.
//
// The caller rebuilds the BucketGrid over the current vertex positions before update() (the
// mesh deforms); the proxy queries it for candidates. Runtime code: float, noexcept, no heap
// after create(); one thread owns the proxy. Units SI, all positions in the mesh's frame.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/core/status.hpp"
#include "trainer/model/bucket_grid.hpp"
#include "trainer/model/geometry.hpp"

namespace trainer::model {

// Views of the current mesh (the grid was rebuilt from the same arrays).
struct TriangleMeshView {
  std::span<const float> positions_m;        // 3n: x y z per vertex
  std::span<const std::uint32_t> triangles;  // 3m vertex indices, counter-clockwise from outside
};

struct ProxySettings {
  float tool_radius_m = 0.0F;              // ≥ 0: 0 is a point tool
  float stiffness_n_per_m = 0.0F;          // > 0
  float damping_n_s_per_m = 0.0F;          // ≥ 0, along the contact normal only
  float max_travel_per_update_m = 0.0005F;  // > 0: cap on the proxy's walk per update
  float contact_tolerance_m = 1e-6F;       // > 0: a triangle "touches" a point this close
  std::uint32_t max_candidates = 256;      // ≥ 1: triangles one grid query may return
};

struct ProxyContact {
  bool in_contact = false;
  Vec3 proxy_m = Vec3::Zero();       // god-object centre (the tool itself when free)
  Vec3 surface_point_m = Vec3::Zero();
  // Of surface_point_m in `triangle` (weights of its vertices 0, 1, 2): the point follows the
  // triangle when the mesh deforms, and splits the reaction over the three vertices.
  Vec3 barycentric = Vec3::Zero();
  Vec3 normal = Vec3::Zero();        // unit, outward at the surface point; zero when free
  Vec3 force_n = Vec3::Zero();       // on the tool
  float depth_m = 0.0F;              // |proxy − tool| when in contact
  std::uint32_t triangle = 0;        // the proxy's triangle
  TriangleFeature feature = TriangleFeature::face;
};

class GodObjectProxy {
 public:
  static constexpr int kMaxWalkSteps = 32;

  static core::Expected<GodObjectProxy> create(const ProxySettings& settings, core::Arena& arena);

  // ---- RT path: noexcept, no heap ----

  // One haptic cycle: the tool centre moved to `tool_m` (velocity for the damping). Status:
  // numeric_error for a non-finite input (the proxy is left as it was); capacity_exceeded
  // when a grid query overflowed max_candidates (the proxy stays where it was, still in
  // contact if it was, so a crowded region never lets the tool escape); invalid_argument
  // from the grid. The contact is valid after every call, whatever the status.
  core::Status update(const Vec3& tool_m, const Vec3& tool_velocity_m_per_s,
                      const TriangleMeshView& mesh, TriangleBroadPhase& grid) noexcept;

  // Free at `tool_m`: no contact, no force; the next update starts from there.
  void reset(const Vec3& tool_m) noexcept;

  const ProxyContact& contact() const noexcept { return contact_; }
  const ProxySettings& settings() const noexcept { return settings_; }

 private:
  struct SurfacePoint {
    Vec3 point_m = Vec3::Zero();
    Vec3 barycentric = Vec3(1.0F, 0.0F, 0.0F);
    std::uint32_t triangle = 0;
    TriangleFeature feature = TriangleFeature::face;
  };

  GodObjectProxy() = default;
  // First triangle crossed from its outward side along p0 → p1 (smallest t).
  core::Status first_crossing(const Vec3& p0, const Vec3& p1, const TriangleMeshView& mesh,
                              TriangleBroadPhase& grid, bool& found, SurfacePoint& hit) noexcept;
  // Closest point to `tool_m` on the triangles within the radius, in front of them.
  core::Status nearest_within_radius(const Vec3& tool_m, const TriangleMeshView& mesh,
                                     TriangleBroadPhase& grid, bool& found, SurfacePoint& nearest) noexcept;
  // Walks from `start` towards the local minimum of the distance to `tool_m`.
  core::Status walk(const Vec3& tool_m, const TriangleMeshView& mesh, TriangleBroadPhase& grid,
                    SurfacePoint& point) noexcept;
  // Angle-weighted pseudo-normal at a surface point (unnormalised; zero if none).
  core::Status pseudo_normal(const SurfacePoint& point, const TriangleMeshView& mesh,
                             TriangleBroadPhase& grid, Vec3& normal) noexcept;
  void set_free(const Vec3& tool_m) noexcept;
  void set_contact(const SurfacePoint& point, const Vec3& direction, const Vec3& tool_m,
                   const Vec3& tool_velocity_m_per_s) noexcept;
  // The cycle's logic; `may_restart` allows one nested start of contact (bounded recursion).
  core::Status advance(const Vec3& tool_m, const Vec3& tool_velocity_m_per_s,
                       const TriangleMeshView& mesh, TriangleBroadPhase& grid, bool may_restart) noexcept;

  ProxySettings settings_{};
  std::span<std::uint32_t> candidates_;
  ProxyContact contact_{};
  Vec3 previous_tool_m_ = Vec3::Zero();
  bool has_previous_ = false;
};

}  // namespace trainer::model
