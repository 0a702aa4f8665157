#include "trainer/model_offline/modal_build.hpp"

#include "elapsed.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <string>

#include "trainer/model/image_format.hpp"
#include "trainer/model_offline/image_writer.hpp"
#include "trainer/model_offline/mesh_validation.hpp"
#include "trainer/model_offline/shell_assembly.hpp"

namespace trainer::model::offline {

namespace {

using Clock = std::chrono::steady_clock;

using detail::seconds_since;

// Measured on the default duct (336 nodes, 960 translational dofs, r = 20): sparse
// shift-invert 25 ms, dense condensation 750 ms. Shift-invert is the default; only when every
// mode is wanted (r = translational dofs, which Lanczos cannot return) does condensation run.

}  // namespace

RayleighDamping rayleigh_for_ratio(double damping_ratio, double omega_low, double omega_high) {
  RayleighDamping rayleigh;
  const double sum = omega_low + omega_high;
  if (!(sum > 0.0)) return rayleigh;
  rayleigh.mass_proportional_per_s = 2.0 * damping_ratio * omega_low * omega_high / sum;
  rayleigh.stiffness_proportional_s = 2.0 * damping_ratio / sum;
  return rayleigh;
}

core::Expected<ModalBuildResult> build_modal_model(const ModalBuildSpec& spec) {
  const auto build_start = Clock::now();
  const std::string where = "model '" + spec.name + "': ";
  if (auto valid = validate_shell_mesh(spec.mesh); !valid) {
    return core::make_error(where + valid.error().message);
  }

  ModalBuildResult result;
  auto start = Clock::now();
  auto shell = assemble_shell(spec.mesh, spec.material, spec.bending, spec.fixes);
  if (!shell) return core::make_error(where + shell.error().message);
  result.shell = std::move(*shell);
  result.timings.assembly_s = seconds_since(start);

  const int translational =
      static_cast<int>(translational_dofs(result.shell.dofs).free_indices.size());
  ModalOptions options;
  options.method = spec.method.value_or(spec.mode_count >= translational
                                            ? ModalMethod::condensation
                                            : ModalMethod::shift_invert);
  start = Clock::now();
  auto basis = compute_modes(result.shell, spec.mode_count, options);
  if (!basis) return core::make_error(where + basis.error().message);
  result.basis = std::move(*basis);
  result.timings.modes_s = seconds_since(start);

  const Eigen::VectorXd& omega_squared = result.basis.omega_squared;
  result.rayleigh = spec.damping_override.value_or(
      rayleigh_for_ratio(spec.damping_ratio, std::sqrt(omega_squared(0)),
                         std::sqrt(omega_squared(omega_squared.size() - 1))));
  auto damping = modal_damping(omega_squared, DampingModel{0.0, result.rayleigh});
  if (!damping) return core::make_error(where + damping.error().message);
  result.modal_damping = std::move(*damping);

  // Surface nodes: the named set's nodes that can move (a clamped node cannot be indented).
  const std::vector<int> movable = nodes_with_free_translation(result.shell.dofs);
  if (spec.surface_set.empty()) {
    result.surface_nodes = movable;
  } else {
    const auto found = spec.mesh.node_sets.find(spec.surface_set);
    if (found == spec.mesh.node_sets.end()) {
      return core::make_error(where + "surface set '" + spec.surface_set +
                              "' is not a node set of the mesh");
    }
    std::vector<int> wanted = found->second;
    std::sort(wanted.begin(), wanted.end());
    std::set_intersection(wanted.begin(), wanted.end(), movable.begin(), movable.end(),
                          std::back_inserter(result.surface_nodes));
  }
  if (result.surface_nodes.empty()) {
    return core::make_error(where + "no movable node in the surface set");
  }

  if (spec.static_correction) {
    start = Clock::now();
    auto residual = compute_residual_compliance(result.shell, result.basis, result.surface_nodes);
    if (!residual) return core::make_error(where + residual.error().message);
    result.residual = std::move(*residual);
    result.timings.residual_s = seconds_since(start);
  }

  start = Clock::now();
  auto truncation = estimate_truncation_error(result.shell, result.basis, result.surface_nodes);
  if (!truncation) return core::make_error(where + truncation.error().message);
  result.truncation = *truncation;
  result.timings.error_estimate_s = seconds_since(start);
  result.timings.total_s = seconds_since(build_start);
  return result;
}

template <typename Scalar>
ModalDataCopy<Scalar>::ModalDataCopy(const ModalBuildSpec& spec, const ModalBuildResult& build)
    : node_count_(static_cast<std::uint32_t>(spec.mesh.nodes.rows())),
      mode_count_(static_cast<std::uint32_t>(build.basis.mode_count())) {
  // Row-major copies, exactly as ImageWriter lays the sections out.
  for (Eigen::Index node = 0; node < spec.mesh.nodes.rows(); ++node) {
    for (int axis = 0; axis < 3; ++axis) {
      rest_positions_.push_back(static_cast<Scalar>(spec.mesh.nodes(node, axis)));
    }
  }
  const Eigen::MatrixXd& shapes = build.basis.node_shapes;
  for (Eigen::Index row = 0; row < shapes.rows(); ++row) {
    for (Eigen::Index col = 0; col < shapes.cols(); ++col) {
      mode_shapes_.push_back(static_cast<Scalar>(shapes(row, col)));
    }
  }
  for (Eigen::Index i = 0; i < build.basis.omega_squared.size(); ++i) {
    omega_squared_.push_back(static_cast<Scalar>(build.basis.omega_squared(i)));
    modal_damping_.push_back(static_cast<Scalar>(build.modal_damping(i)));
  }
  for (int node : build.surface_nodes) surface_nodes_.push_back(static_cast<std::uint32_t>(node));
  if (build.residual) {
    const Eigen::MatrixXd& compliance = build.residual->compliance;
    for (Eigen::Index row = 0; row < compliance.rows(); ++row) {
      for (Eigen::Index col = 0; col < compliance.cols(); ++col) {
        residual_.push_back(static_cast<Scalar>(compliance(row, col)));
      }
    }
  }
}

template <typename Scalar>
model::BasicModalModelData<Scalar> ModalDataCopy<Scalar>::view() const {
  model::BasicModalModelData<Scalar> data;
  data.node_count = node_count_;
  data.mode_count = mode_count_;
  data.rest_positions = rest_positions_;
  data.mode_shapes = mode_shapes_;
  data.omega_squared = omega_squared_;
  data.modal_damping = modal_damping_;
  data.surface_nodes = surface_nodes_;
  data.residual_compliance = residual_;
  return data;
}

template class ModalDataCopy<float>;
template class ModalDataCopy<double>;

core::Expected<void> write_modal_image(const ModalBuildSpec& spec, const ModalBuildResult& result,
                                       const std::filesystem::path& path,
                                       const std::optional<ErrorBudgetRecord>& budget) {
  const int node_count = static_cast<int>(spec.mesh.nodes.rows());
  ImageMetadataV1 metadata = make_metadata();
  metadata.source_mesh_hash = spec.mesh.source_hash;
  metadata.young_modulus_pa = spec.material.young_modulus_pa;
  metadata.poisson_ratio = spec.material.poisson_ratio;
  metadata.thickness_m = spec.material.thickness_m;
  metadata.density_kg_per_m3 = spec.material.density_kg_per_m3;
  metadata.element_type = static_cast<std::uint32_t>(spec.bending == BendingElement::dkt
                                                         ? FiniteElementType::shell_dkt
                                                         : FiniteElementType::shell_rao);
  metadata.mode_count = static_cast<std::uint32_t>(result.basis.mode_count());
  metadata.node_count = static_cast<std::uint32_t>(node_count);
  metadata.surface_node_count = static_cast<std::uint32_t>(result.surface_nodes.size());
  metadata.time_step_s = spec.time_step_s;
  metadata.damping_ratio = spec.damping_ratio;
  // Without static correction the contact response carries the modal truncation error; with
  // it the static response at surface nodes is exact, and what remains is dynamic.
  metadata.error_estimate = spec.static_correction ? 0.0 : result.truncation.max_local_relative;
  if (budget) {
    metadata.error_budget = budget->budget;
    metadata.error_estimate = budget->measured_error;
  }
  metadata.static_correction = spec.static_correction ? 1U : 0U;
  metadata.created_unix_s = static_cast<std::uint64_t>(std::time(nullptr));
  if (auto version = set_tool_version(metadata, "modelc 0.1.0"); !version) return version;

  ImageWriter writer(ModelKind::modal_shell);
  writer.set_metadata(metadata);
  const Eigen::MatrixXd positions = spec.mesh.nodes;
  if (auto r = writer.add_f32(SectionId::rest_positions, positions); !r) return r;
  const Eigen::MatrixXi triangles = spec.mesh.triangles;
  if (auto r = writer.add_u32(SectionId::triangles, triangles); !r) return r;

  std::vector<std::uint32_t> fixed;
  for (int node = 0; node < node_count; ++node) {
    bool all_fixed = true;
    for (int axis = 0; axis < 3; ++axis) {
      all_fixed =
          all_fixed && result.shell.dofs.free_index[static_cast<std::size_t>(node * 6 + axis)] < 0;
    }
    if (all_fixed) fixed.push_back(static_cast<std::uint32_t>(node));
  }
  if (!fixed.empty()) {
    if (auto r = writer.add_u32(SectionId::fixed_nodes, fixed,
                                static_cast<std::uint32_t>(fixed.size()), 1);
        !r) {
      return r;
    }
  }
  std::vector<std::uint32_t> surface(result.surface_nodes.begin(), result.surface_nodes.end());
  if (auto r = writer.add_u32(SectionId::surface_nodes, surface,
                              static_cast<std::uint32_t>(surface.size()), 1);
      !r) {
    return r;
  }
  if (auto r = writer.add_f32(SectionId::mode_shapes, result.basis.node_shapes); !r) return r;
  if (auto r =
          writer.add_f32(SectionId::omega_squared, Eigen::MatrixXd(result.basis.omega_squared));
      !r) {
    return r;
  }
  if (auto r = writer.add_f32(SectionId::modal_damping, Eigen::MatrixXd(result.modal_damping));
      !r) {
    return r;
  }
  if (result.residual) {
    if (auto r = writer.add_f32(SectionId::residual_compliance, result.residual->compliance); !r) {
      return r;
    }
  }
  return writer.write(path);
}

}  // namespace trainer::model::offline
