// Structured shell meshes: tube, flat plate, cylindrical panel.
#include "trainer/model_offline/mesh_generators.hpp"

#include <xxhash.h>

#include <Eigen/Geometry>

#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

namespace trainer::model::offline {
namespace {

// A structured grid of quads split into triangles. `node_index(i, j)` maps grid node (i, j)
// to the mesh node; cells (i, j) for i < cells_i, j < cells_j. `outward(centroid)` is the
// direction the triangle normals must face.
struct GridSpec {
  int cells_i = 0;
  int cells_j = 0;
  std::function<int(int, int)> node_index;
  std::function<Eigen::Vector3d(const Eigen::Vector3d&)> outward;
  TrianglePattern pattern = TrianglePattern::alternating;
};

void add_grid_triangles(const GridSpec& grid, ShellMesh& mesh) {
  std::vector<std::array<int, 3>> triangles;
  triangles.reserve(static_cast<std::size_t>(2 * grid.cells_i * grid.cells_j));
  for (int j = 0; j < grid.cells_j; ++j) {
    for (int i = 0; i < grid.cells_i; ++i) {
      const int n00 = grid.node_index(i, j);
      const int n10 = grid.node_index(i + 1, j);
      const int n01 = grid.node_index(i, j + 1);
      const int n11 = grid.node_index(i + 1, j + 1);
      bool main_diagonal = true;  // n00–n11
      switch (grid.pattern) {
        case TrianglePattern::alternating: main_diagonal = (i + j) % 2 == 0; break;
        case TrianglePattern::right: main_diagonal = true; break;
        case TrianglePattern::left: main_diagonal = false; break;
      }
      if (main_diagonal) {
        triangles.push_back({n00, n10, n11});
        triangles.push_back({n00, n11, n01});
      } else {
        triangles.push_back({n00, n10, n01});
        triangles.push_back({n10, n11, n01});
      }
    }
  }
  mesh.triangles.resize(static_cast<Eigen::Index>(triangles.size()), 3);
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    auto triangle = triangles[t];
    const Eigen::Vector3d p0 = mesh.nodes.row(triangle[0]).transpose();
    const Eigen::Vector3d p1 = mesh.nodes.row(triangle[1]).transpose();
    const Eigen::Vector3d p2 = mesh.nodes.row(triangle[2]).transpose();
    const Eigen::Vector3d normal = (p1 - p0).cross(p2 - p0);
    if (normal.dot(grid.outward((p0 + p1 + p2) / 3.0)) < 0.0) std::swap(triangle[1], triangle[2]);
    const auto row = static_cast<Eigen::Index>(t);
    mesh.triangles.row(row) << triangle[0], triangle[1], triangle[2];
  }
}

std::vector<int> all_nodes(Eigen::Index count) {
  std::vector<int> nodes(static_cast<std::size_t>(count));
  for (std::size_t n = 0; n < nodes.size(); ++n) nodes[n] = static_cast<int>(n);
  return nodes;
}

bool positive_finite(double value) {
  return std::isfinite(value) && value > 0.0;
}

}  // namespace

std::uint64_t hash_generator_parameters(const char* generator, std::initializer_list<double> reals,
                                        std::initializer_list<int> integers) {
  std::string text = generator;
  char buffer[64];
  for (const double value : reals) {
    std::snprintf(buffer, sizeof buffer, " %a", value);
    text += buffer;
  }
  for (const int value : integers) {
    text += ' ';
    text += std::to_string(value);
  }
  return XXH64(text.data(), text.size(), 0);
}

core::Expected<ShellMesh> make_tube(double radius_m, double length_m, int rings, int segments) {
  if (!positive_finite(radius_m) || !positive_finite(length_m) || rings < 2 || segments < 3) {
    return core::make_error("make_tube(radius_m=" + std::to_string(radius_m) + ", length_m=" +
                            std::to_string(length_m) + ", rings=" + std::to_string(rings) +
                            ", segments=" + std::to_string(segments) +
                            "): expected radius and length > 0, rings >= 2, segments >= 3");
  }
  ShellMesh mesh;
  mesh.nodes.resize(static_cast<Eigen::Index>(rings) * segments, 3);
  for (int r = 0; r < rings; ++r) {
    const double x = length_m * static_cast<double>(r) / static_cast<double>(rings - 1);
    for (int s = 0; s < segments; ++s) {
      const double angle = 2.0 * std::numbers::pi * static_cast<double>(s) / segments;
      mesh.nodes.row(static_cast<Eigen::Index>(r) * segments + s) << x, radius_m * std::cos(angle),
          radius_m * std::sin(angle);
    }
  }
  GridSpec grid;
  grid.cells_i = rings - 1;
  grid.cells_j = segments;
  grid.node_index = [segments](int i, int j) { return i * segments + j % segments; };
  grid.outward = [](const Eigen::Vector3d& c) { return Eigen::Vector3d(0.0, c.y(), c.z()); };
  grid.pattern = TrianglePattern::alternating;
  add_grid_triangles(grid, mesh);

  std::vector<int> clamped, free_end;
  for (int s = 0; s < segments; ++s) {
    clamped.push_back(s);
    free_end.push_back((rings - 1) * segments + s);
  }
  mesh.node_sets["clamped"] = std::move(clamped);
  mesh.node_sets["free_end"] = std::move(free_end);
  mesh.node_sets["all"] = all_nodes(mesh.nodes.rows());
  mesh.triangle_sets["wall"] = all_nodes(mesh.triangles.rows());
  mesh.source_hash = hash_generator_parameters("make_tube v1", {radius_m, length_m}, {rings, segments});
  return mesh;
}

