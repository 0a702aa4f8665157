// Cotin's tensor model end to end: precompute (double, one factorisation) → float32 image →
// runtime TensorModel, checked against an independent direct sparse solve of the same FEM with
// the same imposed displacements (solve_imposed_displacements), for one contact, several and
// the maximum; the quasi-non-linear maps reproducing configured compression curves on a
// cylinder (Cotin §4.3); refusals on the RT path; image corruption; no heap on the RT path.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/model/image_loader.hpp"
#include "trainer/model/tensor_image.hpp"
#include "trainer/model/tensor_model.hpp"
#include "trainer/model_offline/image_writer.hpp"
#include "trainer/model_offline/tensor_build.hpp"
#include "trainer/model_offline/tet_elasticity.hpp"
#include "trainer/model_offline/tet_mesh_generators.hpp"

namespace trainer::model {
namespace {

using offline::AssembledTet;
using offline::TetMesh;
using RowMatrixX3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

constexpr double kYoungPa = 15e3;  // soft tissue scale (liver ~ 10-20 kPa)
constexpr double kPoisson = 0.45;

// One precomputed model held with everything the comparisons need.
struct Fixture {
  TetMesh mesh;
  AssembledTet assembled;
  std::vector<int> fixed_nodes;
  offline::TensorPrecompute tensors;
  std::vector<std::byte> image_bytes;
  core::Arena arena;
  ModelImage image;
};

std::vector<int> sorted_set(const TetMesh& mesh, const std::string& name) {
  std::vector<int> nodes = mesh.node_sets.at(name);
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  return nodes;
}

std::vector<int> without(const std::vector<int>& nodes, const std::vector<int>& removed) {
  std::vector<int> result;
  std::set_difference(nodes.begin(), nodes.end(), removed.begin(), removed.end(),
                      std::back_inserter(result));
  return result;
}

// Precomputes the model of `mesh` clamped on `fixed_set`, contacts on the free boundary nodes,
// responses of every node, and loads its image through the runtime parser.
std::unique_ptr<Fixture> build(TetMesh mesh, const std::string& fixed_set) {
  auto fixture = std::make_unique<Fixture>(Fixture{std::move(mesh), {}, {}, {}, {},
                                                   core::Arena::create(64 << 20).value(), {}});
  const offline::TetMaterial material{kYoungPa, kPoisson, 1000.0};
  std::vector<offline::TetNodeFix> fixes{{sorted_set(fixture->mesh, fixed_set), {true, true, true}}};
  auto assembled = offline::assemble_tet(fixture->mesh, material, fixes);
  EXPECT_TRUE(assembled) << assembled.error().message;
  fixture->assembled = std::move(assembled).value();
  auto solver = offline::TetStaticSolver::create(fixture->assembled);
  EXPECT_TRUE(solver) << solver.error().message;
  fixture->fixed_nodes = offline::partly_fixed_nodes(fixture->assembled.dofs);
  offline::TensorPrecomputeOptions options;
  options.contact_nodes = without(sorted_set(fixture->mesh, "surface"), fixture->fixed_nodes);
  options.response_nodes = sorted_set(fixture->mesh, "all");
  options.contacts_per_block = 16;  // several blocks even on small meshes
  auto tensors = offline::precompute_tensors(fixture->assembled, solver.value(), options);
  EXPECT_TRUE(tensors) << tensors.error().message;
  fixture->tensors = std::move(tensors).value();
  offline::TensorImageInputs inputs;
  inputs.mesh = &fixture->mesh;
  inputs.boundary_triangles = offline::boundary_triangles(fixture->mesh);
  inputs.material = material;
  inputs.fixed_nodes = fixture->fixed_nodes;
  inputs.time_step_s = 1e-3;
  auto bytes = offline::serialize_tensor_image(inputs, fixture->tensors);
  EXPECT_TRUE(bytes) << bytes.error().message;
  fixture->image_bytes = std::move(bytes).value();
  // parse_model_image wants 64-byte-aligned bytes, as load_model_image gives it.
  auto block = fixture->arena.allocate_array<std::byte>(fixture->image_bytes.size(), "image");
  EXPECT_TRUE(block);
  std::memcpy(block.value().data(), fixture->image_bytes.data(), fixture->image_bytes.size());
  auto image = parse_model_image(block.value(), "test.img", ModelKind::tet_tensor,
                                 offline::ImageWriter::permissive_limits());
  EXPECT_TRUE(image) << image.error().message;
  fixture->image = std::move(image).value();
  return fixture;
}

std::unique_ptr<Fixture> liver_block() {
  // 60 × 40 × 30 mm block clamped on its base: 7 × 5 × 4 = 140 nodes.
  auto mesh = offline::make_tet_box(0.06, 0.04, 0.03, 6, 4, 3);
  EXPECT_TRUE(mesh) << mesh.error().message;
  return build(std::move(mesh).value(), "z0");
}

TensorModel make_model(const Fixture& fixture, core::Arena& arena, std::uint32_t max_contacts,
                       const QuasiNonLinearMaps& maps = {}) {
  TensorSettings settings;
  settings.max_contacts = max_contacts;
  settings.nonlinear = maps;
  auto model = TensorModel::create(tensor_model_data(fixture.image), settings, arena);
  EXPECT_TRUE(model) << model.error().message;
  return std::move(model).value();
}

int node_nearest(const TetMesh& mesh, const Eigen::Vector3d& point) {
  Eigen::Index best = 0;
  (mesh.nodes.rowwise() - point.transpose()).rowwise().squaredNorm().minCoeff(&best);
  return static_cast<int>(best);
}

struct Comparison {
  double displacement_error = 0.0;  // max over nodes and axes, relative to max |u|
  double force_error = 0.0;         // max over contacts, relative to the largest contact force
};

// Runs the runtime model and the direct solve with the same contacts and compares every node.
Comparison compare_with_direct(const Fixture& fixture, TensorModel& model,
                               const std::vector<TensorContact>& contacts) {
  EXPECT_TRUE(model.solve(contacts).is_ok());
  model.update_field();
  std::vector<int> nodes;
  RowMatrixX3 imposed(static_cast<Eigen::Index>(contacts.size()), 3);
  for (std::size_t i = 0; i < contacts.size(); ++i) {
    nodes.push_back(static_cast<int>(contacts[i].node));
    imposed.row(static_cast<Eigen::Index>(i)) = contacts[i].displacement_m.cast<double>();
  }
  auto direct = offline::solve_imposed_displacements(fixture.assembled, nodes, imposed);
  EXPECT_TRUE(direct) << direct.error().message;
  const RowMatrixX3& reference = direct.value().node_displacements;
  Comparison result;
  const double scale = reference.cwiseAbs().maxCoeff();
  const std::span<const float> field = model.displacements();
  const auto responses = model.response_nodes();
  for (std::size_t j = 0; j < responses.size(); ++j) {
    for (int axis = 0; axis < 3; ++axis) {
      const double expected = reference(responses[j], axis);
      result.displacement_error =
          std::max(result.displacement_error,
                   std::fabs(static_cast<double>(field[3 * j + static_cast<std::size_t>(axis)]) -
                             expected) /
                       scale);
      // The on-demand single-node path agrees with the field update (up to summation order).
      EXPECT_NEAR(model.node_displacement(responses[j])[axis],
                  field[3 * j + static_cast<std::size_t>(axis)], 1e-6 * scale);
    }
  }
  const RowMatrixX3& forces = direct.value().contact_forces;
  const double force_scale = forces.rowwise().norm().maxCoeff();
  for (std::size_t i = 0; i < contacts.size(); ++i) {
    const Eigen::Vector3d runtime = model.contact_force(i).cast<double>();
    result.force_error =
        std::max(result.force_error,
                 (runtime - forces.row(static_cast<Eigen::Index>(i)).transpose()).norm() /
                     force_scale);
  }
  return result;
}

// Float32 storage: tensors carry ~6e-8 relative rounding; superposing and the mutual-influence
// solve amplify it by the conditioning of the contact set. 2e-5 of the largest displacement /
// force is ~100× the rounding and far below anything a user could feel or see (2e-5 of 2 mm
// is 40 nm).
constexpr double kTolerance = 2e-5;

TEST(TensorModel, PrecomputeReproducesTheConstraintAtEveryContact) {
  const auto fixture = liver_block();
  EXPECT_LT(fixture->tensors.self_tensor_error, 1e-9);
  EXPECT_GT(fixture->tensors.contact_nodes.size(), 50U);
  // Force tensors are stiffnesses: symmetric positive definite.
  for (std::size_t k = 0; k < fixture->tensors.contact_nodes.size(); ++k) {
    const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> force(
        fixture->tensors.force_tensors.data() + 9 * k);
    EXPECT_NEAR((force - force.transpose()).norm(), 0.0, 1e-9 * force.norm());
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(Eigen::Matrix3d(force)).eigenvalues().minCoeff(), 0.0);
  }
}

TEST(TensorModel, OneContactMatchesTheDirectSolve) {
  const auto fixture = liver_block();
  core::Arena arena = core::Arena::create(1 << 20).value();
  TensorModel model = make_model(*fixture, arena, 8);
  const int top = node_nearest(fixture->mesh, {0.03, 0.02, 0.03});
  const std::vector<TensorContact> contacts{{static_cast<std::uint32_t>(top), {0.0F, 0.0F, -0.002F}}};
  const Comparison error = compare_with_direct(*fixture, model, contacts);
  EXPECT_LT(error.displacement_error, kTolerance);
  EXPECT_LT(error.force_error, kTolerance);
  // One contact is the plain tensor product: the contact node sits at the imposed position.
  EXPECT_NEAR(model.node_displacement(static_cast<std::uint32_t>(top)).z(), -0.002F, 1e-8F);
  // A press into the top face is resisted: the force on the tissue points down (along the
  // push) and is of the order E·a·δ for a contact patch a of one element.
  EXPECT_LT(model.total_force().z(), 0.0F);
}

TEST(TensorModel, SeveralContactsMatchTheDirectSolveWherePlainSuperpositionOverDeforms) {
  const auto fixture = liver_block();
  core::Arena arena = core::Arena::create(1 << 20).value();
  TensorModel model = make_model(*fixture, arena, 8);
  const auto node = [&](double x, double y, double z) {
    return static_cast<std::uint32_t>(node_nearest(fixture->mesh, {x, y, z}));
  };
  // Two neighbouring top nodes (10 mm apart) pressed, one side node pulled sideways.
  const std::vector<TensorContact> contacts{{node(0.02, 0.02, 0.03), {0.0F, 0.0F, -0.002F}},
                                            {node(0.03, 0.02, 0.03), {0.0F, 0.0005F, -0.0015F}},
                                            {node(0.06, 0.02, 0.02), {0.001F, 0.0F, 0.0F}}};
  const Comparison error = compare_with_direct(*fixture, model, contacts);
  EXPECT_LT(error.displacement_error, kTolerance);
  EXPECT_LT(error.force_error, kTolerance);
  // The contact nodes sit exactly where they were put.
  for (const TensorContact& contact : contacts) {
    EXPECT_LT((model.node_displacement(contact.node) - contact.displacement_m).norm(), 1e-8F);
  }
  // Plain superposition (Cotin's figure: "the mesh over-deforms") moves the first contact
  // node past its imposed displacement, by the neighbour's influence.
  Vec3 superposed = Vec3::Zero();
  for (const TensorContact& contact : contacts) {
    TensorModel single = make_model(*fixture, arena, 1);
    ASSERT_TRUE(single.solve(std::span(&contact, 1)).is_ok());
    superposed += single.node_displacement(contacts[0].node);
  }
  EXPECT_GT(std::fabs(superposed.z()), 1.1F * 0.002F);
}

TEST(TensorModel, MaximumContactsMatchTheDirectSolve) {
  const auto fixture = liver_block();
  core::Arena arena = core::Arena::create(1 << 20).value();
  constexpr std::uint32_t kMax = 8;
  TensorModel model = make_model(*fixture, arena, kMax);
  // A 4 × 2 patch of adjacent top nodes (a jaw-sized contact) pressed unevenly.
  std::vector<TensorContact> contacts;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 2; ++j) {
      const auto node = static_cast<std::uint32_t>(
          node_nearest(fixture->mesh, {0.01 + 0.01 * i, 0.01 + 0.01 * j, 0.03}));
      contacts.push_back({node, {0.0002F * static_cast<float>(j), 0.0F,
                                 -0.001F - 0.0003F * static_cast<float>(i)}});
    }
  }
  ASSERT_EQ(contacts.size(), kMax);
  const Comparison error = compare_with_direct(*fixture, model, contacts);
  EXPECT_LT(error.displacement_error, kTolerance);
  EXPECT_LT(error.force_error, kTolerance);
  EXPECT_GT(model.last_pivot_ratio(), 1e-3);
}

