#include "model_spec.hpp"

#include "trainer/model_offline/gmsh_reader.hpp"
#include "trainer/model_offline/mesh_generators.hpp"

namespace trainer::tools::modelc {

namespace offline = model::offline;

core::Expected<offline::ModalBuildSpec> modal_spec_from(const config::ModelDefinition& definition) {
  offline::ModalBuildSpec spec;
  spec.name = definition.name;
  const std::string where = definition.source_path.string() + ": ";
  if (definition.mesh_source == config::MeshSource::tube) {
    auto mesh = offline::make_tube(definition.tube.radius_m, definition.tube.length_m,
                                   definition.tube.rings, definition.tube.segments);
    if (!mesh) return core::make_error(where + mesh.error().message);
    spec.mesh = std::move(*mesh);
  } else {
    auto mesh = offline::read_gmsh_shell(definition.mesh_file.string());
    if (!mesh) return std::move(mesh).error();
    spec.mesh = std::move(*mesh);
  }
  spec.material = {definition.material.young_modulus_pa, definition.material.poisson_ratio,
                   definition.material.thickness_m, definition.material.density_kg_per_m3};
  spec.bending = definition.bending == config::BendingKind::dkt ? offline::BendingElement::dkt
                                                                : offline::BendingElement::rao;
  for (const config::DofFixConfig& fix : definition.fixes) {
    spec.fixes.push_back({fix.node_set, fix.dofs});
  }
  spec.mode_count = static_cast<int>(definition.modal.mode_count);
  switch (definition.modal.method) {
    case config::ModalMethod::automatic: break;
    case config::ModalMethod::condensation: spec.method = offline::ModalMethod::condensation; break;
    case config::ModalMethod::shift_invert: spec.method = offline::ModalMethod::shift_invert; break;
  }
  spec.damping_ratio = definition.modal.damping_ratio;
  spec.time_step_s = definition.modal.time_step_s;
  spec.static_correction = definition.modal.static_correction;
  spec.surface_set = definition.modal.surface_set;
  return spec;
}

}  // namespace trainer::tools::modelc
