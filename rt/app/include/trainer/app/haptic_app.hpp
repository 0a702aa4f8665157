// The haptic cycle (DESIGN.md "One cycle"): HAL read → kinematics → collide → forces →
// safety → HAL write → publish. Everything it touches is created at configure time (the
// per-instrument and per-object state lives in the arena); run_cycle() is noexcept, takes no
// locks and allocates nothing. It names only HAL interfaces, never a concrete backend.
#pragma once

#include <array>
#include <atomic>
#include <vector>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include "trainer/app/rigid_transform.hpp"
#include "trainer/app/telemetry.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/core/clock.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/core/histogram.hpp"
#include "trainer/core/log_ring.hpp"
#include "trainer/core/triple_buffer.hpp"
#include "trainer/hal/device.hpp"
#include "trainer/hal/joint_scale.hpp"
#include "trainer/kinematics/trocar_kinematics.hpp"
#include "trainer/loop/periodic_loop.hpp"
#include "trainer/model/catheter.hpp"
#include "trainer/model/bucket_grid.hpp"
#include "trainer/model/displacement_contact.hpp"
#include "trainer/model/forceps_catheter.hpp"
#include "trainer/model/particle_contact.hpp"
#include "trainer/model/image_loader.hpp"
#include "trainer/model/modal_image.hpp"
#include "trainer/model/modal_model.hpp"
#include "trainer/model/rigid_contact.hpp"
#include "trainer/model/segment_contact.hpp"
#include "trainer/model/tensor_image.hpp"
#include "trainer/model/tensor_model.hpp"
#include "trainer/safety/safety_supervisor.hpp"

namespace trainer::app {

// The runtime settings of a tensor model from its definition: contact capacity and the
// quasi-non-linear maps, each checked (monotone, c0 = 0) with the definition file named. The
// trainer and the tradeoff tool use it, so both run the model a definition describes.
core::Expected<model::TensorSettings> tensor_settings_from(const config::ModelDefinition& definition);

struct HalBinding {
  hal::EncoderInterface* encoders = nullptr;
  hal::ActuatorInterface* actuators = nullptr;
  hal::DigitalInputInterface* digital_inputs = nullptr;
  hal::DigitalOutputInterface* digital_outputs = nullptr;
};

struct InstrumentStats {
  float peak_force_n = 0.0F;
  float peak_depth_m = 0.0F;
  double force_sum_n = 0.0;  // over contact cycles, for the mean
  std::uint64_t contact_cycles = 0;
  std::uint64_t contact_onsets = 0;
  std::array<float, 5> peak_joint_effort{};
  // Against catheters: grasps started, slips (pulled out of the jaws), cycles holding one,
  // and the largest squeeze on both jaws together.
  std::uint64_t grasps = 0;
  std::uint64_t slips = 0;
  std::uint64_t grasping_cycles = 0;
  float peak_squeeze_n = 0.0F;
  std::uint64_t catheter_contact_cycles = 0;  // the shaft or a jaw pushed a catheter
  std::uint64_t wall_segment_contact_cycles = 0;  // the shaft or a jaw held a duct's wall
};

// Models one scene may name (HapticApp::kMaxModels; the per-model statistics are sized by it).
inline constexpr std::size_t kMaxSceneModels = 4;

// What a modal model (the duct) took from the tools and catheters over the run.
struct ModalModelStats {
  float peak_force_n = 0.0F;       // |total force on the model| in one cycle
  double force_sum_n = 0.0;        // over cycles with any load, for the mean
  std::uint64_t loaded_cycles = 0;
  std::uint64_t tool_contact_cycles = 0;
  std::uint64_t catheter_contact_cycles = 0;
  std::uint32_t peak_catheter_contacts = 0;  // particle–wall contacts in one cycle
  float peak_catheter_force_n = 0.0F;        // |total catheter force on the model|
};

// What a tensor model (Cotin's liver) took from the tools over the run.
struct TensorModelStats {
  float peak_force_n = 0.0F;          // |total force on the model| in one cycle
  double force_sum_n = 0.0;           // over loaded cycles, for the mean
  std::uint64_t loaded_cycles = 0;    // cycles with at least one tool contact
  std::uint64_t contact_onsets = 0;   // tool contacts started
  std::uint32_t peak_contact_nodes = 0;  // nodes imposed in one solve
  float peak_indentation_m = 0.0F;    // largest imposed node displacement
  std::uint64_t refused_solves = 0;   // solves the model refused (contacts released)
};

// Catheter progress against its [model.insertion] goal.
struct CatheterStats {
  float insertion_depth_m = 0.0F;       // at the last cycle
  float peak_insertion_depth_m = 0.0F;
  std::uint64_t first_target_cycle = 0;  // the first cycle at or past the target depth
  float peak_held_depth_m = 0.0F;        // the peak while an instrument grasped the catheter
  bool target_reached = false;
  std::uint64_t wall_contact_cycles = 0;
  std::uint64_t dropped_contacts = 0;  // beyond a capacity (counted, not applied)
};

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
  double stable_substep_s = 0.0;        // the largest stable substep (model::Catheter)
  std::uint32_t substeps_per_period = 0;  // substeps one loop period costs
  std::uint32_t max_substeps = 0;       // the budget from the definition
  bool hold_start = false;
  bool has_insertion_goal = false;
  double insertion_target_depth_m = 0.0;
  // Placement in the trainer frame as the scene wrote it ([[model]] position_m, rotation_deg).
  std::array<double, 3> position_m{};
  std::array<double, 3> rotation_deg{};
  // Filled after the run (run_trainer): the catheter's particle positions when the loop ended.
  std::vector<std::array<float, 3>> final_positions_m;
};

