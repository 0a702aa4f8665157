// Turns a model definition file (config/models/*.toml, read by trainer::config) into the
// offline builder's spec: the mesh it names (generated or read), material, element, fixes,
// modal settings; a tet_tensor definition's mesh and fixes; a catheter definition's chain,
// placement and contact settings. Shared by `modelc build` and `modelc accuracy`.
#pragma once

#include "trainer/config/model.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/model_offline/catheter_image.hpp"
#include "trainer/model_offline/modal_build.hpp"
#include "trainer/model_offline/tet_elasticity.hpp"

namespace trainer::tools::modelc {

core::Expected<model::offline::ModalBuildSpec> modal_spec_from(
    const config::ModelDefinition& definition);

// A tet_tensor definition's mesh (generated or read from Gmsh), with node set "surface" (every
// boundary node) added when the mesh does not name one.
core::Expected<model::offline::TetMesh> tet_mesh_from(const config::ModelDefinition& definition);

// Its [[fix]] entries as node fixes; an unknown node set is an error naming the file.
core::Expected<std::vector<model::offline::TetNodeFix>> tet_fixes_from(
    const config::ModelDefinition& definition, const model::offline::TetMesh& mesh);

// A catheter definition's [catheter], [pose] and [contact] in the runtime's precision: each
// value rounded once from the configuration's double to float, the conversion the trainer
// applies when it creates the catheter from its definition.
model::offline::CatheterImageInputs catheter_inputs_from(const config::ModelDefinition& definition);

}  // namespace trainer::tools::modelc
