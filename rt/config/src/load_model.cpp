// The model definition schema: [model], [mesh], [material], [element], [[fix]], [modal].
// Documented in docs/config.md; keep them in step.
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

constexpr std::array<std::string_view, 1> kKinds = {"modal_shell"};
constexpr std::array<std::string_view, 2> kGenerators = {"tube", "gmsh"};
constexpr std::array<std::string_view, 2> kBending = {"rao", "dkt"};
constexpr std::array<std::string_view, 3> kMethods = {"auto", "condensation", "shift_invert"};
constexpr std::array<std::string_view, 6> kDofNames = {"x", "y", "z", "rx", "ry", "rz"};

void read_mesh(TableReader& mesh, ModelDefinition& model) {
  const auto generator = mesh.required_choice("generator", kGenerators);
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

void read_material(TableReader& material, ModelDefinition& model) {
  ShellMaterialConfig& m = model.material;
  m.young_modulus_pa =
      material.required_double("young_modulus_pa", RealRange::left_open(0.0, 1e12), "pascals");
  m.poisson_ratio = material.required_double(
      "poisson_ratio", RealRange{-0.999, 0.5, false, true}, "dimensionless, below 0.5");
  m.thickness_m = material.required_double("thickness_m", RealRange::left_open(0.0, 1.0), "metres");
  m.density_kg_per_m3 = material.required_double(
      "density_kg_per_m3", RealRange::left_open(0.0, 1e5), "kilograms per cubic metre");
  m.reference = material.required_string("reference", "where the values come from");
  material.finish();
}

void read_fixes(TableReader& root, ModelDefinition& model, ErrorSink& errors) {
  auto fixes = root.array_of_tables("fix", 1, 64, "boundary conditions");
  for (TableReader& fix : fixes) {
    DofFixConfig entry;
    entry.node_set = fix.required_string("node_set", "node set (mesh physical group)");
    auto dofs = fix.optional_string_array("dofs", 1, 6, "dofs to fix (x, y, z, rx, ry, rz)");
    if (!dofs) {
      entry.dofs = {0, 1, 2, 3, 4, 5};
    } else {
      for (const auto& item : *dofs) {
        int found = -1;
        for (std::size_t d = 0; d < kDofNames.size(); ++d) {
          if (item.value == kDofNames[d]) found = static_cast<int>(d);
        }
        if (found < 0) {
          fix.fail_item(item, ": expected one of x, y, z, rx, ry, rz");
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

}  // namespace

core::Expected<ModelDefinition> load_model_definition(const std::filesystem::path& file) {
  auto parsed = detail::parse_toml_file(file);
  if (!parsed) return std::move(parsed).error();
  ErrorSink errors;
  TableReader root = detail::root_reader(*parsed, errors);
  ModelDefinition model;
  model.source_path = parsed->file.absolute_path;

  TableReader header = root.required_table("model");
  model.name = header.required_name("name");
  if (header.required_choice("kind", kKinds)) model.kind = ModelKind::modal_shell;
  model.image_path = header.required_file("image", false);
  header.finish();

  TableReader mesh = root.required_table("mesh");
  read_mesh(mesh, model);
  TableReader material = root.required_table("material");
  read_material(material, model);
  TableReader element = root.required_table("element");
  if (const auto bending = element.required_choice("bending", kBending)) {
    model.bending = *bending == 0 ? BendingKind::rao : BendingKind::dkt;
  }
  element.finish();
  read_fixes(root, model, errors);
  TableReader modal = root.required_table("modal");
  read_modal(modal, model);
  root.finish();
  if (!errors.ok()) return errors.error();
  return model;
}

}  // namespace trainer::config
