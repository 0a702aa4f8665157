// Cotin tensor precompute, its image, and the direct imposed-displacement reference
// (tensor_build.hpp).
#include "trainer/model_offline/tensor_build.hpp"

#include "elapsed.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/SparseCholesky>

#include "trainer/core/arena.hpp"
#include "trainer/model/tensor_image.hpp"
#include "trainer/model/tensor_model.hpp"
#include "trainer/model_offline/image_writer.hpp"

namespace trainer::model::offline {

namespace {

using RowMatrix3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

using detail::seconds_since;

core::Expected<void> check_node_list(std::span<const int> nodes, int node_count,
                                     const char* what) {
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    if (nodes[i] < 0 || nodes[i] >= node_count || (i > 0 && nodes[i] <= nodes[i - 1])) {
      return core::make_error(std::string(what) + " entry " + std::to_string(i) + " is node " +
                              std::to_string(nodes[i]) + ": expected strictly increasing node "
                              "indices below " + std::to_string(node_count));
    }
  }
  return {};
}

}  // namespace

std::vector<int> partly_fixed_nodes(const TetDofMap& dofs) {
  std::vector<int> fixed;
  for (int node = 0; node < dofs.node_count; ++node) {
    for (int axis = 0; axis < kTetDofsPerNode; ++axis) {
      if (dofs.free_index[static_cast<std::size_t>(kTetDofsPerNode * node + axis)] < 0) {
        fixed.push_back(node);
        break;
      }
    }
  }
  return fixed;
}