TEST(TensorModel, RefusesBadContactSetsAndKeepsThePreviousSolution) {
  const auto fixture = liver_block();
  core::Arena arena = core::Arena::create(1 << 20).value();
  TensorModel model = make_model(*fixture, arena, 2);
  const auto top = static_cast<std::uint32_t>(node_nearest(fixture->mesh, {0.03, 0.02, 0.03}));
  const auto other = static_cast<std::uint32_t>(node_nearest(fixture->mesh, {0.0, 0.0, 0.03}));
  const std::vector<TensorContact> good{{top, {0.0F, 0.0F, -0.001F}}};
  ASSERT_TRUE(model.solve(good).is_ok());
  const Vec3 force = model.contact_force(0);
  const auto fixed = static_cast<std::uint32_t>(fixture->fixed_nodes.front());

  const std::vector<std::pair<std::vector<TensorContact>, core::StatusCode>> bad{
      {{{top, {0, 0, -0.001F}}, {other, {0, 0, 0}}, {top + 1, {0, 0, 0}}},
       core::StatusCode::capacity_exceeded},
      {{{fixed, {0, 0, 0.001F}}}, core::StatusCode::invalid_argument},
      {{{static_cast<std::uint32_t>(fixture->assembled.dofs.node_count) + 5U, {0, 0, 0}}}, core::StatusCode::invalid_argument},
      {{{top, {0, 0, -0.001F}}, {top, {0, 0, -0.002F}}}, core::StatusCode::invalid_argument},
      {{{top, {std::nanf(""), 0, 0}}}, core::StatusCode::numeric_error},
      {{{top, {0, 0, std::numeric_limits<float>::infinity()}}}, core::StatusCode::numeric_error},
  };
  for (const auto& [contacts, code] : bad) {
    EXPECT_EQ(model.solve(contacts).code(), code);
    EXPECT_EQ(model.contact_count(), 1U);
    EXPECT_EQ(model.contact_force(0), force);
    // The accepted contacts as imposed (what the telemetry stream sends) are kept too.
    EXPECT_EQ(model.contact_node(0), top);
    EXPECT_EQ(model.imposed_displacement(0), Vec3(0.0F, 0.0F, -0.001F));
  }
  // Releasing every contact zeroes the field.
  ASSERT_TRUE(model.solve({}).is_ok());
  model.update_field();
  for (const float value : model.displacements()) EXPECT_EQ(value, 0.0F);
  EXPECT_EQ(model.total_force(), Vec3::Zero());
}

