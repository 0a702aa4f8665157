// Loading a particle catheter for the cycle from its image (modelc build; docs/model-image.md):
// the chain at the loop period (first pass), then its contacts with every modal model's wall
// and with the instruments touching it (second pass, once every modal model's grid exists).
// The image must have been built from the scene's definition: a stale image is refused.
#include <algorithm>
#include <string>

#include "models/model_setup.hpp"
#include "stages/vector_config.hpp"
#include "trainer/model/catheter_image.hpp"

namespace trainer::app {
namespace {

static_assert(config::kMaxCatheterParticles == model::Catheter::kMaxParticles,
              "the configuration's particle limit must be the runtime catheter's");

// Wall contacts kept per catheter particle and modal model (a particle squeezed between two
// walls has two patches).
constexpr std::uint32_t kWallContactsPerParticle = 2;

struct DefinitionField {
  const char* key;
  double definition;
  float image;
};

// The image was built from this definition: every parameter the definition gives equals the
// image's (as the float it is stored in), or the image is out of date; the first field that
// differs is named.
core::Expected<void> check_image_matches(const config::CatheterConfig& cfg,
                                         const model::CatheterModelData& data) {
  const model::CatheterParams& p = data.params;
  const model::CatheterContactSettings& c = data.contact;
  const std::span<const float> rest = data.rest_positions_m;  // N ≥ 3 rows (the loader's check)
  const DefinitionField fields[] = {
      {"[catheter] length_m", cfg.length_m, p.length_m},
      {"[catheter] outer_radius_m", cfg.outer_radius_m, p.outer_radius_m},
      {"[catheter] bending_stiffness_n_m2", cfg.bending_stiffness_n_m2, p.bending_stiffness_n_m2},
      {"[catheter] axial_stiffness_n", cfg.axial_stiffness_n, p.axial_stiffness_n},
      {"[catheter] linear_density_kg_per_m", cfg.linear_density_kg_per_m,
       p.linear_density_kg_per_m},
      {"[catheter] damping_n_s_per_m", cfg.damping_n_s_per_m, p.damping_n_s_per_m},
      {"[catheter] particle_count", static_cast<double>(cfg.particle_count),
       static_cast<float>(p.particle_count)},
      {"[catheter] max_substeps", static_cast<double>(cfg.max_substeps),
       static_cast<float>(data.max_substeps)},
      {"[pose] start_m[0]", cfg.start_m[0], rest[0]},
      {"[pose] start_m[1]", cfg.start_m[1], rest[1]},
      {"[pose] start_m[2]", cfg.start_m[2], rest[2]},
      {"[pose] hold_start", cfg.hold_start ? 1.0 : 0.0, data.hold_start ? 1.0F : 0.0F},
      {"[pose] gravity_m_per_s2[0]", cfg.gravity_m_per_s2[0], data.gravity_m_per_s2.x()},
      {"[pose] gravity_m_per_s2[1]", cfg.gravity_m_per_s2[1], data.gravity_m_per_s2.y()},
      {"[pose] gravity_m_per_s2[2]", cfg.gravity_m_per_s2[2], data.gravity_m_per_s2.z()},
      {"[contact] wall_stiffness_n_per_m", cfg.wall_stiffness_n_per_m, c.wall_stiffness_n_per_m},
      {"[contact] wall_damping_n_s_per_m", cfg.wall_damping_n_s_per_m, c.wall_damping_n_s_per_m},
      {"[contact] tool_stiffness_n_per_m", cfg.tool_stiffness_n_per_m, c.tool_stiffness_n_per_m},
      {"[contact] grasp_stiffness_n_per_m", cfg.grasp_stiffness_n_per_m, c.grasp_stiffness_n_per_m},
      {"[contact] grasp_friction", cfg.grasp_friction, c.grasp_friction},
      {"[contact] max_contact_force_n", cfg.max_contact_force_n, c.max_contact_force_n},
  };
  for (const DefinitionField& field : fields) {
    if (static_cast<float>(field.definition) != field.image) {
      return core::make_error(std::string(field.key) + " = " + std::to_string(field.definition) +
                              " in the definition but " + std::to_string(field.image) +
                              " in the image: the image is out of date");
    }
  }
  const Eigen::Vector3f direction = to_vec3(cfg.direction).normalized();
  if (!direction.isApprox(data.rest_direction, 1e-6F)) {
    return core::make_error(
        "[pose] direction differs from the image's rest direction: the image is out of date");
  }
  return {};
}

}  // namespace

core::Expected<void> load_catheter_model(const config::SceneConfig& scene,
                                         const config::SceneModelConfig& entry, core::Arena& arena,
                                         SceneModels& models) {
  const config::ModelDefinition& definition = entry.definition;
  const std::size_t arena_before = arena.used_bytes();
  const std::string image_name = definition.image_path.string();
  const std::string rebuild =
      " (build it with: modelc build --scene " + scene.source_path.string() + ")";
  auto image = model::load_model_image(definition.image_path, arena, model::ImageLimits{},
                                       model::ModelKind::catheter);
  if (!image) return core::make_error(": " + image.error().message + rebuild);
  const model::CatheterModelData data = model::catheter_model_data(*image);
  if (auto matches = check_image_matches(definition.catheter, data); !matches) {
    return core::make_error(" (" + image_name + ", built from " + definition.source_path.string() +
                            "): " + matches.error().message + rebuild);
  }
  // Room for every plane one step may take: each particle against each modal model's walls,
  // each instrument touching the catheter.
  const auto modal_count = static_cast<std::uint32_t>(std::count_if(
      scene.models.begin(), scene.models.end(), [](const config::SceneModelConfig& other) {
        return other.definition.kind == config::ModelKind::modal_shell;
      }));
  const std::uint32_t plane_capacity =
      modal_count * kWallContactsPerParticle * data.params.particle_count +
      static_cast<std::uint32_t>(entry.touched_by.size() *
                                 model::ForcepsCatheterContact::kMaxPlanes);
  auto created = model::Catheter::create(data, models.catheter_period_s, plane_capacity, arena);
  if (!created) {
    return core::make_error(" (" + image_name + ", built from " + definition.source_path.string() +
                            "): " + created.error().message);
  }
  CatheterModelState& state = models.catheters[models.catheter_count++];
  state.catheter.emplace(std::move(*created));
  state.catheter->clamp_start(data.hold_start);
  state.gravity_force_n = state.catheter->particle_mass_kg() * data.gravity_m_per_s2;
  state.has_gravity = !data.gravity_m_per_s2.isZero(0.0F);
  state.contact = data.contact;
  state.name = entry.name;
  LoadedModelInfo info = image_model_info(entry, *image, arena.used_bytes() - arena_before);
  info.particle_count = state.catheter->particle_count();
  info.stable_substep_s = static_cast<double>(state.catheter->stable_substep_s());
  info.substeps_per_period = state.catheter->substeps_per_period();
  info.max_substeps = data.max_substeps;
  info.hold_start = data.hold_start;
  info.has_insertion_goal = entry.insertion.has_value();
  info.insertion_target_depth_m = entry.insertion ? entry.insertion->target_depth_m : 0.0;
  models.info.push_back(std::move(info));
  return {};
}

namespace {

// The image's contact stiffnesses against the chain's substep at this loop period.
core::Expected<void> check_contact_stiffness(const CatheterModelState& state) {
  const float limit = state.catheter->max_contact_stiffness_n_per_m();
  const auto check = [&](float value, const char* key) -> core::Expected<void> {
    if (value > limit) {
      return core::make_error("[contact] " + std::string(key) + " = " + std::to_string(value) +
                              " N/m: expected at most " + std::to_string(limit) +
                              " N/m, the stiffest contact this catheter accepts "
                              "(1e5 particle mass / substep^2)");
    }
    return {};
  };
  if (auto ok = check(state.contact.wall_stiffness_n_per_m, "wall_stiffness_n_per_m"); !ok)
    return ok;
  return check(state.contact.tool_stiffness_n_per_m, "tool_stiffness_n_per_m");
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
    settings.stiffness_n_per_m = state.contact.wall_stiffness_n_per_m;
    settings.damping_n_s_per_m = state.contact.wall_damping_n_s_per_m;
    settings.surface_offset_m = 0.0F;  // the planes carry the wall's half-thickness in their reach
    settings.max_force_n = state.contact.max_contact_force_n;
    settings.side = model::ContactSide::inner;
    settings.cached_particles = count;  // each particle's wall candidates kept between cycles
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
  model::Catheter& catheter = *state.catheter;
  const std::uint32_t count = catheter.particle_count();
  if (auto ok = check_contact_stiffness(state); !ok) return ok;
  if (auto ok = add_wall_contacts(state, modal_models, arena); !ok) return ok;
  for (const std::size_t instrument : entry.touched_by) {
    model::ForcepsContactSettings settings;
    settings.shaft_radius_m = kShaftRadiusM;
    settings.jaw_radius_m = kJawRadiusM;
    settings.stiffness_n_per_m = state.contact.tool_stiffness_n_per_m;
    settings.max_force_n = state.contact.max_contact_force_n;
    settings.grasp_stiffness_n_per_m = state.contact.grasp_stiffness_n_per_m;
    settings.max_grasp_force_n = state.contact.max_contact_force_n;
    settings.friction_coefficient = state.contact.grasp_friction;
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