core::Expected<ShellMesh> make_rectangle_plate(double lx_m, double ly_m, int nx, int ny,
                                               TrianglePattern pattern) {
  if (!positive_finite(lx_m) || !positive_finite(ly_m) || nx < 1 || ny < 1) {
    return core::make_error("make_rectangle_plate(lx_m=" + std::to_string(lx_m) +
                            ", ly_m=" + std::to_string(ly_m) + ", nx=" + std::to_string(nx) +
                            ", ny=" + std::to_string(ny) +
                            "): expected lengths > 0 and at least 1 division each way");
  }
  ShellMesh mesh;
  const int row_length = nx + 1;
  mesh.nodes.resize(static_cast<Eigen::Index>(row_length) * (ny + 1), 3);
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) {
      mesh.nodes.row(static_cast<Eigen::Index>(j) * row_length + i)
          << lx_m * static_cast<double>(i) / nx,
          ly_m * static_cast<double>(j) / ny, 0.0;
    }
  }
  GridSpec grid;
  grid.cells_i = nx;
  grid.cells_j = ny;
  grid.node_index = [row_length](int i, int j) { return j * row_length + i; };
  grid.outward = [](const Eigen::Vector3d&) { return Eigen::Vector3d::UnitZ(); };
  grid.pattern = pattern;
  add_grid_triangles(grid, mesh);

  std::vector<int> x0, x1, y0, y1;
  for (int j = 0; j <= ny; ++j) {
    x0.push_back(j * row_length);
    x1.push_back(j * row_length + nx);
  }
  for (int i = 0; i <= nx; ++i) {
    y0.push_back(i);
    y1.push_back(ny * row_length + i);
  }
  mesh.node_sets["x0"] = std::move(x0);
  mesh.node_sets["x1"] = std::move(x1);
  mesh.node_sets["y0"] = std::move(y0);
  mesh.node_sets["y1"] = std::move(y1);
  mesh.node_sets["all"] = all_nodes(mesh.nodes.rows());
  mesh.triangle_sets["plate"] = all_nodes(mesh.triangles.rows());
  mesh.source_hash = hash_generator_parameters("make_rectangle_plate v1", {lx_m, ly_m},
                                               {nx, ny, static_cast<int>(pattern)});
  return mesh;
}

core::Expected<ShellMesh> make_cylindrical_panel(double radius_m, double length_m,
                                                 double start_angle_rad, double end_angle_rad,
                                                 int axial_divisions, int arc_divisions,
                                                 TrianglePattern pattern) {
  const double sweep = end_angle_rad - start_angle_rad;
  if (!positive_finite(radius_m) || !positive_finite(length_m) || !std::isfinite(sweep) ||
      !(sweep > 0.0) || sweep >= 2.0 * std::numbers::pi || axial_divisions < 1 ||
      arc_divisions < 1) {
    return core::make_error(
        "make_cylindrical_panel: expected radius and length > 0, 0 < end angle - start angle "
        "< 2 pi, at least 1 division each way; got radius_m=" +
        std::to_string(radius_m) + ", length_m=" + std::to_string(length_m) + ", angles " +
        std::to_string(start_angle_rad) + ".." + std::to_string(end_angle_rad) +
        " rad, divisions " + std::to_string(axial_divisions) + " x " +
        std::to_string(arc_divisions));
  }
  ShellMesh mesh;
  const int row_length = axial_divisions + 1;
  mesh.nodes.resize(static_cast<Eigen::Index>(row_length) * (arc_divisions + 1), 3);
  for (int j = 0; j <= arc_divisions; ++j) {
    const double angle = start_angle_rad + sweep * static_cast<double>(j) / arc_divisions;
    for (int i = 0; i <= axial_divisions; ++i) {
      mesh.nodes.row(static_cast<Eigen::Index>(j) * row_length + i)
          << length_m * static_cast<double>(i) / axial_divisions,
          radius_m * std::sin(angle), radius_m * std::cos(angle);
    }
  }
  GridSpec grid;
  grid.cells_i = axial_divisions;
  grid.cells_j = arc_divisions;
  grid.node_index = [row_length](int i, int j) { return j * row_length + i; };
  grid.outward = [](const Eigen::Vector3d& c) { return Eigen::Vector3d(0.0, c.y(), c.z()); };
  grid.pattern = pattern;
  add_grid_triangles(grid, mesh);

  std::vector<int> x0, x1, arc0, arc1;
  for (int j = 0; j <= arc_divisions; ++j) {
    x0.push_back(j * row_length);
    x1.push_back(j * row_length + axial_divisions);
  }
  for (int i = 0; i <= axial_divisions; ++i) {
    arc0.push_back(i);
    arc1.push_back(arc_divisions * row_length + i);
  }
  mesh.node_sets["x0"] = std::move(x0);
  mesh.node_sets["x1"] = std::move(x1);
  mesh.node_sets["arc0"] = std::move(arc0);
  mesh.node_sets["arc1"] = std::move(arc1);
  mesh.node_sets["all"] = all_nodes(mesh.nodes.rows());
  mesh.triangle_sets["panel"] = all_nodes(mesh.triangles.rows());
  mesh.source_hash = hash_generator_parameters(
      "make_cylindrical_panel v1", {radius_m, length_m, start_angle_rad, end_angle_rad},
      {axial_divisions, arc_divisions, static_cast<int>(pattern)});
  return mesh;
}

}  // namespace trainer::model::offline
