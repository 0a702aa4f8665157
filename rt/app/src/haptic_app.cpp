#include "trainer/app/haptic_app.hpp"

#include "trainer/app/force_command.hpp"

#include <bit>
#include <limits>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

namespace trainer::app {

namespace {

using kinematics::kJointCount;
using Vec3 = Eigen::Vector3f;

// Joint rates come from differentiated encoder positions, low-passed at this cutoff: high
// enough not to lag the hand (human motion < 10 Hz), low enough to tame quantisation noise
// (one count per cycle at 1 kHz would otherwise read as several rad/s).
constexpr double kVelocityCutoffHz = 150.0;

Vec3 to_vec3(const std::array<double, 3>& v) {
  return {static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2])};
}

bool bit_set(std::uint32_t levels, int bit) {
  return bit >= 0 && ((levels >> static_cast<unsigned>(bit)) & 1U) != 0;
}

safety::SafetyLimits limits_from(const config::SafetyConfig& cfg) {
  safety::SafetyLimits limits;
  limits.max_force_n = static_cast<float>(cfg.max_force_n);
  limits.max_force_rate_n_per_s = static_cast<float>(cfg.max_force_rate_n_per_s);
  limits.max_joint_speed_rad_per_s = static_cast<float>(cfg.max_joint_speed_rad_per_s);
  limits.max_insertion_speed_m_per_s = static_cast<float>(cfg.max_insertion_speed_m_per_s);
  limits.passivity_energy_bound_j = static_cast<float>(cfg.passivity_energy_bound_j);
  limits.require_enable_input = cfg.require_enable_input;
  return limits;
}

static_assert(config::kMaxCatheterParticles == model::Catheter::kMaxParticles,
              "the configuration's particle limit must be the runtime catheter's");

// The chain from its configuration: one loop period per cycle, the definition's budget.
core::Expected<model::Catheter> create_catheter(const config::CatheterConfig& cfg, float period_s,
                                                std::uint32_t plane_capacity, core::Arena& arena) {
  model::CatheterParams params;
  params.length_m = static_cast<float>(cfg.length_m);
  params.outer_radius_m = static_cast<float>(cfg.outer_radius_m);
  params.bending_stiffness_n_m2 = static_cast<float>(cfg.bending_stiffness_n_m2);
  params.axial_stiffness_n = static_cast<float>(cfg.axial_stiffness_n);
  params.linear_density_kg_per_m = static_cast<float>(cfg.linear_density_kg_per_m);
  params.damping_n_s_per_m = static_cast<float>(cfg.damping_n_s_per_m);
  params.particle_count = cfg.particle_count;
  model::CatheterSetup setup;
  setup.start_position_m = to_vec3(cfg.start_m);
  setup.direction = to_vec3(cfg.direction);
  setup.haptic_period_s = period_s;
  setup.max_substeps = cfg.max_substeps;
  setup.max_contact_planes = plane_capacity;
  return model::Catheter::create(params, setup, arena);
}

// Wall contacts kept per catheter particle and modal model (a particle squeezed between two
// walls has two patches).
constexpr std::uint32_t kWallContactsPerParticle = 2;
// Catheter–wall contacts are found this far beyond touching, so a contact that closes during
// the period is already a plane the substeps evaluate (more than a period's travel at 1 m/s).
constexpr float kWallDetectionMarginM = 0.001F;
// The instrument's capsules against catheters (a 5 mm instrument, jaws tapering to 2 mm).
constexpr float kShaftRadiusM = 0.0025F;
constexpr float kJawRadiusM = 0.001F;

// The forceps tip as seen by soft-tissue contact: a sphere of this radius at the closed jaws'
// tip (jaws of a 5 mm instrument taper to about 2 mm).
constexpr float kForcepsTipRadiusM = 0.001F;
// How far outside a model's rest mesh a tool tip must be for the model's surface to be left
// stale: more than the model deforms plus one cycle of tool travel.
constexpr float kSurfaceMarginM = 0.02F;
// Slack of the surfaces' bucket grids, in cells: a rebuild stores every triangle with its box
// grown by it, so the grid stays right until a vertex has moved that far (BucketGrid). A
// quarter cell (~0.75 mm on the duct) triples the (triangle, cell) entries of a duct-like tube
// (1,568 → 4,864, within max_entries = 27 per triangle) and rebuilds only when the wall has
// moved that far instead of every cycle (docs/collision.md).
constexpr float kGridSlackCells = 0.25F;
// Shaft and jaws against a duct wall: the touched wall point is imposed this far inside the
// capsule's reach (not at its edge), so the contact persists from one cycle to the next instead
// of ending the moment the wall sits exactly at the reach and springing back the next.
constexpr float kSegmentSkinM = 5e-4F;
// The shaft is tested only inside the surface's rest box grown by this much.
constexpr float kSegmentClipMarginM = 0.01F;

// A forceps tip on a surface. A grid query can never return more than every triangle: sized
// so, no contact is ever lost to a full candidate list (a few kB per contact on these meshes).
model::DisplacementContactSettings tip_contact_settings(std::span<const std::uint32_t> triangles) {
  model::DisplacementContactSettings settings;
  settings.tip_radius_m = kForcepsTipRadiusM;
  settings.max_candidates = static_cast<std::uint32_t>(triangles.size() / 3);
  return settings;
}

}  // namespace

core::Expected<model::TensorSettings> tensor_settings_from(const config::ModelDefinition& definition) {
  const config::TensorConfig& tensor = definition.tensor;
  model::TensorSettings settings;
  settings.max_contacts = tensor.max_contacts;
  const auto map = [&](const config::AmplitudeMapConfig& cfg, const char* name,
                       model::AmplitudeMap& out) -> core::Expected<void> {
    if (cfg.max_amplitude == 0.0) return {};  // not configured: identity
    std::string what = definition.source_path.string();
    what.append(": [nonlinear.").append(name).append("]");
    auto created = model::AmplitudeMap::create(cfg.coefficients, cfg.max_amplitude, what);
    if (!created) return std::move(created).error();
    out = created.value();
    return {};
  };
  if (auto ok = map(tensor.displacement_colinear, "displacement_colinear",
                    settings.nonlinear.displacement_colinear); !ok) {
    return std::move(ok).error();
  }
  if (auto ok = map(tensor.displacement_orthogonal, "displacement_orthogonal",
                    settings.nonlinear.displacement_orthogonal); !ok) {
    return std::move(ok).error();
  }
  if (auto ok = map(tensor.force_colinear, "force_colinear", settings.nonlinear.force_colinear);
      !ok) {
    return std::move(ok).error();
  }
  if (auto ok = map(tensor.force_orthogonal, "force_orthogonal",
                    settings.nonlinear.force_orthogonal); !ok) {
    return std::move(ok).error();
  }
  return settings;
}

// The instrument's segments as the catheter contact sees them.
model::ForcepsShape HapticApp::forceps_shape(const InstrumentState& instrument) noexcept {
  const kinematics::InstrumentPose& pose = instrument.pose;
  model::ForcepsShape shape;
  shape.shaft_start_m = pose.shaft_start_m;
  shape.hinge_m = pose.hinge_m;
  shape.jaw_tips_m = pose.jaw_tips_m;
  shape.direction = pose.direction;
  shape.opening_direction = pose.opening_direction;
  shape.grip_rad = instrument.position[kinematics::kGrip];
  shape.velocity_m_per_s = instrument.tip_velocity;
  return shape;
}

// Merges a catheter's reaction on one node into the model's pending loads; false when the
// model's load capacity is full (the load is dropped).
bool HapticApp::add_catheter_load(ModalContactState& wall, std::uint32_t node, const Vec3& force_n) noexcept {
  // A clamped node cannot move: the clamp takes its share (the model refuses loads there).
  if (std::binary_search(wall.fixed_nodes.begin(), wall.fixed_nodes.end(), node)) return true;
  for (std::size_t k = 0; k < wall.catheter_load_count; ++k) {
    if (wall.catheter_loads[k].node == node) {
      wall.catheter_loads[k].force_n += force_n;
      return true;
    }
  }
  if (wall.catheter_load_count >= wall.catheter_loads.size()) return false;
  wall.catheter_loads[wall.catheter_load_count++] = model::NodeForce{node, force_n};
  return true;
}

namespace {

// What the report says of a model loaded from an image, whatever its kind.
LoadedModelInfo image_model_info(const config::SceneModelConfig& entry,
                                 const config::ModelDefinition& definition,
                                 const model::ModelImage& image, std::size_t arena_bytes) {
  LoadedModelInfo info;
  info.name = entry.name;
  info.kind = definition.kind;
  info.definition_path = definition.source_path.string();
  info.arena_bytes = arena_bytes;
  info.image_path = definition.image_path.string();
  info.image_checksum = image.checksum();
  info.image_bytes = image.bytes().size();
  info.node_count = image.metadata().node_count;
  info.prepared_time_step_s = image.metadata().time_step_s;
  return info;
}

}  // namespace

HapticApp::HapticApp(core::LogRing& log, core::TripleBuffer<TelemetrySnapshot>& telemetry,
                     core::Clock& clock, HalBinding hal, const safety::SafetyLimits& limits,
                     std::size_t instrument_count, const config::DigitalConfig& digital) noexcept
    : log_(log),
      telemetry_(telemetry),
      clock_(clock),
      hal_(hal),
      safety_(limits, instrument_count),
      digital_(digital) {}

