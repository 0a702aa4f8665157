// Turns a model definition file (config/models/*.toml, read by trainer::config) into the
// offline builder's spec: the mesh it names (generated or read), material, element, fixes,
// modal settings. Shared by `modelc build` and `modelc accuracy`.
#pragma once

#include "trainer/config/model.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/model_offline/modal_build.hpp"

namespace trainer::tools::modelc {

core::Expected<model::offline::ModalBuildSpec> modal_spec_from(
    const config::ModelDefinition& definition);

}  // namespace trainer::tools::modelc