TEST(TensorModel, SolveAndFieldUpdateMakeNoHeapAllocations) {
  const auto fixture = liver_block();
  core::Arena arena = core::Arena::create(1 << 20).value();
  TensorModel model = make_model(*fixture, arena, 8);
  const auto top = static_cast<std::uint32_t>(node_nearest(fixture->mesh, {0.03, 0.02, 0.03}));
  const auto next = static_cast<std::uint32_t>(node_nearest(fixture->mesh, {0.04, 0.02, 0.03}));
  ASSERT_TRUE(core::alloc::hooks_installed());
  core::alloc::begin_counting_this_thread();
  for (int cycle = 0; cycle < 1000; ++cycle) {
    const float depth = -1e-5F * static_cast<float>(cycle);
    const std::array<TensorContact, 2> contacts{
        {{top, {0.0F, 0.0F, depth}}, {next, {0.0F, 0.0F, 0.5F * depth}}}};
    (void)model.solve(contacts);
    model.update_field();
    (void)model.node_displacement(top);
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations(), 0U);
}

// ---- quasi-non-linear maps ----

TEST(AmplitudeMap, ChecksThePolynomialAndContinuesLinearlyBeyondItsRange) {
  const AmplitudeMap identity;
  EXPECT_TRUE(identity.is_identity());
  EXPECT_EQ(identity.evaluate(0.25F), 0.25F);

  const std::vector<double> stiffening{0.0, 1.0, 0.0, 4e4};  // a + 4e4 a³ (m → m)
  auto map = AmplitudeMap::create(stiffening, 0.005, "test");
  ASSERT_TRUE(map) << map.error().message;
  EXPECT_NEAR(map.value().evaluate(0.004F), 0.004 + 4e4 * 0.004 * 0.004 * 0.004, 1e-7);
  // Beyond max: value and slope at max, continued linearly (slope 1 + 3·4e4·0.005² = 4).
  const double at_max = 0.005 + 4e4 * 1.25e-7;
  EXPECT_NEAR(map.value().evaluate(0.006F), at_max + 4.0 * 0.001, 1e-6);

  const auto error_of = [](std::vector<double> coefficients, double max) {
    auto refused = AmplitudeMap::create(coefficients, max, "nonlinear.force_colinear");
    return refused ? std::string("accepted") : refused.error().message;
  };
  EXPECT_NE(error_of({0.001, 1.0}, 1.0).find("c0 = 0.001"), std::string::npos);
  EXPECT_NE(error_of({0.0, 1.0, -1.0}, 1.0).find("decreases at amplitude"), std::string::npos);
  EXPECT_NE(error_of({0.0, 1.0}, 0.0).find("max_amplitude"), std::string::npos);
  EXPECT_NE(error_of({0.0}, 1.0).find("1 coefficients"), std::string::npos);
  EXPECT_NE(error_of(std::vector<double>(9, 0.0), 1.0).find("9 coefficients"), std::string::npos);
  EXPECT_NE(error_of({0.0, std::nan("")}, 1.0).find("nonlinear.force_colinear"),
            std::string::npos);
  EXPECT_EQ(error_of({0.0, 1.0, -1.0}, 0.4), "accepted");  // monotone on [0, 0.4]
}