// Where one cycle's time goes (ns per cycle, real clock; all zero in simulated time). The
// phases run in this order and cover run_cycle() from the HAL read to the telemetry publish.
enum class CyclePhase : std::uint8_t {
  hal_read = 0,    // encoders, digital inputs, drive status; the safety chain's input checks
  kinematics,      // joint positions and rates, forward kinematics of every instrument
  modal_models,    // tool–duct contact (grid query, contact solve), the duct's step, its surface
  tensor_models,   // tool–tissue contact on Cotin's tensor models (solve, field, surface)
  catheters,       // catheter–wall and tool–catheter collision, grasping, the catheter's substeps
  forces,          // rigid objects, Jᵀ efforts, the safety chain's force limits
  hal_write,       // actuator commands, digital outputs, fault logging, telemetry
};
inline constexpr std::size_t kCyclePhaseCount = 7;
inline constexpr std::array<const char*, kCyclePhaseCount> kCyclePhaseNames = {
    "hal_read", "kinematics", "modal_models", "tensor_models", "catheters", "forces", "hal_write"};

struct AppStats {
  std::uint64_t cycles = 0;
  std::array<core::LatencyHistogram, kCyclePhaseCount> phase_ns{};
  std::uint64_t hal_read_errors = 0;
  std::uint64_t hal_write_errors = 0;
  std::uint64_t invalid_encoder_cycles = 0;
  std::uint64_t saturated_actuator_cycles = 0;
  // Instrument-cycles whose efforts the actuators' effort limits scaled or clamped
  // (force_command.hpp); the drives then never clip.
  std::uint64_t effort_limited_cycles = 0;
  std::uint64_t armed_cycles = 0;
  std::uint64_t model_step_errors = 0;
  std::array<InstrumentStats, kMaxInstruments> instruments{};
  std::array<ModalModelStats, kMaxSceneModels> modal_models{};  // modal models in scene order
  std::array<TensorModelStats, kMaxSceneModels> tensor_models{};  // tensor models in scene order
  std::array<CatheterStats, kMaxSceneModels> catheters{};       // catheters in scene order
};

class HapticApp final : public loop::CycleTask {
  // The property test (tests/rt/app/haptic_app_property_test.cpp) puts the models in random
  // states through their own public calls; nothing else reaches inside.
  friend class HapticAppTestAccess;

 public:
  // Consecutive HAL read/write errors tolerated (the cycle holds the last good state)
  // before the device is declared lost and a fault latched.
  static constexpr std::uint32_t kToleratedErrorStreak = 3;
  static constexpr std::size_t kMaxObjects = 16;
  static constexpr std::size_t kMaxModels = kMaxSceneModels;

  // Setup path: checks the HAL offers the channels the scene needs and carves all cycle state
  // from `arena`. Errors name the scene/device item that does not fit.
  static core::Expected<std::unique_ptr<HapticApp>> create(
      const config::SceneConfig& scene, HalBinding hal, core::Arena& arena, core::LogRing& log,
      core::TripleBuffer<TelemetrySnapshot>& telemetry, core::Clock& clock);

  core::Status run_cycle(const loop::CycleTiming& timing) noexcept override;
  void on_overrun_fault(std::uint32_t streak) noexcept override;

  // From any thread: ask the safety chain to arm at the next cycle (an explicit reset).
  void request_reset() noexcept { reset_requested_.store(true, std::memory_order_release); }
  // RT or non-RT, after the loop stopped: zero every output, disable drives, latch shutdown.
  void shutdown() noexcept;

