// Loading a Cotin tensor model (the liver) for the cycle: the runtime settings from its
// definition, its image, the model, its boundary as a contact surface and a tip contact per
// instrument touching it.
#include <bit>
#include <string>

#include "models/model_setup.hpp"

namespace trainer::app {

core::Expected<model::TensorSettings> tensor_settings_from(
    const config::ModelDefinition& definition) {
  const config::TensorConfig& tensor = definition.tensor;
  model::TensorSettings settings;
  settings.max_contacts = tensor.max_contacts;
  struct MapKey {
    const config::AmplitudeMapConfig& config;
    const char* name;
    model::AmplitudeMap& out;
  };
  const MapKey maps[] = {
      {tensor.displacement_colinear, "displacement_colinear",
       settings.nonlinear.displacement_colinear},
      {tensor.displacement_orthogonal, "displacement_orthogonal",
       settings.nonlinear.displacement_orthogonal},
      {tensor.force_colinear, "force_colinear", settings.nonlinear.force_colinear},
      {tensor.force_orthogonal, "force_orthogonal", settings.nonlinear.force_orthogonal},
  };
  for (const MapKey& map : maps) {
    if (map.config.max_amplitude == 0.0) continue;  // not configured: identity
    std::string what = definition.source_path.string();
    what.append(": [nonlinear.").append(map.name).append("]");
    auto created =
        model::AmplitudeMap::create(map.config.coefficients, map.config.max_amplitude, what);
    if (!created) return std::move(created).error();
    map.out = created.value();
  }
  return settings;
}

namespace {

core::Expected<void> add_tensor_contacts(const config::SceneModelConfig& entry,
                                         const model::ModelImage& image, core::Arena& arena,
                                         TensorModelState& state) {
  const model::TensorModel& tensor = *state.model;
  auto surface = make_contact_surface(entry, image.floats(model::SectionId::rest_positions),
                                      image.u32s(model::SectionId::triangles), false, arena);
  if (!surface) return std::move(surface).error();
  state.surface = std::move(surface).value();
  state.response_nodes = tensor.response_nodes();
  const std::uint32_t mask = state.surface.touched_by_mask;
  if (mask == 0) return {};  // nothing touches it: no grid, no contacts

  // A tool's contact imposes the touched triangle's free nodes (up to 3): the solver's capacity
  // must hold every touching tool's at once, or a second tool would be refused mid-run.
  const auto touching = static_cast<std::uint32_t>(std::popcount(mask));
  const std::uint32_t needed =
      static_cast<std::uint32_t>(model::DisplacementContact::kMaxTargets) * touching;
  if (tensor.max_contacts() < needed) {
    return core::make_error("[tensor] max_contacts = " + std::to_string(tensor.max_contacts()) +
                            " is below " + std::to_string(needed) + ": each of the " +
                            std::to_string(touching) +
                            " instrument(s) touching the model imposes "
                            "up to 3 nodes (the touched triangle's)");
  }
  // Nodes a tool may not displace: every node that is not a contact node of the image (fixed,
  // partly fixed, interior). The contact leaves them out of its targets, as fixed nodes on the
  // duct.
  const std::span<const std::uint32_t> contact_nodes = tensor.contact_nodes();
  const std::size_t node_count = state.surface.vertex_count();
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
  for (std::size_t i = 0; i < kMaxInstruments; ++i) {
    if ((mask & (1U << static_cast<unsigned>(i))) == 0) continue;
    auto contact = make_tip_contact(state.surface, held.value(), arena);
    if (!contact) return std::move(contact).error();
    state.surface.contacts[i].emplace(std::move(contact).value());
  }
  return {};
}

}  // namespace

core::Expected<void> load_tensor_model(const config::SceneConfig& scene,
                                       const config::SceneModelConfig& entry, core::Arena& arena,
                                       SceneModels& models) {
  const config::ModelDefinition& definition = entry.definition;
  const std::size_t arena_before = arena.used_bytes();
  const std::string image_name = definition.image_path.string();
  auto settings = tensor_settings_from(definition);
  if (!settings) return core::make_error(": " + settings.error().message);
  auto image = model::load_model_image(definition.image_path, arena, model::ImageLimits{},
                                       model::ModelKind::tet_tensor);
  if (!image) {
    return core::make_error(": " + image.error().message +
                            " (build it with: modelc build --scene " + scene.source_path.string() +
                            ")");
  }
  auto tensor = model::TensorModel::create(model::tensor_model_data(*image), *settings, arena);
  if (!tensor) return core::make_error(" (" + image_name + "): " + tensor.error().message);
  TensorModelState& state = models.tensor[models.tensor_count++];
  state.model.emplace(std::move(*tensor));
  if (auto added = add_tensor_contacts(entry, *image, arena, state); !added) {
    return core::make_error(" (" + definition.source_path.string() + "): " + added.error().message);
  }
  LoadedModelInfo info = image_model_info(entry, *image, arena.used_bytes() - arena_before);
  info.contact_node_count = image->metadata().surface_node_count;
  info.stored_node_count = image->rows(model::SectionId::tensor_nodes);
  info.max_contacts = settings->max_contacts;
  info.quasi_nonlinear = definition.tensor.nonlinear;
  models.info.push_back(std::move(info));
  return {};
}

}  // namespace trainer::app