core::Expected<TensorPrecompute> precompute_tensors(const AssembledTet& assembled,
                                                    const TetStaticSolver& solver,
                                                    const TensorPrecomputeOptions& options) {
  const TetDofMap& dofs = assembled.dofs;
  const int node_count = dofs.node_count;
  if (options.contact_nodes.empty() || options.response_nodes.empty()) {
    return core::make_error("tensor precompute: no contact nodes or no stored nodes");
  }
  if (auto ok = check_node_list(options.contact_nodes, node_count, "contact node list"); !ok) {
    return std::move(ok).error();
  }
  if (auto ok = check_node_list(options.response_nodes, node_count, "stored node list"); !ok) {
    return std::move(ok).error();
  }
  if (options.contacts_per_block < 1) {
    return core::make_error("tensor precompute: contacts_per_block must be >= 1");
  }
  const auto free_dof = [&dofs](int node, int axis) {
    return dofs.free_index[static_cast<std::size_t>(kTetDofsPerNode * node + axis)];
  };
  for (const int node : options.contact_nodes) {
    if (free_dof(node, 0) < 0 || free_dof(node, 1) < 0 || free_dof(node, 2) < 0) {
      return core::make_error("tensor precompute: contact node " + std::to_string(node) +
                              " is fixed on some axis: a contact node must be free to be "
                              "displaced (remove it from the contact set)");
    }
    if (!std::binary_search(options.response_nodes.begin(), options.response_nodes.end(), node)) {
      return core::make_error("tensor precompute: contact node " + std::to_string(node) +
                              " is not among the stored nodes (the mutual-influence solve needs "
                              "its response)");
    }
  }

  const std::size_t contact_count = options.contact_nodes.size();
  const std::size_t response_count = options.response_nodes.size();
  TensorPrecompute result;
  result.contact_nodes.assign(options.contact_nodes.begin(), options.contact_nodes.end());
  result.response_nodes.assign(options.response_nodes.begin(), options.response_nodes.end());
  result.displacement_tensors.assign(contact_count * response_count * 9, 0.0F);
  result.force_tensors.assign(contact_count * 9, 0.0);

  const auto start = std::chrono::steady_clock::now();
  const auto block = static_cast<std::size_t>(options.contacts_per_block);
  for (std::size_t first = 0; first < contact_count; first += block) {
    const std::size_t count = std::min(block, contact_count - first);
    Eigen::MatrixXd unit_forces =
        Eigen::MatrixXd::Zero(dofs.free_count, static_cast<Eigen::Index>(3 * count));
    for (std::size_t c = 0; c < count; ++c) {
      for (int axis = 0; axis < 3; ++axis) {
        unit_forces(free_dof(options.contact_nodes[first + c], axis),
                    static_cast<Eigen::Index>(3 * c) + axis) = 1.0;
      }
    }
    auto compliance = solver.solve_free(unit_forces);  // C(:, k) for the block's contacts
    if (!compliance) return std::move(compliance).error();
    const Eigen::MatrixXd& columns = compliance.value();
    for (std::size_t c = 0; c < count; ++c) {
      const std::size_t k = first + c;
      const int node = options.contact_nodes[k];
      const auto col = static_cast<Eigen::Index>(3 * c);
      RowMatrix3 self;
      for (int row = 0; row < 3; ++row) self.row(row) = columns.block(free_dof(node, row), col, 1, 3);
      self = 0.5 * (self + self.transpose()).eval();
      const Eigen::LLT<RowMatrix3> cholesky(self);
      if (cholesky.info() != Eigen::Success) {
        return core::make_error("tensor precompute: the compliance at contact node " +
                                std::to_string(node) +
                                " is not positive definite (is the node connected to the mesh?)");
      }
      const RowMatrix3 force = cholesky.solve(RowMatrix3::Identity());
      const RowMatrix3 force_symmetric = 0.5 * (force + force.transpose());
      std::copy(force_symmetric.data(), force_symmetric.data() + 9,
                result.force_tensors.begin() + static_cast<std::ptrdiff_t>(9 * k));
      for (std::size_t j = 0; j < response_count; ++j) {
        const int response = options.response_nodes[j];
        RowMatrix3 compliance_nk = RowMatrix3::Zero();
        for (int row = 0; row < 3; ++row) {
          const int dof = free_dof(response, row);
          if (dof >= 0) compliance_nk.row(row) = columns.block(dof, col, 1, 3);
        }
        const RowMatrix3 tensor = compliance_nk * force_symmetric;
        if (response == node) {
          result.self_tensor_error = std::max(
              result.self_tensor_error, (tensor - RowMatrix3::Identity()).cwiseAbs().maxCoeff());
        }
        if (!tensor.allFinite()) {
          return core::make_error("tensor precompute: non-finite tensor T(" +
                                  std::to_string(response) + ", " + std::to_string(node) + ")");
        }
        float* out = result.displacement_tensors.data() + 9 * (k * response_count + j);
        for (int i = 0; i < 9; ++i) out[i] = static_cast<float>(tensor.data()[i]);
      }
    }
  }
  result.solve_time_s = seconds_since(start);
  return result;
}