  const AppStats& stats() const noexcept { return stats_; }
  const safety::SafetySupervisor& safety() const noexcept { return safety_; }
  std::size_t instrument_count() const noexcept { return instruments_.size(); }
  const std::vector<LoadedModelInfo>& models() const noexcept { return model_info_; }
  // Placement of the model named `name` (model frame → trainer frame), nullopt if the scene
  // has no such model. model_transform(index) is the same for models()[index].
  std::optional<RigidTransform> model_transform(const std::string& name) const;
  const RigidTransform& model_transform(std::size_t index) const noexcept {
    return model_transforms_[index];
  }
  // Non-RT, after the loop stopped: the current particle positions of the catheter model
  // named `name` (empty if the scene has no such catheter).
  std::vector<std::array<float, 3>> catheter_positions_m(const std::string& name) const;

  HapticApp(const HapticApp&) = delete;
  HapticApp& operator=(const HapticApp&) = delete;
  ~HapticApp() = default;

 private:
  struct InstrumentState {
    kinematics::TrocarKinematics kinematics;
    std::array<hal::JointKind, 5> kinds{};  // for the encoder-jump limits
    // Per joint, the largest effort its drive accepts (N·m, N): the device's current limits.
    kinematics::JointVector effort_limits{};
    std::size_t first_channel = 0;
    kinematics::JointVector position{};
    kinematics::JointVector velocity{};
    bool has_position = false;
    bool was_in_contact = false;
    // This cycle's pose (sense_instrument) and the force the soft-tissue models put on the
    // tip (contact_models), trainer frame.
    kinematics::InstrumentPose pose{};
    Eigen::Vector3f tip_velocity = Eigen::Vector3f::Zero();
    Eigen::Vector3f previous_tip_m = Eigen::Vector3f::Zero();
    bool has_previous_tip = false;
    Eigen::Vector3f model_force_n = Eigen::Vector3f::Zero();
    bool model_contact = false;
    float model_indentation_m = 0.0F;  // the largest displacement a model contact imposes
    bool wall_segment_contact = false;  // the shaft or a jaw holds a duct's wall this cycle
    // Forces on the shaft and jaws this cycle (ray-based): from the ducts' walls, then from
    // catheters (jaw squeeze and the pull of a grasped catheter included). Beyond the
    // capacity they are dropped and counted as model step errors.
    std::array<model::ToolForce, 2 * model::ForcepsCatheterContact::kMaxToolForces +
                                     kMaxSceneModels * model::SegmentSurfaceContact::kMaxSegments>
        tool_forces{};
    std::size_t tool_force_count = 0;
    bool catheter_contact = false;
    bool grasping = false;
    float squeeze_n = 0.0F;
  };
  // Tool contact on one modal model: its deformed surface (rebuilt after every step), the
  // bucket grid over it, and a displacement-driven contact per instrument touching it.
  struct ModalContactState {
    RigidTransform transform;
    std::uint32_t touched_by_mask = 0;
    std::span<const float> rest_positions;
    std::span<const std::uint32_t> triangles;
    std::span<const std::uint32_t> fixed_nodes;  // strictly increasing (the image's)
    std::span<float> deformed;  // 3n, model frame
    std::optional<model::BucketGrid> grid;
    std::array<std::optional<model::DisplacementContact>, kMaxInstruments> contacts{};
    // Shaft and jaws of the same instruments against the wall (ray-based collision; the wall
    // point found is imposed like the tip's).
    std::array<std::optional<model::SegmentSurfaceContact>, kMaxInstruments> segments{};
    // The rest mesh's box grown by a margin: while no touching tool is inside it and no contact
    // holds, the surface is not rebuilt (a tool far away costs nothing).
    model::Aabb near_box{};
    bool surface_ready = false;
    std::span<float> grid_positions;  // 3n: the surface the grid was last rebuilt over
    bool grid_built = false;
    // Reactions of the catheters' wall contacts (model frame), applied at the next step.
    std::array<model::NodeForce, model::ModalModel::kMaxLoadedNodes> catheter_loads{};
    std::size_t catheter_load_count = 0;
    std::size_t vertex_count = 0;
    float half_thickness_m = 0.0F;  // the shell's: walls lie this far from the mid-surface
  };
  // Tool contact on one tensor model: the same displacement-driven contact as on the duct
  // (the touched triangle's free nodes follow the tip), solved by the tensor model; its
  // deformed boundary rebuilt from the stored responses after every solve.
  struct TensorContactState {
    RigidTransform transform;
    std::uint32_t touched_by_mask = 0;
    std::span<const float> rest_positions;      // 3n, model frame
    std::span<const std::uint32_t> triangles;   // the boundary faces
    std::span<const std::uint32_t> response_nodes;
    std::span<float> deformed;                  // 3n, model frame
    std::optional<model::BucketGrid> grid;
    std::array<std::optional<model::DisplacementContact>, kMaxInstruments> contacts{};
    std::array<bool, kMaxInstruments> was_in_contact{};
    model::Aabb near_box{};
    bool surface_ready = false;
    std::span<float> grid_positions;
    bool grid_built = false;
    bool deformed_is_rest = true;
  };
  // One shaft/jaw contact on a modal model this cycle, imposed with the tips' targets.
  struct SegmentTarget {
    std::size_t instrument = 0;
    model::ToolSegment segment = model::ToolSegment::shaft;
    float along_m = 0.0F;
    float depth_m = 0.0F;
    Eigen::Vector3f normal = Eigen::Vector3f::UnitZ();  // model frame, towards the tool
    Eigen::Vector3f on_tissue_n = Eigen::Vector3f::Zero();  // model frame, from the solve
    bool active = true;
  };
  struct CatheterState;  // below, with the models
  struct ObjectState {
    config::ObjectKind kind = config::ObjectKind::plane;
    model::RigidPlane plane;
    model::RigidSphere sphere;
    std::uint32_t touched_by_mask = 0;  // bit per instrument
  };

