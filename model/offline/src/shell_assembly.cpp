// Shell assembly: dof map, sparse K over free dofs, lumped mass, singularity checks.
#include "trainer/model_offline/shell_assembly.hpp"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <Eigen/SparseCore>

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "trainer/model_offline/mesh_validation.hpp"
#include "trainer/model_offline/shell_element.hpp"
#include "trainer/model_offline/static_solve.hpp"

namespace trainer::model::offline {
namespace {

// Position of (node, dof) in the 6n node-dof numbering, computed in size_t.
std::size_t node_dof_index(int node, int dof) {
  return static_cast<std::size_t>(node) * static_cast<std::size_t>(kShellDofsPerNode) +
         static_cast<std::size_t>(dof);
}

std::string vector_text(const Eigen::Vector3d& v) {
  std::ostringstream out;
  out.precision(3);
  out << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return out.str();
}

// Rigid-body modes left free by the fixes: combinations of the six rigid motions that vanish
// on every fixed dof. Returns a description of each (empty when none is free).
std::vector<std::string> free_rigid_body_modes(const ShellMesh& mesh, const DofMap& dofs) {
  const Eigen::RowVector3d centroid = mesh.nodes.colwise().mean();
  const Eigen::RowVector3d extent =
      mesh.nodes.colwise().maxCoeff() - mesh.nodes.colwise().minCoeff();
  const double size = std::max(extent.norm(), 1e-300);

  // Rows: fixed dofs. Columns: translations x, y, z, then rotations about x, y, z through the
  // centroid, with rotations scaled by the mesh size so all columns have comparable entries.
  const int fixed_count = static_cast<int>(dofs.free_index.size()) - dofs.free_count();
  Eigen::MatrixXd on_fixed(std::max(fixed_count, 1), 6);
  on_fixed.setZero();
  int row = 0;
  for (int node = 0; node < dofs.node_count; ++node) {
    const Eigen::Vector3d arm = (mesh.nodes.row(node) - centroid).transpose() / size;
    for (int dof = 0; dof < kShellDofsPerNode; ++dof) {
      if (dofs.free_index[node_dof_index(node, dof)] >= 0) continue;
      for (int mode = 0; mode < 6; ++mode) {
        Eigen::Vector3d translation = Eigen::Vector3d::Zero();
        Eigen::Vector3d rotation = Eigen::Vector3d::Zero();
        if (mode < 3) {
          translation(mode) = 1.0;
        } else {
          rotation(mode - 3) = 1.0;
          translation = rotation.cross(arm);
        }
        on_fixed(row, mode) = dof < 3 ? translation(dof) : rotation(dof - 3);
      }
      ++row;
    }
  }
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(on_fixed, Eigen::ComputeFullV);
  const Eigen::VectorXd& singular = svd.singularValues();
  const double largest = fixed_count > 0 ? singular(0) : 0.0;
  std::vector<std::string> modes;
  for (int k = 0; k < 6; ++k) {
    const double value = k < singular.size() ? singular(k) : 0.0;
    if (fixed_count > 0 && value > 1e-9 * largest) continue;
    const Eigen::Matrix<double, 6, 1> mode = svd.matrixV().col(k);
    const Eigen::Vector3d translation = mode.head<3>();
    const Eigen::Vector3d rotation = mode.tail<3>();
    if (rotation.norm() < 1e-6) {
      modes.push_back("translation along " + vector_text(translation.normalized()));
    } else {
      // Rotation axis through the point closest to the centroid: the translation component
      // along the axis is a screw, the rest locates the axis.
      const Eigen::Vector3d axis = rotation.normalized();
      const Eigen::Vector3d point =
          centroid.transpose() + size * rotation.cross(translation) / rotation.squaredNorm();
      modes.push_back("rotation about axis " + vector_text(axis) + " through " +
                      vector_text(point));
    }
  }
  return modes;
}

}  // namespace

const char* shell_dof_name(int dof) {
  switch (dof) {
    case kUx: return "ux";
    case kUy: return "uy";
    case kUz: return "uz";
    case kRx: return "rx";
    case kRy: return "ry";
    case kRz: return "rz";
    default: return "?";
  }
}

core::Expected<void> validate_shell_material(const ShellMaterial& material) {
  std::ostringstream out;
  out.precision(9);
  if (!std::isfinite(material.young_modulus_pa) || !(material.young_modulus_pa > 0.0)) {
    out << "shell material: young_modulus_pa = " << material.young_modulus_pa
        << ": expected > 0 (Pa)";
  } else if (!std::isfinite(material.poisson_ratio) || !(material.poisson_ratio > -1.0) ||
             !(material.poisson_ratio < 0.5)) {
    out << "shell material: poisson_ratio = " << material.poisson_ratio
        << ": expected -1 < nu < 0.5";
  } else if (!std::isfinite(material.thickness_m) || !(material.thickness_m > 0.0)) {
    out << "shell material: thickness_m = " << material.thickness_m << ": expected > 0 (m)";
  } else if (!std::isfinite(material.density_kg_per_m3) || !(material.density_kg_per_m3 > 0.0)) {
    out << "shell material: density_kg_per_m3 = " << material.density_kg_per_m3
        << ": expected > 0 (kg/m^3)";
  } else {
    return {};
  }
  return core::make_error(out.str());
}

core::Expected<DofMap> make_dof_map(const ShellMesh& mesh, const std::vector<DofFix>& fixes) {
  const int node_count = static_cast<int>(mesh.nodes.rows());
  std::vector<char> fixed(static_cast<std::size_t>(node_count) * kShellDofsPerNode, 0);
  for (const DofFix& fix : fixes) {
    const auto found = mesh.node_sets.find(fix.node_set);
    if (found == mesh.node_sets.end()) {
      std::string known;
      for (const auto& [name, nodes] : mesh.node_sets) known += (known.empty() ? "" : ", ") + name;
      return core::make_error("boundary condition: unknown node set '" + fix.node_set +
                              "' (the mesh has: " + (known.empty() ? "none" : known) + ")");
    }
    for (const int dof : fix.dofs) {
      if (dof < kUx || dof > kRz) {
        return core::make_error("boundary condition on node set '" + fix.node_set + "': dof " +
                                std::to_string(dof) +
                                " is not one of 0..5 (ux, uy, uz, rx, ry, rz)");
      }
    }
    for (const int node : found->second) {
      if (node < 0 || node >= node_count) {
        return core::make_error("boundary condition: node set '" + fix.node_set + "' lists node " +
                                std::to_string(node) + ", outside 0.." +
                                std::to_string(node_count - 1));
      }
      for (const int dof : fix.dofs) {
        fixed[node_dof_index(node, dof)] = 1;
      }
    }
  }
  DofMap map;
  map.node_count = node_count;
  map.free_index.assign(fixed.size(), -1);
  for (std::size_t i = 0; i < fixed.size(); ++i) {
    if (fixed[i]) continue;
    map.free_index[i] = static_cast<int>(map.free_to_node_dof.size());
    map.free_to_node_dof.push_back(static_cast<int>(i));
  }
  return map;
}

core::Expected<AssembledShell> assemble_shell(const ShellMesh& mesh, const ShellMaterial& material,
                                              BendingElement bending,
                                              const std::vector<DofFix>& fixes) {
  if (auto valid = validate_shell_mesh(mesh); !valid) return valid.error();
  if (auto valid = validate_shell_material(material); !valid) return valid.error();
  auto dof_map = make_dof_map(mesh, fixes);
  if (!dof_map) return dof_map.error();

  if (const auto free_modes = free_rigid_body_modes(mesh, *dof_map); !free_modes.empty()) {
    std::string message = "the boundary conditions leave a rigid-body mode free (" +
                          std::to_string(free_modes.size()) + " of 6): ";
    for (std::size_t i = 0; i < free_modes.size(); ++i) {
      message += (i ? "; " : "") + free_modes[i];
    }
    message +=
        ". Fix at least all six dofs of one node, or the translations of three nodes that are "
        "not on one line";
    return core::make_error(message);
  }

  const int free_count = dof_map->free_count();
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<std::size_t>(mesh.triangles.rows()) * 18 * 18);
  Eigen::VectorXd node_mass = Eigen::VectorXd::Zero(mesh.nodes.rows());
  for (Eigen::Index t = 0; t < mesh.triangles.rows(); ++t) {
    TriangleCorners corners;
    for (int corner = 0; corner < 3; ++corner) {
      corners.row(corner) = mesh.nodes.row(mesh.triangles(t, corner));
    }
    auto element = shell_element_stiffness(corners, material, bending);
    if (!element) {
      return core::make_error("triangle " + std::to_string(t) + ": " + element.error().message);
    }
    std::array<int, 18> global_index{};
    for (int corner = 0; corner < 3; ++corner) {
      for (int dof = 0; dof < kShellDofsPerNode; ++dof) {
        global_index[static_cast<std::size_t>(corner * kShellDofsPerNode + dof)] =
            dof_map->free_index[node_dof_index(mesh.triangles(t, corner), dof)];
      }
    }
    for (int r = 0; r < 18; ++r) {
      const int row = global_index[static_cast<std::size_t>(r)];
      if (row < 0) continue;
      for (int c = 0; c < 18; ++c) {
        const int column = global_index[static_cast<std::size_t>(c)];
        if (column < 0) continue;
        triplets.emplace_back(row, column, (*element)(r, c));
      }
    }
    const double area =
        0.5 * (corners.row(1) - corners.row(0)).cross(corners.row(2) - corners.row(0)).norm();
    const double corner_mass = material.density_kg_per_m3 * material.thickness_m * area / 3.0;
    for (int corner = 0; corner < 3; ++corner) node_mass(mesh.triangles(t, corner)) += corner_mass;
  }

  AssembledShell shell;
  shell.stiffness.resize(free_count, free_count);
  shell.stiffness.setFromTriplets(triplets.begin(), triplets.end());
  shell.stiffness.makeCompressed();
  shell.lumped_mass = Eigen::VectorXd::Zero(free_count);
  for (int i = 0; i < free_count; ++i) {
    const int node_dof = dof_map->free_to_node_dof[static_cast<std::size_t>(i)];
    if (node_dof % kShellDofsPerNode < 3)
      shell.lumped_mass(i) = node_mass(node_dof / kShellDofsPerNode);
  }
  shell.dofs = std::move(*dof_map);

  if (auto solver = ShellStaticSolver::create(shell); !solver) {
    return core::make_error(
        "the assembled stiffness is singular after the boundary conditions "
        "(a mechanism the rigid-body check does not cover): " +
        solver.error().message);
  }
  return shell;
}

}  // namespace trainer::model::offline
