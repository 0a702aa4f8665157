// Test helper for the tetrahedral model: writes a TetMesh as Gmsh MSH 4.1 ASCII (one surface
// entity per named triangle set, which must not share triangles, and one volume entity
// "body"), so the Gmsh path (read_gmsh_tet, `modelc static --mesh`) is tested on meshes whose
// exact answer is known from the generators. Node order is kept, so the indices read back equal
// the generator's.
#pragma once

#include <sstream>
#include <string>
#include <vector>

#include "trainer/model_offline/gmsh_reader.hpp"

namespace trainer::model::offline::testing {

inline std::string write_gmsh_tet(const TetMesh& mesh, const std::vector<std::string>& face_sets) {
  std::ostringstream out;
  out.precision(17);
  const auto face_count = static_cast<int>(face_sets.size());
  out << "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$PhysicalNames\n" << face_count + 1 << "\n";
  for (int s = 0; s < face_count; ++s) {
    out << "2 " << s + 1 << " \"" << face_sets[static_cast<std::size_t>(s)] << "\"\n";
  }
  out << "3 " << face_count + 1 << " \"body\"\n$EndPhysicalNames\n";
  out << "$Entities\n0 0 " << face_count << " 1\n";
  for (int s = 0; s < face_count; ++s) out << s + 1 << " 0 0 0 1 1 1 1 " << s + 1 << " 0\n";
  out << "1 0 0 0 1 1 1 1 " << face_count + 1 << " 0\n$EndEntities\n";
  const auto node_count = mesh.nodes.rows();
  out << "$Nodes\n1 " << node_count << " 1 " << node_count << "\n3 1 0 " << node_count << "\n";
  for (Eigen::Index n = 0; n < node_count; ++n) out << n + 1 << "\n";
  for (Eigen::Index n = 0; n < node_count; ++n) {
    out << mesh.nodes(n, 0) << " " << mesh.nodes(n, 1) << " " << mesh.nodes(n, 2) << "\n";
  }
  out << "$EndNodes\n";
  std::size_t element_total = static_cast<std::size_t>(mesh.tetrahedra.rows());
  for (const std::string& name : face_sets) element_total += mesh.triangle_sets.at(name).size();
  out << "$Elements\n" << face_count + 1 << " " << element_total << " 1 " << element_total << "\n";
  std::size_t tag = 1;
  for (int s = 0; s < face_count; ++s) {
    const std::vector<int>& faces = mesh.triangle_sets.at(face_sets[static_cast<std::size_t>(s)]);
    out << "2 " << s + 1 << " 2 " << faces.size() << "\n";
    for (const int f : faces) {
      out << tag++ << " " << mesh.triangles(f, 0) + 1 << " " << mesh.triangles(f, 1) + 1 << " "
          << mesh.triangles(f, 2) + 1 << "\n";
    }
  }
  out << "3 1 4 " << mesh.tetrahedra.rows() << "\n";
  for (Eigen::Index e = 0; e < mesh.tetrahedra.rows(); ++e) {
    out << tag++;
    for (int c = 0; c < 4; ++c) out << " " << mesh.tetrahedra(e, c) + 1;
    out << "\n";
  }
  out << "$EndElements\n";
  return out.str();
}

}  // namespace trainer::model::offline::testing