core::Expected<std::unique_ptr<HapticApp>> HapticApp::create(
    const config::SceneConfig& scene, HalBinding hal, core::Arena& arena, core::LogRing& log,
    core::TripleBuffer<TelemetrySnapshot>& telemetry, core::Clock& clock) {
  const std::string where = scene.source_path.string();
  if (hal.encoders == nullptr || hal.actuators == nullptr) {
    return core::make_error(where + ": the selected HAL offers no encoders or no actuators");
  }
  const std::size_t instrument_count = scene.instruments.size();
  if (instrument_count == 0 || instrument_count > kMaxInstruments) {
    return core::make_error(where + ": a scene needs 1 to " + std::to_string(kMaxInstruments) +
                            " instruments, it has " + std::to_string(instrument_count));
  }
  if (scene.objects.size() > kMaxObjects) {
    return core::make_error(where + ": at most " + std::to_string(kMaxObjects) +
                            " objects, the scene has " + std::to_string(scene.objects.size()));
  }
  const std::size_t channel_count = scene.device.instruments.size() * kJointCount;
  if (hal.encoders->encoder_count() < channel_count ||
      hal.actuators->actuator_count() < channel_count) {
    return core::make_error(where + ": device '" + scene.device.name + "' offers " +
                            std::to_string(hal.encoders->encoder_count()) + " encoders and " +
                            std::to_string(hal.actuators->actuator_count()) +
                            " actuators; the scene needs " + std::to_string(channel_count));
  }

  std::unique_ptr<HapticApp> app(new HapticApp(log, telemetry, clock, hal,
                                               limits_from(scene.safety), instrument_count,
                                               scene.device.digital));

  auto instruments = arena.allocate_array<InstrumentState>(instrument_count, "instrument state");
  if (!instruments) return std::move(instruments).error();
  auto objects = arena.allocate_array<ObjectState>(scene.objects.size(), "rigid objects");
  if (!objects) return std::move(objects).error();
  auto samples = arena.allocate_array<hal::EncoderSample>(channel_count, "encoder samples");
  if (!samples) return std::move(samples).error();
  auto commands = arena.allocate_array<hal::ActuatorCommand>(channel_count, "actuator commands");
  if (!commands) return std::move(commands).error();
  auto status = arena.allocate_array<hal::ActuatorStatus>(channel_count, "actuator status");
  if (!status) return std::move(status).error();
  auto out = arena.allocate_array<InstrumentTelemetry>(instrument_count, "instrument telemetry");
  if (!out) return std::move(out).error();
  app->instruments_ = *instruments;
  app->objects_ = *objects;
  app->encoder_samples_ = *samples;
  app->commands_ = *commands;
  app->actuator_status_ = *status;
  app->instrument_out_ = *out;

  for (std::size_t i = 0; i < instrument_count; ++i) {
    const std::size_t device_index = scene.instruments[i].device_instrument;
    const config::InstrumentDeviceConfig& device = scene.device.instruments[device_index];
    kinematics::TrocarGeometry geometry;
    geometry.pivot_m = to_vec3(device.trocar_position_m);
    geometry.shaft_axis = to_vec3(device.shaft_axis);
    geometry.up_axis = to_vec3(device.up_axis);
    geometry.shaft_length_m = static_cast<float>(device.shaft_length_m);
    geometry.jaw_length_m = static_cast<float>(device.jaw_length_m);
    InstrumentState& state = app->instruments_[i];
    state.kinematics = kinematics::TrocarKinematics(geometry);
    state.first_channel = device_index * kJointCount;
    for (std::size_t j = 0; j < kJointCount; ++j) {
      state.kinds[j] = device.joints[j].kind;
      state.effort_limits[j] = effort_limit(config::joint_scale(device.joints[j]));
    }
  }

  for (std::size_t k = 0; k < scene.objects.size(); ++k) {
    const config::ObjectConfig& object = scene.objects[k];
    ObjectState& state = app->objects_[k];
    state.kind = object.kind;
    const model::PenaltyMaterial material{static_cast<float>(object.stiffness_n_per_m),
                                          static_cast<float>(object.damping_n_s_per_m)};
    if (object.kind == config::ObjectKind::plane) {
      state.plane = model::RigidPlane(to_vec3(object.point_m), to_vec3(object.normal), material);
    } else {
      state.sphere = model::RigidSphere(to_vec3(object.center_m),
                                        static_cast<float>(object.radius_m), material);
    }
    for (std::size_t instrument : object.touched_by) {
      state.touched_by_mask |= 1U << static_cast<unsigned>(instrument);
    }
  }
  if (scene.models.size() > kMaxModels) {
    return core::make_error(where + ": at most " + std::to_string(kMaxModels) +
                            " models, the scene has " + std::to_string(scene.models.size()));
  }
  app->catheter_period_s_ = static_cast<float>(static_cast<double>(scene.loop.period_ns) * 1e-9);
  for (const config::SceneModelConfig& entry : scene.models) {
    const config::ModelDefinition& definition = entry.definition;
    const std::size_t arena_before = arena.used_bytes();
    if (definition.kind == config::ModelKind::catheter) {
      const auto modal_count = static_cast<std::uint32_t>(
          std::count_if(scene.models.begin(), scene.models.end(), [](const config::SceneModelConfig& other) {
            return other.definition.kind == config::ModelKind::modal_shell;
          }));
      const std::uint32_t plane_capacity =
          modal_count * kWallContactsPerParticle * definition.catheter.particle_count +
          static_cast<std::uint32_t>(entry.touched_by.size() * model::ForcepsCatheterContact::kMaxPlanes);
      auto created = create_catheter(definition.catheter, app->catheter_period_s_, plane_capacity, arena);
      if (!created) {
        return core::make_error(where + ": model '" + entry.name + "' (" +
                                definition.source_path.string() + "): " + created.error().message);
      }
      CatheterState& state = app->catheters_[app->catheter_count_++];
      state.catheter.emplace(std::move(*created));
      state.catheter->clamp_start(definition.catheter.hold_start);
      const Vec3 gravity = to_vec3(definition.catheter.gravity_m_per_s2);
      state.gravity_force_n = state.catheter->particle_mass_kg() * gravity;
      state.has_gravity = !gravity.isZero(0.0F);
      state.name = entry.name;
      LoadedModelInfo info;
      info.name = entry.name;
      info.kind = config::ModelKind::catheter;
      info.definition_path = definition.source_path.string();
      info.arena_bytes = arena.used_bytes() - arena_before;
      info.particle_count = state.catheter->particle_count();
      info.stable_substep_s = static_cast<double>(state.catheter->stable_substep_s());
      info.substeps_per_period = state.catheter->substeps_per_period();
      info.max_substeps = definition.catheter.max_substeps;
      info.hold_start = definition.catheter.hold_start;
      info.has_insertion_goal = entry.insertion.has_value();
      info.insertion_target_depth_m = entry.insertion ? entry.insertion->target_depth_m : 0.0;
      app->model_info_.push_back(std::move(info));
      continue;
    }
    if (definition.kind == config::ModelKind::tet_tensor) {
      const std::string image_name = definition.image_path.string();
      auto settings = tensor_settings_from(definition);
      if (!settings) return core::make_error(where + ": model '" + entry.name + "': " +
                                             settings.error().message);
      auto image = model::load_model_image(definition.image_path, arena, model::ImageLimits{},
                                           model::ModelKind::tet_tensor);
      if (!image) {
        return core::make_error(where + ": model '" + entry.name + "': " + image.error().message +
                                " (build it with: modelc build --scene " + where + ")");
      }
      auto tensor = model::TensorModel::create(model::tensor_model_data(*image), *settings, arena);
      if (!tensor) {
        return core::make_error(where + ": model '" + entry.name + "' (" + image_name +
                                "): " + tensor.error().message);
      }
      const std::size_t tensor_index = app->tensor_model_count_++;
      app->tensor_models_[tensor_index].emplace(std::move(*tensor));
      auto contact_state = make_tensor_contact(entry, *image, *app->tensor_models_[tensor_index],
                                               scene.instruments.size(), arena);
      if (!contact_state) {
        return core::make_error(where + ": model '" + entry.name + "' (" +
                                definition.source_path.string() + "): " + contact_state.error().message);
      }
      app->tensor_contacts_[tensor_index] = std::move(contact_state).value();
      const model::ImageMetadataV1& metadata = image->metadata();
      LoadedModelInfo info = image_model_info(entry, definition, *image, arena.used_bytes() - arena_before);
      info.contact_node_count = metadata.surface_node_count;
      info.stored_node_count = image->rows(model::SectionId::tensor_nodes);
      info.max_contacts = settings->max_contacts;
      info.quasi_nonlinear = definition.tensor.nonlinear;
      app->model_info_.push_back(std::move(info));
      continue;
    }
    const std::string image_name = definition.image_path.string();
    auto image = model::load_model_image(definition.image_path, arena, model::ImageLimits{},
                                         model::ModelKind::modal_shell);
    if (!image) {
      return core::make_error(where + ": model '" + entry.name + "': " + image.error().message +
                              " (build it with: modelc build --scene " + where + ")");
    }
    const model::ImageMetadataV1& metadata = image->metadata();
    const model::ModalModelData data = model::modal_model_data(*image);
    model::ModalSettings settings;
    settings.time_step_s = static_cast<float>(static_cast<double>(scene.loop.period_ns) * 1e-9);
    settings.static_correction = metadata.static_correction != 0;
    auto modal = model::ModalModel::create(data, arena, settings);
    if (!modal) {
      return core::make_error(where + ": model '" + entry.name + "' (" + image_name +
                              "): " + modal.error().message);
    }
    const bool scene_has_catheter =
        std::any_of(scene.models.begin(), scene.models.end(), [](const config::SceneModelConfig& other) {
          return other.definition.kind == config::ModelKind::catheter;
        });
    auto contact_state = make_modal_contact(entry, *image, scene.instruments.size(), scene_has_catheter, arena);
    if (!contact_state) {
      return core::make_error(where + ": model '" + entry.name + "' (" + image_name +
                              "): " + contact_state.error().message);
    }
    app->modal_contacts_[app->modal_model_count_] = std::move(contact_state).value();
    app->modal_models_[app->modal_model_count_++].emplace(std::move(*modal));
    LoadedModelInfo info = image_model_info(entry, definition, *image, arena.used_bytes() - arena_before);
    info.mode_count = metadata.mode_count;
    info.static_correction = metadata.static_correction != 0;
    app->model_info_.push_back(std::move(info));
  }
  // Catheter contacts last: they need every modal model's grid, whatever the scene's order.
  {
    std::size_t catheter = 0;
    for (const config::SceneModelConfig& entry : scene.models) {
      if (entry.definition.kind != config::ModelKind::catheter) continue;
      const std::size_t arena_before = arena.used_bytes();
      auto added = app->add_catheter_contacts(entry, app->catheters_[catheter], arena);
      if (!added) {
        return core::make_error(where + ": model '" + entry.name + "' (" +
                                entry.definition.source_path.string() + "): " + added.error().message);
      }
      for (LoadedModelInfo& info : app->model_info_) {
        if (info.name == entry.name) info.arena_bytes += arena.used_bytes() - arena_before;
      }
      ++catheter;
    }
  }
  // Every entry above pushed exactly one info, so scene order is model_info_ order.
  for (std::size_t m = 0; m < scene.models.size(); ++m) {
    const config::SceneModelConfig& entry = scene.models[m];
    app->model_transforms_[m] = RigidTransform::from_placement(entry.position_m, entry.rotation_deg);
    app->model_info_[m].position_m = entry.position_m;
    app->model_info_[m].rotation_deg = entry.rotation_deg;
  }
  return app;
}