namespace {

core::Expected<ImageWriter> make_tensor_writer(const TensorImageInputs& inputs,
                                               const TensorPrecompute& tensors) {
  if (inputs.mesh == nullptr) return core::make_error("tensor image: no mesh");
  const TetMesh& mesh = *inputs.mesh;
  ImageMetadataV1 metadata = make_metadata();
  metadata.source_mesh_hash = mesh.source_hash;
  metadata.young_modulus_pa = inputs.material.young_modulus_pa;
  metadata.poisson_ratio = inputs.material.poisson_ratio;
  metadata.thickness_m = 0.0;
  metadata.density_kg_per_m3 = inputs.material.density_kg_per_m3;
  metadata.element_type = static_cast<std::uint32_t>(FiniteElementType::tet4);
  metadata.mode_count = 0;
  metadata.node_count = static_cast<std::uint32_t>(mesh.nodes.rows());
  metadata.surface_node_count = static_cast<std::uint32_t>(tensors.contact_nodes.size());
  metadata.time_step_s = inputs.time_step_s;
  // The tensors are exact for the linear FEM; what float storage costs is measured by the
  // tests and `modelc accuracy`, not recorded here.
  if (auto version = set_tool_version(metadata, "modelc 0.1.0"); !version) {
    return std::move(version).error();
  }
  ImageWriter writer(ModelKind::tet_tensor);
  writer.set_metadata(metadata);
  if (auto r = writer.add_f32(SectionId::rest_positions, Eigen::MatrixXd(mesh.nodes)); !r) {
    return std::move(r).error();
  }
  if (auto r = writer.add_u32(SectionId::triangles, Eigen::MatrixXi(inputs.boundary_triangles));
      !r) {
    return std::move(r).error();
  }
  if (!inputs.fixed_nodes.empty()) {
    const std::vector<std::uint32_t> fixed(inputs.fixed_nodes.begin(), inputs.fixed_nodes.end());
    if (auto r = writer.add_u32(SectionId::fixed_nodes, fixed,
                                static_cast<std::uint32_t>(fixed.size()), 1);
        !r) {
      return std::move(r).error();
    }
  }
  const auto contact_count = static_cast<std::uint32_t>(tensors.contact_nodes.size());
  const auto response_count = static_cast<std::uint32_t>(tensors.response_nodes.size());
  if (auto r = writer.add_u32(SectionId::surface_nodes, tensors.contact_nodes, contact_count, 1);
      !r) {
    return std::move(r).error();
  }
  if (auto r = writer.add_u32(SectionId::tensor_nodes, tensors.response_nodes, response_count, 1);
      !r) {
    return std::move(r).error();
  }
  if (auto r = writer.add_f32(SectionId::tensor_displacement,
                              std::span<const float>(tensors.displacement_tensors),
                              contact_count * response_count, 9);
      !r) {
    return std::move(r).error();
  }
  if (auto r = writer.add_f32(SectionId::tensor_force,
                              std::span<const double>(tensors.force_tensors), contact_count, 9);
      !r) {
    return std::move(r).error();
  }
  return writer;
}

}  // namespace

core::Expected<std::vector<std::byte>> serialize_tensor_image(const TensorImageInputs& inputs,
                                                              const TensorPrecompute& tensors) {
  auto writer = make_tensor_writer(inputs, tensors);
  if (!writer) return std::move(writer).error();
  return writer.value().serialize();
}

core::Expected<void> write_tensor_image(const std::filesystem::path& path,
                                        const TensorImageInputs& inputs,
                                        const TensorPrecompute& tensors) {
  auto writer = make_tensor_writer(inputs, tensors);
  if (!writer) return std::move(writer).error();
  return writer.value().write(path);
}

