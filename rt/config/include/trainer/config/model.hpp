// Model definition files (config/models/*.toml): how a soft-tissue model is built offline by
// `modelc` (mesh, material, element, boundary conditions, modal settings) and where its image
// goes. A scene names the models it uses with [[model]] entries; the trainer loads only those
// images. Every key, unit, range and default: docs/config.md.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "trainer/core/expected.hpp"

namespace trainer::config {

enum class ModelKind : std::uint8_t { modal_shell };
enum class MeshSource : std::uint8_t { tube, gmsh };
enum class BendingKind : std::uint8_t { rao, dkt };
enum class ModalMethod : std::uint8_t { automatic, condensation, shift_invert };

struct TubeMeshConfig {  // [mesh] generator = "tube": a cylinder along +x from x = 0
  double radius_m = 0.0;
  double length_m = 0.0;
  int rings = 0;     // node rings along the axis (>= 2)
  int segments = 0;  // nodes around the circumference (>= 3)
};

struct ShellMaterialConfig {  // [material]
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

struct ModelDefinition {
  std::filesystem::path source_path;  // absolute
  std::string name;
  ModelKind kind = ModelKind::modal_shell;
  std::filesystem::path image_path;   // absolute; where modelc writes it, the trainer reads it
  MeshSource mesh_source = MeshSource::tube;
  TubeMeshConfig tube;
  std::filesystem::path mesh_file;    // gmsh source (absolute)
  ShellMaterialConfig material;
  BendingKind bending = BendingKind::dkt;
  std::vector<DofFixConfig> fixes;
  ModalConfig modal;
};

core::Expected<ModelDefinition> load_model_definition(const std::filesystem::path& file);

}  // namespace trainer::config
