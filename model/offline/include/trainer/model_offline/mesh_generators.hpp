// Structured shell meshes made from a few parameters: the duct tube (the paper's geometry),
// a flat rectangular plate and a cylindrical panel (for tests and published benchmarks).
// Every generator names its boundary node sets, orients the triangles' normals consistently
// (outward for the tube and panel, +z for the plate), and hashes its parameters into
// source_hash so a model image records what it was built from.
#pragma once

#include <cstdint>
#include <initializer_list>

#include "trainer/core/expected.hpp"
#include "trainer/model_offline/shell_model.hpp"

namespace trainer::model::offline {

// How each structured quad is split into two triangles.
enum class TrianglePattern : std::uint8_t {
  alternating,  // diagonal direction flips from quad to quad (checkerboard): no mesh bias
  right,        // every quad split along the same diagonal (corner (i,j) to (i+1,j+1))
  left,         // every quad split along the other diagonal (corner (i+1,j) to (i,j+1))
};

// The source_hash of a generated mesh: XXH64 of the generator's name and parameters, printed
// as hexadecimal floats so any bit of any input changes it. Shared by the tet generators.
std::uint64_t hash_generator_parameters(const char* generator, std::initializer_list<double> reals,
                                        std::initializer_list<int> integers);

// Cylinder of radius `radius_m` along +x from x = 0 to x = `length_m`: `rings` node rings
// (≥ 2, including both ends) of `segments` nodes each (≥ 3), node (ring r, segment s) at
// index r·segments + s and position (x_r, R cos φ_s, R sin φ_s), φ_s = 2π s / segments.
// Quads alternate their diagonal. Node sets: "clamped" (x = 0 ring), "free_end" (x = L ring),
// "all"; triangle set "wall". Normals point outward.
core::Expected<ShellMesh> make_tube(double radius_m, double length_m, int rings, int segments);

// Flat plate [0, lx] × [0, ly] in the z = 0 plane with nx × ny quads (each ≥ 1) split by
// `pattern`; node (i, j) at index j·(nx+1) + i. Node sets "x0", "x1", "y0", "y1" (the four
// edges) and "all"; triangle set "plate". Normals +z.
core::Expected<ShellMesh> make_rectangle_plate(double lx_m, double ly_m, int nx, int ny,
                                               TrianglePattern pattern);

// Open cylindrical panel of radius `radius_m` about the x axis, x in [0, length_m], angle φ
// from `start_angle_rad` to `end_angle_rad` measured from +z towards +y, point
// (x, R sin φ, R cos φ) (so φ = 0 is the crown). `axial_divisions` × `arc_divisions` quads
// split by `pattern`; node (i along x, j along φ) at index j·(axial_divisions+1) + i.
// Node sets "x0", "x1", "arc0" (φ = start), "arc1" (φ = end), "all"; triangle set "panel".
// Normals point away from the axis.
core::Expected<ShellMesh> make_cylindrical_panel(double radius_m, double length_m,
                                                 double start_angle_rad, double end_angle_rad,
                                                 int axial_divisions, int arc_divisions,
                                                 TrianglePattern pattern);

}  // namespace trainer::model::offline