// The paper's cylinder compression experiment (Cotin §4.3): a cylindrical sample on a fixed
// base, its top pressed down by a bonded platen (every top node displaced by −δ ẑ). The
// "measured" curves are a stiffening axial force F(δ) and a radial bulge ρ(δ) of the kind
// their brain-tissue tests gave. The linear model gives F_lin = K δ and ρ_lin = c δ; the maps
// configured are the polynomials with P_F(K δ) = F(δ) and P_ρ(c δ) = ρ(δ), and the model with
// those maps must follow the measured curves at every δ.
TEST(TensorModel, CylinderCompressionFollowsTheConfiguredCurves) {
  auto mesh = offline::make_tet_cylinder(0.01, 0.02, 3, 4);  // R 10 mm, h 20 mm
  ASSERT_TRUE(mesh) << mesh.error().message;
  const auto fixture = build(std::move(mesh).value(), "bottom");
  core::Arena arena = core::Arena::create(4 << 20).value();
  const std::vector<int> top = sorted_set(fixture->mesh, "top");
  ASSERT_LE(top.size(), TensorModel::kMaxContactsLimit);
  const auto compress = [&](TensorModel& model, double depth_m) {
    std::vector<TensorContact> contacts;
    for (const int node : top) {
      contacts.push_back({static_cast<std::uint32_t>(node), {0.0F, 0.0F, static_cast<float>(-depth_m)}});
    }
    EXPECT_TRUE(model.solve(contacts).is_ok());
  };
  // A side node at mid-height on +x: its displacement across the push (radial, plus the small
  // tangential part the mesh's prism split gives) is the bulge.
  const auto side = static_cast<std::uint32_t>(node_nearest(fixture->mesh, {0.01, 0.0, 0.01}));
  const auto radial = [&](const TensorModel& model) {
    return static_cast<double>(model.node_displacement(side).head<2>().norm());
  };

  // Linear slopes from the model itself at a small depth (they are exactly linear).
  const auto top_count = static_cast<std::uint32_t>(top.size());
  TensorModel linear = make_model(*fixture, arena, top_count);
  compress(linear, 1e-4);
  const double axial_stiffness = -static_cast<double>(linear.total_force().z()) / 1e-4;  // N/m
  const double bulge_ratio = radial(linear) / 1e-4;                                       // m/m
  ASSERT_GT(axial_stiffness, 0.0);
  ASSERT_GT(bulge_ratio, 0.0);
  // ... and they agree with the direct solve of the same compression.
  {
    RowMatrixX3 imposed = RowMatrixX3::Zero(static_cast<Eigen::Index>(top.size()), 3);
    imposed.col(2).setConstant(-1e-4);
    auto direct = offline::solve_imposed_displacements(fixture->assembled, top, imposed);
    ASSERT_TRUE(direct) << direct.error().message;
    EXPECT_NEAR(-direct.value().contact_forces.col(2).sum() / 1e-4, axial_stiffness,
                1e-4 * axial_stiffness);
    EXPECT_NEAR(direct.value().node_displacements.row(side).head<2>().norm() / 1e-4, bulge_ratio,
                1e-4 * bulge_ratio);
  }

  // "Measured" curves over δ in [0, 4 mm] (20 % strain), stiffening: F = K δ (1 + a δ + b δ²),
  // ρ = c δ (1 + e δ).
  constexpr double kA = 150.0;    // 1/m
  constexpr double kB = 4e4;      // 1/m²
  constexpr double kE = 120.0;    // 1/m
  constexpr double kMaxDepth = 0.004;
  const double k = axial_stiffness;
  const double c = bulge_ratio;
  const auto measured_force = [&](double d) { return k * d * (1.0 + kA * d + kB * d * d); };
  const auto measured_bulge = [&](double d) { return c * d * (1.0 + kE * d); };
  // P_F(x) = F(x / K): coefficients K·(1/K)^i·(1, a, b) → (0, 1, a/K, b/K²).
  const std::vector<double> force_map{0.0, 1.0, kA / k, kB / (k * k)};
  const std::vector<double> bulge_map{0.0, 1.0, kE / c};
  QuasiNonLinearMaps maps;
  maps.force_colinear = AmplitudeMap::create(force_map, k * kMaxDepth, "force").value();
  maps.displacement_orthogonal =
      AmplitudeMap::create(bulge_map, c * kMaxDepth, "displacement").value();
  TensorModel nonlinear = make_model(*fixture, arena, top_count, maps);

  for (int step = 1; step <= 8; ++step) {
    const double depth = kMaxDepth * step / 8;
    compress(nonlinear, depth);
    compress(linear, depth);
    const double force = -static_cast<double>(nonlinear.total_force().z());
    EXPECT_NEAR(force, measured_force(depth), 1e-4 * measured_force(depth)) << "δ " << depth;
    EXPECT_NEAR(radial(nonlinear), measured_bulge(depth), 1e-4 * measured_bulge(depth))
        << "δ " << depth;
    // The linear model stays on its straight lines, and the curves differ from them.
    EXPECT_NEAR(-static_cast<double>(linear.total_force().z()), k * depth, 1e-4 * k * depth);
    EXPECT_GT(force, k * depth * 1.05);
    // Contact nodes still sit on the platen (the colinear displacement is not remapped).
    EXPECT_NEAR(nonlinear.node_displacement(static_cast<std::uint32_t>(top[0])).z(),
                static_cast<float>(-depth), 1e-7F);
  }
}

