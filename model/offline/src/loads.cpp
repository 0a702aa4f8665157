// Nodal load vectors for the shell model (see loads.hpp for the conventions).
#include "trainer/model_offline/loads.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <string>

namespace trainer::model::offline {
namespace {

core::Expected<void> check_load_vector(const ShellMesh& mesh, const Eigen::VectorXd& nodal_loads) {
  const Eigen::Index expected = mesh.nodes.rows() * kShellDofsPerNode;
  if (nodal_loads.size() != expected) {
    return core::make_error("load vector has " + std::to_string(nodal_loads.size()) +
                            " entries; expected " + std::to_string(expected) +
                            " (6 per node of the mesh)");
  }
  return {};
}

std::string known_names(const std::map<std::string, std::vector<int>>& sets) {
  std::string names;
  for (const auto& [name, members] : sets) names += (names.empty() ? "" : ", ") + name;
  return names.empty() ? "none" : names;
}

// Calls add(corner_nodes, area, unit_normal) for every triangle of the named set.
template <class Add>
core::Expected<void> for_each_set_triangle(const ShellMesh& mesh, const std::string& triangle_set,
                                           const char* what, Add&& add) {
  const auto found = mesh.triangle_sets.find(triangle_set);
  if (found == mesh.triangle_sets.end()) {
    return core::make_error(std::string(what) + ": unknown triangle set '" + triangle_set +
                            "' (the mesh has: " + known_names(mesh.triangle_sets) + ")");
  }
  for (const int t : found->second) {
    if (t < 0 || t >= mesh.triangles.rows()) {
      return core::make_error(std::string(what) + ": triangle set '" + triangle_set +
                              "' lists triangle " + std::to_string(t) + ", outside 0.." +
                              std::to_string(mesh.triangles.rows() - 1));
    }
    const Eigen::Vector3d p0 = mesh.nodes.row(mesh.triangles(t, 0)).transpose();
    const Eigen::Vector3d p1 = mesh.nodes.row(mesh.triangles(t, 1)).transpose();
    const Eigen::Vector3d p2 = mesh.nodes.row(mesh.triangles(t, 2)).transpose();
    const Eigen::Vector3d twice_area_normal = (p1 - p0).cross(p2 - p0);
    const double area = 0.5 * twice_area_normal.norm();
    const Eigen::Vector3d normal =
        area > 0.0 ? Eigen::Vector3d(twice_area_normal.normalized()) : Eigen::Vector3d::Zero();
    add(mesh.triangles.row(t), area, normal);
  }
  return {};
}

}  // namespace

Eigen::VectorXd make_zero_loads(const ShellMesh& mesh) {
  return Eigen::VectorXd::Zero(mesh.nodes.rows() * kShellDofsPerNode);
}

core::Expected<void> add_node_set_force(const ShellMesh& mesh, const std::string& node_set,
                                        const Eigen::Vector3d& total_force_n,
                                        Eigen::VectorXd& nodal_loads) {
  if (auto ok = check_load_vector(mesh, nodal_loads); !ok) return ok.error();
  if (!total_force_n.allFinite()) {
    return core::make_error("force on node set '" + node_set + "' is not finite");
  }
  const auto found = mesh.node_sets.find(node_set);
  if (found == mesh.node_sets.end()) {
    return core::make_error("force: unknown node set '" + node_set +
                            "' (the mesh has: " + known_names(mesh.node_sets) + ")");
  }
  if (found->second.empty()) {
    return core::make_error("force: node set '" + node_set + "' is empty");
  }
  const Eigen::Vector3d per_node = total_force_n / static_cast<double>(found->second.size());
  for (const int node : found->second) {
    if (node < 0 || node >= mesh.nodes.rows()) {
      return core::make_error("force: node set '" + node_set + "' lists node " +
                              std::to_string(node) + ", outside 0.." +
                              std::to_string(mesh.nodes.rows() - 1));
    }
    nodal_loads.segment<3>(static_cast<Eigen::Index>(node) * kShellDofsPerNode) += per_node;
  }
  return {};
}

core::Expected<void> add_surface_traction(const ShellMesh& mesh, const std::string& triangle_set,
                                          const Eigen::Vector3d& traction_pa,
                                          Eigen::VectorXd& nodal_loads) {
  if (auto ok = check_load_vector(mesh, nodal_loads); !ok) return ok.error();
  if (!traction_pa.allFinite()) {
    return core::make_error("traction on triangle set '" + triangle_set + "' is not finite");
  }
  return for_each_set_triangle(
      mesh, triangle_set, "surface traction",
      [&](const auto& corners, double area, const Eigen::Vector3d&) {
        for (int corner = 0; corner < 3; ++corner) {
          nodal_loads.segment<3>(static_cast<Eigen::Index>(corners(corner)) * kShellDofsPerNode) +=
              traction_pa * (area / 3.0);
        }
      });
}

core::Expected<void> add_normal_pressure(const ShellMesh& mesh, const std::string& triangle_set,
                                         double pressure_pa, Eigen::VectorXd& nodal_loads) {
  if (auto ok = check_load_vector(mesh, nodal_loads); !ok) return ok.error();
  if (!std::isfinite(pressure_pa)) {
    return core::make_error("pressure on triangle set '" + triangle_set + "' is not finite");
  }
  return for_each_set_triangle(
      mesh, triangle_set, "normal pressure",
      [&](const auto& corners, double area, const Eigen::Vector3d& normal) {
        for (int corner = 0; corner < 3; ++corner) {
          nodal_loads.segment<3>(static_cast<Eigen::Index>(corners(corner)) * kShellDofsPerNode) +=
              normal * (pressure_pa * area / 3.0);
        }
      });
}

}  // namespace trainer::model::offline