std::optional<RigidTransform> HapticApp::model_transform(const std::string& name) const {
  for (std::size_t m = 0; m < model_info_.size(); ++m) {
    if (model_info_[m].name == name) return model_transforms_[m];
  }
  return std::nullopt;
}

bool HapticApp::read_inputs(const loop::CycleTiming& timing,
                            safety::InputConditions& conditions) noexcept {
  const hal::ReturnCode read = hal_.encoders->read_encoders(encoder_samples_);
  bool encoders_ok = read == hal::ReturnCode::ok;
  if (read == hal::ReturnCode::deactivate) safety_.latch(safety::Fault::device_lost, timing.cycle_index);
  if (!encoders_ok) {
    ++stats_.hal_read_errors;
    if (++read_error_streak_ > kToleratedErrorStreak) {
      safety_.latch(safety::Fault::device_lost, timing.cycle_index);
    }
  } else {
    read_error_streak_ = 0;
  }

  if (hal_.digital_inputs != nullptr) {
    std::uint32_t levels = 0;
    if (hal_.digital_inputs->read_digital_inputs(levels) == hal::ReturnCode::ok) {
      conditions.estop_active = bit_set(levels, digital_.estop_input_bit);
      conditions.enable_held = digital_.enable_input_bit < 0 || bit_set(levels, digital_.enable_input_bit);
    } else {
      // Unreadable safety inputs count as pressed e-stop: fail safe.
      conditions.estop_active = true;
      ++stats_.hal_read_errors;
    }
  }

  if (hal_.actuators->read_actuator_status(actuator_status_) != hal::ReturnCode::ok) {
    conditions.drive_fault = true;
  }
  for (const hal::ActuatorStatus& status : actuator_status_) {
    conditions.drive_fault = conditions.drive_fault || status.fault;
    if (status.saturated) ++stats_.saturated_actuator_cycles;
  }
  return encoders_ok;
}

void HapticApp::sense_instrument(std::size_t index, const loop::CycleTiming& timing) noexcept {
  InstrumentState& state = instruments_[index];
  const auto dt = static_cast<float>(timing.dt_s);
  const auto alpha = static_cast<float>(
      timing.dt_s / (timing.dt_s + 1.0 / (2.0 * std::numbers::pi * kVelocityCutoffHz)));

  bool all_valid = true;
  kinematics::JointVector position{};
  for (std::size_t j = 0; j < kJointCount; ++j) {
    const hal::EncoderSample& sample = encoder_samples_[state.first_channel + j];
    all_valid = all_valid && sample.valid;
    position[j] = sample.position;  // joint-side SI, converted by the backend (HAL contract)
  }
  if (!all_valid) {
    ++stats_.invalid_encoder_cycles;
    position = state.position;  // hold the last good reading; the error streak guards this
  } else if (state.has_position) {
    for (std::size_t j = 0; j < kJointCount; ++j) {
      safety_.check_joint_step(state.kinds[j] == hal::JointKind::prismatic,
                               state.position[j], position[j], dt, timing.cycle_index);
      const float raw_rate = (position[j] - state.position[j]) / dt;
      state.velocity[j] += alpha * (raw_rate - state.velocity[j]);
    }
  } else {
    // The first reading has no previous one to check a step against; its numbers still must
    // be finite (a NaN roll or grip would otherwise pass unseen while no jaw force uses it).
    for (const float value : position) {
      if (!std::isfinite(value)) safety_.latch(safety::Fault::non_finite, timing.cycle_index);
    }
  }
  if (all_valid) {
    state.position = position;
    state.has_position = true;
  }

  if (state.has_position) {
    state.previous_tip_m = state.pose.tip_m;
    state.has_previous_tip = true;
  }
  state.pose = state.kinematics.forward(state.position);
  state.tip_velocity =
      kinematics::TrocarKinematics::point_velocity(state.pose, state.pose.insertion_m, state.velocity);
}

void HapticApp::render_instrument(std::size_t index, const loop::CycleTiming& timing) noexcept {
  InstrumentState& state = instruments_[index];
  const auto dt = static_cast<float>(timing.dt_s);
  const kinematics::InstrumentPose& pose = state.pose;
  const Vec3 tip_velocity = state.tip_velocity;

  Vec3 requested = state.model_force_n;
  bool in_contact = state.model_contact;
  float depth = state.model_contact ? state.model_indentation_m : 0.0F;
  for (const ObjectState& object : objects_) {
    if ((object.touched_by_mask & (1U << static_cast<unsigned>(index))) == 0) continue;
    const model::PointContact contact = object.kind == config::ObjectKind::plane
                                            ? object.plane.contact(pose.tip_m, tip_velocity)
                                            : object.sphere.contact(pose.tip_m, tip_velocity);
    if (contact.in_contact) {
      in_contact = true;
      depth = std::max(depth, contact.depth_m);
      requested += contact.force_n;
    }
  }

  // The tip force (rigid objects, the ducts) plus the ray-based forces on the shaft and jaws
  // (walls, catheters) through the safety chain to joint efforts (force_command.hpp).
  in_contact = in_contact || state.catheter_contact;
  const InstrumentForces forces{
      requested, std::span<const model::ToolForce>(state.tool_forces.data(), state.tool_force_count),
      tip_velocity};
  const ForceCommand command =
      command_instrument(safety_, index, state.kinematics, pose, forces, state.effort_limits, dt,
                         timing.cycle_index);
  const Vec3& force = command.force_n;
  const kinematics::JointVector& efforts = command.efforts;
  if (command.effort_limited) ++stats_.effort_limited_cycles;
  for (std::size_t j = 0; j < kJointCount; ++j) {
    commands_[state.first_channel + j].effort = efforts[j];
  }

  InstrumentStats& stats = stats_.instruments[index];
  if (state.wall_segment_contact) ++stats.wall_segment_contact_cycles;
  const float force_norm = force.norm();
  if (in_contact) {
    ++stats.contact_cycles;
    if (!state.was_in_contact) ++stats.contact_onsets;
    stats.force_sum_n += static_cast<double>(force_norm);
  }
  state.was_in_contact = in_contact;
  stats.peak_force_n = std::max(stats.peak_force_n, force_norm);
  stats.peak_depth_m = std::max(stats.peak_depth_m, depth);
  for (std::size_t j = 0; j < kJointCount; ++j) {
    stats.peak_joint_effort[j] = std::max(stats.peak_joint_effort[j], std::fabs(efforts[j]));
  }

  InstrumentTelemetry& out = instrument_out_[index];
  out.joints = state.position;
  out.tip_m = {pose.tip_m.x(), pose.tip_m.y(), pose.tip_m.z()};
  out.force_n = {force.x(), force.y(), force.z()};
  out.joint_efforts = efforts;
  out.in_contact = in_contact;
}

void HapticApp::zero_commands() noexcept {
  for (hal::ActuatorCommand& command : commands_) command = hal::ActuatorCommand{};
}

void HapticApp::write_outputs(bool armed) noexcept {
  // A faulted or unarmed controller still writes every cycle: zero effort, drives disabled,
  // so the drives' own watchdogs see a live host holding them safe.
  if (!armed) zero_commands();
  for (hal::ActuatorCommand& command : commands_) command.enable = armed;
  const hal::ReturnCode written = hal_.actuators->write_actuators(commands_);
  if (written == hal::ReturnCode::deactivate) {
    safety_.latch(safety::Fault::drive_fault, stats_.cycles);
  } else if (written != hal::ReturnCode::ok) {
    ++stats_.hal_write_errors;
    if (++write_error_streak_ > kToleratedErrorStreak) {
      safety_.latch(safety::Fault::device_lost, stats_.cycles);
    }
  } else {
    write_error_streak_ = 0;
  }
  if (hal_.digital_outputs != nullptr) {
    std::uint32_t levels = 0;
    if (armed && digital_.drive_enable_output_bit >= 0) {
      levels |= 1U << static_cast<unsigned>(digital_.drive_enable_output_bit);
    }
    if (!armed && digital_.fault_lamp_output_bit >= 0) {
      levels |= 1U << static_cast<unsigned>(digital_.fault_lamp_output_bit);
    }
    (void)hal_.digital_outputs->write_digital_outputs(levels);
  }
}

