#include "scene_assets.hpp"

#include <cstdio>
#include <system_error>
#include <utility>

#include "trainer/app/instrument_geometry.hpp"
#include "trainer/app/scene_models.hpp"  // tensor_settings_from
#include "trainer/model/image_format.hpp"
#include "trainer/model/tensor_image.hpp"

namespace trainer::viewer {

namespace {

model::ModelKind image_kind_of(config::ModelKind kind) {
  switch (kind) {
    case config::ModelKind::modal_shell: return model::ModelKind::modal_shell;
    case config::ModelKind::tet_tensor: return model::ModelKind::tet_tensor;
    case config::ModelKind::catheter: return model::ModelKind::catheter;
  }
  return model::ModelKind::modal_shell;
}

// What the tensor models' solver state takes beyond the images (the same sizes the runtime
// carves: field, (3M)² system, slots), with room to spare.
constexpr std::size_t kAssetArenaSlackBytes = 8U << 20U;

}  // namespace

std::string checksum_hex(std::uint64_t checksum) {
  char text[19];
  std::snprintf(text, sizeof text, "0x%016llx", static_cast<unsigned long long>(checksum));
  return text;
}

core::Expected<std::unique_ptr<SceneAssets>> SceneAssets::load(
    const std::filesystem::path& scene_file) {
  config::LoadOptions options;
  options.require_script_file = false;
  auto scene = config::load_scene(scene_file, options);
  if (!scene) return std::move(scene).error();

  std::unique_ptr<SceneAssets> assets(new SceneAssets());
  assets->scene_name_ = scene->name;
  assets->scene_path_ = scene->source_path;
  assets->period_s_ = static_cast<double>(scene->loop.period_ns) * 1e-9;

  std::size_t arena_bytes = kAssetArenaSlackBytes;
  for (const config::SceneModelConfig& entry : scene->models) {
    std::error_code error;
    const std::uintmax_t size = std::filesystem::file_size(entry.definition.image_path, error);
    if (error) {
      return core::make_error("model '" + entry.name + "': image " +
                              entry.definition.image_path.string() + ": " + error.message() +
                              " (build it with: modelc build --scene " +
                              scene->source_path.string() + ")");
    }
    arena_bytes += static_cast<std::size_t>(size) + core::Arena::kAlignment;
  }
  auto arena = core::Arena::create(arena_bytes);
  if (!arena) return std::move(arena).error();
  assets->arena_.emplace(std::move(arena).value());

  for (const config::SceneModelConfig& entry : scene->models) {
    const config::ModelDefinition& definition = entry.definition;
    auto image = model::load_model_image(definition.image_path, *assets->arena_,
                                         model::ImageLimits{}, image_kind_of(definition.kind));
    if (!image) {
      return core::make_error("model '" + entry.name + "': " + image.error().message +
                              " (build it with: modelc build --scene " +
                              scene->source_path.string() + ")");
    }
    ModelAssets m;
    m.name = entry.name;
    m.kind = definition.kind;
    m.image_path = definition.image_path;
    m.checksum = image->checksum();
    m.image_bytes = image->bytes().size();
    if (definition.kind == config::ModelKind::catheter) {
      m.rest_positions = image->floats(model::SectionId::catheter_rest_positions);
      m.node_count = image->rows(model::SectionId::catheter_rest_positions);
    } else {
      m.placement = app::RigidTransform::from_placement(entry.position_m, entry.rotation_deg);
      m.rest_positions = image->floats(model::SectionId::rest_positions);
      m.node_count = image->rows(model::SectionId::rest_positions);
      m.triangles = image->u32s(model::SectionId::triangles);
      m.surface_nodes = image->u32s(model::SectionId::surface_nodes);
    }
    if (definition.kind == config::ModelKind::modal_shell) {
      m.mode_shapes = image->floats(model::SectionId::mode_shapes);
      m.omega_squared = image->floats(model::SectionId::omega_squared);
      m.mode_count = image->cols(model::SectionId::mode_shapes);
      m.residual_compliance = image->floats(model::SectionId::residual_compliance);
      m.static_correction =
          image->metadata().static_correction != 0 && !m.residual_compliance.empty();
      m.surface_index.assign(m.node_count, -1);
      for (std::size_t s = 0; s < m.surface_nodes.size(); ++s) {
        m.surface_index[m.surface_nodes[s]] = static_cast<std::int32_t>(s);
      }
    }
    if (definition.kind == config::ModelKind::tet_tensor) {
      auto settings = app::tensor_settings_from(definition);
      if (!settings) return std::move(settings).error();
      auto tensor =
          model::TensorModel::create(model::tensor_model_data(*image), *settings, *assets->arena_);
      if (!tensor) {
        return core::make_error("model '" + entry.name + "' (" + definition.image_path.string() +
                                "): " + tensor.error().message);
      }
      m.tensor.emplace(std::move(tensor).value());
    }
    assets->models_.push_back(std::move(m));
  }

  for (const config::SceneInstrumentConfig& instrument : scene->instruments) {
    const config::InstrumentDeviceConfig& device =
        scene->device.instruments.at(instrument.device_instrument);
    assets->instruments_.push_back(InstrumentAssets{
        instrument.name, kinematics::TrocarKinematics(app::trocar_geometry(device))});
  }
  return assets;
}

core::Expected<void> SceneAssets::check_checksums(
    std::span<const std::uint64_t> stream_checksums) const {
  if (stream_checksums.size() != models_.size()) {
    return core::make_error("stream refused: it carries " +
                            std::to_string(stream_checksums.size()) + " model image(s), scene '" +
                            scene_name_ + "' (" + scene_path_.string() + ") has " +
                            std::to_string(models_.size()));
  }
  for (std::size_t i = 0; i < models_.size(); ++i) {
    if (stream_checksums[i] != models_[i].checksum) {
      return core::make_error("stream refused: model '" + models_[i].name + "' image checksum " +
                              checksum_hex(stream_checksums[i]) + " on the stream, " +
                              checksum_hex(models_[i].checksum) + " in " +
                              models_[i].image_path.string() +
                              ": the appliance runs another image (copy the appliance's image file "
                              "here: a rebuild differs at least in its creation time)");
    }
  }
  return {};
}

}  // namespace trainer::viewer
