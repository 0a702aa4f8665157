// Loading a particle catheter for the cycle: the chain at the loop period (first pass), then
// its contacts with every modal model's wall and with the instruments touching it (second
// pass, once every modal model's grid exists).
#include <algorithm>
#include <string>

#include "models/model_setup.hpp"
#include "stages/vector_config.hpp"

namespace trainer::app {
namespace {

static_assert(config::kMaxCatheterParticles == model::Catheter::kMaxParticles,
              "the configuration's particle limit must be the runtime catheter's");

// Wall contacts kept per catheter particle and modal model (a particle squeezed between two
// walls has two patches).
constexpr std::uint32_t kWallContactsPerParticle = 2;

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

}  // namespace

core::Expected<void> load_catheter_model(const config::SceneConfig& scene,
                                         const config::SceneModelConfig& entry, core::Arena& arena,
                                         SceneModels& models) {
  const config::ModelDefinition& definition = entry.definition;
  const std::size_t arena_before = arena.used_bytes();
  // Room for every plane one step may take: each particle against each modal model's walls,
  // each instrument touching the catheter.
  const auto modal_count = static_cast<std::uint32_t>(std::count_if(
      scene.models.begin(), scene.models.end(), [](const config::SceneModelConfig& other) {
        return other.definition.kind == config::ModelKind::modal_shell;
      }));
  const std::uint32_t plane_capacity =
      modal_count * kWallContactsPerParticle * definition.catheter.particle_count +
      static_cast<std::uint32_t>(entry.touched_by.size() *
                                 model::ForcepsCatheterContact::kMaxPlanes);
  auto created =
      create_catheter(definition.catheter, models.catheter_period_s, plane_capacity, arena);
  if (!created) {
    return core::make_error(" (" + definition.source_path.string() +
                            "): " + created.error().message);
  }
  CatheterModelState& state = models.catheters[models.catheter_count++];
  state.catheter.emplace(std::move(*created));
  state.catheter->clamp_start(definition.catheter.hold_start);
  const Eigen::Vector3f gravity = to_vec3(definition.catheter.gravity_m_per_s2);
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
  models.info.push_back(std::move(info));
  return {};
}

namespace {

// The contact settings of the definition, each stiffness checked against the chain's substep.
core::Expected<void> take_contact_settings(const config::CatheterConfig& cfg,
                                           CatheterModelState& state) {
  const float limit = state.catheter->max_contact_stiffness_n_per_m();
  const auto check_stiffness = [&](double value, const char* key) -> core::Expected<void> {
    if (static_cast<float>(value) > limit) {
      return core::make_error("[contact] " + std::string(key) + " = " + std::to_string(value) +
                              " N/m: expected at most " + std::to_string(limit) +
                              " N/m, the stiffest contact this catheter's substep keeps stable "
                              "(particle mass / substep^2)");
    }
    return {};
  };
  if (auto ok = check_stiffness(cfg.wall_stiffness_n_per_m, "wall_stiffness_n_per_m"); !ok)
    return ok;
  if (auto ok = check_stiffness(cfg.tool_stiffness_n_per_m, "tool_stiffness_n_per_m"); !ok)
    return ok;
  state.wall_stiffness_n_per_m = static_cast<float>(cfg.wall_stiffness_n_per_m);
  state.wall_damping_n_s_per_m = static_cast<float>(cfg.wall_damping_n_s_per_m);
  state.max_contact_force_n = static_cast<float>(cfg.max_contact_force_n);
  return {};
}

core::Expected<void> add_wall_contacts(CatheterModelState& state,
                                       std::span<const ModalModelState> modal_models,
                                       core::Arena& arena) {
  const std::uint32_t count = state.catheter->particle_count();
  for (std::size_t m = 0; m < modal_models.size(); ++m) {
    const ContactSurface& wall = modal_models[m].surface;
    if (!wall.grid) continue;
    model::ParticleContactSettings settings;
    settings.max_particles = count;
    settings.max_contacts = kWallContactsPerParticle * count;
    settings.max_nodes = static_cast<std::uint32_t>(wall.vertex_count());
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
  return {};
}

}  // namespace

core::Expected<void> add_catheter_contacts(const config::SceneModelConfig& entry,
                                           CatheterModelState& state,
                                           std::span<const ModalModelState> modal_models,
                                           core::Arena& arena) {
  const config::CatheterConfig& cfg = entry.definition.catheter;
  model::Catheter& catheter = *state.catheter;
  const std::uint32_t count = catheter.particle_count();
  if (auto ok = take_contact_settings(cfg, state); !ok) return ok;
  if (auto ok = add_wall_contacts(state, modal_models, arena); !ok) return ok;
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
  // The catheter was created with room for every wall and tool plane (load_catheter_model).
  auto planes = arena.allocate_array<model::ContactPlane>(catheter.max_contact_planes(),
                                                          "catheter contact planes (scene)");
  if (!planes) return std::move(planes).error();
  state.planes = planes.value();
  auto positions =
      arena.allocate_array<Eigen::Vector3f>(count, "catheter positions in a model frame");
  if (!positions) return std::move(positions).error();
  state.model_frame_positions = positions.value();
  auto velocities =
      arena.allocate_array<Eigen::Vector3f>(count, "catheter velocities in a model frame");
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

}  // namespace trainer::app