void HapticApp::publish(const loop::CycleTiming& timing) noexcept {
  TelemetrySnapshot& snapshot = telemetry_.write_slot();
  snapshot.cycle = timing.cycle_index;
  snapshot.time_ns = timing.wake_ns;
  snapshot.latched_faults = safety_.latched_faults();
  snapshot.instrument_count = static_cast<std::uint32_t>(instrument_out_.size());
  for (std::size_t i = 0; i < instrument_out_.size(); ++i) snapshot.instruments[i] = instrument_out_[i];
  telemetry_.publish();
}

core::Status HapticApp::run_cycle(const loop::CycleTiming& timing) noexcept {
  ++stats_.cycles;
  std::int64_t phase_start_ns = clock_.now_ns();
  const auto end_phase = [&](CyclePhase phase) {
    const std::int64_t now_ns = clock_.now_ns();
    stats_.phase_ns[static_cast<std::size_t>(phase)].record(now_ns - phase_start_ns);
    phase_start_ns = now_ns;
  };
  const bool reset_requested = reset_requested_.exchange(false, std::memory_order_acq_rel);

  safety::InputConditions conditions;
  const bool encoders_ok = read_inputs(timing, conditions);
  // A reset clears only faults that have been reported: one raised since the last cycle
  // published its state (the overrun streak between cycles, a lost device found by this
  // cycle's reads) keeps the controller faulted, and the request is dropped as it is when an
  // input is active. Otherwise the reset would clear it before any telemetry or log saw it, and
  // arm on a device that failed this very cycle.
  if (reset_requested && raised_fault_count() == raised_at_publish_) safety_.request_reset();
  const bool was_armed = safety_.armed();
  safety_.evaluate_inputs(conditions, timing.cycle_index);
  if (!was_armed && safety_.armed()) {
    log_.write(timing.wake_ns, core::LogLevel::info, "armed at cycle {}", timing.cycle_index);
    for (InstrumentState& state : instruments_) state.velocity.fill(0.0F);
    // A fault latched from here on is new, even of a kind logged before the reset.
    last_logged_faults_ = 0;
  }
  end_phase(CyclePhase::hal_read);

  for (std::size_t i = 0; i < instruments_.size(); ++i) sense_instrument(i, timing);
  end_phase(CyclePhase::kinematics);
  contact_modal_models();  // tool forces from the ducts, their step, next cycle's surfaces
  end_phase(CyclePhase::modal_models);
  contact_tensor_models();  // tool forces from the tensor models, their surfaces
  end_phase(CyclePhase::tensor_models);
  step_catheters();        // walls, shafts and jaws on the catheters, grasps, their step
  end_phase(CyclePhase::catheters);
  for (std::size_t i = 0; i < instruments_.size(); ++i) render_instrument(i, timing);
  end_phase(CyclePhase::forces);

  const bool armed = safety_.armed();
  if (armed) ++stats_.armed_cycles;
  write_outputs(armed);
  if (!armed) {
    // Nothing was commanded: an instrument rendered before another one's fault reports so.
    for (InstrumentTelemetry& out : instrument_out_) {
      out.force_n = {};
      out.joint_efforts = {};
    }
  }

  const std::uint32_t faults = safety_.latched_faults();
  const std::uint32_t new_faults = faults & ~last_logged_faults_;
  if (new_faults != 0) {
    for (std::uint32_t bit = 1; bit != 0; bit <<= 1U) {
      if ((new_faults & bit) != 0 && bit != safety::bit(safety::Fault::not_armed)) {
        log_.write(timing.wake_ns, core::LogLevel::error, "fault latched: {} at cycle {}",
                   safety::to_string(static_cast<safety::Fault>(bit)), timing.cycle_index);
      }
    }
  }
  last_logged_faults_ = faults;
  raised_at_publish_ = raised_fault_count();

  publish(timing);
  end_phase(CyclePhase::hal_write);
  return encoders_ok ? core::Status::ok()
                     : core::Status{core::StatusCode::io_error, "encoder read failed"};
}

core::Expected<model::BucketGrid> HapticApp::make_surface_grid(
    std::span<const float> rest_positions, std::span<const std::uint32_t> triangles,
    model::Aabb& near_box, std::span<float>& grid_positions, core::Arena& arena) {
  auto positions = arena.allocate_array<float>(rest_positions.size(), "bucket grid positions");
  if (!positions) return std::move(positions).error();
  grid_positions = positions.value();
  const auto vertex = [&](std::uint32_t node) {
    const std::size_t base = 3 * static_cast<std::size_t>(node);
    return Vec3(rest_positions[base], rest_positions[base + 1], rest_positions[base + 2]);
  };
  const std::size_t vertex_count = rest_positions.size() / 3;
  const std::size_t triangle_count = triangles.size() / 3;
  near_box.min_m = Vec3::Constant(std::numeric_limits<float>::max());
  near_box.max_m = Vec3::Constant(-std::numeric_limits<float>::max());
  for (std::size_t node = 0; node < vertex_count; ++node) {
    near_box.min_m = near_box.min_m.cwiseMin(vertex(static_cast<std::uint32_t>(node)));
    near_box.max_m = near_box.max_m.cwiseMax(vertex(static_cast<std::uint32_t>(node)));
  }
  near_box.min_m.array() -= kSurfaceMarginM;
  near_box.max_m.array() += kSurfaceMarginM;
  float longest_edge = 0.0F;
  for (std::size_t t = 0; t < triangle_count; ++t) {
    for (std::size_t e = 0; e < 3; ++e) {
      const Vec3 a = vertex(triangles[3 * t + e]);
      const Vec3 b = vertex(triangles[3 * t + (e + 1) % 3]);
      longest_edge = std::max(longest_edge, (a - b).norm());
    }
  }
  model::BucketGridSettings grid_settings;
  grid_settings.max_triangles = static_cast<std::uint32_t>(triangle_count);
  grid_settings.max_vertices = static_cast<std::uint32_t>(vertex_count);
  grid_settings.cell_size_m = 1.5F * longest_edge;
  grid_settings.max_entries = static_cast<std::uint32_t>(27 * triangle_count);
  grid_settings.table_size = std::bit_ceil(2U * grid_settings.max_entries / 8U + 1U);
  return model::BucketGrid::create(grid_settings, arena);
}

core::Expected<HapticApp::ModalContactState> HapticApp::make_modal_contact(
    const config::SceneModelConfig& entry, const model::ModelImage& image,
    std::size_t instrument_count, bool with_grid, core::Arena& arena) {
  ModalContactState state;
  state.transform = RigidTransform::from_placement(entry.position_m, entry.rotation_deg);
  for (const std::size_t instrument : entry.touched_by) {
    state.touched_by_mask |= 1U << static_cast<unsigned>(instrument);
  }
  state.rest_positions = image.floats(model::SectionId::rest_positions);
  state.triangles = image.u32s(model::SectionId::triangles);
  auto deformed = arena.allocate_array<float>(state.rest_positions.size(), "deformed surface");
  if (!deformed) return std::move(deformed).error();
  state.deformed = deformed.value();
  std::copy(state.rest_positions.begin(), state.rest_positions.end(), state.deformed.begin());
  state.vertex_count = state.rest_positions.size() / 3;
  state.half_thickness_m = static_cast<float>(0.5 * image.metadata().thickness_m);
  state.fixed_nodes = image.u32s(model::SectionId::fixed_nodes);
  if (state.touched_by_mask == 0 && !with_grid) return state;  // nothing touches it: no grid
  auto grid = make_surface_grid(state.rest_positions, state.triangles, state.near_box,
                                state.grid_positions, arena);
  if (!grid) return std::move(grid).error();
  state.grid.emplace(std::move(grid).value());
  const model::DisplacementContactSettings contact_settings = tip_contact_settings(state.triangles);
  for (std::size_t i = 0; i < instrument_count; ++i) {
    if ((state.touched_by_mask & (1U << static_cast<unsigned>(i))) == 0) continue;
    auto contact = model::DisplacementContact::create(
        contact_settings, image.u32s(model::SectionId::fixed_nodes), arena);
    if (!contact) return std::move(contact).error();
    state.contacts[i].emplace(std::move(contact).value());
    // The shaft and jaws: only the contact geometry is used (the wall's response comes from
    // the model's imposed solve), so the penalty settings are nominal.
    model::SegmentContactSettings segment_settings;
    segment_settings.surface_half_thickness_m = state.half_thickness_m;
    segment_settings.stiffness_n_per_m = 1.0F;
    segment_settings.max_force_n = 1.0F;
    segment_settings.max_candidates = contact_settings.max_candidates;
    auto segments = model::SegmentSurfaceContact::create(segment_settings, arena);
    if (!segments) return std::move(segments).error();
    state.segments[i].emplace(std::move(segments).value());
  }
  return state;
}

