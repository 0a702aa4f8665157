// Model definition files (config/models/*.toml): how a model is built offline by `modelc` —
// for a soft-tissue model its mesh, material, element, boundary conditions and modal or tensor
// settings, for a catheter its physical parameters, placement and contact settings — and where
// its image goes. A scene names the models it uses with [[model]] entries; the trainer loads
// only those. Every key, unit, range and default: docs/config.md.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "trainer/config/device.hpp"  // Vec3
#include "trainer/core/expected.hpp"

namespace trainer::config {

enum class ModelKind : std::uint8_t { modal_shell, catheter, tet_tensor };
enum class MeshSource : std::uint8_t { tube, gmsh, box, cylinder };
enum class BendingKind : std::uint8_t { rao, dkt };
enum class ModalMethod : std::uint8_t { automatic, condensation, shift_invert };

struct TubeMeshConfig {  // [mesh] generator = "tube": a cylinder along +x from x = 0
  double radius_m = 0.0;
  double length_m = 0.0;
  int rings = 0;     // node rings along the axis (>= 2)
  int segments = 0;  // nodes around the circumference (>= 3)
};

struct BoxMeshConfig {  // [mesh] generator = "box" (tet_tensor): [0,x]×[0,y]×[0,z]
  std::array<double, 3> size_m{};
  std::array<int, 3> divisions{};  // hexahedra per axis, each split into 6 tetrahedra
};

struct CylinderMeshConfig {  // [mesh] generator = "cylinder" (tet_tensor): about +z from z = 0
  double radius_m = 0.0;
  double height_m = 0.0;
  int radial = 0;  // concentric rings from the axis to the wall
  int axial = 0;   // layers along z
};

struct ShellMaterialConfig {  // [material] (thickness_m: shells only, 0 for tet_tensor)
  double young_modulus_pa = 0.0;
  double poisson_ratio = 0.0;
  double thickness_m = 0.0;
  double density_kg_per_m3 = 0.0;
  std::string reference;  // where the values come from (free text, required)
};

struct DofFixConfig {  // [[fix]]: dofs 0..5 = x, y, z, rx, ry, rz of every node of node_set
  std::string node_set;
  std::vector<int> dofs;
};

struct ModalConfig {  // [modal]
  std::uint32_t mode_count = 0;
  ModalMethod method = ModalMethod::automatic;
  double damping_ratio = 0.0;         // modal ζ added as Rayleigh α_M + β_K fitted at ω_1, ω_r
  double time_step_s = 0.0;           // the step the image is prepared for (metadata, checks)
  bool static_correction = true;      // store the residual compliance of the surface nodes
  std::string surface_set;            // node set the tools may touch ("" = all free nodes)
};

// Most particles a catheter may have: model::Catheter::kMaxParticles (the app checks they agree).
inline constexpr std::uint32_t kMaxCatheterParticles = 256;

// [catheter] and [pose] of a kind = "catheter" definition: the particle chain of
// model::Catheter (docs/catheter.md maps these to the chain's springs and masses).
struct CatheterConfig {
  double length_m = 0.0;
  double outer_radius_m = 0.0;
  double bending_stiffness_n_m2 = 0.0;   // EI
  double axial_stiffness_n = 0.0;        // EA
  double linear_density_kg_per_m = 0.0;  // ρ_l
  double damping_n_s_per_m = 0.0;        // b, per particle (force −b v on every particle)
  std::uint32_t particle_count = 0;      // N, 3..kMaxCatheterParticles
  std::uint32_t max_substeps = 0;        // cycle budget: most substeps one haptic period may cost
  // [pose], in the trainer frame.
  Vec3 start_m{};                        // particle 0 (the introducer)
  Vec3 direction{};                      // rest tangent from particle 0, unit (normalised on load)
  bool hold_start = true;                // particle 0 and the root tangent held (clamp_start)
  Vec3 gravity_m_per_s2{};               // applied as m·g on every particle each cycle
  // [contact] (optional table, every key optional): the catheter against duct walls (point-
  // based, every modal model in the scene) and against the forceps touching it (ray-based,
  // grasping). Stiffnesses are checked against the chain's stable substep when the scene loads.
  double wall_stiffness_n_per_m = 500.0;     // particle sphere vs duct wall
  double wall_damping_n_s_per_m = 0.02;
  double tool_stiffness_n_per_m = 300.0;     // catheter vs shaft and jaw capsules
  double grasp_stiffness_n_per_m = 3000.0;   // squeeze per metre of jaw closure past touching
  double grasp_friction = 0.6;               // slip when the pull exceeds this × the squeeze
  double max_contact_force_n = 4.0;          // per contact (walls and tools), and per jaw when grasping
};

enum class TensorStorage : std::uint8_t { surface, all };

// One quasi-non-linear amplitude map (Cotin §4.3): P(a) = Σ c_i a^i on [0, max_amplitude].
struct AmplitudeMapConfig {
  std::vector<double> coefficients{0.0, 1.0};  // c0 (must be 0), c1, ...; identity by default
  double max_amplitude = 0.0;                  // m or N; 0 = identity map (not configured)
};

struct TensorConfig {  // [tensor] and [nonlinear] (tet_tensor)
  std::string contact_set = "surface";  // node set tools may displace (fixed nodes dropped)
  TensorStorage stored = TensorStorage::surface;
  std::uint32_t max_contacts = 8;       // simultaneous contacts the runtime solves
  double time_step_s = 0.001;           // the haptic period (image metadata)
  bool nonlinear = false;               // [nonlinear] present
  AmplitudeMapConfig displacement_colinear;
  AmplitudeMapConfig displacement_orthogonal;
  AmplitudeMapConfig force_colinear;
  AmplitudeMapConfig force_orthogonal;
};

struct ModelDefinition {
  std::filesystem::path source_path;  // absolute
  std::string name;
  ModelKind kind = ModelKind::modal_shell;
  std::filesystem::path image_path;   // absolute; where modelc writes the image, the trainer reads it
  MeshSource mesh_source = MeshSource::tube;
  TubeMeshConfig tube;
  BoxMeshConfig box;
  CylinderMeshConfig cylinder;
  std::filesystem::path mesh_file;    // gmsh source (absolute)
  ShellMaterialConfig material;
  BendingKind bending = BendingKind::dkt;
  std::vector<DofFixConfig> fixes;
  ModalConfig modal;
  TensorConfig tensor;
  CatheterConfig catheter;            // kind == catheter only (the mesh fields above stay default)
};

core::Expected<ModelDefinition> load_model_definition(const std::filesystem::path& file);
// The same for a definition's text already in memory, read as if it were `file` (named in
// messages, its directory anchoring `image` and `mesh.file`; it need not exist).
core::Expected<ModelDefinition> load_model_definition_text(std::string_view text,
                                                           const std::filesystem::path& file);

}  // namespace trainer::config