// ---- the image ----

TEST(TensorImage, CorruptionAndInconsistencyAreRefusedNamingTheField) {
  const auto fixture = liver_block();
  const auto reparse = [&](std::vector<std::byte> bytes) -> std::string {
    core::Arena arena = core::Arena::create(bytes.size() + 4096).value();
    auto block = arena.allocate_array<std::byte>(bytes.size(), "image").value();
    std::memcpy(block.data(), bytes.data(), bytes.size());
    auto image = parse_model_image(block, "liver.img", ModelKind::tet_tensor,
                                   offline::ImageWriter::permissive_limits());
    return image ? std::string("accepted") : image.error().message;
  };
  const auto reseal = [](std::vector<std::byte>& bytes) {
    const std::uint64_t checksum = compute_image_checksum(bytes);
    std::memcpy(bytes.data() + kImageChecksumOffset, &checksum, sizeof checksum);
  };
  const auto section_offset = [&](const std::vector<std::byte>& bytes, SectionId id) {
    ImageHeaderV1 header;
    std::memcpy(&header, bytes.data(), sizeof header);
    for (std::uint32_t i = 0; i < header.section_count; ++i) {
      SectionEntryV1 entry;
      std::memcpy(&entry, bytes.data() + kImageHeaderBytes + i * kImageSectionEntryBytes,
                  sizeof entry);
      if (entry.id == static_cast<std::uint32_t>(id)) return static_cast<std::size_t>(entry.offset);
    }
    ADD_FAILURE() << "no section " << static_cast<int>(id);
    return std::size_t{0};
  };
  ASSERT_EQ(reparse(fixture->image_bytes), "accepted");

  // A flipped bit anywhere in a tensor: the checksum names it.
  std::vector<std::byte> flipped = fixture->image_bytes;
  flipped[section_offset(flipped, SectionId::tensor_displacement) + 1001] ^= std::byte{0x10};
  EXPECT_NE(reparse(flipped).find("checksum mismatch"), std::string::npos);

  // A consistent checksum over a wrong T(k, k) (a writer bug, not damage).
  std::vector<std::byte> wrong_self = fixture->image_bytes;
  const std::size_t responses = fixture->tensors.response_nodes.size();
  const auto self = static_cast<std::size_t>(
      std::lower_bound(fixture->tensors.response_nodes.begin(),
                       fixture->tensors.response_nodes.end(), fixture->tensors.contact_nodes[0]) -
      fixture->tensors.response_nodes.begin());
  const float bad = 0.9F;
  std::memcpy(wrong_self.data() + section_offset(wrong_self, SectionId::tensor_displacement) +
                  sizeof(float) * 9 * self,
              &bad, sizeof bad);
  (void)responses;
  reseal(wrong_self);
  EXPECT_NE(reparse(wrong_self).find("T(k, k) of contact 0"), std::string::npos) << reparse(wrong_self);

  // A contact node list naming a fixed node.
  std::vector<std::byte> fixed_contact = fixture->image_bytes;
  const auto fixed = static_cast<std::uint32_t>(fixture->fixed_nodes.front());
  if (fixed < fixture->tensors.contact_nodes[0]) {
    std::memcpy(fixed_contact.data() + section_offset(fixed_contact, SectionId::surface_nodes),
                &fixed, sizeof fixed);
    reseal(fixed_contact);
    EXPECT_NE(reparse(fixed_contact).find("is also a fixed node"), std::string::npos)
        << reparse(fixed_contact);
  }

  // A NaN in a force tensor.
  std::vector<std::byte> nan_force = fixture->image_bytes;
  const float nan = std::nanf("");
  std::memcpy(nan_force.data() + section_offset(nan_force, SectionId::tensor_force) + 8, &nan,
              sizeof nan);
  reseal(nan_force);
  EXPECT_NE(reparse(nan_force).find("'tensor_force' element 2"), std::string::npos)
      << reparse(nan_force);

  // A modal_shell image is not a tet_tensor image.
  std::vector<std::byte> wrong_kind = fixture->image_bytes;
  const std::uint32_t modal = static_cast<std::uint32_t>(ModelKind::modal_shell);
  std::memcpy(wrong_kind.data() + offsetof(ImageHeaderV1, model_kind), &modal, sizeof modal);
  reseal(wrong_kind);
  EXPECT_NE(reparse(wrong_kind), "accepted");
}