bool HapticApp::fit_grid(model::BucketGrid& grid, bool& grid_built, std::span<float> grid_positions,
                         std::span<const float> deformed, std::span<const std::uint32_t> triangles) noexcept {
  const float slack = kGridSlackCells * grid.cell_size_m();
  float largest_squared = 0.0F;
  for (std::size_t base = 0; base + 2 < deformed.size(); base += 3) {
    const float dx = deformed[base] - grid_positions[base];
    const float dy = deformed[base + 1] - grid_positions[base + 1];
    const float dz = deformed[base + 2] - grid_positions[base + 2];
    largest_squared = std::max(largest_squared, dx * dx + dy * dy + dz * dz);
  }
  // NaN compares false: a non-finite surface goes to rebuild(), which refuses it.
  if (grid_built && largest_squared <= slack * slack) return true;
  grid_built = grid.rebuild(deformed, triangles, slack).is_ok();
  if (grid_built) std::copy(deformed.begin(), deformed.end(), grid_positions.begin());
  return grid_built;
}

void HapticApp::refresh_surface(ModalContactState& state,
                                const model::ModalModel& modal) noexcept {
  state.surface_ready = false;
  if (!state.grid) return;
  if (!modal.reconstruct(state.deformed).is_ok()) return;
  for (std::size_t i = 0; i < state.deformed.size(); ++i) state.deformed[i] += state.rest_positions[i];
  state.surface_ready =
      fit_grid(*state.grid, state.grid_built, state.grid_positions, state.deformed, state.triangles);
}

core::Expected<HapticApp::TensorContactState> HapticApp::make_tensor_contact(
    const config::SceneModelConfig& entry, const model::ModelImage& image,
    const model::TensorModel& tensor, std::size_t instrument_count, core::Arena& arena) {
  TensorContactState state;
  state.transform = RigidTransform::from_placement(entry.position_m, entry.rotation_deg);
  for (const std::size_t instrument : entry.touched_by) {
    state.touched_by_mask |= 1U << static_cast<unsigned>(instrument);
  }
  state.rest_positions = image.floats(model::SectionId::rest_positions);
  state.triangles = image.u32s(model::SectionId::triangles);
  state.response_nodes = tensor.response_nodes();
  auto deformed = arena.allocate_array<float>(state.rest_positions.size(), "deformed tensor surface");
  if (!deformed) return std::move(deformed).error();
  state.deformed = deformed.value();
  std::copy(state.rest_positions.begin(), state.rest_positions.end(), state.deformed.begin());
  if (state.touched_by_mask == 0) return state;  // nothing touches it: no grid, no contacts

  // A tool's contact imposes the touched triangle's free nodes (up to 3): the solver's capacity
  // must hold every touching tool's at once, or a second tool would be refused mid-run.
  const auto touching = static_cast<std::uint32_t>(std::popcount(state.touched_by_mask));
  const std::uint32_t needed = static_cast<std::uint32_t>(model::DisplacementContact::kMaxTargets) * touching;
  if (tensor.max_contacts() < needed) {
    return core::make_error("[tensor] max_contacts = " + std::to_string(tensor.max_contacts()) +
                            " is below " + std::to_string(needed) + ": each of the " +
                            std::to_string(touching) + " instrument(s) touching the model imposes "
                            "up to 3 nodes (the touched triangle's)");
  }
  // Nodes a tool may not displace: every node that is not a contact node of the image (fixed,
  // partly fixed, interior). The contact leaves them out of its targets, as fixed nodes on the duct.
  const std::span<const std::uint32_t> contact_nodes = tensor.contact_nodes();
  const std::size_t node_count = state.rest_positions.size() / 3;
  auto held = arena.allocate_array<std::uint32_t>(node_count - contact_nodes.size(),
                                                  "tensor model's non-contact nodes");
  if (!held) return std::move(held).error();
  std::size_t next_contact = 0;
  std::size_t next_held = 0;
  for (std::uint32_t node = 0; node < node_count; ++node) {
    if (next_contact < contact_nodes.size() && contact_nodes[next_contact] == node) {
      ++next_contact;
    } else {
      held.value()[next_held++] = node;
    }
  }
  auto grid = make_surface_grid(state.rest_positions, state.triangles, state.near_box,
                                state.grid_positions, arena);
  if (!grid) return std::move(grid).error();
  state.grid.emplace(std::move(grid).value());
  const model::DisplacementContactSettings contact_settings = tip_contact_settings(state.triangles);
  for (std::size_t i = 0; i < instrument_count; ++i) {
    if ((state.touched_by_mask & (1U << static_cast<unsigned>(i))) == 0) continue;
    auto contact = model::DisplacementContact::create(contact_settings, held.value(), arena);
    if (!contact) return std::move(contact).error();
    state.contacts[i].emplace(std::move(contact).value());
  }
  return state;
}

void HapticApp::refresh_tensor_surface(TensorContactState& state, model::TensorModel& tensor) noexcept {
  state.surface_ready = false;
  if (!state.grid) return;
  if (tensor.contact_count() == 0) {
    if (!state.deformed_is_rest) {
      std::copy(state.rest_positions.begin(), state.rest_positions.end(), state.deformed.begin());
    }
    state.deformed_is_rest = true;
  } else {
    tensor.update_field();
    const std::span<const float> field = tensor.displacements();
    for (std::size_t j = 0; j < state.response_nodes.size(); ++j) {
      const std::size_t base = 3 * static_cast<std::size_t>(state.response_nodes[j]);
      for (std::size_t axis = 0; axis < 3; ++axis) {
        state.deformed[base + axis] = state.rest_positions[base + axis] + field[3 * j + axis];
      }
    }
    state.deformed_is_rest = false;
  }
  state.surface_ready =
      fit_grid(*state.grid, state.grid_built, state.grid_positions, state.deformed, state.triangles);
}

void HapticApp::contact_tensor_models() noexcept {
  for (std::size_t t = 0; t < tensor_model_count_; ++t) {
    model::TensorModel& tensor = *tensor_models_[t];
    TensorContactState& state = tensor_contacts_[t];
    TensorModelStats& model_stats = stats_.tensor_models[t];
    if (!state.grid) continue;  // no instrument touches it
    bool near = false;
    for (std::size_t i = 0; i < instruments_.size(); ++i) {
      if (!state.contacts[i]) continue;
      const Vec3 tip = state.transform.to_model(instruments_[i].pose.tip_m);
      const bool inside = (tip.array() >= state.near_box.min_m.array()).all() &&
                          (tip.array() <= state.near_box.max_m.array()).all();
      near = near || inside || state.contacts[i]->in_contact();
    }
    if (!near) {
      // Far from every tool: at rest, nothing to solve; the surface is rebuilt once on release.
      if (tensor.contact_count() > 0) (void)tensor.solve({});
      if (!state.deformed_is_rest || !state.surface_ready) refresh_tensor_surface(state, tensor);
      state.was_in_contact.fill(false);
      continue;
    }
    if (!state.surface_ready) refresh_tensor_surface(state, tensor);
    if (!state.surface_ready) {
      ++stats_.model_step_errors;
      continue;
    }
    const model::TriangleMeshView view{state.deformed, state.triangles};
    std::array<model::TensorContact, model::TensorModel::kMaxContactsLimit> targets{};
    std::array<std::size_t, model::TensorModel::kMaxContactsLimit> owner{};
    std::size_t target_count = 0;
    float indentation = 0.0F;
    for (std::size_t i = 0; i < instruments_.size(); ++i) {
      if (!state.contacts[i]) continue;
      InstrumentState& instrument = instruments_[i];
      model::DisplacementContact& contact = *state.contacts[i];
      const Vec3 tip = state.transform.to_model(instrument.pose.tip_m);
      const Vec3 previous =
          instrument.has_previous_tip ? state.transform.to_model(instrument.previous_tip_m) : tip;
      if (!contact.update(view, *state.grid, previous, tip).is_ok()) ++stats_.model_step_errors;
      std::array<model::ImposedDisplacement, model::DisplacementContact::kMaxTargets> mine{};
      const std::size_t count = contact.targets(view, state.rest_positions, tip, mine);
      // Two tools on one triangle's nodes cannot both impose them: the later one lets go, as
      // does one beyond the solver's capacity (setup sizes it for every touching tool).
      bool shared = false;
      for (std::size_t k = 0; k < count; ++k) {
        for (std::size_t q = 0; q < target_count; ++q) shared = shared || targets[q].node == mine[k].node;
      }
      if (shared || target_count + count > tensor.max_contacts()) {
        contact.release();
        continue;
      }
      for (std::size_t k = 0; k < count; ++k) {
        targets[target_count] = model::TensorContact{mine[k].node, mine[k].displacement_m};
        owner[target_count++] = i;
        indentation = std::max(indentation, mine[k].displacement_m.norm());
        instrument.model_indentation_m = std::max(instrument.model_indentation_m, mine[k].displacement_m.norm());
      }
    }
    // Solve; a contact that would pull the tissue is released and the rest re-solved.
    for (int attempt = 0; attempt < 2 && target_count > 0; ++attempt) {
      if (!tensor.solve(std::span(targets.data(), target_count)).is_ok()) {
        ++model_stats.refused_solves;
        ++stats_.model_step_errors;
        for (auto& contact : state.contacts) {
          if (contact) contact->release();
        }
        target_count = 0;
        break;
      }
      std::array<Vec3, kMaxInstruments> on_tissue{};
      for (Vec3& force : on_tissue) force.setZero();
      for (std::size_t k = 0; k < target_count; ++k) on_tissue[owner[k]] += tensor.contact_force(k);
      bool released = false;
      for (std::size_t i = 0; i < instruments_.size(); ++i) {
        if (!state.contacts[i] || !state.contacts[i]->in_contact()) continue;
        state.contacts[i]->observe_force(view, on_tissue[i]);
        released = released || !state.contacts[i]->in_contact();
      }
      if (released && attempt == 0) {
        std::size_t kept = 0;
        for (std::size_t k = 0; k < target_count; ++k) {
          if (state.contacts[owner[k]]->in_contact()) {
            targets[kept] = targets[k];
            owner[kept++] = owner[k];
          }
        }
        target_count = kept;
        continue;
      }
      Vec3 total = Vec3::Zero();
      for (std::size_t i = 0; i < instruments_.size(); ++i) {
        if (!state.contacts[i] || !state.contacts[i]->in_contact()) continue;
        instruments_[i].model_force_n -= state.transform.vector_to_world(on_tissue[i]);
        instruments_[i].model_contact = true;
        total += on_tissue[i];
      }
      const float magnitude = total.norm();
      ++model_stats.loaded_cycles;
      model_stats.force_sum_n += static_cast<double>(magnitude);
      model_stats.peak_force_n = std::max(model_stats.peak_force_n, magnitude);
      model_stats.peak_contact_nodes =
          std::max(model_stats.peak_contact_nodes, static_cast<std::uint32_t>(target_count));
      model_stats.peak_indentation_m = std::max(model_stats.peak_indentation_m, indentation);
      break;
    }
    if (target_count == 0 && tensor.contact_count() > 0) (void)tensor.solve({});
    for (std::size_t i = 0; i < instruments_.size(); ++i) {
      const bool holding = state.contacts[i] && state.contacts[i]->in_contact();
      if (holding && !state.was_in_contact[i]) ++model_stats.contact_onsets;
      state.was_in_contact[i] = holding;
    }
    if (tensor.contact_count() > 0 || !state.deformed_is_rest) refresh_tensor_surface(state, tensor);
  }
}