  HapticApp(core::LogRing& log, core::TripleBuffer<TelemetrySnapshot>& telemetry,
            core::Clock& clock, HalBinding hal, const safety::SafetyLimits& limits,
            std::size_t instrument_count, const config::DigitalConfig& digital) noexcept;

  bool read_inputs(const loop::CycleTiming& timing, safety::InputConditions& conditions) noexcept;
  // A bucket grid for a surface, cells 1.5 × its longest edge at rest, the copy of the positions
  // it is built over (`grid_positions`, 3n), and the rest surface's box grown by
  // kSurfaceMarginM into `near_box`.
  static core::Expected<model::BucketGrid> make_surface_grid(std::span<const float> rest_positions,
                                                             std::span<const std::uint32_t> triangles,
                                                             model::Aabb& near_box,
                                                             std::span<float>& grid_positions,
                                                             core::Arena& arena);
  static core::Expected<TensorContactState> make_tensor_contact(
      const config::SceneModelConfig& entry, const model::ModelImage& image,
      const model::TensorModel& tensor, std::size_t instrument_count, core::Arena& arena);
  // Makes `grid` answer for the `deformed` surface: the grid is rebuilt with a slack of
  // kGridSlackCells cells, and only when some vertex has moved farther than the slack from
  // `grid_positions` (then copied from `deformed`). False on a refusal.
  static bool fit_grid(model::BucketGrid& grid, bool& grid_built, std::span<float> grid_positions,
                       std::span<const float> deformed, std::span<const std::uint32_t> triangles) noexcept;
  // `with_grid`: build the bucket grid even if no instrument touches the model (a catheter does).
  static core::Expected<ModalContactState> make_modal_contact(
      const config::SceneModelConfig& entry, const model::ModelImage& image,
      std::size_t instrument_count, bool with_grid, core::Arena& arena);
  void sense_instrument(std::size_t index, const loop::CycleTiming& timing) noexcept;
  // Tool contacts on the modal models, their solve and step, the surfaces for the next cycle.
  void contact_modal_models() noexcept;
  void refresh_surface(ModalContactState& state, const model::ModalModel& modal) noexcept;
  // Shaft and jaw contacts of the instruments touching a modal model, as imposed displacements
  // appended after the tips' (skipping nodes already imposed); returns how many segments.
  std::size_t gather_segment_targets(
      ModalContactState& state, const model::TriangleMeshView& view,
      std::array<model::ImposedDisplacement, model::ModalModel::kMaxContacts>& targets,
      std::array<std::size_t, model::ModalModel::kMaxContacts>& owner,
      std::array<std::int32_t, model::ModalModel::kMaxContacts>& segment_of, std::size_t& target_count,
      std::span<SegmentTarget> segment_targets) noexcept;
  // Tool contacts on the tensor models, their solve, the surfaces for the next cycle.
  void contact_tensor_models() noexcept;
  static void refresh_tensor_surface(TensorContactState& state, model::TensorModel& tensor) noexcept;
  // Catheters: wall and tool contact planes, the step, the tools' forces, the walls' reactions.
  void step_catheters() noexcept;
  static model::ForcepsShape forceps_shape(const InstrumentState& instrument) noexcept;
  static bool add_catheter_load(ModalContactState& wall, std::uint32_t node, const Eigen::Vector3f& force_n) noexcept;
  void step_catheter(std::size_t index) noexcept;
  core::Expected<void> add_catheter_contacts(const config::SceneModelConfig& entry,
                                             CatheterState& state, core::Arena& arena);
  void render_instrument(std::size_t index, const loop::CycleTiming& timing) noexcept;
  void write_outputs(bool armed) noexcept;
  void publish(const loop::CycleTiming& timing) noexcept;
  void zero_commands() noexcept;
  std::uint64_t raised_fault_count() const noexcept;  // the supervisor's raises of every kind

