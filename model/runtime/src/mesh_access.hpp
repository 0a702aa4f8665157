// Private to model/runtime: reading a TriangleMeshView (3n float positions, 3m vertex ids)
// the way the contact layers do — the particle and segment contacts share these. Everything
// is inline, noexcept and allocation-free.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "trainer/model/geometry.hpp"
#include "trainer/model/proxy.hpp"  // TriangleMeshView

namespace trainer::model::detail {

// Below this centre-to-surface distance (m) a contact direction (c − p)/|c − p| is not trusted
// and the pseudo-normal gives the contact normal instead.
inline constexpr float kMinDirectionDistanceM = 1e-9F;

inline Vec3 vertex_position(const TriangleMeshView& mesh, std::uint32_t vertex) noexcept {
  const std::size_t base = 3 * static_cast<std::size_t>(vertex);
  return {mesh.positions_m[base], mesh.positions_m[base + 1], mesh.positions_m[base + 2]};
}

// False when the triangle id or one of its vertices is outside the mesh (a grid built from
// other arrays): the triangle is then skipped.
inline bool triangle_vertices(const TriangleMeshView& mesh, std::uint32_t triangle,
                              std::uint32_t (&vertices)[3]) noexcept {
  const std::size_t base = 3 * static_cast<std::size_t>(triangle);
  if (base + 2 >= mesh.triangles.size()) return false;
  const std::size_t vertex_count = mesh.positions_m.size() / 3;
  for (std::size_t corner = 0; corner < 3; ++corner) {
    vertices[corner] = mesh.triangles[base + corner];
    if (vertices[corner] >= vertex_count) return false;
  }
  return true;
}

inline bool contains(const std::uint32_t (&vertices)[3], std::uint32_t vertex) noexcept {
  return vertices[0] == vertex || vertices[1] == vertex || vertices[2] == vertex;
}

inline Vec3 face_normal(const TriangleMeshView& mesh, const std::uint32_t (&vertices)[3]) noexcept {
  return triangle_normal(vertex_position(mesh, vertices[0]), vertex_position(mesh, vertices[1]),
                         vertex_position(mesh, vertices[2]));
}

// Interior angle (rad) at the corner whose vertex id is `vertex`.
inline float corner_angle(const TriangleMeshView& mesh, const std::uint32_t (&vertices)[3],
                          std::uint32_t vertex) noexcept {
  int corner = 0;
  while (corner < 2 && vertices[corner] != vertex) ++corner;
  const Vec3 apex = vertex_position(mesh, vertices[corner]);
  const Vec3 first = vertex_position(mesh, vertices[(corner + 1) % 3]) - apex;
  const Vec3 second = vertex_position(mesh, vertices[(corner + 2) % 3]) - apex;
  return std::atan2(first.cross(second).norm(), first.dot(second));
}

}  // namespace trainer::model::detail