std::size_t HapticApp::gather_segment_targets(
    ModalContactState& state, const model::TriangleMeshView& view,
    std::array<model::ImposedDisplacement, model::ModalModel::kMaxContacts>& targets,
    std::array<std::size_t, model::ModalModel::kMaxContacts>& owner,
    std::array<std::int32_t, model::ModalModel::kMaxContacts>& segment_of, std::size_t& target_count,
    std::span<SegmentTarget> segment_targets) noexcept {
  for (std::size_t k = 0; k < target_count; ++k) segment_of[k] = -1;
  std::size_t segment_count = 0;
  for (std::size_t i = 0; i < instruments_.size(); ++i) {
    if (!state.segments[i]) continue;
    const kinematics::InstrumentPose& pose = instruments_[i].pose;
    const Vec3 velocity = state.transform.vector_to_model(instruments_[i].tip_velocity);
    const Vec3 hinge = state.transform.to_model(pose.hinge_m);
    const Vec3 shaft_start = state.transform.to_model(pose.shaft_start_m);
    std::array<model::ToolCapsule, 3> capsules{
        model::ToolCapsule{model::ToolSegment::jaw0, hinge, state.transform.to_model(pose.jaw_tips_m[0]),
                           kJawRadiusM, velocity, velocity},
        model::ToolCapsule{model::ToolSegment::jaw1, hinge, state.transform.to_model(pose.jaw_tips_m[1]),
                           kJawRadiusM, velocity, velocity},
        model::ToolCapsule{}};
    std::size_t capsule_count = 2;
    // The shaft is tens of centimetres long: only its part inside the surface's box (grown by
    // kSegmentClipMarginM) can touch it, and a query box along the whole shaft would cover
    // most of the grid. along_m is measured from the clipped start: add its offset back.
    float shaft_offset_m = 0.0F;
    {
      const model::Aabb clip{state.near_box.min_m.array() + (kSurfaceMarginM - kSegmentClipMarginM),
                             state.near_box.max_m.array() - (kSurfaceMarginM - kSegmentClipMarginM)};
      const Vec3 axis = hinge - shaft_start;
      float enter = 0.0F;
      float leave = 1.0F;
      for (Eigen::Index k = 0; k < 3; ++k) {
        if (std::fabs(axis[k]) < 1e-12F) {
          if (shaft_start[k] < clip.min_m[k] || shaft_start[k] > clip.max_m[k]) leave = -1.0F;
          continue;
        }
        const float a = (clip.min_m[k] - shaft_start[k]) / axis[k];
        const float b = (clip.max_m[k] - shaft_start[k]) / axis[k];
        enter = std::max(enter, std::min(a, b));
        leave = std::min(leave, std::max(a, b));
      }
      if (enter <= leave) {
        shaft_offset_m = enter * axis.norm();
        capsules[capsule_count++] =
            model::ToolCapsule{model::ToolSegment::shaft, shaft_start + enter * axis, shaft_start + leave * axis,
                               kShaftRadiusM, enter * velocity, leave * velocity};
      }
    }
    model::SegmentSurfaceContact& contact = *state.segments[i];
    if (!contact.update(std::span(capsules.data(), capsule_count), view, {}, *state.grid).is_ok()) {
      ++stats_.model_step_errors;
    }
    for (const model::SegmentContact& found : contact.contacts()) {
      // The wall point goes to where the capsule leaves it just inside its reach; the
      // triangle's free nodes share the displacement that puts it there (as for a tip).
      const Vec3 goal = found.mesh_point_m - (found.depth_m - kSegmentSkinM) * found.normal;
      Vec3 rest = Vec3::Zero();
      for (std::size_t corner = 0; corner < 3; ++corner) {
        const std::size_t base = 3 * static_cast<std::size_t>(found.vertices[corner]);
        rest += found.barycentric[static_cast<Eigen::Index>(corner)] *
                Vec3(state.rest_positions[base], state.rest_positions[base + 1], state.rest_positions[base + 2]);
      }
      const Vec3 imposed = goal - rest;
      if (!imposed.allFinite()) continue;
      // Nodes a tip (or an earlier segment) already imposes keep that target; a contact with
      // no node left, or beyond the model's capacity, is left out this cycle.
      std::array<std::uint32_t, 3> free{};
      std::size_t free_count = 0;
      bool shared = false;
      for (const std::uint32_t node : found.vertices) {
        if (std::binary_search(state.fixed_nodes.begin(), state.fixed_nodes.end(), node)) continue;
        for (std::size_t k = 0; k < target_count; ++k) shared = shared || targets[k].node == node;
        free[free_count++] = node;
      }
      if (shared || free_count == 0 || target_count + free_count > targets.size() ||
          segment_count >= segment_targets.size()) {
        continue;
      }
      const float along_m = found.along_m + (found.segment == model::ToolSegment::shaft ? shaft_offset_m : 0.0F);
      segment_targets[segment_count] = SegmentTarget{i, found.segment, along_m, found.depth_m,
                                                     found.normal, Vec3::Zero(), true};
      for (std::size_t k = 0; k < free_count; ++k) {
        targets[target_count] = model::ImposedDisplacement{free[k], imposed};
        owner[target_count] = i;
        segment_of[target_count++] = static_cast<std::int32_t>(segment_count);
      }
      ++segment_count;
    }
  }
  return segment_count;
}

