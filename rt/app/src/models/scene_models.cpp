#include "trainer/app/scene_models.hpp"

#include <algorithm>
#include <string>

#include "models/model_setup.hpp"

namespace trainer::app {

bool ModalModelState::add_catheter_load(std::uint32_t node,
                                        const Eigen::Vector3f& force_n) noexcept {
  // A clamped node cannot move: the clamp takes its share (the model refuses loads there).
  if (std::binary_search(fixed_nodes.begin(), fixed_nodes.end(), node)) return true;
  for (std::size_t k = 0; k < catheter_load_count; ++k) {
    if (catheter_loads[k].node == node) {
      catheter_loads[k].force_n += force_n;
      return true;
    }
  }
  if (catheter_load_count >= catheter_loads.size()) return false;
  catheter_loads[catheter_load_count++] = model::NodeForce{node, force_n};
  return true;
}

LoadedModelInfo image_model_info(const config::SceneModelConfig& entry,
                                 const model::ModelImage& image, std::size_t arena_bytes) {
  const config::ModelDefinition& definition = entry.definition;
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

core::Expected<void> load_scene_models(const config::SceneConfig& scene, core::Arena& arena,
                                       SceneModels& models) {
  const std::string where = scene.source_path.string();
  if (scene.models.size() > kMaxSceneModels) {
    return core::make_error(where + ": at most " + std::to_string(kMaxSceneModels) +
                            " models, the scene has " + std::to_string(scene.models.size()));
  }
  models.catheter_period_s = static_cast<float>(static_cast<double>(scene.loop.period_ns) * 1e-9);
  const bool scene_has_catheter = std::any_of(
      scene.models.begin(), scene.models.end(), [](const config::SceneModelConfig& other) {
        return other.definition.kind == config::ModelKind::catheter;
      });
  for (const config::SceneModelConfig& entry : scene.models) {
    core::Expected<void> loaded;
    switch (entry.definition.kind) {
      case config::ModelKind::catheter:
        loaded = load_catheter_model(scene, entry, arena, models);
        break;
      case config::ModelKind::tet_tensor:
        loaded = load_tensor_model(scene, entry, arena, models);
        break;
      case config::ModelKind::modal_shell:
        loaded = load_modal_model(scene, entry, scene_has_catheter, arena, models);
        break;
    }
    if (!loaded)
      return core::make_error(where + ": model '" + entry.name + "'" + loaded.error().message);
  }
  // Catheter contacts last: they need every modal model's grid, whatever the scene's order.
  std::size_t catheter = 0;
  for (const config::SceneModelConfig& entry : scene.models) {
    if (entry.definition.kind != config::ModelKind::catheter) continue;
    const std::size_t arena_before = arena.used_bytes();
    auto added =
        add_catheter_contacts(entry, models.catheters[catheter++], models.modal_models(), arena);
    if (!added) {
      return core::make_error(where + ": model '" + entry.name + "' (" +
                              entry.definition.source_path.string() +
                              "): " + added.error().message);
    }
    for (LoadedModelInfo& info : models.info) {
      if (info.name == entry.name) info.arena_bytes += arena.used_bytes() - arena_before;
    }
  }
  // Every entry above pushed exactly one info, so scene order is info order.
  for (std::size_t m = 0; m < scene.models.size(); ++m) {
    const config::SceneModelConfig& entry = scene.models[m];
    models.transforms[m] = RigidTransform::from_placement(entry.position_m, entry.rotation_deg);
    models.info[m].position_m = entry.position_m;
    models.info[m].rotation_deg = entry.rotation_deg;
  }
  return {};
}

}  // namespace trainer::app
