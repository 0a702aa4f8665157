// Structured tet meshes (box, cylinder) and boundary-face extraction.
#include "trainer/model_offline/tet_mesh_generators.hpp"

#include "trainer/model_offline/mesh_generators.hpp"

#include <xxhash.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <initializer_list>
#include <numbers>
#include <string>
#include <vector>

#include "trainer/model_offline/tet_elasticity.hpp"

namespace trainer::model::offline {
namespace {

// Larger meshes than this are refused: they would take minutes and gigabytes to factorise.
constexpr std::int64_t kMaxGeneratedNodes = 10'000'000;

using Tet = std::array<int, 4>;
using Face = std::array<int, 3>;

bool positive_finite(double value) {
  return value > 0.0 && std::isfinite(value);
}

// Appends `tet`, swapping two corners when needed so that its volume is positive.
void add_positive_tet(const TetMesh& mesh, Tet tet, std::vector<Tet>& tets) {
  Eigen::Matrix<double, 4, 3> corners;
  for (int c = 0; c < 4; ++c) corners.row(c) = mesh.nodes.row(tet[static_cast<std::size_t>(c)]);
  if (tet_signed_volume(corners) < 0.0) std::swap(tet[2], tet[3]);
  tets.push_back(tet);
}

void store_tets(const std::vector<Tet>& tets, TetMesh& mesh) {
  mesh.tetrahedra.resize(static_cast<Eigen::Index>(tets.size()), 4);
  for (std::size_t e = 0; e < tets.size(); ++e) {
    for (int c = 0; c < 4; ++c) {
      mesh.tetrahedra(static_cast<Eigen::Index>(e), c) = tets[e][static_cast<std::size_t>(c)];
    }
  }
}

// Boundary triangles into mesh.triangles, the "surface" and named sets (a face belongs to the
// named set whose predicate all three of its nodes satisfy), node sets from the faces, "all".
void add_boundary_sets(
    const std::vector<std::pair<std::string, std::function<bool(const Eigen::Vector3d&)>>>& named,
    TetMesh& mesh) {
  mesh.triangles = boundary_triangles(mesh);
  const auto face_count = static_cast<int>(mesh.triangles.rows());
  const auto add_face_set = [&mesh](const std::string& name, std::vector<int> faces) {
    std::vector<int> nodes;
    for (const int face : faces) {
      for (int c = 0; c < 3; ++c) nodes.push_back(mesh.triangles(face, c));
    }
    std::sort(nodes.begin(), nodes.end());
    nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
    mesh.node_sets[name] = std::move(nodes);
    mesh.triangle_sets[name] = std::move(faces);
  };
  std::vector<int> every_face(static_cast<std::size_t>(face_count));
  for (int face = 0; face < face_count; ++face) every_face[static_cast<std::size_t>(face)] = face;
  add_face_set("surface", every_face);
  for (const auto& [name, on_set] : named) {
    std::vector<int> faces;
    for (int face = 0; face < face_count; ++face) {
      bool all_on = true;
      for (int c = 0; c < 3 && all_on; ++c) {
        all_on = on_set(mesh.nodes.row(mesh.triangles(face, c)).transpose());
      }
      if (all_on) faces.push_back(face);
    }
    add_face_set(name, std::move(faces));
  }
  std::vector<int> all(static_cast<std::size_t>(mesh.nodes.rows()));
  for (std::size_t node = 0; node < all.size(); ++node) all[node] = static_cast<int>(node);
  mesh.node_sets["all"] = std::move(all);
}

// The 3 tetrahedra of the triangular prism (bottom a,b,c; top a',b',c' above them), split by the
// rule of Dompierre et al. (1999): every quadrilateral face is cut by the diagonal through its
// lowest global node index, so neighbouring prisms agree on their shared faces whatever their
// local orientation.
void split_prism(const std::array<int, 6>& prism, const TetMesh& mesh, std::vector<Tet>& tets) {
  const auto lowest =
      static_cast<int>(std::min_element(prism.begin(), prism.end()) - prism.begin());
  std::array<int, 6> v{};
  const int base = lowest % 3;
  const bool flipped = lowest >= 3;  // the lowest node is on top: treat the top as the bottom
  for (int i = 0; i < 3; ++i) {
    const int index = (base + i) % 3;
    v[static_cast<std::size_t>(i)] = prism[static_cast<std::size_t>(flipped ? index + 3 : index)];
    v[static_cast<std::size_t>(i + 3)] =
        prism[static_cast<std::size_t>(flipped ? index : index + 3)];
  }
  // v[0] is the lowest: the quads through it are cut along v0–v4 and v0–v5; the opposite quad
  // (v1, v2, v5, v4) along v1–v5 or v2–v4.
  if (std::min(v[1], v[5]) < std::min(v[2], v[4])) {
    add_positive_tet(mesh, {v[0], v[1], v[2], v[5]}, tets);
    add_positive_tet(mesh, {v[0], v[1], v[5], v[4]}, tets);
  } else {
    add_positive_tet(mesh, {v[0], v[1], v[2], v[4]}, tets);
    add_positive_tet(mesh, {v[0], v[4], v[2], v[5]}, tets);
  }
  add_positive_tet(mesh, {v[0], v[4], v[5], v[3]}, tets);
}

}  // namespace

core::Expected<TetMesh> make_tet_box(double lx_m, double ly_m, double lz_m, int nx, int ny,
                                     int nz) {
  if (!positive_finite(lx_m) || !positive_finite(ly_m) || !positive_finite(lz_m)) {
    return core::make_error("tet box: the sizes are " + std::to_string(lx_m) + " x " +
                            std::to_string(ly_m) + " x " + std::to_string(lz_m) +
                            " m; expected finite values > 0");
  }
  if (nx < 1 || ny < 1 || nz < 1) {
    return core::make_error("tet box: the divisions are " + std::to_string(nx) + " x " +
                            std::to_string(ny) + " x " + std::to_string(nz) +
                            "; expected each >= 1");
  }
  const std::int64_t node_total = std::int64_t{nx + 1} * (ny + 1) * (nz + 1);
  if (node_total > kMaxGeneratedNodes) {
    return core::make_error("tet box: " + std::to_string(node_total) +
                            " nodes; expected <= " + std::to_string(kMaxGeneratedNodes));
  }
  TetMesh mesh;
  const auto node_index = [nx, ny](int i, int j, int k) {
    return (k * (ny + 1) + j) * (nx + 1) + i;
  };
  // Grid coordinate; the last one is the length itself so the far faces are exactly planar.
  const auto coordinate = [](double length, int index, int divisions) {
    return index == divisions ? length : length * index / divisions;
  };
  mesh.nodes.resize(static_cast<Eigen::Index>(node_total), 3);
  for (int k = 0; k <= nz; ++k) {
    for (int j = 0; j <= ny; ++j) {
      for (int i = 0; i <= nx; ++i) {
        mesh.nodes.row(node_index(i, j, k)) << coordinate(lx_m, i, nx), coordinate(ly_m, j, ny),
            coordinate(lz_m, k, nz);
      }
    }
  }
  // Kuhn split: one tetrahedron per order in which the path from corner (0,0,0) to (1,1,1)
  // steps along the three axes.
  constexpr std::array<std::array<int, 3>, 6> kAxisOrders{
      {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};
  std::vector<Tet> tets;
  tets.reserve(static_cast<std::size_t>(6 * nx * ny * nz));
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        for (const auto& order : kAxisOrders) {
          std::array<int, 3> step{0, 0, 0};
          Tet tet{node_index(i, j, k), 0, 0, 0};
          for (int s = 0; s < 3; ++s) {
            step[static_cast<std::size_t>(order[static_cast<std::size_t>(s)])] = 1;
            tet[static_cast<std::size_t>(s + 1)] =
                node_index(i + step[0], j + step[1], k + step[2]);
          }
          add_positive_tet(mesh, tet, tets);
        }
      }
    }
  }
  store_tets(tets, mesh);
  add_boundary_sets({{"x0", [](const Eigen::Vector3d& p) { return p.x() == 0.0; }},
                     {"x1", [lx_m](const Eigen::Vector3d& p) { return p.x() == lx_m; }},
                     {"y0", [](const Eigen::Vector3d& p) { return p.y() == 0.0; }},
                     {"y1", [ly_m](const Eigen::Vector3d& p) { return p.y() == ly_m; }},
                     {"z0", [](const Eigen::Vector3d& p) { return p.z() == 0.0; }},
                     {"z1", [lz_m](const Eigen::Vector3d& p) { return p.z() == lz_m; }}},
                    mesh);
  mesh.source_hash = hash_generator_parameters("make_tet_box v1", {lx_m, ly_m, lz_m}, {nx, ny, nz});
  return mesh;
}

