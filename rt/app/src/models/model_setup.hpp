// Setup path of load_scene_models (scene_models.hpp), one file per model kind. Each loads one
// [[model]] entry into SceneModels and pushes its LoadedModelInfo; errors are returned with
// the model's own context, load_scene_models adds the scene's.
#pragma once

#include <cstddef>

#include "trainer/app/scene_models.hpp"
#include "trainer/model/image_loader.hpp"
#include "trainer/model/modal_image.hpp"
#include "trainer/model/tensor_image.hpp"

namespace trainer::app {

// modal_setup.cpp: image, ModalModel at the loop period, its surface and contacts.
// `with_grid`: the scene has a catheter, which collides with every modal model.
core::Expected<void> load_modal_model(const config::SceneConfig& scene,
                                      const config::SceneModelConfig& entry, bool with_grid,
                                      core::Arena& arena, SceneModels& models);

// tensor_setup.cpp: image, TensorModel with the definition's settings, surface and contacts.
core::Expected<void> load_tensor_model(const config::SceneConfig& scene,
                                       const config::SceneModelConfig& entry, core::Arena& arena,
                                       SceneModels& models);

// catheter_setup.cpp: the chain (first pass) and, once every modal model is loaded, its wall
// and tool contacts (second pass).
core::Expected<void> load_catheter_model(const config::SceneConfig& scene,
                                         const config::SceneModelConfig& entry, core::Arena& arena,
                                         SceneModels& models);
core::Expected<void> add_catheter_contacts(const config::SceneModelConfig& entry,
                                           CatheterModelState& state,
                                           std::span<const ModalModelState> modal_models,
                                           core::Arena& arena);

// What the report says of a model loaded from an image, whatever its kind.
LoadedModelInfo image_model_info(const config::SceneModelConfig& entry,
                                 const model::ModelImage& image, std::size_t arena_bytes);

}  // namespace trainer::app