core::Expected<ImposedDisplacementSolution> solve_imposed_displacements(
    const AssembledTet& assembled, std::span<const int> imposed_nodes,
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>&
        imposed_displacements) {
  const TetDofMap& dofs = assembled.dofs;
  if (static_cast<Eigen::Index>(imposed_nodes.size()) != imposed_displacements.rows()) {
    return core::make_error("imposed solve: " + std::to_string(imposed_nodes.size()) +
                            " nodes but " + std::to_string(imposed_displacements.rows()) +
                            " displacement rows");
  }
  // role[free dof] = −1 unknown, else the index into the imposed values (3 i + axis).
  std::vector<int> role(static_cast<std::size_t>(dofs.free_count), -1);
  Eigen::VectorXd imposed_values(static_cast<Eigen::Index>(3 * imposed_nodes.size()));
  for (std::size_t i = 0; i < imposed_nodes.size(); ++i) {
    const int node = imposed_nodes[i];
    if (node < 0 || node >= dofs.node_count) {
      return core::make_error("imposed solve: node " + std::to_string(node) + " out of range");
    }
    for (int axis = 0; axis < 3; ++axis) {
      const int dof = dofs.free_index[static_cast<std::size_t>(3 * node + axis)];
      if (dof < 0) {
        return core::make_error("imposed solve: node " + std::to_string(node) +
                                " is fixed on axis " + std::to_string(axis));
      }
      if (role[static_cast<std::size_t>(dof)] >= 0) {
        return core::make_error("imposed solve: node " + std::to_string(node) + " given twice");
      }
      role[static_cast<std::size_t>(dof)] = static_cast<int>(3 * i) + axis;
      imposed_values(static_cast<Eigen::Index>(3 * i) + axis) =
          imposed_displacements(static_cast<Eigen::Index>(i), axis);
    }
  }
  std::vector<int> unknown_index(static_cast<std::size_t>(dofs.free_count), -1);
  int unknown_count = 0;
  for (std::size_t dof = 0; dof < role.size(); ++dof) {
    if (role[dof] < 0) unknown_index[dof] = unknown_count++;
  }
  // K_uu and the right-hand side −K_uc u_c in one pass over K_ff.
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<std::size_t>(assembled.stiffness_free.nonZeros()));
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(unknown_count);
  Eigen::VectorXd imposed_forces = Eigen::VectorXd::Zero(imposed_values.size());
  const Eigen::SparseMatrix<double>& stiffness = assembled.stiffness_free;
  for (int col = 0; col < stiffness.outerSize(); ++col) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(stiffness, col); it; ++it) {
      const auto row = static_cast<std::size_t>(it.row());
      const auto column = static_cast<std::size_t>(it.col());
      if (role[row] < 0 && role[column] < 0) {
        triplets.emplace_back(unknown_index[row], unknown_index[column], it.value());
      } else if (role[row] < 0 && role[column] >= 0) {
        rhs(unknown_index[row]) -= it.value() * imposed_values(role[column]);
      } else if (role[row] >= 0 && role[column] >= 0) {
        imposed_forces(role[row]) += it.value() * imposed_values(role[column]);
      }
    }
  }
  Eigen::SparseMatrix<double> reduced(unknown_count, unknown_count);
  reduced.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> factorization(reduced);
  if (factorization.info() != Eigen::Success) {
    return core::make_error("imposed solve: the reduced stiffness is not positive definite");
  }
  const Eigen::VectorXd unknowns = factorization.solve(rhs);
  // Forces at the imposed dofs: K_cu u_u + K_cc u_c.
  for (int col = 0; col < stiffness.outerSize(); ++col) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(stiffness, col); it; ++it) {
      const auto row = static_cast<std::size_t>(it.row());
      const auto column = static_cast<std::size_t>(it.col());
      if (role[row] >= 0 && role[column] < 0) {
        imposed_forces(role[row]) += it.value() * unknowns(unknown_index[column]);
      }
    }
  }
  ImposedDisplacementSolution solution;
  solution.node_displacements.setZero(dofs.node_count, 3);
  for (int node = 0; node < dofs.node_count; ++node) {
    for (int axis = 0; axis < 3; ++axis) {
      const int dof = dofs.free_index[static_cast<std::size_t>(3 * node + axis)];
      if (dof < 0) continue;
      const int r = role[static_cast<std::size_t>(dof)];
      solution.node_displacements(node, axis) =
          r >= 0 ? imposed_values(r) : unknowns(unknown_index[static_cast<std::size_t>(dof)]);
    }
  }
  solution.contact_forces.resize(static_cast<Eigen::Index>(imposed_nodes.size()), 3);
  for (Eigen::Index i = 0; i < solution.contact_forces.rows(); ++i) {
    for (int axis = 0; axis < 3; ++axis) solution.contact_forces(i, axis) = imposed_forces(3 * i + axis);
  }
  return solution;
}

