// `modelc static`: assemble the shell model (of a Gmsh surface mesh or a generated tube) or the
// linear tetrahedral model (`--element tet4`, of a Gmsh volume mesh, a generated box or
// cylinder), apply fixes and loads on named groups, solve K u = f and write a JSON report of
// every named node set's displacements. For checking a mesh, a material or the element choice
// before building a model image.
#pragma once

#include <string>
#include <vector>

#include <CLI/CLI.hpp>

namespace trainer::tools::modelc {

struct StaticOptions {
  std::string mesh_path;  // Gmsh MSH 4.1 ASCII
  std::string tube;       // "R,L,RINGS,SEGMENTS" (shell; exclusive with the other meshes)
  std::string box;        // "LX,LY,LZ,NX,NY,NZ" (tet4; exclusive with the other meshes)
  std::string cylinder;   // "R,H,RADIAL,AXIAL" (tet4; exclusive with the other meshes)
  std::string element;    // shell-rao | shell-dkt | tet4
  double young_modulus_pa = 0.0;
  double poisson_ratio = 0.0;
  double thickness_m = 0.0;                // shells only (0 = not given)
  double density_kg_per_m3 = 1000.0;       // enters only the lumped mass, not the static answer
  std::vector<std::string> fixes;          // GROUP=DOFS (tet4: x, y, z or all only)
  std::vector<std::string> loads;          // GROUP=FX,FY,FZ (N, total on the set)
  std::vector<std::string> surface_loads;  // GROUP=PX,PY,PZ (Pa, on a triangle set)
  std::string report_path;
};

// Adds the `static` subcommand to `app`. When the subcommand is parsed its callback runs
// run_static() and stores the exit status in `exit_code` (0 on success).
void add_static_command(CLI::App& app, int& exit_code);

// Runs the static solve and writes the report. Throws std::exception (with a message naming the
// input at fault) on any failure.
void run_static(const StaticOptions& options);

}  // namespace trainer::tools::modelc
