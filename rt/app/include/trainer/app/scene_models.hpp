// The models a scene names, as loaded for the haptic cycle: reduced-modal ducts, Cotin tensor
// models and particle catheters, each with what collides with it, all carved from the arena at
// configure time (load_scene_models). A scene loads only the models it lists, and the app
// runs a model stage only when the scene has a model of its kind.
//
// Who touches what in the cycle:
//   modal stage    owns modal[]: contact, solve, step, surface; applies catheter_loads
//   tensor stage   owns tensor[]: contact, solve, surface
//   catheter stage owns catheters[]; reads modal[].surface, appends to modal[].catheter_loads
//   modal stage    reads catheters[].catheter positions (is a particle near a duct?)
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "trainer/app/app_stats.hpp"
#include "trainer/app/contact_surface.hpp"
#include "trainer/app/lazy_modal_surface.hpp"
#include "trainer/app/rigid_transform.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/model/catheter.hpp"
#include "trainer/model/forceps_catheter.hpp"
#include "trainer/model/modal_model.hpp"
#include "trainer/model/particle_contact.hpp"
#include "trainer/model/segment_contact.hpp"
#include "trainer/model/tensor_model.hpp"

namespace trainer::app {

// The runtime settings of a tensor model from its definition: contact capacity and the
// quasi-non-linear maps, each checked (monotone, c0 = 0) with the definition file named. The
// trainer and the tradeoff tool use it, so both run the model a definition describes.
core::Expected<model::TensorSettings> tensor_settings_from(
    const config::ModelDefinition& definition);

// A model the scene named, as loaded (for the report).
struct LoadedModelInfo {
  std::string name;
  config::ModelKind kind = config::ModelKind::modal_shell;
  std::string definition_path;
  std::size_t arena_bytes = 0;  // what creating the model carved from the arena (image included)
  // modal_shell
  std::string image_path;
  std::uint64_t image_checksum = 0;
  std::size_t image_bytes = 0;
  std::uint32_t node_count = 0;
  std::uint32_t mode_count = 0;
  bool static_correction = false;
  double prepared_time_step_s = 0.0;
  // tet_tensor (image fields above, node_count included)
  std::uint32_t contact_node_count = 0;
  std::uint32_t stored_node_count = 0;
  std::uint32_t max_contacts = 0;
  bool quasi_nonlinear = false;
  // catheter
  std::uint32_t particle_count = 0;
  double stable_substep_s = 0.0;          // the largest stable substep (model::Catheter)
  std::uint32_t substeps_per_period = 0;  // substeps one loop period costs
  std::uint32_t max_substeps = 0;         // the budget from the definition
  bool hold_start = false;
  bool has_insertion_goal = false;
  double insertion_target_depth_m = 0.0;
  // Placement in the trainer frame as the scene wrote it ([[model]] position_m, rotation_deg).
  std::array<double, 3> position_m{};
  std::array<double, 3> rotation_deg{};
  // Filled after the run (run_trainer): the catheter's particle positions when the loop ended.
  std::vector<std::array<float, 3>> final_positions_m;
};

// A modal model (the duct) and what touches it.
struct ModalModelState {
  std::optional<model::ModalModel> model;
  ContactSurface surface;
  // Present when the surface has a grid: the surface reconstructed lazily at haptic rate.
  std::optional<LazyModalSurface> lazy;
  std::span<const std::uint32_t> fixed_nodes;  // strictly increasing (the image's)
  // Shaft and jaws of the instruments touching it against the wall (ray-based collision; the
  // wall point found is imposed like the tip's).
  std::array<std::optional<model::SegmentSurfaceContact>, kMaxInstruments> segments{};
  // Reactions of the catheters' wall contacts (model frame), applied at the next step.
  std::array<model::NodeForce, model::ModalModel::kMaxLoadedNodes> catheter_loads{};
  std::size_t catheter_load_count = 0;
  float half_thickness_m = 0.0F;  // the shell's: walls lie this far from the mid-surface

  // Merges a catheter's reaction on one node into the pending loads (a clamped node's share
  // goes to the clamp); false when the capacity is full (the load is dropped).
  bool add_catheter_load(std::uint32_t node, const Eigen::Vector3f& force_n) noexcept;
};

// A Cotin tensor model (static: it changes only when a contact is imposed) and what touches it.
struct TensorModelState {
  std::optional<model::TensorModel> model;
  ContactSurface surface;
  std::span<const std::uint32_t> response_nodes;  // the nodes whose displacement is stored
  std::array<bool, kMaxInstruments> was_in_contact{};
  bool deformed_is_rest = true;
};

// A particle catheter and its contacts: point-based with each modal model's wall (same index
// as SceneModels::modal), ray-based with each instrument touching it (grasping included).
struct CatheterModelState {
  std::optional<model::Catheter> catheter;
  std::string name;                                           // setup-time only
  Eigen::Vector3f gravity_force_n = Eigen::Vector3f::Zero();  // m·g on every particle
  bool has_gravity = false;
  std::array<std::optional<model::ParticleSurfaceContact>, kMaxSceneModels> walls{};
  std::array<model::ParticleContactOutput, kMaxSceneModels> wall_out{};
  std::array<std::size_t, kMaxSceneModels> wall_first_plane{};
  std::array<std::optional<model::ForcepsCatheterContact>, kMaxInstruments> tools{};
  std::array<std::size_t, kMaxInstruments> tool_first_plane{};
  std::array<std::size_t, kMaxInstruments> tool_plane_count{};
  std::span<model::ContactPlane> planes;             // the step's planes: walls, then tools
  std::span<Eigen::Vector3f> model_frame_positions;  // scratch, one per particle
  std::span<Eigen::Vector3f> model_frame_velocities;
  model::CatheterContactSettings contact;  // the image's, for walls and tools
  // [model.insertion]: the lumen's entry, axis and radius, the depth to reach.
  bool has_goal = false;
  Eigen::Vector3f goal_entry_m = Eigen::Vector3f::Zero();
  Eigen::Vector3f goal_direction = Eigen::Vector3f::UnitX();
  float goal_radius_m = 0.0F;
  float goal_target_m = 0.0F;
};

struct SceneModels {
  std::array<ModalModelState, kMaxSceneModels> modal{};
  std::size_t modal_count = 0;
  std::array<TensorModelState, kMaxSceneModels> tensor{};
  std::size_t tensor_count = 0;
  std::array<CatheterModelState, kMaxSceneModels> catheters{};
  std::size_t catheter_count = 0;
  float catheter_period_s = 0.0F;  // the loop period: each cycle advances a catheter by it
  // Per model in scene order: what the report says of it, its placement.
  std::vector<LoadedModelInfo> info;
  std::array<RigidTransform, kMaxSceneModels> transforms{};

  std::span<ModalModelState> modal_models() noexcept { return {modal.data(), modal_count}; }
  std::span<TensorModelState> tensor_models() noexcept { return {tensor.data(), tensor_count}; }
  std::span<CatheterModelState> catheter_models() noexcept {
    return {catheters.data(), catheter_count};
  }
};

// Setup path: loads every model the scene names (images validated, models created, contacts
// sized for the instruments touching them) into `models`, carving from `arena`. Errors name
// the scene, the model and the file.
core::Expected<void> load_scene_models(const config::SceneConfig& scene, core::Arena& arena,
                                       SceneModels& models);

}  // namespace trainer::app
