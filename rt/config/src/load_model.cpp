// The model definition schema: [model], then for kind = "modal_shell" [mesh], [material],
// [element], [[fix]], [modal]; for kind = "catheter" [catheter] and [pose]; for kind =
// "tet_tensor" [mesh], [material], [[fix]], [tensor] and optionally [nonlinear]. A table of
// another kind is an unknown key. Documented in docs/config.md; keep them in step.
#include <array>
#include <string>
#include <string_view>

#include "table_reader.hpp"
#include "trainer/config/model.hpp"

namespace trainer::config {

namespace {

using detail::ErrorSink;
using detail::IntRange;
using detail::RealRange;
using detail::TableReader;

constexpr std::array<std::string_view, 3> kKinds = {"modal_shell", "catheter", "tet_tensor"};
constexpr std::array<std::string_view, 2> kShellGenerators = {"tube", "gmsh"};
constexpr std::array<std::string_view, 3> kSolidGenerators = {"box", "cylinder", "gmsh"};
constexpr std::array<std::string_view, 2> kStorage = {"surface", "all"};
constexpr std::array<std::string_view, 2> kBending = {"rao", "dkt"};
constexpr std::array<std::string_view, 3> kMethods = {"auto", "condensation", "shift_invert"};
constexpr std::array<std::string_view, 6> kDofNames = {"x", "y", "z", "rx", "ry", "rz"};

void read_mesh(TableReader& mesh, ModelDefinition& model) {
  const auto generator = mesh.required_choice("generator", kShellGenerators);
  if (generator && *generator == 0) {
    model.mesh_source = MeshSource::tube;
    model.tube.radius_m = mesh.required_double("radius_m", RealRange::left_open(0.0, 1.0), "metres");
    model.tube.length_m = mesh.required_double("length_m", RealRange::left_open(0.0, 10.0), "metres");
    model.tube.rings = static_cast<int>(mesh.required_int("rings", IntRange{2, 1000}, "node rings"));
    model.tube.segments =
        static_cast<int>(mesh.required_int("segments", IntRange{3, 1000}, "nodes per ring"));
  } else if (generator) {
    model.mesh_source = MeshSource::gmsh;
    model.mesh_file = mesh.required_file("file", true);
  }
  mesh.finish();
}

void read_solid_mesh(TableReader& mesh, ModelDefinition& model) {
  const auto generator = mesh.required_choice("generator", kSolidGenerators);
  if (generator && *generator == 0) {
    model.mesh_source = MeshSource::box;
    const Vec3 size = mesh.required_vec3("size_m", RealRange::left_open(0.0, 10.0), "metres");
    const Vec3 divisions =
        mesh.required_vec3("divisions", RealRange::closed(1.0, 200.0), "hexahedra per axis");
    for (std::size_t axis = 0; axis < 3; ++axis) {
      model.box.size_m[axis] = size[axis];
      model.box.divisions[axis] = static_cast<int>(divisions[axis]);
      if (static_cast<double>(model.box.divisions[axis]) != divisions[axis]) {
        mesh.fail_value("divisions", ": expected whole numbers of hexahedra per axis");
      }
    }
  } else if (generator && *generator == 1) {
    model.mesh_source = MeshSource::cylinder;
    model.cylinder.radius_m =
        mesh.required_double("radius_m", RealRange::left_open(0.0, 10.0), "metres");
    model.cylinder.height_m =
        mesh.required_double("height_m", RealRange::left_open(0.0, 10.0), "metres");
    model.cylinder.radial =
        static_cast<int>(mesh.required_int("radial", IntRange{1, 100}, "rings from axis to wall"));
    model.cylinder.axial =
        static_cast<int>(mesh.required_int("axial", IntRange{1, 400}, "layers along z"));
  } else if (generator) {
    model.mesh_source = MeshSource::gmsh;
    model.mesh_file = mesh.required_file("file", true);
  }
  mesh.finish();
}

void read_material(TableReader& material, ModelDefinition& model, bool shell) {
  ShellMaterialConfig& m = model.material;
  m.young_modulus_pa =
      material.required_double("young_modulus_pa", RealRange::left_open(0.0, 1e12), "pascals");
  m.poisson_ratio = material.required_double(
      "poisson_ratio", RealRange{-0.999, 0.5, false, true}, "dimensionless, below 0.5");
  if (shell) {
    m.thickness_m =
        material.required_double("thickness_m", RealRange::left_open(0.0, 1.0), "metres");
  }
  m.density_kg_per_m3 = material.required_double(
      "density_kg_per_m3", RealRange::left_open(0.0, 1e5), "kilograms per cubic metre");
  m.reference = material.required_string("reference", "where the values come from");
  material.finish();
}

// `dof_count`: 6 for shells (x, y, z, rx, ry, rz), 3 for solids (x, y, z).
void read_fixes(TableReader& root, ModelDefinition& model, ErrorSink& errors,
                std::size_t dof_count) {
  auto fixes = root.array_of_tables("fix", 1, 64, "boundary conditions");
  const bool shell = dof_count == kDofNames.size();
  for (TableReader& fix : fixes) {
    DofFixConfig entry;
    entry.node_set = fix.required_string("node_set", "node set (mesh physical group)");
    auto dofs = fix.optional_string_array(
        "dofs", 1, dof_count, shell ? "dofs to fix (x, y, z, rx, ry, rz)" : "axes to fix (x, y, z)");
    if (!dofs) {
      for (std::size_t d = 0; d < dof_count; ++d) entry.dofs.push_back(static_cast<int>(d));
    } else {
      for (const auto& item : *dofs) {
        int found = -1;
        for (std::size_t d = 0; d < dof_count; ++d) {
          if (item.value == kDofNames[d]) found = static_cast<int>(d);
        }
        if (found < 0) {
          fix.fail_item(item, shell ? ": expected one of x, y, z, rx, ry, rz"
                                    : ": expected one of x, y, z (a solid node has no rotations)");
        } else {
          entry.dofs.push_back(found);
        }
      }
    }
    fix.finish();
    if (errors.ok()) model.fixes.push_back(std::move(entry));
  }
}

void read_modal(TableReader& modal, ModelDefinition& model) {
  ModalConfig& m = model.modal;
  m.mode_count =
      static_cast<std::uint32_t>(modal.required_int("mode_count", IntRange{1, 4096}, "modes"));
  const auto method = modal.optional_string("method", "auto, condensation or shift_invert");
  if (method) {
    bool known = false;
    for (std::size_t i = 0; i < kMethods.size(); ++i) {
      if (*method == kMethods[i]) {
        m.method = static_cast<ModalMethod>(i);
        known = true;
      }
    }
    if (!known && !method->empty()) {
      modal.fail_value("method", ": expected one of auto, condensation, shift_invert");
    }
  }
  m.damping_ratio = modal.optional_double("damping_ratio", 0.05, RealRange::closed(0.0, 2.0),
                                          "fraction of critical damping");
  m.time_step_s = modal.required_double("time_step_s", RealRange::left_open(0.0, 0.1), "seconds");
  m.static_correction = modal.optional_bool("static_correction", true);
  m.surface_set = modal.optional_string("surface_set", "node set").value_or("");
  modal.finish();
}

void read_tensor(TableReader& table, TensorConfig& t) {
  t.contact_set =
      table.optional_string("contact_set", "node set tools may displace").value_or("surface");
  if (t.contact_set.empty()) table.fail_value("contact_set", ": expected a node set name");
  if (const auto stored = table.optional_string("stored", "surface or all")) {
    if (*stored == kStorage[0]) {
      t.stored = TensorStorage::surface;
    } else if (*stored == kStorage[1]) {
      t.stored = TensorStorage::all;
    } else {
      table.fail_value("stored", ": expected surface (boundary nodes) or all (every node)");
    }
  }
  t.max_contacts = static_cast<std::uint32_t>(
      table.optional_int("max_contacts", 8, IntRange{1, 64}, "simultaneous contacts"));
  t.time_step_s = table.optional_double("time_step_s", 0.001, RealRange::left_open(0.0, 0.1),
                                        "seconds (the haptic period, image metadata)");
  table.finish();
}

void read_amplitude_map(TableReader& nonlinear, std::string_view key, std::string_view unit,
                        AmplitudeMapConfig& map) {
  TableReader table = nonlinear.optional_table(key);
  if (!table.present()) return;
  map.coefficients = table.required_double_array("coefficients", 2, 8,
                                                 RealRange::closed(-1e30, 1e30),
                                                 "c0 (= 0), c1, ... of the polynomial, SI");
  if (!map.coefficients.empty() && map.coefficients[0] != 0.0) {
    table.fail_value("coefficients", ": c0 must be 0 (no contact, no displacement or force)");
  }
  map.max_amplitude = table.required_double("max_amplitude", RealRange::left_open(0.0, 1e6), unit);
  table.finish();
}

void read_nonlinear(TableReader& table, TensorConfig& t) {
  t.nonlinear = true;
  read_amplitude_map(table, "displacement_colinear", "metres", t.displacement_colinear);
  read_amplitude_map(table, "displacement_orthogonal", "metres", t.displacement_orthogonal);
  read_amplitude_map(table, "force_colinear", "newtons", t.force_colinear);
  read_amplitude_map(table, "force_orthogonal", "newtons", t.force_orthogonal);
  table.finish();
}

void read_catheter(TableReader& table, CatheterConfig& c) {
  c.length_m = table.required_double("length_m", RealRange::left_open(0.0, 10.0), "metres");
  c.outer_radius_m =
      table.required_double("outer_radius_m", RealRange::left_open(0.0, 0.05), "metres");
  c.bending_stiffness_n_m2 = table.required_double(
      "bending_stiffness_n_m2", RealRange::left_open(0.0, 1e3), "EI, newton square metres");
  c.axial_stiffness_n =
      table.required_double("axial_stiffness_n", RealRange::left_open(0.0, 1e7), "EA, newtons");
  c.linear_density_kg_per_m = table.required_double(
      "linear_density_kg_per_m", RealRange::left_open(0.0, 100.0), "kilograms per metre");
  c.damping_n_s_per_m = table.required_double(
      "damping_n_s_per_m", RealRange::closed(0.0, 1e3), "newton seconds per metre, per particle");
  c.particle_count = static_cast<std::uint32_t>(
      table.required_int("particle_count", IntRange{3, kMaxCatheterParticles}, "particles"));
  c.max_substeps = static_cast<std::uint32_t>(
      table.required_int("max_substeps", IntRange{1, 10000}, "substeps per haptic period"));
  table.finish();
}

void read_catheter_contact(TableReader& table, CatheterConfig& c) {
  c.wall_stiffness_n_per_m = table.optional_double("wall_stiffness_n_per_m", c.wall_stiffness_n_per_m,
                                                   RealRange::left_open(0.0, 1e6), "newtons per metre");
  c.wall_damping_n_s_per_m = table.optional_double("wall_damping_n_s_per_m", c.wall_damping_n_s_per_m,
                                                   RealRange::closed(0.0, 1e3), "newton seconds per metre");
  c.tool_stiffness_n_per_m = table.optional_double("tool_stiffness_n_per_m", c.tool_stiffness_n_per_m,
                                                   RealRange::left_open(0.0, 1e6), "newtons per metre");
  c.grasp_stiffness_n_per_m = table.optional_double("grasp_stiffness_n_per_m", c.grasp_stiffness_n_per_m,
                                                    RealRange::left_open(0.0, 1e6), "newtons per metre");
  c.grasp_friction = table.optional_double("grasp_friction", c.grasp_friction, RealRange::closed(0.0, 10.0),
                                           "friction coefficient");
  c.max_contact_force_n = table.optional_double("max_contact_force_n", c.max_contact_force_n,
                                                RealRange::left_open(0.0, 100.0), "newtons");
  table.finish();
}

void read_pose(TableReader& pose, CatheterConfig& c) {
  c.start_m = pose.required_vec3("start_m", RealRange::closed(-10.0, 10.0), "metres");
  c.direction = pose.required_direction("direction");
  c.hold_start = pose.optional_bool("hold_start", true);
  c.gravity_m_per_s2 = pose.optional_vec3("gravity_m_per_s2", Vec3{},
                                          RealRange::closed(-100.0, 100.0),
                                          "metres per second squared");
  pose.finish();
}

}  // namespace

namespace {

core::Expected<ModelDefinition> model_from_parsed(core::Expected<detail::ParsedFile> parsed);

}  // namespace

core::Expected<ModelDefinition> load_model_definition(const std::filesystem::path& file) {
  return model_from_parsed(detail::parse_toml_file(file));
}

core::Expected<ModelDefinition> load_model_definition_text(std::string_view text,
                                                           const std::filesystem::path& file) {
  return model_from_parsed(detail::parse_toml_text(text, file));
}

namespace {

core::Expected<ModelDefinition> model_from_parsed(core::Expected<detail::ParsedFile> parsed) {
  if (!parsed) return std::move(parsed).error();
  ErrorSink errors;
  TableReader root = detail::root_reader(*parsed, errors);
  ModelDefinition model;
  model.source_path = parsed->file.absolute_path;

  TableReader header = root.required_table("model");
  model.name = header.required_name("name");
  const auto kind = header.required_choice("kind", kKinds);
  if (!kind) {
    // Which tables belong in the file depends on the kind: without one, say only that.
    header.finish();
    return errors.error();
  }
  model.kind = static_cast<ModelKind>(*kind);
  model.image_path = header.required_file("image", false);
  header.finish();
  if (model.kind == ModelKind::catheter) {
    TableReader catheter = root.required_table("catheter");
    read_catheter(catheter, model.catheter);
    TableReader pose = root.required_table("pose");
    read_pose(pose, model.catheter);
    if (TableReader contact = root.optional_table("contact"); contact.present()) {
      read_catheter_contact(contact, model.catheter);
    }
    root.finish();
    if (!errors.ok()) return errors.error();
    return model;
  }
  if (model.kind == ModelKind::tet_tensor) {
    TableReader mesh = root.required_table("mesh");
    read_solid_mesh(mesh, model);
    TableReader material = root.required_table("material");
    read_material(material, model, false);
    read_fixes(root, model, errors, 3);
    TableReader tensor = root.required_table("tensor");
    read_tensor(tensor, model.tensor);
    if (TableReader nonlinear = root.optional_table("nonlinear"); nonlinear.present()) {
      read_nonlinear(nonlinear, model.tensor);
    }
    root.finish();
    if (!errors.ok()) return errors.error();
    return model;
  }

  TableReader mesh = root.required_table("mesh");
  read_mesh(mesh, model);
  TableReader material = root.required_table("material");
  read_material(material, model, true);
  TableReader element = root.required_table("element");
  if (const auto bending = element.required_choice("bending", kBending)) {
    model.bending = *bending == 0 ? BendingKind::rao : BendingKind::dkt;
  }
  element.finish();
  read_fixes(root, model, errors, kDofNames.size());
  TableReader modal = root.required_table("modal");
  read_modal(modal, model);
  root.finish();
  if (!errors.ok()) return errors.error();
  return model;
}

}  // namespace

}  // namespace trainer::config