  core::LogRing& log_;
  core::TripleBuffer<TelemetrySnapshot>& telemetry_;
  core::Clock& clock_;
  HalBinding hal_;
  safety::SafetySupervisor safety_;
  config::DigitalConfig digital_;

  // Cycle state, carved from the arena at create().
  std::span<InstrumentState> instruments_;
  std::span<ObjectState> objects_;
  std::span<hal::EncoderSample> encoder_samples_;
  std::span<hal::ActuatorCommand> commands_;
  std::span<hal::ActuatorStatus> actuator_status_;
  std::span<InstrumentTelemetry> instrument_out_;
  // Models the scene names (modal ducts, catheters), their data in the arena; stepped every cycle.
  std::array<std::optional<model::ModalModel>, kMaxModels> modal_models_{};
  std::array<ModalContactState, kMaxModels> modal_contacts_{};  // same index as modal_models_
  std::size_t modal_model_count_ = 0;
  struct CatheterState {
    std::optional<model::Catheter> catheter;
    Eigen::Vector3f gravity_force_n = Eigen::Vector3f::Zero();  // m·g on every particle
    bool has_gravity = false;
    std::string name;  // setup-time only
    // Point-based contact with each modal model (same index as modal_models_), ray-based
    // contact and grasping with each instrument touching the catheter.
    std::array<std::optional<model::ParticleSurfaceContact>, kMaxModels> walls{};
    std::array<model::ParticleContactOutput, kMaxModels> wall_out{};
    std::array<std::size_t, kMaxModels> wall_first_plane{};
    std::array<std::optional<model::ForcepsCatheterContact>, kMaxInstruments> tools{};
    std::array<std::size_t, kMaxInstruments> tool_first_plane{};
    std::array<std::size_t, kMaxInstruments> tool_plane_count{};
    std::span<model::ContactPlane> planes;  // the step's planes: walls, then tools
    std::span<Eigen::Vector3f> model_frame_positions;  // scratch, one per particle
    std::span<Eigen::Vector3f> model_frame_velocities;
    float wall_stiffness_n_per_m = 0.0F;
    float wall_damping_n_s_per_m = 0.0F;
    float max_contact_force_n = 0.0F;
    bool has_goal = false;
    Eigen::Vector3f goal_entry_m = Eigen::Vector3f::Zero();
    Eigen::Vector3f goal_direction = Eigen::Vector3f::UnitX();
    float goal_radius_m = 0.0F;
    float goal_target_m = 0.0F;
  };
  std::array<CatheterState, kMaxModels> catheters_{};
  // Cotin tensor models (static: they change only when a contact is imposed).
  std::array<std::optional<model::TensorModel>, kMaxModels> tensor_models_{};
  std::array<TensorContactState, kMaxModels> tensor_contacts_{};  // same index as tensor_models_
  std::size_t tensor_model_count_ = 0;
  std::size_t catheter_count_ = 0;
  float catheter_period_s_ = 0.0F;  // the loop period: each cycle advances the chain by it
  std::vector<LoadedModelInfo> model_info_;  // setup-time description, never touched in the cycle
  // Per model in scene order (as model_info_), from [[model]] position_m / rotation_deg; the
  // modal contacts keep their own copy.
  std::array<RigidTransform, kMaxModels> model_transforms_{};

  AppStats stats_{};
  std::uint32_t read_error_streak_ = 0;
  std::uint32_t write_error_streak_ = 0;
  std::uint32_t last_logged_faults_ = 0;
  // Faults raised (every kind, repeats included) when the last cycle published its state.
  std::uint64_t raised_at_publish_ = 0;
  std::atomic<bool> reset_requested_{false};
};

}  // namespace trainer::app
