// Assembly of the shell model (Basdogan eq. 14, METHODS.md §1 steps 4 and 6): validates the
// mesh and material, sums the 18×18 element matrices into a sparse K, eliminates the fixed
// dofs (cleaner and better conditioned than the paper's large-diagonal penalty), lumps the mass,
// and refuses boundary conditions that leave the structure free to move.
#pragma once

#include <string>
#include <vector>

#include "trainer/core/expected.hpp"
#include "trainer/model_offline/shell_model.hpp"

namespace trainer::model::offline {

// E > 0, −1 < ν < 0.5, t > 0, ρ > 0, all finite; the error names the field and its range.
core::Expected<void> validate_shell_material(const ShellMaterial& material);

// The free-dof numbering left by the fixes: node-major, dofs in kUx..kRz order. Fails on an
// unknown node set (listing the known ones) or a dof outside kUx..kRz.
core::Expected<DofMap> make_dof_map(const ShellMesh& mesh, const std::vector<DofFix>& fixes);

// Full pipeline: validate_shell_mesh, validate_shell_material, element matrices
// (shell_element_stiffness), sparse assembly restricted to the free dofs, lumped mass
// (ρ t A / 3 to each node's three translations, 0 to its rotations), then two singularity
// checks:
//   * rigid-body modes: the six rigid motions (three translations, three rotations about the
//     centroid) are exact zero-energy modes of every element, so any combination of them
//     that vanishes on all fixed dofs is a free rigid-body mode; the error names it;
//   * a sparse LDLᵀ of K must have every pivot > 1e-12 × its diagonal entry (catches
//     mechanisms other than rigid motions, e.g. a free hinge).
core::Expected<AssembledShell> assemble_shell(const ShellMesh& mesh, const ShellMaterial& material,
                                              BendingElement bending,
                                              const std::vector<DofFix>& fixes);

// Smallest pivot ratio below which assemble_shell calls K singular.
inline constexpr double kSingularPivotRatio = 1e-12;

// The name of dof kUx..kRz: "ux", "uy", "uz", "rx", "ry", "rz" ("?" otherwise).
const char* shell_dof_name(int dof);

}  // namespace trainer::model::offline