void HapticApp::contact_modal_models() noexcept {
  for (InstrumentState& instrument : instruments_) {
    instrument.model_force_n.setZero();
    instrument.model_contact = false;
    instrument.model_indentation_m = 0.0F;
    instrument.tool_force_count = 0;  // shaft/jaw forces: the ducts' here, the catheters' next
    instrument.wall_segment_contact = false;
  }
  for (std::size_t m = 0; m < modal_model_count_; ++m) {
    model::ModalModel& modal = *modal_models_[m];
    ModalContactState& state = modal_contacts_[m];
    ModalModelStats& model_stats = stats_.modal_models[m];
    modal.clear_forces();
    // The catheters' wall reactions from their last step (model frame).
    Vec3 catheter_total = Vec3::Zero();
    for (std::size_t k = 0; k < state.catheter_load_count; ++k) {
      if (!modal.add_node_force(state.catheter_loads[k].node, state.catheter_loads[k].force_n).is_ok()) {
        ++stats_.model_step_errors;
      } else {
        catheter_total += state.catheter_loads[k].force_n;
      }
    }
    state.catheter_load_count = 0;
    std::array<model::ImposedDisplacement, model::ModalModel::kMaxContacts> targets{};
    std::array<std::size_t, model::ModalModel::kMaxContacts> owner{};
    // −1 for a tip target, else the index of its shaft/jaw contact in segment_targets.
    std::array<std::int32_t, model::ModalModel::kMaxContacts> segment_of{};
    std::array<SegmentTarget, kMaxInstruments * model::SegmentSurfaceContact::kMaxSegments> segment_targets{};
    std::size_t segment_count = 0;
    std::size_t target_count = 0;
    Vec3 tool_total = Vec3::Zero();
    bool tool_touching = false;
    // Is any touching tool or catheter particle near, or any contact holding? Only then is the
    // surface needed.
    bool near = false;
    for (std::size_t i = 0; i < instruments_.size(); ++i) {
      if (!state.contacts[i]) continue;
      const auto inside = [&](const Vec3& world) {
        const Vec3 local = state.transform.to_model(world);
        return (local.array() >= state.near_box.min_m.array()).all() &&
               (local.array() <= state.near_box.max_m.array()).all();
      };
      near = near || inside(instruments_[i].pose.tip_m) || inside(instruments_[i].pose.hinge_m) ||
             state.contacts[i]->in_contact() ||
             (state.segments[i] && state.segments[i]->contact_count() > 0);
    }
    if (state.grid) {
      for (std::size_t c = 0; c < catheter_count_ && !near; ++c) {
        for (const Vec3& particle : catheters_[c].catheter->positions_m()) {
          const Vec3 local = state.transform.to_model(particle);
          if ((local.array() >= state.near_box.min_m.array()).all() &&
              (local.array() <= state.near_box.max_m.array()).all()) {
            near = true;
            break;
          }
        }
      }
    }
    if (near && !state.surface_ready) refresh_surface(state, modal);
    if (near && state.surface_ready) {
      const model::TriangleMeshView view{state.deformed, state.triangles};
      // Gather every touching tool's imposed displacements; a contact that would need more
      // than the model's capacity is released (its tool feels nothing rather than a wrong force).
      for (std::size_t i = 0; i < instruments_.size(); ++i) {
        if (!state.contacts[i]) continue;
        InstrumentState& instrument = instruments_[i];
        model::DisplacementContact& contact = *state.contacts[i];
        const Vec3 tip = state.transform.to_model(instrument.pose.tip_m);
        const Vec3 previous =
            instrument.has_previous_tip ? state.transform.to_model(instrument.previous_tip_m) : tip;
        if (!contact.update(view, *state.grid, previous, tip).is_ok()) ++stats_.model_step_errors;
        std::array<model::ImposedDisplacement, model::DisplacementContact::kMaxTargets> mine{};
        const std::size_t count = contact.targets(view, state.rest_positions, tip, mine);
        if (target_count + count > targets.size()) {
          contact.release();
          continue;
        }
        for (std::size_t k = 0; k < count; ++k) {
          targets[target_count] = mine[k];
          owner[target_count++] = i;
          instrument.model_indentation_m =
              std::max(instrument.model_indentation_m, mine[k].displacement_m.norm());
        }
      }
      segment_count = gather_segment_targets(state, view, targets, owner, segment_of, target_count, segment_targets);
      // Solve; a contact that would pull the tissue is released and the rest re-solved.
      for (int attempt = 0; attempt < 2 && target_count > 0; ++attempt) {
        std::array<Vec3, model::ModalModel::kMaxContacts> forces{};
        if (!modal.solve_imposed(std::span(targets.data(), target_count),
                                 std::span(forces.data(), target_count)).is_ok()) {
          ++stats_.model_step_errors;
          modal.clear_forces();
          for (auto& contact : state.contacts) {
            if (contact) contact->release();
          }
          target_count = 0;
          break;
        }
        std::array<Vec3, kMaxInstruments> on_tissue{};
        for (Vec3& force : on_tissue) force.setZero();
        for (std::size_t s = 0; s < segment_count; ++s) segment_targets[s].on_tissue_n.setZero();
        for (std::size_t k = 0; k < target_count; ++k) {
          if (segment_of[k] < 0) {
            on_tissue[owner[k]] += forces[k];
          } else {
            segment_targets[static_cast<std::size_t>(segment_of[k])].on_tissue_n += forces[k];
          }
        }
        bool released = false;
        for (std::size_t i = 0; i < instruments_.size(); ++i) {
          if (!state.contacts[i] || !state.contacts[i]->in_contact()) continue;
          state.contacts[i]->observe_force(view, on_tissue[i]);
          released = released || !state.contacts[i]->in_contact();
        }
        // A shaft or jaw holding the wall where it would have to pull it (the tool moving away
        // faster than the wall follows) lets go, as a tip contact does.
        for (std::size_t s = 0; s < segment_count; ++s) {
          SegmentTarget& target = segment_targets[s];
          if (target.active && target.on_tissue_n.dot(target.normal) > 0.0F) {
            target.active = false;
            released = true;
          }
        }
        if (released && attempt == 0) {
          modal.clear_forces();
          std::size_t kept = 0;
          for (std::size_t k = 0; k < target_count; ++k) {
            const bool keep = segment_of[k] < 0 ? state.contacts[owner[k]]->in_contact()
                                                : segment_targets[static_cast<std::size_t>(segment_of[k])].active;
            if (keep) {
              targets[kept] = targets[k];
              owner[kept] = owner[k];
              segment_of[kept++] = segment_of[k];
            }
          }
          target_count = kept;
          continue;
        }
        for (std::size_t i = 0; i < instruments_.size(); ++i) {
          if (!state.contacts[i] || !state.contacts[i]->in_contact()) continue;
          instruments_[i].model_force_n -= state.transform.vector_to_world(on_tissue[i]);
          instruments_[i].model_contact = true;
          tool_total += on_tissue[i];
          tool_touching = true;
        }
        // Shaft and jaws: the opposite of what imposing their wall points took, at the contact
        // point on the segment (ray-based: the Jacobian there gives the torques).
        for (std::size_t s = 0; s < segment_count; ++s) {
          const SegmentTarget& target = segment_targets[s];
          if (!target.active) continue;
          InstrumentState& instrument = instruments_[target.instrument];
          if (instrument.tool_force_count >= instrument.tool_forces.size()) {
            ++stats_.model_step_errors;
            continue;
          }
          instrument.tool_forces[instrument.tool_force_count++] =
              model::ToolForce{target.segment, target.along_m, -state.transform.vector_to_world(target.on_tissue_n)};
          instrument.model_contact = true;
          instrument.wall_segment_contact = true;
          instrument.model_indentation_m = std::max(instrument.model_indentation_m, target.depth_m);
          tool_total += target.on_tissue_n;
          tool_touching = true;
        }
        break;
      }
    }
    const Vec3 total = tool_total + catheter_total;
    if (tool_touching) ++model_stats.tool_contact_cycles;
    if (!total.isZero(0.0F) || tool_touching) {
      const float magnitude = total.norm();
      ++model_stats.loaded_cycles;
      model_stats.force_sum_n += static_cast<double>(magnitude);
      model_stats.peak_force_n = std::max(model_stats.peak_force_n, magnitude);
    }
    if (!modal.step().is_ok()) ++stats_.model_step_errors;
    if (near) {
      refresh_surface(state, modal);
    } else {
      state.surface_ready = false;  // stale: rebuilt when a tool comes near
    }
  }
}

core::Expected<void> HapticApp::add_catheter_contacts(const config::SceneModelConfig& entry,
                                                      CatheterState& state, core::Arena& arena) {
  model::Catheter& catheter = *state.catheter;
  const config::CatheterConfig& cfg = entry.definition.catheter;
  const std::uint32_t count = catheter.particle_count();
  const float limit = catheter.max_contact_stiffness_n_per_m();
  const auto check_stiffness = [&](double value, const char* key) -> core::Expected<void> {
    if (static_cast<float>(value) > limit) {
      return core::make_error("[contact] " + std::string(key) + " = " + std::to_string(value) +
                              " N/m: expected at most " + std::to_string(limit) +
                              " N/m, the stiffest contact this catheter's substep keeps stable "
                              "(particle mass / substep^2)");
    }
    return {};
  };
  if (auto ok = check_stiffness(cfg.wall_stiffness_n_per_m, "wall_stiffness_n_per_m"); !ok) return ok;
  if (auto ok = check_stiffness(cfg.tool_stiffness_n_per_m, "tool_stiffness_n_per_m"); !ok) return ok;
  state.wall_stiffness_n_per_m = static_cast<float>(cfg.wall_stiffness_n_per_m);
  state.wall_damping_n_s_per_m = static_cast<float>(cfg.wall_damping_n_s_per_m);
  state.max_contact_force_n = static_cast<float>(cfg.max_contact_force_n);

  for (std::size_t m = 0; m < modal_model_count_; ++m) {
    const ModalContactState& wall = modal_contacts_[m];
    if (!wall.grid) continue;
    model::ParticleContactSettings settings;
    settings.max_particles = count;
    settings.max_contacts = kWallContactsPerParticle * count;
    settings.max_nodes = static_cast<std::uint32_t>(wall.vertex_count);
    settings.max_candidates = static_cast<std::uint32_t>(wall.triangles.size() / 3);  // never full
    settings.stiffness_n_per_m = state.wall_stiffness_n_per_m;
    settings.damping_n_s_per_m = state.wall_damping_n_s_per_m;
    settings.surface_offset_m = 0.0F;  // the planes carry the wall's half-thickness in their reach
    settings.max_force_n = state.max_contact_force_n;
    settings.side = model::ContactSide::inner;
    auto contact = model::ParticleSurfaceContact::create(settings, arena);
    if (!contact) return std::move(contact).error();
    state.walls[m].emplace(std::move(contact).value());
  }
  for (const std::size_t instrument : entry.touched_by) {
    model::ForcepsContactSettings settings;
    settings.shaft_radius_m = kShaftRadiusM;
    settings.jaw_radius_m = kJawRadiusM;
    settings.stiffness_n_per_m = static_cast<float>(cfg.tool_stiffness_n_per_m);
    settings.max_force_n = state.max_contact_force_n;
    settings.grasp_stiffness_n_per_m = static_cast<float>(cfg.grasp_stiffness_n_per_m);
    settings.max_grasp_force_n = state.max_contact_force_n;
    settings.friction_coefficient = static_cast<float>(cfg.grasp_friction);
    auto contact = model::ForcepsCatheterContact::create(settings);
    if (!contact) return std::move(contact).error();
    state.tools[instrument].emplace(std::move(contact).value());
  }
  // The catheter was created with room for every wall and tool plane (create()).
  auto planes = arena.allocate_array<model::ContactPlane>(catheter.max_contact_planes(),
                                                          "catheter contact planes (scene)");
  if (!planes) return std::move(planes).error();
  state.planes = planes.value();
  auto positions = arena.allocate_array<Vec3>(count, "catheter positions in a model frame");
  if (!positions) return std::move(positions).error();
  state.model_frame_positions = positions.value();
  auto velocities = arena.allocate_array<Vec3>(count, "catheter velocities in a model frame");
  if (!velocities) return std::move(velocities).error();
  state.model_frame_velocities = velocities.value();
  if (entry.insertion) {
    state.has_goal = true;
    state.goal_entry_m = to_vec3(entry.insertion->entry_m);
    state.goal_direction = to_vec3(entry.insertion->direction).normalized();
    state.goal_radius_m = static_cast<float>(entry.insertion->radius_m);
    state.goal_target_m = static_cast<float>(entry.insertion->target_depth_m);
  }
  return {};
}

