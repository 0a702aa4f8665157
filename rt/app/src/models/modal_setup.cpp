// Loading a reduced-modal model (the duct) for the cycle: its image, the model at the loop
// period, its contact surface, a tip contact and a shaft/jaw contact per instrument touching it.
#include <string>

#include "models/model_setup.hpp"

namespace trainer::app {
namespace {

core::Expected<void> add_modal_contacts(const config::SceneModelConfig& entry,
                                        const model::ModelImage& image, bool with_grid,
                                        core::Arena& arena, ModalModelState& state) {
  auto surface = make_contact_surface(entry, image.floats(model::SectionId::rest_positions),
                                      image.u32s(model::SectionId::triangles), with_grid, arena);
  if (!surface) return std::move(surface).error();
  state.surface = std::move(surface).value();
  state.fixed_nodes = image.u32s(model::SectionId::fixed_nodes);
  state.half_thickness_m = static_cast<float>(0.5 * image.metadata().thickness_m);
  for (std::size_t i = 0; i < kMaxInstruments; ++i) {
    if ((state.surface.touched_by_mask & (1U << static_cast<unsigned>(i))) == 0) continue;
    auto contact = make_tip_contact(state.surface, state.fixed_nodes, arena);
    if (!contact) return std::move(contact).error();
    state.surface.contacts[i].emplace(std::move(contact).value());
    // The shaft and jaws: only the contact geometry is used (the wall's response comes from
    // the model's imposed solve), so the penalty settings are nominal.
    model::SegmentContactSettings segment_settings;
    segment_settings.surface_half_thickness_m = state.half_thickness_m;
    segment_settings.stiffness_n_per_m = 1.0F;
    segment_settings.max_force_n = 1.0F;
    segment_settings.max_candidates =
        static_cast<std::uint32_t>(state.surface.triangles.size() / 3);
    auto segments = model::SegmentSurfaceContact::create(segment_settings, arena);
    if (!segments) return std::move(segments).error();
    state.segments[i].emplace(std::move(segments).value());
  }
  return {};
}

}  // namespace

core::Expected<void> load_modal_model(const config::SceneConfig& scene,
                                      const config::SceneModelConfig& entry, bool with_grid,
                                      core::Arena& arena, SceneModels& models) {
  const config::ModelDefinition& definition = entry.definition;
  const std::size_t arena_before = arena.used_bytes();
  const std::string image_name = definition.image_path.string();
  auto image = model::load_model_image(definition.image_path, arena, model::ImageLimits{},
                                       model::ModelKind::modal_shell);
  if (!image) {
    return core::make_error(": " + image.error().message +
                            " (build it with: modelc build --scene " + scene.source_path.string() +
                            ")");
  }
  const model::ImageMetadataV1& metadata = image->metadata();
  model::ModalSettings settings;
  settings.time_step_s = static_cast<float>(static_cast<double>(scene.loop.period_ns) * 1e-9);
  settings.static_correction = metadata.static_correction != 0;
  auto modal = model::ModalModel::create(model::modal_model_data(*image), arena, settings);
  if (!modal) return core::make_error(" (" + image_name + "): " + modal.error().message);
  ModalModelState& state = models.modal[models.modal_count];
  if (auto added = add_modal_contacts(entry, *image, with_grid, arena, state); !added) {
    return core::make_error(" (" + image_name + "): " + added.error().message);
  }
  state.model.emplace(std::move(*modal));
  if (state.surface.grid) {
    auto lazy = LazyModalSurface::create(model::modal_model_data(*image), *state.model, arena);
    if (!lazy) return core::make_error(" (" + image_name + "): " + lazy.error().message);
    state.lazy.emplace(std::move(lazy).value());
  }
  ++models.modal_count;
  LoadedModelInfo info = image_model_info(entry, *image, arena.used_bytes() - arena_before);
  info.mode_count = metadata.mode_count;
  info.static_correction = metadata.static_correction != 0;
  models.info.push_back(std::move(info));
  return {};
}

}  // namespace trainer::app
