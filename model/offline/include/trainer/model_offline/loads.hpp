// External loads on the shell model as a global nodal load vector: 6 entries per node in
// ux uy uz rx ry rz order (forces in N, moments in N·m, global frame), which static_solve()
// restricts to the free dofs (loads on fixed dofs are carried by the supports).
#pragma once

#include <string>

#include <Eigen/Core>

#include "trainer/core/expected.hpp"
#include "trainer/model_offline/shell_model.hpp"

namespace trainer::model::offline {

// A zero load vector of size 6 × node count.
Eigen::VectorXd make_zero_loads(const ShellMesh& mesh);

// Adds a total force (N, global frame) on a node set, split EQUALLY over its nodes. This is
// the simple split, not the consistent edge load: for a uniformly meshed open edge the
// consistent load gives the two end nodes half as much as the others (use
// add_surface_traction for distributed loads over an area, or build the vector by hand).
core::Expected<void> add_node_set_force(const ShellMesh& mesh, const std::string& node_set,
                                        const Eigen::Vector3d& total_force_n,
                                        Eigen::VectorXd& nodal_loads);

// Adds a constant traction (force per unit area, Pa, global frame — e.g. self-weight ρ t g
// downward, or a pressure p n when all triangles of the set share the normal n) over a triangle
// set as consistent nodal loads: for a linear triangle with constant traction that is p·A/3 on
// each corner's translations, nothing on the rotations.
core::Expected<void> add_surface_traction(const ShellMesh& mesh, const std::string& triangle_set,
                                          const Eigen::Vector3d& traction_pa,
                                          Eigen::VectorXd& nodal_loads);

// Adds a pressure (Pa, positive along each triangle's own unit normal, i.e. along
// (p2 − p1) × (p3 − p1)) over a triangle set: p·A/3 along the normal on each corner.
core::Expected<void> add_normal_pressure(const ShellMesh& mesh, const std::string& triangle_set,
                                         double pressure_pa, Eigen::VectorXd& nodal_loads);

}  // namespace trainer::model::offline