core::Expected<TetMesh> make_tet_cylinder(double radius_m, double height_m, int radial, int axial) {
  if (!positive_finite(radius_m) || !positive_finite(height_m)) {
    return core::make_error("tet cylinder: radius " + std::to_string(radius_m) + " m, height " +
                            std::to_string(height_m) + " m; expected finite values > 0");
  }
  if (radial < 1 || axial < 1) {
    return core::make_error("tet cylinder: radial " + std::to_string(radial) + ", axial " +
                            std::to_string(axial) + " divisions; expected each >= 1");
  }
  // Cross-section: 1 + Σ 6r = 1 + 3 radial (radial + 1) nodes.
  const std::int64_t section_nodes = 1 + 3 * std::int64_t{radial} * (radial + 1);
  if (section_nodes * (axial + 1) > kMaxGeneratedNodes) {
    return core::make_error("tet cylinder: " + std::to_string(section_nodes * (axial + 1)) +
                            " nodes; expected <= " + std::to_string(kMaxGeneratedNodes));
  }
  const auto ring_start = [](int ring) { return ring == 0 ? 0 : 1 + 3 * (ring - 1) * ring; };
  const auto ring_size = [](int ring) { return ring == 0 ? 1 : 6 * ring; };
  std::vector<Eigen::Vector2d> section(static_cast<std::size_t>(section_nodes),
                                       Eigen::Vector2d::Zero());
  for (int ring = 1; ring <= radial; ++ring) {
    const double radius = ring == radial ? radius_m : radius_m * ring / radial;
    for (int s = 0; s < ring_size(ring); ++s) {
      const double angle = 2.0 * std::numbers::pi * s / ring_size(ring);
      section[static_cast<std::size_t>(ring_start(ring) + s)] =
          radius * Eigen::Vector2d(std::cos(angle), std::sin(angle));
    }
  }
  // Triangles between consecutive rings: walk both rings by angle, always advancing the ring
  // whose next node comes first (the inner ring wins ties).
  std::vector<Face> section_triangles;
  for (int ring = 1; ring <= radial; ++ring) {
    const int inner_size = ring_size(ring - 1), outer_size = ring_size(ring);
    const auto inner = [&](int a) { return ring_start(ring - 1) + a % inner_size; };
    const auto outer = [&](int b) { return ring_start(ring) + b % outer_size; };
    if (ring == 1) {
      for (int b = 0; b < outer_size; ++b) section_triangles.push_back({0, outer(b), outer(b + 1)});
      continue;
    }
    int a = 0, b = 0;
    while (a < inner_size || b < outer_size) {
      const bool advance_inner =
          b == outer_size ||
          (a < inner_size && std::int64_t{a + 1} * outer_size <= std::int64_t{b + 1} * inner_size);
      if (advance_inner) {
        section_triangles.push_back({inner(a), outer(b), inner(a + 1)});
        ++a;
      } else {
        section_triangles.push_back({inner(a), outer(b), outer(b + 1)});
        ++b;
      }
    }
  }

  TetMesh mesh;
  const auto section_count = static_cast<int>(section_nodes);
  mesh.nodes.resize(static_cast<Eigen::Index>(section_nodes * (axial + 1)), 3);
  for (int layer = 0; layer <= axial; ++layer) {
    const double z = layer == axial ? height_m : height_m * layer / axial;
    for (int n = 0; n < section_count; ++n) {
      const Eigen::Vector2d& p = section[static_cast<std::size_t>(n)];
      mesh.nodes.row(layer * section_count + n) << p.x(), p.y(), z;
    }
  }
  std::vector<Tet> tets;
  tets.reserve(section_triangles.size() * 3 * static_cast<std::size_t>(axial));
  for (int layer = 0; layer < axial; ++layer) {
    const int bottom = layer * section_count, top = (layer + 1) * section_count;
    for (const Face& t : section_triangles) {
      split_prism({bottom + t[0], bottom + t[1], bottom + t[2], top + t[0], top + t[1], top + t[2]},
                  mesh, tets);
    }
  }
  store_tets(tets, mesh);
  // The side test is on the radius with a relative tolerance: cos/sin round.
  const double side_tolerance = 1e-9 * radius_m;
  add_boundary_sets({{"bottom", [](const Eigen::Vector3d& p) { return p.z() == 0.0; }},
                     {"top", [height_m](const Eigen::Vector3d& p) { return p.z() == height_m; }},
                     {"side",
                      [radius_m, side_tolerance](const Eigen::Vector3d& p) {
                        return std::abs(p.head<2>().norm() - radius_m) <= side_tolerance;
                      }}},
                    mesh);
  mesh.node_sets["top_center"] = {axial * section_count};
  mesh.source_hash = hash_generator_parameters("make_tet_cylinder v1", {radius_m, height_m}, {radial, axial});
  return mesh;
}

Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor> boundary_triangles(const TetMesh& mesh) {
  struct OrientedFace {
    Face key;       // sorted node indices, to find the faces two tetrahedra share
    Face oriented;  // outward from its tetrahedron
  };
  // Outward faces of a positive tetrahedron (0,1,2,3): the face opposite each corner.
  constexpr std::array<Face, 4> kOutwardFaces{{{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}}};
  std::vector<OrientedFace> faces;
  faces.reserve(static_cast<std::size_t>(mesh.tetrahedra.rows()) * 4);
  for (Eigen::Index e = 0; e < mesh.tetrahedra.rows(); ++e) {
    Eigen::Matrix<double, 4, 3> corners;
    for (int c = 0; c < 4; ++c) corners.row(c) = mesh.nodes.row(mesh.tetrahedra(e, c));
    const bool inverted = tet_signed_volume(corners) < 0.0;
    for (const Face& local : kOutwardFaces) {
      OrientedFace face;
      for (std::size_t c = 0; c < 3; ++c) face.oriented[c] = mesh.tetrahedra(e, local[c]);
      if (inverted) std::swap(face.oriented[1], face.oriented[2]);
      face.key = face.oriented;
      std::sort(face.key.begin(), face.key.end());
      faces.push_back(face);
    }
  }
  std::sort(faces.begin(), faces.end(),
            [](const OrientedFace& a, const OrientedFace& b) { return a.key < b.key; });
  std::vector<Face> boundary;
  for (std::size_t i = 0; i < faces.size();) {
    std::size_t j = i + 1;
    while (j < faces.size() && faces[j].key == faces[i].key) ++j;
    if (j - i == 1) boundary.push_back(faces[i].oriented);
    i = j;
  }
  Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor> triangles(
      static_cast<Eigen::Index>(boundary.size()), 3);
  for (std::size_t f = 0; f < boundary.size(); ++f) {
    for (int c = 0; c < 3; ++c) {
      triangles(static_cast<Eigen::Index>(f), c) = boundary[f][static_cast<std::size_t>(c)];
    }
  }
  return triangles;
}

}  // namespace trainer::model::offline