core::Expected<std::vector<TensorAgreement>> measure_tensor_agreement(
    const TetMesh& mesh, const AssembledTet& assembled, std::span<const std::byte> image_bytes,
    std::uint32_t max_contacts) {
  // The image as the trainer sees it: parsed in place from a 64-byte-aligned arena block.
  auto arena = core::Arena::create(image_bytes.size() + (std::size_t{4} << 20));
  if (!arena) return std::move(arena).error();
  auto block = arena.value().allocate_array<std::byte>(image_bytes.size(), "tensor image");
  if (!block) return std::move(block).error();
  std::copy(image_bytes.begin(), image_bytes.end(), block.value().begin());
  auto image = parse_model_image(block.value(), "built image", ModelKind::tet_tensor,
                                 ImageWriter::permissive_limits());
  if (!image) return std::move(image).error();
  TensorSettings settings;
  settings.max_contacts = max_contacts;
  auto created = TensorModel::create(tensor_model_data(image.value()), settings, arena.value());
  if (!created) return std::move(created).error();
  TensorModel& runtime = created.value();

  const std::span<const std::uint32_t> contacts = runtime.contact_nodes();
  const std::span<const float> forces = image.value().floats(SectionId::tensor_force);
  std::size_t softest = 0;
  for (std::size_t k = 1; k < contacts.size(); ++k) {
    const auto trace = [&](std::size_t c) {
      return forces[9 * c] + forces[9 * c + 4] + forces[9 * c + 8];
    };
    if (trace(k) < trace(softest)) softest = k;
  }
  const Eigen::RowVector3d centroid = mesh.nodes.colwise().mean();
  const double depth =
      0.02 * (mesh.nodes.colwise().maxCoeff() - mesh.nodes.colwise().minCoeff()).norm();
  const Eigen::RowVector3d origin = mesh.nodes.row(contacts[softest]);
  const Eigen::RowVector3d push = depth * (centroid - origin).normalized();
  std::vector<std::uint32_t> nearest(contacts.begin(), contacts.end());
  std::sort(nearest.begin(), nearest.end(), [&](std::uint32_t a, std::uint32_t b) {
    return (mesh.nodes.row(a) - origin).squaredNorm() < (mesh.nodes.row(b) - origin).squaredNorm();
  });

  std::vector<std::uint32_t> counts{1};
  if (max_contacts >= 2) counts.push_back(2);
  if (max_contacts > 2) counts.push_back(std::min<std::uint32_t>(max_contacts,
                                         static_cast<std::uint32_t>(contacts.size())));
  std::vector<TensorAgreement> results;
  for (const std::uint32_t count : counts) {
    std::vector<TensorContact> imposed;
    std::vector<int> nodes;
    Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> values(count, 3);
    for (std::uint32_t i = 0; i < count; ++i) {
      imposed.push_back({nearest[i], push.transpose().cast<float>()});
      nodes.push_back(static_cast<int>(nearest[i]));
      values.row(i) = push;
    }
    std::sort(imposed.begin(), imposed.end(),
              [](const TensorContact& a, const TensorContact& b) { return a.node < b.node; });
    std::sort(nodes.begin(), nodes.end());
    const auto tensor_start = std::chrono::steady_clock::now();
    if (const core::Status status = runtime.solve(imposed); !status.is_ok()) {
      return core::make_error(std::string("tensor model refused the check's contacts: ") +
                              status.detail());
    }
    runtime.update_field();
    const double tensor_s = seconds_since(tensor_start);
    const auto direct_start = std::chrono::steady_clock::now();
    auto direct = solve_imposed_displacements(assembled, nodes, values);
    if (!direct) return std::move(direct).error();
    TensorAgreement agreement;
    agreement.contact_count = static_cast<int>(count);
    agreement.direct_solve_s = seconds_since(direct_start);
    agreement.tensor_solve_us = 1e6 * tensor_s;
    const auto& reference = direct.value().node_displacements;
    const double scale = reference.cwiseAbs().maxCoeff();
    const std::span<const float> field = runtime.displacements();
    const std::span<const std::uint32_t> stored = runtime.response_nodes();
    for (std::size_t j = 0; j < stored.size(); ++j) {
      for (int axis = 0; axis < 3; ++axis) {
        agreement.displacement_error = std::max(
            agreement.displacement_error,
            std::fabs(static_cast<double>(field[3 * j + static_cast<std::size_t>(axis)]) -
                      reference(stored[j], axis)) / scale);
      }
    }
    const auto& reference_forces = direct.value().contact_forces;
    const double force_scale = reference_forces.rowwise().norm().maxCoeff();
    for (std::uint32_t i = 0; i < count; ++i) {
      const Eigen::Vector3d difference =
          runtime.contact_force(i).cast<double>() - reference_forces.row(i).transpose();
      agreement.force_error = std::max(agreement.force_error, difference.norm() / force_scale);
    }
    results.push_back(agreement);
  }
  return results;
}

}  // namespace trainer::model::offline