TEST(TensorImage, WrittenFileLoadsIntoTheArenaAndRunsTheSameModel) {
  const auto fixture = liver_block();
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("tensor_test_" + std::to_string(::getpid()) + ".img");
  offline::TensorImageInputs inputs;
  inputs.mesh = &fixture->mesh;
  inputs.boundary_triangles = offline::boundary_triangles(fixture->mesh);
  inputs.material = {kYoungPa, kPoisson, 1000.0};
  inputs.fixed_nodes = fixture->fixed_nodes;
  ASSERT_TRUE(offline::write_tensor_image(path, inputs, fixture->tensors));
  core::Arena arena = core::Arena::create(8 << 20).value();
  auto image = load_model_image(path, arena, ImageLimits{}, ModelKind::tet_tensor);
  std::filesystem::remove(path);
  ASSERT_TRUE(image) << image.error().message;
  EXPECT_EQ(image.value().metadata().node_count, 140U);
  EXPECT_EQ(image.value().metadata().element_type,
            static_cast<std::uint32_t>(FiniteElementType::tet4));
  EXPECT_EQ(image.value().rows(SectionId::triangles), inputs.boundary_triangles.rows());
  // The same sections as the serialised image (the checksums differ only by the creation time).
  const std::span<const float> loaded = image.value().floats(SectionId::tensor_displacement);
  const std::span<const float> serialised = fixture->image.floats(SectionId::tensor_displacement);
  ASSERT_EQ(loaded.size(), serialised.size());
  EXPECT_TRUE(std::equal(loaded.begin(), loaded.end(), serialised.begin()));
  EXPECT_TRUE(std::ranges::equal(image.value().u32s(SectionId::surface_nodes),
                                 fixture->image.u32s(SectionId::surface_nodes)));
}

}  // namespace
}  // namespace trainer::model