void HapticApp::step_catheters() noexcept {
  for (InstrumentState& instrument : instruments_) {
    instrument.catheter_contact = false;
    instrument.grasping = false;
    instrument.squeeze_n = 0.0F;
  }
  for (std::size_t c = 0; c < catheter_count_; ++c) step_catheter(c);
}

void HapticApp::step_catheter(std::size_t index) noexcept {
  CatheterState& state = catheters_[index];
  model::Catheter& catheter = *state.catheter;
  CatheterStats& stats = stats_.catheters[index];
  const std::span<const Vec3> positions = catheter.positions_m();
  const std::span<const Vec3> velocities = catheter.velocities_m_per_s();
  std::size_t plane_count = 0;
  bool ok = true;

  // Walls: each particle sphere against each modal model's deformed surface (model frame),
  // turned into planes in the trainer frame. The surface is fresh where it matters: the modal
  // models rebuilt it this cycle when a particle or a tool was near.
  for (std::size_t m = 0; m < modal_model_count_; ++m) {
    state.wall_first_plane[m] = plane_count;
    state.wall_out[m] = model::ParticleContactOutput{};
    if (!state.walls[m]) continue;
    ModalContactState& wall = modal_contacts_[m];
    if (!wall.surface_ready) continue;  // no particle near: nothing to find
    for (std::size_t i = 0; i < positions.size(); ++i) {
      state.model_frame_positions[i] = wall.transform.to_model(positions[i]);
      state.model_frame_velocities[i] = wall.transform.vector_to_model(velocities[i]);
    }
    const model::TriangleMeshView view{wall.deformed, wall.triangles};
    const float detection_radius = catheter.radius_m() + kWallDetectionMarginM;
    const core::Status found = state.walls[m]->compute(
        state.model_frame_positions.first(positions.size()), state.model_frame_velocities.first(positions.size()),
        detection_radius, view, {}, *wall.grid, state.wall_out[m]);
    if (!found.is_ok()) ok = false;
    stats.dropped_contacts += state.wall_out[m].dropped_count;
    const float reach = catheter.radius_m() + wall.half_thickness_m;  // to the wall's surface
    for (const model::ParticleContactRecord& record : state.wall_out[m].contacts) {
      if (plane_count >= state.planes.size()) {
        ++stats.dropped_contacts;
        continue;
      }
      model::ContactPlane& plane = state.planes[plane_count++];
      plane.particle_a = plane.particle_b = record.particle;
      plane.weight_b = 0.0F;
      plane.point_m = wall.transform.to_world(record.point_m);
      plane.normal = wall.transform.vector_to_world(record.normal);
      plane.surface_velocity_m_per_s = Vec3::Zero();
      plane.reach_m = reach;
      plane.stiffness_n_per_m = state.wall_stiffness_n_per_m;
      plane.damping_n_s_per_m = state.wall_damping_n_s_per_m;
      plane.max_force_n = state.max_contact_force_n;
    }
  }
  const std::size_t wall_plane_end = plane_count;

  // Tools: shaft and jaws of every instrument touching this catheter; grasping.
  for (std::size_t i = 0; i < instruments_.size(); ++i) {
    state.tool_first_plane[i] = plane_count;
    state.tool_plane_count[i] = 0;
    if (!state.tools[i]) continue;
    const InstrumentState& instrument = instruments_[i];
    std::size_t added = 0;
    const core::Status prepared = state.tools[i]->prepare(
        forceps_shape(instrument), catheter, state.planes.subspan(plane_count), added);
    if (!prepared.is_ok()) ok = false;
    state.tool_plane_count[i] = added;
    plane_count += added;
  }

  if (!catheter.set_contact_planes(state.planes.first(plane_count)).is_ok()) ok = false;
  catheter.clear_forces();
  if (state.has_gravity) {
    for (std::uint32_t p = 0; p < catheter.particle_count(); ++p) {
      ok = catheter.add_force(p, state.gravity_force_n).is_ok() && ok;
    }
  }
  ok = catheter.step(catheter_period_s_).is_ok() && ok;
  const std::span<const Vec3> plane_forces = catheter.contact_plane_forces_n();

  // The walls' reactions: minus each plane's mean force, split over its triangle's vertices
  // (model frame), applied when the model steps next cycle.
  for (std::size_t m = 0; m < modal_model_count_; ++m) {
    if (!state.walls[m]) continue;
    ModalContactState& wall = modal_contacts_[m];
    const std::span<const model::ParticleContactRecord> records = state.wall_out[m].contacts;
    Vec3 total = Vec3::Zero();
    std::uint32_t touching = 0;
    for (std::size_t k = 0; k < records.size(); ++k) {
      const std::size_t plane = state.wall_first_plane[m] + k;
      if (plane >= wall_plane_end || plane >= plane_forces.size()) break;
      const Vec3 on_wall = -wall.transform.vector_to_model(plane_forces[plane]);
      if (on_wall.isZero(0.0F)) continue;
      ++touching;
      total += on_wall;
      for (std::size_t corner = 0; corner < 3; ++corner) {
        const float weight = records[k].barycentric[static_cast<Eigen::Index>(corner)];
        if (weight == 0.0F) continue;
        if (!add_catheter_load(wall, records[k].vertices[corner], weight * on_wall)) ++stats.dropped_contacts;
      }
    }
    if (touching > 0) ++stats.wall_contact_cycles;
    ModalModelStats& wall_stats = stats_.modal_models[m];
    if (touching > 0) ++wall_stats.catheter_contact_cycles;
    wall_stats.peak_catheter_contacts = std::max(wall_stats.peak_catheter_contacts, touching);
    wall_stats.peak_catheter_force_n = std::max(wall_stats.peak_catheter_force_n, total.norm());
  }

  // The tools' forces.
  for (std::size_t i = 0; i < instruments_.size(); ++i) {
    if (!state.tools[i]) continue;
    InstrumentState& instrument = instruments_[i];
    model::ForcepsCatheterContact& tool = *state.tools[i];
    const std::size_t first = state.tool_first_plane[i];
    const std::size_t count = state.tool_plane_count[i];
    const std::span<const Vec3> mine = first + count <= plane_forces.size()
                                           ? plane_forces.subspan(first, count)
                                           : std::span<const Vec3>{};
    if (!tool.collect(catheter, mine).is_ok()) ok = false;
    for (const model::ToolForce& force : tool.tool_forces()) {
      if (instrument.tool_force_count >= instrument.tool_forces.size()) {
        ok = false;
        break;
      }
      instrument.tool_forces[instrument.tool_force_count++] = force;
      instrument.catheter_contact = true;
    }
    InstrumentStats& tool_stats = stats_.instruments[i];
    if (tool.grasping()) {
      instrument.grasping = true;
      instrument.squeeze_n = std::max(instrument.squeeze_n, tool.squeeze_force_n());
      ++tool_stats.grasping_cycles;
    }
    tool_stats.grasps = tool.grasp_count();
    tool_stats.slips = tool.slip_count();
    tool_stats.peak_squeeze_n = std::max(tool_stats.peak_squeeze_n, tool.squeeze_force_n());
    if (!tool.tool_forces().empty()) ++tool_stats.catheter_contact_cycles;
  }

  if (state.has_goal) {
    float depth = 0.0F;
    for (const Vec3& p : catheter.positions_m()) {
      const Vec3 offset = p - state.goal_entry_m;
      const float along = offset.dot(state.goal_direction);
      const float radial = (offset - along * state.goal_direction).norm();
      if (along > depth && radial <= state.goal_radius_m) depth = along;
    }
    stats.insertion_depth_m = depth;
    stats.peak_insertion_depth_m = std::max(stats.peak_insertion_depth_m, depth);
    bool held = false;
    for (const auto& tool : state.tools) held = held || (tool && tool->grasping());
    if (held) stats.peak_held_depth_m = std::max(stats.peak_held_depth_m, depth);
    if (!stats.target_reached && depth >= state.goal_target_m) {
      stats.target_reached = true;
      stats.first_target_cycle = stats_.cycles;
    }
  }
  if (!ok) ++stats_.model_step_errors;
}

std::vector<std::array<float, 3>> HapticApp::catheter_positions_m(const std::string& name) const {
  std::vector<std::array<float, 3>> positions;
  for (std::size_t c = 0; c < catheter_count_; ++c) {
    if (catheters_[c].name != name) continue;
    for (const Vec3& p : catheters_[c].catheter->positions_m()) positions.push_back({p.x(), p.y(), p.z()});
  }
  return positions;
}

std::uint64_t HapticApp::raised_fault_count() const noexcept {
  std::uint64_t total = 0;
  for (const std::uint64_t count : safety_.fault_counts()) total += count;
  return total;
}

void HapticApp::on_overrun_fault(std::uint32_t streak) noexcept {
  safety_.latch(safety::Fault::overrun_streak, stats_.cycles);
  zero_commands();
  (void)hal_.actuators->write_actuators(commands_);
  log_.write(clock_.now_ns(), core::LogLevel::error, "overrun streak of {} cycles: force zeroed",
             streak);
}

void HapticApp::shutdown() noexcept {
  safety_.latch(safety::Fault::shutdown, stats_.cycles);
  zero_commands();
  (void)hal_.actuators->write_actuators(commands_);
  if (hal_.digital_outputs != nullptr) (void)hal_.digital_outputs->write_digital_outputs(0);
}

}  // namespace trainer::app
