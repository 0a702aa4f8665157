#include "model_spec.hpp"

#include "trainer/model_offline/gmsh_reader.hpp"
#include "trainer/model_offline/mesh_generators.hpp"
#include "trainer/model_offline/tet_mesh_generators.hpp"

#include <algorithm>
#include <set>

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

core::Expected<offline::TetMesh> tet_mesh_from(const config::ModelDefinition& definition) {
  const std::string where = definition.source_path.string() + ": ";
  core::Expected<offline::TetMesh> mesh = core::make_error("no mesh");
  switch (definition.mesh_source) {
    case config::MeshSource::box:
      mesh = offline::make_tet_box(definition.box.size_m[0], definition.box.size_m[1],
                                   definition.box.size_m[2], definition.box.divisions[0],
                                   definition.box.divisions[1], definition.box.divisions[2]);
      break;
    case config::MeshSource::cylinder:
      mesh = offline::make_tet_cylinder(definition.cylinder.radius_m, definition.cylinder.height_m,
                                        definition.cylinder.radial, definition.cylinder.axial);
      break;
    case config::MeshSource::gmsh:
      mesh = offline::read_gmsh_tet(definition.mesh_file.string());
      break;
    case config::MeshSource::tube:
      return core::make_error(where + "a tet_tensor model needs a solid mesh (box, cylinder or gmsh)");
  }
  if (!mesh) return core::make_error(where + mesh.error().message);
  if (auto valid = offline::validate_tet_mesh(*mesh); !valid) {
    return core::make_error(where + valid.error().message);
  }
  if (mesh->node_sets.find("surface") == mesh->node_sets.end()) {
    const auto faces = offline::boundary_triangles(*mesh);
    std::set<int> boundary(faces.data(), faces.data() + faces.size());
    mesh->node_sets["surface"] = std::vector<int>(boundary.begin(), boundary.end());
  }
  return mesh;
}

core::Expected<std::vector<offline::TetNodeFix>> tet_fixes_from(
    const config::ModelDefinition& definition, const offline::TetMesh& mesh) {
  std::vector<offline::TetNodeFix> fixes;
  for (const config::DofFixConfig& fix : definition.fixes) {
    const auto found = mesh.node_sets.find(fix.node_set);
    if (found == mesh.node_sets.end()) {
      std::string known;
      for (const auto& [name, nodes] : mesh.node_sets) known += (known.empty() ? "" : ", ") + name;
      return core::make_error(definition.source_path.string() + ": [[fix]] node_set '" +
                              fix.node_set + "' is not a node set of the mesh (it has: " + known +
                              ")");
    }
    offline::TetNodeFix entry;
    entry.nodes = found->second;
    std::sort(entry.nodes.begin(), entry.nodes.end());
    entry.nodes.erase(std::unique(entry.nodes.begin(), entry.nodes.end()), entry.nodes.end());
    for (const int dof : fix.dofs) entry.axes[static_cast<std::size_t>(dof)] = true;
    fixes.push_back(std::move(entry));
  }
  return fixes;
}

offline::CatheterImageInputs catheter_inputs_from(const config::ModelDefinition& definition) {
  const config::CatheterConfig& c = definition.catheter;
  const auto f = [](double value) { return static_cast<float>(value); };
  const auto vector = [&f](const config::Vec3& v) {
    return Eigen::Vector3f(f(v[0]), f(v[1]), f(v[2]));
  };
  offline::CatheterImageInputs inputs;
  inputs.params = {.length_m = f(c.length_m),
                   .outer_radius_m = f(c.outer_radius_m),
                   .bending_stiffness_n_m2 = f(c.bending_stiffness_n_m2),
                   .axial_stiffness_n = f(c.axial_stiffness_n),
                   .linear_density_kg_per_m = f(c.linear_density_kg_per_m),
                   .damping_n_s_per_m = f(c.damping_n_s_per_m),
                   .particle_count = c.particle_count,
                   .contact_stiffness_n_per_m = model::catheter_contact_stiffness(
                       f(c.wall_stiffness_n_per_m), f(c.tool_stiffness_n_per_m))};
  inputs.start_m = vector(c.start_m);
  inputs.direction = vector(c.direction);
  inputs.max_substeps = c.max_substeps;
  inputs.hold_start = c.hold_start;
  inputs.gravity_m_per_s2 = vector(c.gravity_m_per_s2);
  inputs.contact = {.wall_stiffness_n_per_m = f(c.wall_stiffness_n_per_m),
                    .wall_damping_n_s_per_m = f(c.wall_damping_n_s_per_m),
                    .tool_stiffness_n_per_m = f(c.tool_stiffness_n_per_m),
                    .grasp_stiffness_n_per_m = f(c.grasp_stiffness_n_per_m),
                    .grasp_friction = f(c.grasp_friction),
                    .max_contact_force_n = f(c.max_contact_force_n)};
  return inputs;
}

}  // namespace trainer::tools::modelc
